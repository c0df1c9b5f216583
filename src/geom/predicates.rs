//! Robust 2D predicates (orientation, point in ring), built on the `robust` crate.
//!
//! Every decision here is exact: orientation uses Shewchuk's adaptive-precision `orient2d`, and
//! the point-in-ring test (the odd-crossing ray test that Pina, Serón and Cerezo, §3 uses to assign buildings
//! to blocks) decides every crossing with that orientation, never with a computed intersection.
//!
//! The ring predicates are generic over [`Xy`], so the same code serves world [`Coord`]s
//! (footprints, blocks) and local-frame [`glam::DVec2`]s (occluders, random views) without a
//! conversion or an allocation per call. Rings are slices of points; they may be open or closed
//! (a last point equal to the first is ignored), and any winding.

use super::point::Xy;
use geo_types::{Coord, LineString, Polygon};

/// On which side of the directed line `a → b` a point lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// To the left: `a, b, c` turn counter-clockwise.
    CounterClockwise,
    /// To the right: `a, b, c` turn clockwise.
    Clockwise,
    /// On the line through `a` and `b` (exactly).
    Collinear,
}

/// The exact orientation determinant of `a, b, c` (Shewchuk's adaptive `orient2d`): its sign is
/// exact (`> 0` counter-clockwise, `< 0` clockwise, `0` collinear); its magnitude is twice the
/// triangle's signed area, correct to the last bit only in sign.
pub fn orient2d_det<P: Xy>(a: P, b: P, c: P) -> f64 {
    robust::orient2d(
        robust::Coord { x: a.x(), y: a.y() },
        robust::Coord { x: b.x(), y: b.y() },
        robust::Coord { x: c.x(), y: c.y() },
    )
}

/// Exact orientation of `c` relative to the directed line `a → b`.
pub fn orient2d<P: Xy>(a: P, b: P, c: P) -> Orientation {
    let d = orient2d_det(a, b, c);
    if d > 0.0 {
        Orientation::CounterClockwise
    } else if d < 0.0 {
        Orientation::Clockwise
    } else {
        Orientation::Collinear
    }
}

/// Where a point lies relative to a ring or a polygon.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Location {
    /// Strictly inside.
    Inside,
    /// Strictly outside.
    Outside,
    /// Exactly on an edge or a vertex.
    OnBoundary,
}

/// The ring's points without the closing duplicate (if the last point equals the first).
pub fn open_ring<P: Xy>(ring: &[P]) -> &[P] {
    if ring.len() >= 2 && same_point(ring[0], ring[ring.len() - 1]) {
        &ring[..ring.len() - 1]
    } else {
        ring
    }
}

/// True when the two points have equal coordinates (`==` on both, as `PartialEq` on a pair).
#[inline]
fn same_point<P: Xy>(a: P, b: P) -> bool {
    a.x() == b.x() && a.y() == b.y()
}

/// Signed area of a ring (shoelace formula): positive when counter-clockwise.
///
/// The ring is fanned from its first vertex and each triangle's doubled area is the adaptive
/// exact-sign determinant [`orient2d_det`], so that neither a ring far from the origin (UTM
/// northings of 6e6 m) nor one whose vertices differ in magnitude by many orders (a vertex
/// 1e47 m out, two others a few kilometres apart near the origin, whose differences to it round
/// to the same number) loses its area; the triangles are summed with Neumaier's compensated
/// summation.
pub fn ring_signed_area<P: Xy>(ring: &[P]) -> f64 {
    let r = open_ring(ring);
    if r.len() < 3 {
        return 0.0;
    }
    let o = r[0];
    let mut sum = 0.0f64;
    let mut comp = 0.0f64;
    for i in 1..r.len() - 1 {
        let term = orient2d_det(o, r[i], r[i + 1]);
        let t = sum + term;
        if sum.abs() >= term.abs() {
            comp += (sum - t) + term;
        } else {
            comp += (term - t) + sum;
        }
        sum = t;
    }
    0.5 * (sum + comp)
}

