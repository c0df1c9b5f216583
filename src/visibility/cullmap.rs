//! The cull map (Willmott et al., §3.2.3–3.2.4): a regular grid over the city's plan-view bounds, per cell
//! the height below which everything is hidden this frame.
//!
//! Shadows are drawn on the CPU in f64 and kept as f32 cells, rounded down. A cell takes a
//! shadow's height only when the shadow covers the whole cell, and then the plane's minimum over
//! the cell (the minimum of its four corners, since the plane is linear). The seed shrinks every
//! occluder by half a cell for the same purpose; testing the corners against the exact region is
//! conservative without that approximation.

use super::shadow::OccluderShadow;
use super::VisibilityError;
use crate::geom::clip::clip_polygon;
use crate::geom::hull::convex_hull;
use crate::geom::Aabb3;
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// Largest number of cells along one side.
pub const MAX_CELLS_PER_SIDE: usize = 4096;

/// How fine the cull map is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Resolution {
    /// This many cells along the longer side of the bounds (square cells).
    Cells(u32),
    /// Cells of this size, metres.
    CellSize(f64),
}

/// The grid geometry: square cells of side `cell` from `origin`, `nx × ny` of them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Grid {
    /// Lower-left corner of cell (0, 0), local frame.
    pub origin: DVec2,
    /// Cell side, metres.
    pub cell: f64,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
}

impl Grid {
    /// A grid over `[min, max]` at `resolution`.
    pub fn new(min: DVec2, max: DVec2, resolution: Resolution) -> Result<Self, VisibilityError> {
        let ext = max - min;
        if !(min.is_finite() && max.is_finite()) || ext.x < 0.0 || ext.y < 0.0 {
            return Err(VisibilityError::BadBounds {
                min: min.to_array(),
                max: max.to_array(),
            });
        }
        let side = ext.x.max(ext.y).max(1e-3);
        let cell = match resolution {
            Resolution::Cells(n) if n >= 1 && n as usize <= MAX_CELLS_PER_SIDE => side / n as f64,
            Resolution::CellSize(c) if c.is_finite() && c > 0.0 => c,
            resolution => {
                return Err(VisibilityError::BadResolution {
                    resolution,
                    max: MAX_CELLS_PER_SIDE,
                })
            }
        };
        let nx = ((ext.x / cell).ceil() as usize).max(1);
        let ny = ((ext.y / cell).ceil() as usize).max(1);
        if nx > MAX_CELLS_PER_SIDE || ny > MAX_CELLS_PER_SIDE {
            return Err(VisibilityError::TooManyCells {
                resolution,
                nx,
                ny,
                width: ext.x,
                height: ext.y,
                max: MAX_CELLS_PER_SIDE,
            });
        }
        Ok(Self {
            origin: min,
            cell,
            nx,
            ny,
        })
    }

    /// x of the cell column boundary `i` (0..=nx).
    #[inline]
    pub fn x(&self, i: usize) -> f64 {
        self.origin.x + i as f64 * self.cell
    }
    /// y of the cell row boundary `j` (0..=ny).
    #[inline]
    pub fn y(&self, j: usize) -> f64 {
        self.origin.y + j as f64 * self.cell
    }

    /// The cell columns `[i0, i1)` whose both boundaries lie in `[lo, hi]` (exactly, after the
    /// rounding of [`Grid::x`]); `None` when there are none.
    pub fn columns_within(&self, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let mut i0 = ((lo - self.origin.x) / self.cell).ceil().max(0.0) as usize;
        while i0 > 0 && self.x(i0 - 1) >= lo {
            i0 -= 1;
        }
        while i0 <= self.nx && self.x(i0) < lo {
            i0 += 1;
        }
        let mut i1 = (((hi - self.origin.x) / self.cell).floor().max(0.0) as usize).min(self.nx);
        while i1 < self.nx && self.x(i1 + 1) <= hi {
            i1 += 1;
        }
        while i1 > 0 && self.x(i1) > hi {
            i1 -= 1;
        }
        (i1 > i0 && self.x(i1) <= hi).then_some((i0, i1))
    }

    /// The upper-right corner.
    pub fn max(&self) -> DVec2 {
        DVec2::new(self.x(self.nx), self.y(self.ny))
    }

    /// The inclusive cell ranges `(i0, i1, j0, j1)` touched by the closed plan-view box
    /// `[min, max]` grown by `pad` metres; `None` when any part of it lies outside the map (the
    /// map knows nothing there, so such a box is never hidden).
    pub fn cells_touched(
        &self,
        min: DVec2,
        max: DVec2,
        pad: f64,
    ) -> Option<(usize, usize, usize, usize)> {
        let top = self.max();
        let (lo, hi) = (min - pad, max + pad);
        if !(lo.x >= self.origin.x && lo.y >= self.origin.y && hi.x <= top.x && hi.y <= top.y) {
            return None;
        }
        let c =
            |v: f64, o: f64, n: usize| (((v - o) / self.cell).floor().max(0.0) as usize).min(n - 1);
        Some((
            c(lo.x, self.origin.x, self.nx),
            c(hi.x, self.origin.x, self.nx),
            c(lo.y, self.origin.y, self.ny),
            c(hi.y, self.origin.y, self.ny),
        ))
    }
}

