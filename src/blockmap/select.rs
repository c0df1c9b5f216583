//! Selection of the far field per frame (seed 000 §4, §5; BLOCKMAPS.md C.1–C.2): which nodes of
//! the map quadtree ([`MapTree`]) are drawn as their BlockMap and which blocks as meshes.
//!
//! The walk goes coarse to fine and front to back. A node whose cull box (its map's box joined
//! with its blocks' boxes) lies outside the frustum or is hidden on the occlusion culler's cull
//! map is dropped with everything under it. Otherwise the node is drawn as its map when its
//! projected error
//!
//! `e = ε·H / (2·d·tan(fovy/2))`, `d = max(|c − eye| − r, near)`
//!
//! is at most τ pixels (seed 000 §3.3 and §5: "rendered if their screen projected geometric error
//! is less than a pixel"; the same form as CesiumJS's `getScreenSpaceError`), with `(c, r)` the
//! cull box's circumscribed sphere. Else it is refined: its child maps are visited nearest first,
//! and the blocks under it that no child map holds are drawn as meshes, each tested against the
//! frustum (box ∩ sphere, as the BqR-tree tests a block) and the cull map. Blocks in no map at
//! all (a city whose root is not mapped) are treated the same way at the top.
//!
//! Because a node's blocks are its children's blocks plus its own remainder, and siblings' block
//! sets are disjoint ([`Selector::new`] checks both), every block that is not culled is drawn
//! exactly once: as a mesh or inside exactly one drawn map.
//!
//! **Hysteresis** (against popping, BLOCKMAPS.md C.1), inside τ: a node refined in the previous
//! frame becomes a map only when `e ≤ τ/(1 + h)`; a node drawn as a map in the previous frame
//! stays a map while `e ≤ τ`; a node the previous frame did not decide (a first frame, a node that
//! was culled or under a map) becomes a map when `e ≤ τ`. The default `h = 0.25` is the 1.25 ratio
//! BLOCKMAPS.md C.1 suggests, in its form `τ/1.25 … τ`. So every drawn map has `e ≤ τ` on every
//! frame, which the walk's screen-space bound (no mismatched pixel farther than
//! `1 px + τ/cos²θ` from a silhouette) needs, and a walk towards the city selects the same maps as
//! fresh frames of the same cameras. A band above τ (maps held up to `τ·(1 + h)`) was measured
//! against it on the fly-over of the 80k generated city (τ = 1, K = 64, 1280×1024, 8 frames):
//! coverage error max 1.26 % against 0.85 % with no band, because a camera flying towards the
//! city holds maps at up to 1.25 px on most frames.

use super::tree::MapTree;
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Camera, Containment};
use crate::index::BlockBounds;
use crate::visibility::CullMap;
use glam::DVec3;
use serde::Serialize;
use std::collections::HashMap;

/// Default hysteresis `h` (see the module doc).
pub const DEFAULT_HYSTERESIS: f64 = 0.25;

/// Selection settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SelectOptions {
    /// Largest projected error of a drawn map, pixels (τ; seed 000 §5 uses 1).
    pub tau_px: f64,
    /// Hysteresis `h ≥ 0`: a node refined in the previous frame becomes a map only when
    /// `e ≤ τ/(1 + h)` (a map stays one while `e ≤ τ`).
    pub hysteresis: f64,
}

impl SelectOptions {
    /// τ (pixels) and the hysteresis `h`, checked.
    ///
    /// # Errors
    /// [`SelectError::BadTau`] unless τ is a finite number > 0; [`SelectError::BadHysteresis`]
    /// unless `0 ≤ h < 1`.
    pub fn new(tau_px: f64, hysteresis: f64) -> Result<Self, SelectError> {
        if !(tau_px.is_finite() && tau_px > 0.0) {
            return Err(SelectError::BadTau(tau_px));
        }
        if !(0.0..1.0).contains(&hysteresis) {
            return Err(SelectError::BadHysteresis(hysteresis));
        }
        Ok(Self { tau_px, hysteresis })
    }
}

impl Default for SelectOptions {
    fn default() -> Self {
        Self {
            tau_px: 1.0,
            hysteresis: DEFAULT_HYSTERESIS,
        }
    }
}

