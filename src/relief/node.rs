//! A node's impostor: its zenithal map and pyramid, its oblique maps, and how a hit is coloured
//! (Andujar et al., §5.2–5.3).
//!
//! **Colour.** A hit on a column top (roof, or the flat quad) takes the zenithal map's colour at
//! its texel. A hit on a column side (a façade) is projected onto the three oblique maps chosen
//! for the frame: the first map whose stored depth at the projected texel matches the point's
//! own distance from that map's plane (within [`NodeMaps::match_tol_m`]: the point lies on a
//! texel boundary of the zenithal grid, so the true wall may be up to a zenithal texel diagonal
//! away, plus an oblique texel) gives the colour: the depth-aware projective test, which keeps
//! a wall hidden from one map from taking the colour of whatever hides it. No match: the
//! integer average of the three maps' covered texels (the paper's fallback for simultaneous
//! disocclusions); none covered: the zenithal colour.
//!
//! **Choosing the three maps** (the core-set heuristic of §5.3): the first is the map of the
//! whole set best aligned with the direction from the eye to the node's centre, the second and
//! third the two best aligned of the core set (the first four maps by coverage) other than the
//! first. All of it in `f32` from constants computed in `f64` and rounded ([`ObliqueXform`]),
//! as the shader does.

use super::cast::{Face, Hit};
use super::map::{ReliefMap, EMPTY, Q_MAX};
use super::surfels::Vote;
use crate::blockmap::cast::TexRay;
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Camera};
use glam::DVec3;
use serde::Serialize;

/// Maps of the core set.
pub const CORE_SET: usize = 4;

/// Obliques used per frame and node.
pub const CHOSEN: usize = 3;

/// What the build measured of a node's maps against its meshes (see [`super::error`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct NodeError {
    /// Largest coverage error over the test views: the share of the node's pixels (in an
    /// orthographic image of its meshes) covered by the meshes or the maps but not both.
    pub coverage_error_max: f64,
    /// Mean over the test views.
    pub coverage_error_mean: f64,
    /// Largest share of the covered pixels whose colour is off by more than
    /// [`super::error::COLOUR_TOLERANCE`] (aliasing of sub-texel façade detail, mostly).
    pub colour_mismatch_max: f64,
    /// Smallest colour PSNR of the covered pixels, dB.
    pub psnr_min_db: f64,
    /// Test views.
    pub views: usize,
}

/// One node of the relief tree with its maps.
#[derive(Clone, Debug)]
pub struct NodeMaps {
    /// The tree node (index into `ReliefTree::nodes`).
    pub node: usize,
    /// Depth in the tree.
    pub depth: u32,
    /// Index of the parent in the field's nodes.
    pub parent: Option<usize>,
    /// The node's blocks (whole blocks: no block is in two siblings).
    pub blocks: Vec<BlockId>,
    /// Its buildings (indices into `City::buildings`).
    pub buildings: Vec<u32>,
    /// Its box (local frame): the footprints' box, grown to hold every covered texel's whole
    /// column, × the height range. Every hit of its walk lies in it.
    pub aabb: Aabb3,
    /// The height range `[z_bot, z_top]` the zenithal heights quantise.
    pub z_range: [f64; 2],
    /// The zenithal map.
    pub zenithal: ReliefMap,
    /// Its max pyramid above level 0 (level 1 first).
    pub upper: Vec<Vec<u16>>,
    /// The oblique maps, in decreasing order of the area they add.
    pub obliques: Vec<ReliefMap>,
    /// The façade vote that chose them.
    pub vote: Vote,
    /// The zenithal texel, metres.
    pub texel_m: f64,
    /// Declared world-space error, metres: one zenithal texel (more than the half diagonal by
    /// which a point-sampled column can stand off the footprint, plus the height quantum);
    /// thin and dropped buildings are declared apart ([`NodeMaps::declared`]).
    pub eps_m: f64,
    /// Buildings no texel holds or narrower than a texel (sorted): drawn unfaithfully by
    /// declaration.
    pub declared: Vec<u32>,
    /// The measured coverage error.
    pub error: NodeError,
    /// Height in pixels below which it is drawn as a flat quad (0: never).
    pub flat_px: f64,
    /// Seconds its maps took to build (capture, vote, obliques, error).
    pub build_s: f64,
}

