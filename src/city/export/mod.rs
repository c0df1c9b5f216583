//! Export: glTF binary (`.glb`) of the extruded meshes, and GeoJSON of the footprints with their
//! computed heights, in the input's own coordinates.
//!
//! - [`gltf`]: [`write_glb`], [`glb_bytes`].
//! - [`geojson`]: [`write_geojson`], [`geojson_value`].

pub mod geojson;
pub mod gltf;

use std::path::PathBuf;

pub use self::geojson::{geojson_value, write_geojson};
pub use self::gltf::{glb_bytes, write_glb, GlbStats};

/// Why an export failed. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The file could not be written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The meshes do not match the city, or the JSON could not be produced.
    #[error("{file}: {message}")]
    Invalid {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
}
