//! Assigning buildings to blocks (Pina, Serón and Cerezo, §3, fourth step): one point of each footprint is tested
//! against the blocks' bounding boxes (an R-tree), then by the odd-crossing ray test.
//!
//! The point is a guaranteed interior point of the footprint (a scanline midpoint, see
//! [`interior_point`](crate::geom::predicates::interior_point)), not a vertex: a footprint touching a street line would otherwise have its
//! vertex on the block boundary. When the point lands exactly on a block boundary the next
//! scanline's point is taken, as the paper retries "another point of the polygon".
//! Buildings in no block are grouped into outskirts by proximity.
//!
//! Cost: the blocks are prepared once ([`BandedPolygon`]: their edges bucketed by horizontal
//! bands), so a point is tested against the few edges of its band instead of every edge of the
//! block, with the same exact predicates and the same answer as [`point_in_polygon`]; the
//! footprint's interior points reuse per-thread buffers ([`InteriorPoints`]).

use crate::geom::hull::convex_hull_polygon;
use crate::geom::predicates::{orient2d, point_in_polygon, InteriorPoints, Location, Orientation};
use geo::{Distance, Euclidean};
use geo_types::{Coord, Polygon};
use rayon::prelude::*;
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
use std::borrow::Borrow;

/// Default distance (m) within which outskirts buildings join one group.
pub const DEFAULT_OUTSKIRTS_LINK: f64 = 30.0;

pub(super) type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;

/// Plan-view box of a polygon's exterior grown by `grow`; `None` for an empty exterior.
fn envelope(p: &Polygon<f64>, grow: f64) -> Option<([f64; 2], [f64; 2])> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for c in &p.exterior().0 {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    (lo[0] <= hi[0]).then_some(([lo[0] - grow, lo[1] - grow], [hi[0] + grow, hi[1] + grow]))
}

/// An R-tree of the polygons' exterior boxes grown by `grow`, each tagged with its index.
pub(super) fn tree_of<P: Borrow<Polygon<f64>>>(polys: &[P], grow: f64) -> RTree<Env> {
    RTree::bulk_load(
        polys
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                envelope(p.borrow(), grow)
                    .map(|(lo, hi)| GeomWithData::new(Rectangle::from_corners(lo, hi), i))
            })
            .collect(),
    )
}

/// Rings with more edges than this (all rings together) are banded; smaller ones are tested
/// edge by edge as they are.
const BAND_FROM_EDGES: usize = 24;

/// A polygon prepared for many exact point-in-polygon queries: its edges (all rings) bucketed
/// into horizontal bands of equal height, each edge listed in every band its y-range meets.
///
/// A point can only lie on an edge or have its horizontal ray cross it when its y is within
/// the edge's closed y-range, so the edges of the point's band are all the odd-crossing test
/// needs; the band of a y is `floor((y − y0) · k)` clamped, a monotone function of y, so an
/// edge whose y-range holds the point's y is always in the point's band. Each edge is then
/// decided with the same exact predicates as [`point_in_ring`](crate::geom::predicates::point_in_ring):
/// [`BandedPolygon::locate`] equals [`point_in_polygon`].
#[derive(Clone, Debug)]
pub struct BandedPolygon {
    /// Lowest and highest vertex y.
    y0: f64,
    y1: f64,
    /// Bands per unit of y.
    per_y: f64,
    /// `bands + 1` offsets into `band_edges`.
    offsets: Vec<u32>,
    /// Edge indices, band after band.
    band_edges: Vec<u32>,
    /// Edges: end points and ring (0 = exterior).
    edges: Vec<(Coord<f64>, Coord<f64>, u32)>,
}

