//! The reference caster of relief impostors (Andujar et al., §5.2), written once over
//! [`Real`] and run in `f32` (operation for operation as `render/relief.wgsl`) and `f64` (the
//! twin, whose margin names the ties).
//!
//! **Texture space** of a node: `x, y ∈ [0, M]` texels of its zenithal map, `z ∈ [0, 1]` over the
//! node's height range; a texel's column rises to `q/65535` (`q` its stored height, 0 for
//! none).
//!
//! **The walk cannot miss a hit.** The paper's prototype finds the ray–height-field intersection
//! by a linear search refined by a binary search, which steps over thin columns; the paper
//! points to pyramidal displacement mapping (Oh, Ki and Lee) as the exact alternative. This is
//! that traversal over the map's max pyramid ([`super::map::ReliefMap::pyramid`]): from the
//! one-texel top level down, a cell whose highest column lies below the ray all across the cell
//! (the ray's height is linear in `t`, so its minimum over the cell is at an end) is skipped
//! whole; otherwise the walk descends, and at level 0 a column the ray reaches below its top is
//! a hit: on the side the ray entered through when it is already below the top there (a
//! wall), else where it comes down to the top (a roof). Cells are tracked as integers: a step
//! to the next cell moves the exit axis by one cell and clamps the other axis into the current
//! cell, so a rounding at a boundary can never send the walk back. After a skip the walk rises a
//! level whenever it has left the parent cell. The exact result in `f64` and the `f32` result
//! agree except where the ray passes within rounding of a cell corner or a column top (a tie).
//!
//! **Horizon nodes** (the node's height projects to fewer than two pixels, §5.2) are drawn as a
//! flat quad at mid height: the ray's crossing with `z = z_max/2` over a covered texel.

use crate::blockmap::cast::{Real, TexRay};
use serde::Serialize;

/// Which surface a ray met.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Face {
    /// The top of a column (roof or ground-level cover): coloured from the zenithal map.
    Top,
    /// A side of a column, normal ±x.
    WallX,
    /// A side of a column, normal ±y.
    WallY,
    /// The ray starts inside a column (the eye inside the height field).
    Inside,
    /// The flat quad of a horizon node.
    Flat,
}

/// What a ray met.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Hit {
    /// Ray parameter.
    pub t: f64,
    /// The column `(i, j)` hit.
    pub cell: [u32; 2],
    /// Which of its surfaces.
    pub face: Face,
}

/// The result of one cast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cast {
    /// The first surface met, if any.
    pub hit: Option<Hit>,
    /// Loop iterations.
    pub steps: u32,
    /// The smallest margin met (texels, or height units): how near the ray came to a decision's
    /// boundary. Small margins are ties.
    pub margin: f64,
}

impl Cast {
    /// True when the twin should not be compared exactly: a margin below `tol`.
    pub fn is_tie(&self, tol: f64) -> bool {
        self.margin < tol
    }
}

/// Iterations after which a walk is abandoned as a miss: more than any exact walk needs (each
/// cell of each level is visited at most once per pass through it).
pub fn step_limit(m: u32) -> u32 {
    let levels = m.max(1).ilog2() + 1;
    8 * m * levels + 64
}

/// The largest height of the node (`z_max` of the box) in texture units: the pyramid's top.
pub fn top_height<T: Real>(levels: &[&[u16]]) -> T {
    let q = levels.last().and_then(|l| l.first()).copied().unwrap_or(0);
    T::of(f64::from(q)) / T::of(65535.0)
}

/// The GPU's cast, in `f32`.
pub fn cast_f32(levels: &[&[u16]], m: u32, ray: &TexRay<f32>) -> Cast {
    cast_generic(levels, m, ray)
}

/// The `f64` twin of [`cast_f32`].
pub fn cast_f64(levels: &[&[u16]], m: u32, ray: &TexRay<f64>) -> Cast {
    cast_generic(levels, m, ray)
}