/// What the per-frame decisions need of a node (its box, height range, texture space and
/// oblique directions): small, so that a GPU renderer keeps its own copy and decides exactly
/// as the CPU renderer does.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeFrameInfo {
    /// The node's box (local frame).
    pub aabb: Aabb3,
    /// Its height range.
    pub z_range: [f64; 2],
    /// Texture space → local frame: `p = origin + scale ⊙ q`.
    pub tex_origin: DVec3,
    /// See [`NodeFrameInfo::tex_origin`].
    pub tex_scale: DVec3,
    /// The oblique maps' directions, in map order.
    pub oblique_dirs: Vec<DVec3>,
    /// Height in pixels below which the node is drawn as a flat quad (0: never).
    pub flat_px: f64,
}

impl NodeFrameInfo {
    /// The three obliques for a view from `eye` (see [`choose_obliques`]).
    pub fn choose(&self, eye: DVec3) -> [Option<u32>; CHOSEN] {
        let view = (self.aabb.center() - eye).normalize_or_zero();
        choose_obliques(
            self.oblique_dirs.iter().copied(),
            self.oblique_dirs.len(),
            view,
        )
    }

    /// True when the node's height projects to fewer than [`NodeFrameInfo::flat_px`] pixels
    /// from `camera` on an image `height_px` high: drawn as the flat quad.
    pub fn is_flat(&self, camera: &Camera, height_px: u32) -> bool {
        if self.flat_px <= 0.0 {
            return false;
        }
        let h = self.z_range[1] - self.z_range[0];
        let c = self.aabb.center();
        let r = self.aabb.extent().length() * 0.5;
        crate::blockmap::select::projected_error_px(h, c, r, camera, height_px) < self.flat_px
    }
}

/// Per oblique map and node: texture-space point `(x, y, z, 1)` → `(a, b, dq)`, its texel
/// coordinates on the oblique map and its distance from the map's plane in quantised units,
/// rounded to `f32` as uploaded; and the match tolerance in quantised units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObliqueXform {
    /// Rows of the affine map.
    pub rows: [[f32; 4]; 3],
    /// Tolerance of the depth match, quantised units.
    pub tol_q: f32,
}

impl NodeMaps {
    /// Map side.
    pub fn m(&self) -> u32 {
        self.zenithal.frame.m
    }

    /// The levels of the max pyramid, level 0 (the zenithal depth) first.
    pub fn levels(&self) -> Vec<&[u16]> {
        std::iter::once(self.zenithal.depth.as_slice())
            .chain(self.upper.iter().map(|l| l.as_slice()))
            .collect()
    }

    /// Bytes as stored and uploaded: every map's colour and depth, and the pyramid.
    pub fn bytes(&self) -> u64 {
        self.zenithal.bytes()
            + super::map::pyramid_bytes(self.m())
            + self.obliques.iter().map(|o| o.bytes()).sum::<u64>()
    }

    /// Texture space → local frame: `(origin, scale)` with `p = origin + scale ⊙ q`.
    pub fn tex_to_local(&self) -> (DVec3, DVec3) {
        let f = &self.zenithal.frame;
        let t = f.texel_m();
        let range = self.z_range[1] - self.z_range[0];
        (
            DVec3::new(f.origin.x, f.origin.y, self.z_range[0]),
            DVec3::new(t, t, range),
        )
    }

    /// A world ray (local frame) in texture space, same parameter.
    pub fn tex_ray(&self, origin: DVec3, dir: DVec3) -> TexRay<f64> {
        let (o, s) = self.tex_to_local();
        TexRay {
            o: ((origin - o) / s).to_array(),
            d: (dir / s).to_array(),
        }
    }

