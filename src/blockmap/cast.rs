//! The reference ray caster: the exact 2D grid walk (Amanatides & Woo) over the height map that
//! the GPU runs (Di Benedetto, §4.2.2; BLOCKMAPS.md A.5), written once over a [`Real`] type and run in
//! `f32` (operation for operation as the WGSL shader) and in `f64` (the twin, which also flags
//! rays that pass within a tolerance of a cell corner, a height level or the box's exit, where the
//! two may legitimately differ).
//!
//! Texture space: x, y ∈ [0, K] in texels, z ∈ [0, 1] over `[zmin, zmax]`. A ray `o + t·d` keeps
//! its parameter `t` from the world: `t` is a world distance when the world direction is unit.

use super::layout::BlockMap;
use glam::{DVec3, Vec3};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic the caster needs; implemented for `f32` (the GPU's precision) and `f64`.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// +∞.
    const INF: Self;
    /// Rounded conversion.
    fn of(v: f64) -> Self;
    /// Widening conversion.
    fn to64(self) -> f64;
    /// ⌊x⌋.
    fn floor(self) -> Self;
    /// |x|.
    fn abs(self) -> Self;
    /// min (IEEE `min` as WGSL's).
    fn mn(self, o: Self) -> Self;
    /// max.
    fn mx(self, o: Self) -> Self;
}

macro_rules! real {
    ($t:ty) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const INF: Self = <$t>::INFINITY;
            #[inline]
            fn of(v: f64) -> Self {
                v as $t
            }
            #[inline]
            fn to64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn floor(self) -> Self {
                <$t>::floor(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn mn(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline]
            fn mx(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
        }
    };
}
real!(f32);
real!(f64);

/// The side of a texel's prism a wall hit lies on (the face's outward normal).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Face {
    /// Normal −x.
    West,
    /// Normal +x.
    East,
    /// Normal −y.
    South,
    /// Normal +y.
    North,
    /// The ray starts inside a prism (eye inside, or below the ground): hit at its start.
    Inside,
    /// The footprint edge stored for the texel (the side of its half-plane, see
    /// [`super::layout::Edge`]); its normal is the edge's, read from the map by [`surface`].
    Edge,
    /// The texel's second footprint edge ([`BlockMap::edge2`]).
    Edge2,
}

impl Face {
    /// Outward normal of the face (up for [`Face::Inside`]).
    pub fn normal(self) -> Vec3 {
        match self {
            Face::West => Vec3::NEG_X,
            Face::East => Vec3::X,
            Face::South => Vec3::NEG_Y,
            Face::North => Vec3::Y,
            Face::Inside | Face::Edge | Face::Edge2 => Vec3::Z,
        }
    }
}

/// What a ray met.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hit {
    /// Left the box without meeting a prism.
    Miss,
    /// The top of texel `(i, j)` at parameter `t`.
    Roof {
        /// Column.
        i: u32,
        /// Row.
        j: u32,
        /// Ray parameter.
        t: f64,
    },
    /// A side of texel `(i, j)` at parameter `t`.
    Wall {
        /// Column.
        i: u32,
        /// Row.
        j: u32,
        /// Which side.
        face: Face,
        /// Ray parameter.
        t: f64,
    },
}

impl Hit {
    /// Ray parameter of a hit.
    pub fn t(&self) -> Option<f64> {
        match *self {
            Hit::Miss => None,
            Hit::Roof { t, .. } | Hit::Wall { t, .. } => Some(t),
        }
    }
    /// Texel of a hit.
    pub fn texel(&self) -> Option<(u32, u32)> {
        match *self {
            Hit::Miss => None,
            Hit::Roof { i, j, .. } | Hit::Wall { i, j, .. } => Some((i, j)),
        }
    }
}

/// The result of one cast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cast {
    /// What the ray met.
    pub hit: Hit,
    /// Grid cells visited (loop iterations).
    pub steps: u32,
    /// The smallest margin met on the way (texels or z ∈ [0, 1] units): how close the ray came
    /// to a cell corner, a height level, or the box's exit. Small margins are ties.
    pub margin: f64,
}

impl Cast {
    /// True when the twin should not be compared exactly: a margin below `tol`.
    pub fn is_tie(&self, tol: f64) -> bool {
        self.margin < tol
    }
}

