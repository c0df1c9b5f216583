//! Plan-view metric helpers on segments and boxes: distance and closest point.
//!
//! These measure (in `f64`, with ordinary rounding); the exact decisions live in
//! [`super::predicates`].

use super::point::Xy;

/// Distance from `p` to the closed segment `a–b` and the parameter `t ∈ [0, 1]` of the closest
/// point `a + t (b − a)`; a segment of zero length gives `t = 0`.
///
/// # Units
/// The distance is in the points' units (metres in this crate).
#[inline]
pub fn point_segment_distance<P: Xy>(p: P, a: P, b: P) -> (f64, f64) {
    let (dx, dy) = (b.x() - a.x(), b.y() - a.y());
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.x() - a.x()) * dx + (p.y() - a.y()) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (a.x() + dx * t - p.x(), a.y() + dy * t - p.y());
    ((ex * ex + ey * ey).sqrt(), t)
}

/// Distance from `p` to the closed axis-aligned rectangle `[min, max]` (0 inside or on it).
/// Never panics: an empty rectangle (`min > max`) measures to `max`, and NaN coordinates of the
/// rectangle are ignored per component (`f64::max`, `f64::min`).
#[inline]
pub fn point_rect_distance<P: Xy>(p: P, min: P, max: P) -> f64 {
    let ex = p.x().max(min.x()).min(max.x()) - p.x();
    let ey = p.y().max(min.y()).min(max.y()) - p.y();
    (ex * ex + ey * ey).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::Coord;
    use glam::DVec2;
    use proptest::prelude::*;

    #[test]
    fn ends_middle_and_degenerate() {
        let (a, b) = (DVec2::new(0.0, 0.0), DVec2::new(4.0, 0.0));
        assert_eq!(
            point_segment_distance(DVec2::new(2.0, 3.0), a, b),
            (3.0, 0.5)
        );
        assert_eq!(
            point_segment_distance(DVec2::new(-3.0, 4.0), a, b),
            (5.0, 0.0)
        );
        assert_eq!(
            point_segment_distance(DVec2::new(7.0, 4.0), a, b),
            (5.0, 1.0)
        );
        assert_eq!(
            point_segment_distance(DVec2::new(3.0, 4.0), a, a),
            (5.0, 0.0)
        );
        let (lo, hi) = (DVec2::new(0.0, 0.0), DVec2::new(2.0, 1.0));
        assert_eq!(point_rect_distance(DVec2::new(1.0, 0.5), lo, hi), 0.0);
        assert_eq!(point_rect_distance(DVec2::new(5.0, 5.0), lo, hi), 5.0);
        assert_eq!(point_rect_distance(DVec2::new(1.0, -2.0), lo, hi), 2.0);
    }

    proptest! {
        /// Brute force: no point sampled on the segment is nearer than the answer, the answer
        /// is attained at `t`, and `Coord` and `DVec2` give the same bits.
        #[test]
        fn distance_is_the_minimum_over_the_segment(
            p in (-100.0f64..100.0, -100.0f64..100.0),
            a in (-100.0f64..100.0, -100.0f64..100.0),
            b in (-100.0f64..100.0, -100.0f64..100.0),
        ) {
            let v = |q: (f64, f64)| DVec2::new(q.0, q.1);
            let (d, t) = point_segment_distance(v(p), v(a), v(b));
            prop_assert!((0.0..=1.0).contains(&t));
            let at = v(a) + (v(b) - v(a)) * t;
            prop_assert!((at.distance(v(p)) - d).abs() <= 1e-9 * (1.0 + d));
            for k in 0..=200 {
                let q = v(a) + (v(b) - v(a)) * (k as f64 / 200.0);
                prop_assert!(q.distance(v(p)) >= d - 1e-9 * (1.0 + d));
            }
            let c = |q: (f64, f64)| Coord { x: q.0, y: q.1 };
            let (dc, tc) = point_segment_distance(c(p), c(a), c(b));
            prop_assert_eq!((dc.to_bits(), tc.to_bits()), (d.to_bits(), t.to_bits()));
        }
    }
}
