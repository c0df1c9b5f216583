//! The same queries through the `rstar` crate: a bulk-loaded R*-tree of block boxes, traversed
//! with a [`SelectionFunction`] that tests envelopes against the frustum.
//!
//! `rstar` does not expose a traversal order, so this structure does not visit front to back,
//! and it cannot pass plane masks from parent to child (each envelope is tested against all six
//! planes).

use super::{validate_bounds, BlockBounds, CityIndex, CullQuery, CullStats, IndexError, Structure};
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Containment, Frustum, ALL_PLANES};
use glam::DVec3;
use rstar::{RTree, RTreeObject, SelectionFunction, AABB};
use std::cell::{Cell, RefCell};

#[derive(Clone, Debug)]
struct Entry {
    slot: u32,
    env: AABB<[f64; 3]>,
}

impl RTreeObject for Entry {
    type Envelope = AABB<[f64; 3]>;
    fn envelope(&self) -> Self::Envelope {
        self.env
    }
}

fn to_aabb(e: &AABB<[f64; 3]>) -> Aabb3 {
    Aabb3::new(DVec3::from_array(e.lower()), DVec3::from_array(e.upper()))
}

/// A bulk-loaded `rstar::RTree` of block boxes.
#[derive(Clone, Debug)]
pub struct RstarIndex {
    tree: RTree<Entry>,
    blocks: Vec<BlockBounds>,
}

impl RstarIndex {
    /// Bulk-loads the tree (OMT packing, `rstar`'s default parameters).
    ///
    /// # Errors
    /// [`IndexError::BadBlock`] for a non-finite or empty block box.
    pub fn build(bounds: &[BlockBounds]) -> Result<Self, IndexError> {
        validate_bounds(Structure::Rstar, bounds)?;
        let entries = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| Entry {
                slot: i as u32,
                env: AABB::from_corners(b.aabb.min.to_array(), b.aabb.max.to_array()),
            })
            .collect();
        Ok(Self {
            tree: RTree::bulk_load(entries),
            blocks: bounds.to_vec(),
        })
    }

    /// Every block is in the tree once.
    ///
    /// # Panics
    /// When a block is missing or duplicated.
    pub fn check_invariants(&self) {
        assert_eq!(self.tree.size(), self.blocks.len(), "tree size");
        let mut seen = vec![false; self.blocks.len()];
        for e in self.tree.iter() {
            assert!(!seen[e.slot as usize], "block slot {} twice", e.slot);
            seen[e.slot as usize] = true;
        }
    }

    fn run(
        &self,
        frustum: &Frustum,
        keep: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let sel = FrustumSelection {
            frustum,
            keep: RefCell::new(keep),
            visited: Cell::new(0),
            tests: Cell::new(0),
        };
        let mut stats = CullStats::default();
        for e in self.tree.locate_with_selection_function(&sel) {
            let b = &self.blocks[e.slot as usize];
            out.push(b.id);
            stats.blocks_accepted += 1;
            stats.triangles_accepted += u64::from(b.triangles);
        }
        stats.nodes_visited = sel.visited.get();
        stats.plane_tests = sel.tests.get();
        stats
    }
}

type KeepFn<'k> = &'k mut dyn FnMut(&Aabb3) -> bool;

struct FrustumSelection<'f, 'k> {
    frustum: &'f Frustum,
    keep: RefCell<Option<KeepFn<'k>>>,
    visited: Cell<u64>,
    tests: Cell<u64>,
}

impl FrustumSelection<'_, '_> {
    fn test(&self, b: &Aabb3) -> bool {
        self.visited.set(self.visited.get() + 1);
        let mut t = 0;
        let r = self
            .frustum
            .test_aabb_masked(b, &mut ALL_PLANES.clone(), &mut t);
        self.tests.set(self.tests.get() + t);
        if r == Containment::Outside {
            return false;
        }
        match self.keep.borrow_mut().as_mut() {
            Some(k) => k(b),
            None => true,
        }
    }
}

impl SelectionFunction<Entry> for &FrustumSelection<'_, '_> {
    fn should_unpack_parent(&self, envelope: &AABB<[f64; 3]>) -> bool {
        self.test(&to_aabb(envelope))
    }
    fn should_unpack_leaf(&self, leaf: &Entry) -> bool {
        self.test(&to_aabb(&leaf.env))
    }
}

impl CityIndex for RstarIndex {
    fn structure(&self) -> Structure {
        Structure::Rstar
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