/// Work counters of one selection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SelectStats {
    /// Map nodes whose box was tested.
    pub nodes_visited: u64,
    /// Map nodes dropped by the frustum.
    pub nodes_outside: u64,
    /// Map nodes dropped by the cull map.
    pub nodes_hidden: u64,
    /// Maps drawn.
    pub maps: u64,
    /// Blocks drawn inside the drawn maps.
    pub map_blocks: u64,
    /// Blocks drawn as meshes.
    pub mesh_blocks: u64,
    /// Mesh candidates (blocks under refined nodes) tested one by one.
    pub blocks_tested: u64,
    /// Nodes kept refined only by the hysteresis (refined in the previous frame and
    /// `τ/(1 + h) < e ≤ τ`): drawn finer than τ asks, for fewer switches.
    pub held_by_hysteresis: u64,
}

/// The far field of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Selection {
    /// Maps to draw (indices into [`MapTree::maps`]), in visiting order (front to back).
    pub maps: Vec<usize>,
    /// Blocks to draw as meshes, in visiting order.
    pub meshes: Vec<BlockId>,
    /// Counters.
    pub stats: SelectStats,
}

/// Why a selector cannot be built over a map tree.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SelectError {
    /// τ is not a finite number of pixels > 0.
    #[error("tau {0}: expected a finite number of pixels > 0")]
    BadTau(f64),
    /// The hysteresis is outside [0, 1).
    #[error("hysteresis {0}: expected a number in [0, 1)")]
    BadHysteresis(f64),
    /// A map holds a block the scene has no bounds for.
    #[error("map of node {key}: block {block} has no bounds in the scene")]
    UnknownBlock {
        /// Node key.
        key: u64,
        /// The block.
        block: u32,
    },
    /// A child map holds a block its parent does not.
    #[error("map of node {child}: block {block} is not in its parent map (node {parent})")]
    NotInParent {
        /// The child's key.
        child: u64,
        /// The parent's key.
        parent: u64,
        /// The block.
        block: u32,
    },
    /// Two sibling maps (or two top-level maps) hold the same block.
    #[error("block {block} is in the maps of both nodes {a} and {b}")]
    Shared {
        /// One node key.
        a: u64,
        /// The other.
        b: u64,
        /// The block.
        block: u32,
    },
    /// A parent index points at or after its child (maps must come parents first).
    #[error("map {index}: parent {parent} does not come before it")]
    BadParent {
        /// The map.
        index: usize,
        /// Its parent slot.
        parent: usize,
    },
}

/// A far-field node as a representation hands it to [`Selector::from_nodes`].
#[derive(Clone, Debug, PartialEq)]
pub struct SelectNode {
    /// A key naming it in errors and ordering ties.
    pub key: u64,
    /// Declared world-space error, metres: the node is drawn where it projects to at most τ.
    pub eps_m: f64,
    /// The representation's own box (joined with its blocks' boxes for culling).
    pub aabb: Aabb3,
    /// Its parent's index (parents come first).
    pub parent: Option<usize>,
    /// Its blocks; a child's blocks are its parent's, siblings share none.
    pub blocks: Vec<BlockId>,
}

/// One map node as the selector sees it.
#[derive(Clone, Debug)]
struct Node {
    key: u64,
    eps_m: f64,
    cull_box: Aabb3,
    center: DVec3,
    radius: f64,
    children: Vec<usize>,
    /// Blocks (indices into `bounds`) of this node in no child map.
    own: Vec<usize>,
    /// Number of blocks of the node.
    blocks: usize,
}

/// Selects the far field frame after frame, keeping the previous frame's maps for the
/// hysteresis (see the module doc).
#[derive(Clone, Debug)]
pub struct Selector {
    nodes: Vec<Node>,
    roots: Vec<usize>,
    /// Blocks in no map.
    loose: Vec<usize>,
    bounds: Vec<BlockBounds>,
    opts: SelectOptions,
    /// Last frame's decision per node: [`UNDECIDED`], [`AS_MAP`] or [`REFINED`].
    previous: Vec<u8>,
}

const UNDECIDED: u8 = 0;
const AS_MAP: u8 = 1;
const REFINED: u8 = 2;

/// Projected error in pixels of `eps_m` metres seen from `camera` on an image `height_px` high,
/// at the distance of the nearest point of the sphere `(center, radius)` (at least `near`).
pub fn projected_error_px(
    eps_m: f64,
    center: DVec3,
    radius: f64,
    camera: &Camera,
    height_px: u32,
) -> f64 {
    let d = ((camera.position - center).length() - radius).max(camera.near);
    eps_m * height_px as f64 / (2.0 * d * (0.5 * camera.fov_y).tan())
}

/// Distance from `p` to the box (0 inside), for the front-to-back order.
fn box_distance(b: &Aabb3, p: DVec3) -> f64 {
    let q = p.clamp(b.min, b.max);
    (p - q).length()
}

