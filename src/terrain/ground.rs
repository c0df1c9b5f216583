//! Base heights under building footprints: the ground under a polygon, found exactly where its
//! extremes can be, on both surfaces the terrain has: the bilinear one ([`Terrain::sample`]) and
//! the drawn one ([`Terrain::sample_drawn`], two triangles per cell).
//!
//! # Why both surfaces
//! The drawn terrain splits each cell along its south-west–north-east diagonal; inside a cell it
//! differs from the bilinear surface by up to a quarter of the cell's twist
//! `h00 + h11 − h10 − h01`, above or below (metres on a 30 m grid of steep mountains). A base
//! taken from the bilinear surface alone can float above the drawn ground along a wall: a gap
//! opens under the building, the frame shows what lies behind through it, and the occlusion
//! culler, whose walls stand for solid facades down to the ground (and for the ground below
//! their bases), would hide it. So the lowest point counts both surfaces: the building then
//! reaches the drawn ground everywhere along its walls (and the bilinear one too).

use super::Terrain;
use crate::geom::predicates::{point_in_polygon, Location};
use geo_types::{Coord, Polygon};
use glam::DVec2;
use serde::Serialize;

/// Which height under a footprint is the building's base.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub enum BaseRule {
    /// The lowest point of the terrain under the footprint (as 3dfier's LoD1 prisms do), on the
    /// bilinear and the drawn surface both (see the module doc): the building reaches the ground
    /// everywhere, and is buried on the uphill side.
    #[default]
    Min,
    /// The given percentile (0 … 100, linear between order statistics) of the terrain heights
    /// sampled under the footprint, on both surfaces (see [`Terrain::ground_under`]); 0 is
    /// [`BaseRule::Min`].
    Percentile(f64),
}

/// The terrain under one footprint.
///
/// # Units
/// Metres and degrees.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FootprintGround {
    /// The base height by the rule asked for.
    pub base_m: f64,
    /// The lowest point of the terrain under the footprint, of the bilinear surface and of the
    /// drawn triangles (exact).
    pub min_m: f64,
    /// Where the lowest point is (world x, y; on the footprint's boundary or inside it).
    pub min_at: [f64; 2],
    /// The highest point of the terrain under the footprint, of the bilinear surface and of the
    /// drawn triangles (exact).
    pub max_m: f64,
    /// `max_m − min_m`.
    pub relief_m: f64,
    /// The steepest slope of the terrain under the footprint, degrees from horizontal: the
    /// largest gradient of the bilinear surface over the cells the footprint covers (exact: the
    /// squared gradient is convex in each cell, so its maximum over the part of a cell under
    /// the footprint is at a vertex of that part, and those vertices are all sampled).
    pub slope_deg: f64,
    /// Points sampled (vertices, edge crossings with grid lines and cell diagonals, grid nodes
    /// inside, extrema along edges).
    pub samples: usize,
    /// Of these, the points whose height is nodata.
    pub nodata_samples: usize,
}

/// Why a footprint's ground cannot be given.
#[derive(Debug, thiserror::Error)]
pub enum GroundError {
    /// The footprint is not (wholly) on the grid.
    #[error("footprint {footprint:?} is not inside the terrain grid {grid:?} ([xmin, ymin, xmax, ymax], metres)")]
    OutsideGrid {
        /// The footprint's box.
        footprint: [f64; 4],
        /// The grid's extent.
        grid: [f64; 4],
    },
    /// Part or all of the terrain under the footprint is nodata. `partial` is the ground over
    /// the points that have a height (when there is one): the caller decides.
    #[error("{nodata_samples} of {samples} terrain samples under the footprint are nodata")]
    Nodata {
        /// Points sampled.
        samples: usize,
        /// Of these, nodata.
        nodata_samples: usize,
        /// The ground over the points with a height, if any.
        partial: Option<Box<FootprintGround>>,
    },
    /// The footprint or the rule cannot be used.
    #[error("{0}")]
    Invalid(String),
}