/// The f32 stored for a plane height `z` (f64): never above `z`, at most a few parts in 10⁷
/// below. `z` is first lowered by `1e-9 |z|` (the rounding of the plane's evaluation), then by
/// `2^-23 |z| + 1e-30`, more than half an f32 ulp of `z` (or the smallest subnormal's), so
/// that rounding to the nearest f32 cannot end above `z`: `w + |w| 2^-24 < z`. Branch-free, so
/// that the span loop vectorises (rounding to nearest and stepping down where that went up would branch).
/// Heights above f32's range are clamped to its largest value, still below them; those below
/// it become −∞ (the conversion's own overflow); NaN stays NaN.
#[inline]
fn stored_height(z: f64) -> f32 {
    const LOWER: f64 = 1e-9 + f32::EPSILON as f64;
    let w = z - LOWER * z.abs() - 1e-30;
    // Not `min`, which would turn NaN into the largest height; NaN stays NaN, and the span
    // loop's `max` then keeps the cell as it was.
    (if w > f32::MAX as f64 {
        f32::MAX as f64
    } else {
        w
    }) as f32
}

/// f64 → f32 rounded towards +∞ (for the heights of boxes under test).
#[inline]
pub(crate) fn f32_up(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v {
        f.next_up()
    } else {
        f
    }
}

/// The cull map: per cell, the height below which everything is hidden (−∞ when nothing is known).
///
/// # Examples
/// ```
/// use blockwalk::geom::Aabb3;
/// use blockwalk::visibility::{CullMap, Occluder, OccluderShadow, Resolution};
/// use glam::{DVec2, DVec3};
///
/// // A 20 m high wall along y = 10 seen by a pedestrian south of it.
/// let mut map = CullMap::new(DVec2::splat(-100.0), DVec2::splat(100.0), Resolution::Cells(128))
///     .unwrap();
/// let wall = Occluder { a: DVec2::new(-50.0, 10.0), b: DVec2::new(50.0, 10.0), height: 20.0 };
/// let eye = DVec3::new(0.0, 0.0, 1.7);
/// map.draw(&OccluderShadow::new(eye, &wall).unwrap());
/// map.build_pyramid();
/// // A low shed just behind the wall is hidden; a tower behind it is not, nor is anything in
/// // front of the wall.
/// let shed = Aabb3::new(DVec3::new(-5.0, 20.0, 0.0), DVec3::new(5.0, 25.0, 4.0));
/// let tower = Aabb3::new(DVec3::new(-5.0, 20.0, 0.0), DVec3::new(5.0, 25.0, 60.0));
/// let front = Aabb3::new(DVec3::new(-5.0, 3.0, 0.0), DVec3::new(5.0, 5.0, 1.0));
/// assert!(map.box_hidden(&shed));
/// assert!(!map.box_hidden(&tower));
/// assert!(!map.box_hidden(&front));
/// ```
#[derive(Clone, Debug)]
pub struct CullMap {
    grid: Grid,
    /// Row-major, `j * nx + i`.
    values: Vec<f32>,
    pyramid: MinPyramid,
    /// Margin by which every shadow half-plane is shrunk before the corner test, metres.
    margin: f64,
    /// Amount subtracted from every plane height before it is stored, metres.
    height_margin: f64,
    /// Cells that [`CullMap::draw`] may write (its bounding box).
    window: CellRect,
    /// Per row, the columns `[i0, i1)` of the window.
    row_window: Vec<(usize, usize)>,
    /// Bounding box of the cells written since the last [`CullMap::clear`].
    dirty: CellRect,
    /// Bounding box of the cells above −∞ in the pyramid's levels.
    built: CellRect,
    /// The column boundaries `x(0..=nx)`, exactly [`Grid::x`] (no int → float conversion per
    /// cell or per row).
    xs: Vec<f64>,
    /// Scratch outlines for [`region_y_range`] (no allocation per shadow).
    clip: (Vec<DVec2>, Vec<DVec2>),
}

/// A half-open rectangle of cells `[i0, i1) × [j0, j1)`; empty when `i0 >= i1` or `j0 >= j1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct CellRect {
    i0: usize,
    i1: usize,
    j0: usize,
    j1: usize,
}

impl CellRect {
    const EMPTY: Self = Self {
        i0: usize::MAX,
        i1: 0,
        j0: usize::MAX,
        j1: 0,
    };

    fn full(g: &Grid) -> Self {
        Self {
            i0: 0,
            i1: g.nx,
            j0: 0,
            j1: g.ny,
        }
    }

    fn is_empty(&self) -> bool {
        self.i0 >= self.i1 || self.j0 >= self.j1
    }

    #[inline]
    fn include(&mut self, i0: usize, i1: usize, j: usize) {
        self.i0 = self.i0.min(i0);
        self.i1 = self.i1.max(i1);
        self.j0 = self.j0.min(j);
        self.j1 = self.j1.max(j + 1);
    }

    fn union(&self, o: &Self) -> Self {
        if self.is_empty() {
            return *o;
        }
        if o.is_empty() {
            return *self;
        }
        Self {
            i0: self.i0.min(o.i0),
            i1: self.i1.max(o.i1),
            j0: self.j0.min(o.j0),
            j1: self.j1.max(o.j1),
        }
    }
}

/// The y-range of the shadow's region (without margin) clipped to the box `[min, max]`, by
/// clipping the box's outline with each half-plane (in the scratch outlines `poly` and `next`);
/// `None` when nothing is left.
fn region_y_range(
    s: &OccluderShadow,
    min: DVec2,
    max: DVec2,
    (poly, next): &mut (Vec<DVec2>, Vec<DVec2>),
) -> Option<(f64, f64)> {
    poly.clear();
    poly.extend([min, DVec2::new(max.x, min.y), max, DVec2::new(min.x, max.y)]);
    for h in &s.region {
        if h.c == f64::INFINITY {
            continue;
        }
        clip_polygon(poly, next, |p| h.eval(p));
        if poly.is_empty() {
            return None;
        }
    }
    let (lo, hi) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.y), b.max(p.y))
        });
    (lo <= hi).then_some((lo, hi))
}

