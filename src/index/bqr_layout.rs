//! The BqR-tree's traversal layout: the same tree (Pina, Serón and Cerezo, §4) laid out for the frustum cull of
//! Pina, Serón and Cerezo, §5, apart from the node records that the build, the mobile objects and
//! [`super::BqrTree::node`] use.
//!
//! # Why a second layout
//! The build's node record (key, depth, parent, quadrant, sphere, box, children, ranges: about
//! 180 bytes) spreads one visit over three cache lines, and a tree of a million blocks has 1.3
//! million of them: at that size the cull was bound by cache misses, not by plane tests. Here a
//! node is one 64-byte line holding only what the traversal reads (its sphere, its quadrant's
//! middle for the front-to-back order, where its children and blocks are); the blocks' volumes
//! are in arrays of their own in tree order, and what an accepted block hands over (id,
//! triangles) in another, so accepting a subtree reads 8 bytes per block.
//!
//! # Layout
//! Depth-first, children contiguous: a node's children (those of its non-empty quadrants, in
//! quadrant order) sit side by side, and each child's own children follow the whole group, its
//! subtree before the next sibling's. The blocks keep the build's order (a subtree's blocks
//! contiguous), so a node found completely inside the frustum hands over one range.
//!
//! # What is not the paper's, and why
//! - **Chains collapsed.** An inner node with one child and no object of its own has exactly its
//!   child's volumes (copied at build); it is not laid out, its parent points to the end of the
//!   chain. The build tree keeps every node; only redundant tests go.
//! - **Leaf buckets.** A subtree with at most [`BUCKET_BLOCKS`] blocks is laid out as one node,
//!   the subtree root's sphere followed by its blocks' own box ∩ sphere volumes, tested one by one
//!   with the planes the sphere left crossing. The paper tests every quadtree node on the way
//!   down; below a handful of blocks the inner spheres of a quadtree barely cut (the blocks'
//!   boxes are tighter than any sphere around two of them), and each one costs a node visit. The
//!   accepted blocks are the same: a block is accepted when its own leaf volume is not outside
//!   (every ancestor's sphere holds the leaf's box or sphere, so an ancestor outside a plane
//!   means the leaf is, and one inside every plane means the leaf is).
//! - **Tests branch-free over the six planes.** A node's sphere is tested against all six
//!   planes at once (six multiply-adds per coordinate, in arrays the compiler vectorises) and the
//!   planes already cleared by an ancestor are masked out afterwards: same results as testing
//!   plane by plane, without the unpredictable early exits. A leaf tests its box, and its own
//!   sphere only when that can cut something off the box.
//!
//! The build tree's traversal (`bqr.rs`) still serves the hidden-volume filter, temporal
//! coherence and mobile objects; this layout serves the plain frustum cull, the paper's setting.

use super::{BlockBounds, Sink};
use crate::blocks::BlockId;
use crate::geom::{BoundingSphere, Frustum, PlaneMask, ALL_PLANES};
use glam::DVec3;

/// A subtree with at most this many blocks is laid out as one bucket (see the module doc).
/// Measured on jittered grids of 5,000 to 1,000,000 blocks (README, index figures).
pub(crate) const BUCKET_BLOCKS: u32 = 16;

/// One node, one cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct HotNode {
    /// Bounding sphere of the subtree: centre and radius.
    c: [f64; 3],
    r: f64,
    /// The middle of the node's quadrant (x, y): front-to-back order of the children.
    mid: [f64; 2],
    /// Index of the first child (children contiguous); unused for a bucket.
    first: u32,
    /// The subtree's blocks, a range of the tree order.
    block_start: u32,
    block_end: u32,
    /// Bit `q` set when quadrant `q` has a child; 0 for a bucket.
    quads: u8,
}

/// A block's box as centre and half extent (what the plane test reads).
#[derive(Clone, Copy, Debug)]
struct BoxCe {
    c: [f64; 3],
    e: [f64; 3],
}

