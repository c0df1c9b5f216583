//! The two references: no structure at all, and a flat list whose every block box is tested.

use super::{
    validate_bounds, BlockBounds, CityIndex, CullQuery, CullStats, IndexError, Sink, Structure,
};
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Containment, Frustum, ALL_PLANES};

/// Accepts every block without a test (the paper's "no tree", Pina, Serón and Cerezo, §5.1 Table 1).
#[derive(Clone, Debug)]
pub struct NoStructure {
    blocks: Vec<BlockBounds>,
}

impl NoStructure {
    /// Keeps the blocks.
    ///
    /// # Errors
    /// [`IndexError::BadBlock`] for a non-finite or empty block box.
    pub fn build(bounds: &[BlockBounds]) -> Result<Self, IndexError> {
        validate_bounds(Structure::None, bounds)?;
        Ok(Self {
            blocks: bounds.to_vec(),
        })
    }
    /// Nothing to check beyond the build's validation; present for symmetry.
    pub fn check_invariants(&self) {
        assert!(self.blocks.iter().all(|b| !b.aabb.is_empty()));
    }
}

impl CityIndex for NoStructure {
    fn structure(&self) -> Structure {
        Structure::None
    }
    /// Every block, in input order; `hidden_filter` is still asked about each (it is not a
    /// frustum test).
    fn cull(
        &self,
        _query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut sink = Sink {
            keep: hidden_filter,
            out,
            stats: CullStats::default(),
        };
        for b in &self.blocks {
            if sink.keep(&b.aabb) {
                sink.accept(b);
            }
        }
        sink.stats
    }
    fn len(&self) -> usize {
        self.blocks.len()
    }
}

/// Tests every block's box against the frustum, in input order (no hierarchy, no order).
#[derive(Clone, Debug)]
pub struct FlatList {
    blocks: Vec<BlockBounds>,
}

impl FlatList {
    /// Keeps the blocks.
    ///
    /// # Errors
    /// [`IndexError::BadBlock`] for a non-finite or empty block box.
    pub fn build(bounds: &[BlockBounds]) -> Result<Self, IndexError> {
        validate_bounds(Structure::Flat, bounds)?;
        Ok(Self {
            blocks: bounds.to_vec(),
        })
    }
    /// Nothing to check beyond the build's validation; present for symmetry.
    pub fn check_invariants(&self) {
        assert!(self.blocks.iter().all(|b| !b.aabb.is_empty()));
    }
    fn run(
        &self,
        frustum: &Frustum,
        keep: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut sink = Sink {
            keep,
            out,
            stats: CullStats::default(),
        };
        for b in &self.blocks {
            sink.stats.nodes_visited += 1;
            let mut m = ALL_PLANES;
            if frustum.test_aabb_masked(&b.aabb, &mut m, &mut sink.stats.plane_tests)
                != Containment::Outside
                && sink.keep(&b.aabb)
            {
                sink.accept(b);
            }
        }
        sink.stats
    }
}

impl CityIndex for FlatList {
    fn structure(&self) -> Structure {
        Structure::Flat
    }
    fn cull(
        &self,
        query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        self.run(query.frustum, hidden_filter, out)
    }
    fn len(&self) -> usize {
        self.blocks.len()
    }
}
