//! Relief maps: orthographic colour + depth images of a node's buildings (Andujar et al., §3,
//! §4.2). Every map of a tree is `M × M` texels, RGBA8 colour and a 16-bit depth:
//!
//! - the **zenithal** map looks straight down on the node's box; its depth channel is stored as
//!   a *height* `q ∈ 1..=65535` over the node's height range (`z = z_bot + q/65535 ·
//!   (z_top − z_bot)`), 0 where no building covers the texel centre: the 2.5D height field the
//!   caster walks. A max pyramid of it ([`ReliefMap::pyramid`]) lets the walk skip empty space
//!   without ever skipping a hit (a max-mipmap traversal, see [`super::cast`]).
//! - an **oblique** map looks along a direction chosen by the façade vote
//!   ([`super::surfels`]); its depth is the distance from the map plane,
//!   `d = (q − 1)/65534 · depth_m`, 0 where nothing was drawn.
//!
//! Maps are captured by the CPU z-buffer of the visibility oracle
//! ([`crate::visibility::oracle::shade_ids_clip`]) with the meshes' own lit colours (the mesh
//! shader's appearance and sun), sampled at texel centres: the colour a map stores is the colour
//! the mesh frame shows at that point, so a map differs from the meshes only by where it
//! samples.

use crate::city::Mesh;
use crate::visibility::oracle::{shade_ids_clip, SKY};
use glam::{DMat4, DVec3};
use serde::Serialize;

/// Depth value of a texel nothing covers.
pub const EMPTY: u16 = 0;

/// Largest quantised height or depth.
pub const Q_MAX: u16 = u16::MAX;

/// The orthographic frame of one map, in the city's local frame (f64).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MapFrame {
    /// The corner of texel `(0, 0)` on the map plane (depth 0).
    pub origin: DVec3,
    /// Unit axis of the columns (texel `i` spans `[i, i + 1]·t` along it).
    pub u: DVec3,
    /// Unit axis of the rows.
    pub v: DVec3,
    /// Unit viewing direction, from the plane into the scene.
    pub dir: DVec3,
    /// Side of the square, metres.
    pub side_m: f64,
    /// Depth range the quantised depth covers, metres.
    pub depth_m: f64,
    /// Texels per side.
    pub m: u32,
}

impl MapFrame {
    /// A frame looking along `dir` (unit) at the box `[min, max]` (local frame): the square on
    /// the plane perpendicular to `dir` that holds the box's projection, a millimetre of margin
    /// around it, and the depth range of the box.
    pub fn fitting(dir: DVec3, min: DVec3, max: DVec3, m: u32) -> Self {
        let dir = dir.normalize();
        // Columns run horizontally, perpendicular to the direction (east for a vertical view).
        let h = DVec3::new(dir.x, dir.y, 0.0);
        let u = if h.length() < 1e-9 {
            DVec3::X
        } else {
            DVec3::new(-dir.y, dir.x, 0.0).normalize()
        };
        let v = dir.cross(u).normalize();
        // For the straight-down view (dir = −Z, u = X) this gives v = −Z × X = −Y; turn it to +Y
        // so that rows run north like the ground's y.
        let v = if h.length() < 1e-9 { DVec3::Y } else { v };
        let corners = crate::geom::Aabb3::new(min, max).corners();
        let span = |axis: DVec3| {
            corners
                .iter()
                .map(|c| c.dot(axis))
                .fold([f64::INFINITY, f64::NEG_INFINITY], |a, x| {
                    [a[0].min(x), a[1].max(x)]
                })
        };
        let (su, sv, sd) = (span(u), span(v), span(dir));
        let margin = 1e-3;
        let side = (su[1] - su[0]).max(sv[1] - sv[0]) + 2.0 * margin;
        // Centre the box's projection in the square.
        let cu = 0.5 * (su[0] + su[1]) - 0.5 * side;
        let cv = 0.5 * (sv[0] + sv[1]) - 0.5 * side;
        let d0 = sd[0] - margin;
        Self {
            origin: u * cu + v * cv + dir * d0,
            u,
            v,
            dir,
            side_m: side,
            depth_m: (sd[1] - sd[0]) + 2.0 * margin,
            m,
        }
    }

