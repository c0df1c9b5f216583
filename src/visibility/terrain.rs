//! A terrain as the renderers and the oracle draw it: tile meshes (local frame), a per-frame cut
//! of them, and the full-resolution mesh that is the truth.
//!
//! The terrain itself (a DEM, a quadtree of tiles and its selection by projected error) lives
//! elsewhere; everything that draws only sees [`TerrainDraw`]. [`FixedTerrain`] is the simple
//! implementation (every tile, every frame), and [`height_mesh`] / [`FixedTerrain::from_heights`]
//! make a terrain from a height function on a grid (tests and callers without LOD).
//!
//! # How a terrain is drawn
//! - **Oracle** ([`super::oracle`], [`super::MeshOracle::with_terrain`]): the full mesh goes into
//!   the z-buffer first, with the reserved id [`TERRAIN_ID`], as an occluder; it is never
//!   reported as a visible block ([`super::oracle::IdBuffer::visible`] leaves it out).
//! - **Lit frames** (the CPU [`super::CpuFrameRenderer::with_terrain`] and the GPU mesh
//!   renderer): the cut's tiles, depth-tested and writing depth, before the blocks and before
//!   the far passes, in [`crate::city::appearance::TERRAIN`] lit by
//!   [`crate::city::appearance::shade`] with the normal of each triangle's first vertex (flat
//!   shading, as buildings are shaded).
//! - **Id frames**: the cut's tiles with the id [`TERRAIN_ID`].
//! - **The flat ground** (the ground plane at z = 0, the street strips and the blocks' ground
//!   of `Scene::ground`, drawn with the depth test always passing): not drawn when a terrain is
//!   given, see [`draws_flat_ground`], the one place that decides it. (Draping the street and
//!   block layers over the terrain is future work.)

use crate::city::Mesh;
use crate::geom::Camera;
use glam::DVec3;
use std::sync::Arc;

/// The id terrain pixels carry in id frames (the oracle's [`super::oracle::IdBuffer`] and the
/// GPU's id pass, where it is written as `id + 1` in 24 bits like every block): never a block's
/// id, and never reported as a visible block. Block ids must be below it.
pub const TERRAIN_ID: u32 = 0x00FF_FFFE;

/// A terrain as the renderers draw it: meshes of tiles (local frame), a per-frame cut.
pub trait TerrainDraw: Sync {
    /// Every tile mesh, indexed by tile; built once. (`crate::city::Mesh`: positions, normals,
    /// indices, appearance may be empty.)
    fn tiles(&self) -> &[Mesh];
    /// The tiles to draw for `camera` at `size` pixels (indices into `tiles`), appended to `out`.
    fn cut(&self, camera: &Camera, size: (u32, u32), out: &mut Vec<usize>);
    /// The terrain at full resolution (the truth the oracle and the reference images use).
    fn full(&self) -> &Mesh;
}

/// A terrain shared by a scene and the renderers built from it.
pub type SharedTerrain = Arc<dyn TerrainDraw + Send>;

/// The one rule for the flat ground under a terrain: whether the ground plane (z = 0) and the flat
/// ground layers (`Scene::ground`: the blocks' ground and the street strips at z = 0, drawn with
/// the depth test always passing) are drawn. They would paint over the terrain (or show through
/// it), so with a terrain they are left out; draping them over it is future work.
pub const fn draws_flat_ground(has_terrain: bool) -> bool {
    !has_terrain
}

/// The simplest terrain: fixed tiles, all drawn every frame, and the full mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FixedTerrain {
    /// The tile meshes (local frame).
    pub tiles: Vec<Mesh>,
    /// The full-resolution mesh (local frame).
    pub full: Mesh,
}

impl FixedTerrain {
    /// A terrain of `tiles`, its full mesh their union.
    pub fn new(tiles: Vec<Mesh>) -> Self {
        let mut full = Mesh::default();
        for t in &tiles {
            full.append(t);
        }
        Self { tiles, full }
    }

    /// The height field `height(x, y)` (local metres) on the grid `grid`, cut into
    /// `tiles.0 × tiles.1` tiles of whole cells (see [`height_mesh`]); the full mesh is the
    /// whole grid. Each grid vertex is computed once the same way, so the tiles hold exactly the
    /// full mesh's triangles.
    pub fn from_heights(
        grid: &HeightGrid,
        tiles: (usize, usize),
        height: impl Fn(f64, f64) -> f64,
    ) -> Self {
        let (tx, ty) = (
            tiles.0.clamp(1, grid.cells.0.max(1)),
            tiles.1.clamp(1, grid.cells.1.max(1)),
        );
        let split = |n: usize, parts: usize, k: usize| k * n / parts;
        let mut out = Vec::with_capacity(tx * ty);
        for j in 0..ty {
            for i in 0..tx {
                let (i0, i1) = (split(grid.cells.0, tx, i), split(grid.cells.0, tx, i + 1));
                let (j0, j1) = (split(grid.cells.1, ty, j), split(grid.cells.1, ty, j + 1));
                out.push(grid_cells_mesh(grid, (i0, i1), (j0, j1), &height));
            }
        }
        Self {
            tiles: out,
            full: height_mesh(grid, &height),
        }
    }
}

