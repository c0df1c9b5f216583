//! The BlockMap texture: the revised RGBA8 layout of Di Benedetto, §4.2.1, its box and its storage as
//! a PNG plus a small JSON file.
//!
//! # Which version, and why
//! - **Texel format and sections: Di Benedetto, §4.2.1** (RGBA8, `(2K + 256) × K`), not the 2007 RGB8
//!   layout (Cignoni et al., §3.1): RGBA8 is PNG-encodable, carries AO and roof normals, and addresses 256
//!   wall columns in slices instead of rescaling the wall region along u.
//! - **Distance map: Cignoni et al., §3.1–3.2**, kept out of the texture (the revised B channel holds the
//!   roof normal x) as an optional side array ([`BlockMap::distance_map`]), derived from the
//!   height map, so that the space leap can be measured against the plain grid walk.
//!
//! # Texel addressing (row `j` of the image is height-map row `j`, south first)
//! | u | R | G | B | A |
//! |---|---|---|---|---|
//! | `[0, K)` shape | height code, 256 levels over `[zmin, zmax]`, 0 = empty | wall column offset, 0 = none, 1..=255 | roof normal x | roof normal y |
//! | `[K, 2K)` roof | colour r | g | b | AO (255 = open sky) |
//! | `[2K, 2K + 256)` walls | colour r | g | b | AO; last row of each slice: the column's normal xyz, A = 255 |
//! | `[2K + 256, 3K + 256)` edges | edge normal x | edge normal y | offset `o` | 255 = the texel has an edge, 0 = whole square |
//! | `[3K + 256, 4K + 256)` second edges | normal x | normal y | offset `o` | 255 = a second half-plane (only with a first) |
//!
//! - Offset `c` of height-map row `j` addresses image column `2K + c − 1` (column `2K + 255` is
//!   never used: offset 0 is reserved, BLOCKMAPS.md A.4-3) in slice `s = ⌊j·S/K⌋`, whose rows are
//!   `[s·K/S, (s+1)·K/S)`: `K/S − 1` colour rows over the box height, then the normal row.
//! - Normal components are stored as `byte = round(127·n) + 128`, decoded `(byte − 128)/127`:
//!   deviation from the `byte/127.5 − 1` reading of BLOCKMAPS.md A.2, so that a flat roof decodes to
//!   exactly `(0, 0, 1)`. The roof normal's z is rebuilt as `√max(0, 1 − x² − y²)` (Di Benedetto, §4.2.1).
//! - Heights decode as `zmin + code/255·(zmax − zmin)` so that `zmax` is exact (BLOCKMAPS.md A.4-4);
//!   `zmin` is the ground (0), and code 0 is empty: rays pass through, the ground is drawn elsewhere.
//! - Edges: `n = (decode_unit(R), decode_unit(G))` and `o = (B − 128)/127 · 0.75` texels
//!   ([`EDGE_OFFSET_RANGE`]; the half-plane cuts the square only for `|o| < ½(|nx| + |ny|) ≤ 0.71`).
//!   The builder computes `o` with the *decoded* `n` and rounds it up, so the stored half-plane
//!   still holds every footprint point of the texel (conservative). Maps written before the
//!   section existed (`(2K + 256) × K` PNGs) read as maps without edges.
//! - Second edges: a texel whose footprint part no single half-plane holds closely (a convex
//!   corner inside the texel, or a building narrower than the texel: two parallel sides) keeps
//!   `square ∩ H₁ ∩ H₂`, both half-planes encoded as above and each holding every footprint
//!   point of the texel, so the intersection does too. The diagnosis of hybrid frames
//!   (`blockmap::diagnose`) found the one-half-plane excess of such texels to be the largest
//!   class of wrong pixels on fly-overs. Maps written with one edge section (`(3K + 256) × K`)
//!   read as maps without second edges.

use super::BlockMapError;
use crate::geom::Aabb3;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The height-map sides a BlockMap may have (Di Benedetto, §4.2.1: "64 or 128" are best).
pub const ALLOWED_K: [u32; 3] = [32, 64, 128];

