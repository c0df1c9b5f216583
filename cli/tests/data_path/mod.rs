//! The repository's bundled data for the command-line tests (`mod data_path;` in a test file).

use std::path::{Path, PathBuf};

/// `data/REL` in the repository (the workspace root, one folder above this crate).
pub fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(rel)
}
