//! Terrain meshes in the local frame: a node's tile (with its skirts) and the full-resolution
//! reference.

use super::tree::{NodeId, TerrainTree};
use super::Terrain;
use crate::geom::LocalFrame;
use glam::{DVec3, Vec3};

/// A terrain mesh in the local frame (f32, through [`LocalFrame`]): triangles counter-clockwise
/// seen from above (skirts facing out of their tile).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TerrainMesh {
    /// Vertex positions, local frame.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals from the full grid's gradient (a skirt vertex has its edge vertex's).
    pub normals: Vec<Vec3>,
    /// Triangles, three indices each: the surface first, then the skirts.
    pub indices: Vec<u32>,
    /// How many of `indices` are the surface's (the rest are skirts).
    pub surface_indices: usize,
}

impl TerrainMesh {
    /// Triangles in all.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// Builds a mesh over the grid columns `xs` and rows `ys` (increasing grid node indices),
/// drawing cell `(k, m)` when `drawn(k, m)`.
struct Builder<'a> {
    terrain: &'a Terrain,
    frame: &'a LocalFrame,
    xs: Vec<usize>,
    ys: Vec<usize>,
    map: Vec<u32>,
    mesh: TerrainMesh,
}

impl<'a> Builder<'a> {
    fn new(terrain: &'a Terrain, frame: &'a LocalFrame, xs: Vec<usize>, ys: Vec<usize>) -> Self {
        let map = vec![u32::MAX; xs.len() * ys.len()];
        Self {
            terrain,
            frame,
            xs,
            ys,
            map,
            mesh: TerrainMesh::default(),
        }
    }

    fn push_vertex(&mut self, i: usize, j: usize, dz: f64) -> u32 {
        let t = self.terrain;
        let p = DVec3::new(t.x(i), t.y(j), t.raw(i, j) - dz);
        let g = t.gradient_at_node(i, j);
        let n = DVec3::new(-g.x, -g.y, 1.0).normalize();
        self.mesh.positions.push(self.frame.to_local(p));
        self.mesh.normals.push(LocalFrame::round_to_f32(n));
        (self.mesh.positions.len() - 1) as u32
    }

    fn vertex(&mut self, k: usize, m: usize) -> u32 {
        let slot = m * self.xs.len() + k;
        if self.map[slot] == u32::MAX {
            self.map[slot] = self.push_vertex(self.xs[k], self.ys[m], 0.0);
        }
        self.map[slot]
    }

    fn surface(&mut self, drawn: impl Fn(usize, usize) -> bool) {
        for m in 0..self.ys.len() - 1 {
            for k in 0..self.xs.len() - 1 {
                if !drawn(k, m) {
                    continue;
                }
                let a = self.vertex(k, m);
                let b = self.vertex(k + 1, m);
                let c = self.vertex(k, m + 1);
                let d = self.vertex(k + 1, m + 1);
                // The south-west–north-east diagonal, at every level.
                self.mesh.indices.extend_from_slice(&[a, b, d, a, d, c]);
            }
        }
        self.mesh.surface_indices = self.mesh.indices.len();
    }

    /// A skirt `depth` deep under the edge from coarse vertex `p` to `q` (`(k, m)` pairs),
    /// facing right of the direction `p → q` seen from above.
    fn skirt(&mut self, p: (usize, usize), q: (usize, usize), depth: f64) {
        let top_p = self.vertex(p.0, p.1);
        let top_q = self.vertex(q.0, q.1);
        let bottom_p = self.push_vertex(self.xs[p.0], self.ys[p.1], depth);
        let bottom_q = self.push_vertex(self.xs[q.0], self.ys[q.1], depth);
        self.mesh
            .indices
            .extend_from_slice(&[top_p, top_q, bottom_q, top_p, bottom_q, bottom_p]);
    }
}

/// The increasing node indices `a, a + s, …` up to `b`, with `b` itself last (the clamped end).
fn lattice(a: usize, b: usize, s: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (a..b).step_by(s).collect();
    v.push(b);
    v
}

impl TerrainTree {
    /// The mesh of node `id` as drawn: its coarse grid (every `stride`-th sample, and the last
    /// column and row of the grid where the tile is clamped), two triangles per coarse cell
    /// with the south-west–north-east diagonal, and vertical skirts under every edge that has a
    /// neighbour ([`TerrainTree::skirt_depth_m`] deep). Coarse cells with a nodata sample under
    /// them are left out (holes), and so are the skirts along them. Positions go through
    /// `frame` ([`LocalFrame::to_local`]); normals come from the full grid's gradient.
    pub fn node_mesh(&self, id: NodeId, frame: &LocalFrame) -> TerrainMesh {
        let t = self.terrain();
        let s = self.stride(id);
        let l = self.level(id);
        let [i0, j0, i1, j1] = self.node_range(id);
        let mut b = Builder::new(t, frame, lattice(i0, i1, s), lattice(j0, j1, s));
        let (xs, ys) = (b.xs.clone(), b.ys.clone());
        let drawn = |k: usize, m: usize| self.cell_drawn(l, xs[k] / s, ys[m] / s);
        b.surface(drawn);
        let [west, east, south, north] = self.skirt_depth_m(id);
        let (kx, my) = (xs.len() - 1, ys.len() - 1);
        for m in 0..my {
            if west > 0.0 && drawn(0, m) {
                b.skirt((0, m), (0, m + 1), west);
            }
            if east > 0.0 && drawn(kx - 1, m) {
                b.skirt((kx, m + 1), (kx, m), east);
            }
        }
        for k in 0..kx {
            if south > 0.0 && drawn(k, 0) {
                b.skirt((k + 1, 0), (k, 0), south);
            }
            if north > 0.0 && drawn(k, my - 1) {
                b.skirt((k, my), (k + 1, my), north);
            }
        }
        b.mesh
    }

    /// The full-resolution mesh ([`Terrain::full_mesh`]).
    pub fn full_mesh(&self, frame: &LocalFrame) -> TerrainMesh {
        self.terrain().full_mesh(frame)
    }
}

impl Terrain {
    /// The full-resolution mesh, the reference the levels are measured and compared against:
    /// two triangles per cell (the south-west–north-east diagonal), cells with a nodata corner
    /// left out, positions through `frame`, normals from the grid's gradient.
    pub fn full_mesh(&self, frame: &LocalFrame) -> TerrainMesh {
        let mut b = Builder::new(
            self,
            frame,
            (0..self.nx()).collect(),
            (0..self.ny()).collect(),
        );
        b.surface(|k, m| {
            !(self.raw(k, m).is_nan()
                || self.raw(k + 1, m).is_nan()
                || self.raw(k, m + 1).is_nan()
                || self.raw(k + 1, m + 1).is_nan())
        });
        b.mesh
    }
}
