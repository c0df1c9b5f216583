//! A terrain surface for the exports: a triangulated irregular network (TIN) in metric world
//! coordinates, as the CityJSON ([`super::cityjson`]), glTF ([`super::gltf`]) and 3D Tiles
//! ([`crate::tiles`]) writers take it beside the buildings.
//!
//! The exports know nothing of where a terrain comes from: a DEM, a survey, a generated surface
//! all arrive here as vertices and counter-clockwise triangles. [`TerrainTin::from_grid`] makes
//! one from a regular height grid (cells touching a missing height left out).

use glam::{DVec2, DVec3};

use crate::city::{LocalFrame, Mesh};

/// The terrain's colour in the exports (linear RGB; the `.glb` material's base colour and the
/// terrain tiles' vertex colour): a green grey, unlike the buildings' warm grey.
pub const TERRAIN_COLOR: [f32; 3] = [0.42, 0.50, 0.36];

/// A terrain surface to export: a TIN in metric world coordinates (f64), CCW seen from above.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TerrainTin {
    /// Vertices, metric world coordinates (the city's frame; z is the height).
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
}

/// Why a terrain cannot be made or exported.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TerrainError {
    /// The height grid does not have `nx × ny` heights, or fewer than 2 × 2 nodes.
    #[error("a height grid of {nx} × {ny} nodes needs at least 2 × 2 nodes and nx·ny heights, got {heights}")]
    GridSize {
        /// Nodes along x.
        nx: usize,
        /// Nodes along y.
        ny: usize,
        /// Heights given.
        heights: usize,
    },
    /// The grid's spacing or origin is not a finite positive length / a finite point.
    #[error(
        "a height grid needs a finite origin and a finite spacing above 0 (spacing {spacing} m)"
    )]
    Grid {
        /// The spacing given.
        spacing: f64,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("terrain triangle {triangle} refers to vertex {vertex}, of {vertices}")]
    Index {
        /// The triangle.
        triangle: usize,
        /// The index.
        vertex: u32,
        /// Vertices in the TIN.
        vertices: usize,
    },
    /// A vertex is not finite.
    #[error("terrain vertex {0} is not finite")]
    NotFinite(usize),
    /// A triangle is clockwise or flat seen from above (a TIN's are counter-clockwise).
    #[error("terrain triangle {0} is not counter-clockwise seen from above (plan area ≤ 0)")]
    Orientation(usize),
}

