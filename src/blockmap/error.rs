//! The geometric error of a BlockMap, measured (BLOCKMAPS.md §B.3): a sampled symmetric
//! Hausdorff distance in f64 between the surface of the map's prisms and the surface of the
//! original prisms, and the declared bound `ε = max(½ voxel diagonal (Cignoni et al., §3.3), measured)`.
//!
//! Both surfaces are taken with the ground (`z = 0`) as part of them, as a viewer sees them.
//! Distances are exact point-to-surface distances; only the point sets are sampled:
//! - original → map: roof points on a lattice of one texel side and along the roof outline every
//!   half texel, wall points along every ring edge every half texel at the bottom, the top and
//!   every 2 texels in between (a wall covered by a neighbour prism is not a surface and is
//!   skipped); for raised parts (`min_height` > 0) the underside and the ground below it, which a
//!   2.5D map cannot represent (Di Benedetto, §4.2.1: height fields are 2.5D).
//! - map → original: every texel's top at its centre and corners, and every exposed side at its
//!   midpoint (at the bottom, the top and every 2 texels of its wall) and its two ends (bottom
//!   and top).
//!
//! A sample farther than the ½ voxel diagonal is a feature the 2.5D grid cannot hold: a building
//! narrower than a texel that vanished or swelled, a courtyard or street narrower than a texel
//! that was filled, or a raised part. A roof sample whose nearest map surface is the ground
//! below marks a building (part) the map does not hold at all, whatever its error. These are
//! reported with building ids, never hidden.

use super::layout::BlockMap;
use super::source::{Source, SourceBuilding};
use glam::{DVec2, DVec3};
use serde::Serialize;

/// What kind of feature exceeded the ½ voxel diagonal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ThinKind {
    /// A building (or part of one) narrower than a texel: its surface is far from the map's.
    NarrowBuilding,
    /// The map has a surface where the original has a gap narrower than a texel (a courtyard
    /// or a street filled in).
    FilledGap,
    /// A raised part (`min_height` > 0) or a bridge: filled down to the ground by the map.
    RaisedPart,
    /// (Part of) a building the map does not hold: the nearest map surface to a roof sample is
    /// the ground below it, so the error there is the building's height, reported even when
    /// that is under the ½ voxel diagonal (a low building between texel centres vanishes, and
    /// a viewer can miss it).
    Vanished,
}

/// A feature whose error exceeds the ½ voxel diagonal.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ThinFeature {
    /// Kind.
    pub kind: ThinKind,
    /// The building (its index in `City::buildings`) and its source id.
    pub building: u32,
    /// Source id.
    pub source_id: String,
    /// Largest distance found for it, metres.
    pub error_m: f64,
    /// Where (local frame x, y), metres.
    pub at: [f64; 2],
}

/// The measured error of one map.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ErrorReport {
    /// ½·√(2s² + Δz²), metres (Cignoni et al., §3.3).
    pub half_voxel_diagonal_m: f64,
    /// Largest original → map distance, metres.
    pub original_to_map_m: f64,
    /// Largest map → original distance, metres.
    pub map_to_original_m: f64,
    /// `max` of the two, metres.
    pub measured_m: f64,
    /// `max(½ voxel diagonal, measured)`, metres.
    pub declared_m: f64,
    /// Samples taken.
    pub samples: usize,
    /// Buildings with `min_height` > 0.
    pub raised_parts: usize,
    /// Buildings marked as bridges.
    pub bridges: usize,
    /// Features past the ½ voxel diagonal, one entry per building and kind (largest error).
    pub thin: Vec<ThinFeature>,
}

/// What the original → map samples of one building found so far.
struct BuildingError {
    /// Largest distance of a surface sample, and where.
    worst: f64,
    worst_at: DVec2,
    /// Largest distance of an underside (or ground below a raised part) sample.
    raised: f64,
    /// The largest roof distance that marks the building vanished, and where.
    vanished: Option<(f64, DVec2)>,
}

/// Working memory of [`BuildingGrid`]'s queries: reuse one per thread.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    list: Vec<u32>,
    mark: Vec<u32>,
    gen: u32,
    levels: Vec<f64>,
    covering: Vec<u32>,
}

/// Buildings per texel of a map (by footprint box), to find the prisms near a point.
pub struct BuildingGrid<'a> {
    k: usize,
    min: DVec2,
    s: f64,
    /// The buildings of cell `c` are `items[start[c]..start[c + 1]]` (in building order).
    start: Vec<u32>,
    items: Vec<u32>,
    all: Vec<&'a SourceBuilding>,
    /// Each building's box, `[min.x, min.y, max.x, max.y, z0, z1]`, side by side: the tests
    /// that reject most candidates read only these.
    boxes: Vec<[f64; 6]>,
}

impl<'a> BuildingGrid<'a> {
    /// Buckets `buildings` (indices into `source.buildings`) over the map's square.
    pub fn new(map: &BlockMap, source: &'a Source, buildings: &[u32]) -> Self {
        Self::over_square(
            DVec2::new(map.meta.min[0], map.meta.min[1]),
            map.texel_m(),
            map.k() as usize,
            source,
            buildings,
        )
    }

