//! Procedural appearance: one deterministic definition of what buildings, streets and the ground
//! look like, shared by the mesh shader (`render/mesh.wgsl` mirrors [`facade_color`] and
//! [`shade`] line for line), the CPU fallback renderer (`visibility::oracle::shade`) and BlockMap
//! construction (Cignoni et al., §3.3 and Di Benedetto, §4.3 take wall and roof colours "from the geometry";
//! here the geometry's colours are these functions).
//!
//! # The definition
//! A building's [`BuildingStyle`] is a pure function of the building ([`building_style`]): no RNG
//! state, only a 32-bit hash of its `source_id` ([`style_hash`]), its height, its levels and its
//! type attribute ([`BuildingKind`]). Colours are 8-bit levels `k / 255` (so they survive an
//! `Rgba8Unorm` target exactly); the style also stores the reciprocals the shader needs, rounded
//! once on the CPU, so the GPU never divides.
//!
//! A wall point is given by `u` (metres along the unfolded ring, [`ring_u`]) and `z` (its local
//! height; the building's ground is at `ground_z`, 0 without terrain). [`facade_color`] is, with
//! `fl` = floor and every operation one f32 operation:
//!
//! ```text
//! t = (z − ground_z) · inv_storey_m         s = fl(t)        v = t − s          (storey s, height v in it)
//! b = u · inv_bay_m             f = b − fl(b)                        (position f in its bay)
//! plain  if levels = 0, s < 0 or s ≥ levels            → facade
//! window if v ≥ v0 and v < v1 and |f − 0.5| < window_half   → window
//!        with (v0, v1) = (GROUND_SILL, GROUND_LINTEL) on the ground floor (s < 1),
//!        else (SILL, LINTEL)
//! else   ground floor (s < 1)  → facade · GROUND_FLOOR_SHADE,  upper floors → facade
//! ```
//!
//! So each storey has exactly one row of windows, bays of `bay_m` with a pier of
//! `(1 − 2·window_half)·bay_m` between windows, and a darker ground floor. Roofs are
//! [`roof_color`] (by [`BuildingKind`], varied by the hash), the undersides of raised parts
//! [`UNDERSIDE`]. Lighting ([`shade`]) is `base · (AMBIENT + (1 − AMBIENT)·max(n·sun, 0))`,
//! clamped to 1, with the sun of [`sun_direction`].
//!
//! # Reproducibility on the GPU
//! Only IEEE-754 f32 multiplication, subtraction, `floor`, `abs` and comparisons are used; each is
//! correctly rounded in WGSL as in Rust, and the style values are uploaded as computed here, so
//! the GPU reproduces the function bit for bit. Two caveats, both confined to the edges of the
//! pattern: a shader compiler may fuse `z·inv − fl(…)` into one FMA (which moves an edge by at
//! most one ulp of `t`), and the rasteriser interpolates `u` and `z` (so a pixel samples a point
//! that differs from the exact ray hit by the interpolation error). The image test compares
//! colours away from pattern edges. Lighting uses `normalize` and `dot`, which are not correctly
//! rounded in WGSL: lit colours agree within 1/255.
//!
//! # Ground
//! [`ground_mesh`] lays the blocks' ground ([`BLOCK_GROUND`]) and then the street layer as strips
//! ([`street_width_m`], [`street_color`]) flat at z = 0. The renderers draw the ground plane
//! ([`GROUND`]), then these, in that order, with the depth test set to always pass (painter's
//! order, no z offsets and so no z-fighting), and the buildings after them with the normal depth
//! test. Ground geometry never takes part in the block-id pass.
//!
//! # Terrain
//! With a terrain ([`crate::visibility::TerrainDraw`]) the ground is no longer z = 0: the
//! renderers then draw neither the ground plane nor the flat ground layers
//! ([`crate::visibility::draws_flat_ground`] is the one rule; draping them is future work), and
//! draw the terrain's tiles depth-tested, in [`TERRAIN`] lit by [`shade`] with the normal of each
//! triangle's first vertex (flat, as buildings). In id frames terrain carries
//! [`crate::visibility::TERRAIN_ID`], never a block.

mod ground;
mod streets;
mod style;
#[cfg(test)]
mod tests;

pub use ground::*;
pub use streets::*;
pub use style::*;

use glam::{DVec3, Vec3};

/// Ambient share of the light (the rest is the sun's Lambert term).
pub const AMBIENT: f32 = 0.35;
/// Ground floor: the facade colour times this.
pub const GROUND_FLOOR_SHADE: f32 = 0.75;
/// Window band of upper storeys, as fractions of the storey height: sill and lintel.
pub const SILL: f32 = 0.3125;
/// See [`SILL`].
pub const LINTEL: f32 = 0.8125;
/// Window band of the ground floor (shop fronts: taller).
pub const GROUND_SILL: f32 = 0.125;
/// See [`GROUND_SILL`].
pub const GROUND_LINTEL: f32 = 0.8125;
// The constants of the pattern are exact binary fractions, so that the shader (which receives
// them as WGSL literals written from these values, see `render/mesh.rs`) has the same f32 values
// whatever way its compiler rounds literals.

/// Storey height (m) assumed when a building has no levels attribute.
pub const DEFAULT_STOREY_M: f64 = 3.0;

/// 8-bit colour levels as the f32 the shader sees (`k / 255`, correctly rounded).
pub fn unit_rgb(c: [u8; 3]) -> [f32; 3] {
    c.map(|k| k as f32 / 255.0)
}

fn rgb(r: u8, g: u8, b: u8) -> [f32; 3] {
    unit_rgb([r, g, b])
}

/// The ground plane outside blocks (8-bit levels; [`unit_rgb`] gives the f32 colour).
pub const GROUND: [u8; 3] = [140, 148, 128];
/// The ground of a block (yards, pavements): greyer than [`GROUND`].
pub const BLOCK_GROUND: [u8; 3] = [158, 156, 142];
/// Terrain ([`crate::visibility::TerrainDraw`]): lit by [`shade`] with the terrain's normals;
/// `mesh.wgsl` gets it from `render/mesh.rs`, printed from this value.
pub const TERRAIN: [u8; 3] = [126, 142, 98];
/// Undersides of raised parts (facing down).
pub const UNDERSIDE: [u8; 3] = [89, 89, 89];
/// The sky (clear colour of lit frames).
pub const SKY: [u8; 3] = [158, 196, 237];

/// Unit direction towards the sun (from the south-east, 50° up): the one light of [`shade`].
pub fn sun_direction() -> Vec3 {
    DVec3::new(0.5, -0.6, 1.3).normalize().as_vec3()
}

/// Lit colour: `base · (AMBIENT + (1 − AMBIENT)·max(n·sun, 0))`, each channel at most 1
/// (`mesh.wgsl`'s `fs_main`).
pub fn shade(base: [f32; 3], normal: Vec3) -> [f32; 3] {
    let light = AMBIENT + (1.0 - AMBIENT) * normal.dot(sun_direction()).max(0.0);
    base.map(|c| (c * light).min(1.0))
}

/// A colour in `[0, 1]` as the 8-bit levels an `Rgba8Unorm` target stores (round to nearest).
pub fn to_rgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}
