//! [`TerrainTree`]: the quadtree of square tiles over a [`Terrain`], with a measured L∞ error
//! per node, its saturated (monotone) bound, skirt depths, the min-filtered occluder level, and
//! the per-frame cut by projected error.

use super::Terrain;
use crate::geom::{Aabb3, Camera, LocalFrame};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Extra depth of every skirt, metres, beyond the errors it must cover: it covers the rounding
/// of local positions to f32 (half an ulp is 2 mm at 32 km from the local origin, 4 mm at 65 km)
/// where two tiles round the same edge differently.
pub const SKIRT_MARGIN_M: f64 = 0.01;

/// How a [`TerrainTree`] is cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TreeOptions {
    /// `T`: a tile is `T × T` cells at its level's stride (a power of two, 2 … 1024).
    pub tile_cells: usize,
}

impl Default for TreeOptions {
    fn default() -> Self {
        Self { tile_cells: 32 }
    }
}

/// Why a tree cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum TreeError {
    /// The options cannot be used.
    #[error("tile_cells = {tile_cells}: must be a power of two from 2 to 1024")]
    TileCells {
        /// The value given.
        tile_cells: usize,
    },
}

/// A node of a [`TerrainTree`] (its index in the tree; level 0 first, then level by level,
/// tiles row-major within a level).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct NodeId(pub u32);

/// One level of the tree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelStats {
    /// 0 is the root.
    pub level: usize,
    /// Samples of the full grid between two vertices of this level's meshes.
    pub stride: usize,
    /// Tiles in this level.
    pub nodes: usize,
    /// The bound this level declares, metres: the largest saturated node error in it (every
    /// node of the level, and every descendant, is within it).
    pub declared_error_m: f64,
    /// The largest error measured on a node of this level (before saturation), metres.
    pub max_measured_error_m: f64,
}

/// A summary of a tree, for reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TreeSummary {
    /// The options it was built with.
    pub tile_cells: usize,
    /// Grid size, nodes.
    pub grid: [usize; 2],
    /// Node spacing, metres.
    pub spacing_m: [f64; 2],
    /// Levels below the root (the finest level's stride is 1, the root's `2^depth`).
    pub depth: usize,
    /// Nodes in all.
    pub nodes: usize,
    /// Per level.
    pub levels: Vec<LevelStats>,
    /// Bytes the tree holds besides the terrain.
    pub heap_bytes: usize,
    /// Bytes the terrain holds.
    pub terrain_heap_bytes: usize,
}

#[derive(Clone, Debug)]
struct Level {
    stride: usize,
    tiles: [usize; 2],
    first: usize,
    /// Coarse cells of this stride, `[x, y]`.
    cells: [usize; 2],
    /// Min of the full-resolution samples per coarse cell, `NaN` when one of them is nodata;
    /// empty at stride 1 (read from the grid).
    mins: Vec<f64>,
}

#[derive(Clone, Debug)]
struct Node {
    extent: Aabb3,
    error_m: f64,
    measured_m: f64,
    /// West, east, south, north; 0 where the edge has no neighbour.
    skirt_m: [f64; 4],
    /// The lowest point of the node's and its descendants' drawn geometry, skirts included.
    floor_z: f64,
    level: u8,
    tile: [u32; 2],
}

/// The terrain's level-of-detail tree; see the [module documentation](super) for the design.
#[derive(Clone, Debug)]
pub struct TerrainTree {
    terrain: std::sync::Arc<Terrain>,
    opts: TreeOptions,
    depth: usize,
    levels: Vec<Level>,
    nodes: Vec<Node>,
}

/// Min of two heights, `NaN` when either is.
#[inline]
fn min_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.min(b)
    }
}

impl TerrainTree {
    /// Builds the tree over `terrain` (which it keeps: meshes are made from the grid on demand).
    ///
    /// # Errors
    /// [`TreeError::TileCells`] when `opts.tile_cells` is not a power of two from 2 to 1024.
    pub fn build(terrain: Terrain, opts: &TreeOptions) -> Result<TerrainTree, TreeError> {
        Self::build_shared(std::sync::Arc::new(terrain), opts)
    }

