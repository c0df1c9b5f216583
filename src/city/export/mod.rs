//! Export: glTF binary (`.glb`) of the extruded meshes, and GeoJSON of the footprints with their
//! computed heights, in the input's own coordinates.
//!
//! - [`gltf`]: [`write_glb`], [`write_glb_to`] (streamed to any writer), [`glb_bytes`].
//! - [`geojson`]: [`write_geojson`], [`geojson_value`].
//! - [`terrain`]: [`TerrainTin`], the terrain surface the CityJSON, glTF and 3D Tiles writers
//!   take beside the buildings.

pub mod cityjson;
pub mod geojson;
pub mod gltf;
pub mod terrain;

use std::path::PathBuf;

pub use self::geojson::{geojson_value, write_geojson};
pub use self::gltf::{
    glb_bytes, glb_bytes_with_terrain, tile_glb, tile_glb_bytes, write_glb, write_glb_to,
    write_glb_to_with_terrain, write_glb_with_terrain, ContentEncoding, GlbStats, TileContent,
    TileFeature, TileMesh, GLB_MAX_BYTES, POSITION_TOLERANCE_M,
};
pub use self::terrain::{TerrainError, TerrainTin};

/// Why an export failed. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The output could not be written, renamed or placed (see [`crate::output`]).
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// The file could not be written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The meshes do not match the city's buildings.
    #[error("{file}: {meshes} meshes for {buildings} buildings")]
    MeshCount {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// Meshes given.
        meshes: usize,
        /// Buildings in the city.
        buildings: usize,
    },
    /// A per-vertex array of a tile mesh does not have one entry per position.
    #[error("{file}: {attribute} has {count} entries for {vertices} vertices")]
    AttributeCount {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// The attribute (`NORMAL`, `COLOR_0`, `_FEATURE_ID_0`).
        attribute: &'static str,
        /// Entries given.
        count: usize,
        /// Positions.
        vertices: usize,
    },
    /// A tile mesh's indices are not whole triangles of its vertices.
    #[error("{file}: {what}")]
    Indices {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// What is wrong: the count, or the first index past the vertices.
        what: String,
    },
    /// The `.glb` would be larger than the format allows ([`GLB_MAX_BYTES`]: its header stores
    /// the length in 32 bits). Nothing was written.
    #[error(
        "{file}: the glTF binary would be {} bytes, over the format's limit of {limit} bytes \
         (4 GiB); export a smaller area (fewer buildings) per file",
        bytes.map_or_else(|| "more than 2^64".to_string(), |b| b.to_string())
    )]
    TooLarge {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// The size the file would have, `None` when it does not even fit in 64 bits.
        bytes: Option<u64>,
        /// The largest size allowed.
        limit: u64,
    },
    /// The terrain given with the city cannot be exported (see [`TerrainTin::check`]).
    #[error("{file}: {source}")]
    Terrain {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// What is wrong with it.
        #[source]
        source: TerrainError,
    },
    /// The JSON (the glTF document or the GeoJSON) could not be serialised or written.
    #[error("{file}: writing the JSON failed: {source}")]
    Json {
        /// The file (`<glb>` when no file is written).
        file: PathBuf,
        /// What `serde_json` said.
        #[source]
        source: serde_json::Error,
    },
}

impl ExportError {
    /// The same error naming `file` instead (for errors made before the file was known).
    fn for_file(self, file: &std::path::Path) -> Self {
        match self {
            ExportError::Output(e) => ExportError::Output(e),
            ExportError::Io { source, .. } => ExportError::Io {
                file: file.to_path_buf(),
                source,
            },
            ExportError::Indices { what, .. } => ExportError::Indices {
                file: file.to_path_buf(),
                what,
            },
            ExportError::MeshCount {
                meshes, buildings, ..
            } => ExportError::MeshCount {
                file: file.to_path_buf(),
                meshes,
                buildings,
            },
            ExportError::AttributeCount {
                attribute,
                count,
                vertices,
                ..
            } => ExportError::AttributeCount {
                file: file.to_path_buf(),
                attribute,
                count,
                vertices,
            },
            ExportError::TooLarge { bytes, limit, .. } => ExportError::TooLarge {
                file: file.to_path_buf(),
                bytes,
                limit,
            },
            ExportError::Terrain { source, .. } => ExportError::Terrain {
                file: file.to_path_buf(),
                source,
            },
            ExportError::Json { source, .. } => ExportError::Json {
                file: file.to_path_buf(),
                source,
            },
        }
    }
}