/// Options of a cast.
#[derive(Clone, Copy, Debug, Default)]
pub struct CastOptions<'a> {
    /// The distance map ([`BlockMap::distance_map`]) for space leaping (Cignoni et al., §3.2); `None`
    /// runs the plain grid walk (Di Benedetto, §4.2.2).
    pub leap: Option<&'a [u8]>,
}

/// A ray in texture space (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexRay<T> {
    /// Origin (x, y texels; z ∈ [0, 1]).
    pub o: [T; 3],
    /// Direction.
    pub d: [T; 3],
}

impl BlockMap {
    /// A world ray (local frame, f64) in this map's texture space, same parameter `t`.
    pub fn tex_ray(&self, origin: DVec3, dir: DVec3) -> TexRay<f64> {
        let s = self.texel_m();
        let hz = self.meta.zmax - self.meta.zmin;
        let m = self.meta.min;
        TexRay {
            o: [
                (origin.x - m[0]) / s,
                (origin.y - m[1]) / s,
                (origin.z - self.meta.zmin) / hz,
            ],
            d: [dir.x / s, dir.y / s, dir.z / hz],
        }
    }

    /// The point at parameter `t` of a texture-space ray, in the local frame (metres): the
    /// inverse of [`Self::tex_ray`]'s mapping.
    pub fn local_point(&self, ray: &TexRay<f64>, t: f64) -> DVec3 {
        let s = self.texel_m();
        let hz = self.meta.zmax - self.meta.zmin;
        let q = [0, 1, 2].map(|a| ray.o[a] + ray.d[a] * t);
        DVec3::new(
            self.meta.min[0] + q[0] * s,
            self.meta.min[1] + q[1] * s,
            self.meta.zmin + q[2] * hz,
        )
    }
}

impl TexRay<f64> {
    /// The same ray rounded to `f32`, as the vertex shader hands it to the fragment shader.
    pub fn to_f32(self) -> TexRay<f32> {
        TexRay {
            o: self.o.map(|v| v as f32),
            d: self.d.map(|v| v as f32),
        }
    }
}

/// The GPU's cast, in `f32`.
pub fn cast_f32(map: &BlockMap, ray: &TexRay<f32>, opts: &CastOptions) -> Cast {
    cast_generic(map, ray, opts)
}

/// The `f64` twin of [`cast_f32`]: same operations; its [`Cast::margin`] names the ties.
pub fn cast_f64(map: &BlockMap, ray: &TexRay<f64>, opts: &CastOptions) -> Cast {
    cast_generic(map, ray, opts)
}

/// Cell and next-boundary state of the walk.
struct Walk<T> {
    i: i64,
    j: i64,
    t_max_x: T,
    t_max_y: T,
}

fn start_cell<T: Real>(ray: &TexRay<T>, t: T, k: i64, step: [i64; 2]) -> Walk<T> {
    let [ox, oy, _] = ray.o;
    let [dx, dy, _] = ray.d;
    let px = ox + t * dx;
    let py = oy + t * dy;
    let i = (px.floor().to64() as i64).clamp(0, k - 1);
    let j = (py.floor().to64() as i64).clamp(0, k - 1);
    let next = |c: i64, s: i64, o: T, d: T| -> T {
        if s > 0 {
            (T::of((c + 1) as f64) - o) / d
        } else if s < 0 {
            (T::of(c as f64) - o) / d
        } else {
            T::INF
        }
    };
    Walk {
        i,
        j,
        t_max_x: next(i, step[0], ox, dx),
        t_max_y: next(j, step[1], oy, dy),
    }
}

