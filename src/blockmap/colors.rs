//! Surface colours and light for BlockMaps, in one place: the city's procedural appearance
//! ([`crate::city::appearance`]), which the mesh renderer and the CPU fallback use too.
//! Construction, the reference caster's shading and the image comparison all call these
//! functions.

use crate::city::appearance::{self, BuildingStyle};
use glam::Vec3;

/// Unlit roof colour of a building, RGB in `[0, 1]`.
pub fn roof_rgb(style: &BuildingStyle) -> [f32; 3] {
    appearance::roof_color(style)
}

/// Unlit facade colour at `u_m` metres along the unfolded ring and `z_m` above the ground.
pub fn facade_rgb(style: &BuildingStyle, u_m: f32, z_m: f32) -> [f32; 3] {
    appearance::facade_color(style, u_m, z_m)
}

/// Unlit colour of the underside of a raised part.
pub fn underside_rgb() -> [f32; 3] {
    appearance::unit_rgb(appearance::UNDERSIDE)
}

/// `[0, 1]` RGB to bytes (rounded, clamped), as an `Rgba8Unorm` target stores it.
pub fn to_bytes(c: [f32; 3]) -> [u8; 3] {
    appearance::to_rgb8(c)
}

/// A lit colour as the mesh shader writes it ([`appearance::shade`]), to bytes.
pub fn lit(base: [u8; 3], n: Vec3) -> [u8; 3] {
    to_bytes(appearance::shade(base.map(|b| b as f32 / 255.0), n))
}