fn floor_i<T: Real>(v: T) -> i64 {
    let f = v.floor().to64();
    if f.is_finite() {
        f.clamp(-1e15, 1e15) as i64
    } else {
        0
    }
}

/// The walk (see the module doc).
pub fn cast_generic<T: Real>(levels: &[&[u16]], m: u32, ray: &TexRay<T>) -> Cast {
    let mut margin = f64::INFINITY;
    let miss = |steps, margin| Cast {
        hit: None,
        steps,
        margin,
    };
    if levels.is_empty() || m == 0 {
        return miss(0, margin);
    }
    let mf = T::of(f64::from(m));
    // The box's top lies a height quantum above the highest column, so that a ray entering
    // through it starts strictly above every column top (were it level with the highest, the
    // rounding of the entry point could decide whether the ray is above or below it).
    let zbox: T = top_height::<T>(levels) + T::of(1.0 / 65535.0);
    let [ox, oy, oz] = ray.o;
    let [dx, dy, dz] = ray.d;
    // Slabs: x, y ∈ [0, M], z ∈ [0, zbox].
    let mut t0 = -T::INF;
    let mut t1 = T::INF;
    let mut entry_axis = 3usize; // 3: the ray starts inside the box
    for (a, (o, d, hi)) in [(ox, dx, mf), (oy, dy, mf), (oz, dz, zbox)]
        .into_iter()
        .enumerate()
    {
        if d == T::ZERO {
            if o < T::ZERO || o > hi {
                return miss(0, margin);
            }
            continue;
        }
        let ta = (T::ZERO - o) / d;
        let tb = (hi - o) / d;
        let (lo, up) = if ta < tb { (ta, tb) } else { (tb, ta) };
        if lo > t0 {
            t0 = lo;
            entry_axis = a;
        }
        if up < t1 {
            t1 = up;
        }
    }
    let mut face = match entry_axis {
        0 => Face::WallX,
        1 => Face::WallY,
        2 => Face::Top,
        _ => Face::Inside,
    };
    if t0 < T::ZERO {
        t0 = T::ZERO;
        face = Face::Inside;
    }
    if t0.partial_cmp(&t1).is_none_or(|o| o.is_gt()) {
        return miss(0, margin);
    }
    margin = margin.min((t1 - t0).abs().to64());
    let top = levels.len() - 1;
    let mi = i64::from(m);
    let start = |o: T, d: T, t: T| -> i64 {
        let p = o + d * t;
        let mut i = floor_i(p);
        if d < T::ZERO && p.floor() == p {
            i -= 1;
        }
        i.clamp(0, mi - 1)
    };
    let mut ix = start(ox, dx, t0);
    let mut iy = start(oy, dy, t0);
    let mut level = top;
    let mut t = t0;
    let limit = step_limit(m);
    let q_scale = T::of(65535.0);
    let mut steps = 0u32;
    while steps < limit {
        steps += 1;
        let size = 1i64 << level;
        let (cx, cy) = (ix >> level, iy >> level);
        let side = (mi >> level).max(1);
        let q = levels[level][(cy * side + cx) as usize];
        let x_lo = T::of((cx * size) as f64);
        let x_hi = T::of(((cx + 1) * size) as f64);
        let y_lo = T::of((cy * size) as f64);
        let y_hi = T::of(((cy + 1) * size) as f64);
        let tx = if dx > T::ZERO {
            (x_hi - ox) / dx
        } else if dx < T::ZERO {
            (x_lo - ox) / dx
        } else {
            T::INF
        };
        let ty = if dy > T::ZERO {
            (y_hi - oy) / dy
        } else if dy < T::ZERO {
            (y_lo - oy) / dy
        } else {
            T::INF
        };
        let te = tx.mn(ty).mn(t1);
        let h = T::of(f64::from(q)) / q_scale;
        let zt = oz + dz * t;
        let ze = oz + dz * te;
        if q != 0 {
            margin = margin.min((zt - h).abs().to64()).min((ze - h).abs().to64());
        }
        let below = q != 0 && !(zt > h && ze > h);
        if below && level > 0 {
            level -= 1;
            continue;
        }
        if below {
            // A column the ray reaches below its top.
            let cell = [ix as u32, iy as u32];
            if zt <= h {
                return Cast {
                    hit: Some(Hit {
                        t: t.to64(),
                        cell,
                        face,
                    }),
                    steps,
                    margin,
                };
            }
            let th = (h - oz) / dz;
            return Cast {
                hit: Some(Hit {
                    t: th.to64(),
                    cell,
                    face: Face::Top,
                }),
                steps,
                margin,
            };
        }
        // Skip the cell.
        if te.partial_cmp(&t1).is_none_or(|o| o.is_ge()) {
            return miss(steps, margin);
        }
        margin = margin.min((tx - ty).abs().to64());
        t = te;
        let (step_x, step_y) = (tx <= ty, ty <= tx);
        if step_x {
            ix = if dx > T::ZERO {
                (cx + 1) * size
            } else {
                cx * size - 1
            };
            face = Face::WallX;
        } else {
            ix = floor_i(ox + dx * t).clamp(cx * size, (cx + 1) * size - 1);
        }
        if step_y {
            iy = if dy > T::ZERO {
                (cy + 1) * size
            } else {
                cy * size - 1
            };
            face = Face::WallY;
        } else {
            iy = floor_i(oy + dy * t).clamp(cy * size, (cy + 1) * size - 1);
        }
        if ix < 0 || iy < 0 || ix >= mi || iy >= mi {
            return miss(steps, margin);
        }
        if level < top && ((ix >> (level + 1)) != (cx >> 1) || (iy >> (level + 1)) != (cy >> 1)) {
            level += 1;
        }
    }
    miss(steps, margin)
}