    /// The zenithal frame of the box `[min, max]`: looking down, columns east, rows north,
    /// the square's south-west corner at the box's and its depth from the box's top.
    pub fn zenithal(min: DVec3, max: DVec3, m: u32) -> Self {
        let margin = 1e-3;
        let side = (max.x - min.x).max(max.y - min.y) + 2.0 * margin;
        Self {
            origin: DVec3::new(min.x - margin, min.y - margin, max.z + margin),
            u: DVec3::X,
            v: DVec3::Y,
            dir: DVec3::NEG_Z,
            side_m: side,
            depth_m: (max.z - min.z) + 2.0 * margin,
            m,
        }
    }

    /// Texel size, metres.
    pub fn texel_m(&self) -> f64 {
        self.side_m / f64::from(self.m)
    }

    /// `(i, j, d)`: the continuous texel coordinates of `p` (local frame) and its distance from
    /// the plane along the direction, metres.
    pub fn to_map(&self, p: DVec3) -> DVec3 {
        let q = p - self.origin;
        let t = self.texel_m();
        DVec3::new(q.dot(self.u) / t, q.dot(self.v) / t, q.dot(self.dir))
    }

    /// The local point at texel coordinates `(i, j)` and depth `d`.
    pub fn from_map(&self, i: f64, j: f64, d: f64) -> DVec3 {
        let t = self.texel_m();
        self.origin + self.u * (i * t) + self.v * (j * t) + self.dir * d
    }

    /// Clip from local coordinates for the oracle's rasteriser: pixel `(i, j)` of an `M × M`
    /// image is texel `(i, j)` (row 0 is clip `y = +1`, so `y_clip = 1 − 2·v/side`), and clip
    /// depth is `d / depth_m`.
    pub fn clip_from_local(&self) -> DMat4 {
        let k = 2.0 / self.side_m;
        let (o, u, v, w) = (self.origin, self.u, self.v, self.dir);
        let rows = [
            [k * u.x, k * u.y, k * u.z, -k * o.dot(u) - 1.0],
            [-k * v.x, -k * v.y, -k * v.z, k * o.dot(v) + 1.0],
            [
                w.x / self.depth_m,
                w.y / self.depth_m,
                w.z / self.depth_m,
                -o.dot(w) / self.depth_m,
            ],
            [0.0, 0.0, 0.0, 1.0],
        ];
        DMat4::from_cols_array_2d(&rows).transpose()
    }

    /// The quantised depth of distance `d` (metres from the plane): `1 + round(d/depth_m ·
    /// 65534)`, clamped.
    pub fn quantise_depth(&self, d: f64) -> u16 {
        let q = 1.0 + (d / self.depth_m * f64::from(Q_MAX - 1)).round();
        q.clamp(1.0, f64::from(Q_MAX)) as u16
    }

    /// The distance (metres) of a quantised depth `q ≥ 1`.
    pub fn depth_of(&self, q: u16) -> f64 {
        f64::from(q.saturating_sub(1)) / f64::from(Q_MAX - 1) * self.depth_m
    }
}

/// Whether a map is the zenithal one or an oblique one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MapKind {
    /// Straight down; depth stored as height.
    Zenithal,
    /// Along a voted direction; depth from the plane.
    Oblique,
}

/// One relief map (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct ReliefMap {
    /// Zenithal or oblique.
    pub kind: MapKind,
    /// Its orthographic frame.
    pub frame: MapFrame,
    /// RGBA8 per texel, row-major (row `j` along [`MapFrame::v`]); alpha 255 where covered.
    pub color: Vec<[u8; 4]>,
    /// Quantised height (zenithal) or depth (oblique) per texel; [`EMPTY`] where nothing is.
    pub depth: Vec<u16>,
}

