//! Surface colours and light for BlockMaps, in one place.
//!
//! Until the procedural appearance of the city (issue 11, "Appearance first") lands in
//! `city::appearance`, these mirror the mesh renderer's shader (`render/mesh.wgsl`): roofs
//! `(0.70, 0.36, 0.28)` and facades `(0.86, 0.82, 0.72)`, each times the per-block tint, lit by
//! `ambient + (1 − ambient)·max(n·sun, 0)`. Construction, the reference caster's shading and the
//! image comparison all call these functions, so switching to the appearance is one edit here.

use crate::blocks::BlockId;
use crate::city::Building;
use glam::Vec3;

/// Ambient term of the light (`render/mesh.rs`).
pub const AMBIENT: f32 = 0.35;

/// Unit direction towards the sun (`render/mesh.rs`: south-east, about 50° up).
pub fn sun() -> Vec3 {
    glam::DVec3::new(0.5, -0.6, 1.3).normalize().as_vec3()
}

/// The mesh shader's per-block tint (`render/mesh.wgsl` `tint`).
pub fn tint(block: BlockId) -> f32 {
    let h = block.0.wrapping_mul(2_654_435_761) >> 24;
    0.9 + 0.2 * h as f32 / 255.0
}

/// Unlit roof colour of a building, RGB in `[0, 1]`.
pub fn roof_rgb(_b: &Building, block: BlockId) -> [f32; 3] {
    let t = tint(block);
    [0.70 * t, 0.36 * t, 0.28 * t]
}

/// Unlit facade colour of a building at height `z_m` above the ground, RGB in `[0, 1]`.
pub fn facade_rgb(_b: &Building, block: BlockId, _z_m: f64) -> [f32; 3] {
    let t = tint(block);
    [0.86 * t, 0.82 * t, 0.72 * t]
}

/// The light factor of a unit normal.
pub fn light(n: Vec3) -> f32 {
    AMBIENT + (1.0 - AMBIENT) * n.dot(sun()).max(0.0)
}

/// `[0, 1]` RGB to bytes (rounded, clamped).
pub fn to_bytes(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// A lit colour: `min(base·light, 1)` as the mesh shader writes it, to bytes.
pub fn lit(base: [u8; 3], n: Vec3) -> [u8; 3] {
    let l = light(n);
    base.map(|b| ((b as f32 / 255.0 * l).min(1.0) * 255.0).round() as u8)
}