    /// Buckets `buildings` over the `k × k` cells of side `s` from `min` (local frame): the
    /// square of any far-field node.
    pub fn over_square(
        min: DVec2,
        s: f64,
        k: usize,
        source: &'a Source,
        buildings: &[u32],
    ) -> Self {
        let all: Vec<&SourceBuilding> = buildings
            .iter()
            .filter_map(|&i| source.buildings.get(i as usize).and_then(|b| b.as_ref()))
            .collect();
        // The cells each building's box covers.
        let span = |b: &SourceBuilding| {
            let c0 = ((b.min - min) / s).floor();
            let c1 = ((b.max - min) / s).floor();
            let (i0, j0) = (c0.x.max(0.0) as usize, c0.y.max(0.0) as usize);
            let (i1, j1) = (
                (c1.x.max(0.0) as usize).min(k - 1),
                (c1.y.max(0.0) as usize).min(k - 1),
            );
            (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| j * k + i))
        };
        // Counted, then filled: one array for all cells.
        let mut start = vec![0u32; k * k + 1];
        for b in &all {
            for c in span(b) {
                start[c + 1] += 1;
            }
        }
        for c in 0..k * k {
            start[c + 1] += start[c];
        }
        let mut fill: Vec<u32> = start[..k * k].to_vec();
        let mut items = vec![0u32; start[k * k] as usize];
        for (n, b) in all.iter().enumerate() {
            for c in span(b) {
                items[fill[c] as usize] = n as u32;
                fill[c] += 1;
            }
        }
        let boxes = all
            .iter()
            .map(|b| [b.min.x, b.min.y, b.max.x, b.max.y, b.z0, b.z1])
            .collect();
        Self {
            k,
            min,
            s,
            start,
            items,
            all,
            boxes,
        }
    }

    /// The buildings of cell `c`.
    #[inline]
    fn cell(&self, c: usize) -> &[u32] {
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// The buildings whose box may hold `p`: those of its cell (what [`BuildingGrid::near`]
    /// gives for `r = 0`, without copying).
    #[inline]
    fn at(&self, p: DVec2) -> &[u32] {
        let c = (p - self.min) / self.s;
        let (i, j) = (floor_i64(c.x), floor_i64(c.y));
        let k = self.k as i64;
        if i < 0 || j < 0 || i >= k || j >= k {
            return &[];
        }
        self.cell(j as usize * self.k + i as usize)
    }

    /// Buildings whose box may lie within `r` of `p` (horizontally), each once, into
    /// `out.list` (in cell order; a mark per building replaces sorting out the repeats).
    fn near(&self, p: DVec2, r: f64, out: &mut Scratch) {
        out.list.clear();
        if out.mark.len() != self.all.len() {
            out.mark = vec![0; self.all.len()];
            out.gen = 0;
        }
        out.gen = out.gen.wrapping_add(1);
        if out.gen == 0 {
            out.mark.fill(0);
            out.gen = 1;
        }
        let lo = ((p - DVec2::splat(r) - self.min) / self.s).floor();
        let hi = ((p + DVec2::splat(r) - self.min) / self.s).floor();
        let k = self.k as f64;
        if hi.x < 0.0 || hi.y < 0.0 || lo.x >= k || lo.y >= k {
            return;
        }
        let (i0, j0) = (lo.x.max(0.0) as usize, lo.y.max(0.0) as usize);
        let (i1, j1) = (hi.x.min(k - 1.0) as usize, hi.y.min(k - 1.0) as usize);
        for j in j0..=j1 {
            for i in i0..=i1 {
                for &n in self.cell(j * self.k + i) {
                    if out.mark[n as usize] != out.gen {
                        out.mark[n as usize] = out.gen;
                        out.list.push(n);
                    }
                }
            }
        }
    }

    /// Exact distance from `p` to the surface of the original solid (ground ∪ prisms).
    pub fn surface_distance(&self, p: DVec3, scratch: &mut Scratch) -> f64 {
        self.surface_distance_within(p, f64::NEG_INFINITY, scratch)
    }

    /// [`BuildingGrid::surface_distance`] where below the threshold `t` an upper bound will
    /// do: the search stops as soon as it has a surface point within `t`. The value returned
    /// is never below the exact distance, and it is the exact distance unless both are at most
    /// `t` (`t = −∞`: always exact).
    pub fn surface_distance_within(&self, p: DVec3, t: f64, scratch: &mut Scratch) -> f64 {
        let xy = p.truncate();
        // Upper bound: the ground, or the nearest way out of the prisms holding p.
        let mut inside_any = p.z < 0.0;
        let mut bound = p.z.abs();
        let own = self.at(xy);
        // Whether the box of building `n` holds `xy` (the first test of `in_polygon`).
        let holds = |n: u32| {
            let [x0, y0, x1, y1, _, _] = self.boxes[n as usize];
            !(xy.x < x0 || xy.x > x1 || xy.y < y0 || xy.y > y1)
        };
        for &n in own {
            let [.., z0, z1] = self.boxes[n as usize];
            if p.z >= z0 && p.z <= z1 && holds(n) && in_polygon(self.all[n as usize], xy) {
                inside_any = true;
                break;
            }
        }
        if !inside_any {
            // Outside the solid: distance to the solid, the nearest of ground and prisms. The
            // prisms of the point's own cell first, then those of the cells within that bound.
            // A prism whose box is already no nearer than the bound is skipped.
            let dist = |n: u32, bound: f64| {
                let [x0, y0, x1, y1, z0, z1] = self.boxes[n as usize];
                let dv = (z0 - p.z).max(p.z - z1).max(0.0);
                let bx = (x0 - xy.x).max(xy.x - x1).max(0.0);
                let by = (y0 - xy.y).max(xy.y - y1).max(0.0);
                if bx * bx + by * by + dv * dv >= bound * bound {
                    return bound;
                }
                let dh = horizontal_distance(self.all[n as usize], xy);
                (dh * dh + dv * dv).sqrt().min(bound)
            };
            if bound <= t {
                return bound;
            }
            for &n in own {
                bound = dist(n, bound);
                if bound <= t {
                    return bound;
                }
            }
            self.near(xy, bound, scratch);
            for &n in scratch.list.iter() {
                bound = dist(n, bound);
                if bound <= t {
                    return bound;
                }
            }
            return bound;
        }
        // Inside: the nearest point of the complement. Levels where the complement can start:
        // the point's own height (horizontally out), and every prism top above it or raised
        // bottom below it (BLOCKMAPS.md B.3: exact per level; the horizontal way out of a union
        // of footprints is searched along the edges not covered by another footprint, which
        // can only overestimate).
        let mut best = f64::INFINITY;
        // First a cheap upper bound: straight up through every prism stacked at p.
        let mut top = p.z.max(0.0);
        loop {
            let mut raised = false;
            for &n in own {
                let [.., z0, z1] = self.boxes[n as usize];
                if top >= z0 && top < z1 && holds(n) && in_polygon(self.all[n as usize], xy) {
                    top = z1;
                    raised = true;
                }
            }
            if !raised {
                break;
            }
        }
        best = best.min(top - p.z);
        if best <= t {
            return best;
        }
        self.near(xy, best, scratch);
        let Scratch {
            list: cands,
            levels,
            covering,
            ..
        } = scratch;
        levels.clear();
        levels.push(p.z);
        for &n in cands.iter() {
            let b = self.all[n as usize];
            if b.z1 > p.z && b.z1 - p.z < best {
                levels.push(b.z1);
            }
            if b.z0 > 0.0 && b.z0 < p.z && p.z - b.z0 < best {
                levels.push(b.z0);
            }
        }
        levels.sort_by(f64::total_cmp);
        levels.dedup();
        for &l in levels.iter() {
            let dz = (l - p.z).abs();
            if dz >= best {
                continue;
            }
            if l <= 0.0 && l != p.z {
                continue; // below the ground: never a way out
            }
            covering.clear();
            covering.extend(cands.iter().copied().filter(|&n| {
                let b = self.all[n as usize];
                if l == p.z {
                    b.z0 <= l && l <= b.z1
                } else {
                    b.z0 < l && l < b.z1
                }
            }));
            let dh = if l == p.z && p.z < 0.0 {
                f64::INFINITY // below the ground, only upwards
            } else {
                // Only an exit nearer than √(best² − dz²) can improve on `best`.
                horizontal_exit(
                    &self.all,
                    covering,
                    xy,
                    (best * best - dz * dz).max(0.0).sqrt(),
                )
            };
            best = best.min((dh * dh + dz * dz).sqrt());
            if best <= t {
                return best;
            }
        }
        best
    }
}