impl ReliefMap {
    /// Texels per side.
    pub fn m(&self) -> u32 {
        self.frame.m
    }

    /// The depth value at texel `(i, j)`.
    pub fn at(&self, i: u32, j: u32) -> u16 {
        self.depth[(j * self.frame.m + i) as usize]
    }

    /// Texels that hold a surface.
    pub fn covered(&self) -> usize {
        self.depth.iter().filter(|&&q| q != EMPTY).count()
    }

    /// Bytes of the map as stored and uploaded: RGBA8 colour and 16-bit depth per texel (the
    /// zenithal map's pyramid counted by [`pyramid_bytes`]).
    pub fn bytes(&self) -> u64 {
        let n = u64::from(self.frame.m) * u64::from(self.frame.m);
        n * 6
    }

    /// The max pyramid of the depth channel: level 0 is the map itself, level `L` holds, per
    /// `2^L × 2^L` block, the largest value (so [`EMPTY`] only where the whole block is empty),
    /// down to one texel. Meaningful for the zenithal map (heights).
    pub fn pyramid(&self) -> Vec<Vec<u16>> {
        let mut levels = vec![self.depth.clone()];
        let mut m = self.frame.m as usize;
        while m > 1 {
            let prev = levels.last().expect("level 0 is there");
            let h = m / 2;
            let mut next = vec![EMPTY; h * h];
            for j in 0..h {
                for i in 0..h {
                    let a = prev[2 * j * m + 2 * i];
                    let b = prev[2 * j * m + 2 * i + 1];
                    let c = prev[(2 * j + 1) * m + 2 * i];
                    let d = prev[(2 * j + 1) * m + 2 * i + 1];
                    next[j * h + i] = a.max(b).max(c).max(d);
                }
            }
            levels.push(next);
            m = h;
        }
        levels
    }

    /// Captures `meshes` (building id, mesh; local frame) through `frame`, zenithal or oblique.
    /// Texels whose centre shows a building get its lit colour and its height (zenithal, over
    /// `[z_bot, z_top]`) or depth (oblique).
    pub fn capture(
        kind: MapKind,
        frame: MapFrame,
        meshes: &[(u32, &Mesh)],
        z_range: [f64; 2],
    ) -> Self {
        let m = frame.m;
        let (ids, colors) = shade_ids_clip(meshes, &frame.clip_from_local(), m, m);
        let n = (m * m) as usize;
        let mut color = vec![[0u8; 4]; n];
        let mut depth = vec![EMPTY; n];
        let range = (z_range[1] - z_range[0]).max(f64::MIN_POSITIVE);
        for k in 0..n {
            if ids.ids[k] == SKY {
                continue;
            }
            let [r, g, b] = colors[k];
            color[k] = [r, g, b, 255];
            let d = f64::from(ids.depth[k]) * frame.depth_m;
            depth[k] = match kind {
                MapKind::Oblique => frame.quantise_depth(d),
                MapKind::Zenithal => {
                    // The plane lies at the box top (plus the margin): z = top − d.
                    let z = frame.origin.z - d;
                    let q = ((z - z_range[0]) / range * f64::from(Q_MAX)).round();
                    q.clamp(1.0, f64::from(Q_MAX)) as u16
                }
            };
        }
        Self {
            kind,
            frame,
            color,
            depth,
        }
    }
}

/// Samples per texel side of the zenithal capture.
pub const ZENITHAL_SAMPLES: u32 = 4;