/// The traversal layout of a [`super::BqrTree`] (see the module doc).
#[derive(Clone, Debug, Default)]
pub(crate) struct HotLayout {
    nodes: Vec<HotNode>,
    boxes: Vec<BoxCe>,
    spheres: Vec<BoundingSphere>,
    /// The block's sphere holds its box: box ∩ sphere is the box, the box test suffices.
    box_only: Vec<bool>,
    /// What an accepted block hands over: its id and triangle count.
    hand: Vec<(BlockId, u32)>,
}

/// What the layout needs of a build-tree node.
pub(crate) struct SourceNode {
    pub sphere: BoundingSphere,
    pub mid: [f64; 2],
    /// Children per quadrant, each already resolved to the end of its chain.
    pub children: [Option<usize>; 4],
    pub block_start: u32,
    pub block_end: u32,
}

impl HotLayout {
    /// Lays out the tree whose root (chain resolved) is `root`; `node(i)` describes build node
    /// `i`, `blocks` are the blocks in tree order, `box_only(k)` says whether block `k`'s sphere
    /// holds its box.
    pub(crate) fn new(
        root: Option<usize>,
        node: &dyn Fn(usize) -> SourceNode,
        blocks: &[BlockBounds],
        box_only: &dyn Fn(usize) -> bool,
    ) -> Self {
        let boxes = blocks
            .iter()
            .map(|b| {
                // The same arithmetic as `Frustum::test_aabb_masked`, so the same answers.
                let c = b.aabb.center();
                let e = b.aabb.extent() * 0.5;
                BoxCe {
                    c: c.to_array(),
                    e: e.to_array(),
                }
            })
            .collect();
        let mut layout = Self {
            nodes: Vec::new(),
            boxes,
            spheres: blocks.iter().map(|b| b.sphere).collect(),
            box_only: (0..blocks.len()).map(box_only).collect(),
            hand: blocks.iter().map(|b| (b.id, b.triangles)).collect(),
        };
        if let Some(r) = root {
            layout.nodes.push(hot(&node(r)));
            layout.lay_children(0, r, node);
        }
        layout
    }

    /// Lays out the children of build node `src` (already placed at `at`), then their subtrees.
    fn lay_children(&mut self, at: usize, src: usize, node: &dyn Fn(usize) -> SourceNode) {
        let s = node(src);
        if s.block_end - s.block_start <= BUCKET_BLOCKS {
            return; // a bucket: its blocks are tested directly
        }
        let kids: Vec<usize> = s.children.iter().flatten().copied().collect();
        if kids.is_empty() {
            return; // a leaf at the depth limit holding more blocks than a bucket
        }
        let first = self.nodes.len();
        let mut quads = 0u8;
        for (q, c) in s.children.iter().enumerate() {
            if c.is_some() {
                quads |= 1 << q;
            }
        }
        for &c in &kids {
            self.nodes.push(hot(&node(c)));
        }
        let n = &mut self.nodes[at];
        n.first = first as u32;
        n.quads = quads;
        for (k, &c) in kids.iter().enumerate() {
            self.lay_children(first + k, c, node);
        }
    }

    /// Number of laid-out nodes.
    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Checks the layout: children contiguous and after their parent, block ranges nested and
    /// in quadrant order, every block in exactly one bucket, no subtree of a bucket's size
    /// split. (The volumes are the build tree's, checked there.)
    ///
    /// # Panics
    /// When an invariant is broken.
    pub(crate) fn check(&self, blocks: usize) {
        let mut covered = vec![0u8; blocks];
        if self.nodes.is_empty() {
            assert_eq!(blocks, 0, "layout: blocks but no node");
            return;
        }
        let root = &self.nodes[0];
        assert_eq!(
            (root.block_start as usize, root.block_end as usize),
            (0, blocks),
            "layout: the root holds every block"
        );
        for (i, n) in self.nodes.iter().enumerate() {
            assert!(n.block_start < n.block_end, "layout node {i}: no block");
            if n.quads == 0 {
                for k in n.block_start..n.block_end {
                    covered[k as usize] += 1;
                }
                continue;
            }
            let first = n.first as usize;
            let kids = n.quads.count_ones() as usize;
            assert!(
                first > i && first + kids <= self.nodes.len(),
                "layout node {i}: children out of place"
            );
            assert!(
                n.block_end - n.block_start > BUCKET_BLOCKS,
                "layout node {i}: a subtree of a bucket's size laid out"
            );
            let mut next = n.block_start;
            for c in &self.nodes[first..first + kids] {
                assert_eq!(c.block_start, next, "layout node {i}: children's blocks");
                next = c.block_end;
            }
            assert_eq!(next, n.block_end, "layout node {i}: children's blocks");
        }
        assert!(
            covered.iter().all(|&c| c == 1),
            "layout: a block in no bucket or in two"
        );
    }