/// `x.floor() as i64` (saturating, NaN → 0) without the library call: the integer part
/// rounds toward zero, one less for a negative non-integer.
#[inline]
fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

pub(crate) fn in_polygon(b: &SourceBuilding, p: DVec2) -> bool {
    if p.x < b.min.x || p.x > b.max.x || p.y < b.min.y || p.y > b.max.y {
        return false;
    }
    let mut inside = false;
    for ring in &b.rings {
        let n = ring.len();
        let mut j = n - 1;
        for i in 0..n {
            let (a, c) = (ring[i], ring[j]);
            if (a.y > p.y) != (c.y > p.y) && p.x < (c.x - a.x) * (p.y - a.y) / (c.y - a.y) + a.x {
                inside = !inside;
            }
            j = i;
        }
    }
    inside
}

/// Squared distance from `p` to the segment `ac` (as [`seg_dist`] finds the nearest point).
#[inline]
fn seg_dist2(a: DVec2, c: DVec2, p: DVec2) -> f64 {
    let d = c - a;
    let l2 = d.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + d * t - p).length_squared()
}

fn seg_dist(a: DVec2, c: DVec2, p: DVec2) -> (f64, DVec2) {
    let d = c - a;
    let l2 = d.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = a + d * t;
    ((q - p).length(), q)
}

pub(crate) fn horizontal_distance(b: &SourceBuilding, p: DVec2) -> f64 {
    if in_polygon(b, p) {
        return 0.0;
    }
    // The nearest edge by squared distance, one square root (the same value: the root is
    // monotone and correctly rounded).
    let mut best = f64::INFINITY;
    for ring in &b.rings {
        let n = ring.len();
        for e in 0..n {
            best = best.min(seg_dist2(ring[e], ring[(e + 1) % n], p));
        }
    }
    best.sqrt()
}

/// Horizontal distance from `p` to the complement of the union of the footprints of `polys`
/// (indices into `all`; 0 when `p` is outside them all), or `bound` when there is no way out
/// nearer than `bound`. An edge point counts as a way out when a point just outside it lies in
/// no footprint; the nearest such point of each edge is tried.
fn horizontal_exit(all: &[&SourceBuilding], polys: &[u32], p: DVec2, bound: f64) -> f64 {
    let poly = |n: &u32| all[*n as usize];
    if !polys.iter().any(|n| in_polygon(poly(n), p)) {
        return 0.0;
    }
    let mut best = bound;
    for b in polys.iter().map(poly) {
        for ring in &b.rings {
            let n = ring.len();
            for e in 0..n {
                let (a, c) = (ring[e], ring[(e + 1) % n]);
                let (d, q) = seg_dist(a, c, p);
                if d >= best {
                    continue;
                }
                let dir = c - a;
                let out = DVec2::new(dir.y, -dir.x).normalize_or_zero();
                let probe = q + out * (1e-6 * (1.0 + q.abs().max_element()));
                if !polys.iter().any(|o| in_polygon(poly(o), probe)) {
                    best = d;
                }
            }
        }
    }
    best
}

/// A texel column's footprint: a convex polygon (world xy, counter-clockwise, at most 6
/// vertices) and its height.
#[derive(Clone, Copy, Debug)]
struct Part {
    v: [DVec2; 6],
    n: usize,
    h: f64,
}

impl Part {
    fn verts(&self) -> &[DVec2] {
        &self.v[..self.n]
    }
    /// Horizontal distance from `p` (0 inside).
    fn distance(&self, p: DVec2) -> f64 {
        let v = self.verts();
        if v.is_empty() {
            return f64::INFINITY;
        }
        let inside = (0..v.len()).all(|q| (v[(q + 1) % v.len()] - v[q]).perp_dot(p - v[q]) >= 0.0);
        if inside {
            return 0.0;
        }
        (0..v.len())
            .map(|q| seg_dist(v[q], v[(q + 1) % v.len()], p).0)
            .fold(f64::INFINITY, f64::min)
    }
}

