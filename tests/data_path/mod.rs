//! The repository's bundled data for the integration tests (`mod data_path;` in a test file).

use std::path::PathBuf;

/// `data/REL` in the repository (Bubeneč and Helsinki are copied there; see `data/README.md`).
pub fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(rel)
}
