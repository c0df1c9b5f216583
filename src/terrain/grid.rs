//! [`Terrain`]: an elevation grid on a regular, north-up metric grid in the city's world frame
//! (f64), made from a [`DemGrid`] in any CRS, and its bilinear surface.

use blockwalk_importers::dem::DemGrid;
use blockwalk_importers::{Crs, MetricTransform};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::Serialize;

/// The most nodes a resampled grid may have (4·10⁸ nodes, 3.2 GB of f64): a larger one means a
/// region or a spacing that cannot be meant.
pub const MAX_NODES: usize = 400_000_000;

/// How a DEM becomes a [`Terrain`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TerrainOptions {
    /// The part of the city's metric world frame to keep, `[xmin, ymin, xmax, ymax]` in metres
    /// (the city's box plus a margin): a 1° tile is not resampled whole for a city of a few
    /// kilometres. `None` keeps the whole DEM.
    pub region: Option<[f64; 4]>,
    /// Take a DEM without CRS ([`Crs::Unknown`]) as metres in the city's own frame. Without it
    /// such a DEM is refused when the city has a CRS ([`TerrainError::NoCrs`]).
    pub assume_city_frame: bool,
}

/// What [`Terrain::from_dem`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TerrainReport {
    /// The DEM's file.
    pub source: String,
    /// The DEM's CRS and what was done with it.
    pub crs: String,
    /// The DEM's size, samples `[width, height]`.
    pub source_size: [usize; 2],
    /// True when the samples were resampled onto a new metric grid (a reprojection, or a rotated
    /// grid); false when they are the DEM's own (possibly cropped and reordered south to north).
    pub resampled: bool,
    /// Node spacing `[dx, dy]`, metres.
    pub spacing_m: [f64; 2],
    /// Grid size, nodes `[nx, ny]`.
    pub size: [usize; 2],
    /// The nodes' extent `[xmin, ymin, xmax, ymax]` in the metric world frame, metres.
    pub extent: [f64; 4],
    /// Lowest height, metres.
    pub min_m: f64,
    /// Highest height, metres.
    pub max_m: f64,
    /// Nodes without a height (nodata in the source, or outside it after reprojection).
    pub nodata_count: usize,
    /// Other things worth saying (a DEM taken in the city's frame, a crop).
    pub notes: Vec<String>,
}

/// Why a DEM cannot become a [`Terrain`].
#[derive(Debug, thiserror::Error)]
pub enum TerrainError {
    /// The DEM has no CRS while the city has one.
    #[error(
        "{file}: the DEM has no CRS, and the city is in {city_crs}; refusing to guess where it \
         lies (TerrainOptions::assume_city_frame takes it as metres in the city's frame)"
    )]
    NoCrs {
        /// The DEM's file.
        file: String,
        /// The city's CRS.
        city_crs: String,
    },
    /// The metric transform given is not the DEM's.
    #[error("{file}: the DEM is in {dem_crs}, but the transform given maps from {transform_crs}")]
    CrsMismatch {
        /// The DEM's file.
        file: String,
        /// The DEM's CRS.
        dem_crs: String,
        /// The CRS the transform maps from.
        transform_crs: String,
    },
    /// The grid's shape, values or georeferencing cannot be used.
    #[error("{file}: {problem}")]
    Grid {
        /// The DEM's file.
        file: String,
        /// What is wrong.
        problem: String,
    },
    /// The DEM and the region asked for do not overlap.
    #[error(
        "{file}: the DEM covers {dem:?} in the city's metric frame, which does not overlap the \
         region {region:?} (metres, [xmin, ymin, xmax, ymax])"
    )]
    NoOverlap {
        /// The DEM's file.
        file: String,
        /// The DEM's extent in the metric frame.
        dem: [f64; 4],
        /// The region asked for.
        region: [f64; 4],
    },
    /// Every node of the region is nodata.
    #[error("{file}: all {nodes} nodes in {extent:?} are nodata")]
    AllNodata {
        /// The DEM's file.
        file: String,
        /// Nodes in the region.
        nodes: usize,
        /// The region's extent in the metric frame.
        extent: [f64; 4],
    },
}

/// A regular north-up elevation grid in the city's metric world frame (f64).
///
/// Node `(i, j)` lies at `origin + (i·dx, j·dy)`: `i` grows east, `j` grows **north** (row 0 is
/// the southern one, whatever the source's row order). A height is metres; nodata is `NaN` and
/// never read as 0. The surface between nodes is bilinear ([`Terrain::sample`]).
///
/// # Units
/// Metres throughout (positions in the metric world frame, heights above the DEM's datum).
#[derive(Clone, Debug)]
pub struct Terrain {
    nx: usize,
    ny: usize,
    origin: DVec2,
    spacing: DVec2,
    heights: Vec<f64>,
    report: TerrainReport,
}