impl ReliefMap {
    /// The zenithal map of `meshes` (building id, mesh; local frame) through `frame` (from
    /// [`MapFrame::zenithal`]), heights over `z_range`, captured at `ZENITHAL_SAMPLES²` samples
    /// per texel: a texel is covered where at least half its samples show a roof, with the
    /// highest sampled roof and the colour of the covered sample nearest its centre. Returns the
    /// map; per building id, the texels that show it (a building narrower than half a texel may
    /// have none: it is a fraction of a pixel where the node is drawn); and the buildings with a
    /// part no covered texel lies within a texel of (sorted): what the map loses of them.
    pub fn capture_zenithal(
        frame: MapFrame,
        meshes: &[(u32, &Mesh)],
        z_range: [f64; 2],
    ) -> (Self, std::collections::HashMap<u32, usize>, Vec<u32>) {
        let m = frame.m;
        let s = ZENITHAL_SAMPLES;
        let side = m * s;
        let (ids, colors) = shade_ids_clip(meshes, &frame.clip_from_local(), side, side);
        let range = (z_range[1] - z_range[0]).max(f64::MIN_POSITIVE);
        let n = (m * m) as usize;
        let mut color = vec![[0u8; 4]; n];
        let mut depth = vec![EMPTY; n];
        let mut texels: std::collections::HashMap<u32, usize> = Default::default();
        let height = |k: usize| -> u16 {
            let z = frame.origin.z - f64::from(ids.depth[k]) * frame.depth_m;
            ((z - z_range[0]) / range * f64::from(Q_MAX))
                .round()
                .clamp(1.0, f64::from(Q_MAX)) as u16
        };
        // Sample order from the texel centre outwards (ties by row, then column).
        let mut order: Vec<(u32, u32)> = (0..s).flat_map(|b| (0..s).map(move |a| (a, b))).collect();
        let c = f64::from(s) / 2.0 - 0.5;
        order.sort_by(|p, q| {
            let d = |(a, b): (u32, u32)| (f64::from(a) - c).powi(2) + (f64::from(b) - c).powi(2);
            d(*p)
                .total_cmp(&d(*q))
                .then(p.1.cmp(&q.1))
                .then(p.0.cmp(&q.0))
        });
        let sample = |i: u32, j: u32, (a, b): (u32, u32)| ((j * s + b) * side + i * s + a) as usize;
        for j in 0..m {
            for i in 0..m {
                let t = (j * m + i) as usize;
                let hits: Vec<usize> = order
                    .iter()
                    .map(|&o| sample(i, j, o))
                    .filter(|&k| ids.ids[k] != SKY)
                    .collect();
                if 2 * hits.len() < (s * s) as usize {
                    continue;
                }
                let first = hits[0];
                let [r, g, b] = colors[first];
                color[t] = [r, g, b, 255];
                depth[t] = hits.iter().map(|&k| height(k)).max().unwrap_or(EMPTY);
                *texels.entry(ids.ids[first]).or_default() += 1;
            }
        }
        // Buildings with a part no column stands within a texel of: samples of theirs in an
        // empty texel whose eight neighbours are empty too (a thin wing, a wall standing alone).
        let mut lost: Vec<u32> = Vec::new();
        let mi = i64::from(m);
        for j in 0..mi {
            for i in 0..mi {
                let t = (j * mi + i) as usize;
                if depth[t] != EMPTY {
                    continue;
                }
                let near = (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        let (x, y) = (i + dx, j + dy);
                        x >= 0
                            && y >= 0
                            && x < mi
                            && y < mi
                            && depth[(y * mi + x) as usize] != EMPTY
                    })
                });
                if near {
                    continue;
                }
                for &o in &order {
                    let id = ids.ids[sample(i as u32, j as u32, o)];
                    if id != SKY {
                        lost.push(id);
                    }
                }
            }
        }
        lost.sort_unstable();
        lost.dedup();
        (
            Self {
                kind: MapKind::Zenithal,
                frame,
                color,
                depth,
            },
            texels,
            lost,
        )
    }
}

