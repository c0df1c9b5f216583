//! Convex hulls in the plan view, exact.
//!
//! One implementation for the crate: `geo`'s QuickHull, whose turn test is the same exact
//! `orient2d` as [`super::predicates`] (geo's robust kernel for `f64`). Points that are not finite
//! are ignored; collinear points on the hull's edges are left out.

use super::point::Xy;
use geo::algorithm::convex_hull::quick_hull;
use geo_types::{Coord, LineString, Polygon};

/// The hull as `geo` builds it: a closed, counter-clockwise ring (the first point repeated at the
/// end); a single point or two points give a degenerate closed ring.
fn hull_ring(points: impl IntoIterator<Item = Coord<f64>>) -> LineString<f64> {
    let mut pts: Vec<Coord<f64>> = points.into_iter().filter(|c| c.is_finite_xy()).collect();
    if pts.is_empty() {
        return LineString(Vec::new());
    }
    quick_hull(&mut pts)
}

/// Convex hull of `points` as a polygon with a closed, counter-clockwise exterior (what
/// `geo::ConvexHull` gives for the same points); empty for no finite point.
pub fn convex_hull_polygon(points: impl IntoIterator<Item = Coord<f64>>) -> Polygon<f64> {
    Polygon::new(hull_ring(points), vec![])
}

/// Convex hull of `points`: its vertices counter-clockwise, each once, without the closing
/// repeat. Fewer than three distinct points come back as they are (deduplicated): one point, or
/// the two ends of a segment.
pub fn convex_hull<P: Xy>(points: &[P]) -> Vec<P> {
    let ring = hull_ring(points.iter().map(|p| p.to::<Coord<f64>>()));
    let mut out: Vec<P> = Vec::with_capacity(ring.0.len());
    for c in &ring.0 {
        if out.last().is_none_or(|q: &P| q.x() != c.x || q.y() != c.y) {
            out.push(P::from_xy(c.x, c.y));
        }
    }
    while out.len() >= 2 && {
        let (a, b) = (out[0], out[out.len() - 1]);
        a.x() == b.x() && a.y() == b.y()
    } {
        out.pop();
    }
    drop_collinear(out)
}

