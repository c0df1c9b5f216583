//! (to be written)
use crate::{ImportError, Layer, Theme};
use std::path::Path;

/// Reads a layer.
pub fn read(path: &Path, _theme: &Theme) -> Result<Layer, ImportError> {
    Err(ImportError::Unsupported {
        file: path.to_path_buf(),
        message: "not yet".into(),
    })
}
