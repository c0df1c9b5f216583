//! Clipping a polygon against one half-space (one step of Sutherland–Hodgman).
//!
//! One implementation serves the plan-view cull map (`DVec2`, half-planes of an occluder shadow)
//! and the oracle's homogeneous clip space (`DVec4`, near and far planes). Clipping to an
//! axis-aligned box, where crossings land exactly on the box's sides, is [`clip_to_box`].

use glam::DVec2;
use std::ops::{Add, Mul, Sub};

/// Keeps the part of the polygon `poly` (vertices in order, implicitly closed) where
/// `dist(p) ≥ 0`, for a `dist` that is affine in `p`; `tmp` is scratch space (both vectors are
/// reused, nothing is allocated once they have grown). A convex polygon stays convex.
///
/// Vertices with `dist ≥ 0` are kept as they are; where an edge crosses the boundary the
/// crossing `a + (b − a) t`, `t = d(a) / (d(a) − d(b))` is inserted. A crossing that is not finite
/// (a `dist` of ±∞ or NaN) is dropped.
pub fn clip_polygon<V>(poly: &mut Vec<V>, tmp: &mut Vec<V>, dist: impl Fn(V) -> f64)
where
    V: Copy + Add<Output = V> + Sub<Output = V> + Mul<f64, Output = V>,
{
    tmp.clear();
    let n = poly.len();
    for k in 0..n {
        let a = poly[k];
        let b = poly[(k + 1) % n];
        let (da, db) = (dist(a), dist(b));
        if da >= 0.0 {
            tmp.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            if t.is_finite() {
                tmp.push(a + (b - a) * t.clamp(0.0, 1.0));
            }
        }
    }
    std::mem::swap(poly, tmp);
}

/// Clips the polygon `poly` (vertices in order, implicitly closed) to the axis-aligned box
/// `[lo, hi]`: Sutherland–Hodgman against `x ≥ lo.x`, `x ≤ hi.x`, `y ≥ lo.y`, `y ≤ hi.y` in that
/// order. A crossing is interpolated along the clipped axis, `t = (bound − a) / (b − a)`, and its
/// clipped coordinate set to the bound exactly, so parts of neighbouring boxes share their sides
/// bit for bit. A convex polygon stays convex; a non-convex one may come back with degenerate
/// edges along the box, whose shoelace area is still exact.
pub fn clip_to_box(poly: &[DVec2], lo: DVec2, hi: DVec2) -> Vec<DVec2> {
    let (mut out, mut tmp) = (Vec::new(), Vec::new());
    clip_to_box_into(poly, lo, hi, &mut out, &mut tmp);
    out
}

/// [`clip_to_box`] into `out`, with `tmp` as working memory: the same points, and no
/// allocation once both have grown (for loops that clip many small polygons).
pub fn clip_to_box_into(
    poly: &[DVec2],
    lo: DVec2,
    hi: DVec2,
    out: &mut Vec<DVec2>,
    tmp: &mut Vec<DVec2>,
) {
    out.clear();
    out.extend_from_slice(poly);
    // (axis, bound, keep below)
    for (axis, bound, below) in [
        (0usize, lo.x, false),
        (0, hi.x, true),
        (1, lo.y, false),
        (1, hi.y, true),
    ] {
        if out.is_empty() {
            break;
        }
        let v = |q: DVec2| if axis == 0 { q.x } else { q.y };
        let inside = |q: DVec2| if below { v(q) <= bound } else { v(q) >= bound };
        tmp.clear();
        for q in 0..out.len() {
            let (a, b) = (out[q], out[(q + 1) % out.len()]);
            let (ia, ib) = (inside(a), inside(b));
            if ia {
                tmp.push(a);
            }
            if ia != ib {
                let t = (bound - v(a)) / (v(b) - v(a));
                let mut x = a + (b - a) * t;
                if axis == 0 {
                    x.x = bound;
                } else {
                    x.y = bound;
                }
                tmp.push(x);
            }
        }
        std::mem::swap(out, tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec2, DVec4};

    #[test]
    fn square_loses_a_corner_to_a_diagonal_line() {
        let mut poly = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        let mut tmp = Vec::new();
        // Keep x + y ≤ 3: the corner (2, 2) is cut off.
        clip_polygon(&mut poly, &mut tmp, |p| 3.0 - p.x - p.y);
        assert_eq!(
            poly,
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(2.0, 0.0),
                DVec2::new(2.0, 1.0),
                DVec2::new(1.0, 2.0),
                DVec2::new(0.0, 2.0)
            ]
        );
        // Everything on the wrong side: nothing left.
        clip_polygon(&mut poly, &mut tmp, |p| p.x - 10.0);
        assert!(poly.is_empty());
    }

    #[test]
    fn box_clip_puts_crossings_on_the_sides() {
        let tri = [
            DVec2::new(-1.0, 0.5),
            DVec2::new(3.0, 0.5),
            DVec2::new(1.0, 3.0),
        ];
        let p = clip_to_box(&tri, DVec2::ZERO, DVec2::splat(2.0));
        assert!(!p.is_empty());
        assert!(p
            .iter()
            .all(|q| (0.0..=2.0).contains(&q.x) && (0.0..=2.0).contains(&q.y)));
        assert!(p.iter().filter(|q| q.x == 0.0 || q.x == 2.0).count() >= 2);
        assert!(clip_to_box(&tri, DVec2::splat(5.0), DVec2::splat(6.0)).is_empty());
    }

    #[test]
    fn homogeneous_triangle_through_the_near_plane() {
        let mut poly = vec![
            DVec4::new(0.0, 0.0, -1.0, 1.0),
            DVec4::new(1.0, 0.0, 1.0, 1.0),
            DVec4::new(0.0, 1.0, 1.0, 1.0),
        ];
        let mut tmp = Vec::new();
        clip_polygon(&mut poly, &mut tmp, |q| q.z);
        assert_eq!(poly.len(), 4);
        assert!(poly.iter().all(|q| q.z >= 0.0));
        assert!(poly.contains(&DVec4::new(0.5, 0.0, 0.0, 1.0)));
        assert!(poly.contains(&DVec4::new(0.0, 0.5, 0.0, 1.0)));
    }
}
