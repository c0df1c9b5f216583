//! The BqR-tree (Pina, Serón and Cerezo, §4): an adaptive quadtree over the city's bounding rectangle whose
//! nodes hold bounding spheres and whose leaves hold one block each with a box∩sphere volume.
//!
//! # Layout
//! Nodes live in one `Vec` in depth-first preorder, so a node's subtree is the contiguous node
//! range `[i, subtree_end)` and its blocks the contiguous range `block_range` of
//! [`BqrTree::blocks`]: a subtree found fully inside the frustum is appended in one go. The
//! plain frustum cull (no hidden-volume filter, no temporal coherence, no mobile object) runs
//! on a second layout of the same tree laid out for it (`bqr_layout`: one cache line per node,
//! chains collapsed, leaf buckets); it accepts the same blocks.
//!
//! # Linear quadtree key
//! Every node carries a key: the root is `1`, and the child in quadrant `q` of a node with key
//! `k` has key `4k + q`, with `q = east + 2·north` (0 south-west, 1 south-east, 2 north-west,
//! 3 north-east; `east` when the centre's x ≥ the quadrant's middle, `north` likewise for y).
//! The leading 1 bit marks the depth, so keys of different depths never collide (the paper
//! stores a numeric key because empty quadrants get no node).
//!
//! # Mobile objects
//! Small dynamic objects (cars, pedestrians) are kept in the deepest existing node whose
//! quadrant holds their whole footprint (the root when none does). Inserting one grows the
//! spheres and boxes of its node and every ancestor; removing or moving one never shrinks them
//! (still conservative) until [`BqrTree::refit`]. They have their own id space ([`ObjectId`])
//! and are reported in a separate output by [`BqrTree::cull_with_objects`]; the
//! [`CityIndex`] methods report blocks only.

use super::bqr_layout::{HotLayout, SourceNode};
use super::{
    validate_bounds, BlockBounds, CityIndex, CullQuery, CullStats, IndexError, Sink, Structure,
};
use crate::blocks::BlockId;
use crate::geom::{
    Aabb3, BoundingSphere, CoherenceState, Containment, Frustum, PlaneMask, ALL_PLANES,
};
use glam::{DVec2, DVec3};

const NONE: u32 = u32::MAX;
const NAME: Structure = Structure::Bqr;

/// Build parameters of a [`BqrTree`].
#[derive(Clone, Debug, PartialEq)]
pub struct BqrParams {
    /// Depth at which splitting stops even when a quadrant still holds several blocks (blocks
    /// whose centres coincide, or nearly: the quadrant would never separate them). Such a
    /// quadrant becomes a multi-block leaf. 1..=30 (the key needs 2 bits per level).
    pub max_depth: u32,
}

impl Default for BqrParams {
    fn default() -> Self {
        Self { max_depth: 24 }
    }
}

/// A mobile object's id (its own id space, separate from [`BlockId`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub struct ObjectId(pub u32);

/// Inner node or leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BqrNodeKind {
    /// Holds children; volume = bounding sphere.
    Inner,
    /// Holds one block (or several at the depth limit); volume = box ∩ sphere.
    Leaf,
}

#[derive(Clone, Debug)]
struct Node {
    key: u64,
    depth: u32,
    kind: BqrNodeKind,
    parent: u32,
    /// The quadrant (x, y), used to place objects and check invariants.
    quad_min: DVec2,
    quad_max: DVec2,
    /// Encloses every block and object of the subtree.
    sphere: BoundingSphere,
    /// Box of every block and object of the subtree (the leaf volume's box, and what `keep`
    /// is asked about).
    aabb: Aabb3,
    children: [u32; 4],
    subtree_end: u32,
    block_start: u32,
    block_end: u32,
    /// The node a traversal tests in this one's place: itself, or the end of the chain of
    /// single-child nodes below it that hold no object and whose volumes are copies of its
    /// own (a chain is tested once, at its deepest node).
    pass: u32,
    /// Leaf whose sphere holds its box: box ∩ sphere is the box, one test suffices.
    box_only: bool,
}

/// What a node holds, as [`BqrTree::node`] shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct BqrNodeView {
    /// Linear quadtree key (root 1; child `4k + q`).
    pub key: u64,
    /// Depth (root 0).
    pub depth: u32,
    /// Inner node or leaf.
    pub kind: BqrNodeKind,
    /// Box of every block of the subtree (local frame).
    pub aabb: Aabb3,
    /// Bounding sphere of the subtree.
    pub sphere: BoundingSphere,
    /// The subtree's blocks: a range of [`BqrTree::blocks`] (whole blocks, never cut).
    pub blocks: std::ops::Range<usize>,
    /// Children's node indices per quadrant (south-west, south-east, north-west, north-east).
    pub children: [Option<usize>; 4],
}

