//! The scratch folder every file-reading target writes its input into (one per process).

use std::path::Path;
use std::sync::OnceLock;

pub fn dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("a temporary folder for the fuzz inputs"))
        .path()
}
