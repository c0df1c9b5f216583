//! A perspective camera in the local frame (x east, y north, z up; metres).

use super::Frustum;
use glam::{DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

/// A perspective camera. Orientation is yaw (radians, counter-clockwise from +x/east) and pitch
/// (radians, positive looking up, in `[-π/2, π/2]`); looking straight down or up is well defined
/// (the image's up vector then follows the yaw) and never produces NaN.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Eye position in the local frame (metres).
    pub position: DVec3,
    /// Heading, radians counter-clockwise from east.
    pub yaw: f64,
    /// Elevation angle, radians; −π/2 looks straight down.
    pub pitch: f64,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Width / height of the image.
    pub aspect: f64,
    /// Near plane distance (metres, > 0).
    pub near: f64,
    /// Far plane distance (metres, > near).
    pub far: f64,
}

impl Camera {
    /// A camera at `position` looking along `yaw`/`pitch` with a 60° vertical field of view,
    /// 16:9, near 0.5 m and far 5 km.
    pub fn new(position: DVec3, yaw: f64, pitch: f64) -> Self {
        Self {
            position,
            yaw,
            pitch,
            fov_y: 60f64.to_radians(),
            aspect: 16.0 / 9.0,
            near: 0.5,
            far: 5000.0,
        }
    }

    /// A camera at `eye` looking at `target` (yaw and pitch derived; straight down is fine).
    pub fn looking_at(eye: DVec3, target: DVec3) -> Self {
        let d = target - eye;
        let horiz = (d.x * d.x + d.y * d.y).sqrt();
        let yaw = if horiz > 0.0 { d.y.atan2(d.x) } else { 0.0 };
        let pitch = d.z.atan2(horiz);
        Self::new(eye, yaw, pitch)
    }

    /// Unit viewing direction.
    pub fn forward(&self) -> DVec3 {
        let p = self
            .pitch
            .clamp(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2);
        DVec3::new(p.cos() * self.yaw.cos(), p.cos() * self.yaw.sin(), p.sin())
    }

    /// Unit image-up direction, perpendicular to [`Self::forward`]; follows the yaw when the
    /// camera looks straight down or up, so the frame never flips.
    pub fn up(&self) -> DVec3 {
        let p = self
            .pitch
            .clamp(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2);
        // d(forward)/d(pitch): always unit length and perpendicular to forward.
        DVec3::new(
            -p.sin() * self.yaw.cos(),
            -p.sin() * self.yaw.sin(),
            p.cos(),
        )
    }

    /// View matrix (right-handed, camera looks down −z in view space).
    pub fn view_from_world(&self) -> DMat4 {
        let f = self.forward();
        let u = self.up();
        let s = f.cross(u); // right; unit because f ⟂ u, both unit
        let e = self.position;
        DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(e), -u.dot(e), f.dot(e), 1.0),
        )
    }

    /// Projection matrix (right-handed, depth 0..1 as in wgpu).
    pub fn clip_from_view(&self) -> DMat4 {
        let h = 1.0 / (0.5 * self.fov_y).tan();
        let w = h / self.aspect;
        let r = self.far / (self.near - self.far);
        DMat4::from_cols(
            DVec4::new(w, 0.0, 0.0, 0.0),
            DVec4::new(0.0, h, 0.0, 0.0),
            DVec4::new(0.0, 0.0, r, -1.0),
            DVec4::new(0.0, 0.0, r * self.near, 0.0),
        )
    }

    /// Projection × view.
    pub fn clip_from_world(&self) -> DMat4 {
        self.clip_from_view() * self.view_from_world()
    }

    /// The view frustum.
    pub fn frustum(&self) -> Frustum {
        Frustum::from_clip_from_world(&self.clip_from_world())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_down_is_finite_and_orthonormal() {
        for yaw in [0.0, 1.0, 3.0, -2.0] {
            let c = Camera::new(
                DVec3::new(1e3, 2e3, 300.0),
                yaw,
                -std::f64::consts::FRAC_PI_2,
            );
            let m = c.clip_from_world();
            assert!(m.to_cols_array().iter().all(|v| v.is_finite()));
            assert!(c.forward().dot(c.up()).abs() < 1e-12);
            assert!((c.forward().z + 1.0).abs() < 1e-12);
        }
    }
}