#[derive(Clone, Debug)]
struct ObjectSlot {
    aabb: Aabb3,
    node: u32,
}

/// The BqR-tree (Pina, Serón and Cerezo, §4). Immutable for blocks after its build; mobile objects can be
/// inserted, moved and removed.
#[derive(Clone, Debug)]
pub struct BqrTree {
    nodes: Vec<Node>,
    blocks: Vec<BlockBounds>,
    max_depth: u32,
    objects: Vec<Option<ObjectSlot>>,
    node_objects: Vec<Vec<u32>>,
    object_count: usize,
    /// The traversal layout of the plain frustum cull (`bqr_layout`), laid out at build and by
    /// [`BqrTree::refit`]; dropped when an object is inserted (the build tree then serves).
    hot: Option<HotLayout>,
}

struct Builder<'a> {
    input: &'a [BlockBounds],
    nodes: Vec<Node>,
    order: Vec<u32>,
    max_depth: u32,
}

impl Builder<'_> {
    fn build(
        &mut self,
        items: &mut [u32],
        qmin: DVec2,
        qmax: DVec2,
        key: u64,
        depth: u32,
        parent: u32,
    ) -> u32 {
        let idx = self.nodes.len() as u32;
        let block_start = self.order.len() as u32;
        self.nodes.push(Node {
            key,
            depth,
            kind: BqrNodeKind::Leaf,
            parent,
            quad_min: qmin,
            quad_max: qmax,
            sphere: BoundingSphere {
                center: DVec3::ZERO,
                radius: 0.0,
            },
            aabb: Aabb3::EMPTY,
            children: [NONE; 4],
            subtree_end: 0,
            block_start,
            block_end: 0,
            pass: idx,
            box_only: false,
        });
        // A quadrant with one block is indivisible (Pina, Serón and Cerezo, §4); several blocks with the same
        // centre can never be separated: stop at the depth limit with a multi-block leaf.
        if items.len() <= 1 || depth >= self.max_depth {
            self.order.extend_from_slice(items);
            let mut aabb = Aabb3::EMPTY;
            let mut sphere: Option<BoundingSphere> = None;
            for &i in items.iter() {
                let b = &self.input[i as usize].aabb;
                aabb = aabb.union(*b);
                // The leaf volume is the block's own sphere (the smallest around its geometry,
                // `BlockBounds::sphere`) ∩ a box. Deviation (Pina, Serón and Cerezo, §4 intersects it with the
                // quadrant box): a block is assigned by its centre and may stick out of its
                // quadrant, so the quadrant box is not conservative; we intersect with the
                // block's own AABB. Each holds the geometry, so the intersection does.
                let s = self.input[i as usize].sphere;
                sphere = Some(match sphere {
                    None => s,
                    Some(acc) => acc.merge(s),
                });
            }
            let end = self.nodes.len() as u32;
            let n = &mut self.nodes[idx as usize];
            n.aabb = aabb;
            n.sphere = sphere.unwrap_or(BoundingSphere {
                center: DVec3::ZERO,
                radius: 0.0,
            });
            n.block_end = self.order.len() as u32;
            n.subtree_end = end;
            return idx;
        }
        let mid = (qmin + qmax) * 0.5;
        let input = self.input;
        let quadrant = |i: &u32| {
            let c = input[*i as usize].center;
            usize::from(c.x >= mid.x) + 2 * usize::from(c.y >= mid.y)
        };
        items.sort_unstable_by_key(quadrant);
        let mut children = [NONE; 4];
        let mut rest: &mut [u32] = items;
        for (q, child) in children.iter_mut().enumerate() {
            let n = rest.iter().take_while(|i| quadrant(i) == q).count();
            let (head, tail) = rest.split_at_mut(n);
            rest = tail;
            if head.is_empty() {
                continue; // empty quadrants get no node (adaptive quadtree)
            }
            let cmin = DVec2::new(
                if q & 1 == 1 { mid.x } else { qmin.x },
                if q & 2 == 2 { mid.y } else { qmin.y },
            );
            let cmax = DVec2::new(
                if q & 1 == 1 { qmax.x } else { mid.x },
                if q & 2 == 2 { qmax.y } else { mid.y },
            );
            *child = self.build(head, cmin, cmax, (key << 2) | q as u64, depth + 1, idx);
        }
        // Inner node: the sphere enclosing its children's spheres, bottom-up (Pina, Serón and Cerezo, §4).
        let mut aabb = Aabb3::EMPTY;
        let mut sphere: Option<BoundingSphere> = None;
        for &c in children.iter().filter(|&&c| c != NONE) {
            let cn = &self.nodes[c as usize];
            aabb = aabb.union(cn.aabb);
            sphere = Some(match sphere {
                None => cn.sphere,
                Some(s) => s.merge(cn.sphere),
            });
        }
        let end = self.nodes.len() as u32;
        let n = &mut self.nodes[idx as usize];
        n.kind = BqrNodeKind::Inner;
        n.children = children;
        n.aabb = aabb;
        n.sphere = tighter(sphere.expect("an inner node has at least one child"), &aabb);
        n.block_end = self.order.len() as u32;
        n.subtree_end = end;
        idx
    }
}

