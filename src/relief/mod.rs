//! Multi-level relief impostors, the second far field (Andujar, Brunet, Chica and Navazo,
//! *Visualization of Large-Scale Urban Models through Multi-Level Relief Impostors*, Computer
//! Graphics Forum 29(8), 2010).
//!
//! - [`tree`]: the object-space quaternary tree over building groups (§3, §4.1): buildings
//!   closer than a gap merged first (and, for the far field, the buildings of one block), each
//!   group sent to a child by its barycentre so that no group is ever cut, the overlap ratio δ
//!   of formula (1) per level, and formulas (3)–(9) evaluated against the built tree.
//! - [`map`]: the `M × M` colour + depth maps, captured orthographically from the meshes.
//! - [`surfels`]: the façade vote that chooses the oblique maps (§4.2).
//! - [`build`]: every node's zenithal and oblique maps ([`ReliefField`]), `M` from formula (9).
//! - [`cast`]: the ray–height-field walk over the zenithal map's max pyramid, which cannot
//!   miss a hit, in `f32` (the GPU's) and `f64`.
//! - [`node`]: a node's maps and the colouring of a hit (zenithal on roofs, the core-set
//!   obliques with the depth-aware projective test on walls, §5.2–5.3).
//! - [`error`]: the coverage error of each node against its meshes, measured at build.
//! - [`image`]: CPU images as the GPU draws them, and the CPU hybrid renderer.

pub mod build;
pub mod cast;
pub mod error;
pub mod image;
pub mod map;
pub mod node;
pub mod surfels;
pub mod tree;

pub use build::{
    build_field, LevelReport, ReliefError, ReliefField, ReliefOptions, ReliefReport, ReliefSummary,
    Stop,
};
pub use image::{cast_image, frame_nodes, CpuReliefRenderer, FrameNode, ReliefImage};
pub use map::{MapFrame, MapKind, ReliefMap};
pub use node::{NodeFrameInfo, NodeMaps};
pub use tree::{Formulas, LevelStats, ReliefNode, ReliefTree, TreeError, TreeParams, TreeReport};