impl BandedPolygon {
    /// Prepares `poly` (about one band per two edges); `None` for a polygon of more than 64
    /// rings or with a coordinate that is not finite.
    pub fn new(poly: &Polygon<f64>) -> Option<Self> {
        use crate::geom::predicates::open_ring;
        let mut edges = Vec::new();
        let rings: Vec<_> = std::iter::once(poly.exterior())
            .chain(poly.interiors())
            .collect();
        if rings.len() > 64 {
            return None;
        }
        for (k, r) in rings.iter().enumerate() {
            let r = open_ring(&r.0);
            let n = r.len();
            edges.extend((0..n).map(|i| (r[i], r[(i + 1) % n], k as u32)));
        }
        if !edges.iter().all(|e| e.0.x.is_finite() && e.0.y.is_finite()) {
            return None;
        }
        let (mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY);
        for e in &edges {
            y0 = y0.min(e.0.y);
            y1 = y1.max(e.0.y);
        }
        let n_bands = (edges.len() / 2).max(1);
        let per_y = if y1 > y0 && (y1 - y0).is_finite() {
            n_bands as f64 / (y1 - y0)
        } else {
            0.0
        };
        let mut p = Self {
            y0,
            y1,
            per_y,
            offsets: vec![0; n_bands + 1],
            band_edges: Vec::new(),
            edges,
        };
        // Counting sort of (band, edge) pairs.
        for e in &p.edges {
            let (b0, b1) = p.bands_of(e.0.y.min(e.1.y), e.0.y.max(e.1.y));
            for b in b0..=b1 {
                p.offsets[b + 1] += 1;
            }
        }
        for b in 0..n_bands {
            p.offsets[b + 1] += p.offsets[b];
        }
        let mut fill = p.offsets.clone();
        p.band_edges = vec![0; p.offsets[n_bands] as usize];
        for (k, e) in p.edges.iter().enumerate() {
            let (b0, b1) = p.bands_of(e.0.y.min(e.1.y), e.0.y.max(e.1.y));
            for slot in &mut fill[b0..=b1] {
                p.band_edges[*slot as usize] = k as u32;
                *slot += 1;
            }
        }
        Some(p)
    }

    /// The band of `y`, clamped to the bands (monotone in `y`).
    fn band(&self, y: f64) -> usize {
        let last = self.offsets.len() - 2;
        let b = ((y - self.y0) * self.per_y).floor();
        if b.is_nan() || b <= 0.0 {
            0
        } else {
            (b as usize).min(last)
        }
    }

    /// The bands `[b0, b1]` that `[lo, hi]` meets.
    fn bands_of(&self, lo: f64, hi: f64) -> (usize, usize) {
        (self.band(lo), self.band(hi))
    }

    /// Where `p` lies, exactly as [`point_in_polygon`] says (built by [`BandedPolygon::new`],
    /// which refuses more than 64 rings).
    pub fn locate(&self, p: Coord<f64>) -> Location {
        if !(p.y >= self.y0 && p.y <= self.y1) {
            // No edge's y-range holds p.y: outside the exterior (NaN too, as the ring test
            // finds no crossing).
            return Location::Outside;
        }
        let b = self.band(p.y);
        let (s, e) = (self.offsets[b] as usize, self.offsets[b + 1] as usize);
        // Per ring: odd crossings, and p on the ring.
        let (mut parity, mut boundary) = (0u64, 0u64);
        for &k in &self.band_edges[s..e] {
            let (a, c, ring) = self.edges[k as usize];
            let (lo, hi) = if a.y <= c.y { (a.y, c.y) } else { (c.y, a.y) };
            if p.y < lo || p.y > hi {
                continue;
            }
            let in_x = p.x >= a.x.min(c.x) && p.x <= a.x.max(c.x);
            let a_above = a.y >= p.y;
            let c_above = c.y >= p.y;
            if !in_x && a_above == c_above {
                continue;
            }
            let o = orient2d(a, c, p);
            if in_x && o == Orientation::Collinear {
                boundary |= 1 << ring;
                continue;
            }
            if a_above != c_above {
                let right = if c_above {
                    o == Orientation::CounterClockwise
                } else {
                    o == Orientation::Clockwise
                };
                if right {
                    parity ^= 1 << ring;
                }
            }
        }
        // In point_in_polygon's order: the exterior, then the first hole that says anything.
        if boundary & 1 != 0 {
            return Location::OnBoundary;
        }
        if parity & 1 == 0 {
            return Location::Outside;
        }
        let holes = (parity | boundary) >> 1;
        if holes == 0 {
            return Location::Inside;
        }
        let first = holes.trailing_zeros();
        if (boundary >> 1) & (1 << first) != 0 {
            Location::OnBoundary
        } else {
            Location::Outside
        }
    }
}

