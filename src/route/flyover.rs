//! The high fly-over: the whole city in view from above, for the far field's experiments.

use super::{CameraRoute, KeyFrame, Lens, RouteError};
use crate::geom::{Aabb3, Camera};
use glam::DVec3;

/// A high fly-over: across the city's box from south-west to north-east at an altitude of
/// 0.8 × its larger side, looking ahead and down 35°, so that most of the city stays in view.
/// The near plane lies at half the height above the highest roof (nothing is nearer), as a
/// viewer sets it for a view from high up: with the lens's 0.5 m, Depth32Float cannot tell a
/// wall's lower metres from the ground kilometres away, and the ground's depth test then decides
/// pixels differently for meshes and maps (half the fly-over's mismatched pixels on the 80k
/// city came from there).
///
/// # Errors
/// None in practice (the route's two key frames are finite for a finite box).
pub fn flyover_route(bounds: Aabb3, aspect: f64) -> Result<CameraRoute, RouteError> {
    flyover_route_with_near(bounds, aspect, FLYOVER_NEAR_SHARE)
}

/// The near plane of [`flyover_route`] as a share of the height above the highest roof.
pub const FLYOVER_NEAR_SHARE: f64 = 0.5;

/// [`flyover_route`] with the near plane at `near_share` of the height above the highest roof
/// (`0`: the lens's default near plane).
///
/// # Errors
/// [`RouteError::Bad`] for a share outside [0, 1).
pub fn flyover_route_with_near(
    bounds: Aabb3,
    aspect: f64,
    near_share: f64,
) -> Result<CameraRoute, RouteError> {
    let e = bounds.extent();
    let side = e.x.max(e.y).max(100.0);
    let z = bounds.max.z + 0.8 * side;
    let c = bounds.center();
    let a = DVec3::new(bounds.min.x - 0.3 * e.x, bounds.min.y - 0.3 * e.y, z);
    let b = DVec3::new(c.x + 0.2 * e.x, c.y + 0.2 * e.y, z);
    let look = |p: DVec3| {
        Camera::looking_at(
            p,
            p + (DVec3::new(c.x, c.y, p.z) - a).normalize() * side
                + DVec3::new(0.0, 0.0, -side * 0.7),
        )
    };
    let (ca, cb) = (look(a), look(b));
    let base = Lens::default();
    let lens = Lens {
        aspect,
        far: 4.0 * side + z * 2.0,
        near: if near_share > 0.0 {
            (near_share * (z - bounds.max.z)).max(base.near)
        } else {
            base.near
        },
        ..base
    };
    if !(near_share.is_finite() && (0.0..1.0).contains(&near_share)) {
        return Err(RouteError::Bad {
            route: "flyover".into(),
            problem: format!("near-plane share {near_share}: expected a share in [0, 1)"),
        });
    }
    CameraRoute::new(
        "flyover",
        vec![
            KeyFrame::new(0.0, a, ca.yaw, ca.pitch),
            KeyFrame::new(30.0, b, cb.yaw, cb.pitch),
        ],
        lens,
    )
}