/// Signed area of a closed vertex list by the plain shoelace sum, `½ Σ pᵢ × pᵢ₊₁`, about the
/// coordinate origin and uncompensated: for small polygons in a local frame (texel-sized clips),
/// where every caller must get this exact sum. [`ring_signed_area`] is the precise one for world
/// coordinates. Positive when counter-clockwise; the list is taken as closed (no repeated point).
pub fn shoelace<P: Xy>(p: &[P]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|q| {
            let (a, b) = (p[q], p[(q + 1) % n]);
            a.x() * b.y() - a.y() * b.x()
        })
        .sum::<f64>()
        * 0.5
}

/// Area of a polygon: |exterior| − Σ |holes|, whatever the rings' winding.
pub fn polygon_area(p: &Polygon<f64>) -> f64 {
    ring_signed_area(&p.exterior().0).abs()
        - p.interiors()
            .iter()
            .map(|h| ring_signed_area(&h.0).abs())
            .sum::<f64>()
}

/// True when `p` lies on the closed segment `a–b` (exactly).
pub fn on_segment<P: Xy>(a: P, b: P, p: P) -> bool {
    orient2d(a, b, p) == Orientation::Collinear
        && p.x() >= a.x().min(b.x())
        && p.x() <= a.x().max(b.x())
        && p.y() >= a.y().min(b.y())
        && p.y() <= a.y().max(b.y())
}

/// Where `p` lies relative to a ring: the odd-crossing ray test (Pina, Serón and Cerezo, §3), exact.
///
/// A horizontal ray goes from `p` towards +x. An edge counts as crossed when its end points lie
/// on different sides of the line `y = p.y` under the half-open rule (an end point exactly on the
/// line counts as above), so a ray through a vertex, or along a horizontal edge, is counted
/// exactly once or not at all, as it must be. Whether the crossing lies right of `p` is decided
/// by the exact orientation of `p` against the edge. Points on an edge or a vertex are
/// [`Location::OnBoundary`].
///
/// Allocates nothing: the ring is read in place, whatever its point type.
pub fn point_in_ring<P: Xy>(p: P, ring: &[P]) -> Location {
    let r = open_ring(ring);
    let n = r.len();
    if n == 0 {
        return Location::Outside;
    }
    let mut inside = false;
    for i in 0..n {
        let a = r[i];
        let b = r[(i + 1) % n];
        if on_segment(a, b, p) {
            return Location::OnBoundary;
        }
        let a_above = a.y() >= p.y();
        let b_above = b.y() >= p.y();
        if a_above != b_above {
            // The edge straddles the line; the crossing is right of p when p is left of an
            // upward edge, or right of a downward edge.
            let o = orient2d(a, b, p);
            let right = if b_above {
                o == Orientation::CounterClockwise
            } else {
                o == Orientation::Clockwise
            };
            if right {
                inside = !inside;
            }
        }
    }
    if inside {
        Location::Inside
    } else {
        Location::Outside
    }
}

/// Where `p` lies relative to a polygon with holes (exact): inside the exterior and outside
/// every hole is [`Location::Inside`]; on any ring is [`Location::OnBoundary`].
pub fn point_in_polygon(p: Coord<f64>, poly: &Polygon<f64>) -> Location {
    match point_in_ring(p, &poly.exterior().0) {
        Location::Inside => {}
        other => return other,
    }
    for h in poly.interiors() {
        match point_in_ring(p, &h.0) {
            Location::Inside => return Location::Outside,
            Location::OnBoundary => return Location::OnBoundary,
            Location::Outside => {}
        }
    }
    Location::Inside
}

/// How two closed segments meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentIntersection {
    /// They share no point.
    None,
    /// They cross at one point interior to both.
    Proper,
    /// They share one or more points, at least one of which is an end point of a segment, or they
    /// overlap collinearly.
    Touch,
}

