//! The smallest sphere around a block's geometry, the sphere half of the BqR-tree's
//! "bounding-box-sphere" leaf volume (Pina, Serón and Cerezo, §4: "calculate [the blocks'] geometric centers and
//! bounding spheres"; the leaf volume is that sphere intersected with a box).
//!
//! # Method
//! Welzl's randomised algorithm (1991) in Gärtner's move-to-front form (1999): an exact minimum
//! enclosing ball in expected linear time for a shuffled input; the shuffle is seeded, so the
//! result is deterministic. The ball through a support set of up to four points is the one whose
//! centre lies in their affine hull, found from the 3 × 3 (at most) Gram system with partial
//! pivoting.
//!
//! # Conservative whatever the rounding
//! Floating point can leave a point a hair outside the ball the algorithm returns, and an
//! affinely dependent support set (four co-circular corners of a rectangle, common in cities) has
//! no unique solution. Neither matters for culling: the algorithm only chooses the *centre*; the
//! radius returned is then measured, the largest distance from that centre to any input point,
//! rounded up. So every point is inside whatever happened on the way, and at worst the sphere is a
//! little looser than the minimum.
//!
//! Why not a crate: `miniball` (MPL-2.0, nalgebra 0.32) does the same in any dimension; the one
//! function here is the whole need, and the verification above is ours either way.

use crate::geom::BoundingSphere;
use glam::DVec3;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A ball under construction: centre and squared radius; `r2 < 0` is the empty ball.
#[derive(Clone, Copy, Debug)]
struct Ball {
    c: DVec3,
    r2: f64,
}

impl Ball {
    const EMPTY: Ball = Ball {
        c: DVec3::ZERO,
        r2: -1.0,
    };

    /// Inside up to a relative tolerance: co-circular points count as on the sphere, so that
    /// affinely dependent support sets are rarely formed (the final radius is measured anyway).
    fn holds(&self, p: DVec3) -> bool {
        self.r2 >= 0.0 && (p - self.c).length_squared() <= self.r2 + 1e-10 * self.r2.max(1.0)
    }
}

/// The smallest ball with every point of `s` (1 to 4 points) on its boundary and its centre in
/// their affine hull; `None` when they are affinely dependent (no unique such ball).
fn ball_through(s: &[DVec3]) -> Option<Ball> {
    let Some((&p0, rest)) = s.split_first() else {
        return Some(Ball::EMPTY);
    };
    let k = rest.len();
    if k == 0 {
        return Some(Ball { c: p0, r2: 0.0 });
    }
    // c = p0 + Σ λ_j v_j with v_j = p_j − p0 and, for every i, v_i · (c − p0) = |v_i|² / 2.
    let v: Vec<DVec3> = rest.iter().map(|p| *p - p0).collect();
    let mut a = [[0.0f64; 4]; 3];
    let mut scale = 0.0f64;
    for i in 0..k {
        for j in 0..k {
            a[i][j] = v[i].dot(v[j]);
        }
        a[i][k] = 0.5 * v[i].length_squared();
        scale = scale.max(a[i][i]);
    }
    if scale <= 0.0 {
        return None;
    }
    // Gaussian elimination with partial pivoting on the k × (k + 1) system.
    for col in 0..k {
        let piv = (col..k)
            .max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))
            .unwrap_or(col);
        if a[piv][col].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(col, piv);
        let pivot_row = a[col];
        for row in a.iter_mut().take(k).skip(col + 1) {
            let f = row[col] / pivot_row[col];
            for (x, p) in row.iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
        }
    }
    let mut lambda = [0.0f64; 3];
    for row in (0..k).rev() {
        let mut acc = a[row][k];
        for c in row + 1..k {
            acc -= a[row][c] * lambda[c];
        }
        lambda[row] = acc / a[row][row];
    }
    let off: DVec3 = v.iter().zip(lambda).map(|(vi, l)| *vi * l).sum();
    if !off.is_finite() {
        return None;
    }
    Some(Ball {
        c: p0 + off,
        r2: off.length_squared(),
    })
}

/// Gärtner's move-to-front Welzl: the smallest ball holding `pts[..end]` with `support` on its
/// boundary.
fn mtf(pts: &mut [DVec3], end: usize, support: &mut Vec<DVec3>) -> Ball {
    let mut ball = match ball_through(support) {
        Some(b) => b,
        None => {
            // Affinely dependent support (within rounding): keep the ball of the earlier
            // support points, grown to reach the newest one. The final radius is measured.
            let (last, head) = support.split_last().expect("a degenerate set is not empty");
            let mut b = ball_through(head).unwrap_or(Ball { c: *last, r2: 0.0 });
            b.r2 = b.r2.max((*last - b.c).length_squared());
            b
        }
    };
    if support.len() == 4 {
        return ball;
    }
    for i in 0..end {
        let p = pts[i];
        if !ball.holds(p) {
            support.push(p);
            ball = mtf(pts, i, support);
            support.pop();
            pts[..=i].rotate_right(1);
        }
    }
    ball
}