/// A block as [`assign`] tests points against it.
enum Prepared {
    /// Many edges: banded.
    Banded(BandedPolygon),
    /// Few edges (or not bandable): the plain ring test.
    Plain,
}

/// The blocks prepared for point queries, in parallel.
fn prepare(blocks: &[Polygon<f64>]) -> Vec<Prepared> {
    blocks
        .par_iter()
        .map(|p| {
            let edges: usize =
                p.exterior().0.len() + p.interiors().iter().map(|r| r.0.len()).sum::<usize>();
            if edges > BAND_FROM_EDGES {
                BandedPolygon::new(p).map_or(Prepared::Plain, Prepared::Banded)
            } else {
                Prepared::Plain
            }
        })
        .collect()
}

/// The blocks with what [`block_at`] needs.
struct Blocks<'a> {
    polys: &'a [Polygon<f64>],
    prepared: Vec<Prepared>,
    areas: Vec<f64>,
    tree: RTree<Env>,
}

impl Blocks<'_> {
    /// Where `p` lies relative to block `j`.
    fn locate(&self, p: Coord<f64>, j: usize) -> Location {
        match &self.prepared[j] {
            Prepared::Banded(b) => b.locate(p),
            Prepared::Plain => point_in_polygon(p, &self.polys[j]),
        }
    }

    /// The block (index into the blocks) containing `p` strictly, `Err(())` when `p` is exactly
    /// on a block boundary, `Ok(None)` when in none. Blocks are disjoint; if rounding ever made
    /// two contain the point, the smaller is taken so the answer is still unique.
    fn block_at(&self, p: Coord<f64>) -> Result<Option<usize>, ()> {
        let mut found: Option<usize> = None;
        for cand in self.tree.locate_all_at_point(&[p.x, p.y]) {
            let j = cand.data;
            match self.locate(p, j) {
                Location::OnBoundary => return Err(()),
                Location::Inside => {
                    if found.is_none_or(|f| (self.areas[j], j) < (self.areas[f], f)) {
                        found = Some(j);
                    }
                }
                Location::Outside => {}
            }
        }
        Ok(found)
    }
}

/// Assigns every footprint to at most one block: `result[i]` is the block of `buildings[i]`.
pub fn assign<P: Borrow<Polygon<f64>> + Sync>(
    buildings: &[P],
    blocks: &[Polygon<f64>],
) -> Vec<Option<usize>> {
    let blocks = Blocks {
        polys: blocks,
        prepared: prepare(blocks),
        areas: blocks
            .iter()
            .map(crate::geom::predicates::polygon_area)
            .collect(),
        tree: tree_of(blocks, 0.0),
    };
    buildings
        .par_iter()
        .map_init(InteriorPoints::default, |ip, b| {
            let b = b.borrow();
            let n = b.exterior().0.len().clamp(1, 16);
            ip.reset(b);
            for k in 0..n {
                let Some(p) = ip.point(b, k) else { break };
                if point_in_polygon(p, b) != Location::Inside && k + 1 < n {
                    continue;
                }
                if let Ok(r) = blocks.block_at(p) {
                    return r;
                }
            }
            // Every point tried was on a block boundary: use the first vertex not on one.
            b.exterior()
                .0
                .iter()
                .find_map(|&c| blocks.block_at(c).ok())
                .flatten()
        })
        .collect()
}
/// Whether two footprints are at most `link` apart. Cheap bounds decide most pairs: the gap
/// between their boxes is a lower bound of the distance (farther apart: no), the nearest pair of
/// exterior vertices an upper bound (that close: yes); the others are measured exactly.
fn within(a: &Polygon<f64>, b: &Polygon<f64>, link: f64) -> bool {
    let (Some((alo, ahi)), Some((blo, bhi))) = (envelope(a, 0.0), envelope(b, 0.0)) else {
        return Euclidean.distance(a, b) <= link;
    };
    let gx = (blo[0] - ahi[0]).max(alo[0] - bhi[0]).max(0.0);
    let gy = (blo[1] - ahi[1]).max(alo[1] - bhi[1]).max(0.0);
    if gx > link || gy > link || gx * gx + gy * gy > link * link * (1.0 + 1e-9) {
        return false;
    }
    let close = a.exterior().0.iter().any(|p| {
        b.exterior().0.iter().any(|q| {
            (p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) < link * link * (1.0 - 1e-9)
        })
    });
    close || Euclidean.distance(a, b) <= link
}

