//! Ambient occlusion of a BlockMap (Di Benedetto, §4.2.1 stores it in the A channels of the roof/ground
//! section and of the wall columns; §4.3.2 computes it by rendering the occluders from many
//! directions). Here it is horizon-based over the map's own height field, on the CPU:
//!
//! - **Roof and ground texels**: from the texel centre at its height, `ROOF_DIRECTIONS`
//!   azimuths are marched over the height map out to `radius_m`; in each, the horizon's elevation
//!   `α` is the largest `atan((H(q) − H₀)/r)` (never below 0). For a cosine-weighted upper
//!   hemisphere the unoccluded share of a slice with horizon `α` is `cos²α`, so the texel's
//!   openness is the mean of `cos²α` over the azimuths.
//! - **Wall columns**: from the midpoint of each exposed side of the column's texels, at the
//!   height of each colour row (capped at the texel's height), `WALL_DIRECTIONS` azimuths spread
//!   over the half-space in front of the wall are marched the same way. The cosine-weighted share
//!   of the sky above a horizon `α ≥ 0` seen by a vertical wall, relative to an open wall over
//!   flat ground, is `(π/4 − α/2 − sin 2α/4)/(π/4)`; the azimuths are weighted by `cos φ` (φ off
//!   the wall's normal). The ground below the horizon counts as open (the same as over flat
//!   ground), so an unobstructed wall reads 255 like an open roof.
//!
//! Deviations from Di Benedetto, for a CPU build: the occluders are the map's own prisms (Di Benedetto
//! renders "all potential occluders", or those within a fixed radius), so the ground near the
//! map's border misses the occlusion of buildings in other maps; every map computes its own AO
//! instead of computing it at the leaves and inheriting it upwards, because every map here is built
//! from the source prisms (see `tree`).
//!
//! A byte is `round(255·openness)`: 255 is open sky, as in a map without AO.

use super::layout::BlockMap;
use serde::Serialize;

/// Azimuths marched per roof or ground texel.
pub const ROOF_DIRECTIONS: usize = 8;
/// Azimuths marched per exposed side and colour row, over the half-space in front of the wall.
pub const WALL_DIRECTIONS: usize = 5;
/// Most samples along one azimuth.
pub const MAX_STEPS: usize = 16;

/// The AO a construction computed, summarised (the effect of the option).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct AoStats {
    /// Mean openness (0..1) of roof texels.
    pub roof_mean: f64,
    /// Mean openness of ground (empty) texels.
    pub ground_mean: f64,
    /// Mean openness of the wall colour texels in use.
    pub wall_mean: f64,
    /// Share of roof, ground and wall texels darker than 0.9.
    pub occluded_share: f64,
}

/// Height of texel `(i, j)` in metres above `zmin`; 0 for empty texels and outside the map.
fn height_at(map: &BlockMap, i: i64, j: i64) -> f64 {
    map.texel_height_m(i, j).map_or(0.0, |h| h - map.meta.zmin)
}

/// Largest `tan α` of the horizon seen from `(x, y)` (texel units) at height `z0` (metres) along
/// the unit direction `(dx, dy)`, out to `steps` samples `step` texels apart (`s` metres a texel).
#[allow(clippy::too_many_arguments)]
fn horizon_tan(
    map: &BlockMap,
    x: f64,
    y: f64,
    z0: f64,
    dx: f64,
    dy: f64,
    step: f64,
    steps: usize,
    s: f64,
) -> f64 {
    let mut best = 0.0f64;
    for q in 1..=steps {
        let r = step * q as f64;
        let h = height_at(
            map,
            (x + dx * r).floor() as i64,
            (y + dy * r).floor() as i64,
        );
        best = best.max((h - z0) / (r * s));
    }
    best
}

/// March parameters for a map: (step in texels, steps).
fn march(map: &BlockMap, radius_m: f64) -> (f64, usize) {
    let s = map.texel_m();
    let r = (radius_m / s).max(1.0); // at least one texel
    let steps = ((2.0 * r).ceil() as usize).clamp(1, MAX_STEPS); // half-texel steps when it fits
    (r / steps as f64, steps)
}

/// Openness of a vertical wall slice whose horizon has elevation `α` (radians, ≥ 0), relative to
/// an open wall: `(π/4 − α/2 − sin 2α/4)/(π/4)`.
fn wall_open(alpha: f64) -> f64 {
    use std::f64::consts::FRAC_PI_4;
    ((FRAC_PI_4 - alpha / 2.0 - (2.0 * alpha).sin() / 4.0) / FRAC_PI_4).clamp(0.0, 1.0)
}