impl Terrain {
    /// The ground under `footprint` (world coordinates, any ring orientation, holes allowed).
    ///
    /// The bilinear surface has no strict extremum inside a cell (a bilinear patch is a saddle
    /// or a ruled surface), and along a grid line it is linear; so over the part of a cell under
    /// the footprint its extremes lie on the footprint's edges, at grid nodes inside the
    /// footprint, or where an edge crosses a grid line. Along a footprint edge inside a cell the
    /// surface is a quadratic in the edge's parameter, with at most one interior extremum.
    /// Sampling exactly these points (footprint vertices, the crossings of footprint edges with
    /// grid lines, the grid nodes inside, the interior extremum of each edge piece) gives the
    /// true minimum and maximum of the surface under the footprint, not an estimate. The drawn
    /// surface ([`Terrain::sample_drawn`]) is linear on each triangle, so its extremes under the
    /// footprint lie at its vertices, at the crossings of its edges with grid lines and cell
    /// diagonals, or at grid nodes inside; the diagonal crossings are sampled too, and every
    /// point gives both surfaces' heights (the drawn one where the cell is drawn). The minimum,
    /// maximum and percentiles are over both (see the module doc).
    ///
    /// # Errors
    /// [`GroundError::OutsideGrid`] when the footprint's box is not inside the grid;
    /// [`GroundError::Nodata`] (with the counts, and the ground over the rest) when a sampled
    /// point has no height; [`GroundError::Invalid`] for a footprint with a non-finite or no
    /// vertex, or a percentile outside 0 … 100.
    pub fn ground_under(
        &self,
        footprint: &Polygon<f64>,
        rule: BaseRule,
    ) -> Result<FootprintGround, GroundError> {
        if let BaseRule::Percentile(p) = rule {
            if !(0.0..=100.0).contains(&p) {
                return Err(GroundError::Invalid(format!(
                    "percentile {p} is outside 0 … 100"
                )));
            }
        }
        let rings: Vec<&[Coord<f64>]> = std::iter::once(&footprint.exterior().0[..])
            .chain(footprint.interiors().iter().map(|r| &r.0[..]))
            .collect();
        let mut bb = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for c in rings.iter().flat_map(|r| r.iter()) {
            if !(c.x.is_finite() && c.y.is_finite()) {
                return Err(GroundError::Invalid(format!(
                    "footprint vertex ({}, {}) is not finite",
                    c.x, c.y
                )));
            }
            bb = [
                bb[0].min(c.x),
                bb[1].min(c.y),
                bb[2].max(c.x),
                bb[3].max(c.y),
            ];
        }
        if bb[0] > bb[2] {
            return Err(GroundError::Invalid("footprint without vertices".into()));
        }
        let g = self.extent();
        if bb[0] < g[0] || bb[1] < g[1] || bb[2] > g[2] || bb[3] > g[3] {
            return Err(GroundError::OutsideGrid {
                footprint: bb,
                grid: g,
            });
        }

        // Candidate points in grid coordinates (u, v).
        let mut ts: Vec<f64> = Vec::with_capacity(16);
        let mut grad2 = 0.0f64;
        let mut pts: Vec<DVec2> = Vec::new();
        for ring in &rings {
            for w in ring.windows(2) {
                let a = self.grid_uv(DVec2::new(w[0].x, w[0].y));
                let b = self.grid_uv(DVec2::new(w[1].x, w[1].y));
                self.edge_candidates(a, b, &mut pts, &mut ts, &mut grad2);
            }
            // An unclosed ring's closing edge.
            if let (Some(f), Some(l)) = (ring.first(), ring.last()) {
                if f != l {
                    let a = self.grid_uv(DVec2::new(l.x, l.y));
                    let b = self.grid_uv(DVec2::new(f.x, f.y));
                    self.edge_candidates(a, b, &mut pts, &mut ts, &mut grad2);
                }
            }
        }
        // Grid nodes inside (or on) the footprint.
        let lo = self.grid_uv(DVec2::new(bb[0], bb[1]));
        let hi = self.grid_uv(DVec2::new(bb[2], bb[3]));
        let clamp_i = |v: f64, n: usize| (v.max(0.0) as usize).min(n - 1);
        // Points from here on that lie strictly inside: every cell around them reaches under
        // the footprint, so their slope needs no further test.
        let mut strictly_inside = vec![false; pts.len()];
        for j in clamp_i(lo.y.ceil(), self.ny())..=clamp_i(hi.y.floor(), self.ny()) {
            for i in clamp_i(lo.x.ceil(), self.nx())..=clamp_i(hi.x.floor(), self.nx()) {
                let p = self.node_xy(i, j);
                match point_in_polygon(Coord { x: p.x, y: p.y }, footprint) {
                    Location::Outside => {}
                    l => {
                        pts.push(DVec2::new(i as f64, j as f64));
                        strictly_inside.push(l == Location::Inside);
                    }
                }
            }
        }

        let mut heights = Vec::with_capacity(pts.len());
        let (mut lo_h, mut hi_h, mut lo_at) = (f64::INFINITY, f64::NEG_INFINITY, DVec2::ZERO);
        let mut nodata = 0;
        for (&uv, &inside) in pts.iter().zip(&strictly_inside) {
            let Some((i, j, fu, fv)) = self.cell_of(uv) else {
                nodata += 1;
                continue;
            };
            let Some(h) = self.bilinear_in_cell(i, j, fu, fv) else {
                nodata += 1;
                continue;
            };
            let drawn = self.drawn_in_cell(i, j, fu, fv);
            for h in std::iter::once(h).chain(drawn) {
                heights.push(h);
                if h < lo_h {
                    lo_h = h;
                    lo_at = uv;
                }
                hi_h = hi_h.max(h);
            }
            if inside {
                grad2 = grad2.max(self.steepest_around(uv));
            }
        }
        let samples = pts.len();
        if heights.is_empty() {
            return Err(GroundError::Nodata {
                samples,
                nodata_samples: nodata,
                partial: None,
            });
        }
        let base_m = match rule {
            BaseRule::Min => lo_h,
            BaseRule::Percentile(p) => percentile(&mut heights, p),
        };
        let at = self.origin() + lo_at * self.spacing();
        let ground = FootprintGround {
            base_m,
            min_m: lo_h,
            min_at: [at.x, at.y],
            max_m: hi_h,
            relief_m: hi_h - lo_h,
            slope_deg: grad2.sqrt().atan().to_degrees(),
            samples,
            nodata_samples: nodata,
        };
        if nodata > 0 {
            return Err(GroundError::Nodata {
                samples,
                nodata_samples: nodata,
                partial: Some(Box::new(ground)),
            });
        }
        Ok(ground)
    }

