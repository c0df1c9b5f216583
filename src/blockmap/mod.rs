//! BlockMaps: the far-field representation of Cignoni et al., (Cignoni et al. 2007, §3–5) in the revised
//! layout of Di Benedetto, (Di Benedetto 2011, ch. 4), built on the CPU from the extruded prisms, with
//! a reference ray caster equal to the GPU's and a measured error bound.
//!
//! - [`layout`]: [`BlockMap`], the RGBA8 `(2K + 256) × K` texture (Di Benedetto, §4.2.1) plus
//!   two `K × K` sections of footprint edges (one or two half-planes per boundary texel,
//!   blockwalk's addition), its box, PNG + JSON storage, and the optional 2007 distance map (Cignoni et al.
//!   §3.1–3.2).
//! - [`source`]: what maps are built from, the buildings in the local frame ([`Source`]).
//! - [`build`]: construction from the prisms (Cignoni et al., §3.3, Di Benedetto, §4.3.2): top-down
//!   orthographic sampling through the oracle's rasteriser, exposed texels, unfolded wall
//!   columns, slices.
//! - [`error`]: sampled symmetric Hausdorff distance (f64) and the declared
//!   `ε = max(½ voxel diagonal, measured)`; thin features, raised parts and bridges.
//! - [`cast`]: the reference caster (2D Amanatides–Woo walk, Di Benedetto, §4.2.2) in f32 as the
//!   shader runs it, with an f64 twin that names ties; optional distance-map leaps.
//! - [`tree`]: maps for the BqR-tree's nodes (whole blocks per node).
//! - [`children`]: the option of building inner nodes' maps from their children's maps
//!   (conservative max filter), with a derived and measured ε.
//! - [`select`]: which nodes a frame draws as maps and which blocks as meshes (Cignoni et al., §4–5).
//! - [`compare`]: ray-cast image against the oracle's mesh image: coverage error, the projected
//!   bound at silhouettes, 3D point error, colour PSNR.
//! - [`diagnose`]: every coverage-mismatched pixel of a hybrid frame classified by cause.
//! - [`image`]: images of maps as the GPU draws them ([`cast_image`]), and the CPU fallback of
//!   hybrid frames ([`CpuHybridRenderer`]: meshes near, maps far, composited by depth).
//! - [`colors`]: the one definition of colours and light used by all of the above.
//! - [`ao`]: optional ambient occlusion, horizon-based over the height map (Di Benedetto, §4.2.1).

pub mod ao;
pub mod build;
pub mod cast;
pub mod children;
pub mod colors;
pub mod compare;
pub mod diagnose;
pub mod error;
pub mod image;
pub mod layout;
pub mod select;
pub mod source;
pub mod tree;

pub use build::{build_map, BuildOptions, BuildStats, Parents, ResampleStats};
pub use cast::{cast_f32, cast_f64, Cast, CastOptions, Face, Hit, TexRay};
pub use children::build_from_children;
pub use error::{measure, ErrorReport, ThinFeature, ThinKind};
pub use image::{cast_image, CpuHybridRenderer, FrameRays, MapImage, MapXform};
pub use layout::{BlockMap, BlockMapMeta, Edge};
pub use select::{
    projected_error_px, SelectError, SelectNode, SelectOptions, SelectStats, Selection, Selector,
};
pub use source::{Source, SourceBuilding};
pub use tree::{
    build_city_maps, build_city_maps_from, build_tree, is_maps_entry, skeleton_tree, CityMaps,
    CityMapsOptions, MapTree, NodeMap, Stop, TreeOptions, TreeViolation,
};

use std::path::PathBuf;

/// What went wrong with a BlockMap.
#[derive(Debug, thiserror::Error)]
pub enum BlockMapError {
    /// A parameter is out of range.
    #[error("blockmap: {0}")]
    BadParameter(String),
    /// A file could not be read or written.
    #[error("{path}: {what}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What happened.
        what: String,
    },
    /// A file holds something that is not a valid BlockMap.
    #[error("{path}: not a valid BlockMap: {what}")]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// Building the map of a quadtree node failed.
    #[error("blockmap of quadtree node {key}: {what}")]
    Node {
        /// The node's key.
        key: u64,
        /// What happened.
        what: String,
    },
}