/// Splits the convex `part` by the half-plane `g ≤ 0` into the part inside (height of
/// `part`) and the part outside (height `h_out`), either possibly empty.
fn split(part: &Part, g: &dyn Fn(DVec2) -> f64, h_out: f64) -> [Part; 2] {
    let mut out = [
        Part {
            v: [DVec2::ZERO; 6],
            n: 0,
            h: part.h,
        },
        Part {
            v: [DVec2::ZERO; 6],
            n: 0,
            h: h_out,
        },
    ];
    let v = part.verts();
    for q in 0..v.len() {
        let (a, b) = (v[q], v[(q + 1) % v.len()]);
        let (ga, gb) = (g(a), g(b));
        let pa = &mut out[usize::from(ga > 0.0)];
        pa.v[pa.n] = a;
        pa.n += 1;
        if (ga <= 0.0) != (gb <= 0.0) {
            let x = a + (b - a) * (ga / (ga - gb));
            for o in &mut out {
                o.v[o.n] = x;
                o.n += 1;
            }
        }
    }
    out
}

/// The columns of texel `(i, j)` (outside the map: the ground, height 0): the whole square at
/// the texel's height, or, for a texel with footprint edges, the part inside the edges'
/// half-planes at that height and the rest (one convex piece per half-plane) at 0.
fn cell_parts(map: &BlockMap, i: i64, j: i64) -> ([Part; 3], usize) {
    let s = map.texel_m();
    let m = map.meta.min;
    let lo = DVec2::new(m[0] + i as f64 * s, m[1] + j as f64 * s);
    let h = map.texel_height_m(i, j).unwrap_or(0.0);
    let mut v = [DVec2::ZERO; 6];
    v[..4].copy_from_slice(&[
        lo,
        lo + DVec2::new(s, 0.0),
        lo + DVec2::new(s, s),
        lo + DVec2::new(0.0, s),
    ]);
    let whole = Part { v, n: 4, h };
    let [e1, e2] = if h > 0.0 {
        map.edges(i as u32, j as u32)
    } else {
        [None, None]
    };
    let Some(e1) = e1 else {
        return ([whole, whole, whole], 1);
    };
    let c = lo + DVec2::splat(0.5 * s);
    let g = |e: super::layout::Edge| {
        let n = DVec2::new(e.n[0] as f64, e.n[1] as f64);
        move |p: DVec2| n.dot((p - c) / s) - e.o as f64
    };
    let [inside, rest] = split(&whole, &g(e1), 0.0);
    match e2 {
        None => ([inside, rest, rest], 2),
        Some(e2) => {
            let [solid, rest2] = split(&inside, &g(e2), 0.0);
            ([solid, rest, rest2], 3)
        }
    }
}

/// The columns of every texel of a map, cut once ([`cell_parts`] of each texel), for the many
/// distance queries of one measurement against the same map.
pub struct MapColumns<'a> {
    map: &'a BlockMap,
    k: i64,
    s: f64,
    min: DVec2,
    /// Height of each texel's column (0 for an empty texel), row-major.
    h: Vec<f64>,
    /// Index into `cuts` of a texel cut by footprint edges, `u32::MAX` for a whole texel.
    cut: Vec<u32>,
    /// The parts of the cut texels.
    cuts: Vec<([Part; 3], usize)>,
}

impl<'a> MapColumns<'a> {
    /// Cuts every texel of `map`.
    pub fn new(map: &'a BlockMap) -> Self {
        let k = map.k() as i64;
        let n = (k * k) as usize;
        let (mut h, mut cut, mut cuts) = (Vec::with_capacity(n), vec![u32::MAX; n], Vec::new());
        for j in 0..k {
            for i in 0..k {
                let th = map.texel_height_m(i, j).unwrap_or(0.0);
                h.push(th);
                if th > 0.0 && map.edge(i as u32, j as u32).is_some() {
                    cut[(j * k + i) as usize] = cuts.len() as u32;
                    cuts.push(cell_parts(map, i, j));
                }
            }
        }
        Self {
            map,
            k,
            s: map.texel_m(),
            min: DVec2::new(map.meta.min[0], map.meta.min[1]),
            h,
            cut,
            cuts,
        }
    }