impl Terrain {
    /// A terrain from its heights (row-major, row 0 south, `NaN` for nodata).
    ///
    /// # Errors
    /// [`TerrainError::Grid`] for fewer than 2 × 2 nodes, a spacing that is not finite and
    /// positive, a wrong number of heights or an origin that is not finite;
    /// [`TerrainError::AllNodata`] when no height is finite.
    pub fn from_heights(
        source: &str,
        nx: usize,
        ny: usize,
        origin: DVec2,
        spacing: DVec2,
        heights: Vec<f64>,
    ) -> Result<Terrain, TerrainError> {
        let bad = |problem: String| TerrainError::Grid {
            file: source.to_string(),
            problem,
        };
        if nx < 2 || ny < 2 {
            return Err(bad(format!("{nx} × {ny} nodes: need at least 2 × 2")));
        }
        if !(spacing.x > 0.0 && spacing.y > 0.0 && spacing.is_finite()) {
            return Err(bad(format!(
                "spacing {spacing}: must be finite and positive"
            )));
        }
        if !origin.is_finite() {
            return Err(bad(format!("origin {origin} is not finite")));
        }
        if heights.len() != nx * ny {
            return Err(bad(format!(
                "{} heights for {nx} × {ny} nodes",
                heights.len()
            )));
        }
        let mut t = Terrain {
            nx,
            ny,
            origin,
            spacing,
            heights,
            report: TerrainReport {
                source: source.to_string(),
                crs: String::new(),
                source_size: [nx, ny],
                resampled: false,
                spacing_m: [spacing.x, spacing.y],
                size: [nx, ny],
                extent: [0.0; 4],
                min_m: f64::NAN,
                max_m: f64::NAN,
                nodata_count: 0,
                notes: Vec::new(),
            },
        };
        // Any non-finite height (±∞ included) is nodata.
        for h in &mut t.heights {
            if !h.is_finite() {
                *h = f64::NAN;
            }
        }
        t.refresh_report();
        if t.report.nodata_count == nx * ny {
            return Err(TerrainError::AllNodata {
                file: source.to_string(),
                nodes: nx * ny,
                extent: t.extent(),
            });
        }
        Ok(t)
    }

    /// The terrain of `dem` in the city's metric world frame with the default options but the
    /// `region`; see [`Terrain::from_dem_with`].
    ///
    /// # Errors
    /// As [`Terrain::from_dem_with`].
    pub fn from_dem(
        dem: &DemGrid,
        to_metric: &MetricTransform,
        region: Option<[f64; 4]>,
    ) -> Result<Terrain, TerrainError> {
        Self::from_dem_with(
            dem,
            to_metric,
            &TerrainOptions {
                region,
                ..TerrainOptions::default()
            },
        )
    }

    /// The terrain of `dem`, whose CRS `to_metric` maps into the city's metric world frame (the
    /// city's own transform for a DEM in the city's CRS; `city.transform.for_layer(&dem.crs)`
    /// otherwise).
    ///
    /// When the map is the identity and the grid is axis-aligned, the samples are kept as they
    /// are (cropped to the region, rows reordered south to north). Otherwise they are resampled
    /// onto a north-up metric grid whose spacing is the DEM's ground spacing (the smaller of its
    /// two axes, measured in metres at its centre), aligned to multiples of that spacing; each
    /// node is sampled bilinearly (f64) in the source at `from_metric(node)`, and is nodata
    /// where that point is outside the source or a source sample it uses is nodata.
    ///
    /// # Errors
    /// [`TerrainError`]: a DEM without CRS for a city with one (unless
    /// [`TerrainOptions::assume_city_frame`]), a transform for another CRS, a grid that cannot
    /// be used, no overlap with the region, or nothing but nodata in it.
    pub fn from_dem_with(
        dem: &DemGrid,
        to_metric: &MetricTransform,
        opts: &TerrainOptions,
    ) -> Result<Terrain, TerrainError> {
        let file = dem.source.display().to_string();
        let bad = |problem: String| TerrainError::Grid {
            file: file.clone(),
            problem,
        };
        let (w, h) = (dem.width, dem.height);
        if w < 2 || h < 2 {
            return Err(bad(format!("{w} × {h} samples: need at least 2 × 2")));
        }
        if dem.values.len() != w * h {
            return Err(bad(format!(
                "{} values for {w} × {h} samples",
                dem.values.len()
            )));
        }
        let t = dem.transform;
        let det = t[1] * t[5] - t[2] * t[4];
        if !(t.iter().all(|v| v.is_finite()) && det != 0.0) {
            return Err(bad(format!("the sample transform {t:?} is not invertible")));
        }
        if let Some(r) = opts.region {
            if !(r.iter().all(|v| v.is_finite()) && r[0] < r[2] && r[1] < r[3]) {
                return Err(bad(format!("the region {r:?} is not a box")));
            }
        }
        let mut notes = Vec::new();
        // The city's CRS: the frame the transform maps into.
        let city_crs = to_metric
            .frame_crs
            .clone()
            .unwrap_or_else(|| to_metric.crs.clone());
        let same_frame = if dem.crs == Crs::Unknown {
            if city_crs != Crs::Unknown {
                if !opts.assume_city_frame {
                    return Err(TerrainError::NoCrs {
                        file,
                        city_crs: city_crs.describe(),
                    });
                }
                notes.push(format!(
                    "the DEM has no CRS: taken as metres in the city's frame ({}), as asked",
                    city_crs.describe()
                ));
            }
            true
        } else {
            if to_metric.crs != dem.crs {
                return Err(TerrainError::CrsMismatch {
                    file,
                    dem_crs: dem.crs.describe(),
                    transform_crs: to_metric.crs.describe(),
                });
            }
            to_metric.is_identity()
        };
        let crs = if dem.crs == Crs::Unknown {
            if same_frame && city_crs != Crs::Unknown {
                format!("no CRS: taken in the frame of {}", city_crs.describe())
            } else {
                "no CRS: coordinates taken as metres, used as they are".to_string()
            }
        } else {
            to_metric.describe()
        };
        let axis_aligned = t[2] == 0.0 && t[4] == 0.0;
        let mut terrain = if same_frame && axis_aligned {
            kept(dem, opts.region, &file)?
        } else {
            let map = if same_frame { None } else { Some(to_metric) };
            resampled(dem, map, opts.region, &file)?
        };
        terrain.report.crs = crs;
        terrain.report.source_size = [w, h];
        terrain.report.notes.extend(notes);
        if terrain.report.nodata_count == terrain.nx * terrain.ny {
            return Err(TerrainError::AllNodata {
                file,
                nodes: terrain.nx * terrain.ny,
                extent: terrain.extent(),
            });
        }
        Ok(terrain)
    }

