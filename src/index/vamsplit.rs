//! The VAMSplit R-tree (White & Jain 1996), the structure the BqR-tree is compared with in
//! Pina, Serón and Cerezo, §5.1.
//!
//! A static top-down build: a node's items are split recursively in two on the dimension of
//! maximum variance of the block centres, at the multiple of the child subtree's capacity
//! closest to the median, so that every subtree but the last is filled to capacity. Nodes hold
//! minimum bounding boxes (3D). Stored flat in depth-first preorder, a subtree's blocks
//! contiguous.

use super::bqr::box_distance_2;
use super::{
    validate_bounds, BlockBounds, CityIndex, CullQuery, CullStats, IndexError, Sink, Structure,
};
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Containment, PlaneMask, ALL_PLANES};
use glam::DVec3;

const NAME: Structure = Structure::Vamsplit;

/// Build parameters of a [`VamSplitTree`].
#[derive(Clone, Debug, PartialEq)]
pub struct VamSplitParams {
    /// Most children of an inner node and most blocks of a leaf (≥ 2).
    pub node_capacity: usize,
}

impl Default for VamSplitParams {
    fn default() -> Self {
        Self { node_capacity: 8 }
    }
}

#[derive(Clone, Debug)]
struct Node {
    aabb: Aabb3,
    /// Inner: range in `child_list`; leaf: empty.
    child_start: u32,
    child_end: u32,
    block_start: u32,
    block_end: u32,
    leaf: bool,
}

/// The VAMSplit R-tree (White & Jain 1996).
#[derive(Clone, Debug)]
pub struct VamSplitTree {
    nodes: Vec<Node>,
    child_list: Vec<u32>,
    blocks: Vec<BlockBounds>,
    capacity: usize,
}

struct Builder<'a> {
    input: &'a [BlockBounds],
    cap: usize,
    nodes: Vec<Node>,
    child_list: Vec<u32>,
    order: Vec<u32>,
}

fn key(b: &BlockBounds) -> DVec3 {
    DVec3::new(b.center.x, b.center.y, b.aabb.center().z)
}

impl Builder<'_> {
    fn build(&mut self, items: &mut [u32]) -> u32 {
        let idx = self.nodes.len() as u32;
        let block_start = self.order.len() as u32;
        self.nodes.push(Node {
            aabb: Aabb3::EMPTY,
            child_start: 0,
            child_end: 0,
            block_start,
            block_end: 0,
            leaf: true,
        });
        if items.len() <= self.cap {
            self.order.extend_from_slice(items);
            let aabb = items
                .iter()
                .fold(Aabb3::EMPTY, |a, &i| a.union(self.input[i as usize].aabb));
            let n = &mut self.nodes[idx as usize];
            n.aabb = aabb;
            n.block_end = self.order.len() as u32;
            return idx;
        }
        // Capacity of a child subtree: the smallest power cap^h (h ≥ 1) with cap^(h+1) ≥ n.
        let child_cap = child_capacity(self.cap, self.cap, items.len());
        let mut groups = Vec::new();
        vam_split(self.input, items, child_cap, 0, &mut groups);
        let mut children = Vec::with_capacity(groups.len());
        for (a, b) in groups {
            children.push(self.build(&mut items[a..b]));
        }
        let aabb = children
            .iter()
            .fold(Aabb3::EMPTY, |a, &c| a.union(self.nodes[c as usize].aabb));
        let child_start = self.child_list.len() as u32;
        self.child_list.extend_from_slice(&children);
        let n = &mut self.nodes[idx as usize];
        n.aabb = aabb;
        n.leaf = false;
        n.child_start = child_start;
        n.child_end = self.child_list.len() as u32;
        n.block_end = self.order.len() as u32;
        idx
    }
}

/// Capacity of one child subtree of a node over `n` items: the smallest
/// `leaf_cap · node_cap^h` (h ≥ 0) whose `node_cap` copies hold `n` (with `leaf_cap = node_cap`,
/// the smallest power `cap^h`, h ≥ 1, with `cap^(h+1) ≥ n`). Shared by the block tree and the
/// scene graph ([`super::SceneGraphTree`]).
pub(super) fn child_capacity(leaf_cap: usize, node_cap: usize, n: usize) -> usize {
    let mut c = leaf_cap;
    while c.saturating_mul(node_cap) < n {
        c = c.saturating_mul(node_cap);
    }
    c
}