/// Width of the wall attribute section (8-bit offsets address 256 columns).
pub const WALL_COLUMNS: u32 = 256;

/// The largest edge offset the edge section encodes, texels (≥ ½·(|nx| + |ny|) for any decoded
/// normal).
pub const EDGE_OFFSET_RANGE: f32 = 0.75;

/// Image width of a map of side `k`: shape, roof and two edge sections (`4K`) plus the wall
/// columns.
#[inline]
pub const fn image_width(k: u32) -> u32 {
    4 * k + WALL_COLUMNS
}

/// A footprint edge inside a texel, decoded: the texel's solid is the part of its square where
/// `n·q ≤ o`, `q` the point relative to the texel centre in texels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    /// Outward normal of the kept part (not necessarily unit).
    pub n: [f32; 2],
    /// Offset, texels.
    pub o: f32,
}

impl Edge {
    /// Decodes an edge texel (`None` when its A byte is not 255).
    #[inline]
    pub fn decode(t: [u8; 4]) -> Option<Self> {
        (t[3] == 255).then(|| Self {
            n: [decode_unit(t[0]), decode_unit(t[1])],
            o: decode_offset(t[2]),
        })
    }
}

/// Decodes an edge offset byte: `(b − 128)/127 · EDGE_OFFSET_RANGE` (the shader's operations).
#[inline]
pub fn decode_offset(b: u8) -> f32 {
    (b as f32 - 128.0) / 127.0 * EDGE_OFFSET_RANGE
}

/// The smallest offset byte whose decoded offset is at least `o` (texels), or `None` past the
/// range.
pub fn encode_offset_up(o: f64) -> Option<u8> {
    let guess = (o / EDGE_OFFSET_RANGE as f64 * 127.0 + 128.0).floor() - 1.0;
    let mut b = guess.max(0.0);
    while b <= 255.0 {
        if decode_offset(b as u8) as f64 >= o {
            return Some(b as u8);
        }
        b += 1.0;
    }
    None
}

/// Encodes a unit-vector component in `[-1, 1]` as a byte (`round(127·c) + 128`).
#[inline]
pub fn encode_unit(c: f32) -> u8 {
    ((c.clamp(-1.0, 1.0) * 127.0).round() + 128.0) as u8
}

/// Decodes [`encode_unit`]: `(byte − 128)/127`, clamped to `[-1, 1]`.
#[inline]
pub fn decode_unit(b: u8) -> f32 {
    ((b as f32 - 128.0) / 127.0).clamp(-1.0, 1.0)
}

/// Where a BlockMap stands in the world and how it is quantised: the JSON side of a map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockMapMeta {
    /// Height-map side in texels (32, 64 or 128).
    pub k: u32,
    /// Lower corner of the box, local frame (x, y, and z = `zmin`), metres.
    pub min: [f64; 3],
    /// Side of the square base, metres.
    pub side: f64,
    /// Bottom of the height range (the ground), metres.
    pub zmin: f64,
    /// Top of the height range, metres (> `zmin`).
    pub zmax: f64,
    /// Number of wall slices (a power of two, `K/S ≥ 2`).
    pub slices: u32,
    /// Declared geometric error, metres (`max(½ voxel diagonal, measured)`, see `error`).
    pub eps_m: f64,
    /// The measured part of `eps_m` (sampled symmetric Hausdorff distance), metres.
    pub eps_measured_m: f64,
    /// Key of the quadtree node the map stands for (`0` when not from a tree).
    pub node_key: u64,
}

/// A BlockMap (Di Benedetto, §4.2.1): the RGBA8 image and its box.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockMap {
    /// Box, quantisation and error.
    pub meta: BlockMapMeta,
    /// `(2K + 256) × K` texels, RGBA, row-major, row 0 = height-map row 0 (south).
    pub texels: Vec<[u8; 4]>,
}

