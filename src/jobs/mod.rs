//! A city processed in tiles, each tile a self-contained, deterministic job that any batch engine
//! can run (a Slurm array, Kubernetes indexed jobs, GNU parallel, `xargs -P`): no scheduler here.
//!
//! Three steps, each a function and a `blockwalk jobs` command:
//!
//! 1. [`plan`]: the street graph's faces for the whole city (Pina, Serón and Cerezo, §3), then one streaming
//!    pass over the footprints (read [`STREAM_CHUNK`] at a time, never all at once) that repairs
//!    each footprint and assigns it to its block with the one-job rule
//!    ([`crate::blocks::assign::assign`]), counting buildings and growing each block's box; the
//!    buildings in no face form the outskirts groups, as in [`crate::blocks::detect`]. The blocks
//!    are then cut into tiles along the block quadtree (the BqR-tree's quadrant rule, Pina, Serón and Cerezo
//!    §4: the region of the blocks' boxes and centres split into four equal quadrants, a block
//!    going to the quadrant of its centre) where a node holds at most `max_buildings`
//!    buildings (a single block, or blocks at the depth limit, is never split: a tile can hold
//!    more then). A tile is a set of whole blocks, so no building is ever cut. `plan.json`
//!    holds the blocks (outlines with exact coordinates), the tiles, the metric transform's
//!    centre and the local frame's origin of the whole city, and stamps (size, CRC-32) of every
//!    input file (each layer with its `.shx`, `.dbf`, `.prj`, `.cpg`). Its `plan_id` is the
//!    CRC-32 of the rest of the plan, checked whenever the plan is read: an edited plan is
//!    refused.
//! 2. [`run_tile`]: one tile. It reads only the footprints whose box meets the tile's box
//!    (streaming filter while reading: memory is bounded by the tile), builds them in the whole
//!    city's metric frame and local frame (so its f32 meshes are bit for bit the one-job run's),
//!    assigns them with the same rule against every block whose box meets them (a building
//!    straddling tile bounds is read by both tiles but assigned to exactly one), checks the
//!    counts against the plan, extrudes, writes `tiles/tile_NNNNN.glb` and, last, the manifest
//!    `tiles/tile_NNNNN.json` that says the tile is done.
//!    Optionally ([`TileOptions`]) the tile's BlockMaps (for streaming) and its own 3D Tiles
//!    tileset (`tiles/tile_NNNNN_tileset/`, [`crate::tiles::build_tileset`] over its blocks).
//! 3. [`merge`]: checks that every tile is done, belongs to this plan and that its files are
//!    intact (size and CRC-32), and writes `index.json`: per tile its id, quadtree key, bounds,
//!    blocks, buildings, triangles and files with their hashes, and the sums. When the tiles
//!    have tilesets, it also writes the root `tileset.json` that references them as external
//!    tilesets, grouped along the plan's quadtree (see [`merge`]).
//!
//! Supported input: a street layer (blocks are street faces) and Shapefile footprints (the
//! streaming reader, [`blockwalk_importers::shp::read_streaming`]); other footprint formats are
//! refused with the reason.

mod cut;
mod input;
mod merge;
pub mod pack;
mod plan;
mod tile;

pub use cut::cut_tiles;
pub use input::city_files;
pub use merge::{merge, IndexTile, TileIndex};
pub use plan::{layer_files, plan, write_plan, Plan, PlanBlock, PlanOptions, PlanTile};
pub use tile::{
    manifest_path, run_tile, tiles_dir, TileBlock, TileFile, TileManifest, TileOptions, TileRun,
    TileTileset,
};

use std::io::Read;
use std::path::{Path, PathBuf};

use blockwalk_importers::ImportError;
use serde::{Deserialize, Serialize};

use crate::blocks::BlockError;
use crate::city::build::BuildError;
use crate::city::export::ExportError;

/// The format tag of `plan.json`.
pub const PLAN_FORMAT: &str = "blockwalk-jobs-plan/2";
/// The format tag of a tile's manifest.
pub const TILE_FORMAT: &str = "blockwalk-jobs-tile/1";
/// The format tag of `index.json`.
pub const INDEX_FORMAT: &str = "blockwalk-jobs-index/1";
/// Footprints read, repaired and assigned at a time by [`plan`].
pub const STREAM_CHUNK: usize = 50_000;
/// Depth at which the quadtree cut stops (as the BqR-tree's default `max_depth`).
pub const MAX_DEPTH: u32 = 24;
/// Margin, metres, added around a tile's box when its footprints are read: a footprint's box
/// in the file's CRS is mapped to metres by its corners, which is exact for projected metric
/// CRS and within millimetres for a building-sized box in Web Mercator or lon/lat.
pub const READ_MARGIN_M: f64 = 1.0;