    pub(super) fn heights_mut(&mut self) -> &mut [f64] {
        &mut self.heights
    }

    pub(super) fn refresh_report(&mut self) {
        let (mut lo, mut hi, mut nodata) = (f64::INFINITY, f64::NEG_INFINITY, 0);
        for &h in &self.heights {
            if h.is_nan() {
                nodata += 1;
            } else {
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        let extent = self.extent();
        let r = &mut self.report;
        r.spacing_m = [self.spacing.x, self.spacing.y];
        r.size = [self.nx, self.ny];
        r.min_m = if nodata < self.heights.len() {
            lo
        } else {
            f64::NAN
        };
        r.max_m = if nodata < self.heights.len() {
            hi
        } else {
            f64::NAN
        };
        r.nodata_count = nodata;
        r.extent = extent;
    }

    /// Nodes west to east.
    pub fn nx(&self) -> usize {
        self.nx
    }
    /// Nodes south to north.
    pub fn ny(&self) -> usize {
        self.ny
    }
    /// World position of node (0, 0), the south-west one.
    pub fn origin(&self) -> DVec2 {
        self.origin
    }
    /// Node spacing `(dx, dy)`, metres.
    pub fn spacing(&self) -> DVec2 {
        self.spacing
    }
    /// The heights, row-major, row 0 south; `NaN` is nodata.
    pub fn heights(&self) -> &[f64] {
        &self.heights
    }
    /// What was done to make this terrain.
    pub fn report(&self) -> &TerrainReport {
        &self.report
    }
    /// World position of node `(i, j)`.
    pub fn node_xy(&self, i: usize, j: usize) -> DVec2 {
        DVec2::new(
            self.origin.x + i as f64 * self.spacing.x,
            self.origin.y + j as f64 * self.spacing.y,
        )
    }
    /// World x of grid column `i`.
    pub fn x(&self, i: usize) -> f64 {
        self.origin.x + i as f64 * self.spacing.x
    }
    /// World y of grid row `j`.
    pub fn y(&self, j: usize) -> f64 {
        self.origin.y + j as f64 * self.spacing.y
    }
    /// Height of node `(i, j)` (`NaN` for nodata).
    #[inline]
    pub fn raw(&self, i: usize, j: usize) -> f64 {
        self.heights[j * self.nx + i]
    }
    /// Height of node `(i, j)`, `None` for nodata.
    pub fn height(&self, i: usize, j: usize) -> Option<f64> {
        let h = self.raw(i, j);
        (!h.is_nan()).then_some(h)
    }
    /// The nodes' extent `[xmin, ymin, xmax, ymax]`.
    pub fn extent(&self) -> [f64; 4] {
        [
            self.origin.x,
            self.origin.y,
            self.x(self.nx - 1),
            self.y(self.ny - 1),
        ]
    }
    /// Bytes this terrain holds on the heap (the heights and the report's strings).
    pub fn heap_bytes(&self) -> usize {
        self.heights.capacity() * std::mem::size_of::<f64>()
            + self.report.source.capacity()
            + self.report.crs.capacity()
            + self
                .report
                .notes
                .iter()
                .map(|n| n.capacity())
                .sum::<usize>()
    }

    /// Grid coordinates `(u, v)` of a world point (node units: node `(i, j)` is at `(i, j)`).
    pub fn grid_uv(&self, p: DVec2) -> DVec2 {
        (p - self.origin) / self.spacing
    }

    /// The cell holding grid coordinates `(u, v)` and the fractions within it, or `None` when
    /// `(u, v)` is outside the grid (points on the last row or column belong to the last cell).
    pub fn cell_of(&self, uv: DVec2) -> Option<(usize, usize, f64, f64)> {
        let (mx, my) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        if !(uv.x >= 0.0 && uv.x <= mx && uv.y >= 0.0 && uv.y <= my) {
            return None;
        }
        let i = (uv.x.floor() as usize).min(self.nx - 2);
        let j = (uv.y.floor() as usize).min(self.ny - 2);
        Some((i, j, uv.x - i as f64, uv.y - j as f64))
    }

    /// The bilinear surface in cell `(i, j)` at fractions `(fu, fv)`; `None` when a corner with
    /// a non-zero weight is nodata.
    #[inline]
    pub fn bilinear_in_cell(&self, i: usize, j: usize, fu: f64, fv: f64) -> Option<f64> {
        let v = bilinear(
            [
                self.raw(i, j),
                self.raw(i + 1, j),
                self.raw(i, j + 1),
                self.raw(i + 1, j + 1),
            ],
            fu,
            fv,
        );
        (!v.is_nan()).then_some(v)
    }

    /// The bilinear surface at world point `p` (f64): `None` outside the grid, or when a corner
    /// the point uses (one with a non-zero weight) is nodata. Never 0 for a missing height.
    pub fn sample(&self, p: DVec2) -> Option<f64> {
        let (i, j, fu, fv) = self.cell_of(self.grid_uv(p))?;
        self.bilinear_in_cell(i, j, fu, fv)
    }

    /// The gradient `(∂h/∂x, ∂h/∂y)` of the full grid at node `(i, j)`: central differences,
    /// one-sided at the border and beside nodata, zero along an axis with no usable neighbour.
    pub fn gradient_at_node(&self, i: usize, j: usize) -> DVec2 {
        let c = self.raw(i, j);
        let d = |a: Option<f64>, b: Option<f64>, step: f64| -> f64 {
            match (a, b) {
                (Some(a), Some(b)) => (b - a) / (2.0 * step),
                (None, Some(b)) if !c.is_nan() => (b - c) / step,
                (Some(a), None) if !c.is_nan() => (c - a) / step,
                _ => 0.0,
            }
        };
        let w = if i > 0 { self.height(i - 1, j) } else { None };
        let e = if i + 1 < self.nx {
            self.height(i + 1, j)
        } else {
            None
        };
        let s = if j > 0 { self.height(i, j - 1) } else { None };
        let n = if j + 1 < self.ny {
            self.height(i, j + 1)
        } else {
            None
        };
        DVec2::new(d(w, e, self.spacing.x), d(s, n, self.spacing.y))
    }
}

impl Terrain {
    /// The drawn full-resolution surface at world point `p`: two triangles per cell, split
    /// along the south-west–north-east diagonal, as [`Terrain::full_mesh`] draws them (the
    /// bilinear surface, [`Terrain::sample`], is between the same nodes but curved: inside a
    /// cell the two differ by up to a quarter of the cell's twist `h00 + h11 − h10 − h01`).
    /// `None` outside the grid and over a hole (a cell with a nodata corner is not drawn).
    pub fn sample_drawn(&self, p: DVec2) -> Option<f64> {
        let (i, j, fu, fv) = self.cell_of(self.grid_uv(p))?;
        self.drawn_in_cell(i, j, fu, fv)
    }

    /// [`Terrain::sample_drawn`] in cell `(i, j)` at fractions `(fu, fv)`.
    #[inline]
    pub fn drawn_in_cell(&self, i: usize, j: usize, fu: f64, fv: f64) -> Option<f64> {
        let [h00, h10, h01, h11] = [
            self.raw(i, j),
            self.raw(i + 1, j),
            self.raw(i, j + 1),
            self.raw(i + 1, j + 1),
        ];
        let h = if fu >= fv {
            // South-east triangle (0,0) (1,0) (1,1).
            h00 + fu * (h10 - h00) + fv * (h11 - h10)
        } else {
            // North-west triangle (0,0) (1,1) (0,1).
            h00 + fu * (h11 - h01) + fv * (h01 - h00)
        };
        (!(h00.is_nan() || h10.is_nan() || h01.is_nan() || h11.is_nan())).then_some(h)
    }

    /// The lowest clearance of the segment `a → b` (world metres) above the drawn surface
    /// ([`Terrain::sample_drawn`]) over the parts of it above the grid: the minimum of
    /// `z − surface`, the surface raised by what moving it `plan_tol` metres sideways can add
    /// (twice the cell's rise over its smaller spacing, times `plan_tol`: the mesh's vertices
    /// are rounded). Exact: both are linear between the crossings of the segment's plan view
    /// with grid lines and diagonals, which are all evaluated. `+∞` when no part is above the
    /// grid; `None` when a part is above a hole.
    pub fn drawn_clearance(&self, a: DVec3, b: DVec3, plan_tol: f64) -> Option<f64> {
        let (ua, ub) = (self.grid_uv(a.truncate()), self.grid_uv(b.truncate()));
        let d = ub - ua;
        let mut ts = vec![0.0, 1.0];
        let mut crossings = |p: f64, dd: f64| {
            if dd != 0.0 && dd.is_finite() {
                let (lo, hi) = (p.min(p + dd), p.max(p + dd));
                let mut k = lo.floor() + 1.0;
                while k < hi {
                    ts.push((k - p) / dd);
                    k += 1.0;
                }
            }
        };
        crossings(ua.x, d.x);
        crossings(ua.y, d.y);
        crossings(ua.x - ua.y, d.x - d.y);
        ts.sort_by(f64::total_cmp);
        let (mx, my) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        let spacing = self.spacing.min_element();
        let mut best = f64::INFINITY;
        for t in ts {
            let uv = ua + d * t;
            if !(uv.x >= 0.0 && uv.x <= mx && uv.y >= 0.0 && uv.y <= my) {
                continue;
            }
            // A point on a cell boundary counts for every cell that holds it.
            let cells = |v: f64, n: usize| {
                let f = v.floor();
                let hi = (f as usize).min(n - 2);
                let lo = if v == f && f >= 1.0 {
                    hi.min(f as usize - 1)
                } else {
                    hi
                };
                lo..=hi
            };
            let z = a.z + (b.z - a.z) * t;
            for j in cells(uv.y, self.ny) {
                for i in cells(uv.x, self.nx) {
                    let (fu, fv) = (uv.x - i as f64, uv.y - j as f64);
                    let h = self.drawn_in_cell(i, j, fu.clamp(0.0, 1.0), fv.clamp(0.0, 1.0))?;
                    let c = [
                        self.raw(i, j),
                        self.raw(i + 1, j),
                        self.raw(i, j + 1),
                        self.raw(i + 1, j + 1),
                    ];
                    let rise = c.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                        - c.iter().copied().fold(f64::INFINITY, f64::min);
                    best = best.min(z - h - 2.0 * rise / spacing * plan_tol.max(0.0));
                }
            }
        }
        Some(best)
    }
}

/// Bilinear interpolation of `[h00, h10, h01, h11]` at `(fu, fv)`; a corner with zero weight is
/// not read (so nodata there does not matter); `NaN` when a corner with weight is nodata.
#[inline]
pub(crate) fn bilinear(c: [f64; 4], fu: f64, fv: f64) -> f64 {
    let w = [
        (1.0 - fu) * (1.0 - fv),
        fu * (1.0 - fv),
        (1.0 - fu) * fv,
        fu * fv,
    ];
    let mut s = 0.0;
    for k in 0..4 {
        if w[k] != 0.0 {
            s += w[k] * c[k];
        }
    }
    s
}

/// The DEM's own samples, cropped to `region` and reordered to rows south to north, columns
/// west to east.
fn kept(dem: &DemGrid, region: Option<[f64; 4]>, file: &str) -> Result<Terrain, TerrainError> {
    let t = dem.transform;
    let (w, h) = (dem.width, dem.height);
    let (dx, dy) = (t[1].abs(), t[5].abs());
    let x0 = t[0] + (t[1] * (w - 1) as f64).min(0.0);
    let y0 = t[3] + (t[5] * (h - 1) as f64).min(0.0);
    let full = [x0, y0, x0 + dx * (w - 1) as f64, y0 + dy * (h - 1) as f64];
    // Node range (in the reordered grid) to keep.
    let (mut i0, mut i1, mut j0, mut j1) = (0usize, w - 1, 0usize, h - 1);
    let mut notes = Vec::new();
    if let Some(r) = region {
        let no_overlap = || TerrainError::NoOverlap {
            file: file.to_string(),
            dem: full,
            region: r,
        };
        if r[2] < full[0] || r[0] > full[2] || r[3] < full[1] || r[1] > full[3] {
            return Err(no_overlap());
        }
        let lo =
            |v: f64, o: f64, s: f64, n: usize| (((v - o) / s).floor().max(0.0) as usize).min(n - 1);
        let hi =
            |v: f64, o: f64, s: f64, n: usize| (((v - o) / s).ceil().max(0.0) as usize).min(n - 1);
        i0 = lo(r[0], x0, dx, w);
        i1 = hi(r[2], x0, dx, w);
        j0 = lo(r[1], y0, dy, h);
        j1 = hi(r[3], y0, dy, h);
        // At least one cell each way.
        if i1 == i0 {
            if i1 + 1 < w {
                i1 += 1
            } else {
                i0 -= 1
            }
        }
        if j1 == j0 {
            if j1 + 1 < h {
                j1 += 1
            } else {
                j0 -= 1
            }
        }
        if (i0, i1, j0, j1) != (0, w - 1, 0, h - 1) {
            notes.push(format!(
                "cropped to the region: nodes {i0}..={i1} × {j0}..={j1} of {w} × {h}"
            ));
        }
    }
    let (nx, ny) = (i1 - i0 + 1, j1 - j0 + 1);
    let mut heights = Vec::with_capacity(nx * ny);
    for j in j0..=j1 {
        let row = if t[5] < 0.0 { h - 1 - j } else { j };
        for i in i0..=i1 {
            let col = if t[1] < 0.0 { w - 1 - i } else { i };
            let v = dem.values[row * w + col];
            // The declared nodata value too, should a reader leave it in place.
            heights.push(if Some(v) == dem.nodata { f64::NAN } else { v });
        }
    }
    let origin = DVec2::new(x0 + i0 as f64 * dx, y0 + j0 as f64 * dy);
    let mut terrain = Terrain::from_heights(file, nx, ny, origin, DVec2::new(dx, dy), heights)
        .or_else(|e| match e {
            // The all-nodata case is reported by the caller with the DEM's file.
            TerrainError::AllNodata { .. } => Ok(Terrain {
                nx,
                ny,
                origin,
                spacing: DVec2::new(dx, dy),
                heights: vec![f64::NAN; nx * ny],
                report: empty_report(file),
            }),
            e => Err(e),
        })?;
    terrain.refresh_report();
    terrain.report.notes = notes;
    Ok(terrain)
}

fn empty_report(file: &str) -> TerrainReport {
    TerrainReport {
        source: file.to_string(),
        crs: String::new(),
        source_size: [0, 0],
        resampled: false,
        spacing_m: [0.0; 2],
        size: [0, 0],
        extent: [0.0; 4],
        min_m: f64::NAN,
        max_m: f64::NAN,
        nodata_count: 0,
        notes: Vec::new(),
    }
}

/// The DEM's sample at source grid coordinates `(col, row)`, bilinear; `NaN` outside or on
/// nodata.
fn source_bilinear(dem: &DemGrid, col: f64, row: f64) -> f64 {
    let (w, h) = (dem.width, dem.height);
    if !(col >= 0.0 && col <= (w - 1) as f64 && row >= 0.0 && row <= (h - 1) as f64) {
        return f64::NAN;
    }
    let c = (col.floor() as usize).min(w - 2);
    let r = (row.floor() as usize).min(h - 2);
    let v = |c: usize, r: usize| {
        let x = dem.values[r * w + c];
        if x.is_finite() && Some(x) != dem.nodata {
            x
        } else {
            f64::NAN
        }
    };
    bilinear(
        [v(c, r), v(c + 1, r), v(c, r + 1), v(c + 1, r + 1)],
        col - c as f64,
        row - r as f64,
    )
}

/// CRS position → source `(col, row)` (the inverse of the DEM's affine map).
fn source_colrow(t: &[f64; 6], p: [f64; 2]) -> [f64; 2] {
    let det = t[1] * t[5] - t[2] * t[4];
    let (x, y) = (p[0] - t[0], p[1] - t[3]);
    [(t[5] * x - t[2] * y) / det, (t[1] * y - t[4] * x) / det]
}

fn affine(t: &[f64; 6], c: f64, r: f64) -> [f64; 2] {
    [t[0] + t[1] * c + t[2] * r, t[3] + t[4] * c + t[5] * r]
}

/// The DEM resampled onto a north-up metric grid (see [`Terrain::from_dem_with`]); `map` is
/// `None` for a DEM already in the metric frame (a rotated grid).
fn resampled(
    dem: &DemGrid,
    map: Option<&MetricTransform>,
    region: Option<[f64; 4]>,
    file: &str,
) -> Result<Terrain, TerrainError> {
    let t = dem.transform;
    let (w, h) = (dem.width, dem.height);
    let to_m = |p: [f64; 2]| map.map_or(p, |m| m.to_metric(p));
    let from_m = |p: [f64; 2]| map.map_or(p, |m| m.from_metric(p));
    let bad = |problem: String| TerrainError::Grid {
        file: file.to_string(),
        problem,
    };
    // Ground spacing at the centre.
    let (cc, cr) = (((w - 1) / 2) as f64, ((h - 1) / 2) as f64);
    let p0 = DVec2::from(to_m(affine(&t, cc, cr)));
    let pc = DVec2::from(to_m(affine(&t, cc + 1.0, cr)));
    let pr = DVec2::from(to_m(affine(&t, cc, cr + 1.0)));
    let sp = (pc - p0).length().min((pr - p0).length());
    if !(sp.is_finite() && sp > 0.0) {
        return Err(bad(format!(
            "the DEM's centre cannot be mapped to the metric frame (ground spacing {sp})"
        )));
    }
    // The source's outline in the metric frame (its edges walked, not only its corners: a
    // reprojected edge bows).
    let mut bb = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    let steps = 256;
    for k in 0..=steps {
        let f = k as f64 / steps as f64;
        let (c, r) = (f * (w - 1) as f64, f * (h - 1) as f64);
        for (a, b) in [(c, 0.0), (c, (h - 1) as f64), (0.0, r), ((w - 1) as f64, r)] {
            let q = to_m(affine(&t, a, b));
            if q[0].is_finite() && q[1].is_finite() {
                bb = [
                    bb[0].min(q[0]),
                    bb[1].min(q[1]),
                    bb[2].max(q[0]),
                    bb[3].max(q[1]),
                ];
            }
        }
    }
    if !(bb[0] <= bb[2] && bb[1] <= bb[3]) {
        return Err(bad("no edge of the DEM maps to the metric frame".into()));
    }
    let mut notes = Vec::new();
    if let Some(r) = region {
        if r[2] < bb[0] || r[0] > bb[2] || r[3] < bb[1] || r[1] > bb[3] {
            return Err(TerrainError::NoOverlap {
                file: file.to_string(),
                dem: bb,
                region: r,
            });
        }
        bb = [
            bb[0].max(r[0]),
            bb[1].max(r[1]),
            bb[2].min(r[2]),
            bb[3].min(r[3]),
        ];
        notes.push(format!("restricted to the region {r:?}"));
    }
    let x0 = (bb[0] / sp).floor() * sp;
    let y0 = (bb[1] / sp).floor() * sp;
    let nx = (((bb[2] - x0) / sp).ceil() as usize + 1).max(2);
    let ny = (((bb[3] - y0) / sp).ceil() as usize + 1).max(2);
    if nx.saturating_mul(ny) > MAX_NODES {
        return Err(bad(format!(
            "resampling at {sp:.3} m would make {nx} × {ny} nodes (more than {MAX_NODES}); \
             give a smaller region"
        )));
    }
    let mut heights = vec![f64::NAN; nx * ny];
    heights.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        let y = y0 + j as f64 * sp;
        for (i, out) in row.iter_mut().enumerate() {
            let x = x0 + i as f64 * sp;
            let q = from_m([x, y]);
            if q[0].is_finite() && q[1].is_finite() {
                let [c, r] = source_colrow(&t, q);
                *out = source_bilinear(dem, c, r);
            }
        }
    });
    let mut terrain = Terrain {
        nx,
        ny,
        origin: DVec2::new(x0, y0),
        spacing: DVec2::splat(sp),
        heights,
        report: empty_report(file),
    };
    terrain.refresh_report();
    terrain.report.resampled = true;
    notes.insert(
        0,
        format!("resampled bilinearly onto a north-up grid at the DEM's ground spacing, {sp:.3} m"),
    );
    terrain.report.notes = notes;
    Ok(terrain)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn dem(
        w: usize,
        h: usize,
        transform: [f64; 6],
        crs: Crs,
        f: impl Fn(f64, f64) -> f64,
    ) -> DemGrid {
        let mut values = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let [x, y] = affine(&transform, c as f64, r as f64);
                values.push(f(x, y));
            }
        }
        DemGrid {
            source: PathBuf::from("test.tif"),
            width: w,
            height: h,
            nodata_count: values.iter().filter(|v| v.is_nan()).count(),
            values,
            transform,
            crs,
            pixel_is: blockwalk_importers::dem::PixelIs::Point,
            nodata: None,
            sample_type: "float64".into(),
            layout: "strips",
        }
    }

    fn utm() -> Crs {
        Crs::from_epsg(32633).unwrap()
    }

    #[test]
    fn north_up_grid_is_kept_and_reordered_south_to_north() {
        let d = dem(
            5,
            4,
            [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0],
            utm(),
            |x, y| x + 2.0 * y,
        );
        let m = utm().metric_transform([1000.0, 2000.0]);
        let t = Terrain::from_dem(&d, &m, None).unwrap();
        assert!(!t.report().resampled);
        assert_eq!((t.nx(), t.ny()), (5, 4));
        assert_eq!(t.origin(), DVec2::new(1000.0, 1970.0));
        for j in 0..4 {
            for i in 0..5 {
                let p = t.node_xy(i, j);
                assert_eq!(t.raw(i, j), p.x + 2.0 * p.y, "({i}, {j})");
            }
        }
        // Bilinear of a linear function is exact, anywhere.
        let p = DVec2::new(1013.7, 1981.2);
        assert!((t.sample(p).unwrap() - (p.x + 2.0 * p.y)).abs() < 1e-9);
        assert_eq!(t.sample(DVec2::new(999.0, 1980.0)), None);
    }

    #[test]
    fn positive_row_step_is_kept_as_is() {
        let d = dem(3, 3, [0.0, 1.0, 0.0, 0.0, 0.0, 2.0], utm(), |x, y| x * y);
        let m = utm().metric_transform([0.0, 0.0]);
        let t = Terrain::from_dem(&d, &m, None).unwrap();
        assert_eq!(t.spacing(), DVec2::new(1.0, 2.0));
        assert_eq!(t.raw(2, 2), 2.0 * 4.0);
    }

    #[test]
    fn nodata_is_none_never_zero() {
        let d = dem(3, 3, [0.0, 1.0, 0.0, 2.0, 0.0, -1.0], utm(), |x, y| {
            if x == 1.0 && y == 1.0 {
                f64::NAN
            } else {
                5.0
            }
        });
        let m = utm().metric_transform([0.0, 0.0]);
        let t = Terrain::from_dem(&d, &m, None).unwrap();
        assert_eq!(t.report().nodata_count, 1);
        assert_eq!(t.sample(DVec2::new(0.5, 0.5)), None);
        assert_eq!(t.sample(DVec2::new(1.0, 1.0)), None);
        // The corner (1, 1) has zero weight on the line x = 0 … 1, y = 0.
        assert_eq!(t.sample(DVec2::new(0.5, 0.0)), Some(5.0));
    }

    #[test]
    fn a_declared_nodata_value_is_nodata() {
        let mut d = dem(3, 3, [0.0, 1.0, 0.0, 2.0, 0.0, -1.0], utm(), |x, _| {
            if x == 2.0 {
                -9999.0
            } else {
                7.0
            }
        });
        d.nodata = Some(-9999.0);
        let m = utm().metric_transform([0.0, 0.0]);
        let t = Terrain::from_dem(&d, &m, None).unwrap();
        assert_eq!(t.report().nodata_count, 3);
        assert_eq!(t.report().min_m, 7.0);
        let json = serde_json::to_string(t.report()).unwrap();
        assert!(json.contains("\"nodata_count\":3"), "{json}");
    }

    #[test]
    fn refusals_name_the_file_and_the_problem() {
        let d = dem(
            3,
            3,
            [0.0, 1.0, 0.0, 2.0, 0.0, -1.0],
            Crs::Unknown,
            |_, _| 1.0,
        );
        let m = utm().metric_transform([0.0, 0.0]);
        let city = m.for_layer(&Crs::Unknown).unwrap();
        let e = Terrain::from_dem(&d, &city, None).unwrap_err().to_string();
        assert!(e.contains("test.tif") && e.contains("no CRS"), "{e}");
        let ok = Terrain::from_dem_with(
            &d,
            &city,
            &TerrainOptions {
                assume_city_frame: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(ok.report().notes[0].contains("taken as metres"));
        let d2 = dem(3, 3, [0.0, 1.0, 0.0, 2.0, 0.0, -1.0], utm(), |_, _| 1.0);
        let e = Terrain::from_dem(&d2, &m, Some([10.0, 10.0, 20.0, 20.0]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("test.tif")
                && e.contains("[0.0, 0.0, 2.0, 2.0]")
                && e.contains("[10.0, 10.0, 20.0, 20.0]"),
            "{e}"
        );
        let d3 = dem(3, 3, [0.0, 1.0, 0.0, 2.0, 0.0, -1.0], utm(), |_, _| {
            f64::NAN
        });
        let e = Terrain::from_dem(&d3, &m, None).unwrap_err().to_string();
        assert!(e.contains("test.tif") && e.contains("nodata"), "{e}");
        let wgs = Crs::Geographic { epsg: Some(4326) };
        let e = Terrain::from_dem(&d2, &wgs.metric_transform([0.0, 0.0]), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("maps from"), "{e}");
    }

    #[test]
    fn region_crops_without_resampling() {
        let d = dem(
            101,
            101,
            [0.0, 10.0, 0.0, 1000.0, 0.0, -10.0],
            utm(),
            |x, y| x - y,
        );
        let m = utm().metric_transform([0.0, 0.0]);
        let t = Terrain::from_dem(&d, &m, Some([205.0, 301.0, 399.0, 455.0])).unwrap();
        assert!(!t.report().resampled);
        assert_eq!(t.extent(), [200.0, 300.0, 400.0, 460.0]);
        let p = t.node_xy(3, 2);
        assert_eq!(t.raw(3, 2), p.x - p.y);
    }

    #[test]
    fn a_rotated_grid_is_resampled() {
        // 30° rotation, 10 m samples.
        let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
        let tr = [500.0, 10.0 * c, -10.0 * s, 500.0, 10.0 * s, 10.0 * c];
        let d = dem(40, 40, tr, utm(), |x, y| 3.0 * x - y);
        let m = utm().metric_transform([0.0, 0.0]);
        let t = Terrain::from_dem(&d, &m, None).unwrap();
        assert!(t.report().resampled);
        assert!((t.spacing().x - 10.0).abs() < 1e-9);
        let mut n = 0;
        for j in 0..t.ny() {
            for i in 0..t.nx() {
                if let Some(h) = t.height(i, j) {
                    let p = t.node_xy(i, j);
                    assert!((h - (3.0 * p.x - p.y)).abs() < 1e-9);
                    n += 1;
                }
            }
        }
        assert!(n > 1000, "{n}");
    }
}