impl BlockMap {
    /// An empty map (no building, one slice) over the square with lower corner `min` and side
    /// `side`, heights over `[zmin, zmax]`.
    ///
    /// # Errors
    /// [`BlockMapError::BadParameter`] when `k` is not 32, 64 or 128, or the box is not finite
    /// with `side > 0` and `zmax > zmin`.
    pub fn empty(k: u32, min: DVec3, side: f64, zmax: f64) -> Result<Self, BlockMapError> {
        if !ALLOWED_K.contains(&k) {
            return Err(BlockMapError::BadParameter(format!(
                "K = {k}: expected one of 32, 64, 128 (Di Benedetto, §4.2.1)"
            )));
        }
        if !(min.is_finite() && side.is_finite() && side > 0.0 && zmax.is_finite()) || zmax <= min.z
        {
            return Err(BlockMapError::BadParameter(format!(
                "box min {min:?}, side {side}, zmax {zmax}: need finite, side > 0, zmax > zmin"
            )));
        }
        let w = image_width(k);
        let mut texels = vec![[0u8; 4]; (w * k) as usize];
        for j in 0..k {
            for i in 0..k {
                let t = &mut texels[(j * w + i) as usize];
                *t = [0, 0, 128, 128];
                texels[(j * w + k + i) as usize] = [0, 0, 0, 255];
                texels[(j * w + 2 * k + WALL_COLUMNS + i) as usize] = [128, 128, 128, 0];
                texels[(j * w + 3 * k + WALL_COLUMNS + i) as usize] = [128, 128, 128, 0];
            }
        }
        Ok(Self {
            meta: BlockMapMeta {
                k,
                min: min.to_array(),
                side,
                zmin: min.z,
                zmax,
                slices: 1,
                eps_m: 0.0,
                eps_measured_m: 0.0,
                node_key: 0,
            },
            texels,
        })
    }

    /// Height-map side K.
    #[inline]
    pub fn k(&self) -> u32 {
        self.meta.k
    }
    /// Image width `4K + 256`.
    #[inline]
    pub fn width(&self) -> u32 {
        image_width(self.meta.k)
    }
    /// Texel side in metres.
    #[inline]
    pub fn texel_m(&self) -> f64 {
        self.meta.side / self.meta.k as f64
    }
    /// Height step of one code, metres: `(zmax − zmin)/255`.
    #[inline]
    pub fn dz_m(&self) -> f64 {
        (self.meta.zmax - self.meta.zmin) / 255.0
    }
    /// Bytes of the texture (`(4K + 256)·K·4`: 128 KiB at K = 64).
    pub fn bytes(&self) -> usize {
        self.texels.len() * 4
    }
    /// The 3D box (local frame).
    pub fn aabb(&self) -> Aabb3 {
        let m = DVec3::from_array(self.meta.min);
        Aabb3::new(
            m,
            DVec3::new(m.x + self.meta.side, m.y + self.meta.side, self.meta.zmax),
        )
    }
    /// Half the diagonal of one voxel (Cignoni et al., §3.3): `½·√(2s² + Δz²)`.
    pub fn half_voxel_diagonal(&self) -> f64 {
        let s = self.texel_m();
        let dz = self.dz_m();
        0.5 * (2.0 * s * s + dz * dz).sqrt()
    }

