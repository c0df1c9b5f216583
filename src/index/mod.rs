//! Spatial structures over blocks behind one interface (seed 003 §4).
//!
//! - [`block_bounds`]: per block, its 3D box, outline centre and triangle count.
//! - [`BqrTree`]: the BqR-tree (seed 003 §4), adaptive quadtree of bounding spheres ending in
//!   box∩sphere leaves; also holds small mobile objects.
//! - [`VamSplitTree`]: the VAMSplit R-tree (White & Jain 1996), the paper's comparison.
//! - [`FlatList`], [`NoStructure`]: test every block, or none.
//! - [`RstarIndex`]: the same queries through the `rstar` crate.
//! - [`synthetic`]: seeded synthetic block grids for benches and tests.
//! - [`bench`]: the `cull-bench` core (random views, timings, false culls against brute force).
//!
//! Every structure is immutable after its build and `Send + Sync`; per-frame state (temporal
//! coherence) is owned by the caller.

pub mod bench;
mod bounds;
mod bqr;
mod flat;
mod rstar_index;
pub mod synthetic;
mod vamsplit;

pub use bounds::{block_bounds, extruded_triangles};
pub use bqr::{BqrNodeKind, BqrNodeView, BqrParams, BqrTree, ObjectId};
pub use flat::{FlatList, NoStructure};
pub use rstar_index::RstarIndex;
pub use vamsplit::{VamSplitParams, VamSplitTree};

use crate::blocks::BlockId;
use crate::geom::{Aabb3, Frustum};
use glam::DVec3;
use serde::Serialize;

/// Bad parameters or input for an index build.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IndexError {
    /// A parameter is out of its range.
    #[error("{structure}: parameter `{name}` = {value} is invalid: {reason}")]
    BadParam {
        /// Structure being built.
        structure: &'static str,
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: String,
        /// What is expected.
        reason: &'static str,
    },
    /// A mobile object's box is empty or not finite.
    #[error("{structure}: object {id} has a non-finite or empty box")]
    BadObject {
        /// Structure.
        structure: &'static str,
        /// The object's id.
        id: u32,
    },
    /// An object id inserted twice.
    #[error("{structure}: object {id} is already in the index")]
    DuplicateObject {
        /// Structure.
        structure: &'static str,
        /// The object's id.
        id: u32,
    },
    /// An object id not in the index.
    #[error("{structure}: object {id} is not in the index")]
    UnknownObject {
        /// Structure.
        structure: &'static str,
        /// The object's id.
        id: u32,
    },
    /// A block's bounds hold NaN or infinite coordinates, or an empty box.
    #[error("{structure}: block {index} (id {id}) has a non-finite or empty box or centre")]
    BadBlock {
        /// Structure being built.
        structure: &'static str,
        /// Position in the input slice.
        index: usize,
        /// The block's id.
        id: u32,
    },
}

/// Checks what every structure needs of its input: finite, non-empty boxes and centres.
pub(crate) fn validate_bounds(
    structure: &'static str,
    bounds: &[BlockBounds],
) -> Result<(), IndexError> {
    for (index, b) in bounds.iter().enumerate() {
        let finite = b.aabb.min.is_finite() && b.aabb.max.is_finite() && b.center.is_finite();
        if !finite || b.aabb.is_empty() {
            return Err(IndexError::BadBlock {
                structure,
                index,
                id: b.id.0,
            });
        }
    }
    Ok(())
}

/// A view query: the frustum (local frame) and the eye, for front-to-back order.
#[derive(Clone, Copy, Debug)]
pub struct CullQuery<'a> {
    /// The view frustum, local frame.
    pub frustum: &'a Frustum,
    /// Eye position, local frame: children are visited nearest first.
    pub eye: DVec3,
}

impl<'a> CullQuery<'a> {
    /// A query whose eye is the frustum's apex (or the centre of its corners for a degenerate
    /// frustum).
    pub fn new(frustum: &'a Frustum) -> Self {
        let eye = frustum
            .apex()
            .or_else(|| {
                frustum
                    .corners()
                    .map(|c| c.iter().copied().sum::<DVec3>() / 8.0)
            })
            .unwrap_or(DVec3::ZERO);
        Self { frustum, eye }
    }
    /// A query with an explicit eye.
    pub fn with_eye(frustum: &'a Frustum, eye: DVec3) -> Self {
        Self { frustum, eye }
    }
}

