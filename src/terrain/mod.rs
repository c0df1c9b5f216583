//! Terrain: cities on real elevation grids.
//!
//! An elevation grid ([`blockwalk_importers::dem::DemGrid`], in its own CRS) becomes a
//! [`Terrain`]: a regular north-up grid in the city's metric world frame (f64), its samples kept
//! as they are when the DEM is already in that frame, else resampled bilinearly at the DEM's
//! ground spacing. The terrain gives the bilinear surface ([`Terrain::sample`]), the ground
//! under a footprint ([`Terrain::ground_under`]: exact min, max, relief and slope, and the
//! building's base by a [`BaseRule`]), and a level-of-detail tree for drawing and culling
//! ([`TerrainTree`]).
//!
//! # The tree
//!
//! **Tiles and levels.** A quadtree of square tiles of `T × T` cells (`T` = 32 by default).
//! Level `L` of a tree of depth `D` samples the full grid with stride `2^(D−L)`, so a tile at
//! level `L` spans `T·2^(D−L)` full-resolution cells; the root (level 0) covers the whole grid
//! and the finest level (stride 1) is the grid itself. Tiles are clamped at the grid's east and
//! north edges: their last coarse cell ends on the grid's last column or row. This is the
//! regular-grid, square-tile variant of the batched hierarchies of Di Benedetto, *Multiresolution
//! Techniques for Real-Time Visualization of Urban Environments and Terrains*, ch. 3 §3.2 (BDAM's
//! patches of many triangles refined a patch at a time), without C-BDAM's wavelet compression
//! (§3.3): a coarse tile's vertices are the grid's own samples (point sampling, as C-BDAM keeps
//! patch borders), so meshes are made on demand from the grid and the tree stores only per-node
//! numbers and a min pyramid.
//!
//! **Error.** Each node's mesh is drawn as two triangles per coarse cell with a fixed
//! (south-west–north-east) diagonal. Its measured error is the L∞ distance between that mesh and
//! the full-resolution mesh over the cells it draws, computed exactly (at every full-resolution
//! sample it covers, and for the border's clamped non-square cells also where the coarse
//! diagonal crosses grid lines: the difference of the two piecewise-linear surfaces has its
//! extremes there). As C-BDAM does (§3.3, "we keep under strict control each level's error"),
//! the bound is strict L∞, not a mean. Errors are then **saturated**: a node's error is the
//! largest of its own and its descendants' (the monotone errors of the BDAM / ROAM family,
//! Willmott et al., *Rendering of Large and Complex Urban Environments for Real time Heritage
//! Reconstructions*, §4.1, after Duchaineau et al.'s ROAM), so refining never increases the
//! error and a top-down cut is well defined. Each level declares the largest saturated error in
//! it ([`TerrainTree::levels`]).
//!
//! **Selection.** Per frame, top-down from the root ([`TerrainTree::select`]): a node outside the
//! frustum is left out with its subtree; a node whose projected error
//! `e · focal_px / max(distance from the eye to its box, near)` is at most τ pixels is drawn;
//! otherwise its children are visited, down to the finest level (Di Benedetto, ch. 3 §3.5.1,
//! the view-dependent cut by screen-space error; here a plain top-down traversal, since the
//! tree is small enough to walk whole each frame).
//!
//! **Cracks: skirts.** Neighbouring tiles of different levels do not share their edge vertices,
//! so cracks would open between them. Each tile hangs a vertical skirt under every edge that
//! has a neighbour, deep enough to close any crack: the tile's error plus the largest error of
//! any node that can lie across that edge in a cut, plus [`tree::SKIRT_MARGIN_M`] for the f32
//! rounding of local positions. Along a shared edge both tiles interpolate samples of the same
//! grid line and each is within its own error of the full-resolution surface there, so the two
//! edges are at most `e_A + e_B` apart. (Stitching would avoid the extra triangles, but would
//! make a tile's mesh depend on its neighbours' levels.)
//!
//! **Occluder level.** Each node also has a min-filtered occluder level
//! ([`TerrainTree::occluder_cells`]): the lowest full-resolution sample per coarse cell. The
//! drawn surface over a cell is a convex combination of its samples, so it never goes below
//! that height: a block from below up to it is a conservative occluder (the min pyramid of
//! Willmott et al. §3.2, over heights).
//!
//! **Nodata.** A nodata sample is `NaN` in the grid and is never read as 0. Meshes leave out the
//! cells that have a nodata sample under them (holes): at stride `s`, a coarse cell is drawn only
//! when every full-resolution sample it covers has a height, so coarse levels' holes are the
//! full-resolution holes grown to whole coarse cells. Errors are measured over the drawn cells.
//!
//! **Memory.** The tree stores per node its box, its errors and skirt depths (about 100 bytes),
//! and the min pyramid for strides ≥ 2 (a third of the grid's cells at most): about a third of
//! the grid's own memory ([`TerrainTree::heap_bytes`], [`Terrain::heap_bytes`]).
//!
//! - [`grid`]: [`Terrain`] from a DEM ([`Terrain::from_dem`]), [`TerrainReport`], sampling.
//! - [`ground`]: [`Terrain::ground_under`], [`BaseRule`], [`FootprintGround`].
//! - [`tree`]: [`TerrainTree`], errors, selection, skirts, occluder cells.
//! - [`mesh`]: [`TerrainMesh`] of a node, and of the full grid.
//! - [`synthetic`]: planes, cliffs, cones and smooth hills for tests and benches.

pub mod grid;
pub mod ground;
pub mod mesh;
pub mod synthetic;
pub mod tree;

pub use grid::{Terrain, TerrainError, TerrainOptions, TerrainReport};
pub use ground::{BaseRule, FootprintGround, GroundError};
pub use mesh::TerrainMesh;
pub use synthetic::{GridSpec, Synthetic};
pub use tree::{LevelStats, NodeId, TerrainTree, TreeError, TreeOptions, TreeSummary};
