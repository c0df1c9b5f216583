//! Storeys and heights of generated buildings.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::tuning::*;

/// Storeys of one building: a tower with probability [`TOWER_P`], else a log-normal law with
/// median [`MEDIAN_STOREYS`] and log-deviation [`STOREYS_LOG_SIGMA`], clamped to
/// [`STOREYS_CLAMP`].
pub(super) fn storeys(rng: &mut ChaCha8Rng) -> u32 {
    if rng.random::<f64>() < TOWER_P {
        return rng.random_range(TOWER_STOREYS.0..=TOWER_STOREYS.1);
    }
    // Log-normal (Box–Muller).
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    ((MEDIAN_STOREYS.ln() + STOREYS_LOG_SIGMA * z).exp().round() as u32)
        .clamp(STOREYS_CLAMP.0, STOREYS_CLAMP.1)
}

/// Height of a building of `levels` storeys of `storey_m` metres, with a roof allowance drawn
/// from [`ROOF_EXTRA_M`], rounded to centimetres.
pub(super) fn height_m(rng: &mut ChaCha8Rng, levels: u32, storey_m: f64) -> f64 {
    round_cm(levels as f64 * storey_m + rng.random_range(ROOF_EXTRA_M.0..ROOF_EXTRA_M.1))
}

/// `v` rounded to `1 / HEIGHT_ROUNDING` metres.
pub(super) fn round_cm(v: f64) -> f64 {
    (v * HEIGHT_ROUNDING).round() / HEIGHT_ROUNDING
}