/// Groups the given buildings (indices into `buildings`) into outskirts: buildings within `link`
/// of each other (footprint to footprint) are in one group. Returns the groups, each with the
/// convex hull of its footprints, in order of their first building.
pub fn outskirts_groups<P: Borrow<Polygon<f64>>>(
    buildings: &[P],
    which: &[usize],
    link: f64,
) -> Vec<(Polygon<f64>, Vec<usize>)> {
    let polys: Vec<&Polygon<f64>> = which.iter().map(|&i| buildings[i].borrow()).collect();
    let tree = tree_of(&polys, 0.5 * link);
    let mut parent: Vec<usize> = (0..polys.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for (i, p) in polys.iter().enumerate() {
        let Some((lo, hi)) = envelope(p, 0.5 * link) else {
            continue;
        };
        for cand in tree.locate_in_envelope_intersecting(&AABB::from_corners(lo, hi)) {
            let j = cand.data;
            if j <= i || find(&mut parent, i) == find(&mut parent, j) {
                continue;
            }
            if within(p, polys[j], link) {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                parent[ri.max(rj)] = ri.min(rj);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; polys.len()];
    for (i, &b) in which.iter().enumerate() {
        let r = find(&mut parent, i);
        if slot[r] == usize::MAX {
            slot[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[r]].push(b);
    }
    groups
        .into_iter()
        .map(|g| {
            let pts = g
                .iter()
                .flat_map(|&i| buildings[i].borrow().exterior().0.iter().copied());
            (convex_hull_polygon(pts), g)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::predicates::interior_point;
    use geo_types::LineString;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    /// A star-shaped ring of `n` vertices around `(cx, cy)`, counter-clockwise.
    fn star(
        n: usize,
        rng: &mut rand_chacha::ChaCha8Rng,
        c: f64,
        r0: f64,
        r1: f64,
    ) -> LineString<f64> {
        let mut pts: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + rng.random_range(0.0..0.8)) / n as f64;
                let r = rng.random_range(r0..r1);
                (c + r * a.cos(), c + r * a.sin())
            })
            .collect();
        pts.push(pts[0]);
        LineString::from(pts)
    }

    /// An axis-aligned staircase on integer coordinates: many horizontal edges and vertices at
    /// the heights the test points use.
    fn staircase(steps: usize) -> Polygon<f64> {
        let mut pts = vec![(0.0, 0.0)];
        for k in 0..steps {
            let (x, y) = (k as f64 + 1.0, k as f64);
            pts.push((x, y));
            pts.push((x, y + 1.0));
        }
        pts.push((0.0, steps as f64));
        pts.push((0.0, 0.0));
        let hole = LineString::from(vec![
            (0.5, 1.0),
            (0.5, 2.0),
            (1.0, 2.0),
            (1.0, 1.0),
            (0.5, 1.0),
        ]);
        Polygon::new(LineString::from(pts), vec![hole])
    }

    fn check(poly: &Polygon<f64>, pts: &[Coord<f64>]) -> Result<(), TestCaseError> {
        let b = BandedPolygon::new(poly).expect("bandable");
        for &p in pts {
            prop_assert_eq!(b.locate(p), point_in_polygon(p, poly), "{:?}", p);
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn banded_test_equals_the_ring_test(n in 3usize..200, holes in 0usize..3, seed: u64) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let ext = star(n, &mut rng, 0.0, 60.0, 100.0);
            // Small holes on a circle of radius 30 (inside every star), clockwise.
            let hs: Vec<LineString<f64>> = (0..holes)
                .map(|k| {
                    let a = k as f64 * 2.0;
                    let (cx, cy) = (30.0 * a.cos(), 30.0 * a.sin());
                    let mut r = star(7, &mut rng, 0.0, 3.0, 8.0);
                    r.0.iter_mut().for_each(|c| { c.x += cx; c.y += cy; });
                    r.0.reverse();
                    r
                })
                .collect();
            let poly = Polygon::new(ext, hs);
            let mut pts: Vec<Coord<f64>> = (0..300)
                .map(|_| Coord { x: rng.random_range(-110.0..110.0), y: rng.random_range(-110.0..110.0) })
                .collect();
            // Vertices, points at vertex heights, and edge midpoints.
            for r in std::iter::once(poly.exterior()).chain(poly.interiors()) {
                for w in r.0.windows(2) {
                    pts.push(w[0]);
                    pts.push(Coord { x: rng.random_range(-110.0..110.0), y: w[0].y });
                    pts.push(Coord { x: 0.5 * (w[0].x + w[1].x), y: 0.5 * (w[0].y + w[1].y) });
                }
            }
            check(&poly, &pts)?;
        }
    }

    #[test]
    fn banded_test_on_a_staircase_with_boundary_points() {
        let poly = staircase(40);
        let pts: Vec<Coord<f64>> = (-2..=84)
            .flat_map(|i| {
                (-2..=84).map(move |j| Coord {
                    x: i as f64 * 0.5,
                    y: j as f64 * 0.5,
                })
            })
            .collect();
        check(&poly, &pts).unwrap();
        // Some of them are on the boundary, inside and outside (the test is not vacuous).
        let b = BandedPolygon::new(&poly).unwrap();
        for want in [Location::Inside, Location::Outside, Location::OnBoundary] {
            assert!(pts.iter().any(|&p| b.locate(p) == want), "{want:?}");
        }
    }

    #[test]
    fn assignment_with_banded_blocks_matches_the_plain_test() {
        // Blocks with many edges (banded) and footprints inside, across and outside them.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let blocks: Vec<Polygon<f64>> = (0..4)
            .map(|k| {
                let mut r = star(60, &mut rng, 0.0, 40.0, 50.0);
                r.0.iter_mut().for_each(|c| c.x += 120.0 * k as f64);
                Polygon::new(r, vec![])
            })
            .collect();
        let buildings: Vec<Polygon<f64>> = (0..400)
            .map(|_| {
                let (x, y) = (
                    rng.random_range(-60.0..420.0),
                    rng.random_range(-60.0..60.0),
                );
                Polygon::new(
                    LineString::from(vec![
                        (x, y),
                        (x + 4.0, y),
                        (x + 4.0, y + 3.0),
                        (x, y + 3.0),
                        (x, y),
                    ]),
                    vec![],
                )
            })
            .collect();
        let got = assign(&buildings, &blocks);
        let areas: Vec<f64> = blocks
            .iter()
            .map(crate::geom::predicates::polygon_area)
            .collect();
        // Reference: the plain test on the same interior points, every block.
        for (b, g) in buildings.iter().zip(&got) {
            let p = interior_point(b, 0).unwrap();
            let inside: Vec<usize> = (0..blocks.len())
                .filter(|&j| point_in_polygon(p, &blocks[j]) == Location::Inside)
                .collect();
            let on =
                (0..blocks.len()).any(|j| point_in_polygon(p, &blocks[j]) == Location::OnBoundary);
            if !on {
                let want = inside
                    .iter()
                    .copied()
                    .min_by(|&a, &b| (areas[a], a).partial_cmp(&(areas[b], b)).unwrap());
                assert_eq!(*g, want);
            }
        }
        assert!(got.iter().any(|g| g.is_some()) && got.iter().any(|g| g.is_none()));
    }
}