impl BqrTree {
    /// Builds the tree over `bounds` (Pina, Serón and Cerezo, §4): the city's bounding rectangle (of the
    /// blocks' boxes and centres) is split into four equal quadrants recursively until a
    /// quadrant holds at most one block centre.
    ///
    /// # Errors
    /// [`IndexError::BadParam`] for `max_depth` outside 1..=30, [`IndexError::BadBlock`] for a
    /// non-finite or empty block box.
    pub fn build(bounds: &[BlockBounds], params: &BqrParams) -> Result<Self, IndexError> {
        if !(1..=30).contains(&params.max_depth) {
            return Err(IndexError::BadParam {
                structure: NAME,
                name: "max_depth",
                value: params.max_depth.to_string(),
                reason: "must be in 1..=30",
            });
        }
        validate_bounds(NAME, bounds)?;
        let mut b = Builder {
            input: bounds,
            nodes: Vec::with_capacity(bounds.len() * 2),
            order: Vec::with_capacity(bounds.len()),
            max_depth: params.max_depth,
        };
        if !bounds.is_empty() {
            let mut rmin = DVec2::splat(f64::INFINITY);
            let mut rmax = DVec2::splat(f64::NEG_INFINITY);
            for bb in bounds {
                rmin = rmin.min(bb.aabb.min.truncate()).min(bb.center);
                rmax = rmax.max(bb.aabb.max.truncate()).max(bb.center);
            }
            let mut items: Vec<u32> = (0..bounds.len() as u32).collect();
            b.build(&mut items, rmin, rmax, 1, 0, NONE);
        }
        let blocks = b
            .order
            .iter()
            .map(|&i| bounds[i as usize].clone())
            .collect();
        let n = b.nodes.len();
        let mut tree = Self {
            nodes: b.nodes,
            blocks,
            max_depth: params.max_depth,
            objects: Vec::new(),
            node_objects: vec![Vec::new(); n],
            object_count: 0,
            hot: None,
        };
        tree.refresh_all();
        tree.lay_out();
        Ok(tree)
    }

    /// Blocks in tree order (depth-first, a subtree's blocks contiguous).
    pub fn blocks(&self) -> &[BlockBounds] {
        &self.blocks
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes
            .iter()
            .filter(|n| n.kind == BqrNodeKind::Leaf)
            .count()
    }

    /// Depth of the deepest node (root 0).
    pub fn depth(&self) -> u32 {
        self.nodes.iter().map(|n| n.depth).max().unwrap_or(0)
    }

