//! Spatial structures over blocks behind one interface (seed 003 §4).

use crate::blocks::BlockId;
use crate::geom::{Aabb3, Frustum};
use serde::Serialize;

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

/// A spatial structure that returns the blocks to draw for a view.
pub trait CityIndex {
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
}