/// Why a job step failed. Every variant names the file (and the tile) it concerns.
#[derive(Debug, thiserror::Error)]
pub enum JobsError {
    /// A file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON file could not be parsed or written.
    #[error("{file}: {source}")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's error.
        #[source]
        source: serde_json::Error,
    },
    /// A file is not what it should be (another format, a bad value).
    #[error("{file}: {why}")]
    Format {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// An input layer could not be read.
    #[error("reading {file}: {source}")]
    Read {
        /// The layer's file.
        file: PathBuf,
        /// The importer's error.
        #[source]
        source: Box<ImportError>,
    },
    /// A layer could not be built into the city.
    #[error("building {file}: {source}")]
    Build {
        /// The layer's file.
        file: PathBuf,
        /// Why.
        #[source]
        source: BuildError,
    },
    /// Block detection failed.
    #[error("blocks of {file}: {source}")]
    Blocks {
        /// The street file.
        file: PathBuf,
        /// Why.
        #[source]
        source: BlockError,
    },
    /// The input cannot be processed in tiles.
    #[error("{file}: {why}")]
    Unsupported {
        /// The input.
        file: PathBuf,
        /// Why.
        why: String,
    },
    /// A tile index beyond the plan's tiles.
    #[error("{plan}: tile {tile} is out of range: the plan has {tiles} tiles (0..={last})", last = tiles.saturating_sub(1))]
    TileOutOfRange {
        /// The plan.
        plan: PathBuf,
        /// The tile asked for.
        tile: usize,
        /// Tiles in the plan.
        tiles: usize,
    },
    /// An input file is not the one the plan was made from (another city, or changed since).
    #[error("{plan} was made from another city: {file} {why}; make a new plan")]
    InputChanged {
        /// The plan.
        plan: PathBuf,
        /// The input file.
        file: PathBuf,
        /// What differs.
        why: String,
    },
    /// A tile has not finished (its manifest is missing).
    #[error("tile {tile} has not finished: {file} is missing (run `blockwalk jobs run {plan} --tile {tile}`)")]
    MissingTile {
        /// The plan.
        plan: PathBuf,
        /// The tile.
        tile: usize,
        /// The missing manifest.
        file: PathBuf,
    },
    /// A tile's output belongs to another plan.
    #[error("tile {tile}: {file} belongs to another plan (plan id {found}, this plan is {expected}); run the tile again")]
    OtherPlan {
        /// The tile.
        tile: usize,
        /// Its manifest.
        file: PathBuf,
        /// This plan's id.
        expected: String,
        /// The manifest's plan id.
        found: String,
    },
    /// A tile's output disagrees with the plan or its own manifest.
    #[error("tile {tile}: {file}: {why}")]
    TileMismatch {
        /// The tile.
        tile: usize,
        /// The file concerned.
        file: PathBuf,
        /// What disagrees.
        why: String,
    },
    /// The tile's `.glb` could not be written.
    #[error("tile {tile}: {source}")]
    Export {
        /// The tile.
        tile: usize,
        /// Why.
        #[source]
        source: ExportError,
    },
}

/// A number written as text in Rust's shortest round-trip form, read back bit for bit (JSON
/// numbers would go through `serde_json`'s fast float parser, which may be one ulp off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactF64(pub f64);

impl Serialize for ExactF64 {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{}", self.0))
    }
}

impl<'de> Deserialize<'de> for ExactF64 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse::<f64>()
            .map(ExactF64)
            .map_err(|_| serde::de::Error::custom(format!("{s:?} is not a number")))
    }
}

/// An input file's identity: path, size and CRC-32 of its bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileStamp {
    /// The file (absolute when it was given as an existing path).
    pub path: PathBuf,
    /// Size in bytes.
    pub bytes: u64,
    /// CRC-32 of the bytes, 8 hex digits.
    pub crc32: String,
}

impl FileStamp {
    /// The stamp of the file at `path`, read in 1 MiB pieces.
    ///
    /// # Errors
    /// [`JobsError::Io`].
    pub fn of(path: &Path) -> Result<Self, JobsError> {
        let io = |source| JobsError::Io {
            file: path.to_path_buf(),
            source,
        };
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut h = crc32fast::Hasher::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(FileStamp {
            path: std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            bytes,
            crc32: format!("{:08x}", h.finalize()),
        })
    }
}