    /// `(key, depth, kind)` of every node in preorder.
    pub fn node_keys(&self) -> impl Iterator<Item = (u64, u32, BqrNodeKind)> + '_ {
        self.nodes.iter().map(|n| (n.key, n.depth, n.kind))
    }

    /// Number of nodes.
    pub fn nodes_len(&self) -> usize {
        self.nodes.len()
    }

    /// A read-only view of node `i` (preorder index, the root is 0), or `None` past the end.
    pub fn node(&self, i: usize) -> Option<BqrNodeView> {
        let n = self.nodes.get(i)?;
        Some(BqrNodeView {
            key: n.key,
            depth: n.depth,
            kind: n.kind,
            aabb: n.aabb,
            sphere: n.sphere,
            blocks: n.block_start as usize..n.block_end as usize,
            children: n.children.map(|c| (c != NONE).then_some(c as usize)),
        })
    }

    /// The quadrant of node `i` (its square's south-west and north-east corners, local x, y), or
    /// `None` past the end. The root's is the square the keys subdivide.
    pub fn quadrant(&self, i: usize) -> Option<(DVec2, DVec2)> {
        self.nodes.get(i).map(|n| (n.quad_min, n.quad_max))
    }

    /// Number of mobile objects.
    pub fn object_count(&self) -> usize {
        self.object_count
    }

    /// The box of a mobile object, if present.
    pub fn object(&self, id: ObjectId) -> Option<Aabb3> {
        self.objects
            .get(id.0 as usize)
            .and_then(|o| o.as_ref())
            .map(|o| o.aabb)
    }

    /// Adds a mobile object without rebuilding: it goes to the deepest existing node whose
    /// quadrant holds its footprint, whose sphere and box (and its ancestors') grow to hold it.
    ///
    /// # Errors
    /// [`IndexError::BadObject`] for an empty or non-finite box, [`IndexError::DuplicateObject`]
    /// when `id` is present.
    pub fn insert_object(&mut self, id: ObjectId, aabb: Aabb3) -> Result<(), IndexError> {
        if aabb.is_empty() || !aabb.min.is_finite() || !aabb.max.is_finite() {
            return Err(IndexError::BadObject {
                structure: NAME,
                id: id.0,
            });
        }
        let i = id.0 as usize;
        if self.objects.get(i).is_some_and(|o| o.is_some()) {
            return Err(IndexError::DuplicateObject {
                structure: NAME,
                id: id.0,
            });
        }
        if self.nodes.is_empty() {
            // No block: a lone root leaf holding objects only.
            let p = aabb.center().truncate();
            self.nodes.push(Node {
                key: 1,
                depth: 0,
                kind: BqrNodeKind::Leaf,
                parent: NONE,
                quad_min: p,
                quad_max: p,
                sphere: BoundingSphere::from_aabb(&aabb),
                aabb,
                children: [NONE; 4],
                subtree_end: 1,
                block_start: 0,
                block_end: 0,
                pass: 0,
                box_only: true,
            });
            self.node_objects.push(Vec::new());
        }
        self.hot = None;
        let node = self.place(&aabb);
        if self.objects.len() <= i {
            self.objects.resize(i + 1, None);
        }
        self.objects[i] = Some(ObjectSlot { aabb, node });
        self.node_objects[node as usize].push(id.0);
        self.object_count += 1;
        let s = BoundingSphere::from_aabb(&aabb);
        let mut n = node;
        while n != NONE {
            let nd = &mut self.nodes[n as usize];
            nd.aabb = nd.aabb.union(aabb);
            nd.sphere = tighter(nd.sphere.merge(s), &nd.aabb);
            let parent = nd.parent;
            // Children are refreshed before their parent: the chains stay right.
            self.refresh(n as usize);
            n = parent;
        }
        Ok(())
    }

    /// Removes a mobile object. Volumes are not shrunk (see [`BqrTree::refit`]).
    ///
    /// # Errors
    /// [`IndexError::UnknownObject`] when `id` is absent.
    pub fn remove_object(&mut self, id: ObjectId) -> Result<Aabb3, IndexError> {
        let slot = self
            .objects
            .get_mut(id.0 as usize)
            .and_then(Option::take)
            .ok_or(IndexError::UnknownObject {
                structure: NAME,
                id: id.0,
            })?;
        let list = &mut self.node_objects[slot.node as usize];
        if let Some(p) = list.iter().position(|&o| o == id.0) {
            list.swap_remove(p);
        }
        self.object_count -= 1;
        Ok(slot.aabb)
    }

    /// Moves a mobile object to a new box (remove, then insert).
    ///
    /// # Errors
    /// As [`BqrTree::remove_object`] and [`BqrTree::insert_object`]; on error the object is
    /// left where it was.
    pub fn move_object(&mut self, id: ObjectId, aabb: Aabb3) -> Result<(), IndexError> {
        if aabb.is_empty() || !aabb.min.is_finite() || !aabb.max.is_finite() {
            return Err(IndexError::BadObject {
                structure: NAME,
                id: id.0,
            });
        }
        self.remove_object(id)?;
        self.insert_object(id, aabb)
    }

    /// Recomputes every volume bottom-up from the blocks and the objects present now
    /// (shrinks what removals and moves left grown).
    pub fn refit(&mut self) {
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            let mut aabb = Aabb3::EMPTY;
            let mut sphere: Option<BoundingSphere> = None;
            let mut add = |b: Aabb3, s: BoundingSphere| {
                aabb = aabb.union(b);
                sphere = Some(match sphere {
                    None => s,
                    Some(a) => a.merge(s),
                });
            };
            if n.kind == BqrNodeKind::Leaf {
                for b in &self.blocks[n.block_start as usize..n.block_end as usize] {
                    add(b.aabb, b.sphere);
                }
            }
            for &c in n.children.iter().filter(|&&c| c != NONE) {
                let cn = &self.nodes[c as usize];
                if !cn.aabb.is_empty() {
                    add(cn.aabb, cn.sphere);
                }
            }
            for &o in &self.node_objects[i] {
                if let Some(slot) = &self.objects[o as usize] {
                    add(slot.aabb, BoundingSphere::from_aabb(&slot.aabb));
                }
            }
            let n = &mut self.nodes[i];
            n.aabb = aabb;
            n.sphere = match sphere {
                Some(s) => tighter(s, &aabb),
                None => BoundingSphere {
                    center: n.sphere.center,
                    radius: 0.0,
                },
            };
        }
        self.refresh_all();
        self.lay_out();
    }

    /// Lays out the traversal layout when no mobile object is present (see `bqr_layout`).
    fn lay_out(&mut self) {
        self.hot = None;
        if self.object_count > 0 {
            return;
        }
        let nodes = &self.nodes;
        let source = |i: usize| {
            let n = &nodes[i];
            SourceNode {
                sphere: n.sphere,
                mid: ((n.quad_min + n.quad_max) * 0.5).to_array(),
                children: n
                    .children
                    .map(|c| (c != NONE).then(|| nodes[c as usize].pass as usize)),
                block_start: n.block_start,
                block_end: n.block_end,
            }
        };
        let blocks = &self.blocks;
        let box_only = |k: usize| sphere_holds_box(&blocks[k].sphere, &blocks[k].aabb);
        let root = nodes.first().map(|r| r.pass as usize);
        self.hot = Some(HotLayout::new(root, &source, blocks, &box_only));
    }

    /// Nodes of the traversal layout (`bqr_layout`): the build tree's nodes less the collapsed
    /// chains and the nodes inside leaf buckets; 0 while mobile objects are present.
    pub fn traversal_nodes(&self) -> usize {
        self.hot.as_ref().map_or(0, HotLayout::len)
    }

    /// Recomputes `pass` and `box_only` of every node (children before parents).
    fn refresh_all(&mut self) {
        for i in (0..self.nodes.len()).rev() {
            self.refresh(i);
        }
    }

    /// Recomputes `pass` and `box_only` of node `i` from its children's (already current).
    fn refresh(&mut self, i: usize) {
        let pass = self
            .single_child_copy(i)
            .map_or(i as u32, |c| self.nodes[c].pass);
        let n = &self.nodes[i];
        let box_only = n.kind == BqrNodeKind::Leaf && sphere_holds_box(&n.sphere, &n.aabb);
        let n = &mut self.nodes[i];
        n.pass = pass;
        n.box_only = box_only;
    }

    fn single_child_copy(&self, i: usize) -> Option<usize> {
        let n = &self.nodes[i];
        if n.kind != BqrNodeKind::Inner || !self.node_objects[i].is_empty() {
            return None;
        }
        let mut kids = n.children.iter().filter(|&&c| c != NONE);
        let c = *kids.next()?;
        if kids.next().is_some() {
            return None;
        }
        let cn = &self.nodes[c as usize];
        (cn.sphere == n.sphere && cn.aabb == n.aabb).then_some(c as usize)
    }

    fn place(&self, aabb: &Aabb3) -> u32 {
        let (lo, hi) = (aabb.min.truncate(), aabb.max.truncate());
        let mut n = 0u32;
        loop {
            let nd = &self.nodes[n as usize];
            let next = nd.children.iter().copied().find(|&c| {
                c != NONE && {
                    let cn = &self.nodes[c as usize];
                    cn.quad_min.cmple(lo).all() && hi.cmple(cn.quad_max).all()
                }
            });
            match next {
                Some(c) => n = c,
                None => return n,
            }
        }
    }

    /// Blocks (to `out`) and mobile objects (to `objects`) that may intersect the query's
    /// frustum, front to back. `coherence`, when given, holds per node the plane that rejected
    /// it last frame and is tested first (temporal coherence; sized on first use).
    pub fn cull_with_objects(
        &self,
        query: &CullQuery<'_>,
        keep: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
        objects: &mut Vec<ObjectId>,
        coherence: Option<&mut CoherenceState>,
    ) -> CullStats {
        let mut sink = Sink {
            keep,
            out,
            stats: CullStats::default(),
        };
        let mut t = Traversal {
            tree: self,
            frustum: query.frustum,
            eye: query.eye,
            objects: Some(objects),
            coherence,
        };
        if !self.nodes.is_empty() {
            t.visit(0, ALL_PLANES, &mut sink);
        }
        sink.stats
    }

    /// As [`CityIndex::cull`] with temporal coherence (see [`BqrTree::cull_with_objects`]).
    pub fn cull_coherent(
        &self,
        frustum: &Frustum,
        coherence: &mut CoherenceState,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let q = CullQuery::new(frustum);
        self.run(&q, None, out, Some(coherence))
    }

    fn run(
        &self,
        query: &CullQuery<'_>,
        keep: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
        coherence: Option<&mut CoherenceState>,
    ) -> CullStats {
        let mut sink = Sink {
            keep,
            out,
            stats: CullStats::default(),
        };
        if let (Some(hot), None, None) = (&self.hot, &sink.keep, &coherence) {
            // The plain frustum cull (Pina, Serón and Cerezo, §5) on the traversal layout: the same blocks.
            hot.cull(query.frustum, query.eye, &mut sink);
            return sink.stats;
        }
        let mut t = Traversal {
            tree: self,
            frustum: query.frustum,
            eye: query.eye,
            objects: None,
            coherence,
        };
        if !self.nodes.is_empty() {
            t.visit(0, ALL_PLANES, &mut sink);
        }
        sink.stats
    }

    /// Checks the structure's invariants; panics with a message naming the broken one.
    /// Always compiled (tests and `--check` call it).
    ///
    /// # Panics
    /// When an invariant is broken.
    pub fn check_invariants(&self) {
        let tol = |s: &BoundingSphere| 1e-9 * (1.0 + s.center.abs().max_element() + s.radius);
        let mut seen = vec![false; self.blocks.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            assert!(
                (n.subtree_end as usize) > i && (n.subtree_end as usize) <= self.nodes.len(),
                "node {i}: bad subtree end"
            );
            assert!(n.depth <= self.max_depth, "node {i}: deeper than the limit");
            assert_eq!(
                64 - n.key.leading_zeros(),
                2 * n.depth + 1,
                "node {i}: key {} does not encode depth {}",
                n.key,
                n.depth
            );
            if i == 0 {
                assert_eq!(n.parent, NONE, "root has a parent");
            }
            // A pass-through chain ends in the subtree at a node with the same volumes, and
            // every node skipped on the way has one child and no object.
            let p = n.pass as usize;
            assert!(
                p >= i && p < n.subtree_end as usize,
                "node {i}: pass {p} outside its subtree"
            );
            assert!(
                self.nodes[p].sphere == n.sphere && self.nodes[p].aabb == n.aabb,
                "node {i}: pass {p} has other volumes"
            );
            let mut k = i;
            while k != p {
                assert!(
                    self.node_objects[k].is_empty(),
                    "node {k}: skipped with objects"
                );
                let kids: Vec<u32> = self.nodes[k]
                    .children
                    .iter()
                    .copied()
                    .filter(|&c| c != NONE)
                    .collect();
                assert_eq!(kids.len(), 1, "node {k}: skipped with several children");
                k = kids[0] as usize;
            }
            match n.kind {
                BqrNodeKind::Leaf => {
                    assert!(
                        n.children.iter().all(|&c| c == NONE),
                        "leaf {i} has children"
                    );
                    let count = n.block_end - n.block_start;
                    assert!(
                        count <= 1 || n.depth == self.max_depth,
                        "leaf {i} holds {count} blocks above the depth limit"
                    );
                    assert!(
                        count >= 1 || self.blocks.is_empty(),
                        "leaf {i} holds no block"
                    );
                    for k in n.block_start..n.block_end {
                        assert!(!seen[k as usize], "block slot {k} in two leaves");
                        seen[k as usize] = true;
                    }
                }
                BqrNodeKind::Inner => {
                    let mut next_block = n.block_start;
                    let mut next_node = i as u32 + 1;
                    for (q, &c) in n.children.iter().enumerate() {
                        if c == NONE {
                            continue;
                        }
                        let cn = &self.nodes[c as usize];
                        assert_eq!(c, next_node, "node {i}: children not in preorder");
                        assert_eq!(cn.parent, i as u32, "node {c}: wrong parent");
                        assert_eq!(cn.key, (n.key << 2) | q as u64, "node {c}: wrong key");
                        assert_eq!(cn.depth, n.depth + 1, "node {c}: wrong depth");
                        assert_eq!(cn.block_start, next_block, "node {c}: block ranges");
                        next_block = cn.block_end;
                        next_node = cn.subtree_end;
                        if self.object_count == 0 && !cn.aabb.is_empty() {
                            // The parent's sphere is the merged children's spheres or the
                            // sphere around its box, whichever is smaller: it holds the
                            // child's sphere or the child's box.
                            let d = (cn.sphere.center - n.sphere.center).length();
                            let holds_sphere =
                                d + cn.sphere.radius <= n.sphere.radius + tol(&n.sphere);
                            let holds_box = cn.aabb.corners().iter().all(|&p| {
                                (p - n.sphere.center).length() <= n.sphere.radius + tol(&n.sphere)
                            });
                            assert!(
                                holds_sphere || holds_box,
                                "node {i}: sphere holds neither child {c}'s sphere nor box"
                            );
                        }
                    }
                    assert_eq!(next_block, n.block_end, "node {i}: block range");
                    assert_eq!(next_node, n.subtree_end, "node {i}: subtree range");
                    assert!(n.children.iter().any(|&c| c != NONE), "inner {i} is empty");
                }
            }
            // The volume holds every block of the subtree (its box, and its sphere or its box:
            // either holds the geometry), and the leaf's quadrant its centre.
            for b in &self.blocks[n.block_start as usize..n.block_end as usize] {
                assert!(
                    n.aabb.contains_point(b.aabb.min) && n.aabb.contains_point(b.aabb.max),
                    "node {i}: box misses block {:?}",
                    b.id
                );
                let holds_sphere = (b.sphere.center - n.sphere.center).length() + b.sphere.radius
                    <= n.sphere.radius + tol(&n.sphere);
                let holds_box =
                    b.aabb.corners().iter().all(|&p| {
                        (p - n.sphere.center).length() <= n.sphere.radius + tol(&n.sphere)
                    });
                assert!(
                    holds_sphere || holds_box,
                    "node {i}: sphere misses block {:?}",
                    b.id
                );
                let c = b.center;
                assert!(
                    n.quad_min.cmple(c).all() && c.cmple(n.quad_max).all(),
                    "node {i}: block {:?} centre outside the quadrant",
                    b.id
                );
            }
        }
        assert!(seen.iter().all(|&s| s), "a block is in no leaf");
        // Objects: in their node's list, inside the node's quadrant (unless at the root), and
        // inside every ancestor's volume.
        let mut live = 0;
        for (id, o) in self.objects.iter().enumerate() {
            let Some(o) = o else { continue };
            live += 1;
            assert!(
                self.node_objects[o.node as usize].contains(&(id as u32)),
                "object {id} missing from its node's list"
            );
            let mut n = o.node;
            while n != NONE {
                let nd = &self.nodes[n as usize];
                assert!(
                    nd.aabb.contains_point(o.aabb.min) && nd.aabb.contains_point(o.aabb.max),
                    "node {n}: box misses object {id}"
                );
                for p in o.aabb.corners() {
                    assert!(
                        (p - nd.sphere.center).length() <= nd.sphere.radius + tol(&nd.sphere),
                        "node {n}: sphere misses object {id}"
                    );
                }
                n = nd.parent;
            }
        }
        assert_eq!(live, self.object_count, "object count");
        if let Some(hot) = &self.hot {
            assert_eq!(
                self.object_count, 0,
                "a traversal layout with objects present"
            );
            hot.check(self.blocks.len());
        }
    }
}