/// White & Jain's VAMSplit: `items` (indices into `input`, at `offset` in the node's slice) cut
/// recursively in two on the dimension of largest variance of the item centres, at the multiple
/// of `cap` nearest the median, until every group holds at most `cap`; pushes the groups' ranges
/// to `out`. Shared by the block tree and the scene graph over buildings
/// ([`super::SceneGraphTree`]).
pub(super) fn vam_split(
    input: &[BlockBounds],
    items: &mut [u32],
    cap: usize,
    offset: usize,
    out: &mut Vec<(usize, usize)>,
) {
    let n = items.len();
    if n <= cap {
        out.push((offset, offset + n));
        return;
    }
    // Dimension of maximum variance of the centres.
    let mut mean = DVec3::ZERO;
    for &i in items.iter() {
        mean += key(&input[i as usize]);
    }
    mean /= n as f64;
    let mut var = DVec3::ZERO;
    for &i in items.iter() {
        let d = key(&input[i as usize]) - mean;
        var += d * d;
    }
    let dim = if var.x >= var.y && var.x >= var.z {
        0
    } else if var.y >= var.z {
        1
    } else {
        2
    };
    // Split position: the multiple of the subtree capacity closest to the median.
    let max_k = (n - 1) / cap * cap;
    let k = (((n as f64 / 2.0) / cap as f64).round() as usize * cap).clamp(cap, max_k);
    items.select_nth_unstable_by(k, |&a, &b| {
        key(&input[a as usize])[dim].total_cmp(&key(&input[b as usize])[dim])
    });
    let (left, right) = items.split_at_mut(k);
    vam_split(input, left, cap, offset, out);
    vam_split(input, right, cap, offset + k, out);
}

impl VamSplitTree {
    /// Builds the tree over `bounds`.
    ///
    /// # Errors
    /// [`IndexError::BadParam`] for `node_capacity < 2`, [`IndexError::BadBlock`] for a
    /// non-finite or empty block box.
    pub fn build(bounds: &[BlockBounds], params: &VamSplitParams) -> Result<Self, IndexError> {
        if params.node_capacity < 2 {
            return Err(IndexError::BadParam {
                structure: NAME,
                name: "node_capacity",
                value: params.node_capacity.to_string(),
                reason: "must be at least 2",
            });
        }
        validate_bounds(NAME, bounds)?;
        let mut b = Builder {
            input: bounds,
            cap: params.node_capacity,
            nodes: Vec::new(),
            child_list: Vec::new(),
            order: Vec::with_capacity(bounds.len()),
        };
        if !bounds.is_empty() {
            let mut items: Vec<u32> = (0..bounds.len() as u32).collect();
            b.build(&mut items);
        }
        Ok(Self {
            blocks: b
                .order
                .iter()
                .map(|&i| bounds[i as usize].clone())
                .collect(),
            nodes: b.nodes,
            child_list: b.child_list,
            capacity: params.node_capacity,
        })
    }