/// The cell columns `[i0, i1)` whose both boundaries lie in `[lo, hi]`, from the table `xs` of
/// column boundaries (increasing, `nx + 1` of them; `inv` is one over the cell size): the same
/// answer as [`Grid::columns_within`] (the smallest boundary ≥ `lo`, the largest ≤ `hi`). The
/// first guess truncates instead of calling `ceil`/`floor`; the table lookups correct it.
#[inline]
fn columns_in(xs: &[f64], ox: f64, inv: f64, lo: f64, hi: f64) -> Option<(usize, usize)> {
    let n = xs.len() - 1;
    let guess = |v: f64| ((v - ox) * inv).clamp(0.0, n as f64) as usize;
    let mut i0 = guess(lo);
    while i0 > 0 && xs[i0 - 1] >= lo {
        i0 -= 1;
    }
    while i0 <= n && xs[i0] < lo {
        i0 += 1;
    }
    let mut i1 = guess(hi);
    while i1 < n && xs[i1 + 1] <= hi {
        i1 += 1;
    }
    while i1 > 0 && xs[i1] > hi {
        i1 -= 1;
    }
    (i1 > i0 && xs[i1] <= hi).then_some((i0, i1))
}

impl CullMap {
    /// An empty cull map over `[min, max]` (local frame, metres).
    pub fn new(min: DVec2, max: DVec2, resolution: Resolution) -> Result<Self, VisibilityError> {
        let grid = Grid::new(min, max, resolution)?;
        let scale = (grid.max() - grid.origin).abs().max_element().max(1.0)
            + grid.origin.abs().max_element();
        Ok(Self {
            values: vec![f32::NEG_INFINITY; grid.nx * grid.ny],
            pyramid: MinPyramid::new(grid.nx, grid.ny),
            grid,
            margin: 1e-9 * scale + 1e-7,
            height_margin: 1e-4,
            window: CellRect::full(&grid),
            row_window: vec![(0, grid.nx); grid.ny],
            dirty: CellRect::full(&grid),
            built: CellRect::full(&grid),
            xs: (0..=grid.nx).map(|i| grid.x(i)).collect(),
            clip: (Vec::with_capacity(8), Vec::with_capacity(8)),
        })
    }

    /// Lets [`CullMap::draw`] write every cell (the default).
    pub fn clear_window(&mut self) {
        let g = self.grid;
        self.window = CellRect::full(&g);
        self.row_window.fill((0, g.nx));
    }