    /// [`Self::build`] over a terrain shared with its owner (a city's), not copied.
    ///
    /// # Errors
    /// As [`Self::build`].
    pub fn build_shared(
        terrain: std::sync::Arc<Terrain>,
        opts: &TreeOptions,
    ) -> Result<TerrainTree, TreeError> {
        let t = opts.tile_cells;
        if !(2..=1024).contains(&t) || !t.is_power_of_two() {
            return Err(TreeError::TileCells { tile_cells: t });
        }
        let (nx, ny) = (terrain.nx(), terrain.ny());
        let cells = (nx - 1).max(ny - 1);
        let mut depth = 0;
        while t << depth < cells {
            depth += 1;
        }
        // Levels, coarse to fine; tiles and the min pyramid (built fine to coarse).
        let mut levels: Vec<Level> = Vec::with_capacity(depth + 1);
        let mut first = 0;
        for l in 0..=depth {
            let stride = 1usize << (depth - l);
            let span = t * stride;
            let tiles = [(nx - 1).div_ceil(span), (ny - 1).div_ceil(span)];
            levels.push(Level {
                stride,
                tiles,
                first,
                cells: [(nx - 1).div_ceil(stride), (ny - 1).div_ceil(stride)],
                mins: Vec::new(),
            });
            first += tiles[0] * tiles[1];
        }
        for l in (0..depth).rev() {
            let [cx, cy] = levels[l].cells;
            let mins: Vec<f64> = (0..cy)
                .into_par_iter()
                .flat_map_iter(|cj| {
                    let fine = &levels[l + 1];
                    let terrain = &terrain;
                    (0..cx).map(move |ci| {
                        let mut m = f64::INFINITY;
                        for (a, b) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (fi, fj) = (2 * ci + a, 2 * cj + b);
                            if fi < fine.cells[0] && fj < fine.cells[1] {
                                let v = if fine.stride == 1 {
                                    min_nan(
                                        min_nan(terrain.raw(fi, fj), terrain.raw(fi + 1, fj)),
                                        min_nan(
                                            terrain.raw(fi, fj + 1),
                                            terrain.raw(fi + 1, fj + 1),
                                        ),
                                    )
                                } else {
                                    fine.mins[fj * fine.cells[0] + fi]
                                };
                                m = min_nan(m, v);
                            }
                        }
                        m
                    })
                })
                .collect();
            levels[l].mins = mins;
        }
        let mut tree = TerrainTree {
            terrain,
            opts: *opts,
            depth,
            levels,
            nodes: Vec::new(),
        };
        // Nodes: extents and measured errors, per level in parallel.
        let mut nodes = Vec::with_capacity(first);
        for l in 0..=depth {
            let [tx, ty] = tree.levels[l].tiles;
            let level_nodes: Vec<Node> = (0..tx * ty)
                .into_par_iter()
                .map(|k| tree.measure_node(l, [k % tx, k / tx]))
                .collect();
            nodes.extend(level_nodes);
        }
        tree.nodes = nodes;
        // Saturation, fine to coarse: a parent's error is at least each child's.
        for id in (0..tree.nodes.len()).rev() {
            let e = tree
                .children(NodeId(id as u32))
                .map(|c| tree.nodes[c.0 as usize].error_m)
                .fold(tree.nodes[id].measured_m, f64::max);
            tree.nodes[id].error_m = e;
        }
        // Skirts.
        let skirts: Vec<[f64; 4]> = (0..tree.nodes.len())
            .into_par_iter()
            .map(|id| tree.skirt_depths(id))
            .collect();
        for (n, s) in tree.nodes.iter_mut().zip(skirts) {
            n.skirt_m = s;
            n.floor_z = n.extent.min.z - s.iter().fold(0.0f64, |a, &b| a.max(b));
        }
        // A subtree's drawn geometry reaches down to the lowest skirt in it (a child's skirt
        // can be deeper than its parent's).
        for id in (0..tree.nodes.len()).rev() {
            let f = tree
                .children(NodeId(id as u32))
                .map(|c| tree.nodes[c.0 as usize].floor_z)
                .fold(tree.nodes[id].floor_z, f64::min);
            tree.nodes[id].floor_z = f;
        }
        Ok(tree)
    }

    /// The grid node range `[i0, j0, i1, j1]` (inclusive) of tile `tile` at level `l`.
    fn range(&self, l: usize, tile: [usize; 2]) -> [usize; 4] {
        let span = self.opts.tile_cells * self.levels[l].stride;
        let (nx, ny) = (self.terrain.nx(), self.terrain.ny());
        [
            tile[0] * span,
            tile[1] * span,
            (tile[0] * span + span).min(nx - 1),
            (tile[1] * span + span).min(ny - 1),
        ]
    }

    /// Min of the full-resolution samples of coarse cell `(ci, cj)` at level `l` (`NaN` when one
    /// is nodata).
    #[inline]
    fn cell_min(&self, l: usize, ci: usize, cj: usize) -> f64 {
        let lv = &self.levels[l];
        if lv.stride == 1 {
            let t = &self.terrain;
            min_nan(
                min_nan(t.raw(ci, cj), t.raw(ci + 1, cj)),
                min_nan(t.raw(ci, cj + 1), t.raw(ci + 1, cj + 1)),
            )
        } else {
            lv.mins[cj * lv.cells[0] + ci]
        }
    }

    /// A node's extent and measured error (not yet saturated).
    fn measure_node(&self, l: usize, tile: [usize; 2]) -> Node {
        let t = &self.terrain;
        let [i0, j0, i1, j1] = self.range(l, tile);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let h = t.raw(i, j);
                if !h.is_nan() {
                    lo = lo.min(h);
                    hi = hi.max(h);
                }
            }
        }
        let s = self.levels[l].stride;
        let mut err = 0.0f64;
        if s > 1 {
            let mut ya = j0;
            while ya < j1 {
                let yb = (ya + s).min(j1);
                let mut xa = i0;
                while xa < i1 {
                    let xb = (xa + s).min(i1);
                    if !self.cell_min(l, xa / s, ya / s).is_nan() {
                        err = err.max(coarse_cell_error(t, xa, ya, xb, yb));
                    }
                    xa = xb;
                }
                ya = yb;
            }
        }
        let extent = Aabb3::new(
            DVec3::new(t.x(i0), t.y(j0), lo),
            DVec3::new(t.x(i1), t.y(j1), hi),
        );
        Node {
            extent,
            error_m: err,
            measured_m: err,
            skirt_m: [0.0; 4],
            floor_z: lo,
            level: l as u8,
            tile: [tile[0] as u32, tile[1] as u32],
        }
    }

    /// Skirt depth per edge (west, east, south, north) of node `id`: its error, plus the
    /// largest error of any node that can lie across that edge in a cut, plus
    /// [`SKIRT_MARGIN_M`]; 0 on the grid's border.
    ///
    /// Along a shared edge both tiles interpolate samples of the same grid line, and each is
    /// within its node's error of the full-resolution surface there, so the two edges are at
    /// most `e_A + e_B` apart; a skirt of that depth under each edge closes the gap whichever
    /// side is higher. Across an edge a cut holds either one node of a level at most as fine
    /// as this one (the node of that level holding the cells beyond the edge, unless it is this
    /// node's own ancestor, which cannot be in the same cut), or finer nodes, whose errors are
    /// at most that of their same-level ancestor (errors are saturated). So the largest error
    /// across is the maximum over the levels `0 ..= level` of the node beyond the edge.
    fn skirt_depths(&self, id: usize) -> [f64; 4] {
        let n = &self.nodes[id];
        let l = n.level as usize;
        let [i0, j0, i1, j1] = self.range(l, [n.tile[0] as usize, n.tile[1] as usize]);
        let (nx, ny) = (self.terrain.nx(), self.terrain.ny());
        // For each edge: the cell just beyond it (None on the border) and a cell inside.
        let beyond: [Option<[usize; 2]>; 4] = [
            (i0 > 0).then(|| [i0 - 1, j0]),
            (i1 < nx - 1).then_some([i1, j0]),
            (j0 > 0).then(|| [i0, j0 - 1]),
            (j1 < ny - 1).then_some([i0, j1]),
        ];
        let inside = [i0, j0];
        let mut out = [0.0; 4];
        for (e, b) in beyond.iter().enumerate() {
            let Some(b) = b else { continue };
            let mut across = 0.0f64;
            for lv in (0..=l).rev() {
                let span = self.opts.tile_cells * self.levels[lv].stride;
                let tb = [b[0] / span, b[1] / span];
                let ta = [inside[0] / span, inside[1] / span];
                if tb == ta {
                    break;
                }
                let k = self.levels[lv].first + tb[1] * self.levels[lv].tiles[0] + tb[0];
                across = across.max(self.nodes[k].error_m);
            }
            out[e] = n.error_m + across + SKIRT_MARGIN_M;
        }
        out
    }

    /// The terrain the tree is built over.
    pub fn terrain(&self) -> &Terrain {
        &self.terrain
    }
    /// The terrain back.
    pub fn into_terrain(self) -> Terrain {
        std::sync::Arc::unwrap_or_clone(self.terrain)
    }
    /// The options it was built with.
    pub fn options(&self) -> TreeOptions {
        self.opts
    }
    /// Levels below the root.
    pub fn depth(&self) -> usize {
        self.depth
    }
    /// Nodes in all.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    /// Never: a tree has a root.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
    /// The root, covering the whole grid.
    pub fn root(&self) -> NodeId {
        NodeId(0)
    }
    /// Every node, coarse to fine.
    pub fn node_ids(&self) -> impl Iterator<Item = NodeId> {
        (0..self.nodes.len() as u32).map(NodeId)
    }
    /// A node's level (0 is the root).
    pub fn level(&self, id: NodeId) -> usize {
        self.nodes[id.0 as usize].level as usize
    }
    /// A node's tile index `[x, y]` within its level.
    pub fn tile(&self, id: NodeId) -> [usize; 2] {
        let t = self.nodes[id.0 as usize].tile;
        [t[0] as usize, t[1] as usize]
    }
    /// Grid samples between two vertices of a node's mesh (`2^(depth − level)`).
    pub fn stride(&self, id: NodeId) -> usize {
        self.levels[self.level(id)].stride
    }
    /// The grid nodes a node covers, `[i0, j0, i1, j1]` inclusive.
    pub fn node_range(&self, id: NodeId) -> [usize; 4] {
        self.range(self.level(id), self.tile(id))
    }
    /// A node's box in world coordinates: the xy of the samples it covers, z from the lowest to
    /// the highest full-resolution sample (empty when all of them are nodata). Skirts reach
    /// below it by [`Self::skirt_depth_m`].
    pub fn extent(&self, id: NodeId) -> Aabb3 {
        self.nodes[id.0 as usize].extent
    }
    /// A box holding everything the node and its descendants draw: [`Self::extent`] reaching
    /// down to the bottom of the deepest skirt in the subtree (what [`Self::select`] culls
    /// with).
    pub fn draw_box(&self, id: NodeId) -> Aabb3 {
        let n = &self.nodes[id.0 as usize];
        let mut b = n.extent;
        b.min.z = n.floor_z;
        b
    }

    /// The node's error bound, metres: the largest of its measured error and its descendants'
    /// (saturated, so a parent's is at least each child's).
    pub fn error_m(&self, id: NodeId) -> f64 {
        self.nodes[id.0 as usize].error_m
    }
    /// The node's measured error, metres: the L∞ distance between its mesh (two triangles per
    /// coarse cell, the south-west–north-east diagonal) and the full-resolution mesh, over the
    /// cells it draws.
    pub fn measured_error_m(&self, id: NodeId) -> f64 {
        self.nodes[id.0 as usize].measured_m
    }
    /// Skirt depths below the west, east, south and north edges, metres (0 on the grid border).
    pub fn skirt_depth_m(&self, id: NodeId) -> [f64; 4] {
        self.nodes[id.0 as usize].skirt_m
    }
    /// The node's parent (`None` for the root).
    pub fn parent(&self, id: NodeId) -> Option<NodeId> {
        let l = self.level(id);
        if l == 0 {
            return None;
        }
        let [x, y] = self.tile(id);
        let lv = &self.levels[l - 1];
        Some(NodeId((lv.first + (y / 2) * lv.tiles[0] + x / 2) as u32))
    }
    /// The node's children (none at the finest level; fewer than four on the grid's east and
    /// north borders).
    pub fn children(&self, id: NodeId) -> impl Iterator<Item = NodeId> + '_ {
        let l = self.level(id);
        let [x, y] = self.tile(id);
        let fine = self.levels.get(l + 1);
        [(0, 0), (1, 0), (0, 1), (1, 1)]
            .into_iter()
            .filter_map(move |(a, b)| {
                let lv = fine?;
                let (cx, cy) = (2 * x + a, 2 * y + b);
                (cx < lv.tiles[0] && cy < lv.tiles[1])
                    .then(|| NodeId((lv.first + cy * lv.tiles[0] + cx) as u32))
            })
    }

    /// The min-filtered occluder level of a node: for each of its coarse cells whose samples all
    /// have a height, the cell's box `[xmin, ymin, xmax, ymax]` and the lowest full-resolution
    /// sample under it. The drawn surface over the box (the full-resolution mesh, and the
    /// bilinear surface alike) is a convex combination of those samples cell by cell, so it
    /// never goes below that height: a box from below up to it is a conservative occluder
    /// (the min pyramid of Willmott et al., §3.2, here over heights).
    pub fn occluder_cells(&self, id: NodeId) -> impl Iterator<Item = ([f64; 4], f64)> + '_ {
        let l = self.level(id);
        let s = self.levels[l].stride;
        let [i0, j0, i1, j1] = self.node_range(id);
        let t = &self.terrain;
        (j0 / s..j1.div_ceil(s)).flat_map(move |cj| {
            (i0 / s..i1.div_ceil(s)).filter_map(move |ci| {
                let z = self.cell_min(l, ci, cj);
                if z.is_nan() {
                    return None;
                }
                let (xa, ya) = (ci * s, cj * s);
                let (xb, yb) = ((xa + s).min(i1), (ya + s).min(j1));
                Some(([t.x(xa), t.y(ya), t.x(xb), t.y(yb)], z))
            })
        })
    }

    /// Whether coarse cell `(ci, cj)` of level `l` is drawn (all its samples have a height).
    pub(super) fn cell_drawn(&self, l: usize, ci: usize, cj: usize) -> bool {
        !self.cell_min(l, ci, cj).is_nan()
    }

    /// The cut for one frame: pushes into `out` (cleared first) the nodes to draw for `camera`
    /// (in the local frame of `frame`, as every camera of blockwalk) on an image
    /// `viewport_h_px` high, so that each drawn node's projected error is at most `tau_px`
    /// pixels where the finest level allows.
    ///
    /// Top-down from the root: a node whose [`Self::draw_box`] lies outside the frustum is left
    /// out with its subtree; a node is drawn when
    /// `e · focal_px / max(distance from the eye to its box, near) ≤ τ`, or at the finest
    /// level; else its children are visited. `focal_px = viewport_h_px / (2 tan(fov_y / 2))`.
    /// Nodes without a height are never drawn. The drawn nodes partition the visible part of
    /// the grid: no two overlap, and no visible cell is left out (the view-dependent cut of
    /// Di Benedetto, ch. 3 §3.5.1, with the saturated errors making the top-down cut
    /// well defined).
    pub fn select(
        &self,
        camera: &Camera,
        frame: &LocalFrame,
        viewport_h_px: u32,
        tau_px: f64,
        out: &mut Vec<NodeId>,
    ) {
        out.clear();
        let frustum = camera.frustum().translated(-frame.origin);
        let eye = frame.to_world(camera.position);
        let focal = viewport_h_px as f64 / (2.0 * (0.5 * camera.fov_y).tan());
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(k) = stack.pop() {
            let n = &self.nodes[k as usize];
            if n.extent.is_empty() {
                continue;
            }
            let mut cull_box = n.extent;
            cull_box.min.z = n.floor_z;
            if !frustum.intersects_aabb(&cull_box) {
                continue;
            }
            let finest = n.level as usize == self.depth;
            let d = box_distance(&n.extent, eye).max(camera.near);
            if finest || n.error_m * focal <= tau_px * d {
                out.push(NodeId(k));
            } else {
                stack.extend(self.children(NodeId(k)).map(|c| c.0));
            }
        }
    }

    /// The projected error of node `id` for `camera` (local to `frame`) on an image
    /// `viewport_h_px` high, pixels: the quantity [`Self::select`] keeps at most τ.
    pub fn projected_error_px(
        &self,
        id: NodeId,
        camera: &Camera,
        frame: &LocalFrame,
        viewport_h_px: u32,
    ) -> f64 {
        let n = &self.nodes[id.0 as usize];
        let eye = frame.to_world(camera.position);
        let focal = viewport_h_px as f64 / (2.0 * (0.5 * camera.fov_y).tan());
        n.error_m * focal / box_distance(&n.extent, eye).max(camera.near)
    }

    /// Per level: stride, node count, the declared bound and the largest measured error.
    pub fn levels(&self) -> Vec<LevelStats> {
        self.levels
            .iter()
            .enumerate()
            .map(|(l, lv)| {
                let n = lv.tiles[0] * lv.tiles[1];
                let nodes = &self.nodes[lv.first..lv.first + n];
                LevelStats {
                    level: l,
                    stride: lv.stride,
                    nodes: n,
                    declared_error_m: nodes.iter().map(|n| n.error_m).fold(0.0, f64::max),
                    max_measured_error_m: nodes.iter().map(|n| n.measured_m).fold(0.0, f64::max),
                }
            })
            .collect()
    }

    /// Bytes the tree holds on the heap besides its terrain: the nodes and the min pyramid.
    pub fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.levels.capacity() * std::mem::size_of::<Level>()
            + self
                .levels
                .iter()
                .map(|l| l.mins.capacity() * std::mem::size_of::<f64>())
                .sum::<usize>()
    }

    /// A summary for reports.
    pub fn summary(&self) -> TreeSummary {
        let s = self.terrain.spacing();
        TreeSummary {
            tile_cells: self.opts.tile_cells,
            grid: [self.terrain.nx(), self.terrain.ny()],
            spacing_m: [s.x, s.y],
            depth: self.depth,
            nodes: self.nodes.len(),
            levels: self.levels(),
            heap_bytes: self.heap_bytes(),
            terrain_heap_bytes: self.terrain.heap_bytes(),
        }
    }

    /// Checks the tree's invariants: one root covering the grid; children inside their parent,
    /// covering it without overlap; errors saturated (a parent's at least each child's, and at
    /// least its own measurement); zero error at the finest level; skirts at least the node's
    /// error deep on every inner edge.
    ///
    /// # Panics
    /// On the first invariant broken, saying which.
    pub fn check_invariants(&self) {
        let t = &self.terrain;
        assert_eq!(
            self.node_range(self.root()),
            [0, 0, t.nx() - 1, t.ny() - 1],
            "the root covers the grid"
        );
        for id in self.node_ids() {
            let e = self.error_m(id);
            assert!(
                e >= self.measured_error_m(id),
                "{id:?}: saturated ≥ measured"
            );
            if self.level(id) == self.depth {
                assert_eq!(
                    self.measured_error_m(id),
                    0.0,
                    "{id:?}: finest level is exact"
                );
            }
            let r = self.node_range(id);
            let mut area = 0;
            for c in self.children(id) {
                assert!(
                    self.error_m(c) <= e,
                    "{id:?}: child {c:?} has a larger error"
                );
                assert_eq!(self.parent(c), Some(id), "{c:?}'s parent");
                let q = self.node_range(c);
                assert!(
                    q[0] >= r[0] && q[1] >= r[1] && q[2] <= r[2] && q[3] <= r[3],
                    "{c:?} outside {id:?}"
                );
                area += (q[2] - q[0]) * (q[3] - q[1]);
            }
            if self.level(id) < self.depth {
                assert_eq!(
                    area,
                    (r[2] - r[0]) * (r[3] - r[1]),
                    "{id:?}: children tile it"
                );
            }
            for (k, &d) in self.skirt_depth_m(id).iter().enumerate() {
                let border = [r[0] == 0, r[2] == t.nx() - 1, r[1] == 0, r[3] == t.ny() - 1][k];
                assert!(
                    border || d >= e + SKIRT_MARGIN_M,
                    "{id:?}: skirt {k} too shallow"
                );
            }
        }
    }
}