fn cast_generic<T: Real>(map: &BlockMap, ray: &TexRay<T>, opts: &CastOptions) -> Cast {
    let k = map.k() as i64;
    let kt = T::of(k as f64);
    let hi = [kt, kt, T::ONE];
    let mut margin = f64::INFINITY;
    let miss = |steps, margin| Cast {
        hit: Hit::Miss,
        steps,
        margin,
    };
    // Slab test: [t_near, t_far] and the axis of entry (Di Benedetto, §4.2.2 step (d): the longest
    // the ray can travel in the box, so the loop needs no box test).
    let mut t_near = -T::INF;
    let mut t_far = T::INF;
    let mut entry_axis = 3usize;
    let mut near_list = [f64::NEG_INFINITY; 3];
    for a in 0..3 {
        let (o, d) = (ray.o[a], ray.d[a]);
        if d == T::ZERO {
            if o < T::ZERO || o > hi[a] {
                return miss(0, margin);
            }
            continue;
        }
        let ta = (T::ZERO - o) / d;
        let tb = (hi[a] - o) / d;
        let (lo, up) = if ta < tb { (ta, tb) } else { (tb, ta) };
        near_list[a] = lo.to64();
        if lo > t_near {
            t_near = lo;
            entry_axis = a;
        }
        t_far = t_far.mn(up);
    }
    let t0 = t_near.mx(T::ZERO);
    let t1 = t_far;
    if t0 >= t1 {
        return miss(0, margin);
    }
    let eye_inside = t_near <= T::ZERO;
    if !eye_inside {
        // Tie: two slabs entered at (nearly) the same t: the entry face is ambiguous.
        for (a, tn) in near_list.iter().enumerate() {
            if a != entry_axis {
                let dn = (tn - t_near.to64()).abs() * dir_scale(ray);
                margin = margin.min(dn);
            }
        }
    }
    let step = [sign(ray.d[0]), sign(ray.d[1])];
    let t_delta = [
        if step[0] != 0 {
            T::ONE / ray.d[0].abs()
        } else {
            T::INF
        },
        if step[1] != 0 {
            T::ONE / ray.d[1].abs()
        } else {
            T::INF
        },
    ];
    let mut w = start_cell(ray, t0, k, step);
    // The entry point lies on the entry face's plane by construction; only the other axes can
    // put it near a cell edge.
    margin = margin.min(cell_margin(
        ray,
        t0,
        if eye_inside { 3 } else { entry_axis },
    ));
    // The wall face met when entering the first cell from outside the box.
    let mut face = match (eye_inside, entry_axis) {
        (true, _) => Face::Inside,
        (false, 0) => {
            if step[0] > 0 {
                Face::West
            } else {
                Face::East
            }
        }
        (false, 1) => {
            if step[1] > 0 {
                Face::South
            } else {
                Face::North
            }
        }
        // Through the top (or bottom) of the box: a hit in the first cell is a roof (or inside).
        _ => Face::Inside,
    };
    let entered_top = !eye_inside && entry_axis == 2 && ray.d[2] < T::ZERO;
    let mut t_in = t0;
    let xy_speed = ray.d[0].abs().mx(ray.d[1].abs()).to64();
    let k255 = T::of(255.0);
    let mut steps = 0u32;
    let mut leaped_at = -1i64;
    for _ in 0..(2 * k) {
        steps += 1;
        // Space leap (Cignoni et al., §3.2): from an empty cell at Chebyshev distance D ≥ 2 from any
        // prism, every cell within D − 1 is empty: advance by D − 1 texels in max-norm.
        if let Some(dm) = opts.leap {
            let cell = w.j * k + w.i;
            let dist = dm[cell as usize] as i64;
            if dist >= 2 && xy_speed > 0.0 && leaped_at != cell {
                let t_new = t_in + T::of((dist - 1) as f64) / ray.d[0].abs().mx(ray.d[1].abs());
                if t_new >= t1 {
                    return miss(steps, margin);
                }
                t_in = t_new;
                w = start_cell(ray, t_in, k, step);
                margin = margin.min(cell_margin(ray, t_in, 3));
                leaped_at = w.j * k + w.i;
                face = Face::Inside; // not used: the landing cell is empty
                continue;
            }
        }
        let t_out = w.t_max_x.mn(w.t_max_y).mn(t1);
        let za = ray.o[2] + t_in * ray.d[2];
        let zb = ray.o[2] + t_out * ray.d[2];
        let code = map.height_code(w.i as u32, w.j as u32);
        let h = T::of(code as f64) / k255;
        // A segment wholly above the column misses it whatever its half-planes: they are read
        // only when the segment reaches down to the column's height (as the shader does).
        let [edge, edge2] = if code > 0 && za.mn(zb) <= h {
            map.edges(w.i as u32, w.j as u32)
        } else {
            [None, None]
        };
        if let Some(e) = edge {
            // The cell's solid is (half-plane ∩ square) × [0, h], or, with a second edge,
            // (both half-planes ∩ square) × [0, h].
            let half = T::of(0.5);
            let cx = T::of(w.i as f64) + half;
            let cy = T::of(w.j as f64) + half;
            if !(steps == 1 && entered_top) {
                margin = margin.min((za - h).abs().to64());
            }
            margin = margin.min((zb - h).abs().to64());
            // [z_lo, z_hi]: where the segment is at or below the roof.
            let mut z_ok = true;
            let mut z_roof = false;
            let (mut z_lo, mut z_hi) = (t_in, t_out);
            if za <= h {
                if zb > h {
                    z_hi = t_in + (h - za) / ray.d[2];
                }
            } else if zb <= h {
                z_lo = t_in + (za - h) / (-ray.d[2]);
                z_roof = true;
            } else {
                z_ok = false;
            }
            // [g_lo, g_hi]: where the segment is inside the half-plane(s).
            let g1 = plane_interval(ray, &e, cx, cy, t_in, t_out);
            margin = margin.min(g1.g_in.abs().to64()).min(g1.g_out.abs().to64());
            let g2 = match edge2 {
                Some(e2) => {
                    let g = plane_interval(ray, &e2, cx, cy, t_in, t_out);
                    margin = margin.min(g.g_in.abs().to64()).min(g.g_out.abs().to64());
                    g
                }
                None => Interval {
                    ok: true,
                    edge: false,
                    lo: t_in,
                    hi: t_out,
                    g_in: -T::ONE,
                    g_out: -T::ONE,
                },
            };
            if z_ok && g1.ok && g2.ok {
                let lo = z_lo.mx(g1.lo).mx(g2.lo);
                let hi = z_hi.mn(g1.hi).mn(g2.hi);
                margin = margin.min((hi - lo).abs().to64() * dir_scale(ray));
                if g1.edge && g2.edge {
                    margin = margin.min((g1.lo - g2.lo).abs().to64() * dir_scale(ray));
                }
                if lo <= hi {
                    let (i, j) = (w.i as u32, w.j as u32);
                    let hit = if g2.edge && g2.lo > z_lo && g2.lo > g1.lo {
                        Hit::Wall {
                            i,
                            j,
                            face: Face::Edge2,
                            t: g2.lo.to64(),
                        }
                    } else if g1.edge && g1.lo > z_lo {
                        Hit::Wall {
                            i,
                            j,
                            face: Face::Edge,
                            t: g1.lo.to64(),
                        }
                    } else if z_roof {
                        Hit::Roof {
                            i,
                            j,
                            t: z_lo.to64(),
                        }
                    } else if steps == 1 && entered_top {
                        Hit::Roof {
                            i,
                            j,
                            t: t_in.to64(),
                        }
                    } else {
                        Hit::Wall {
                            i,
                            j,
                            face,
                            t: t_in.to64(),
                        }
                    };
                    return Cast { hit, steps, margin };
                }
            }
        } else if code > 0 {
            // Entering through the top face over a texel of the top level is a roof hit either
            // way (za ≈ 1 = h): not a tie.
            if !(steps == 1 && entered_top) {
                margin = margin.min((za - h).abs().to64());
            }
            margin = margin.min((zb - h).abs().to64());
            if za <= h {
                let (i, j) = (w.i as u32, w.j as u32);
                let t = t_in.to64();
                let hit = if steps == 1 && entered_top {
                    Hit::Roof { i, j, t }
                } else {
                    Hit::Wall { i, j, face, t }
                };
                return Cast { hit, steps, margin };
            }
            if zb <= h {
                let t = t_in + (za - h) / (-ray.d[2]);
                return Cast {
                    hit: Hit::Roof {
                        i: w.i as u32,
                        j: w.j as u32,
                        t: t.to64(),
                    },
                    steps,
                    margin,
                };
            }
        }
        if t_out >= t1 {
            return miss(steps, margin);
        }
        margin = margin.min((t1 - t_out).to64() * dir_scale(ray));
        if w.t_max_x < w.t_max_y {
            margin = margin.min((w.t_max_y - w.t_max_x).to64() * xy_speed);
            w.i += step[0];
            t_in = w.t_max_x;
            w.t_max_x = w.t_max_x + t_delta[0];
            face = if step[0] > 0 { Face::West } else { Face::East };
        } else {
            margin = margin.min((w.t_max_x - w.t_max_y).to64() * xy_speed);
            w.j += step[1];
            t_in = w.t_max_y;
            w.t_max_y = w.t_max_y + t_delta[1];
            face = if step[1] > 0 {
                Face::South
            } else {
                Face::North
            };
        }
        if w.i < 0 || w.i >= k || w.j < 0 || w.j >= k {
            return miss(steps, margin);
        }
    }
    miss(steps, margin)
}