    /// The map.
    pub fn map(&self) -> &'a BlockMap {
        self.map
    }

    /// Lower corner of texel `(i, j)`, as [`cell_parts`] places it.
    #[inline]
    fn lo(&self, i: i64, j: i64) -> DVec2 {
        DVec2::new(
            self.min.x + i as f64 * self.s,
            self.min.y + j as f64 * self.s,
        )
    }

    /// The column height of texel `(i, j)` (0 outside the map) and its cut parts, if any.
    #[inline]
    fn cell(&self, i: i64, j: i64) -> (f64, Option<&([Part; 3], usize)>) {
        if i < 0 || j < 0 || i >= self.k || j >= self.k {
            return (0.0, None);
        }
        let q = (j * self.k + i) as usize;
        let c = self.cut[q];
        (self.h[q], (c != u32::MAX).then(|| &self.cuts[c as usize]))
    }

    /// The parts of texel `(i, j)` as [`cell_parts`] gives them (`buf` holds a whole texel).
    #[inline]
    fn parts<'s>(&'s self, i: i64, j: i64, buf: &'s mut [Part; 1]) -> &'s [Part] {
        match self.cell(i, j) {
            (_, Some((parts, n))) => &parts[..*n],
            (h, None) => {
                let lo = self.lo(i, j);
                let s = self.s;
                let mut v = [DVec2::ZERO; 6];
                v[..4].copy_from_slice(&[
                    lo,
                    lo + DVec2::new(s, 0.0),
                    lo + DVec2::new(s, s),
                    lo + DVec2::new(0.0, s),
                ]);
                buf[0] = Part { v, n: 4, h };
                &buf[..]
            }
        }
    }

    /// Height of the map's column over `xy` (0 over empty ground and outside the map).
    pub fn height_at(&self, xy: DVec2) -> f64 {
        let (i, j) = (
            floor_i64((xy.x - self.min.x) / self.s),
            floor_i64((xy.y - self.min.y) / self.s),
        );
        let mut buf = [PART_NONE];
        self.parts(i, j, &mut buf)
            .iter()
            .find(|q| q.distance(xy) == 0.0)
            .map_or(0.0, |q| q.h)
    }

    /// Exact distance from `p` to the surface of the map's prisms (ground included): the
    /// boundary of the union of texel columns `footprint × (−∞, H]` (empty texels and the
    /// outside have H = 0; a texel with a footprint edge is two columns, the part inside its
    /// half-plane at the texel's height and the rest at 0).
    ///
    /// Below the threshold `t` only an upper bound is needed: the search stops as soon as it
    /// has found a surface point within `t`. The value returned is never below the exact
    /// distance, and it is the exact distance unless both are at most `t`
    /// (`t = −∞`: always exact).
    pub fn distance(&self, p: DVec3, t: f64) -> f64 {
        let s = self.s;
        let (fx, fy) = ((p.x - self.min.x) / s, (p.y - self.min.y) / s);
        let (ci, cj) = (floor_i64(fx), floor_i64(fy));
        let xy = p.truncate();
        let mut buf = [PART_NONE];
        let own = self.parts(ci, cj, &mut buf);
        let own_h = own
            .iter()
            .find(|q| q.distance(xy) == 0.0)
            .map_or(own[0].h, |q| q.h);
        let inside = p.z <= own_h;
        // A texel whose square (and heights) put every one of its parts at least as far as
        // the best found is skipped; the margin covers rounding, so the minimum taken is the
        // same as over every part.
        let margin = 1e-9 * (1.0 + xy.abs().max_element() + p.z.abs() + s);
        let mut best = f64::INFINITY;
        let mut r = 0i64;
        loop {
            // Cells of ring r around (ci, cj); outside cells stand for the ground around the map.
            let lower = (r as f64 - 1.0).max(0.0) * s;
            if lower > best {
                break;
            }
            for j in cj - r..=cj + r {
                let full_row = (j - cj).abs() == r;
                let step = if full_row { 1 } else { (2 * r).max(1) as usize };
                for i in (ci - r..=ci + r).step_by(step) {
                    let (h, cut) = self.cell(i, j);
                    let lo = self.lo(i, j);
                    let hi = lo + DVec2::splat(s);
                    let b = (lo - xy).max(xy - hi).max(DVec2::ZERO);
                    let (hmin, hmax) = if cut.is_some() { (0.0, h) } else { (h, h) };
                    let dz = if inside {
                        (hmin - p.z).max(0.0)
                    } else {
                        (p.z - hmax).max(0.0)
                    };
                    if (b.length_squared() + dz * dz).sqrt() - margin >= best {
                        continue;
                    }
                    for part in self.parts(i, j, &mut buf) {
                        let h = part.h;
                        let dz = if inside {
                            (h - p.z).max(0.0)
                        } else {
                            (p.z - h).max(0.0)
                        };
                        // Inside: complement column above h; outside: solid column below h.
                        let d = part.distance(xy);
                        let v = (d * d + dz * dz).sqrt();
                        if inside && h >= p.z && d == 0.0 {
                            // The own column's way out is straight up.
                            best = best.min(dz);
                        } else {
                            best = best.min(v);
                        }
                    }
                    if best <= t {
                        return best;
                    }
                }
            }
            r += 1;
            if r > 2 * self.k + 4 {
                break;
            }
        }
        best
    }
}

/// A placeholder part (no vertices).
const PART_NONE: Part = Part {
    v: [DVec2::ZERO; 6],
    n: 0,
    h: 0.0,
};

/// Exact distance from `p` to the surface of `map`'s prisms ([`MapColumns::distance`]); for
/// many points of one map, make the [`MapColumns`] once.
pub fn map_surface_distance(map: &BlockMap, p: DVec3) -> f64 {
    MapColumns::new(map).distance(p, f64::NEG_INFINITY)
}

/// Measures the error of `map` against `buildings` (indices into `source.buildings`).
pub fn measure(map: &BlockMap, source: &Source, buildings: &[u32]) -> ErrorReport {
    if map.meta.zmin != 0.0 {
        return measure_on_ground(map, source, buildings);
    }
    measure_flat(map, source, buildings, true)
}

/// [`measure`] of a map whose ground is not z = 0 (a city on terrain, where a node's heights
/// start at the lowest ground under its buildings and the terrain is drawn beside the maps).
/// The terrain hides whatever lies under it, and the ground under a footprint is at least the
/// building's base (its lowest ground), so a map column reaching below a building's base shows
/// nothing more than the building standing on its ground: both surfaces are measured in heights
/// above the node's lowest ground, each building (but a raised part) taken down to it, as over a
/// flat city. What the terrain itself hides between buildings is not credited: a gap the map
/// fills is measured from the lowest ground, as a larger error than the visible one.
fn measure_on_ground(map: &BlockMap, source: &Source, buildings: &[u32]) -> ErrorReport {
    let zmin = map.meta.zmin;
    let mut flat_map = map.clone();
    flat_map.meta.zmin = 0.0;
    flat_map.meta.zmax = map.meta.zmax - zmin;
    let mut flat = Source {
        buildings: vec![None; source.buildings.len()],
        meshes: source.meshes,
        city: source.city,
        terrain: None,
    };
    for &i in buildings {
        if let Some(Some(b)) = source.buildings.get(i as usize) {
            let raised = b.z0 > b.ground + 1e-9;
            flat.buildings[i as usize] = Some(SourceBuilding {
                ground: 0.0,
                z0: if raised { b.z0 - zmin } else { 0.0 },
                z1: b.z1 - zmin,
                ..b.clone()
            });
        }
    }
    measure_flat(&flat_map, &flat, buildings, true)
}