    #[inline]
    fn idx(&self, u: u32, v: u32) -> usize {
        (v * self.width() + u) as usize
    }
    /// Texel at image column `u`, row `v`.
    #[inline]
    pub fn texel(&self, u: u32, v: u32) -> [u8; 4] {
        self.texels[self.idx(u, v)]
    }
    /// Mutable texel at image column `u`, row `v`.
    #[inline]
    pub fn texel_mut(&mut self, u: u32, v: u32) -> &mut [u8; 4] {
        let k = self.idx(u, v);
        &mut self.texels[k]
    }
    /// Height code of height-map texel `(i, j)` (0 = empty).
    #[inline]
    pub fn height_code(&self, i: u32, j: u32) -> u8 {
        self.texel(i, j)[0]
    }
    /// Height of a code, metres (local z).
    #[inline]
    pub fn code_height_m(&self, code: u8) -> f64 {
        self.meta.zmin + code as f64 / 255.0 * (self.meta.zmax - self.meta.zmin)
    }
    /// Height (local z, metres) of the column at texel `(i, j)`; `None` for an empty texel
    /// (code 0) and outside the map.
    #[inline]
    pub fn texel_height_m(&self, i: i64, j: i64) -> Option<f64> {
        let k = i64::from(self.meta.k);
        if i < 0 || j < 0 || i >= k || j >= k {
            return None;
        }
        match self.height_code(i as u32, j as u32) {
            0 => None,
            c => Some(self.code_height_m(c)),
        }
    }
    /// Image column of the edge texel of height-map column `i`.
    #[inline]
    pub fn edge_u(&self, i: u32) -> u32 {
        2 * self.meta.k + WALL_COLUMNS + i
    }
    /// The footprint edge of texel `(i, j)`, if it has one.
    #[inline]
    pub fn edge(&self, i: u32, j: u32) -> Option<Edge> {
        Edge::decode(self.texel(self.edge_u(i), j))
    }
    /// Sets (or, with `None`, clears) the edge bytes of texel `(i, j)`: normal bytes and offset
    /// byte as [`Edge::decode`] reads them.
    pub fn set_edge_bytes(&mut self, i: u32, j: u32, e: Option<[u8; 3]>) {
        let u = self.edge_u(i);
        *self.texel_mut(u, j) = match e {
            Some([x, y, o]) => [x, y, o, 255],
            None => [128, 128, 128, 0],
        };
    }
    /// Image column of the second edge texel of height-map column `i`.
    #[inline]
    pub fn edge2_u(&self, i: u32) -> u32 {
        3 * self.meta.k + WALL_COLUMNS + i
    }
    /// The second footprint edge of texel `(i, j)`, if it has one (only read with a first).
    #[inline]
    pub fn edge2(&self, i: u32, j: u32) -> Option<Edge> {
        Edge::decode(self.texel(self.edge2_u(i), j))
    }
    /// Sets (or clears) the second edge bytes of texel `(i, j)`, as [`BlockMap::set_edge_bytes`].
    pub fn set_edge2_bytes(&mut self, i: u32, j: u32, e: Option<[u8; 3]>) {
        let u = self.edge2_u(i);
        *self.texel_mut(u, j) = match e {
            Some([x, y, o]) => [x, y, o, 255],
            None => [128, 128, 128, 0],
        };
    }
    /// The half-planes of texel `(i, j)`: none, the first, or both (a second edge counts only
    /// with a first, as the casters read them).
    pub fn edges(&self, i: u32, j: u32) -> [Option<Edge>; 2] {
        match self.edge(i, j) {
            None => [None, None],
            Some(e) => [Some(e), self.edge2(i, j)],
        }
    }
    /// Texels with two edges.
    pub fn edge2_texels(&self) -> usize {
        let k = self.k();
        (0..k)
            .flat_map(|j| (0..k).map(move |i| (i, j)))
            .filter(|&(i, j)| self.height_code(i, j) > 0 && self.edges(i, j)[1].is_some())
            .count()
    }
    /// Texels with an edge.
    pub fn edge_texels(&self) -> usize {
        let k = self.k();
        (0..k)
            .flat_map(|j| (0..k).map(move |i| (i, j)))
            .filter(|&(i, j)| self.height_code(i, j) > 0 && self.edge(i, j).is_some())
            .count()
    }
    /// Wall column offset of texel `(i, j)` (0 = none).
    #[inline]
    pub fn wall_offset(&self, i: u32, j: u32) -> u8 {
        self.texel(i, j)[1]
    }
    /// Slice of height-map row `j`: `⌊j·S/K⌋`.
    #[inline]
    pub fn slice_of_row(&self, j: u32) -> u32 {
        j * self.meta.slices / self.meta.k
    }
    /// Rows per slice `K/S` (the last is the normal row).
    #[inline]
    pub fn slice_rows(&self) -> u32 {
        self.meta.k / self.meta.slices
    }
    /// Image column of wall offset `c` (1..=255): `2K + c − 1`.
    #[inline]
    pub fn wall_u(&self, c: u8) -> u32 {
        2 * self.meta.k + c as u32 - 1
    }
    /// Image row of the wall colour of height-map row `j` at normalised height `z01` ∈ [0, 1].
    pub fn wall_color_row(&self, j: u32, z01: f32) -> u32 {
        let r = self.slice_rows();
        let colour_rows = r - 1;
        let k = ((z01 * colour_rows as f32).floor() as i64).clamp(0, colour_rows as i64 - 1) as u32;
        self.slice_of_row(j) * r + k
    }
    /// Image row of the wall normal of height-map row `j`.
    pub fn wall_normal_row(&self, j: u32) -> u32 {
        let r = self.slice_rows();
        self.slice_of_row(j) * r + r - 1
    }
    /// Roof normal of texel `(i, j)` (unit, upper hemisphere).
    pub fn roof_normal(&self, i: u32, j: u32) -> Vec3 {
        let t = self.texel(i, j);
        let (x, y) = (decode_unit(t[2]), decode_unit(t[3]));
        Vec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
    }