impl Selector {
    /// A selector over `tree`, whose maps hold blocks of `bounds` (the scene's block bounds).
    ///
    /// # Errors
    /// [`SelectError`] when the tree would not draw every block exactly once: a block without
    /// bounds, a child block missing from its parent, two siblings sharing a block, or parents
    /// listed after their children.
    pub fn new(
        tree: &MapTree,
        bounds: &[BlockBounds],
        opts: SelectOptions,
    ) -> Result<Self, SelectError> {
        let nodes: Vec<SelectNode> = tree
            .maps
            .iter()
            .map(|m| SelectNode {
                key: m.key,
                eps_m: m.map.meta.eps_m,
                aabb: m.map.aabb(),
                parent: m.parent,
                blocks: m.blocks.clone(),
            })
            .collect();
        Self::from_nodes(&nodes, bounds, opts)
    }

    /// A selector over any far-field nodes `tree` (parents first), whose blocks are blocks of
    /// `bounds`: what [`Selector::new`] makes of a [`MapTree`], and what other far-field
    /// representations give it.
    ///
    /// # Errors
    /// As [`Selector::new`].
    pub fn from_nodes(
        tree: &[SelectNode],
        bounds: &[BlockBounds],
        opts: SelectOptions,
    ) -> Result<Self, SelectError> {
        let slot: HashMap<BlockId, usize> =
            bounds.iter().enumerate().map(|(i, b)| (b.id, i)).collect();
        let n = tree.len();
        let mut children = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for (i, m) in tree.iter().enumerate() {
            match m.parent {
                Some(p) if p >= i => {
                    return Err(SelectError::BadParent {
                        index: i,
                        parent: p,
                    })
                }
                Some(p) => children[p].push(i),
                None => roots.push(i),
            }
        }
        // Which child (or root) holds each block, per level of the hierarchy.
        let owner_check = |group: &[usize]| -> Result<HashMap<usize, usize>, SelectError> {
            let mut owner: HashMap<usize, usize> = HashMap::new();
            for &c in group {
                let m = &tree[c];
                for b in &m.blocks {
                    let Some(&s) = slot.get(b) else {
                        return Err(SelectError::UnknownBlock {
                            key: m.key,
                            block: b.0,
                        });
                    };
                    if let Some(&o) = owner.get(&s) {
                        return Err(SelectError::Shared {
                            a: tree[o].key,
                            b: m.key,
                            block: b.0,
                        });
                    }
                    owner.insert(s, c);
                }
            }
            Ok(owner)
        };
        let mut nodes = Vec::with_capacity(n);
        for (i, m) in tree.iter().enumerate() {
            let taken = owner_check(&children[i])?;
            let mine: Vec<usize> = m
                .blocks
                .iter()
                .map(|b| {
                    slot.get(b).copied().ok_or(SelectError::UnknownBlock {
                        key: m.key,
                        block: b.0,
                    })
                })
                .collect::<Result<_, _>>()?;
            let set: std::collections::HashSet<usize> = mine.iter().copied().collect();
            if let Some((&s, &c)) = taken.iter().find(|(s, _)| !set.contains(s)) {
                return Err(SelectError::NotInParent {
                    child: tree[c].key,
                    parent: m.key,
                    block: bounds[s].id.0,
                });
            }
            let mut own: Vec<usize> = mine
                .into_iter()
                .filter(|s| !taken.contains_key(s))
                .collect();
            own.sort_unstable();
            let cull_box = m
                .blocks
                .iter()
                .filter_map(|b| slot.get(b))
                .fold(m.aabb, |a, &s| a.union(bounds[s].aabb));
            nodes.push(Node {
                key: m.key,
                eps_m: m.eps_m,
                center: cull_box.center(),
                radius: cull_box.extent().length() * 0.5,
                cull_box,
                children: children[i].clone(),
                own,
                blocks: m.blocks.len(),
            });
        }
        let top = owner_check(&roots)?;
        let loose: Vec<usize> = (0..bounds.len()).filter(|s| !top.contains_key(s)).collect();
        Ok(Self {
            nodes,
            roots,
            loose,
            bounds: bounds.to_vec(),
            opts,
            previous: vec![UNDECIDED; n],
        })
    }

    /// The settings.
    pub fn options(&self) -> SelectOptions {
        self.opts
    }

    /// Changes the settings (the previous frame's maps are kept).
    pub fn set_options(&mut self, opts: SelectOptions) {
        self.opts = opts;
    }

    /// Forgets the previous frame: the next selection is made without hysteresis.
    pub fn reset(&mut self) {
        self.previous.iter_mut().for_each(|p| *p = UNDECIDED);
    }