    /// The candidate points of one footprint edge `a → b` (grid coordinates): its start, its
    /// crossings with grid lines, and the interior extremum of the surface along each piece
    /// between crossings. Raises `grad2` to the squared gradient at both ends of each piece, in
    /// the one cell that holds the piece: with the grid nodes strictly inside the footprint
    /// (every cell around them), these are all the vertices of the parts of cells under the
    /// footprint, where the convex squared gradient of each cell has its maximum.
    fn edge_candidates(
        &self,
        a: DVec2,
        b: DVec2,
        out: &mut Vec<DVec2>,
        ts: &mut Vec<f64>,
        grad2: &mut f64,
    ) {
        out.push(a);
        let d = b - a;
        // `ts` is the caller's scratch buffer (one allocation per footprint, not per edge).
        ts.clear();
        ts.extend([0.0, 1.0]);
        // Grid lines (u, v integer) and the drawn cells' diagonals (u − v integer).
        let diag = (a.x - a.y, b.x - b.y, d.x - d.y);
        for (p, q, dd) in [(a.x, b.x, d.x), (a.y, b.y, d.y), diag] {
            if dd != 0.0 {
                let (lo, hi) = (p.min(q), p.max(q));
                let mut k = lo.floor() + 1.0;
                while k < hi {
                    ts.push((k - p) / dd);
                    k += 1.0;
                }
            }
        }
        ts.sort_by(f64::total_cmp);
        ts.dedup();
        for w in ts.windows(2) {
            let (t0, t1) = (w[0], w[1]);
            if t0 > 0.0 {
                // A crossing with a grid line: snap the crossed coordinate onto the line.
                let mut p = a + d * t0;
                for (c, pc, dc) in [(0, a.x, d.x), (1, a.y, d.y)] {
                    let v = pc + dc * t0;
                    if (v - v.round()).abs() < 1e-9 {
                        p[c] = v.round();
                    }
                }
                out.push(p);
            }
            // The quadratic along the piece [t0, t1], inside one cell.
            let mid = a + d * (0.5 * (t0 + t1));
            let Some((i, j, _, _)) = self.cell_of(mid) else {
                continue;
            };
            let [h00, h10, h01, h11] = [
                self.raw(i, j),
                self.raw(i + 1, j),
                self.raw(i, j + 1),
                self.raw(i + 1, j + 1),
            ];
            if [h00, h10, h01, h11].iter().all(|v| v.is_finite()) {
                let s = self.spacing();
                for t in [t0, t1] {
                    let p = a + d * t;
                    let fu = (p.x - i as f64).clamp(0.0, 1.0);
                    let fv = (p.y - j as f64).clamp(0.0, 1.0);
                    let gx = ((h10 - h00) * (1.0 - fv) + (h11 - h01) * fv) / s.x;
                    let gy = ((h01 - h00) * (1.0 - fu) + (h11 - h10) * fu) / s.y;
                    *grad2 = grad2.max(gx * gx + gy * gy);
                }
            }
            let (ca, cb, cc) = (h10 - h00, h01 - h00, h00 - h10 - h01 + h11);
            let (fu0, fv0) = (a.x - i as f64, a.y - j as f64);
            // h(t) = h00 + ca·fu + cb·fv + cc·fu·fv with fu = fu0 + t·dx, fv = fv0 + t·dy.
            let q2 = cc * d.x * d.y;
            let q1 = ca * d.x + cb * d.y + cc * (fu0 * d.y + fv0 * d.x);
            if q2 != 0.0 && q2.is_finite() && q1.is_finite() {
                let t = -q1 / (2.0 * q2);
                if t > t0 && t < t1 {
                    out.push(a + d * t);
                }
            }
        }
    }