/// The measurement over a flat ground. With `prune`, each distance search stops below the
/// threshold past which its value could change the report; without, every distance is exact
/// (the same report, slower: the tests compare the two).
fn measure_flat(map: &BlockMap, source: &Source, buildings: &[u32], prune: bool) -> ErrorReport {
    let grid = BuildingGrid::new(map, source, buildings);
    let s = map.texel_m();
    let half = map.half_voxel_diagonal();
    let tol = half * (1.0 + 1e-9) + 1e-9;
    let mut rep = ErrorReport {
        half_voxel_diagonal_m: half,
        ..ErrorReport::default()
    };
    let mut thin: std::collections::BTreeMap<(u32, u8), ThinFeature> = Default::default();
    let mut note = |kind: ThinKind, b: &SourceBuilding, e: f64, at: DVec2| {
        let key = (b.id.0, kind as u8);
        let f = thin.entry(key).or_insert_with(|| ThinFeature {
            kind,
            building: b.id.0,
            source_id: b.source_id.clone(),
            error_m: 0.0,
            at: at.to_array(),
        });
        if e > f.error_m {
            f.error_m = e;
            f.at = at.to_array();
        }
    };
    let cols = MapColumns::new(map);
    let mut scratch = Scratch::default();
    let mut covers: Vec<(f64, f64)> = Vec::new();
    let mut zs: Vec<f64> = Vec::new();
    let mut samples = 0usize;
    // Original → map. A sample's distance matters only where it can raise the map's maximum,
    // its building's worst (past the ½ voxel diagonal) or mark the building vanished: below
    // that threshold the distance search may stop at any surface point within it, which
    // changes no result (see `MapColumns::distance`).
    let mut o2m: f64 = 0.0;
    for b in &grid.all {
        if b.z0 > 0.0 {
            rep.raised_parts += 1;
        }
        if b.bridge {
            rep.bridges += 1;
        }
        let mut e = BuildingError {
            worst: 0.0,
            worst_at: b.min,
            raised: 0.0,
            vanished: None,
        };
        // One sample at `p`: `raised` for the underside of a raised part and the ground below
        // it; `top` for a point of the roof (at `z1`), which marks the building vanished when
        // no prism stands over it and its nearest map surface is the ground (a roof inside a
        // taller prism is covered, not gone).
        let sample = |p: DVec3, raised: bool, top: bool, e: &mut BuildingError, o2m: &mut f64| {
            let xy = p.truncate();
            let gone_here = top && b.z1 > 0.0 && {
                let (ti, tj) = (
                    floor_i64((xy.x - map.meta.min[0]) / s),
                    floor_i64((xy.y - map.meta.min[1]) / s),
                );
                map.texel_height_m(ti, tj).is_none()
            };
            let gone_at = b.z1 * (1.0 - 1e-9);
            let mut t = o2m.min(if raised { e.raised } else { e.worst }.max(tol));
            if !prune {
                t = f64::NEG_INFINITY;
            } else if gone_here {
                // Strictly below `gone_at` when nothing is marked yet.
                t = t.min(e.vanished.map_or(b.z1 * (1.0 - 2e-9), |v| v.0));
            }
            let d = cols.distance(p, t);
            if raised {
                e.raised = e.raised.max(d);
            } else if d > e.worst {
                e.worst = d;
                e.worst_at = xy;
            }
            *o2m = o2m.max(d);
            if gone_here && d >= gone_at && e.vanished.is_none_or(|v| d > v.0) {
                e.vanished = Some((d, xy));
            }
        };
        // Walls and roof outline.
        heights_into(b.z0, b.z1, 2.0 * s, &mut zs);
        for ring in &b.rings {
            let n = ring.len();
            for q in 0..n {
                let (a, c) = (ring[q], ring[(q + 1) % n]);
                let len = (c - a).length();
                let steps = ((len / (0.5 * s)).ceil() as usize).max(1);
                let dir = (c - a).normalize_or_zero();
                let out = DVec2::new(dir.y, -dir.x);
                for step in 0..steps {
                    let xy = a + (c - a) * (step as f64 / steps as f64);
                    let probe = xy + out * (1e-6 * (1.0 + xy.abs().max_element()));
                    // The neighbour prisms standing just outside this point of the wall: where
                    // one covers a height, the wall there is no surface.
                    covers.clear();
                    covers.extend(grid.at(probe).iter().filter_map(|&m| {
                        let [x0, y0, x1, y1, z0, z1] = grid.boxes[m as usize];
                        if probe.x < x0 || probe.x > x1 || probe.y < y0 || probe.y > y1 {
                            return None;
                        }
                        let o = grid.all[m as usize];
                        (o.id != b.id && in_polygon(o, probe)).then_some((z0, z1))
                    }));
                    for &z in &zs {
                        if covers.iter().any(|&(z0, z1)| z >= z0 && z <= z1) {
                            continue;
                        }
                        samples += 1;
                        sample(xy.extend(z), false, z == b.z1, &mut e, &mut o2m);
                    }
                }
            }
        }
        // Roof lattice (and, for raised parts, the underside and the ground below).
        let nx = ((b.max.x - b.min.x) / s).ceil().max(1.0) as usize;
        let ny = ((b.max.y - b.min.y) / s).ceil().max(1.0) as usize;
        for jy in 0..ny {
            for ix in 0..nx {
                let xy = DVec2::new(
                    b.min.x + (ix as f64 + 0.5) * (b.max.x - b.min.x) / nx as f64,
                    b.min.y + (jy as f64 + 0.5) * (b.max.y - b.min.y) / ny as f64,
                );
                if !in_polygon(b, xy) {
                    continue;
                }
                samples += 1;
                sample(xy.extend(b.z1), false, true, &mut e, &mut o2m);
                if b.z0 > 0.0 {
                    samples += 2;
                    sample(xy.extend(b.z0), true, false, &mut e, &mut o2m);
                    sample(xy.extend(0.0), true, false, &mut e, &mut o2m);
                }
            }
        }
        if e.worst > tol {
            note(ThinKind::NarrowBuilding, b, e.worst, e.worst_at);
        }
        if e.raised > tol {
            note(ThinKind::RaisedPart, b, e.raised, (b.min + b.max) * 0.5);
        }
        if let Some((d, at)) = e.vanished {
            note(ThinKind::Vanished, b, d, at);
        }
    }
    // Map → original.
    let k = map.k() as i64;
    let m = map.meta.min;
    let hof = |i: i64, j: i64| -> f64 { map.texel_height_m(i, j).unwrap_or(0.0) };
    let mut m2o: f64 = 0.0;
    for j in 0..k {
        for i in 0..k {
            let h = hof(i, j);
            let c = DVec2::new(m[0] + (i as f64 + 0.5) * s, m[1] + (j as f64 + 0.5) * s);
            // The texel's largest distance matters only past the map's maximum so far or past
            // the ½ voxel diagonal (a filled gap); below both, any bound will do.
            let floor = m2o.min(tol);
            let mut sd = |p: DVec3, local: f64| {
                let t = if prune {
                    local.max(floor)
                } else {
                    f64::NEG_INFINITY
                };
                grid.surface_distance_within(p, t, &mut scratch)
            };
            let mut local: f64;
            samples += 1;
            local = sd(c.extend(h), 0.0);
            // A neighbour with a footprint edge may leave the shared side open: count it as
            // empty there (more samples, never fewer).
            let side_h = |i: i64, j: i64| -> f64 {
                if i >= 0 && j >= 0 && i < k && j < k && map.edge(i as u32, j as u32).is_some() {
                    0.0
                } else {
                    hof(i, j)
                }
            };
            let cut = if h > 0.0 { cols.cell(i, j).1 } else { None };
            if let Some((parts, _)) = cut {
                // The kept part: its roof (centroid and corners) and each side, from the
                // neighbour's height (0 on the edge's side) to the roof.
                let v = parts[0].verts();
                let centroid = v.iter().copied().sum::<DVec2>() / v.len().max(1) as f64;
                samples += 1;
                local = sd(centroid.extend(h), 0.0);
                for q in 0..v.len() {
                    let (a, b) = (v[q], v[(q + 1) % v.len()]);
                    let mid = (a + b) * 0.5;
                    // Which square side the side lies on, if any.
                    let rel = (mid - c) / s;
                    let hn = if (rel.x.abs() - 0.5).abs() < 1e-9 {
                        side_h(i + rel.x.signum() as i64, j)
                    } else if (rel.y.abs() - 0.5).abs() < 1e-9 {
                        side_h(i, j + rel.y.signum() as i64)
                    } else {
                        0.0
                    };
                    samples += 1;
                    local = local.max(sd(a.extend(h), local));
                    if hn >= h {
                        continue;
                    }
                    // Only points of the side that are on the map's surface: the column just
                    // across is lower.
                    let out = (b - a).perp().normalize_or_zero() * (-1e-6 * s);
                    heights_into(hn, h, 2.0 * s, &mut zs);
                    for &z in &zs {
                        if cols.height_at(mid + out) > z {
                            continue;
                        }
                        samples += 1;
                        local = local.max(sd(mid.extend(z), local));
                    }
                    for end in [a, b] {
                        let across = cols.height_at(end + out + (mid - end) * 1e-6);
                        if across >= h {
                            continue;
                        }
                        samples += 1;
                        local = local.max(sd(end.extend(hn.max(across)), local));
                    }
                }
            } else if h > 0.0 {
                for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let hn = side_h(i + di, j + dj);
                    if hn >= h {
                        continue;
                    }
                    let dir = DVec2::new(di as f64, dj as f64);
                    let mid = c + dir * (0.5 * s);
                    // Only points of the side on the map's surface (next to a neighbour with
                    // an edge, the part of the side its column does not cover).
                    let out = dir * (1e-6 * s);
                    heights_into(hn, h, 2.0 * s, &mut zs);
                    for &z in &zs {
                        if cols.height_at(mid + out) > z {
                            continue;
                        }
                        samples += 1;
                        local = local.max(sd(mid.extend(z), local));
                    }
                    // The side's two ends (the staircase's corners, the points of a texel
                    // farthest from a footprint edge) at its bottom and top.
                    let along = DVec2::new(dir.y, dir.x) * (0.5 * s);
                    for end in [mid - along, mid + along] {
                        let across = cols.height_at(end + out + (mid - end) * 1e-6);
                        if across >= h {
                            continue;
                        }
                        for z in [hn.max(across), h] {
                            samples += 1;
                            local = local.max(sd(end.extend(z), local));
                        }
                    }
                }
                // The top's corners.
                for (cx, cy) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                    samples += 1;
                    let q = c + DVec2::new(cx, cy) * s;
                    local = local.max(sd(q.extend(h), local));
                }
            }
            m2o = m2o.max(local);
            if local > tol {
                // Name the building nearest to the sample.
                grid.near(c, s, &mut scratch);
                let nearest = scratch
                    .list
                    .iter()
                    .map(|&n| grid.all[n as usize])
                    .min_by(|a, b| horizontal_distance(a, c).total_cmp(&horizontal_distance(b, c)));
                if let Some(b) = nearest {
                    note(ThinKind::FilledGap, b, local, c);
                }
            }
        }
    }
    rep.samples = samples;
    rep.original_to_map_m = o2m;
    rep.map_to_original_m = m2o;
    rep.measured_m = o2m.max(m2o);
    rep.declared_m = half.max(rep.measured_m);
    rep.thin = thin.into_values().collect();
    rep
}