/// Where a ray's segment `[t_in, t_out]` in a cell lies inside a half-plane `n·q ≤ o` (`q`
/// relative to the cell centre `(cx, cy)`).
struct Interval<T> {
    /// Some part of the segment is inside.
    ok: bool,
    /// The segment enters the half-plane inside the cell (through its side).
    edge: bool,
    lo: T,
    hi: T,
    /// The half-plane function at both ends (for the tie margins).
    g_in: T,
    g_out: T,
}

fn plane_interval<T: Real>(
    ray: &TexRay<T>,
    e: &super::layout::Edge,
    cx: T,
    cy: T,
    t_in: T,
    t_out: T,
) -> Interval<T> {
    let (nx, ny, eo) = (
        T::of(e.n[0] as f64),
        T::of(e.n[1] as f64),
        T::of(e.o as f64),
    );
    let g_in = (ray.o[0] + t_in * ray.d[0] - cx) * nx + (ray.o[1] + t_in * ray.d[1] - cy) * ny - eo;
    let g_out =
        (ray.o[0] + t_out * ray.d[0] - cx) * nx + (ray.o[1] + t_out * ray.d[1] - cy) * ny - eo;
    let mut out = Interval {
        ok: true,
        edge: false,
        lo: t_in,
        hi: t_out,
        g_in,
        g_out,
    };
    if g_in <= T::ZERO {
        if g_out > T::ZERO {
            out.hi = t_in + (t_out - t_in) * (g_in / (g_in - g_out));
        }
    } else if g_out <= T::ZERO {
        out.lo = t_in + (t_out - t_in) * (g_in / (g_in - g_out));
        out.edge = true;
    } else {
        out.ok = false;
    }
    out
}