impl TerrainTin {
    /// The TIN of a regular height grid: node `(i, j)` lies at `origin + (i, j) · spacing` (x east,
    /// y north, world metres) with height `heights[j · nx + i]`. Each cell whose four corner
    /// heights are finite becomes two counter-clockwise triangles (split along the diagonal from
    /// its south-west to its north-east corner); a cell touching a missing height (NaN, or any
    /// non-finite value) is left out, and so are the nodes no triangle uses. Vertices are in row
    /// order (`j` then `i`), triangles in cell order: the same grid gives the same TIN.
    ///
    /// # Errors
    /// [`TerrainError::GridSize`] when `heights` is not `nx · ny` long or the grid has fewer than
    /// 2 × 2 nodes, [`TerrainError::Grid`] for a spacing that is not finite and positive or an
    /// origin that is not finite.
    ///
    /// # Examples
    /// ```
    /// use blockwalk::city::export::terrain::TerrainTin;
    /// use glam::DVec2;
    /// // 3 × 2 nodes, one missing: only the western cell (two triangles) is left.
    /// let h = [10.0, 11.0, 12.0, 10.5, 11.5, f64::NAN];
    /// let tin = TerrainTin::from_grid(DVec2::new(1000.0, 2000.0), 5.0, 3, 2, &h).unwrap();
    /// assert_eq!(tin.triangles.len(), 2);
    /// assert_eq!(tin.vertices.len(), 4);
    /// ```
    pub fn from_grid(
        origin: DVec2,
        spacing: f64,
        nx: usize,
        ny: usize,
        heights: &[f64],
    ) -> Result<TerrainTin, TerrainError> {
        if nx < 2 || ny < 2 || nx.checked_mul(ny) != Some(heights.len()) {
            return Err(TerrainError::GridSize {
                nx,
                ny,
                heights: heights.len(),
            });
        }
        if !(spacing.is_finite() && spacing > 0.0 && origin.is_finite()) {
            return Err(TerrainError::Grid { spacing });
        }
        let h = |i: usize, j: usize| heights[j * nx + i];
        let cell_ok = |i: usize, j: usize| {
            h(i, j).is_finite()
                && h(i + 1, j).is_finite()
                && h(i + 1, j + 1).is_finite()
                && h(i, j + 1).is_finite()
        };
        // Nodes used by a kept cell, numbered in row order.
        let mut used = vec![false; heights.len()];
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                if cell_ok(i, j) {
                    for (a, b) in [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)] {
                        used[b * nx + a] = true;
                    }
                }
            }
        }
        let mut index = vec![u32::MAX; heights.len()];
        let mut vertices = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                if used[j * nx + i] {
                    index[j * nx + i] = vertices.len() as u32;
                    let p = origin + DVec2::new(i as f64, j as f64) * spacing;
                    vertices.push(p.extend(h(i, j)));
                }
            }
        }
        let mut triangles = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                if cell_ok(i, j) {
                    let k = |a: usize, b: usize| index[b * nx + a];
                    let (sw, se, ne, nw) = (k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1));
                    triangles.push([sw, se, ne]);
                    triangles.push([sw, ne, nw]);
                }
            }
        }
        Ok(TerrainTin {
            vertices,
            triangles,
        })
    }

    /// Checks what every export relies on: indices in range, finite vertices, every triangle
    /// counter-clockwise with a positive plan area.
    ///
    /// # Errors
    /// The first problem found.
    pub fn check(&self) -> Result<(), TerrainError> {
        if let Some(k) = self.vertices.iter().position(|v| !v.is_finite()) {
            return Err(TerrainError::NotFinite(k));
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v as usize >= self.vertices.len()) {
                return Err(TerrainError::Index {
                    triangle: t,
                    vertex: v,
                    vertices: self.vertices.len(),
                });
            }
            if plan_area2(self.corners(t)) <= 0.0 {
                return Err(TerrainError::Orientation(t));
            }
        }
        Ok(())
    }

    /// The three corners of triangle `t`, world coordinates.
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|v| self.vertices[v as usize])
    }

    /// The centroid of triangle `t`, world coordinates.
    pub fn centroid(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners(t);
        (a + b + c) / 3.0
    }

    /// Minimum and maximum corners of the vertices that triangles use (`None` without
    /// triangles).
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut it = self
            .triangles
            .iter()
            .flatten()
            .map(|&v| self.vertices[v as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Unit vertex normals from the triangles: each vertex's is the sum of its triangles' normals
    /// weighted by their areas (the cross products), normalised; straight up for a vertex no
    /// triangle uses. In f64, from the world coordinates (a normal is the same in the local
    /// frame).
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.vertices.len()];
        for t in 0..self.triangles.len() {
            let [a, b, c] = self.corners(t);
            let w = (b - a).cross(c - a);
            for &v in &self.triangles[t] {
                n[v as usize] += w;
            }
        }
        n.into_iter()
            .map(|v| v.try_normalize().unwrap_or(DVec3::Z))
            .collect()
    }

    /// The TIN as a mesh in `frame`'s local coordinates (f32, z up): every vertex (shared
    /// between its triangles, so neighbouring triangles meet exactly), the normals of
    /// [`TerrainTin::vertex_normals`], the triangles in order. No appearance.
    pub fn local_mesh(&self, frame: &LocalFrame) -> Mesh {
        Mesh {
            positions: self.vertices.iter().map(|&p| frame.to_local(p)).collect(),
            normals: self
                .vertex_normals()
                .into_iter()
                .map(LocalFrame::round_to_f32)
                .collect(),
            indices: self.triangles.iter().flatten().copied().collect(),
            appearance: Vec::new(),
            styles: Vec::new(),
        }
    }
}