/// Exact classification of how segments `p1–p2` and `q1–q2` meet.
pub fn segments_intersect<P: Xy>(p1: P, p2: P, q1: P, q2: P) -> SegmentIntersection {
    if p1.x().max(p2.x()) < q1.x().min(q2.x())
        || q1.x().max(q2.x()) < p1.x().min(p2.x())
        || p1.y().max(p2.y()) < q1.y().min(q2.y())
        || q1.y().max(q2.y()) < p1.y().min(p2.y())
    {
        return SegmentIntersection::None;
    }
    let o1 = orient2d(p1, p2, q1);
    let o2 = orient2d(p1, p2, q2);
    let o3 = orient2d(q1, q2, p1);
    let o4 = orient2d(q1, q2, p2);
    use Orientation::Collinear as C;
    if o1 != C && o2 != C && o3 != C && o4 != C {
        if o1 != o2 && o3 != o4 {
            return SegmentIntersection::Proper;
        }
        return SegmentIntersection::None;
    }
    if (o1 == C && on_segment(p1, p2, q1))
        || (o2 == C && on_segment(p1, p2, q2))
        || (o3 == C && on_segment(q1, q2, p1))
        || (o4 == C && on_segment(q1, q2, p2))
    {
        return SegmentIntersection::Touch;
    }
    SegmentIntersection::None
}

/// Convenience: [`point_in_ring`] on a [`LineString`].
pub fn point_in_linestring(p: Coord<f64>, ring: &LineString<f64>) -> Location {
    point_in_ring(p, &ring.0)
}

/// A point strictly inside a polygon (not the centroid, which can fall outside a concave or
/// holed footprint), or `None` for a degenerate polygon.
///
/// A horizontal scanline is placed halfway between two consecutive distinct vertex heights, so it
/// passes through no vertex; its crossings with every ring are sorted and the midpoint of the widest
/// inside interval is returned. `attempt` picks other scanlines (0 = the one nearest the middle,
/// then alternating outwards), for the rare case where rounding puts the point on the boundary.
pub fn interior_point(poly: &Polygon<f64>, attempt: usize) -> Option<Coord<f64>> {
    let mut s = InteriorPoints::default();
    s.reset(poly);
    s.point(poly, attempt)
}

/// [`interior_point`] for many attempts on one polygon, or many polygons in turn, with its
/// buffers kept: the sorted vertex heights are computed once per polygon ([`InteriorPoints::reset`])
/// and nothing is allocated once the buffers have grown. Gives exactly [`interior_point`]'s points.
#[derive(Clone, Debug, Default)]
pub struct InteriorPoints {
    /// The polygon's distinct vertex heights, ascending.
    ys: Vec<f64>,
    /// One scanline's crossings.
    xs: Vec<f64>,
}

impl InteriorPoints {
    /// Prepares for `poly` (its sorted, distinct vertex heights).
    pub fn reset(&mut self, poly: &Polygon<f64>) {
        self.ys.clear();
        self.ys.extend(
            std::iter::once(poly.exterior())
                .chain(poly.interiors())
                .flat_map(|r| r.0.iter().map(|c| c.y)),
        );
        self.ys.sort_by(f64::total_cmp);
        self.ys.dedup();
    }

    /// [`interior_point`]`(poly, attempt)`; `poly` is the polygon last given to
    /// [`InteriorPoints::reset`].
    pub fn point(&mut self, poly: &Polygon<f64>, attempt: usize) -> Option<Coord<f64>> {
        let ys = &self.ys;
        if ys.len() < 2 {
            return None;
        }
        let gaps = ys.len() - 1;
        let g = gap_from_middle(gaps, attempt % gaps);
        let y = 0.5 * (ys[g] + ys[g + 1]);
        self.xs.clear();
        for r in std::iter::once(poly.exterior()).chain(poly.interiors()) {
            let ring = open_ring(&r.0);
            let n = ring.len();
            for i in 0..n {
                let a = ring[i];
                let b = ring[(i + 1) % n];
                if (a.y > y) != (b.y > y) {
                    let t = (y - a.y) / (b.y - a.y);
                    self.xs.push(a.x + t * (b.x - a.x));
                }
            }
        }
        self.xs.sort_by(f64::total_cmp);
        let mut best: Option<(f64, f64)> = None;
        for pair in self.xs.chunks_exact(2) {
            let w = pair[1] - pair[0];
            if w > 0.0 && best.is_none_or(|(bw, _)| w > bw) {
                best = Some((w, 0.5 * (pair[0] + pair[1])));
            }
        }
        best.map(|(_, x)| Coord { x, y })
    }
}