    /// Restricts [`CullMap::draw`] to the cells that meet the convex hull of `points` grown by
    /// `pad` metres (the frustum's plan-view footprint, Willmott et al., §3.2.4: cells nobody looks at
    /// need no shadow). Drawing fewer cells only ever hides less, so any window is conservative;
    /// boxes that stick out of the window are not hidden.
    pub fn set_window(&mut self, points: &[DVec2], pad: f64) {
        let g = self.grid;
        let hull = convex_hull(points);
        let pad = if pad.is_finite() { pad.max(0.0) } else { 0.0 };
        self.window = CellRect::EMPTY;
        for j in 0..g.ny {
            let (y0, y1) = (g.y(j) - pad, g.y(j + 1) + pad);
            // x-extent of the hull within the slab [y0, y1].
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..hull.len() {
                let (p, q) = (hull[k], hull[(k + 1) % hull.len()]);
                if p.y >= y0 && p.y <= y1 {
                    lo = lo.min(p.x);
                    hi = hi.max(p.x);
                }
                for y in [y0, y1] {
                    if (p.y - y) * (q.y - y) < 0.0 {
                        let x = p.x + (q.x - p.x) * ((y - p.y) / (q.y - p.y));
                        lo = lo.min(x);
                        hi = hi.max(x);
                    }
                }
            }
            let r = if lo <= hi {
                let c = |x: f64| ((x - g.origin.x) / g.cell).floor();
                let i0 = (c(lo - pad) - 1.0).clamp(0.0, g.nx as f64) as usize;
                let i1 = (c(hi + pad) + 2.0).clamp(0.0, g.nx as f64) as usize;
                (i0, i1.max(i0))
            } else {
                (0, 0)
            };
            self.row_window[j] = r;
            if r.0 < r.1 {
                self.window.include(r.0, r.1, j);
            }
        }
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Cell values, row-major (`j * nx + i`).
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// The value of cell `(i, j)`.
    pub fn value(&self, i: usize, j: usize) -> f32 {
        self.values[j * self.grid.nx + i]
    }

    /// Resets every cell to −∞ (only the rows and columns written since the last clear).
    pub fn clear(&mut self) {
        let (d, nx) = (self.dirty, self.grid.nx);
        if !d.is_empty() {
            for j in d.j0..d.j1 {
                self.values[j * nx + d.i0..j * nx + d.i1].fill(f32::NEG_INFINITY);
            }
        }
        self.dirty = CellRect::EMPTY;
    }

    /// Draws one shadow, keeping the maximum per cell, into cells the shadow covers completely
    /// and that lie in the window (see [`CullMap::set_window`]). Returns the number of cells
    /// covered.
    ///
    /// Scanline span fill: only the rows the shadow's region (clipped to the window) can reach
    /// are visited; per row the covered columns are the intersection of the shadow's x-intervals
    /// on the row's two boundary lines (a cell lies in a convex region iff its four corners do),
    /// and the plane's minimum over a cell is at its left or right column boundary according to
    /// the sign of the x slope, the same for the whole shadow. A row whose interval, cut to the
    /// window, is narrower than half a cell is dropped before any column search.
    pub fn draw(&mut self, s: &OccluderShadow) -> u64 {
        let g = self.grid;
        let w = self.window;
        if w.j0 >= w.j1 {
            return 0;
        }
        let (x_lo, x_hi) = (g.x(0), g.x(g.nx));
        // Rows the region can reach inside the window box (one row of slack each side).
        let Some((ymin, ymax)) = region_y_range(
            s,
            DVec2::new(g.x(w.i0), g.y(w.j0)),
            DVec2::new(g.x(w.i1), g.y(w.j1)),
            &mut self.clip,
        ) else {
            return 0;
        };
        let fj = |y: f64| ((y - g.origin.y) / g.cell).floor();
        let j0 = (fj(ymin) - 1.0).max(w.j0 as f64) as usize;
        let j1 = ((fj(ymax) + 2.0).min(w.j1 as f64).max(0.0) as usize).max(j0);
        let p = s.plane;
        // Column boundary offset (0 or 1) holding the plane's minimum over a cell.
        let right = (p.zx < 0.0) as usize;
        let mut covered = 0u64;
        let rb = s.row_bounds(self.margin);
        let (inv, half) = (1.0 / g.cell, 0.5 * g.cell);
        let xs = &self.xs[..];
        let mut y_next = g.y(j0);
        let mut prev = rb.interval(y_next, x_lo, x_hi);
        for j in j0..j1 {
            let y_prev = y_next;
            y_next = g.y(j + 1);
            let next = rb.interval(y_next, x_lo, x_hi);
            let (Some((a0, a1)), Some((b0, b1))) = (prev, next) else {
                prev = next;
                continue;
            };
            prev = next;
            let (r0, r1) = self.row_window[j];
            if r0 >= r1 {
                continue;
            }
            // The row's interval cut to the window's columns: the smallest boundary ≥ lo is
            // then at least r0 and the largest ≤ hi at most r1 (the boundaries increase).
            let lo = a0.max(b0).max(xs[r0]);
            let hi = a1.min(b1).min(xs[r1]);
            // Two boundaries in [lo, hi] are a cell apart (give or take a rounding far below
            // half a cell): a narrower interval holds no cell. Most rows of the long, thin
            // wedges end here. (lo and hi are finite: taken with the table's boundaries.)
            if hi - lo < half {
                continue;
            }
            let Some((i0, i1)) = columns_in(xs, g.origin.x, inv, lo, hi) else {
                continue;
            };
            let zy = (p.zy * y_prev).min(p.zy * y_next);
            let base = p.z0 + zy - self.height_margin;
            let row = &mut self.values[j * g.nx + i0..j * g.nx + i1];
            for (cell, &x) in row.iter_mut().zip(&xs[i0 + right..i1 + right]) {
                *cell = cell.max(stored_height(base + p.zx * x));
            }
            covered += (i1 - i0) as u64;
            self.dirty.include(i0, i1, j);
        }
        covered
    }

    /// True when every cell met by the segment `a`–`b` (sampled every half cell) already holds
    /// at least `height`: a wall standing there up to `height` lies inside shadows drawn before
    /// it, so everything it hides is hidden by their walls too (the ray from the eye to a point
    /// behind it crosses the wall at a hidden point, hence crosses an earlier wall before).
    /// Used to skip such occluders; a wrong answer either way only costs effectiveness or time,
    /// never correctness, since drawing fewer shadows only hides less.
    pub fn segment_hidden(&self, a: DVec2, b: DVec2, height: f64) -> bool {
        let g = &self.grid;
        let d = b - a;
        let n = ((d.length() / (0.5 * g.cell)).ceil()).clamp(1.0, 1e6) as usize;
        let inv = 1.0 / g.cell;
        for k in 0..=n {
            let p = a + d * (k as f64 / n as f64);
            let (fi, fj) = ((p.x - g.origin.x) * inv, (p.y - g.origin.y) * inv);
            if !(fi >= 0.0 && fj >= 0.0 && fi < g.nx as f64 && fj < g.ny as f64) {
                return false;
            }
            let v = self.values[fj as usize * g.nx + fi as usize];
            if (v as f64) < height || height.is_nan() {
                return false;
            }
        }
        true
    }

    /// Reference rasterisation: the same cells and values as [`CullMap::draw`] over the whole
    /// map (no window), visiting every row and taking each cell's minimum with `min`. Kept to
    /// check the fast path cell by cell.
    pub fn draw_reference(&mut self, s: &OccluderShadow) -> u64 {
        let g = self.grid;
        let (x_lo, x_hi) = (g.x(0), g.x(g.nx));
        let p = s.plane;
        let mut covered = 0u64;
        // Interval of the shadow on the previous boundary line.
        let mut prev = s.row_interval(g.y(0), self.margin, x_lo, x_hi);
        for j in 0..g.ny {
            let next = s.row_interval(g.y(j + 1), self.margin, x_lo, x_hi);
            if let (Some((a0, a1)), Some((b0, b1))) = (prev, next) {
                let lo = a0.max(b0);
                let hi = a1.min(b1);
                if lo < hi {
                    // First column boundary ≥ lo and last ≤ hi; corrected for rounding.
                    let mut i0 = ((lo - g.origin.x) / g.cell).ceil().max(0.0) as usize;
                    while i0 > 0 && g.x(i0 - 1) >= lo {
                        i0 -= 1;
                    }
                    while i0 <= g.nx && g.x(i0) < lo {
                        i0 += 1;
                    }
                    let mut i1 = (((hi - g.origin.x) / g.cell).floor().max(0.0) as usize).min(g.nx);
                    while i1 < g.nx && g.x(i1 + 1) <= hi {
                        i1 += 1;
                    }
                    while i1 > 0 && g.x(i1) > hi {
                        i1 -= 1;
                    }
                    if i1 > i0 && g.x(i1) <= hi {
                        let (y0, y1) = (g.y(j), g.y(j + 1));
                        let zy = (p.zy * y0).min(p.zy * y1);
                        let base = p.z0 + zy - self.height_margin;
                        let row = &mut self.values[j * g.nx..(j + 1) * g.nx];
                        for (i, cell) in row.iter_mut().enumerate().take(i1).skip(i0) {
                            let zx = (p.zx * g.x(i)).min(p.zx * g.x(i + 1));
                            *cell = cell.max(stored_height(base + zx));
                        }
                        covered += (i1 - i0) as u64;
                    }
                }
            }
            prev = next;
        }
        self.dirty = CellRect::full(&g);
        covered
    }

    /// Rebuilds the min pyramid from the cells; call after drawing, before [`CullMap::box_hidden`].
    ///
    /// Only the part of the pyramid over the cells written since the last clear, and over those
    /// of the previous build, is recomputed; everything else is −∞ in both.
    pub fn build_pyramid(&mut self) {
        let region = self.dirty.union(&self.built);
        if !region.is_empty() {
            self.pyramid.build_region(&self.values, region);
        }
        self.built = self.dirty;
    }

    /// Rebuilds the whole min pyramid from the cells (reference for the partial rebuild).
    pub fn build_pyramid_full(&mut self) {
        self.pyramid.build(&self.values);
        self.built = CellRect::full(&self.grid);
    }

    /// The min pyramid (valid after [`CullMap::build_pyramid`]).
    pub fn pyramid(&self) -> &MinPyramid {
        &self.pyramid
    }

    /// Brute force: true when the box's top is at or below the cull map value in every cell its
    /// plan-view footprint touches.
    ///
    /// The seed tests one point (the footprint's centre at the box's top, §3.2.8), which misses
    /// parts of the box that stick out of a shadow; here every touched cell must hide the top,
    /// and cells are counted as touched with a small pad so that a box whose side lies on a cell
    /// boundary also tests the neighbouring cell. A box reaching outside the map is never hidden.
    pub fn box_hidden_brute(&self, b: &Aabb3) -> bool {
        let Some((i0, i1, j0, j1)) = self.touched(b) else {
            return false;
        };
        let top = f32_up(drawn_top(b));
        (j0..=j1).all(|j| (i0..=i1).all(|i| self.value(i, j) >= top))
    }

    /// As [`CullMap::box_hidden_brute`], through the min pyramid: the box is first tested at the
    /// level where it covers at most 2×2 cells, and only cells that fail are refined. Gives the
    /// same answer as the brute force test.
    pub fn box_hidden(&self, b: &Aabb3) -> bool {
        let Some((i0, i1, j0, j1)) = self.touched(b) else {
            return false;
        };
        self.pyramid
            .all_at_least(i0, i1, j0, j1, f32_up(drawn_top(b)))
    }

    fn touched(&self, b: &Aabb3) -> Option<(usize, usize, usize, usize)> {
        if b.is_empty() || !b.max.z.is_finite() {
            return None;
        }
        // The drawn mesh of what the box bounds is rounded to f32 (see `drawn_top`).
        let m = b
            .min
            .truncate()
            .abs()
            .max(b.max.truncate().abs())
            .max_element();
        let pad = self.margin + f32::EPSILON as f64 * m + 1e-6;
        self.grid
            .cells_touched(b.min.truncate(), b.max.truncate(), pad)
    }
}

/// The highest the drawn top of what `b` bounds can be: the meshes hold local-frame f32
/// coordinates, each within half an ulp (at most `2^-24 |z|`, bounded here by
/// `f32::EPSILON · |z|`) of the f64 value, plus a micrometre for the world → local subtraction.
/// The plan-view extent is padded the same way in `touched`.
fn drawn_top(b: &Aabb3) -> f64 {
    b.max.z + f32::EPSILON as f64 * b.max.z.abs() + 1e-6
}

/// A min pyramid over the cull map: level 0 is the map, each level above holds the minimum of (up
/// to) 2×2 cells below it.
#[derive(Clone, Debug)]
pub struct MinPyramid {
    /// Levels from fine (0) to one cell; `(nx, ny, values)`.
    levels: Vec<(usize, usize, Vec<f32>)>,
}

impl MinPyramid {
    fn new(nx: usize, ny: usize) -> Self {
        let mut levels = vec![(nx, ny, vec![f32::NEG_INFINITY; nx * ny])];
        let (mut w, mut h) = (nx, ny);
        while w > 1 || h > 1 {
            w = w.div_ceil(2);
            h = h.div_ceil(2);
            levels.push((w, h, vec![f32::NEG_INFINITY; w * h]));
        }
        Self { levels }
    }