/// How far `o + t·d` lies from the nearest grid line in x or y (except axis `skip`), texels.
fn cell_margin<T: Real>(ray: &TexRay<T>, t: T, skip: usize) -> f64 {
    let mut m = f64::INFINITY;
    for a in (0..2).filter(|&a| a != skip) {
        let p = (ray.o[a] + t * ray.d[a]).to64();
        m = m.min((p - p.round()).abs());
    }
    m
}

fn dir_scale<T: Real>(ray: &TexRay<T>) -> f64 {
    let [a, b, c] = ray.d.map(|v| v.abs().to64());
    a.max(b).max(c)
}

fn sign<T: Real>(v: T) -> i64 {
    if v > T::ZERO {
        1
    } else if v < T::ZERO {
        -1
    } else {
        0
    }
}

/// A hit's surface attributes as the shader reads them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Unlit base colour (RGB8).
    pub color: [u8; 3],
    /// Ambient occlusion byte (255 = open).
    pub ao: u8,
    /// Unit normal.
    pub normal: Vec3,
}

/// The attributes of a hit (Di Benedetto, §4.2.2, Fig. 4.6): a roof reads section 2 and the roof
/// normal; a wall reads the column addressed by the offset map, at the row of the hit's height
/// in the texel's slice, and the column's normal row. A wall texel without a column (only
/// possible with an exposure threshold, BLOCKMAPS.md A.4-1) and an inside hit use the roof
/// colour and the face's axis normal.
pub fn surface(map: &BlockMap, ray: &TexRay<f64>, hit: &Hit) -> Option<Surface> {
    let k = map.k();
    match *hit {
        Hit::Miss => None,
        Hit::Roof { i, j, .. } => {
            let c = map.texel(k + i, j);
            Some(Surface {
                color: [c[0], c[1], c[2]],
                ao: c[3],
                normal: map.roof_normal(i, j),
            })
        }
        Hit::Wall { i, j, face, t } => {
            let off = map.wall_offset(i, j);
            // The edge's normal (a hit on the half-plane's side), else the cell face's.
            let [e1, e2] = map.edges(i, j);
            let edge_normal = match (face, e1, e2) {
                (Face::Edge, Some(e), _) | (Face::Edge2, _, Some(e)) => {
                    Some(Vec3::new(e.n[0], e.n[1], 0.0).normalize_or(Vec3::Z))
                }
                _ => None,
            };
            if off == 0 || face == Face::Inside {
                let c = map.texel(k + i, j);
                return Some(Surface {
                    color: [c[0], c[1], c[2]],
                    ao: c[3],
                    normal: edge_normal.unwrap_or(face.normal()),
                });
            }
            let u = map.wall_u(off);
            let z = (ray.o[2] + t * ray.d[2]) as f32;
            let c = map.texel(u, map.wall_color_row(j, z));
            let n = map.texel(u, map.wall_normal_row(j));
            let normal = edge_normal.unwrap_or_else(|| {
                Vec3::new(
                    super::layout::decode_unit(n[0]),
                    super::layout::decode_unit(n[1]),
                    super::layout::decode_unit(n[2]),
                )
                .normalize_or(face.normal())
            });
            Some(Surface {
                color: [c[0], c[1], c[2]],
                ao: c[3],
                normal,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tower_map() -> BlockMap {
        let mut m = BlockMap::empty(32, DVec3::ZERO, 32.0, 100.0).unwrap();
        for j in 10..12 {
            for i in 10..12 {
                m.texel_mut(i, j)[0] = 255;
            }
        }
        m
    }

    /// `local_point` undoes `tex_ray`: a world ray's point at `t` is found again from the
    /// texture-space ray.
    #[test]
    fn local_point_inverts_tex_ray() {
        let m = tower_map();
        let (o, d) = (DVec3::new(-3.25, 7.5, 40.0), DVec3::new(0.6, -0.3, -0.74));
        let r = m.tex_ray(o, d);
        for t in [0.0, 1.5, 17.25] {
            let p = m.local_point(&r, t);
            assert!(
                (p - (o + d * t)).length() < 1e-9,
                "t {t}: {p} vs {}",
                o + d * t
            );
        }
    }

    #[test]
    fn axis_aligned_ray_hits_the_west_wall() {
        let m = tower_map();
        let r = m.tex_ray(DVec3::new(-5.0, 10.5, 30.0), DVec3::X);
        let c = cast_f64(&m, &r, &CastOptions::default());
        assert_eq!(
            c.hit,
            Hit::Wall {
                i: 10,
                j: 10,
                face: Face::West,
                t: 15.0
            }
        );
        let c32 = cast_f32(&m, &r.to_f32(), &CastOptions::default());
        assert_eq!(c32.hit, c.hit);
    }

    #[test]
    fn vertical_ray_hits_the_roof_or_passes() {
        let m = tower_map();
        let r = m.tex_ray(DVec3::new(10.5, 11.5, 150.0), DVec3::NEG_Z);
        let c = cast_f64(&m, &r, &CastOptions::default());
        assert!(
            matches!(c.hit, Hit::Roof { i: 10, j: 11, t } if (t - 50.0).abs() < 1e-9),
            "{c:?}"
        );
        let r = m.tex_ray(DVec3::new(3.5, 11.5, 150.0), DVec3::NEG_Z);
        assert_eq!(cast_f64(&m, &r, &CastOptions::default()).hit, Hit::Miss);
    }

    #[test]
    fn eye_inside_a_prism_hits_at_once() {
        let m = tower_map();
        let r = m.tex_ray(DVec3::new(10.5, 10.5, 5.0), DVec3::X);
        let c = cast_f64(&m, &r, &CastOptions::default());
        assert_eq!(
            c.hit,
            Hit::Wall {
                i: 10,
                j: 10,
                face: Face::Inside,
                t: 0.0
            }
        );
    }

    /// Tower texel (10, 10) of `tower_map` alone, with an edge: normal bytes and offset.
    fn edge_map(nx: f32, ny: f32, o: f64) -> BlockMap {
        use crate::blockmap::layout::{encode_offset_up, encode_unit};
        let mut m = BlockMap::empty(32, DVec3::ZERO, 32.0, 100.0).unwrap();
        m.texel_mut(10, 10)[0] = 255;
        m.set_edge_bytes(
            10,
            10,
            Some([
                encode_unit(nx),
                encode_unit(ny),
                encode_offset_up(o).unwrap(),
            ]),
        );
        m
    }

    fn both(m: &BlockMap, o: DVec3, d: DVec3) -> Hit {
        let r = m.tex_ray(o, d.normalize());
        let a = cast_f64(m, &r, &CastOptions::default());
        let b = cast_f32(m, &r.to_f32(), &CastOptions::default());
        assert_eq!(a.hit.texel(), b.hit.texel(), "{a:?} vs {b:?}");
        assert_eq!(
            std::mem::discriminant(&a.hit),
            std::mem::discriminant(&b.hit)
        );
        if let (Some(ta), Some(tb)) = (a.hit.t(), b.hit.t()) {
            assert!((ta - tb).abs() < 1e-4, "{ta} vs {tb}");
        }
        a.hit
    }

    #[test]
    fn an_edge_texel_is_hit_on_its_half_plane_only() {
        // Kept: the west half (n = +x, o = 0).
        let m = edge_map(1.0, 0.0, 0.0);
        // From the west the square's own face is hit.
        assert_eq!(
            both(&m, DVec3::new(-5.0, 10.5, 30.0), DVec3::X),
            Hit::Wall {
                i: 10,
                j: 10,
                face: Face::West,
                t: 15.0
            }
        );
        // From the east the edge, half a texel in, with the edge's normal.
        let h = both(&m, DVec3::new(40.0, 10.5, 30.0), DVec3::NEG_X);
        assert!(
            matches!(h, Hit::Wall { i: 10, j: 10, face: Face::Edge, t } if (t - 29.5).abs() < 1e-9),
            "{h:?}"
        );
        let r = m.tex_ray(DVec3::new(40.0, 10.5, 30.0), DVec3::NEG_X);
        let s = surface(&m, &r, &h).unwrap();
        assert_eq!(s.normal, Vec3::X);
        // Vertical rays on each side of the edge: the roof, then nothing.
        assert!(matches!(
            both(&m, DVec3::new(10.2, 10.5, 150.0), DVec3::NEG_Z),
            Hit::Roof { i: 10, j: 10, t } if (t - 50.0).abs() < 1e-9
        ));
        assert_eq!(
            both(&m, DVec3::new(10.8, 10.5, 150.0), DVec3::NEG_Z),
            Hit::Miss
        );
        // Grazing rays along the edge, just inside (the south face) and just outside (nothing).
        assert!(matches!(
            both(&m, DVec3::new(10.49, -5.0, 30.0), DVec3::Y),
            Hit::Wall {
                i: 10,
                j: 10,
                face: Face::South,
                ..
            }
        ));
        assert_eq!(both(&m, DVec3::new(10.51, -5.0, 30.0), DVec3::Y), Hit::Miss);
        // From inside the box, over the cut half and below the roof, sloping west: the edge.
        let h = both(
            &m,
            DVec3::new(10.9, 10.5, 90.0),
            DVec3::new(-0.4, 0.0, -1.0),
        );
        assert!(
            matches!(h, Hit::Wall { face: Face::Edge, t, .. } if t > 0.0),
            "{h:?}"
        );
    }

    #[test]
    fn a_ray_through_the_cut_corner_misses() {
        // Kept: all but the north-east corner (n = (1, 1)/√2, o = 0.5).
        let s2 = std::f32::consts::FRAC_1_SQRT_2;
        let m = edge_map(s2, s2, 0.5);
        // Entering at the top side inside the cut corner, leaving by the east side: no hit
        // (a whole texel would be hit).
        let d = DVec3::new(1.0, -1.0, 0.0);
        assert_eq!(both(&m, DVec3::new(0.9, 21.0, 30.0), d), Hit::Miss);
        // Along −x through the corner: the diagonal edge, with its normal.
        let h = both(&m, DVec3::new(40.0, 10.95, 30.0), DVec3::NEG_X);
        let Hit::Wall {
            face: Face::Edge,
            t,
            ..
        } = h
        else {
            panic!("{h:?}")
        };
        let e = m.edge(10, 10).unwrap();
        let x = 40.0 - t;
        let g = (x - 10.5) * e.n[0] as f64 + 0.45 * e.n[1] as f64 - e.o as f64;
        assert!(g.abs() < 1e-6, "hit {x} is off the edge by {g}");
        // The same ray with no edge hits the east face.
        let mut whole = m.clone();
        whole.set_edge_bytes(10, 10, None);
        assert!(matches!(
            both(&whole, DVec3::new(40.0, 10.95, 30.0), DVec3::NEG_X),
            Hit::Wall { face: Face::East, t, .. } if (t - 29.0).abs() < 1e-9
        ));
    }

    #[test]
    fn two_edges_keep_a_convex_corner() {
        use crate::blockmap::layout::{encode_offset_up, encode_unit};
        // Kept: the south-west quarter (x ≤ 0 and y ≤ 0 about the centre): n₁ = +x, n₂ = +y.
        let mut m = edge_map(1.0, 0.0, 0.0);
        m.set_edge2_bytes(
            10,
            10,
            Some([
                encode_unit(0.0),
                encode_unit(1.0),
                encode_offset_up(0.0).unwrap(),
            ]),
        );
        assert!(m.edges(10, 10)[1].is_some());
        // Vertical rays: the kept quarter's roof; the three other quarters are empty (one
        // half-plane alone kept the north-west one).
        assert!(matches!(
            both(&m, DVec3::new(10.25, 10.25, 150.0), DVec3::NEG_Z),
            Hit::Roof { i: 10, j: 10, .. }
        ));
        for (x, y) in [(10.75, 10.25), (10.25, 10.75), (10.75, 10.75)] {
            assert_eq!(both(&m, DVec3::new(x, y, 150.0), DVec3::NEG_Z), Hit::Miss);
        }
        // From the north the second edge, half a texel in, with its normal.
        let h = both(&m, DVec3::new(10.25, 40.0, 30.0), DVec3::NEG_Y);
        assert!(
            matches!(h, Hit::Wall { i: 10, j: 10, face: Face::Edge2, t } if (t - 29.5).abs() < 1e-9),
            "{h:?}"
        );
        let r = m.tex_ray(DVec3::new(10.25, 40.0, 30.0), DVec3::NEG_Y);
        assert_eq!(surface(&m, &r, &h).unwrap().normal, Vec3::Y);
        // From the east the first edge.
        let h = both(&m, DVec3::new(40.0, 10.25, 30.0), DVec3::NEG_X);
        assert!(
            matches!(h, Hit::Wall { face: Face::Edge, t, .. } if (t - 29.5).abs() < 1e-9),
            "{h:?}"
        );
        // A second edge without a first is not read (the casters' rule).
        let mut only2 = m.clone();
        only2.set_edge_bytes(10, 10, None);
        assert_eq!(only2.edges(10, 10), [None, None]);
        assert!(matches!(
            both(&only2, DVec3::new(10.75, 10.75, 150.0), DVec3::NEG_Z),
            Hit::Roof { .. }
        ));
    }

    #[test]
    fn leap_gives_the_same_hit_in_fewer_steps() {
        let m = tower_map();
        let dm = m.distance_map();
        let r = m.tex_ray(
            DVec3::new(0.2, 0.3, 60.0),
            DVec3::new(1.0, 1.0, -0.2).normalize(),
        );
        let a = cast_f64(&m, &r, &CastOptions::default());
        let b = cast_f64(&m, &r, &CastOptions { leap: Some(&dm) });
        assert_eq!(a.hit.texel(), b.hit.texel());
        assert!((a.hit.t().unwrap() - b.hit.t().unwrap()).abs() < 1e-9);
        assert!(matches!(a.hit, Hit::Wall { .. }), "{a:?}");
        assert!(b.steps < a.steps, "{} vs {}", b.steps, a.steps);
    }
}
