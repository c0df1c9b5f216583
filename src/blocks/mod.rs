//! Streets and urban blocks (seed 003 §3): "any portion of terrain completely surrounded by
//! streets".
//!
//! Build a planar street graph (noding, snapping), extract its bounded faces, or infer blocks from
//! parcels or footprints when there is no street layer, then assign every building to one block.

pub mod faces;
pub mod noding;
pub mod predicates;
pub mod types;

pub use types::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