/// The `k`-th of the gaps `0..gaps` ordered from the middle (`gaps / 2`) outwards, the lower
/// one first at equal distance (prefer wide gaps near the middle): middle, middle − 1,
/// middle + 1, middle − 2, … then what is left on the longer side. `k < gaps`.
fn gap_from_middle(gaps: usize, k: usize) -> usize {
    let mid = gaps / 2;
    let (below, above) = (mid, gaps - mid - 1);
    let both = below.min(above);
    if k == 0 {
        mid
    } else if k <= 2 * both {
        let d = k.div_ceil(2);
        if k % 2 == 1 {
            mid - d
        } else {
            mid + d
        }
    } else if below > above {
        mid - (k - both)
    } else {
        mid + (k - both)
    }
}

/// A point strictly inside `poly` by the exact test, trying several scanlines.
pub fn robust_interior_point(poly: &Polygon<f64>) -> Option<Coord<f64>> {
    let n = poly.exterior().0.len() + poly.interiors().iter().map(|h| h.0.len()).sum::<usize>();
    let tries = n.clamp(1, 16);
    let mut fallback = None;
    for k in 0..tries {
        if let Some(p) = interior_point(poly, k) {
            if point_in_polygon(p, poly) == Location::Inside {
                return Some(p);
            }
            fallback.get_or_insert(p);
        }
    }
    fallback
}

#[cfg(test)]
mod tests {

    #[test]
    fn gaps_from_the_middle_follow_the_stable_sort() {
        for gaps in 1..40usize {
            let mid = gaps / 2;
            let mut order: Vec<usize> = (0..gaps).collect();
            order.sort_by_key(|&g| (g as isize - mid as isize).unsigned_abs());
            let direct: Vec<usize> = (0..gaps).map(|k| gap_from_middle(gaps, k)).collect();
            assert_eq!(direct, order, "{gaps} gaps");
        }
    }
    use super::*;
    use geo_types::{coord, polygon};

    fn square() -> Vec<Coord<f64>> {
        vec![
            coord! {x: 0.0, y: 0.0},
            coord! {x: 2.0, y: 0.0},
            coord! {x: 2.0, y: 2.0},
            coord! {x: 0.0, y: 2.0},
        ]
    }

    #[test]
    fn orientation_signs() {
        let a = coord! {x: 0.0, y: 0.0};
        let b = coord! {x: 1.0, y: 0.0};
        assert_eq!(
            orient2d(a, b, coord! {x: 0.5, y: 1.0}),
            Orientation::CounterClockwise
        );
        assert_eq!(
            orient2d(a, b, coord! {x: 0.5, y: -1.0}),
            Orientation::Clockwise
        );
        assert_eq!(
            orient2d(a, b, coord! {x: 7.0, y: 0.0}),
            Orientation::Collinear
        );
    }

    #[test]
    fn orientation_is_exact_near_collinear() {
        // A point 1 ulp off a line far from the origin: naive f64 arithmetic gets this wrong.
        let a = coord! {x: 5.0e5, y: 5.4e6};
        let b = coord! {x: 5.0e5 + 3.0, y: 5.4e6 + 3.0};
        let c = coord! {x: 5.0e5 + 1.0, y: f64::from_bits((5.4e6f64 + 1.0).to_bits() + 1)};
        assert_eq!(orient2d(a, b, c), Orientation::CounterClockwise);
        let c2 = coord! {x: 5.0e5 + 1.0, y: 5.4e6 + 1.0};
        assert_eq!(orient2d(a, b, c2), Orientation::Collinear);
    }