/// Leaves out the vertices of a hull ring that lie on the segment between their neighbours
/// (exact `orient2d`): QuickHull can keep such a vertex when several input points repeat or are
/// collinear with a hull edge. When every vertex is collinear, the two extreme points remain.
fn drop_collinear<P: Xy>(mut ring: Vec<P>) -> Vec<P> {
    use super::predicates::{orient2d, Orientation};
    if ring.len() < 3 {
        return ring;
    }
    let all_collinear = ring
        .iter()
        .all(|&p| orient2d(ring[0], ring[1], p) == Orientation::Collinear);
    if all_collinear {
        let key = |p: &P| (p.x(), p.y());
        let lo = *ring
            .iter()
            .min_by(|a, b| {
                key(a)
                    .partial_cmp(&key(b))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .unwrap_or(&ring[0]);
        let hi = *ring
            .iter()
            .max_by(|a, b| {
                key(a)
                    .partial_cmp(&key(b))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .unwrap_or(&ring[0]);
        return vec![lo, hi];
    }
    let mut k = 0;
    let mut since_removal = 0;
    while ring.len() >= 3 && since_removal < ring.len() {
        let n = ring.len();
        let (a, b, c) = (ring[(k + n - 1) % n], ring[k % n], ring[(k + 1) % n]);
        if orient2d(a, b, c) == Orientation::Collinear {
            ring.remove(k % n);
            since_removal = 0;
        } else {
            k = (k + 1) % n;
            since_removal += 1;
        }
        k %= ring.len().max(1);
    }
    ring
}

#[cfg(test)]
mod tests {
    use super::super::predicates::{orient2d, Orientation};
    use super::*;
    use glam::DVec2;
    use proptest::prelude::*;

    #[test]
    fn square_with_inner_and_edge_points() {
        let pts = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.5),
            DVec2::new(2.0, 0.0),
            DVec2::new(1.0, 0.0), // on an edge: left out
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
            DVec2::new(f64::NAN, 5.0), // ignored
            DVec2::new(2.0, 2.0),      // duplicate
        ];
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4, "{h:?}");
        for k in 0..4 {
            assert_eq!(
                orient2d(h[k], h[(k + 1) % 4], h[(k + 2) % 4]),
                Orientation::CounterClockwise
            );
        }
        for c in [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)] {
            assert!(h.contains(&DVec2::new(c.0, c.1)));
        }
    }

    #[test]
    fn degenerate_inputs() {
        assert!(convex_hull::<DVec2>(&[]).is_empty());
        let p = DVec2::new(3.0, 4.0);
        assert_eq!(convex_hull(&[p, p, p]), vec![p]);
        let q = DVec2::new(5.0, 4.0);
        let h = convex_hull(&[p, q, p, DVec2::new(4.0, 4.0)]);
        assert_eq!(h.len(), 2, "{h:?}");
        assert!(h.contains(&p) && h.contains(&q));
    }

    /// Repeated points and a point on a hull edge (a case QuickHull left a collinear vertex in):
    /// the hull turns strictly left at every vertex.
    #[test]
    fn repeated_and_edge_points_leave_no_collinear_vertex() {
        #[rustfmt::skip]
        let raw = [
            (0, 0), (0, 0), (0, 0), (0, 49), (13, 49), (0, 0), (0, 0), (0, 0), (0, 0), (0, 0),
            (0, 0), (1, 49), (0, 0), (14, 45), (-1, 45),
        ];
        for off in [0.0, 5.0e6] {
            let pts: Vec<DVec2> = raw
                .iter()
                .map(|&(x, y)| DVec2::new(x as f64 * 0.25 + off, y as f64 * 0.25 + off))
                .collect();
            let h = convex_hull(&pts);
            let n = h.len();
            assert!(n >= 3, "{h:?}");
            for k in 0..n {
                assert_eq!(
                    orient2d(h[k], h[(k + 1) % n], h[(k + 2) % n]),
                    Orientation::CounterClockwise,
                    "{h:?}"
                );
            }
        }
        // Every point collinear: the two extremes, whatever the order.
        let line: Vec<DVec2> = [3.0, -1.0, 7.0, 2.0, 7.0]
            .iter()
            .map(|&t| DVec2::new(t, 2.0 * t + 1.0))
            .collect();
        let h = convex_hull(&line);
        assert_eq!(h.len(), 2, "{h:?}");
        assert!(h.contains(&DVec2::new(-1.0, -1.0)) && h.contains(&DVec2::new(7.0, 15.0)));
    }

    #[test]
    fn polygon_form_equals_geo_convex_hull() {
        use geo::ConvexHull;
        let pts: Vec<Coord<f64>> = (0..40)
            .map(|i| {
                let a = i as f64 * 0.7;
                Coord {
                    x: 5.0e5 + (i % 7) as f64 * a.cos() * 10.0,
                    y: 5.4e6 + (i % 5) as f64 * a.sin() * 10.0,
                }
            })
            .collect();
        let mp: geo_types::MultiPoint<f64> = pts.iter().map(|&c| geo_types::Point(c)).collect();
        assert_eq!(convex_hull_polygon(pts.iter().copied()), mp.convex_hull());
    }

    proptest! {
        /// Brute force: every point is inside or on the hull (exact orientation against every
        /// hull edge), every hull vertex is an input point, and the hull turns left everywhere.
        #[test]
        fn hull_holds_every_point(
            raw in proptest::collection::vec((-50i32..50, -50i32..50), 0..40),
            off in prop_oneof![Just(0.0), Just(5.0e6)],
        ) {
            let pts: Vec<DVec2> = raw
                .iter()
                .map(|&(x, y)| DVec2::new(x as f64 * 0.25 + off, y as f64 * 0.25 + off))
                .collect();
            let h = convex_hull(&pts);
            for v in &h {
                prop_assert!(pts.contains(v));
            }
            if h.len() >= 3 {
                let n = h.len();
                for k in 0..n {
                    prop_assert_eq!(
                        orient2d(h[k], h[(k + 1) % n], h[(k + 2) % n]),
                        Orientation::CounterClockwise
                    );
                    for p in &pts {
                        prop_assert_ne!(orient2d(h[k], h[(k + 1) % n], *p), Orientation::Clockwise);
                    }
                }
            } else {
                // All points on one line (or fewer than three distinct points).
                for p in &pts {
                    for q in &pts {
                        for r in &pts {
                            prop_assert_eq!(orient2d(*p, *q, *r), Orientation::Collinear);
                        }
                    }
                }
            }
        }
    }
}