/// Bytes of the pyramid above level 0 of an `m × m` map (16 bits per texel).
pub fn pyramid_bytes(m: u32) -> u64 {
    let mut total = 0u64;
    let mut s = u64::from(m) / 2;
    while s >= 1 {
        total += s * s * 2;
        s /= 2;
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_map_points_to_texels_and_back() {
        let min = DVec3::new(10.0, -5.0, 0.0);
        let max = DVec3::new(50.0, 20.0, 30.0);
        for dir in [
            DVec3::NEG_Z,
            DVec3::new(0.5, 0.3, -0.6),
            DVec3::new(-1.0, 0.2, -0.1),
        ] {
            let f = if dir == DVec3::NEG_Z {
                MapFrame::zenithal(min, max, 64)
            } else {
                MapFrame::fitting(dir, min, max, 64)
            };
            assert!((f.u.dot(f.v)).abs() < 1e-12 && (f.u.dot(f.dir)).abs() < 1e-12);
            for c in crate::geom::Aabb3::new(min, max).corners() {
                let p = f.to_map(c);
                assert!(
                    p.x >= 0.0 && p.x <= 64.0 && p.y >= 0.0 && p.y <= 64.0,
                    "{p}"
                );
                assert!(p.z >= 0.0 && p.z <= f.depth_m, "{p}");
                let back = f.from_map(p.x, p.y, p.z);
                assert!((back - c).length() < 1e-9);
                // The clip matrix agrees: x = 2i/M − 1, y = 1 − 2j/M, z = d/depth.
                let q = f.clip_from_local() * c.extend(1.0);
                assert!((q.x - (2.0 * p.x / 64.0 - 1.0)).abs() < 1e-9);
                assert!((q.y - (1.0 - 2.0 * p.y / 64.0)).abs() < 1e-9);
                assert!((q.z - p.z / f.depth_m).abs() < 1e-9);
            }
        }
        let z = MapFrame::zenithal(min, max, 64);
        assert_eq!(z.v, DVec3::Y, "zenithal rows run north");
    }

    #[test]
    fn depths_quantise_within_half_a_step() {
        let f = MapFrame::zenithal(DVec3::ZERO, DVec3::new(10.0, 10.0, 300.0), 8);
        for d in [0.0, 0.001, 17.3, 150.0, f.depth_m] {
            let q = f.quantise_depth(d);
            assert!(q >= 1);
            assert!((f.depth_of(q) - d).abs() <= 0.5 * f.depth_m / 65534.0 + 1e-12);
        }
    }

    #[test]
    fn a_box_captured_from_above_fills_its_texels_with_its_height() {
        use crate::visibility::oracle::box_mesh;
        use glam::Vec3;
        let mesh = box_mesh(Vec3::new(2.0, 2.0, 0.0), Vec3::new(6.0, 4.0, 12.0));
        let min = DVec3::new(0.0, 0.0, 0.0);
        let max = DVec3::new(8.0, 8.0, 12.0);
        let f = MapFrame::zenithal(min, max, 8);
        let m = ReliefMap::capture(MapKind::Zenithal, f, &[(0, &mesh)], [0.0, 12.0]);
        let mut covered = 0;
        for j in 0..8u32 {
            for i in 0..8u32 {
                let c = f.from_map(i as f64 + 0.5, j as f64 + 0.5, 0.0);
                let inside = c.x > 2.0 && c.x < 6.0 && c.y > 2.0 && c.y < 4.0;
                let q = m.at(i, j);
                assert_eq!(q != EMPTY, inside, "texel {i},{j} at {c}");
                if inside {
                    covered += 1;
                    let z = f64::from(q) / 65535.0 * 12.0;
                    assert!((z - 12.0).abs() < 1e-3, "{z}");
                }
            }
        }
        assert_eq!(covered, 8);
        let p = m.pyramid();
        assert_eq!(p.len(), 4);
        assert_eq!(p[3].len(), 1);
        assert_eq!(p[3][0], m.depth.iter().copied().max().unwrap());
    }
}