    /// A face found by fuzzing the street noder: from its far vertex, the other two differ
    /// by 7 km, far below the rounding of 1e47, and relative coordinates made the area 0.
    /// The doubled area is |a × b| about the near vertex, where nothing rounds away.
    #[test]
    fn area_of_a_triangle_with_a_far_vertex() {
        let far = coord! {x: -2.8544953854119198e47, y: -4.492944253233375e42};
        let a = coord! {x: -7167.24915933568, y: -0.1128117112625216};
        let b = coord! {x: -1.3785177045934016e-49, y: 7167.992199527515};
        let want = 0.5 * ((b.x - a.x) * (far.y - a.y) - (b.y - a.y) * (far.x - a.x));
        for ring in [[far, a, b], [a, b, far], [b, far, a]] {
            let got = ring_signed_area(&ring);
            assert!((got / want - 1.0).abs() < 1e-12, "{got} vs {want}");
            assert!(got > 1e51);
        }
    }

    #[test]
    fn area_of_square_far_away() {
        let off = 1.0e7;
        let r: Vec<_> = square()
            .into_iter()
            .map(|c| coord! {x: c.x + off, y: c.y + off})
            .collect();
        assert_eq!(ring_signed_area(&r), 4.0);
        let mut rev = r.clone();
        rev.reverse();
        assert_eq!(ring_signed_area(&rev), -4.0);
    }

    #[test]
    fn point_in_square_all_cases() {
        let r = square();
        assert_eq!(point_in_ring(coord! {x: 1.0, y: 1.0}, &r), Location::Inside);
        assert_eq!(
            point_in_ring(coord! {x: 3.0, y: 1.0}, &r),
            Location::Outside
        );
        assert_eq!(
            point_in_ring(coord! {x: 2.0, y: 1.0}, &r),
            Location::OnBoundary
        );
        assert_eq!(
            point_in_ring(coord! {x: 0.0, y: 0.0}, &r),
            Location::OnBoundary
        );
        // Ray along the bottom edge's line and through vertices.
        assert_eq!(
            point_in_ring(coord! {x: -1.0, y: 0.0}, &r),
            Location::Outside
        );
        assert_eq!(
            point_in_ring(coord! {x: -1.0, y: 2.0}, &r),
            Location::Outside
        );
    }

    #[test]
    fn ray_through_a_vertex_counts_once() {
        // A diamond: a ray from the left through the right vertex's height passes vertices.
        let r = vec![
            coord! {x: 0.0, y: -1.0},
            coord! {x: 1.0, y: 0.0},
            coord! {x: 0.0, y: 1.0},
            coord! {x: -1.0, y: 0.0},
        ];
        assert_eq!(point_in_ring(coord! {x: 0.0, y: 0.0}, &r), Location::Inside);
        assert_eq!(
            point_in_ring(coord! {x: -2.0, y: 0.0}, &r),
            Location::Outside
        );
        assert_eq!(point_in_ring(coord! {x: 0.5, y: 0.0}, &r), Location::Inside);
    }

    #[test]
    fn polygon_with_hole() {
        let hole = vec![
            coord! {x: 0.5, y: 0.5},
            coord! {x: 0.5, y: 1.5},
            coord! {x: 1.5, y: 1.5},
            coord! {x: 1.5, y: 0.5},
        ];
        let p = Polygon::new(LineString::from(square()), vec![LineString::from(hole)]);
        assert_eq!(
            point_in_polygon(coord! {x: 1.0, y: 1.0}, &p),
            Location::Outside
        );
        assert_eq!(
            point_in_polygon(coord! {x: 0.25, y: 1.0}, &p),
            Location::Inside
        );
        assert_eq!(
            point_in_polygon(coord! {x: 0.5, y: 1.0}, &p),
            Location::OnBoundary
        );
        assert_eq!(polygon_area(&p), 3.0);
    }