    /// Height of the tree (a lone leaf has height 0; 0 for an empty tree).
    pub fn height(&self) -> usize {
        let mut h = 0;
        let mut n = 0usize;
        while let Some(nd) = self.nodes.get(n) {
            if nd.leaf {
                break;
            }
            h += 1;
            n = self.child_list[nd.child_start as usize] as usize;
        }
        h
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.leaf).count()
    }

    /// Checks the invariants: capacities, every block in one leaf, boxes holding their
    /// children, contiguous block ranges.
    ///
    /// # Panics
    /// When an invariant is broken.
    pub fn check_invariants(&self) {
        let mut seen = vec![false; self.blocks.len()];
        let mut stack = Vec::new();
        if !self.nodes.is_empty() {
            stack.push(0usize);
        }
        let mut visited = 0;
        while let Some(i) = stack.pop() {
            visited += 1;
            let n = &self.nodes[i];
            if n.leaf {
                let count = (n.block_end - n.block_start) as usize;
                assert!(
                    (1..=self.capacity).contains(&count),
                    "leaf {i} holds {count}"
                );
                for k in n.block_start..n.block_end {
                    let b = &self.blocks[k as usize];
                    assert!(!seen[k as usize], "block slot {k} twice");
                    seen[k as usize] = true;
                    assert!(
                        n.aabb.contains_point(b.aabb.min) && n.aabb.contains_point(b.aabb.max),
                        "leaf {i} box misses block {:?}",
                        b.id
                    );
                }
            } else {
                let kids = &self.child_list[n.child_start as usize..n.child_end as usize];
                assert!(
                    (2..=self.capacity).contains(&kids.len()),
                    "node {i} has {} children",
                    kids.len()
                );
                let mut next = n.block_start;
                for &c in kids {
                    let cn = &self.nodes[c as usize];
                    assert!(c as usize > i, "children after parent");
                    assert_eq!(cn.block_start, next, "node {i}: block ranges");
                    next = cn.block_end;
                    assert!(
                        n.aabb.contains_point(cn.aabb.min) && n.aabb.contains_point(cn.aabb.max),
                        "node {i} box misses child {c}"
                    );
                    stack.push(c as usize);
                }
                assert_eq!(next, n.block_end, "node {i}: block range");
            }
        }
        assert_eq!(visited, self.nodes.len(), "unreachable nodes");
        assert!(seen.iter().all(|&s| s), "a block is in no leaf");
    }

    fn run(
        &self,
        query: &CullQuery<'_>,
        keep: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut sink = Sink {
            keep,
            out,
            stats: CullStats::default(),
        };
        if !self.nodes.is_empty() {
            let mut scratch = Vec::with_capacity(64);
            self.visit(0, ALL_PLANES, query, &mut sink, &mut scratch);
        }
        sink.stats
    }

    fn visit(
        &self,
        i: usize,
        mask: PlaneMask,
        q: &CullQuery<'_>,
        sink: &mut Sink<'_, '_>,
        scratch: &mut Vec<(f64, u32)>,
    ) {
        let n = &self.nodes[i];
        sink.stats.nodes_visited += 1;
        let mut m = mask;
        let res = if m == 0 {
            Containment::Inside
        } else {
            q.frustum
                .test_aabb_masked(&n.aabb, &mut m, &mut sink.stats.plane_tests)
        };
        if res == Containment::Outside || !sink.keep(&n.aabb) {
            return;
        }
        let blocks = &self.blocks[n.block_start as usize..n.block_end as usize];
        if res == Containment::Inside && sink.keep.is_none() {
            for b in blocks {
                sink.accept(b);
            }
            return;
        }
        if n.leaf {
            // Leaf entries are block boxes, tested one by one; nearest first.
            let base = scratch.len();
            for (k, b) in blocks.iter().enumerate() {
                scratch.push((box_distance_2(&b.aabb, q.eye), k as u32));
            }
            scratch[base..].sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            for j in base..scratch.len() {
                let b = &blocks[scratch[j].1 as usize];
                sink.stats.nodes_visited += 1;
                let mut bm = m;
                let r = if bm == 0 {
                    Containment::Inside
                } else {
                    q.frustum
                        .test_aabb_masked(&b.aabb, &mut bm, &mut sink.stats.plane_tests)
                };
                if r != Containment::Outside && sink.keep(&b.aabb) {
                    sink.accept(b);
                }
            }
            scratch.truncate(base);
            return;
        }
        let base = scratch.len();
        for &c in &self.child_list[n.child_start as usize..n.child_end as usize] {
            scratch.push((box_distance_2(&self.nodes[c as usize].aabb, q.eye), c));
        }
        scratch[base..].sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let end = scratch.len();
        for j in base..end {
            let c = scratch[j].1;
            self.visit(c as usize, m, q, sink, scratch);
        }
        scratch.truncate(base);
    }
}

impl CityIndex for VamSplitTree {
    fn structure(&self) -> Structure {
        NAME
    }
    fn cull(
        &self,
        query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        self.run(query, hidden_filter, out)
    }
    fn len(&self) -> usize {
        self.blocks.len()
    }
    fn node_count(&self) -> usize {
        self.nodes.len()
    }
}