    /// The `f64` twin of the ray the GPU casts through the centre of pixel `(x, y)` of a
    /// `w × h` frame from `camera` in this node's texture space (for the casts' `f64` twins,
    /// which name the ties).
    pub fn twin_ray(&self, camera: &Camera, w: u32, h: u32, x: u32, y: u32) -> TexRay<f64> {
        let (o, s) = self.tex_to_local();
        crate::blockmap::image::twin_ray_in(o, s, camera, w, h, x, y)
    }

    /// The local point at parameter `t` of a texture-space ray.
    pub fn local_point(&self, ray: &TexRay<f64>, t: f64) -> DVec3 {
        let (o, s) = self.tex_to_local();
        let q = DVec3::from_array([0, 1, 2].map(|a| ray.o[a] + ray.d[a] * t));
        o + q * s
    }

    /// The depth-match tolerance, metres: a zenithal texel diagonal and an oblique texel.
    pub fn match_tol_m(&self) -> f64 {
        let obl = self.obliques.first().map_or(0.0, |o| o.frame.texel_m());
        self.texel_m * std::f64::consts::SQRT_2 + obl
    }

    /// The constants of every oblique map.
    pub fn oblique_xforms(&self) -> Vec<ObliqueXform> {
        let (o, s) = self.tex_to_local();
        let tol = self.match_tol_m();
        self.obliques
            .iter()
            .map(|ob| {
                let f = &ob.frame;
                let t = f.texel_m();
                let kq = f64::from(Q_MAX - 1) / f.depth_m;
                // value(q) = axis · (o + s ⊙ q − origin) · scale (+ offset)
                let row = |axis: DVec3, scale: f64, offset: f64| -> [f32; 4] {
                    let c = axis * s * scale;
                    let k = axis.dot(o - f.origin) * scale + offset;
                    [c.x as f32, c.y as f32, c.z as f32, k as f32]
                };
                ObliqueXform {
                    rows: [
                        row(f.u, 1.0 / t, 0.0),
                        row(f.v, 1.0 / t, 0.0),
                        row(f.dir, kq, 1.0),
                    ],
                    tol_q: (tol * kq) as f32,
                }
            })
            .collect()
    }

    /// What the per-frame decisions need of this node.
    pub fn frame_info(&self) -> NodeFrameInfo {
        let (tex_origin, tex_scale) = self.tex_to_local();
        NodeFrameInfo {
            aabb: self.aabb,
            z_range: self.z_range,
            tex_origin,
            tex_scale,
            oblique_dirs: self.obliques.iter().map(|o| o.frame.dir).collect(),
            flat_px: self.flat_px,
        }
    }
}

/// The core-set choice over map directions `dirs` (into the scene, in map order) for the unit
/// view direction `view`.
pub fn choose_obliques(
    dirs: impl Iterator<Item = DVec3>,
    n: usize,
    view: DVec3,
) -> [Option<u32>; CHOSEN] {
    let align: Vec<f64> = dirs.map(|d| d.dot(view)).collect();
    debug_assert_eq!(align.len(), n);
    let best = |from: std::ops::Range<usize>, skip: &[Option<u32>]| -> Option<u32> {
        from.filter(|k| !skip.contains(&Some(*k as u32)))
            .max_by(|&a, &b| align[a].total_cmp(&align[b]).then(b.cmp(&a)))
            .map(|k| k as u32)
    };
    let mut out = [None; CHOSEN];
    out[0] = best(0..n, &[]);
    out[1] = best(0..n.min(CORE_SET), &out[..1]);
    out[2] = best(0..n.min(CORE_SET), &out[..2]);
    // A node with fewer than three core maps fills the rest from the whole set.
    for k in 1..CHOSEN {
        if out[k].is_none() {
            out[k] = best(0..n, &out[..k]);
        }
    }
    out
}