    #[test]
    fn segment_cases() {
        let c = |x, y| coord! {x: x, y: y};
        use SegmentIntersection::*;
        assert_eq!(
            segments_intersect(c(0., 0.), c(2., 2.), c(0., 2.), c(2., 0.)),
            Proper
        );
        assert_eq!(
            segments_intersect(c(0., 0.), c(2., 2.), c(1., 1.), c(3., 0.)),
            Touch
        );
        assert_eq!(
            segments_intersect(c(0., 0.), c(2., 0.), c(1., 0.), c(3., 0.)),
            Touch
        );
        assert_eq!(
            segments_intersect(c(0., 0.), c(1., 0.), c(2., 0.), c(3., 0.)),
            None
        );
        assert_eq!(
            segments_intersect(c(0., 0.), c(1., 1.), c(0., 1.), c(0.4, 0.6)),
            None
        );
    }

    proptest::proptest! {
        #[test]
        fn point_in_convex_ring_matches_half_planes(
            px in -3.0f64..3.0, py in -3.0f64..3.0, off in proptest::prop_oneof![proptest::strategy::Just(0.0), proptest::strategy::Just(1.0e7)]
        ) {
            // A convex ring: inside iff left of every edge (brute force truth).
            let r: Vec<Coord<f64>> = [(0.0, -2.0), (2.0, -1.0), (2.0, 1.5), (-1.0, 2.0), (-2.0, 0.0)]
                .iter().map(|&(x, y)| coord! {x: x + off, y: y + off}).collect();
            let p = coord! {x: px + off, y: py + off};
            let n = r.len();
            let os: Vec<_> = (0..n).map(|i| orient2d(r[i], r[(i + 1) % n], p)).collect();
            let truth = if os.contains(&Orientation::Clockwise) {
                Location::Outside
            } else if os.iter().all(|o| *o == Orientation::CounterClockwise) {
                Location::Inside
            } else {
                Location::OnBoundary
            };
            proptest::prop_assert_eq!(point_in_ring(p, &r), truth);
        }
    }

