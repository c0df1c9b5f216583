//! Streets and urban blocks (seed 003 §3): "any portion of terrain completely surrounded by
//! streets".
//!
//! Build a planar street graph ([`noding`]: splitting, snapping), extract its bounded faces by the
//! counter-clockwise walk ([`faces`]), or infer blocks from parcels or footprints when there is no
//! street layer ([`infer`]), then assign every building to one block ([`assign`]); [`detect`] does
//! it all. [`export`] writes GeoJSON in the input's own coordinates and an SVG/PNG map.

pub mod assign;
pub mod detect;
pub mod export;
pub mod faces;
pub mod infer;
pub mod noding;
pub mod predicates;
pub mod types;

pub use detect::{detect, detect_geometry, BlockError, BlockOptions};
pub use types::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