/// The flat quad of a horizon node: the crossing of the ray with `z = z_max/2` over a covered
/// texel of level 0.
pub fn cast_flat<T: Real>(levels: &[&[u16]], m: u32, ray: &TexRay<T>) -> Cast {
    let mut out = Cast {
        hit: None,
        steps: 1,
        margin: f64::INFINITY,
    };
    let zmax: T = top_height(levels);
    let zf = zmax * T::of(0.5);
    let [ox, oy, oz] = ray.o;
    let [dx, dy, dz] = ray.d;
    if dz == T::ZERO || levels.is_empty() {
        return out;
    }
    let t = (zf - oz) / dz;
    if t < T::ZERO {
        return out;
    }
    let (x, y) = (ox + dx * t, oy + dy * t);
    let mf = T::of(f64::from(m));
    if !(x >= T::ZERO && y >= T::ZERO && x < mf && y < mf) {
        return out;
    }
    let (i, j) = (floor_i(x), floor_i(y));
    let frac = |v: T| {
        let f = (v - v.floor()).to64();
        f.min(1.0 - f)
    };
    out.margin = frac(x).min(frac(y));
    if levels[0][(j * i64::from(m) + i) as usize] != 0 {
        out.hit = Some(Hit {
            t: t.to64(),
            cell: [i as u32, j as u32],
            face: Face::Flat,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::relief::map::{MapFrame, MapKind, ReliefMap};
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    fn map_of(m: u32, depth: Vec<u16>) -> ReliefMap {
        ReliefMap {
            kind: MapKind::Zenithal,
            frame: MapFrame::zenithal(DVec3::ZERO, DVec3::new(1.0, 1.0, 1.0), m),
            color: vec![[0; 4]; depth.len()],
            depth,
        }
    }

    /// The exact first hit of a ray with a column field, by brute force over every column
    /// (each a box `[i, i+1] × [j, j+1] × [0, h]`), in f64.
    fn brute(depth: &[u16], m: u32, ray: &TexRay<f64>) -> Option<f64> {
        let mut best: Option<f64> = None;
        for j in 0..m {
            for i in 0..m {
                let q = depth[(j * m + i) as usize];
                if q == 0 {
                    continue;
                }
                let h = f64::from(q) / 65535.0;
                let lo = [i as f64, j as f64, 0.0];
                let hi = [i as f64 + 1.0, j as f64 + 1.0, h];
                let (mut a, mut b) = (0.0f64, f64::INFINITY);
                let mut ok = true;
                for k in 0..3 {
                    let (o, d) = (ray.o[k], ray.d[k]);
                    if d == 0.0 {
                        if o < lo[k] || o > hi[k] {
                            ok = false;
                        }
                        continue;
                    }
                    let (u, v) = ((lo[k] - o) / d, (hi[k] - o) / d);
                    a = a.max(u.min(v));
                    b = b.min(u.max(v));
                }
                if ok && a <= b && best.is_none_or(|x| a < x) {
                    best = Some(a);
                }
            }
        }
        best
    }

    #[test]
    fn the_pyramid_walk_finds_the_first_column_brute_force_finds() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut ties = 0;
        let mut hits = 0;
        let mut checked = 0;
        for case in 0..60 {
            let m = [4u32, 8, 16, 32][case % 4];
            let fill = rng.random_range(0.02..0.5);
            let depth: Vec<u16> = (0..m * m)
                .map(|_| {
                    if rng.random_bool(fill) {
                        rng.random_range(1..=65535)
                    } else {
                        0
                    }
                })
                .collect();
            let map = map_of(m, depth.clone());
            let pyramid = map.pyramid();
            let levels: Vec<&[u16]> = pyramid.iter().map(|l| l.as_slice()).collect();
            for _ in 0..200 {
                let mf = f64::from(m);
                let o = [
                    rng.random_range(-0.5 * mf..1.5 * mf),
                    rng.random_range(-0.5 * mf..1.5 * mf),
                    rng.random_range(0.2..2.0),
                ];
                let target = [
                    rng.random_range(0.0..mf),
                    rng.random_range(0.0..mf),
                    rng.random_range(0.0..0.8),
                ];
                let d = [0, 1, 2].map(|k| target[k] - o[k]);
                let ray = TexRay { o, d };
                let c = cast_f64(&levels, m, &ray);
                let truth = brute(&depth, m, &ray);
                checked += 1;
                if c.is_tie(1e-9) {
                    ties += 1;
                    continue;
                }
                match (c.hit, truth) {
                    (None, None) => {}
                    (Some(h), Some(t)) => {
                        hits += 1;
                        assert!((h.t - t).abs() < 1e-9, "case {case}: {h:?} vs {t}");
                    }
                    (a, b) => panic!("case {case}: walk {a:?}, brute force {b:?}, ray {ray:?}"),
                }
            }
        }
        assert!(hits > 2000, "{hits} hits of {checked}");
        assert!(ties * 100 < checked, "{ties} ties of {checked}");
    }

    #[test]
    fn a_thin_column_between_samples_is_not_stepped_over() {
        // One column at texel 20 of 32, grazed at a shallow angle: a linear search with a step
        // of a few texels would pass over it.
        let m = 32;
        let mut depth = vec![0u16; (m * m) as usize];
        depth[(16 * m + 20) as usize] = 30_000;
        let pyramid = map_of(m, depth).pyramid();
        let levels: Vec<&[u16]> = pyramid.iter().map(|l| l.as_slice()).collect();
        let ray = TexRay {
            o: [0.0, 16.5, 0.46],
            d: [1.0, 0.0, -0.001],
        };
        let c = cast_f64(&levels, m, &ray);
        let h = c.hit.expect("hits the column");
        assert_eq!(h.cell, [20, 16]);
        assert_eq!(h.face, Face::WallX);
        assert!((h.t - 20.0).abs() < 1e-12);
        // And from above onto its top.
        let ray = TexRay {
            o: [20.5, 16.5, 2.0],
            d: [0.0, 0.0, -1.0],
        };
        let h = cast_f64(&levels, m, &ray).hit.unwrap();
        assert_eq!(h.face, Face::Top);
        assert!((h.t - (2.0 - 30_000.0 / 65535.0)).abs() < 1e-12);
    }
}