    /// A star-shaped ring of `n` vertices around `(cx, cy)`, radii from `radii` (counter-clockwise).
    fn star(cx: f64, cy: f64, radii: &[f64]) -> Vec<glam::DVec2> {
        let n = radii.len();
        radii
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                glam::DVec2::new(cx + r * a.cos(), cy + r * a.sin())
            })
            .collect()
    }

    proptest::proptest! {
        /// The one point-in-ring agrees with `geo`'s independent implementation
        /// (`CoordinatePosition`) on random star-shaped rings, near the origin and at UTM
        /// magnitudes, for points anywhere including on vertices; and a `DVec2` ring gives the same
        /// answer as the same ring in `Coord`s (what the allocating copy in the occlusion bench
        /// used to do).
        #[test]
        fn point_in_ring_matches_geo_and_both_point_types(
            radii in proptest::collection::vec(1.0f64..10.0, 3..16),
            px in -12.0f64..12.0, py in -12.0f64..12.0,
            vertex in proptest::option::of(0usize..16),
            off in proptest::prop_oneof![proptest::strategy::Just(0.0), proptest::strategy::Just(5.4e6)],
        ) {
            use geo::coordinate_position::{CoordPos, CoordinatePosition};
            let ring = star(off, off, &radii);
            let p = match vertex {
                Some(k) => ring[k % ring.len()],
                None => glam::DVec2::new(px + off, py + off),
            };
            let coords: Vec<Coord<f64>> = ring.iter().map(|v| v.to()).collect();
            let got = point_in_ring(p, &ring);
            proptest::prop_assert_eq!(got, point_in_ring(p.to::<Coord<f64>>(), &coords));
            let mut closed = coords.clone();
            closed.push(coords[0]);
            let poly = Polygon::new(LineString(closed.clone()), vec![]);
            let truth = match poly.coordinate_position(&p.to::<Coord<f64>>()) {
                CoordPos::Inside => Location::Inside,
                CoordPos::Outside => Location::Outside,
                CoordPos::OnBoundary => Location::OnBoundary,
            };
            proptest::prop_assert_eq!(got, truth);
            // Closed and open rings are the same ring.
            proptest::prop_assert_eq!(point_in_ring(p.to::<Coord<f64>>(), &closed), got);
        }

        /// The one signed area agrees with the plain shoelace sum the occluder extraction used
        /// to compute on its own (same sign; equal up to rounding), for rings far from the origin
        /// in both windings.
        #[test]
        fn signed_area_matches_the_plain_shoelace(
            radii in proptest::collection::vec(1.0f64..10.0, 3..16),
            off in proptest::prop_oneof![proptest::strategy::Just(0.0), proptest::strategy::Just(100.0)],
            reverse in proptest::bool::ANY,
        ) {
            let mut ring = star(off, -off, &radii);
            if reverse {
                ring.reverse();
            }
            ring.push(ring[0]);
            let plain = ring.windows(2).map(|w| w[0].perp_dot(w[1])).sum::<f64>() * 0.5;
            let one = ring_signed_area(&ring);
            proptest::prop_assert!(plain != 0.0 && one != 0.0);
            proptest::prop_assert_eq!(plain > 0.0, !reverse);
            proptest::prop_assert_eq!(one > 0.0, !reverse);
            proptest::prop_assert!((one - plain).abs() <= 1e-9 * plain.abs(), "{} vs {}", one, plain);
            let coords: Vec<Coord<f64>> = ring.iter().map(|v| v.to()).collect();
            proptest::prop_assert_eq!(ring_signed_area(&coords).to_bits(), one.to_bits());
        }

        /// The proper-crossing case of `segments_intersect` is exactly the sign test the street
        /// noding used to write by hand (`o1·o2 < 0 && o3·o4 < 0` on `orient2d_det`), on integer
        /// grids where collinear and touching cases are frequent.
        #[test]
        fn proper_crossing_is_the_strict_sign_test(
            c in proptest::collection::vec((-4i32..4, -4i32..4), 4),
        ) {
            let v: Vec<Coord<f64>> = c.iter().map(|&(x, y)| Coord { x: x as f64, y: y as f64 }).collect();
            let (a, b, p, q) = (v[0], v[1], v[2], v[3]);
            let hand = orient2d_det(a, b, p) * orient2d_det(a, b, q) < 0.0
                && orient2d_det(p, q, a) * orient2d_det(p, q, b) < 0.0;
            proptest::prop_assert_eq!(segments_intersect(a, b, p, q) == SegmentIntersection::Proper, hand);
        }
    }

    #[test]
    fn interior_point_of_concave_and_holed() {
        // U shape: centroid of the bbox is in the notch.
        let u = polygon![(x: 0., y: 0.), (x: 3., y: 0.), (x: 3., y: 3.), (x: 2., y: 3.),
            (x: 2., y: 1.), (x: 1., y: 1.), (x: 1., y: 3.), (x: 0., y: 3.)];
        let p = robust_interior_point(&u).unwrap();
        assert_eq!(point_in_polygon(p, &u), Location::Inside);
        let holed = polygon!(
            exterior: [(x: 0., y: 0.), (x: 4., y: 0.), (x: 4., y: 4.), (x: 0., y: 4.)],
            interiors: [[(x: 1., y: 1.), (x: 1., y: 3.), (x: 3., y: 3.), (x: 3., y: 1.)]],
        );
        let p = robust_interior_point(&holed).unwrap();
        assert_eq!(point_in_polygon(p, &holed), Location::Inside);
        assert!((polygon_area(&holed) - 12.0).abs() < 1e-12);
    }
}