    /// Number of levels.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    fn build(&mut self, base: &[f32]) {
        self.levels[0].2.copy_from_slice(base);
        for l in 1..self.levels.len() {
            let (lo, hi) = self.levels.split_at_mut(l);
            let (cw, ch, child) = (&lo[l - 1].0, &lo[l - 1].1, &lo[l - 1].2);
            let (w, h, vals) = (&hi[0].0, &hi[0].1, &mut hi[0].2);
            for j in 0..*h {
                for i in 0..*w {
                    let mut m = f32::INFINITY;
                    for dj in 0..2 {
                        for di in 0..2 {
                            let (ci, cj) = (2 * i + di, 2 * j + dj);
                            if ci < *cw && cj < *ch {
                                m = m.min(child[cj * cw + ci]);
                            }
                        }
                    }
                    vals[j * w + i] = m;
                }
            }
        }
    }

    /// As `build`, recomputing only the cells over `r` at every level.
    fn build_region(&mut self, base: &[f32], r: CellRect) {
        let nx = self.levels[0].0;
        for j in r.j0..r.j1 {
            let s = j * nx;
            self.levels[0].2[s + r.i0..s + r.i1].copy_from_slice(&base[s + r.i0..s + r.i1]);
        }
        for l in 1..self.levels.len() {
            let (lo, hi) = self.levels.split_at_mut(l);
            let (cw, ch, child) = (lo[l - 1].0, lo[l - 1].1, &lo[l - 1].2);
            let (w, vals) = (hi[0].0, &mut hi[0].2);
            let (i0, i1) = (r.i0 >> l, ((r.i1 - 1) >> l) + 1);
            let (j0, j1) = (r.j0 >> l, ((r.j1 - 1) >> l) + 1);
            for j in j0..j1 {
                for i in i0..i1 {
                    let (ci, cj) = (2 * i, 2 * j);
                    let mut m = child[cj * cw + ci];
                    if ci + 1 < cw {
                        m = m.min(child[cj * cw + ci + 1]);
                    }
                    if cj + 1 < ch {
                        m = m.min(child[(cj + 1) * cw + ci]);
                        if ci + 1 < cw {
                            m = m.min(child[(cj + 1) * cw + ci + 1]);
                        }
                    }
                    vals[j * w + i] = m;
                }
            }
        }
    }