struct Traversal<'t, 'q, 'o, 'c> {
    tree: &'t BqrTree,
    frustum: &'q Frustum,
    eye: DVec3,
    objects: Option<&'o mut Vec<ObjectId>>,
    coherence: Option<&'c mut CoherenceState>,
}

impl Traversal<'_, '_, '_, '_> {
    fn visit(&mut self, i: usize, mask: PlaneMask, sink: &mut Sink<'_, '_>) {
        let tree = self.tree;
        // An inner node with one child and no object of its own has exactly its child's
        // sphere and box (copied, not merged, at build): pass through to the chain's deepest
        // node without a test. The structure is the paper's; only redundant tests are skipped.
        let i = tree.nodes[i].pass as usize;
        let n = &tree.nodes[i];
        sink.stats.nodes_visited += 1;
        let mut m = mask;
        let tests = &mut sink.stats.plane_tests;
        // Top-down culling (Pina, Serón and Cerezo, §5): outside → cull the subtree, inside → accept it
        // without further tests, partial → descend. `m` keeps the planes still crossed.
        let res = if m == 0 {
            Containment::Inside
        } else if let Some(coh) = self.coherence.as_deref_mut() {
            let slot = coh.slot(i);
            match n.kind {
                // Box first (with coherence), then the sphere as below: the same volume, so the
                // same result as without coherence.
                BqrNodeKind::Leaf => {
                    let r = self
                        .frustum
                        .test_aabb_coherent(&n.aabb, &mut m, slot, tests);
                    if r == Containment::Intersecting && !n.box_only {
                        self.frustum.test_sphere_masked(&n.sphere, &mut m, tests)
                    } else {
                        r
                    }
                }
                BqrNodeKind::Inner => self
                    .frustum
                    .test_sphere_coherent(&n.sphere, &mut m, slot, tests),
            }
        } else {
            match n.kind {
                BqrNodeKind::Leaf => {
                    // Box first (a block's box rejects more than its sphere, and cheaper);
                    // the sphere only on the planes the box still crosses, and only when it
                    // can cut something off the box.
                    let r = self.frustum.test_aabb_masked(&n.aabb, &mut m, tests);
                    if r == Containment::Intersecting && !n.box_only {
                        self.frustum.test_sphere_masked(&n.sphere, &mut m, tests)
                    } else {
                        r
                    }
                }
                BqrNodeKind::Inner => self.frustum.test_sphere_masked(&n.sphere, &mut m, tests),
            }
        };
        if res == Containment::Outside || !sink.keep(&n.aabb) {
            return;
        }
        if res == Containment::Inside && sink.keep.is_none() {
            // Accept the whole subtree in one go.
            for b in &tree.blocks[n.block_start as usize..n.block_end as usize] {
                sink.accept(b);
            }
            if let Some(objs) = self.objects.as_deref_mut() {
                for k in i..n.subtree_end as usize {
                    objs.extend(tree.node_objects[k].iter().map(|&o| ObjectId(o)));
                }
            }
            return;
        }
        let own_objects = &tree.node_objects[i];
        if n.kind == BqrNodeKind::Leaf {
            let range = &tree.blocks[n.block_start as usize..n.block_end as usize];
            let exact = range.len() == 1 && own_objects.is_empty();
            for b in range {
                if exact {
                    // The leaf volume is this block's volume: already tested.
                    sink.accept(b);
                    continue;
                }
                sink.stats.nodes_visited += 1;
                let mut bm = m;
                if self
                    .frustum
                    .test_aabb_masked(&b.aabb, &mut bm, &mut sink.stats.plane_tests)
                    != Containment::Outside
                    && sink.keep(&b.aabb)
                {
                    sink.accept(b);
                }
            }
        }
        if let Some(objs) = self.objects.as_deref_mut() {
            for &o in own_objects {
                let Some(slot) = &tree.objects[o as usize] else {
                    continue;
                };
                let mut om = m;
                if self
                    .frustum
                    .test_aabb_masked(&slot.aabb, &mut om, &mut sink.stats.plane_tests)
                    != Containment::Outside
                    && sink.keep(&slot.aabb)
                {
                    objs.push(ObjectId(o));
                }
            }
        }
        if n.kind == BqrNodeKind::Inner {
            // Nearest child first (front to back), by quadrant: the eye's own quadrant, then
            // the one across the nearer split line, then the other side one, then the
            // opposite one. No distances, no sort.
            let mid = (n.quad_min + n.quad_max) * 0.5;
            let d = self.eye.truncate() - mid;
            let own = usize::from(d.x >= 0.0) + 2 * usize::from(d.y >= 0.0);
            let (near, far) = if d.x.abs() <= d.y.abs() {
                (1, 2)
            } else {
                (2, 1)
            };
            for q in [own, own ^ near, own ^ far, own ^ 3] {
                let c = n.children[q];
                if c != NONE {
                    self.visit(c as usize, m, sink);
                }
            }
        }
    }
}