    /// The 2007 distance map (Cignoni et al., §3.1–3.2), computed from the height map: per texel, the
    /// Chebyshev distance in texels to the nearest non-empty texel, clamped to 255 (0 on a
    /// building). Units and metric are not in the paper (BLOCKMAPS.md A.4-8): this reading makes
    /// a leap of `D − 1` texels in max-norm safe.
    pub fn distance_map(&self) -> Vec<u8> {
        let k = self.k() as usize;
        let mut d = vec![255u32; k * k];
        for j in 0..k {
            for i in 0..k {
                if self.height_code(i as u32, j as u32) > 0 {
                    d[j * k + i] = 0;
                }
            }
        }
        // Two-pass chamfer with unit weights in all 8 directions = exact Chebyshev distance.
        for j in 0..k {
            for i in 0..k {
                let mut v = d[j * k + i];
                if i > 0 {
                    v = v.min(d[j * k + i - 1] + 1);
                }
                if j > 0 {
                    v = v.min(d[(j - 1) * k + i] + 1);
                    if i > 0 {
                        v = v.min(d[(j - 1) * k + i - 1] + 1);
                    }
                    if i + 1 < k {
                        v = v.min(d[(j - 1) * k + i + 1] + 1);
                    }
                }
                d[j * k + i] = v;
            }
        }
        for j in (0..k).rev() {
            for i in (0..k).rev() {
                let mut v = d[j * k + i];
                if i + 1 < k {
                    v = v.min(d[j * k + i + 1] + 1);
                }
                if j + 1 < k {
                    v = v.min(d[(j + 1) * k + i] + 1);
                    if i + 1 < k {
                        v = v.min(d[(j + 1) * k + i + 1] + 1);
                    }
                    if i > 0 {
                        v = v.min(d[(j + 1) * k + i - 1] + 1);
                    }
                }
                d[j * k + i] = v;
            }
        }
        d.into_iter().map(|v| v.min(255) as u8).collect()
    }

    /// The image as an `image::RgbaImage` (row 0 = height-map row 0).
    pub fn to_image(&self) -> image::RgbaImage {
        let mut img = image::RgbaImage::new(self.width(), self.k());
        for (p, t) in img.pixels_mut().zip(&self.texels) {
            *p = image::Rgba(*t);
        }
        img
    }

    /// Writes `DIR/NAME.png` (lossless RGBA8) and `DIR/NAME.json` (the [`BlockMapMeta`]).
    ///
    /// # Errors
    /// [`BlockMapError::Io`] naming the file.
    pub fn write(&self, dir: &Path, name: &str) -> Result<(PathBuf, PathBuf), BlockMapError> {
        let png = dir.join(format!("{name}.png"));
        let json = dir.join(format!("{name}.json"));
        crate::output::write_png(&png, &self.to_image()).map_err(|e| BlockMapError::Io {
            path: png.clone(),
            what: e.to_string(),
        })?;
        let text = serde_json::to_string_pretty(&self.meta).map_err(|e| BlockMapError::Io {
            path: json.clone(),
            what: e.to_string(),
        })?;
        crate::output::write_bytes(&json, text)
            .map(drop)
            .map_err(crate::output::OutputError::into_io)
            .map_err(|e| BlockMapError::Io {
                path: json.clone(),
                what: e.to_string(),
            })?;
        Ok((png, json))
    }