impl TerrainDraw for FixedTerrain {
    fn tiles(&self) -> &[Mesh] {
        &self.tiles
    }
    fn cut(&self, _camera: &Camera, _size: (u32, u32), out: &mut Vec<usize>) {
        out.extend(0..self.tiles.len());
    }
    fn full(&self) -> &Mesh {
        &self.full
    }
}

/// A regular grid in the local frame: `cells.0 × cells.1` square cells of `step_m` metres, the
/// lower-left corner at `origin` (x, y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightGrid {
    /// Lower-left corner (local x, y), metres.
    pub origin: [f64; 2],
    /// Cell side, metres (> 0).
    pub step_m: f64,
    /// Cells along x and y.
    pub cells: (usize, usize),
}

impl HeightGrid {
    /// The grid vertex `(i, j)`'s position (x, y).
    pub fn xy(&self, i: usize, j: usize) -> (f64, f64) {
        (
            self.origin[0] + i as f64 * self.step_m,
            self.origin[1] + j as f64 * self.step_m,
        )
    }
}

/// The height field `height(x, y)` (local metres, f64) on `grid` as one mesh: a vertex per grid
/// point at `(x, y, height(x, y))` rounded once to f32, two triangles per cell (split along the
/// diagonal from its lower-left corner), counter-clockwise seen from above; vertex normals from
/// central differences of `height` at the grid step. No appearance (the renderers colour terrain
/// themselves).
pub fn height_mesh(grid: &HeightGrid, height: impl Fn(f64, f64) -> f64) -> Mesh {
    grid_cells_mesh(grid, (0, grid.cells.0), (0, grid.cells.1), &height)
}

fn grid_cells_mesh(
    grid: &HeightGrid,
    (i0, i1): (usize, usize),
    (j0, j1): (usize, usize),
    height: &dyn Fn(f64, f64) -> f64,
) -> Mesh {
    let mut m = Mesh::default();
    if i1 <= i0 || j1 <= j0 {
        return m;
    }
    let h = grid.step_m;
    let nx = i1 - i0 + 1;
    for j in j0..=j1 {
        for i in i0..=i1 {
            let (x, y) = grid.xy(i, j);
            let z = height(x, y);
            m.positions.push(DVec3::new(x, y, z).as_vec3());
            let dx = (height(x + h, y) - height(x - h, y)) / (2.0 * h);
            let dy = (height(x, y + h) - height(x, y - h)) / (2.0 * h);
            let n = DVec3::new(-dx, -dy, 1.0).normalize_or(DVec3::Z);
            m.normals.push(n.as_vec3());
        }
    }
    let v = |i: usize, j: usize| ((j - j0) * nx + (i - i0)) as u32;
    for j in j0..j1 {
        for i in i0..i1 {
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            m.indices.extend([a, b, c, a, c, d]);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn tiles_hold_exactly_the_full_meshs_triangles() {
        let grid = HeightGrid {
            origin: [-10.0, 5.0],
            step_m: 2.5,
            cells: (7, 5),
        };
        let f = |x: f64, y: f64| 0.3 * x + (0.2 * y).sin() * 4.0;
        let t = FixedTerrain::from_heights(&grid, (3, 2), f);
        assert_eq!(t.tiles.len(), 6);
        let tris = |m: &Mesh| -> Vec<[[u32; 3]; 3]> {
            let mut v: Vec<[[u32; 3]; 3]> = m
                .indices
                .chunks_exact(3)
                .map(|t| {
                    t.iter()
                        .map(|&k| m.positions[k as usize].to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap()
                })
                .collect();
            v.sort_unstable();
            v
        };
        let mut from_tiles: Vec<[[u32; 3]; 3]> = t.tiles.iter().flat_map(&tris).collect();
        from_tiles.sort_unstable();
        assert_eq!(from_tiles, tris(&t.full));
        assert_eq!(t.full.triangle_count(), 2 * 7 * 5);
        // Counter-clockwise from above, normals up.
        for tr in t.full.indices.chunks_exact(3) {
            let p: Vec<Vec3> = tr.iter().map(|&k| t.full.positions[k as usize]).collect();
            assert!((p[1] - p[0]).cross(p[2] - p[0]).z > 0.0);
        }
        assert!(t.full.normals.iter().all(|n| n.z > 0.0));
        let mut cut = Vec::new();
        t.cut(&Camera::new(DVec3::ZERO, 0.0, 0.0), (8, 8), &mut cut);
        assert_eq!(cut, (0..6).collect::<Vec<_>>());
        assert!(!draws_flat_ground(true) && draws_flat_ground(false));
    }
}