/// `a`, `b` and every `step` in between (at least the two ends), into `v`.
fn heights_into(a: f64, b: f64, step: f64, v: &mut Vec<f64>) {
    v.clear();
    v.push(a);
    if b > a {
        let n = ((b - a) / step).ceil() as usize;
        for q in 1..n {
            v.push(a + (b - a) * q as f64 / n as f64);
        }
        v.push(b);
    }
}

/// Exact distance from a point (local frame) to the original surface of the map's buildings.
pub fn original_surface_distance(grid: &BuildingGrid, p: DVec3) -> f64 {
    let mut scratch = Scratch::default();
    grid.surface_distance(p, &mut scratch)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blockmap::{build_map, BuildOptions};
    use crate::city::extrude::extrude_city;
    use crate::visibility::synthetic::SyntheticCity;
    use rand::{Rng, SeedableRng};

    /// The distance to the map's surface by brute force: every part of every texel (and of the
    /// ground cells around the map) that the ring search could reach, through [`cell_parts`].
    fn brute_map_distance(map: &BlockMap, p: DVec3) -> f64 {
        let k = map.k() as i64;
        let s = map.texel_m();
        let m = map.meta.min;
        let (ci, cj) = (
            ((p.x - m[0]) / s).floor() as i64,
            ((p.y - m[1]) / s).floor() as i64,
        );
        let xy = p.truncate();
        let (own, own_n) = cell_parts(map, ci, cj);
        let own_h = own[..own_n]
            .iter()
            .find(|q| q.distance(xy) == 0.0)
            .map_or(own[0].h, |q| q.h);
        let inside = p.z <= own_h;
        let r = 2 * k + 4;
        let mut best = f64::INFINITY;
        for j in cj - r..=cj + r {
            for i in ci - r..=ci + r {
                let (parts, n) = cell_parts(map, i, j);
                for part in &parts[..n] {
                    let dz = if inside {
                        (part.h - p.z).max(0.0)
                    } else {
                        (p.z - part.h).max(0.0)
                    };
                    let d = part.distance(xy);
                    best = best.min(if inside && part.h >= p.z && d == 0.0 {
                        dz
                    } else {
                        (d * d + dz * dz).sqrt()
                    });
                }
            }
        }
        best
    }

    fn synthetic_city() -> (SyntheticCity, Vec<crate::city::Mesh>) {
        let sc = SyntheticCity::generate(2, 2, 11, DVec2::new(5.0e5, 6.0e6));
        let meshes = extrude_city(&sc.city);
        (sc, meshes)
    }

    /// Points over the map's square and around it: on texel tops and sides, inside columns,
    /// high above and below the ground.
    fn points(map: &BlockMap, n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let (m, side, zmax) = (map.meta.min, map.meta.side, map.meta.zmax);
        (0..n)
            .map(|q| {
                let x = m[0] + rng.random_range(-0.2..1.2) * side;
                let y = m[1] + rng.random_range(-0.2..1.2) * side;
                let z = match q % 4 {
                    0 => rng.random_range(0.0..zmax),
                    1 => rng.random_range(-0.1..1.5) * zmax,
                    // On a column's top.
                    2 => MapColumns::new(map).height_at(DVec2::new(x, y)),
                    _ => rng.random_range(0.0..0.2) * zmax,
                };
                DVec3::new(x, y, z)
            })
            .collect()
    }

    #[test]
    fn floor_without_the_library_call_is_floor() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0,
            -1e-300,
            1e300,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            9.2e18,
            -9.3e18,
            4503599627370497.0,
            -4503599627370497.5,
        ];
        let random = (0..10_000).map(|q| {
            let x: f64 = rng.random_range(-300.0..300.0);
            if q % 3 == 0 {
                x.round()
            } else {
                x
            }
        });
        for x in special.into_iter().chain(random) {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn map_distance_is_the_brute_force_minimum_and_the_threshold_only_cuts_below_it() {
        let (sc, meshes) = synthetic_city();
        let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
        let all = source.buildings_of(
            &sc.layout,
            &sc.layout.blocks.iter().map(|b| b.id).collect::<Vec<_>>(),
        );
        let opts = BuildOptions {
            k: 32,
            ..BuildOptions::default()
        };
        let (map, _, _) = build_map(&source, &all, &opts).unwrap();
        assert!(map.edge_texels() > 0, "the map has cut texels");
        let cols = MapColumns::new(&map);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut cut_short = 0;
        for p in points(&map, 400, 7) {
            let exact = brute_map_distance(&map, p);
            let d = cols.distance(p, f64::NEG_INFINITY);
            assert_eq!(d.to_bits(), exact.to_bits(), "{p}: {d} vs {exact}");
            assert_eq!(map_surface_distance(&map, p).to_bits(), exact.to_bits());
            let t = rng.random_range(0.0..2.0) * exact;
            let w = cols.distance(p, t);
            assert!(w >= exact, "{p}: {w} < {exact}");
            assert!(w == exact || w <= t, "{p}: {w} vs {exact}, t {t}");
            cut_short += usize::from(w != exact);
        }
        assert!(cut_short > 0, "some searches stop early");
    }

    #[test]
    fn original_distance_with_a_threshold_is_exact_above_it() {
        let (sc, meshes) = synthetic_city();
        let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
        let all = source.buildings_of(
            &sc.layout,
            &sc.layout.blocks.iter().map(|b| b.id).collect::<Vec<_>>(),
        );
        let (map, kept, _) = build_map(&source, &all, &BuildOptions::default()).unwrap();
        let grid = BuildingGrid::new(&map, &source, &kept);
        let mut scratch = Scratch::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut inside, mut cut_short) = (0, 0);
        for p in points(&map, 400, 9) {
            let exact = grid.surface_distance(p, &mut scratch);
            inside += usize::from(
                grid.all
                    .iter()
                    .any(|b| p.z > b.z0 && p.z < b.z1 && in_polygon(b, p.truncate())),
            );
            let t = rng.random_range(0.0..2.0) * exact;
            let w = grid.surface_distance_within(p, t, &mut scratch);
            assert!(w >= exact, "{p}: {w} < {exact}");
            assert!(w == exact || w <= t, "{p}: {w} vs {exact}, t {t}");
            cut_short += usize::from(w != exact);
        }
        assert!(
            inside > 0 && cut_short > 0,
            "{inside} inside, {cut_short} cut short"
        );
    }

    #[test]
    fn pruned_measurement_equals_the_exact_one() {
        let (sc, meshes) = synthetic_city();
        let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
        let ids: Vec<_> = sc.layout.blocks.iter().map(|b| b.id).collect();
        let mut thin = 0;
        // The whole city and each block alone, at every K.
        let sets: Vec<Vec<u32>> = std::iter::once(source.buildings_of(&sc.layout, &ids))
            .chain(ids.iter().map(|b| source.buildings_of(&sc.layout, &[*b])))
            .collect();
        for k in [32, 64, 128] {
            for set in &sets {
                let opts = BuildOptions {
                    k,
                    ..BuildOptions::default()
                };
                let (map, kept, _) = build_map(&source, set, &opts).unwrap();
                let pruned = measure_flat(&map, &source, &kept, true);
                let exact = measure_flat(&map, &source, &kept, false);
                assert_eq!(pruned, exact, "K = {k}");
                assert_eq!(pruned.measured_m.to_bits(), exact.measured_m.to_bits());
                thin += pruned.thin.len();
            }
        }
        assert!(thin > 0, "some maps report thin features");
    }
}