/// Twice the signed plan area of a triangle (positive when counter-clockwise seen from above).
fn plan_area2([a, b, c]: [DVec3; 3]) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// The TIN of `city`'s terrain when it stands on one (`None` for a flat city), or why it
/// cannot be made, as an export error naming `file`.
pub fn city_tin(
    city: &crate::city::City,
    file: &std::path::Path,
) -> Result<Option<TerrainTin>, super::ExportError> {
    city.terrain
        .as_deref()
        .map(|t| {
            TerrainTin::from_terrain(t).map_err(|source| super::ExportError::Terrain {
                file: file.to_path_buf(),
                source,
            })
        })
        .transpose()
}

impl TerrainTin {
    /// The full-resolution surface of `terrain` (metric world coordinates): two triangles per
    /// cell, as [`TerrainTin::from_grid`] makes them (the same diagonal as the drawn terrain),
    /// cells touching nodata left out.
    ///
    /// # Errors
    /// As [`TerrainTin::from_grid`].
    pub fn from_terrain(terrain: &crate::terrain::Terrain) -> Result<TerrainTin, TerrainError> {
        let (o, s) = (terrain.origin(), terrain.spacing());
        let mut tin = Self::from_grid(o, s.x, terrain.nx(), terrain.ny(), terrain.heights())?;
        if s.y != s.x {
            // Rows were laid out at the x spacing: put each back on its own row.
            for v in &mut tin.vertices {
                let j = ((v.y - o.y) / s.x).round();
                v.y = o.y + j * s.y;
            }
        }
        Ok(tin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_with_a_hole_leaves_out_the_cells_around_it() {
        // 4 × 4 nodes, the node (1, 1) missing: the 4 cells around it are left out, 5 kept.
        let mut h: Vec<f64> = (0..16).map(|k| k as f64).collect();
        h[4 + 1] = f64::NAN;
        let tin = TerrainTin::from_grid(DVec2::new(10.0, 20.0), 2.0, 4, 4, &h).unwrap();
        assert_eq!(tin.triangles.len(), 10);
        // Only the nodes of kept cells: not the missing one, nor (0, 0), (1, 0) and (0, 1),
        // which only left-out cells use.
        assert_eq!(tin.vertices.len(), 12);
        assert!(!tin.vertices.iter().any(|v| v.x < 14.0 && v.y < 22.5));
        assert!(tin.vertices.iter().all(|v| v.z.is_finite()));
        assert!(tin.check().is_ok());
        // Node (3, 2) at origin + (6, 4) with height 2·4 + 3.
        assert!(tin.vertices.contains(&DVec3::new(16.0, 24.0, 11.0)));
        // Plan area: 5 cells of 4 m².
        let area: f64 = (0..tin.triangles.len())
            .map(|t| 0.5 * plan_area2(tin.corners(t)))
            .sum();
        assert_eq!(area, 20.0);
    }

    #[test]
    fn bad_grids_and_tins_are_refused() {
        assert!(TerrainTin::from_grid(DVec2::ZERO, 1.0, 2, 2, &[0.0; 3]).is_err());
        assert!(TerrainTin::from_grid(DVec2::ZERO, 0.0, 2, 2, &[0.0; 4]).is_err());
        assert!(TerrainTin::from_grid(DVec2::ZERO, 1.0, 1, 4, &[0.0; 4]).is_err());
        let mut tin = TerrainTin::from_grid(DVec2::ZERO, 1.0, 2, 2, &[0.0; 4]).unwrap();
        assert!(tin.check().is_ok());
        tin.triangles[1].swap(1, 2);
        assert_eq!(tin.check(), Err(TerrainError::Orientation(1)));
        tin.triangles[1] = [0, 1, 9];
        assert!(matches!(
            tin.check(),
            Err(TerrainError::Index { vertex: 9, .. })
        ));
    }

    #[test]
    fn normals_of_a_plane_are_its_normal() {
        // z = 0.5 x: the normal is (-0.5, 0, 1) normalised, at every vertex.
        let h: Vec<f64> = (0..9).map(|k| 0.5 * (k % 3) as f64 * 3.0).collect();
        let tin = TerrainTin::from_grid(DVec2::ZERO, 3.0, 3, 3, &h).unwrap();
        let want = DVec3::new(-0.5, 0.0, 1.0).normalize();
        for n in tin.vertex_normals() {
            assert!((n - want).length() < 1e-12, "{n:?}");
        }
    }
}