    /// Plain frustum cull (no hidden-volume filter): pushes the blocks whose leaf volume may meet
    /// the frustum to `sink`, nearest quadrant first.
    pub(crate) fn cull(&self, frustum: &Frustum, eye: DVec3, sink: &mut Sink<'_, '_>) {
        if self.nodes.is_empty() {
            return;
        }
        let planes = Planes::new(frustum);
        let mut t = Walk {
            layout: self,
            planes: &planes,
            eye: [eye.x, eye.y],
            sink,
        };
        t.visit(0, ALL_PLANES);
    }
}

/// A node's record, as a bucket; [`HotLayout::lay_children`] sets `first` and `quads` when its
/// children are laid out.
fn hot(s: &SourceNode) -> HotNode {
    HotNode {
        c: s.sphere.center.to_array(),
        r: s.sphere.radius,
        mid: s.mid,
        first: 0,
        block_start: s.block_start,
        block_end: s.block_end,
        quads: 0,
    }
}

/// The six planes as arrays per coordinate (structure of arrays), and the absolute normals for
/// the box test.
struct Planes {
    nx: [f64; 6],
    ny: [f64; 6],
    nz: [f64; 6],
    d: [f64; 6],
    ax: [f64; 6],
    ay: [f64; 6],
    az: [f64; 6],
}

impl Planes {
    fn new(f: &Frustum) -> Self {
        let get = |g: fn(&crate::geom::Plane) -> f64| std::array::from_fn(|i| g(&f.planes[i]));
        Self {
            nx: get(|p| p.normal.x),
            ny: get(|p| p.normal.y),
            nz: get(|p| p.normal.z),
            d: get(|p| p.d),
            ax: get(|p| p.normal.x.abs()),
            ay: get(|p| p.normal.y.abs()),
            az: get(|p| p.normal.z.abs()),
        }
    }

    /// Signed distances of `c` to the six planes (`Plane::distance`, the same operations in
    /// the same order).
    #[inline(always)]
    fn distances(&self, c: &[f64; 3]) -> [f64; 6] {
        let mut s = [0.0; 6];
        for (i, si) in s.iter_mut().enumerate() {
            *si = self.nx[i] * c[0] + self.ny[i] * c[1] + self.nz[i] * c[2] + self.d[i];
        }
        s
    }

    /// Sphere against the six planes: (planes it is outside, planes it is fully inside).
    #[inline(always)]
    fn sphere(&self, c: &[f64; 3], r: f64) -> (PlaneMask, PlaneMask) {
        let s = self.distances(c);
        let (mut out, mut inside) = (0u8, 0u8);
        for (i, &si) in s.iter().enumerate() {
            out |= u8::from(si < -r) << i;
            inside |= u8::from(si >= r) << i;
        }
        (out, inside)
    }

    /// Box (centre, half extent) against the six planes: p-vertex behind → outside, n-vertex in
    /// front → fully inside (`Frustum::test_aabb_masked`'s arithmetic).
    #[inline(always)]
    fn aabb(&self, b: &BoxCe) -> (PlaneMask, PlaneMask) {
        let s = self.distances(&b.c);
        let (mut out, mut inside) = (0u8, 0u8);
        for (i, &si) in s.iter().enumerate() {
            let r = self.ax[i] * b.e[0] + self.ay[i] * b.e[1] + self.az[i] * b.e[2];
            out |= u8::from(si + r < 0.0) << i;
            inside |= u8::from(si - r >= 0.0) << i;
        }
        (out, inside)
    }
}

