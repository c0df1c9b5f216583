//! Interpolation kernels: centripetal Catmull–Rom for positions, squad for orientations.
//!
//! The route of Pina, Serón and Cerezo, §5 is a sequence of camera moves; these kernels turn its key frames into a
//! smooth path that passes exactly through every key.

use glam::{DQuat, DVec3};

/// Knot spacing exponent of the centripetal parameterisation (α = ½): no cusps or self
/// intersections inside a segment (Yuksel, Schaefer & Keyser 2011).
pub const ALPHA: f64 = 0.5;

/// Distances below this (metres) count as coincident key positions.
const COINCIDENT: f64 = 1e-9;

/// A point on the centripetal Catmull–Rom segment from `p1` (u = 0) to `p2` (u = 1), shaped by
/// the neighbours `p0` and `p3` (Barry–Goldman pyramid). Pass `None` for a missing neighbour (the
/// first or last segment, or a corner): it is replaced by the reflection of the far end, which
/// makes the segment start or end straight. A neighbour that coincides with its key is treated as
/// missing too, so that repeated keys never divide by zero.
pub fn catmull_rom(p0: Option<DVec3>, p1: DVec3, p2: DVec3, p3: Option<DVec3>, u: f64) -> DVec3 {
    let d12 = p1.distance(p2);
    if d12 < COINCIDENT {
        return p1;
    }
    let p0 = p0
        .filter(|p| p.distance(p1) >= COINCIDENT)
        .unwrap_or(2.0 * p1 - p2);
    let p3 = p3
        .filter(|p| p.distance(p2) >= COINCIDENT)
        .unwrap_or(2.0 * p2 - p1);
    let t0 = 0.0;
    let t1 = t0 + p0.distance(p1).powf(ALPHA);
    let t2 = t1 + d12.powf(ALPHA);
    let t3 = t2 + p2.distance(p3).powf(ALPHA);
    let t = t1 + (t2 - t1) * u.clamp(0.0, 1.0);
    let lerp = |a: DVec3, b: DVec3, ta: f64, tb: f64| {
        a * ((tb - t) / (tb - ta)) + b * ((t - ta) / (tb - ta))
    };
    let a1 = lerp(p0, p1, t0, t1);
    let a2 = lerp(p1, p2, t1, t2);
    let a3 = lerp(p2, p3, t2, t3);
    let b1 = lerp(a1, a2, t0, t2);
    let b2 = lerp(a2, a3, t1, t3);
    lerp(b1, b2, t1, t2)
}

/// Logarithm of a unit quaternion (a pure quaternion, returned as its vector part).
fn log_unit(q: DQuat) -> DVec3 {
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-15 {
        return DVec3::ZERO;
    }
    v * (s.atan2(q.w) / s)
}

/// Exponential of a pure quaternion given by its vector part.
fn exp_pure(v: DVec3) -> DQuat {
    let theta = v.length();
    if theta < 1e-15 {
        return DQuat::IDENTITY;
    }
    let s = theta.sin() / theta;
    DQuat::from_xyzw(v.x * s, v.y * s, v.z * s, theta.cos()).normalize()
}

/// Flips signs so that consecutive quaternions lie in the same hemisphere (`dot ≥ 0`); the
/// rotations are unchanged, and interpolation then never takes the long way round.
pub fn align_hemispheres(qs: &mut [DQuat]) {
    for i in 1..qs.len() {
        if qs[i - 1].dot(qs[i]) < 0.0 {
            qs[i] = -qs[i];
        }
    }
}

/// The squad control quaternion at `q` between `prev` and `next` (Shoemake 1987):
/// `s = q · exp(−(log(q⁻¹·next) + log(q⁻¹·prev)) / 4)`. A missing neighbour (end or corner) gives
/// `s = q`, which makes the curve start or stop turning smoothly from that key.
pub fn squad_control(prev: Option<DQuat>, q: DQuat, next: Option<DQuat>) -> DQuat {
    match (prev, next) {
        (Some(p), Some(n)) => {
            let inv = q.conjugate();
            let l = log_unit((inv * n).normalize()) + log_unit((inv * p).normalize());
            (q * exp_pure(-l * 0.25)).normalize()
        }
        _ => q,
    }
}

/// Spherical quadrangle interpolation from `q1` (h = 0) to `q2` (h = 1) with control quaternions
/// `s1`, `s2`: passes through both keys and is C¹ across keys.
pub fn squad(q1: DQuat, q2: DQuat, s1: DQuat, s2: DQuat, h: f64) -> DQuat {
    let h = h.clamp(0.0, 1.0);
    let a = q1.slerp(q2, h);
    let b = s1.slerp(s2, h);
    a.slerp(b, 2.0 * h * (1.0 - h)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catmull_rom_hits_ends_and_follows_a_line() {
        let p0 = DVec3::new(0.0, 0.0, 0.0);
        let p1 = DVec3::new(1.0, 0.0, 0.0);
        let p2 = DVec3::new(3.0, 0.0, 0.0);
        let p3 = DVec3::new(7.0, 0.0, 0.0);
        assert!(catmull_rom(Some(p0), p1, p2, Some(p3), 0.0).distance(p1) < 1e-12);
        assert!(catmull_rom(Some(p0), p1, p2, Some(p3), 1.0).distance(p2) < 1e-12);
        // Collinear keys: the curve stays on the line and between the keys.
        for i in 0..=20 {
            let p = catmull_rom(Some(p0), p1, p2, Some(p3), i as f64 / 20.0);
            assert!(p.y.abs() < 1e-12 && p.z.abs() < 1e-12);
            assert!(p.x >= 1.0 - 1e-12 && p.x <= 3.0 + 1e-12, "{p}");
        }
    }

    #[test]
    fn log_exp_round_trip() {
        let q = DQuat::from_rotation_z(0.7) * DQuat::from_rotation_y(-1.2);
        let back = exp_pure(log_unit(q));
        assert!(back.dot(q).abs() > 1.0 - 1e-12);
    }

    #[test]
    fn squad_hits_keys() {
        let qs = [
            DQuat::from_rotation_z(0.0),
            DQuat::from_rotation_z(1.0),
            DQuat::from_rotation_y(1.0),
            DQuat::from_rotation_x(0.3),
        ];
        let s1 = squad_control(Some(qs[0]), qs[1], Some(qs[2]));
        let s2 = squad_control(Some(qs[1]), qs[2], Some(qs[3]));
        assert!(squad(qs[1], qs[2], s1, s2, 0.0).dot(qs[1]).abs() > 1.0 - 1e-12);
        assert!(squad(qs[1], qs[2], s1, s2, 1.0).dot(qs[2]).abs() > 1.0 - 1e-12);
    }
}