    /// True when every level-0 cell in `[i0, i1] × [j0, j1]` is ≥ `top`.
    pub fn all_at_least(&self, i0: usize, i1: usize, j0: usize, j1: usize, top: f32) -> bool {
        let mut l = 0;
        while l + 1 < self.levels.len() && ((i1 >> l) - (i0 >> l) > 1 || (j1 >> l) - (j0 >> l) > 1)
        {
            l += 1;
        }
        for cj in (j0 >> l)..=(j1 >> l) {
            for ci in (i0 >> l)..=(i1 >> l) {
                if !self.cell_ok(l, ci, cj, (i0, i1, j0, j1), top) {
                    return false;
                }
            }
        }
        true
    }

    fn cell_ok(
        &self,
        l: usize,
        ci: usize,
        cj: usize,
        r: (usize, usize, usize, usize),
        top: f32,
    ) -> bool {
        let (w, _, vals) = &self.levels[l];
        if vals[cj * w + ci] >= top {
            return true;
        }
        if l == 0 {
            return false;
        }
        let (cw, ch, _) = &self.levels[l - 1];
        let (i0, i1, j0, j1) = (
            r.0 >> (l - 1),
            r.1 >> (l - 1),
            r.2 >> (l - 1),
            r.3 >> (l - 1),
        );
        for dj in 0..2 {
            for di in 0..2 {
                let (x, y) = (2 * ci + di, 2 * cj + dj);
                if x < *cw
                    && y < *ch
                    && x >= i0
                    && x <= i1
                    && y >= j0
                    && y <= j1
                    && !self.cell_ok(l - 1, x, y, r, top)
                {
                    return false;
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::super::shadow::Occluder;
    use super::*;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    fn map(n: u32) -> CullMap {
        CullMap::new(
            DVec2::new(-100.0, -100.0),
            DVec2::new(100.0, 100.0),
            Resolution::Cells(n),
        )
        .unwrap()
    }

    fn wall() -> Occluder {
        Occluder {
            a: DVec2::new(10.0, -20.0),
            b: DVec2::new(10.0, 20.0),
            height: 15.0,
        }
    }

    /// Brute force coverage: a cell is covered when its four corners lie in the closed region;
    /// the stored value must never exceed the plane's minimum over the corners.
    #[test]
    fn drawn_cells_are_fully_covered_and_below_the_plane() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in [16u32, 64, 200] {
            for _ in 0..40 {
                let mut m = map(n);
                let v = DVec3::new(
                    rng.random_range(-90.0..5.0),
                    rng.random_range(-90.0..90.0),
                    rng.random_range(0.0..40.0),
                );
                let Ok(s) = OccluderShadow::new(v, &wall()) else {
                    continue;
                };
                m.draw(&s);
                let g = *m.grid();
                let mut drawn = 0;
                for j in 0..g.ny {
                    for i in 0..g.nx {
                        let val = m.value(i, j);
                        let corners = [
                            DVec2::new(g.x(i), g.y(j)),
                            DVec2::new(g.x(i + 1), g.y(j)),
                            DVec2::new(g.x(i), g.y(j + 1)),
                            DVec2::new(g.x(i + 1), g.y(j + 1)),
                        ];
                        let inside = corners.iter().all(|c| s.contains(*c));
                        if val > f32::NEG_INFINITY {
                            drawn += 1;
                            assert!(inside, "cell {i},{j} drawn but not covered");
                            let zmin = corners
                                .iter()
                                .map(|c| s.plane.at(*c))
                                .fold(f64::INFINITY, f64::min);
                            assert!((val as f64) <= zmin, "{val} > {zmin}");
                            assert!((val as f64) > zmin - 1e-2, "too low: {val} vs {zmin}");
                        } else {
                            // Cells strictly inside (with some slack) must have been drawn.
                            let strictly = corners
                                .iter()
                                .all(|c| s.region.iter().all(|h| h.eval(*c) > 1e-6));
                            assert!(!strictly, "cell {i},{j} covered but not drawn");
                        }
                    }
                }
                let _ = drawn;
            }
        }
    }

    #[test]
    fn segment_hidden_reads_the_drawn_cells() {
        // The wall x = 10, y ∈ [−20, 20], 15 m high, seen from the origin at 1.7 m: its shadow
        // plane rises behind it (about 28 m at x = 20).
        let mut m = map(64);
        let v = DVec3::new(0.0, 0.0, 1.7);
        m.draw(&OccluderShadow::new(v, &wall()).unwrap());
        let (a, b) = (DVec2::new(30.0, -5.0), DVec2::new(30.0, 5.0));
        assert!(m.segment_hidden(a, b, 15.0), "a lower wall behind it");
        assert!(
            !m.segment_hidden(a, b, 80.0),
            "a wall rising above the shadow"
        );
        assert!(
            !m.segment_hidden(DVec2::new(5.0, -5.0), DVec2::new(5.0, 5.0), 1.0),
            "a wall in front of it"
        );
        assert!(
            !m.segment_hidden(DVec2::new(30.0, -80.0), DVec2::new(30.0, 5.0), 1.0),
            "a wall reaching out of the shadow's wedge"
        );
        assert!(
            !m.segment_hidden(DVec2::new(30.0, 0.0), DVec2::new(130.0, 0.0), 1.0),
            "a wall leaving the map"
        );
        assert!(!m.segment_hidden(a, b, f64::NAN));
    }

    #[test]
    fn viewer_cell_and_front_are_never_drawn() {
        let mut m = map(64);
        let v = DVec3::new(0.0, 0.0, 1.7);
        m.draw(&OccluderShadow::new(v, &wall()).unwrap());
        let g = *m.grid();
        for j in 0..g.ny {
            for i in 0..g.nx {
                if m.value(i, j) > f32::NEG_INFINITY {
                    assert!(g.x(i) >= 10.0, "cell in front of the wall drawn");
                }
            }
        }
        // Something was drawn behind the wall.
        assert!(m.values().iter().any(|v| *v > 15.0));
    }

    #[test]
    fn wall_on_a_cell_boundary_does_not_hide_its_own_building() {
        // Map cells of 200/64 = 3.125 m; put the wall at x = 12.5 (a boundary).
        let mut m = map(64);
        let occ = Occluder {
            a: DVec2::new(12.5, -20.0),
            b: DVec2::new(12.5, 20.0),
            height: 15.0,
        };
        m.draw(&OccluderShadow::new(DVec3::new(0.0, 0.0, 1.7), &occ).unwrap());
        m.build_pyramid();
        let own = Aabb3::new(DVec3::new(12.5, -20.0, 0.0), DVec3::new(30.0, 20.0, 15.0));
        assert!(!m.box_hidden_brute(&own));
        assert!(!m.box_hidden(&own));
        let behind = Aabb3::new(DVec3::new(40.0, -5.0, 0.0), DVec3::new(50.0, 5.0, 20.0));
        assert!(m.box_hidden_brute(&behind));
        assert!(m.box_hidden(&behind));
    }

    #[test]
    fn pyramid_equals_brute_force_on_random_boxes() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for (n, extent) in [(64u32, 200.0), (100, 200.0), (37, 150.0)] {
            let mut m = CullMap::new(
                DVec2::new(-100.0, -100.0),
                DVec2::new(-100.0 + extent, 100.0),
                Resolution::Cells(n),
            )
            .unwrap();
            for _ in 0..6 {
                let a = DVec2::new(rng.random_range(-90.0..40.0), rng.random_range(-90.0..90.0));
                let b =
                    a + DVec2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0));
                let occ = Occluder {
                    a,
                    b,
                    height: rng.random_range(5.0..30.0),
                };
                let v = DVec3::new(
                    rng.random_range(-100.0..50.0),
                    rng.random_range(-100.0..100.0),
                    rng.random_range(0.0..20.0),
                );
                if let Ok(s) = OccluderShadow::new(v, &occ) {
                    m.draw(&s);
                }
            }
            m.build_pyramid();
            let mut hidden = 0;
            for _ in 0..3000 {
                let c = DVec2::new(
                    rng.random_range(-110.0..60.0),
                    rng.random_range(-110.0..110.0),
                );
                let e = DVec2::new(rng.random_range(0.0..40.0), rng.random_range(0.0..40.0));
                let b = Aabb3::new(c.extend(0.0), (c + e).extend(rng.random_range(0.0..40.0)));
                let brute = m.box_hidden_brute(&b);
                assert_eq!(brute, m.box_hidden(&b), "{b:?}");
                hidden += brute as usize;
            }
            assert!(hidden > 0, "test would be vacuous");
        }
    }

