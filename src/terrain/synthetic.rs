//! Synthetic terrains for tests and benches: a plane, a cliff, a cone, smooth random hills.

use super::Terrain;
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The grid of a synthetic terrain: `nx × ny` nodes `spacing_m` apart, node (0, 0) at `origin`
/// (world metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Nodes west to east (≥ 2).
    pub nx: usize,
    /// Nodes south to north (≥ 2).
    pub ny: usize,
    /// Node spacing, metres (> 0).
    pub spacing_m: f64,
    /// World position of node (0, 0).
    pub origin: DVec2,
}

impl GridSpec {
    /// A grid spec.
    pub fn new(nx: usize, ny: usize, spacing_m: f64, origin: DVec2) -> Self {
        Self {
            nx,
            ny,
            spacing_m,
            origin,
        }
    }
}

/// A synthetic surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Synthetic {
    /// The same height everywhere.
    Flat {
        /// Height, metres.
        height_m: f64,
    },
    /// A plane rising at `slope_deg` towards `azimuth_deg` (counter-clockwise from east), at
    /// `base_m` over the origin.
    Plane {
        /// Slope, degrees from horizontal.
        slope_deg: f64,
        /// Direction of steepest ascent, degrees counter-clockwise from east.
        azimuth_deg: f64,
        /// Height at the grid's origin, metres.
        base_m: f64,
    },
    /// `low_m` on columns `0 ..= column`, `low_m + step_m` from column `column + 1` on: a step
    /// of `step_m` between two columns of nodes (one cell wide on the bilinear surface).
    Cliff {
        /// The last low column.
        column: usize,
        /// Height of the low side, metres.
        low_m: f64,
        /// The step, metres.
        step_m: f64,
    },
    /// A cone with its apex at the grid's centre: `height_m` there, falling at `slope_deg` to
    /// 0 and flat beyond.
    Cone {
        /// Apex height, metres.
        height_m: f64,
        /// Flank slope, degrees.
        slope_deg: f64,
    },
    /// Smooth random hills: a sum of 12 sinusoids of random direction, wavelength (8 to 120
    /// cells) and phase, scaled to about `relief_m` from the lowest to the highest point
    /// (seeded, deterministic).
    Smooth {
        /// The seed.
        seed: u64,
        /// Roughly the height range, metres.
        relief_m: f64,
    },
}

impl Terrain {
    /// A synthetic terrain on `grid`.
    ///
    /// # Panics
    /// When `grid` has fewer than 2 × 2 nodes or a spacing that is not finite and positive.
    pub fn synthetic(grid: GridSpec, kind: Synthetic) -> Terrain {
        let sp = grid.spacing_m;
        let centre = DVec2::new(
            (grid.nx - 1) as f64 * sp * 0.5,
            (grid.ny - 1) as f64 * sp * 0.5,
        );
        let waves: Vec<(DVec2, f64, f64)> = match kind {
            Synthetic::Smooth { seed, .. } => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                (0..12)
                    .map(|_| {
                        let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                        let wl = rng.random_range(8.0..120.0) * sp;
                        let ph: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                        let amp = rng.random_range(0.3..1.0);
                        (
                            DVec2::new(a.cos(), a.sin()) * (std::f64::consts::TAU / wl),
                            ph,
                            amp,
                        )
                    })
                    .collect()
            }
            _ => Vec::new(),
        };
        let amp_sum: f64 = waves.iter().map(|w| w.2).sum::<f64>().max(1e-9);
        let mut heights = Vec::with_capacity(grid.nx * grid.ny);
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let p = DVec2::new(i as f64 * sp, j as f64 * sp);
                let h = match kind {
                    Synthetic::Flat { height_m } => height_m,
                    Synthetic::Plane {
                        slope_deg,
                        azimuth_deg,
                        base_m,
                    } => {
                        let a = azimuth_deg.to_radians();
                        base_m + slope_deg.to_radians().tan() * p.dot(DVec2::new(a.cos(), a.sin()))
                    }
                    Synthetic::Cliff {
                        column,
                        low_m,
                        step_m,
                    } => {
                        if i <= column {
                            low_m
                        } else {
                            low_m + step_m
                        }
                    }
                    Synthetic::Cone {
                        height_m,
                        slope_deg,
                    } => (height_m - slope_deg.to_radians().tan() * (p - centre).length()).max(0.0),
                    Synthetic::Smooth { relief_m, .. } => {
                        let s: f64 = waves
                            .iter()
                            .map(|(k, ph, amp)| amp * (k.dot(p) + ph).sin())
                            .sum();
                        relief_m * 0.5 * (1.0 + s / amp_sum)
                    }
                };
                heights.push(h);
            }
        }
        Terrain::from_heights(
            &format!("synthetic {kind:?}"),
            grid.nx,
            grid.ny,
            grid.origin,
            DVec2::splat(sp),
            heights,
        )
        .unwrap_or_else(|e| panic!("synthetic terrain {grid:?}: {e}"))
    }

    /// This terrain with the nodes `f(i, j)` picks set to nodata (holes for tests).
    pub fn with_nodata(mut self, f: impl Fn(usize, usize) -> bool) -> Terrain {
        let nx = self.nx();
        for (k, h) in self.heights_mut().iter_mut().enumerate() {
            if f(k % nx, k / nx) {
                *h = f64::NAN;
            }
        }
        self.refresh_report();
        self
    }
}