/// Distance from `p` to the box (0 inside).
fn box_distance(b: &Aabb3, p: DVec3) -> f64 {
    (p - p.clamp(b.min, b.max)).length()
}

/// The height of the coarse triangle pair over grid nodes `[xa, xb] × [ya, yb]` (diagonal from
/// `(xa, ya)` to `(xb, yb)`) at fractions `(fu, fv)` of the cell, from its corner heights.
#[inline]
pub(super) fn tri_height(h: [f64; 4], fu: f64, fv: f64) -> f64 {
    let [h00, h10, h01, h11] = h;
    if fu >= fv {
        h00 + fu * (h10 - h00) + fv * (h11 - h10)
    } else {
        h00 + fv * (h01 - h00) + fu * (h11 - h01)
    }
}

/// L∞ distance between one drawn coarse cell (two triangles) and the full-resolution mesh
/// under it. For a square cell both triangulations share every edge of the coarse one (its
/// diagonal runs along fine diagonals), so the difference is linear on each fine triangle and
/// its extremes are at samples. A non-square cell (clamped at the grid's border) has a
/// diagonal that crosses fine cells: the difference's extra vertices are where it crosses the
/// grid lines, evaluated too.
fn coarse_cell_error(t: &Terrain, xa: usize, ya: usize, xb: usize, yb: usize) -> f64 {
    let h = [t.raw(xa, ya), t.raw(xb, ya), t.raw(xa, yb), t.raw(xb, yb)];
    let (wx, wy) = ((xb - xa) as f64, (yb - ya) as f64);
    let mut e = 0.0f64;
    for j in ya..=yb {
        let fv = (j - ya) as f64 / wy;
        for i in xa..=xb {
            let fu = (i - xa) as f64 / wx;
            e = e.max((t.raw(i, j) - tri_height(h, fu, fv)).abs());
        }
    }
    if xb - xa != yb - ya {
        // The diagonal's crossings with vertical grid lines x = xa + k …
        for k in 1..xb - xa {
            let s = k as f64 / wx;
            let y = ya as f64 + s * wy;
            let j = (y.floor() as usize).min(yb - 1);
            let f = y - j as f64;
            let fine = t.raw(xa + k, j) * (1.0 - f) + t.raw(xa + k, j + 1) * f;
            e = e.max((fine - (h[0] + s * (h[3] - h[0]))).abs());
        }
        // … and with horizontal ones y = ya + m.
        for m in 1..yb - ya {
            let s = m as f64 / wy;
            let x = xa as f64 + s * wx;
            let i = (x.floor() as usize).min(xb - 1);
            let f = x - i as f64;
            let fine = t.raw(i, ya + m) * (1.0 - f) + t.raw(i + 1, ya + m) * f;
            e = e.max((fine - (h[0] + s * (h[3] - h[0]))).abs());
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::synthetic::{GridSpec, Synthetic};
    use glam::DVec2;

    fn smooth(nx: usize, ny: usize) -> Terrain {
        Terrain::synthetic(
            GridSpec::new(nx, ny, 10.0, DVec2::new(1000.0, 2000.0)),
            Synthetic::Smooth {
                seed: 7,
                relief_m: 200.0,
            },
        )
    }

    #[test]
    fn levels_strides_and_invariants() {
        let tree = TerrainTree::build(smooth(70, 41), &TreeOptions { tile_cells: 8 }).unwrap();
        tree.check_invariants();
        // 69 cells → 8 · 2^4 = 128 ≥ 69 > 64.
        assert_eq!(tree.depth(), 4);
        let lv = tree.levels();
        assert_eq!(
            lv.iter().map(|l| l.stride).collect::<Vec<_>>(),
            [16, 8, 4, 2, 1]
        );
        assert_eq!(lv[4].nodes, 9 * 5);
        assert_eq!(lv[4].declared_error_m, 0.0);
        for w in lv.windows(2) {
            assert!(w[0].declared_error_m >= w[1].declared_error_m);
        }
        assert!(lv[0].declared_error_m > 0.0);
    }

    #[test]
    fn bad_tile_sizes_are_refused() {
        for t in [0, 1, 3, 48, 2048] {
            assert!(TerrainTree::build(smooth(5, 5), &TreeOptions { tile_cells: t }).is_err());
        }
    }

    #[test]
    fn nodata_cells_are_not_drawn_by_coarser_levels() {
        let t = smooth(33, 33).with_nodata(|i, j| i == 10 && j == 10);
        let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
        tree.check_invariants();
        for id in tree.node_ids() {
            let s = tree.stride(id);
            for (b, _) in tree.occluder_cells(id) {
                // No occluder cell contains the nodata node (10 · 10 m from the origin).
                let (x, y) = (1100.0, 2100.0);
                assert!(
                    !(b[0] <= x && x <= b[2] && b[1] <= y && y <= b[3]),
                    "stride {s}: {b:?}"
                );
            }
        }
    }
}