/// What a structure indexes for each block: its 3D bounds in the local frame (f64) and how many
/// triangles drawing it costs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlockBounds {
    /// The block.
    pub id: BlockId,
    /// Box around all of the block's geometry (footprint × [0, max height]), local frame.
    pub aabb: Aabb3,
    /// Geometric centre of the block's outline (x, y), local frame.
    pub center: glam::DVec2,
    /// Triangles of the block's meshes.
    pub triangles: u32,
}

/// Per-query work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CullStats {
    /// Nodes whose volume was tested or accepted.
    pub nodes_visited: u64,
    /// Plane tests done.
    pub plane_tests: u64,
    /// Blocks pushed to the output.
    pub blocks_accepted: u64,
    /// Triangles of the accepted blocks.
    pub triangles_accepted: u64,
}

impl std::ops::AddAssign for CullStats {
    fn add_assign(&mut self, o: Self) {
        self.nodes_visited += o.nodes_visited;
        self.plane_tests += o.plane_tests;
        self.blocks_accepted += o.blocks_accepted;
        self.triangles_accepted += o.triangles_accepted;
    }
}

/// A spatial structure that returns the blocks to draw for a view.
///
/// Block ids in the output are those of the [`BlockBounds`] the structure was built from.
pub trait CityIndex: Send + Sync {
    /// Short name (`bqr`, `vamsplit`, `flat`, `none`, `rstar`).
    fn name(&self) -> &'static str;

    /// Pushes every block that may intersect `frustum` to `out` (never drops one that does).
    fn cull(&self, frustum: &Frustum, out: &mut Vec<BlockId>) -> CullStats {
        self.cull_filtered(frustum, &mut |_| true, out)
    }

    /// As [`CityIndex::cull`], front to back when the structure can, and additionally asking
    /// `keep(volume)` for every node and block that survives the frustum test: a node whose
    /// conservative box gets `false` (proven hidden, e.g. by the cull map) is dropped with its
    /// subtree.
    fn cull_filtered(
        &self,
        frustum: &Frustum,
        keep: &mut dyn FnMut(&Aabb3) -> bool,
        out: &mut Vec<BlockId>,
    ) -> CullStats;

    /// As [`CityIndex::cull_filtered`] with an explicit eye for the front-to-back order
    /// (nearest child first). The default ignores the eye and uses the frustum's apex.
    fn cull_query(
        &self,
        query: &CullQuery<'_>,
        keep: &mut dyn FnMut(&Aabb3) -> bool,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        self.cull_filtered(query.frustum, keep, out)
    }

    /// Number of blocks indexed.
    fn len(&self) -> usize;

    /// True when no block is indexed.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of nodes (0 for flat structures).
    fn node_count(&self) -> usize {
        0
    }
}

/// Builds one structure by name (`bqr`, `vamsplit`, `flat`, `none`, `rstar`) with default
/// parameters.
///
/// # Errors
/// [`IndexError::BadParam`] for an unknown name, and the structure's own build errors.
pub fn build_by_name(name: &str, bounds: &[BlockBounds]) -> Result<Box<dyn CityIndex>, IndexError> {
    Ok(match name {
        "bqr" => Box::new(BqrTree::build(bounds, &BqrParams::default())?),
        "vamsplit" => Box::new(VamSplitTree::build(bounds, &VamSplitParams::default())?),
        "flat" => Box::new(FlatList::build(bounds)?),
        "none" => Box::new(NoStructure::build(bounds)?),
        "rstar" => Box::new(RstarIndex::build(bounds)?),
        other => {
            return Err(IndexError::BadParam {
                structure: "index",
                name: "structure",
                value: other.to_string(),
                reason: "expected one of bqr, vamsplit, flat, none, rstar",
            })
        }
    })
}

/// The structure names [`build_by_name`] knows.
pub const STRUCTURES: [&str; 5] = ["bqr", "vamsplit", "flat", "none", "rstar"];

/// Collects accepted blocks and counts; shared by the traversals.
pub(crate) struct Sink<'k, 'o> {
    pub keep: Option<&'k mut dyn FnMut(&Aabb3) -> bool>,
    pub out: &'o mut Vec<BlockId>,
    pub stats: CullStats,
}

impl Sink<'_, '_> {
    #[inline]
    pub fn keep(&mut self, b: &Aabb3) -> bool {
        match &mut self.keep {
            Some(k) => k(b),
            None => true,
        }
    }
    #[inline]
    pub fn accept(&mut self, b: &BlockBounds) {
        self.out.push(b.id);
        self.stats.blocks_accepted += 1;
        self.stats.triangles_accepted += u64::from(b.triangles);
    }
}