/// The colour of `hit` of ray `ray` (texture space, `f32` as the shader) on `node`, with the
/// chosen obliques `chosen` and their constants `xf` (see the module doc). RGBA8, alpha 255.
pub fn shade(
    node: &NodeMaps,
    xf: &[ObliqueXform],
    chosen: &[Option<u32>; CHOSEN],
    ray: &TexRay<f32>,
    hit: &Hit,
) -> [u8; 4] {
    let m = node.m();
    let zen = |c: [u32; 2]| -> [u8; 4] {
        let mut v = node.zenithal.color[(c[1] * m + c[0]) as usize];
        v[3] = 255;
        v
    };
    match hit.face {
        Face::Top | Face::Flat | Face::Inside => zen(hit.cell),
        Face::WallX | Face::WallY => {
            let t = hit.t as f32;
            let p = [0, 1, 2].map(|a| ray.o[a] + ray.d[a] * t);
            let mut sum = [0u32; 3];
            let mut n = 0u32;
            for k in chosen.iter().flatten() {
                let (ob, x) = (&node.obliques[*k as usize], &xf[*k as usize]);
                let val = |r: &[f32; 4]| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
                let (a, b, dq) = (val(&x.rows[0]), val(&x.rows[1]), val(&x.rows[2]));
                let mf = ob.frame.m as f32;
                if !(a >= 0.0 && b >= 0.0 && a < mf && b < mf) {
                    continue;
                }
                let (i, j) = (a.floor() as u32, b.floor() as u32);
                let idx = (j * ob.frame.m + i) as usize;
                let q = ob.depth[idx];
                if q == EMPTY {
                    continue;
                }
                let c = ob.color[idx];
                if (f32::from(q) - dq).abs() <= x.tol_q {
                    return [c[0], c[1], c[2], 255];
                }
                for ch in 0..3 {
                    sum[ch] += u32::from(c[ch]);
                }
                n += 1;
            }
            if n == 0 {
                return zen(hit.cell);
            }
            let avg = |s: u32| ((s + n / 2) / n) as u8;
            [avg(sum[0]), avg(sum[1]), avg(sum[2]), 255]
        }
    }
}

/// [`shade`] while a switch of obliques is blended: on a wall, the colour with the `previous`
/// three mixed with the colour with `chosen` by `weight` (of 256, the new set's share) in
/// integers, `(old·(256 − w) + new·w + 128) / 256` per channel, as the shader mixes them;
/// elsewhere, or without a previous set, the plain colour.
pub fn shade_blended(
    node: &NodeMaps,
    xf: &[ObliqueXform],
    chosen: &[Option<u32>; CHOSEN],
    previous: Option<&[Option<u32>; CHOSEN]>,
    weight: u32,
    ray: &TexRay<f32>,
    hit: &Hit,
) -> [u8; 4] {
    let new = shade(node, xf, chosen, ray, hit);
    let wall = matches!(hit.face, Face::WallX | Face::WallY);
    match previous {
        Some(prev) if wall && weight < 256 => {
            let old = shade(node, xf, prev, ray, hit);
            let mix = |o: u8, n: u8| {
                ((u32::from(o) * (256 - weight) + u32::from(n) * weight + 128) >> 8) as u8
            };
            [
                mix(old[0], new[0]),
                mix(old[1], new[1]),
                mix(old[2], new[2]),
                255,
            ]
        }
        _ => new,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_core_set_heuristic_takes_two_of_the_first_four() {
        let dirs = [
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(0.0, 1.0, -1.0),
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::new(0.0, -1.0, -1.0),
            DVec3::new(0.7, 0.7, -0.2),
            DVec3::new(0.6, 0.8, -0.3),
        ]
        .map(|d| d.normalize());
        let view = DVec3::new(0.7, 0.7, -0.2).normalize();
        let c = choose_obliques(dirs.iter().copied(), 6, view);
        // The best overall is map 4; the next two come from the core set: 0 and 1 (both at
        // 45° of the view's azimuth), 0 first on the tie (lower index).
        assert_eq!(c, [Some(4), Some(0), Some(1)]);
        // Two maps only: both, then none.
        let c = choose_obliques(dirs[..2].iter().copied(), 2, view);
        assert_eq!(c, [Some(0), Some(1), None]);
        let c = choose_obliques(std::iter::empty(), 0, view);
        assert_eq!(c, [None, None, None]);
    }
}