/// The smaller of `merged` (the sphere around the children's spheres, Pina, Serón and Cerezo, §4) and the
/// sphere around the corners of `aabb`, the box of the node's whole content. Both hold every
/// block and object of the subtree, so either is conservative; the box's sphere is often the
/// smaller one, as the merged spheres accumulate slack level after level.
fn tighter(merged: BoundingSphere, aabb: &Aabb3) -> BoundingSphere {
    if aabb.is_empty() {
        return merged;
    }
    let mut around = BoundingSphere::from_aabb(aabb);
    // Round up so that floating error never leaves a corner outside.
    around.radius *= 1.0 + 1e-12;
    if around.radius < merged.radius {
        around
    } else {
        merged
    }
}

/// True when `s` holds every corner of `b`: box ∩ sphere is then the box. Testing the box alone
/// is always conservative (box ⊇ box ∩ sphere); this only says that the sphere would cut
/// nothing off, so a rounding tolerance is harmless.
fn sphere_holds_box(s: &BoundingSphere, b: &Aabb3) -> bool {
    let r2 = (s.radius * (1.0 + 1e-9)).powi(2);
    b.corners()
        .iter()
        .all(|&p| (p - s.center).length_squared() <= r2)
}

/// Squared distance from `p` to the box (0 inside).
pub(crate) fn box_distance_2(b: &Aabb3, p: DVec3) -> f64 {
    let d = (b.min - p).max(p - b.max).max(DVec3::ZERO);
    d.length_squared()
}

impl CityIndex for BqrTree {
    fn structure(&self) -> Structure {
        NAME
    }

    fn cull(
        &self,
        query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        self.run(query, hidden_filter, out, None)
    }

    fn len(&self) -> usize {
        self.blocks.len()
    }

    fn node_count(&self) -> usize {
        self.nodes.len()
    }
}