struct Walk<'l, 'p, 's, 'k, 'o> {
    layout: &'l HotLayout,
    planes: &'p Planes,
    eye: [f64; 2],
    sink: &'s mut Sink<'k, 'o>,
}

impl Walk<'_, '_, '_, '_, '_> {
    fn visit(&mut self, i: usize, mask: PlaneMask) {
        let n = &self.layout.nodes[i];
        let (bs, be) = (n.block_start as usize, n.block_end as usize);
        if n.quads == 0 && be - bs == 1 {
            // A one-block leaf: its volume is the block's box ∩ sphere, tested once.
            self.sink.stats.nodes_visited += 1;
            if mask == 0 || self.block(bs, mask).is_some() {
                self.accept(bs, be);
            }
            return;
        }
        self.sink.stats.nodes_visited += 1;
        let mut m = mask;
        if m != 0 {
            // Top-down culling (Pina, Serón and Cerezo, §5) on the planes still crossed (`m`).
            self.sink.stats.plane_tests += u64::from(m.count_ones());
            let (out, inside) = self.planes.sphere(&n.c, n.r);
            if out & m != 0 {
                return;
            }
            m &= !inside;
        }
        if m == 0 {
            // Completely inside: the subtree is accepted without further tests.
            self.accept(bs, be);
            return;
        }
        let d = [self.eye[0] - n.mid[0], self.eye[1] - n.mid[1]];
        if n.quads == 0 {
            // A bucket: its blocks one by one, the northern half first when the eye is north
            // (the blocks are in quadrant order, south-west first): roughly front to back.
            if d[1] >= 0.0 {
                for k in (bs..be).rev() {
                    self.sink.stats.nodes_visited += 1;
                    if self.block(k, m).is_some() {
                        self.accept(k, k + 1);
                    }
                }
            } else {
                for k in bs..be {
                    self.sink.stats.nodes_visited += 1;
                    if self.block(k, m).is_some() {
                        self.accept(k, k + 1);
                    }
                }
            }
            return;
        }
        // Nearest child first, by quadrant (as the build tree's traversal): the eye's own
        // quadrant, the one across the nearer split line, the other side one, the opposite one.
        let own = usize::from(d[0] >= 0.0) + 2 * usize::from(d[1] >= 0.0);
        let (near, far) = if d[0].abs() <= d[1].abs() {
            (1, 2)
        } else {
            (2, 1)
        };
        let quads = u32::from(n.quads);
        let first = n.first as usize;
        for q in [own, own ^ near, own ^ far, own ^ 3] {
            if quads & (1 << q) != 0 {
                let k = (quads & ((1 << q) - 1)).count_ones() as usize;
                self.visit(first + k, m);
            }
        }
    }

    /// Block `k`'s leaf volume (box ∩ its own sphere) against the planes of `mask` (not 0):
    /// `None` when outside, else the planes it still crosses.
    #[inline]
    fn block(&mut self, k: usize, mask: PlaneMask) -> Option<PlaneMask> {
        let l = self.layout;
        self.sink.stats.plane_tests += u64::from(mask.count_ones());
        let (out, inside) = self.planes.aabb(&l.boxes[k]);
        if out & mask != 0 {
            return None;
        }
        let m = mask & !inside;
        if m == 0 || l.box_only[k] {
            return Some(m);
        }
        // The sphere, on the planes the box still crosses, can cut a corner off the box.
        self.sink.stats.plane_tests += u64::from(m.count_ones());
        let s = &l.spheres[k];
        let (out, inside) = self.planes.sphere(&s.center.to_array(), s.radius);
        if out & m != 0 {
            return None;
        }
        Some(m & !inside)
    }

    #[inline]
    fn accept(&mut self, start: usize, end: usize) {
        let stats = &mut self.sink.stats;
        for &(id, tris) in &self.layout.hand[start..end] {
            self.sink.out.push(id);
            stats.blocks_accepted += 1;
            stats.triangles_accepted += u64::from(tris);
        }
    }
}
