//! Seeded synthetic cities for benches and tests: a jittered grid of block boxes with
//! realistic sizes and heights, centred on the local origin.

use super::BlockBounds;
use crate::blocks::BlockId;
use crate::geom::Aabb3;
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Distance between block centres along a grid row, metres (a block plus its street).
pub const GRID_PITCH_M: f64 = 100.0;

/// `n` blocks on a jittered square grid (pitch [`GRID_PITCH_M`]): each block 55–85 m wide,
/// its centre moved by up to ±6 m, buildings 6–30 m high with one block in twenty a tower up to
/// 120 m, 200–3000 triangles. Deterministic for a seed; `result[i].id == BlockId(i)`.
///
/// # Units
/// Metres, local frame; the grid is centred on the origin, ground at z = 0.
pub fn block_grid(n: usize, seed: u64) -> Vec<BlockBounds> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let side = (n as f64).sqrt().ceil().max(1.0) as usize;
    let half = side as f64 * GRID_PITCH_M * 0.5;
    (0..n)
        .map(|i| {
            let (gx, gy) = (i % side, i / side);
            let c = DVec2::new(
                gx as f64 * GRID_PITCH_M - half + rng.random_range(-6.0..6.0),
                gy as f64 * GRID_PITCH_M - half + rng.random_range(-6.0..6.0),
            );
            let w = DVec2::new(rng.random_range(55.0..85.0), rng.random_range(55.0..85.0));
            let h = if rng.random_range(0..20) == 0 {
                rng.random_range(40.0..120.0)
            } else {
                rng.random_range(6.0..30.0)
            };
            let lo = c - w * 0.5;
            let hi = c + w * 0.5;
            BlockBounds::from_box(
                BlockId(i as u32),
                Aabb3::new(lo.extend(0.0), DVec3::new(hi.x, hi.y, h)),
                // The outline centroid is not the box centre in general.
                c + DVec2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)),
                rng.random_range(200..3000),
            )
        })
        .collect()
}

/// Side length of the square [`block_grid`] covers, metres.
pub fn grid_extent_m(n: usize) -> f64 {
    (n as f64).sqrt().ceil().max(1.0) * GRID_PITCH_M
}