/// The smallest sphere holding every finite point of `points` (Welzl / Gärtner, see the module
/// doc), with its radius measured from its centre to the farthest point and rounded up, so that
/// it holds every point exactly; `None` when no point is finite.
///
/// # Examples
/// ```
/// use blockwalk::index::enclosing_sphere;
/// use glam::DVec3;
///
/// // The corners of a 2 × 2 square: the circle through them, not the box's sphere.
/// let pts = [(0., 0.), (2., 0.), (2., 2.), (0., 2.)].map(|(x, y)| DVec3::new(x, y, 0.0));
/// let s = enclosing_sphere(&pts).unwrap();
/// assert!((s.radius - 2f64.sqrt()).abs() < 1e-6);
/// assert!(pts.iter().all(|p| s.contains_point(*p)));
/// ```
pub fn enclosing_sphere(points: &[DVec3]) -> Option<BoundingSphere> {
    let first = *points.iter().find(|p| p.is_finite())?;
    // Relative to one of the points: the Gram system then works with block-sized numbers, not
    // with coordinates kilometres from the frame's origin.
    let mut rel: Vec<DVec3> = points
        .iter()
        .filter(|p| p.is_finite())
        .map(|p| *p - first)
        .collect();
    // Welzl's expected linear time needs a random order (footprints come in ring order).
    rel.shuffle(&mut ChaCha8Rng::seed_from_u64(0x5EB));
    let end = rel.len();
    let ball = mtf(&mut rel, end, &mut Vec::with_capacity(4));
    let center = first + ball.c;
    let radius = points
        .iter()
        .filter(|p| p.is_finite())
        .map(|p| (*p - center).length())
        .fold(0.0f64, f64::max);
    Some(BoundingSphere {
        center,
        // Round up so that no point is left outside by the last bit of a distance.
        radius: radius * (1.0 + 1e-12) + 1e-9,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_minimum_balls() {
        // Two points: the ball on their segment.
        let s = enclosing_sphere(&[DVec3::ZERO, DVec3::new(4.0, 0.0, 0.0)]).unwrap();
        assert!(s.center.distance(DVec3::new(2.0, 0.0, 0.0)) < 1e-9);
        assert!((s.radius - 2.0).abs() < 1e-6);
        // A cube's corners: its circumscribed sphere.
        let b = crate::geom::Aabb3::new(DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0));
        let s = enclosing_sphere(&b.corners()).unwrap();
        assert!((s.radius - BoundingSphere::from_aabb(&b).radius).abs() < 1e-6);
        // An obtuse triangle: the ball on its longest side, smaller than the box's sphere.
        let t = [
            DVec3::ZERO,
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(5.0, 1.0, 0.0),
        ];
        let s = enclosing_sphere(&t).unwrap();
        assert!((s.radius - 5.0).abs() < 1e-6, "{s:?}");
        // Points far from the origin keep their precision.
        let far: Vec<DVec3> = t.iter().map(|p| *p + DVec3::new(3e6, 5e6, 0.0)).collect();
        let s = enclosing_sphere(&far).unwrap();
        assert!((s.radius - 5.0).abs() < 1e-6, "{s:?}");
        assert!(enclosing_sphere(&[DVec3::NAN]).is_none());
        assert!(enclosing_sphere(&[]).is_none());
    }

    #[test]
    fn a_tall_tower_on_a_low_block_is_tighter_than_the_box() {
        // A 70 × 70 m block 8 m high with a 15 × 15 m tower of 120 m in the middle: the
        // sphere through the slab's corners and the tower's top, centre 50.26 m up, radius
        // √(2·35² + 50.26²) = 70.54 m, against the box's 77.8 m.
        let mut pts = Vec::new();
        for z in [0.0, 8.0] {
            for (x, y) in [(0., 0.), (70., 0.), (70., 70.), (0., 70.)] {
                pts.push(DVec3::new(x, y, z));
            }
        }
        for z in [0.0, 120.0] {
            for (x, y) in [(27.5, 27.5), (42.5, 27.5), (42.5, 42.5), (27.5, 42.5)] {
                pts.push(DVec3::new(x, y, z));
            }
        }
        let s = enclosing_sphere(&pts).unwrap();
        let b = crate::geom::Aabb3::from_points(pts.iter().copied());
        assert!(pts.iter().all(|p| s.contains_point(*p)));
        assert!((s.radius - 70.54).abs() < 0.01, "{s:?}");
        assert!((BoundingSphere::from_aabb(&b).radius - 77.78).abs() < 0.01);
    }
}