    fn random_shadow(rng: &mut rand_chacha::ChaCha8Rng) -> Option<OccluderShadow> {
        let a = DVec2::new(rng.random_range(-90.0..90.0), rng.random_range(-90.0..90.0));
        let b = a + DVec2::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0));
        let occ = Occluder {
            a,
            b,
            height: rng.random_range(1.0..40.0),
        };
        let v = DVec3::new(
            rng.random_range(-120.0..120.0),
            rng.random_range(-120.0..120.0),
            rng.random_range(0.0..50.0),
        );
        OccluderShadow::new(v, &occ).ok()
    }

    /// The span fill writes exactly the cells and values of the reference rasterisation, and
    /// the partial pyramid equals a full rebuild, over several frames (clears in between).
    #[test]
    fn span_fill_equals_reference_cell_by_cell() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        let mut drawn = 0u64;
        for n in [7u32, 16, 64, 201] {
            let mut fast = map(n);
            let mut refm = map(n);
            for _frame in 0..6 {
                fast.clear();
                refm.clear();
                for _ in 0..12 {
                    let Some(s) = random_shadow(&mut rng) else {
                        continue;
                    };
                    let c = fast.draw(&s);
                    assert_eq!(c, refm.draw_reference(&s));
                    drawn += c;
                }
                let (a, b) = (fast.values(), refm.values());
                for k in 0..a.len() {
                    assert_eq!(a[k].to_bits(), b[k].to_bits(), "n {n} cell {k}");
                }
                fast.build_pyramid();
                refm.build_pyramid_full();
                for l in 0..fast.pyramid.levels.len() {
                    assert_eq!(
                        fast.pyramid.levels[l].2, refm.pyramid.levels[l].2,
                        "level {l}"
                    );
                }
            }
        }
        assert!(drawn > 1000, "vacuous: {drawn}");
    }

    /// With a window, drawn cells are exactly the reference's cells inside the window's rows
    /// and columns, and nothing outside it.
    #[test]
    fn window_only_restricts_cells() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut m = map(64);
        let mut refm = map(64);
        let tri = [
            DVec2::new(-30.0, -10.0),
            DVec2::new(80.0, -70.0),
            DVec2::new(70.0, 60.0),
        ];
        m.set_window(&tri, 0.0);
        let g = *m.grid();
        let (mut inside, mut outside) = (0, 0);
        for _ in 0..40 {
            let Some(s) = random_shadow(&mut rng) else {
                continue;
            };
            m.draw(&s);
            refm.draw_reference(&s);
        }
        for j in 0..g.ny {
            let (r0, r1) = m.row_window[j];
            for i in 0..g.nx {
                let (a, b) = (m.value(i, j), refm.value(i, j));
                if i >= r0 && i < r1 {
                    assert_eq!(a.to_bits(), b.to_bits());
                    inside += (b > f32::NEG_INFINITY) as u32;
                } else {
                    assert_eq!(a, f32::NEG_INFINITY);
                    outside += (b > f32::NEG_INFINITY) as u32;
                }
                // Every cell meeting the triangle is in the window.
                let c = DVec2::new(g.x(i) + g.cell / 2.0, g.y(j) + g.cell / 2.0);
                let in_tri = (0..3).all(|k| {
                    let (p, q) = (tri[k], tri[(k + 1) % 3]);
                    (q - p).perp_dot(c - p) >= 0.0
                });
                if in_tri {
                    assert!(
                        i >= r0 && i < r1,
                        "cell {i},{j} in the triangle, not the window"
                    );
                }
            }
        }
        assert!(inside > 0 && outside > 0, "{inside} {outside}");
    }

    /// The table lookup gives the same columns as the grid's own search, over random
    /// intervals, intervals ending on boundaries, and intervals narrower than a cell.
    #[test]
    fn columns_in_equals_columns_within() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut found = 0;
        for n in [1u32, 7, 64, 257] {
            let m = CullMap::new(
                DVec2::new(512_345.6, -80.0),
                DVec2::new(514_000.1, 900.0),
                Resolution::Cells(n),
            )
            .unwrap();
            let g = *m.grid();
            let (lo_x, hi_x) = (g.x(0), g.x(g.nx));
            for k in 0..4000 {
                let (mut lo, mut hi) = (rng.random_range(lo_x..hi_x), rng.random_range(lo_x..hi_x));
                if k % 3 == 0 {
                    lo = g.x(rng.random_range(0..=g.nx));
                }
                if k % 5 == 0 {
                    hi = g.x(rng.random_range(0..=g.nx));
                }
                if k % 7 == 0 {
                    hi = lo + rng.random_range(0.0..1.5) * g.cell;
                }
                let (lo, hi) = (lo.max(lo_x), hi.min(hi_x));
                let want = g.columns_within(lo, hi);
                found += want.is_some() as usize;
                assert_eq!(
                    columns_in(&m.xs, g.origin.x, 1.0 / g.cell, lo, hi),
                    want,
                    "n {n}: [{lo}, {hi}]"
                );
            }
        }
        assert!(found > 1000, "vacuous: {found}");
    }

    #[test]
    fn rounding_helpers_are_directed() {
        for v in [0.1f64, 1.0 / 3.0, 12345.678901, -7.3, 1e30] {
            assert!(f32_up(v) as f64 >= v);
        }
        // Stored heights never exceed the plane and stay within a few f32 ulps of it, over
        // random values of every magnitude and sign, values just above an f32 (where rounding
        // to nearest goes up), zero, subnormals and values beyond f32's range.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let mut vals = vec![
            0.0,
            -0.0,
            1e-40,
            -1e-40,
            1e-300,
            1e39,
            -1e39,
            f64::MAX,
            -f64::MAX,
        ];
        for _ in 0..100_000 {
            let m: f64 = rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-6..8));
            vals.push(m);
            let f = m as f32;
            vals.push(f as f64 + (f.next_up() as f64 - f as f64) * 0.49);
        }
        for v in vals {
            let s = stored_height(v);
            assert!((s as f64) <= v, "{v}: {s}");
            if v.abs() > 1e-20 && v.abs() < 1e38 {
                assert!((s as f64) >= v - 3e-7 * v.abs(), "{v}: {s} too low");
            }
        }
        assert!(stored_height(f64::NAN).is_nan());
    }

    #[test]
    fn bad_resolutions_are_refused() {
        let (a, b) = (DVec2::ZERO, DVec2::splat(100.0));
        for r in [
            Resolution::Cells(0),
            Resolution::Cells(5000),
            Resolution::CellSize(f64::NAN),
            Resolution::CellSize(-1.0),
        ] {
            let e = CullMap::new(a, b, r).unwrap_err();
            assert!(
                matches!(
                    e,
                    VisibilityError::BadResolution {
                        max: MAX_CELLS_PER_SIDE,
                        ..
                    }
                ),
                "{r:?}: {e:?}"
            );
        }
        let e = CullMap::new(a, b, Resolution::CellSize(0.001)).unwrap_err();
        assert!(
            matches!(e, VisibilityError::TooManyCells { nx, ny, max, .. } if nx > max && ny > max),
            "{e:?}"
        );
        let e = CullMap::new(b, a, Resolution::Cells(4)).unwrap_err();
        assert!(
            matches!(e, VisibilityError::BadBounds { min, max } if min == [100.0; 2] && max == [0.0; 2]),
            "{e:?}"
        );
        let g = *CullMap::new(a, DVec2::new(100.0, 50.0), Resolution::Cells(64))
            .unwrap()
            .grid();
        assert_eq!((g.nx, g.ny), (64, 32));
    }
}