    /// Reads a map written by [`BlockMap::write`] (`png` and its `.json` beside it).
    ///
    /// # Errors
    /// [`BlockMapError::Io`] for unreadable files, [`BlockMapError::BadFile`] when the image size
    /// does not match K or the slice count is not valid.
    pub fn read(png: &Path) -> Result<Self, BlockMapError> {
        let json = png.with_extension("json");
        let text = std::fs::read_to_string(&json).map_err(|e| BlockMapError::Io {
            path: json.clone(),
            what: e.to_string(),
        })?;
        let meta: BlockMapMeta =
            serde_json::from_str(&text).map_err(|e| BlockMapError::BadFile {
                path: json.clone(),
                what: e.to_string(),
            })?;
        let bytes = std::fs::read(png).map_err(|e| BlockMapError::Io {
            path: png.to_path_buf(),
            what: e.to_string(),
        })?;
        Self::decode_png(meta, &bytes, png)
    }

    /// A map from its [`BlockMapMeta`] and the bytes of its PNG (as [`BlockMap::write`] writes
    /// it); `path` names the file in errors.
    ///
    /// # Errors
    /// [`BlockMapError::BadFile`] when the bytes are not a PNG, the image size does not match K
    /// or the slice count is not valid.
    pub fn decode_png(
        meta: BlockMapMeta,
        bytes: &[u8],
        path: &Path,
    ) -> Result<Self, BlockMapError> {
        let png = path;
        let bad = |what: String| BlockMapError::BadFile {
            path: png.to_path_buf(),
            what,
        };
        let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
            .map_err(|e| bad(e.to_string()))?
            .into_rgba8();
        if !ALLOWED_K.contains(&meta.k) {
            return Err(bad(format!("K = {} is not 32, 64 or 128", meta.k)));
        }
        // Older layouts: without edges (`2K + 256`) or with one edge section (`3K + 256`).
        let sections = (2..=4)
            .find(|n| img.dimensions() == (n * meta.k + WALL_COLUMNS, meta.k))
            .ok_or_else(|| {
                bad(format!(
                    "image is {:?}, K = {} needs {}x{} (or {}x{} / {}x{} from older layouts)",
                    img.dimensions(),
                    meta.k,
                    image_width(meta.k),
                    meta.k,
                    3 * meta.k + WALL_COLUMNS,
                    meta.k,
                    2 * meta.k + WALL_COLUMNS,
                    meta.k
                ))
            })?;
        if meta.slices == 0 || !meta.slices.is_power_of_two() || meta.k / meta.slices < 2 {
            return Err(bad(format!(
                "slice count {} is invalid for K = {}",
                meta.slices, meta.k
            )));
        }
        let k = meta.k;
        let w0 = sections * k + WALL_COLUMNS;
        let pad = ((4 - sections) * k) as usize;
        let mut texels = Vec::with_capacity((image_width(k) * k) as usize);
        for row in img
            .pixels()
            .map(|p| p.0)
            .collect::<Vec<_>>()
            .chunks(w0 as usize)
        {
            // The missing edge sections read as texels without edges.
            texels.extend_from_slice(row);
            texels.extend(std::iter::repeat_n([128, 128, 128, 0], pad));
        }
        Ok(Self { meta, texels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_encoding_is_exact_at_zero_and_ends() {
        assert_eq!(decode_unit(encode_unit(0.0)), 0.0);
        assert_eq!(decode_unit(encode_unit(1.0)), 1.0);
        assert_eq!(decode_unit(encode_unit(-1.0)), -1.0);
        for b in 1..=255u8 {
            assert_eq!(encode_unit(decode_unit(b)), b);
        }
    }

    #[test]
    fn sizes_follow_the_layout() {
        for (k, kib) in [(32, 48), (64, 128), (128, 384)] {
            let m = BlockMap::empty(k, DVec3::ZERO, 100.0, 30.0).unwrap();
            assert_eq!(m.bytes(), kib * 1024, "K = {k}");
        }
        assert!(matches!(
            BlockMap::empty(48, DVec3::ZERO, 100.0, 30.0),
            Err(BlockMapError::BadParameter(_))
        ));
        assert!(matches!(
            BlockMap::empty(64, DVec3::ZERO, 100.0, 0.0),
            Err(BlockMapError::BadParameter(_))
        ));
    }

    #[test]
    fn edge_offsets_round_up_and_decode_as_the_shader() {
        for o in [-0.7, -0.31, 0.0, 0.001, 0.2, 0.5, 0.7] {
            let b = encode_offset_up(o).unwrap();
            assert!(decode_offset(b) as f64 >= o, "{o}");
            assert!(
                b == 0 || (decode_offset(b - 1) as f64) < o,
                "{o}: not the smallest"
            );
        }
        assert_eq!(encode_offset_up(0.8), None);
        let mut m = BlockMap::empty(32, DVec3::ZERO, 32.0, 10.0).unwrap();
        assert_eq!(m.edge(3, 4), None);
        m.set_edge_bytes(3, 4, Some([255, 128, 140]));
        let e = m.edge(3, 4).unwrap();
        assert_eq!(e.n, [1.0, 0.0]);
        assert!((e.o - 12.0 / 127.0 * 0.75).abs() < 1e-7);
        m.set_edge_bytes(3, 4, None);
        assert_eq!(m.edge(3, 4), None);
    }

    #[test]
    fn legacy_images_read_without_edges() {
        let m = BlockMap::empty(32, DVec3::ZERO, 32.0, 10.0).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let (png, _) = m.write(dir.path(), "a").unwrap();
        let w0 = 2 * 32 + WALL_COLUMNS;
        let mut old = image::RgbaImage::new(w0, 32);
        for (x, y, p) in old.enumerate_pixels_mut() {
            *p = image::Rgba(m.texel(x, y));
        }
        old.save(&png).unwrap();
        let back = BlockMap::read(&png).unwrap();
        assert_eq!(back, m);
        // One edge section: the first edges stay, no second edge.
        let mut m1 = BlockMap::empty(32, DVec3::ZERO, 32.0, 10.0).unwrap();
        m1.texel_mut(5, 6)[0] = 9;
        m1.set_edge_bytes(5, 6, Some([255, 128, 140]));
        let w1 = 3 * 32 + WALL_COLUMNS;
        let mut one = image::RgbaImage::new(w1, 32);
        for (x, y, p) in one.enumerate_pixels_mut() {
            *p = image::Rgba(m1.texel(x, y));
        }
        m1.write(dir.path(), "b").unwrap();
        one.save(dir.path().join("b.png")).unwrap();
        let back = BlockMap::read(&dir.path().join("b.png")).unwrap();
        assert_eq!(back, m1);
        assert!(back.edge(5, 6).is_some() && back.edge2(5, 6).is_none());
        // A width of no layout is a clear error.
        image::RgbaImage::new(w1 + 1, 32)
            .save(dir.path().join("b.png"))
            .unwrap();
        assert!(matches!(
            BlockMap::read(&dir.path().join("b.png")),
            Err(BlockMapError::BadFile { .. })
        ));
    }

    #[test]
    fn distance_map_is_chebyshev() {
        let mut m = BlockMap::empty(32, DVec3::ZERO, 32.0, 10.0).unwrap();
        m.texel_mut(10, 20)[0] = 7;
        let d = m.distance_map();
        assert_eq!(d[20 * 32 + 10], 0);
        assert_eq!(d[20 * 32 + 13], 3);
        assert_eq!(d[23 * 32 + 12], 3);
        assert_eq!(d[0], 20);
    }
}