    /// Number of map nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when the tree has no maps (everything is drawn as meshes).
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The projected error of map `i` from `camera` (pixels, image `height_px` high).
    pub fn error_px(&self, i: usize, camera: &Camera, height_px: u32) -> f64 {
        let n = &self.nodes[i];
        projected_error_px(n.eps_m, n.center, n.radius, camera, height_px)
    }

    /// The box map `i` is culled with: its map's box joined with its blocks' boxes.
    pub fn cull_box(&self, i: usize) -> Aabb3 {
        self.nodes[i].cull_box
    }

    /// Selects the far field for `camera` on an image `height_px` pixels high, pruning with
    /// `cull` (the occlusion culler's map for this camera) when given, and remembers the
    /// decisions for the next frame's hysteresis.
    pub fn select(&mut self, camera: &Camera, height_px: u32, cull: Option<&CullMap>) -> Selection {
        let (sel, decided) = self.run(camera, height_px, cull, false);
        self.previous = decided;
        sel
    }

    /// The selection for `camera` with the previous frame's decisions kept wherever a node was
    /// decided then (drawn as its map, or refined), the rule deciding only nodes the previous
    /// frame did not reach; the state is left unchanged. Drawn beside [`Selector::select`]'s
    /// result for the same camera, the two frames differ only by what the selection changed:
    /// the walk's popping measure.
    pub fn select_frozen(
        &self,
        camera: &Camera,
        height_px: u32,
        cull: Option<&CullMap>,
    ) -> Selection {
        self.run(camera, height_px, cull, true).0
    }

    fn run(
        &self,
        camera: &Camera,
        height_px: u32,
        cull: Option<&CullMap>,
        frozen: bool,
    ) -> (Selection, Vec<u8>) {
        let mut out = Selection::default();
        let frustum = camera.frustum();
        let mut decided = vec![UNDECIDED; self.nodes.len()];
        let eye = camera.position;
        let mut stack: Vec<usize> = Vec::new();
        let mut roots = self.roots.clone();
        self.order(&mut roots, eye);
        stack.extend(roots.iter().rev());
        let hidden = |b: &Aabb3| cull.is_some_and(|m| m.box_hidden(b));
        let mesh_ok = |b: &BlockBounds| {
            frustum.test_aabb_sphere(&b.aabb, &b.sphere) != Containment::Outside && !hidden(&b.aabb)
        };
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            out.stats.nodes_visited += 1;
            if !frustum.intersects_aabb(&n.cull_box) {
                out.stats.nodes_outside += 1;
                continue;
            }
            if hidden(&n.cull_box) {
                out.stats.nodes_hidden += 1;
                continue;
            }
            let e = projected_error_px(n.eps_m, n.center, n.radius, camera, height_px);
            let tau = self.opts.tau_px;
            let as_map = match (frozen, self.previous[i]) {
                (true, AS_MAP) => true,
                (true, REFINED) => false,
                (_, REFINED) => e <= tau / (1.0 + self.opts.hysteresis.max(0.0)),
                _ => e <= tau,
            };
            if !as_map && !frozen && self.previous[i] == REFINED && e <= tau {
                out.stats.held_by_hysteresis += 1;
            }
            if as_map {
                decided[i] = AS_MAP;
                out.maps.push(i);
                out.stats.maps += 1;
                out.stats.map_blocks += n.blocks as u64;
                continue;
            }
            decided[i] = REFINED;
            for &s in &n.own {
                out.stats.blocks_tested += 1;
                if mesh_ok(&self.bounds[s]) {
                    out.meshes.push(self.bounds[s].id);
                }
            }
            let mut kids = n.children.clone();
            self.order(&mut kids, eye);
            stack.extend(kids.iter().rev());
        }
        // Blocks in no map: meshes, tested one by one.
        for &s in &self.loose {
            out.stats.blocks_tested += 1;
            if mesh_ok(&self.bounds[s]) {
                out.meshes.push(self.bounds[s].id);
            }
        }
        out.stats.mesh_blocks = out.meshes.len() as u64;
        (out, decided)
    }

    /// Nearest first (ties by key, so the order is deterministic).
    fn order(&self, v: &mut [usize], eye: DVec3) {
        v.sort_by(|&a, &b| {
            let (na, nb) = (&self.nodes[a], &self.nodes[b]);
            box_distance(&na.cull_box, eye)
                .total_cmp(&box_distance(&nb.cull_box, eye))
                .then(na.key.cmp(&nb.key))
        });
    }
}