fn to_byte(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Computes the AO of `map` in place (roof/ground section A and wall colour A) from its height
/// map, out to `radius_m` around each sample. `exposed[j·K + i]` holds the lower sides of each
/// texel (bit `s` for side `s` of `(−x, +x, −y, +y)`), as construction found them.
pub fn compute(map: &mut BlockMap, exposed: &[u8], radius_m: f64) -> AoStats {
    let k = map.k();
    let kk = k as usize;
    let s = map.texel_m();
    let (step, steps) = march(map, radius_m);
    let mut st = AoStats::default();
    let (mut n_roof, mut n_ground, mut n_dark) = (0usize, 0usize, 0usize);
    let dirs: Vec<(f64, f64)> = (0..ROOF_DIRECTIONS)
        .map(|a| {
            let t = std::f64::consts::TAU * (a as f64 + 0.5) / ROOF_DIRECTIONS as f64;
            (t.cos(), t.sin())
        })
        .collect();
    // Roof and ground.
    let mut roof_ao = vec![255u8; kk * kk];
    for j in 0..k {
        for i in 0..k {
            let h0 = height_at(map, i as i64, j as i64);
            let (x, y) = (i as f64 + 0.5, j as f64 + 0.5);
            let mut open = 0.0;
            for &(dx, dy) in &dirs {
                let t = horizon_tan(map, x, y, h0, dx, dy, step, steps, s);
                open += 1.0 / (1.0 + t * t); // cos²α
            }
            open /= ROOF_DIRECTIONS as f64;
            if map.height_code(i, j) > 0 {
                st.roof_mean += open;
                n_roof += 1;
            } else {
                st.ground_mean += open;
                n_ground += 1;
            }
            n_dark += usize::from(open < 0.9);
            roof_ao[j as usize * kk + i as usize] = to_byte(open);
        }
    }
    for j in 0..k {
        for i in 0..k {
            map.texel_mut(k + i, j)[3] = roof_ao[j as usize * kk + i as usize];
        }
    }
    // Walls: per (slice, offset), the summed openness per colour row and the count.
    let rows = map.slice_rows();
    let colour_rows = (rows - 1) as usize;
    let slices = map.meta.slices as usize;
    let mut sum = vec![0f64; slices * 255 * colour_rows];
    let mut cnt = vec![0u32; slices * 255 * colour_rows];
    let zspan = map.meta.zmax - map.meta.zmin;
    const SIDES: [(i64, i64); 4] = [(-1, 0), (1, 0), (0, -1), (0, 1)];
    let wall_dirs: Vec<(f64, f64, f64)> = (0..WALL_DIRECTIONS)
        .map(|a| {
            // φ spread over (−90°, 90°) around the normal, weight cos φ.
            let phi = std::f64::consts::PI * ((a as f64 + 0.5) / WALL_DIRECTIONS as f64 - 0.5);
            (phi.cos(), phi.sin(), phi.cos())
        })
        .collect();
    let wsum: f64 = wall_dirs.iter().map(|d| d.2).sum();
    for j in 0..k {
        for i in 0..k {
            let t = j as usize * kk + i as usize;
            let off = map.wall_offset(i, j);
            if off == 0 || exposed[t] == 0 {
                continue;
            }
            let h0 = height_at(map, i as i64, j as i64);
            let slice = map.slice_of_row(j) as usize;
            for (sidx, (di, dj)) in SIDES.iter().enumerate() {
                if exposed[t] & (1 << sidx) == 0 {
                    continue;
                }
                let (nx, ny) = (*di as f64, *dj as f64);
                // Just outside the side's midpoint.
                let (x, y) = (
                    i as f64 + 0.5 + nx * (0.5 + 1e-6),
                    j as f64 + 0.5 + ny * (0.5 + 1e-6),
                );
                for r in 0..colour_rows {
                    let z = ((r as f64 + 0.5) / colour_rows as f64 * zspan).min(h0);
                    let mut open = 0.0;
                    for &(c, sn, w) in &wall_dirs {
                        // Rotate the normal by φ.
                        let (dx, dy) = (nx * c - ny * sn, nx * sn + ny * c);
                        let tn = horizon_tan(map, x, y, z, dx, dy, step, steps, s);
                        open += w * wall_open(tn.atan());
                    }
                    let slot = (slice * 255 + off as usize - 1) * colour_rows + r;
                    sum[slot] += open / wsum;
                    cnt[slot] += 1;
                }
            }
        }
    }
    let mut n_wall = 0usize;
    for slice in 0..slices {
        for off in 1..=255u8 {
            let u = map.wall_u(off);
            for r in 0..colour_rows {
                let slot = (slice * 255 + off as usize - 1) * colour_rows + r;
                if cnt[slot] == 0 {
                    continue;
                }
                let open = sum[slot] / cnt[slot] as f64;
                st.wall_mean += open;
                n_wall += 1;
                n_dark += usize::from(open < 0.9);
                map.texel_mut(u, (slice * rows as usize + r) as u32)[3] = to_byte(open);
            }
        }
    }
    st.roof_mean /= n_roof.max(1) as f64;
    st.ground_mean /= n_ground.max(1) as f64;
    st.wall_mean /= n_wall.max(1) as f64;
    if n_roof == 0 {
        st.roof_mean = 1.0;
    }
    if n_ground == 0 {
        st.ground_mean = 1.0;
    }
    if n_wall == 0 {
        st.wall_mean = 1.0;
    }
    st.occluded_share = n_dark as f64 / (n_roof + n_ground + n_wall).max(1) as f64;
    st
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn open_ground_is_255_and_a_courtyard_is_darker() {
        let mut m = BlockMap::empty(32, DVec3::ZERO, 64.0, 30.0).unwrap();
        // A ring of 30 m walls around texel (16, 16), one texel thick.
        for j in 14..=18u32 {
            for i in 14..=18u32 {
                if i == 14 || i == 18 || j == 14 || j == 18 {
                    m.texel_mut(i, j)[0] = 255;
                }
            }
        }
        let exposed = vec![0u8; 32 * 32];
        let st = compute(&mut m, &exposed, 20.0);
        assert_eq!(m.texel(32 + 2, 2)[3], 255, "far from the walls");
        let court = m.texel(32 + 16, 16)[3];
        // The walls stand 4 m away (2 texels of 2 m) and 30 m high: α ≈ 82°, cos² ≈ 0.02.
        assert!(court < 20, "courtyard {court}");
        assert!(st.ground_mean < 1.0 && st.roof_mean <= 1.0);
    }

    #[test]
    fn wall_openness_ends() {
        assert!((wall_open(0.0) - 1.0).abs() < 1e-12);
        assert!(wall_open(std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(wall_open(0.3) > wall_open(0.6));
    }
}