    /// The largest squared gradient of the bilinear surface at `uv` over the cells that hold it
    /// (for a point strictly inside the footprint, around which every cell lies under it).
    fn steepest_around(&self, uv: DVec2) -> f64 {
        let range = |v: f64, n: usize| -> (usize, usize) {
            let f = v.floor();
            let hi = (f as usize).min(n - 2);
            let lo = if v == f && f >= 1.0 {
                (f as usize - 1).min(n - 2)
            } else {
                hi
            };
            (lo, hi)
        };
        let (i0, i1) = range(uv.x, self.nx());
        let (j0, j1) = range(uv.y, self.ny());
        let mut best = 0.0f64;
        for j in j0..=j1 {
            for i in i0..=i1 {
                let h = [
                    self.raw(i, j),
                    self.raw(i + 1, j),
                    self.raw(i, j + 1),
                    self.raw(i + 1, j + 1),
                ];
                if h.iter().any(|v| v.is_nan()) {
                    continue;
                }
                let fu = (uv.x - i as f64).clamp(0.0, 1.0);
                let fv = (uv.y - j as f64).clamp(0.0, 1.0);
                let gx = ((h[1] - h[0]) * (1.0 - fv) + (h[3] - h[2]) * fv) / self.spacing().x;
                let gy = ((h[2] - h[0]) * (1.0 - fu) + (h[3] - h[1]) * fu) / self.spacing().y;
                best = best.max(gx * gx + gy * gy);
            }
        }
        best
    }
}

/// The `p`-th percentile (0 … 100) of `v`, linear between order statistics.
fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let r = p / 100.0 * (v.len() - 1) as f64;
    let k = r.floor() as usize;
    if k + 1 >= v.len() {
        return v[v.len() - 1];
    }
    v[k] + (r - k as f64) * (v[k + 1] - v[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::synthetic::{GridSpec, Synthetic};
    use geo_types::polygon;

    #[test]
    fn plane_base_is_the_lowest_corner() {
        let t = Terrain::synthetic(
            GridSpec::new(20, 20, 1.0, DVec2::ZERO),
            Synthetic::Plane {
                slope_deg: 45.0,
                azimuth_deg: 0.0,
                base_m: 100.0,
            },
        );
        let fp = polygon![(x: 2.5, y: 2.5), (x: 7.25, y: 2.5), (x: 7.25, y: 6.0), (x: 2.5, y: 6.0)];
        let g = t.ground_under(&fp, BaseRule::Min).unwrap();
        assert!((g.base_m - 102.5).abs() < 1e-9, "{g:?}");
        assert!((g.max_m - 107.25).abs() < 1e-9);
        assert!((g.slope_deg - 45.0).abs() < 1e-9);
        let m = t.ground_under(&fp, BaseRule::Percentile(50.0)).unwrap();
        assert!(m.base_m > g.base_m && m.base_m < g.max_m);
    }

    #[test]
    fn percentiles_out_of_range_are_refused() {
        let t = Terrain::synthetic(
            GridSpec::new(4, 4, 1.0, DVec2::ZERO),
            Synthetic::Flat { height_m: 3.0 },
        );
        let fp = polygon![(x: 0.5, y: 0.5), (x: 1.0, y: 0.5), (x: 1.0, y: 1.0)];
        assert!(matches!(
            t.ground_under(&fp, BaseRule::Percentile(101.0)),
            Err(GroundError::Invalid(_))
        ));
        let out = polygon![(x: 0.5, y: 0.5), (x: 5.0, y: 0.5), (x: 1.0, y: 1.0)];
        assert!(matches!(
            t.ground_under(&out, BaseRule::Min),
            Err(GroundError::OutsideGrid { .. })
        ));
    }
}
