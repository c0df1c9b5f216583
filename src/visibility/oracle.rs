//! The visibility oracle: a CPU z-buffer rasteriser that draws block ids, the ground truth the
//! cull map is checked against, and a simple shaded fallback renderer.
//!
//! Triangles are transformed in f64, clipped against the near and far planes in homogeneous clip
//! space, and sampled at pixel centres with a top-left style tie rule (a pixel centre on an edge
//! shared by two triangles belongs to exactly one). Depth is `z/w`, which is affine in screen
//! space, so interpolating it with screen barycentrics is exact. No back-face culling: a block
//! counts as visible wherever any of its triangles wins the depth test.

use crate::blocks::BlockId;
use crate::city::appearance::{self, BuildingStyle};
use crate::city::Mesh;
use crate::geom::clip::clip_polygon;
use crate::geom::Camera;
use crate::visibility::terrain::TERRAIN_ID;
use glam::{DMat4, DVec2, DVec3, DVec4, Vec3};
use rayon::prelude::*;
use std::collections::BTreeSet;

/// Id of a pixel that shows no block.
pub const SKY: u32 = u32::MAX;

/// Block ids and depths of an image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct IdBuffer {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Block id per pixel ([`SKY`] where nothing was drawn).
    pub ids: Vec<u32>,
    /// Depth per pixel (`z/w` in `[0, 1]`, 1 = far plane / sky).
    pub depth: Vec<f32>,
}

impl IdBuffer {
    /// The set of blocks with at least one pixel ([`SKY`] and terrain, [`TERRAIN_ID`], are no
    /// blocks).
    pub fn visible(&self) -> BTreeSet<BlockId> {
        let mut seen: Vec<u32> = self
            .ids
            .iter()
            .copied()
            .filter(|&i| i != SKY && i != TERRAIN_ID)
            .collect();
        seen.sort_unstable();
        seen.dedup();
        seen.into_iter().map(BlockId).collect()
    }
}

/// Id of a pixel that shows the ground (plane, streets, blocks' ground) in [`shade_with_ground`];
/// never in an [`IdBuffer`] that [`render_ids`] returns.
const GROUND_ID: u32 = u32::MAX - 1;

/// What shading a triangle needs (the lit pass only).
#[derive(Clone, Copy, Debug)]
struct TriShading {
    style: BuildingStyle,
    /// A terrain triangle (layer id [`TERRAIN_ID`]): coloured [`appearance::TERRAIN`], not by
    /// `style`.
    terrain: bool,
    /// The mesh normal (flat: that of the first vertex), as the shader gets it.
    normal: Vec3,
    /// 1/w of the three screen vertices, for perspective-correct interpolation.
    inv_w: [f64; 3],
    /// (u, z) of the three screen vertices.
    uz: [DVec2; 3],
}

#[derive(Clone, Copy, Debug)]
struct ScreenTri {
    p: [DVec3; 3],
    id: u32,
    /// Ground layers: drawn in order, the depth test always passing (as the GPU does).
    always: bool,
    ymin: i64,
    ymax: i64,
}

/// A clip-space vertex and the attributes (u, z) carried through clipping.
#[derive(Clone, Copy, Debug)]
struct ClipVertex {
    c: DVec4,
    a: DVec2,
}

// Clipping interpolates the clip-space position and the attributes together
// (geom::clip::clip_polygon works on any vector-like vertex).
impl std::ops::Add for ClipVertex {
    type Output = ClipVertex;
    fn add(self, o: ClipVertex) -> ClipVertex {
        ClipVertex {
            c: self.c + o.c,
            a: self.a + o.a,
        }
    }
}

impl std::ops::Sub for ClipVertex {
    type Output = ClipVertex;
    fn sub(self, o: ClipVertex) -> ClipVertex {
        ClipVertex {
            c: self.c - o.c,
            a: self.a - o.a,
        }
    }
}

impl std::ops::Mul<f64> for ClipVertex {
    type Output = ClipVertex;
    fn mul(self, t: f64) -> ClipVertex {
        ClipVertex {
            c: self.c * t,
            a: self.a * t,
        }
    }
}

/// One mesh to project: its id, whether it is a ground layer, and the mesh.
type Layer<'a> = (u32, bool, &'a Mesh);

fn project(
    layers: &[Layer<'_>],
    clip_from_world: &DMat4,
    width: u32,
    height: u32,
    with_shading: bool,
) -> (Vec<ScreenTri>, Vec<TriShading>) {
    let m = *clip_from_world;
    let (w, h) = (width as f64, height as f64);
    let mut out = Vec::new();
    // Parallel to `out` when shading (kept apart so that the id pass stays lean).
    let mut shadings = Vec::new();
    let mut poly = Vec::with_capacity(8);
    let mut tmp = Vec::with_capacity(8);
    let mut screen: Vec<DVec3> = Vec::with_capacity(8);
    for &(id, always, mesh) in layers {
        for t in mesh.indices.chunks_exact(3) {
            let (Some(a), Some(b), Some(d)) = (
                mesh.positions.get(t[0] as usize),
                mesh.positions.get(t[1] as usize),
                mesh.positions.get(t[2] as usize),
            ) else {
                continue;
            };
            let v = [a.as_dvec3(), b.as_dvec3(), d.as_dvec3()];
            let c = v.map(|p| m * p.extend(1.0));
            // Trivially outside one side plane: skip.
            if c.iter().all(|q| q.x > q.w)
                || c.iter().all(|q| q.x < -q.w)
                || c.iter().all(|q| q.y > q.w)
                || c.iter().all(|q| q.y < -q.w)
            {
                continue;
            }
            poly.clear();
            poly.extend(c.iter().zip(t).zip(&v).map(|((&c, &i), p)| {
                let u = if with_shading {
                    mesh.vertex_style(i as usize).1 as f64
                } else {
                    0.0
                };
                ClipVertex {
                    c,
                    a: DVec2::new(u, p.z),
                }
            }));
            clip_polygon(&mut poly, &mut tmp, |q| q.c.z); // near: z ≥ 0
            if poly.len() < 3 {
                continue;
            }
            clip_polygon(&mut poly, &mut tmp, |q| q.c.w - q.c.z); // far: z ≤ w
            if poly.len() < 3 {
                continue;
            }
            let style = with_shading.then(|| {
                let i = t[0] as usize;
                (
                    mesh.vertex_style(i).0,
                    mesh.normals.get(i).copied().unwrap_or(Vec3::Z),
                )
            });
            screen.clear();
            screen.extend(poly.iter().map(|q| {
                let q = q.c;
                DVec3::new(
                    (q.x / q.w + 1.0) * 0.5 * w,
                    (1.0 - q.y / q.w) * 0.5 * h,
                    q.z / q.w,
                )
            }));
            let s = &screen;
            for k in 1..s.len() - 1 {
                let p = [s[0], s[k], s[k + 1]];
                let ymin = p.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
                let ymax = p.iter().map(|q| q.y).fold(f64::NEG_INFINITY, f64::max);
                if !(ymin.is_finite() && ymax.is_finite()) {
                    continue;
                }
                if let Some((style, normal)) = style {
                    let q = [poly[0], poly[k], poly[k + 1]];
                    shadings.push(TriShading {
                        style,
                        terrain: id == TERRAIN_ID,
                        normal,
                        inv_w: q.map(|v| 1.0 / v.c.w),
                        uz: q.map(|v| v.a),
                    });
                }
                out.push(ScreenTri {
                    p,
                    id,
                    always,
                    ymin: (ymin - 0.5).ceil().max(0.0) as i64,
                    ymax: ((ymax - 0.5).floor()).min(h - 1.0) as i64,
                });
            }
        }
    }
    (out, shadings)
}

#[inline]
fn edge(a: DVec3, b: DVec3, px: f64, py: f64) -> f64 {
    (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x)
}

/// Owns a pixel centre lying exactly on the edge `a → b`: exactly one of the two directions of a
/// shared edge does.
#[inline]
fn owns_tie(a: DVec3, b: DVec3) -> bool {
    let d = b - a;
    d.y > 0.0 || (d.y == 0.0 && d.x < 0.0)
}

fn raster(
    tris: &[ScreenTri],
    shadings: &[TriShading],
    width: u32,
    mut colors: Option<&mut [[u8; 3]]>,
    ids: &mut [u32],
    depth: &mut [f32],
    row0: usize,
) {
    let w = width as usize;
    let rows = ids.len() / w.max(1);
    let (r0, r1) = (row0 as i64, (row0 + rows) as i64 - 1);
    for (i, t) in tris.iter().enumerate() {
        if t.ymax < r0 || t.ymin > r1 {
            continue;
        }
        let mut p = t.p;
        let mut shading = shadings.get(i).copied();
        let mut area = edge(p[0], p[1], p[2].x, p[2].y);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        if area < 0.0 {
            p.swap(1, 2);
            if let Some(s) = shading.as_mut() {
                s.inv_w.swap(1, 2);
                s.uz.swap(1, 2);
            }
            area = -area;
        }
        let xmin = p.iter().map(|q| q.x).fold(f64::INFINITY, f64::min);
        let xmax = p.iter().map(|q| q.x).fold(f64::NEG_INFINITY, f64::max);
        let x0 = ((xmin - 0.5).ceil().max(0.0)) as i64;
        let x1 = ((xmax - 0.5).floor().min(width as f64 - 1.0)) as i64;
        let tie = [
            owns_tie(p[1], p[2]),
            owns_tie(p[2], p[0]),
            owns_tie(p[0], p[1]),
        ];
        for y in t.ymin.max(r0)..=t.ymax.min(r1) {
            let py = y as f64 + 0.5;
            let row = (y - r0) as usize * w;
            for x in x0..=x1 {
                let px = x as f64 + 0.5;
                let e0 = edge(p[1], p[2], px, py);
                let e1 = edge(p[2], p[0], px, py);
                let e2 = edge(p[0], p[1], px, py);
                let inside = (e0 > 0.0 || (e0 == 0.0 && tie[0]))
                    && (e1 > 0.0 || (e1 == 0.0 && tie[1]))
                    && (e2 > 0.0 || (e2 == 0.0 && tie[2]));
                if !inside {
                    continue;
                }
                let z = ((e0 * p[0].z + e1 * p[1].z + e2 * p[2].z) / area) as f32;
                let k = row + x as usize;
                if t.always || z < depth[k] {
                    depth[k] = z;
                    ids[k] = t.id;
                    if let (Some(c), Some(s)) = (colors.as_deref_mut(), shading.as_ref()) {
                        c[k] = pixel_color(s, [e0, e1, e2]);
                    }
                }
            }
        }
    }
}

/// The lit colour of a pixel with screen-space edge functions `e` (barycentrics × area): u and
/// z interpolated perspective-correctly (as the GPU interpolates its varyings), then
/// [`appearance::surface_color`] and [`appearance::shade`], as `mesh.wgsl` does.
fn pixel_color(s: &TriShading, e: [f64; 3]) -> [u8; 3] {
    let wgt = [e[0] * s.inv_w[0], e[1] * s.inv_w[1], e[2] * s.inv_w[2]];
    let sum = wgt[0] + wgt[1] + wgt[2];
    let uz = if sum != 0.0 && sum.is_finite() {
        (s.uz[0] * wgt[0] + s.uz[1] * wgt[1] + s.uz[2] * wgt[2]) / sum
    } else {
        s.uz[0]
    };
    let n = s.normal.normalize_or_zero();
    let base = if s.terrain {
        appearance::unit_rgb(appearance::TERRAIN)
    } else {
        appearance::surface_color(&s.style, n, uz.x as f32, uz.y as f32)
    };
    appearance::to_rgb8(appearance::shade(base, n))
}

const BAND: usize = 16;

fn render(
    layers: &[Layer<'_>],
    camera: &Camera,
    width: u32,
    height: u32,
    with_color: bool,
) -> (IdBuffer, Vec<[u8; 3]>) {
    render_clip(layers, &camera.clip_from_world(), width, height, with_color)
}

fn render_clip(
    layers: &[Layer<'_>],
    clip_from_world: &DMat4,
    width: u32,
    height: u32,
    with_color: bool,
) -> (IdBuffer, Vec<[u8; 3]>) {
    let (tris, shadings) = project(layers, clip_from_world, width, height, with_color);
    let n = width as usize * height as usize;
    let mut ids = vec![SKY; n];
    let mut depth = vec![1.0f32; n];
    let mut colors = vec![[0u8; 3]; if with_color { n } else { 0 }];
    let band = BAND * width as usize;
    if n > 0 {
        if with_color {
            ids.par_chunks_mut(band)
                .zip(depth.par_chunks_mut(band))
                .zip(colors.par_chunks_mut(band))
                .enumerate()
                .for_each(|(b, ((i, d), c))| {
                    raster(&tris, &shadings, width, Some(c), i, d, b * BAND)
                });
        } else {
            ids.par_chunks_mut(band)
                .zip(depth.par_chunks_mut(band))
                .enumerate()
                .for_each(|(b, (i, d))| raster(&tris, &shadings, width, None, i, d, b * BAND));
        }
    }
    (
        IdBuffer {
            width,
            height,
            ids,
            depth,
        },
        colors,
    )
}

fn block_layers<'a>(blocks: &[(BlockId, &'a Mesh)]) -> Vec<Layer<'a>> {
    blocks.iter().map(|(id, m)| (id.0, false, *m)).collect()
}

/// Draws the blocks' meshes (local frame) seen by `camera` into an id and depth buffer.
pub fn render_ids(
    blocks: &[(BlockId, &Mesh)],
    camera: &Camera,
    width: u32,
    height: u32,
) -> IdBuffer {
    render(&block_layers(blocks), camera, width, height, false).0
}

/// Draws the blocks' meshes (local frame) through any `clip_from_world` (perspective or
/// orthographic, depth `z/w` in `[0, 1]`, nearer is smaller) into an id and depth buffer. Pixel
/// row 0 is clip `y = +1`.
pub fn render_ids_clip(
    blocks: &[(BlockId, &Mesh)],
    clip_from_world: &DMat4,
    width: u32,
    height: u32,
) -> IdBuffer {
    render_clip(&block_layers(blocks), clip_from_world, width, height, false).0
}

/// Lit colours, ids and depths of `meshes` (an id and a mesh each, local frame) through any
/// `clip_from_world` (orthographic included; depth `z/w` in `[0, 1]`, nearer is smaller), as
/// [`shade_with_ground`] shades them but with no ground: pixels nothing covers keep [`SKY`] and
/// colour `[0, 0, 0]`. Pixel row 0 is clip `y = +1`. What far-field maps are captured with.
pub fn shade_ids_clip(
    meshes: &[(u32, &Mesh)],
    clip_from_world: &DMat4,
    width: u32,
    height: u32,
) -> (IdBuffer, Vec<[u8; 3]>) {
    let layers: Vec<Layer<'_>> = meshes.iter().map(|&(id, m)| (id, false, m)).collect();
    render_clip(&layers, clip_from_world, width, height, true)
}

/// The blocks with at least one pixel in a `width × height` image from `camera`: the visibility
/// ground truth at that resolution.
pub fn visible_blocks(
    blocks: &[(BlockId, &Mesh)],
    camera: &Camera,
    width: u32,
    height: u32,
) -> BTreeSet<BlockId> {
    render_ids(blocks, camera, width, height).visible()
}

/// The blocks seen by at least one of `samples × samples` regularly spaced samples in some
/// pixel of a `width × height` image from `camera`: the stricter ground truth, which also sees
/// what is thinner than a pixel (a block seen through a gap narrower than the pixel spacing).
/// Samples sit at `(x + (i + ½) / samples, y + (j + ½) / samples)` of pixel `(x, y)`, so
/// `samples = 1` is [`visible_blocks`]; the image is the same view (same frustum) sampled
/// `samples` times finer along each axis.
pub fn visible_blocks_supersampled(
    blocks: &[(BlockId, &Mesh)],
    camera: &Camera,
    width: u32,
    height: u32,
    samples: u32,
) -> BTreeSet<BlockId> {
    let s = samples.max(1);
    render_ids(
        blocks,
        camera,
        width.saturating_mul(s),
        height.saturating_mul(s),
    )
    .visible()
}

/// The id layers of blocks over a terrain: the terrain first (id [`TERRAIN_ID`], depth-tested
/// like every block), then the blocks.
fn terrain_layers<'a>(blocks: &[(BlockId, &'a Mesh)], terrain: &[&'a Mesh]) -> Vec<Layer<'a>> {
    let mut layers: Vec<Layer<'a>> = terrain.iter().map(|&m| (TERRAIN_ID, false, m)).collect();
    layers.extend(block_layers(blocks));
    layers
}

/// As [`render_ids`], with `terrain` (local frame) drawn first as an occluder: its pixels carry
/// [`TERRAIN_ID`] (which [`IdBuffer::visible`] never reports) and its depth hides what is behind
/// it.
pub fn render_ids_with_terrain(
    blocks: &[(BlockId, &Mesh)],
    terrain: &Mesh,
    camera: &Camera,
    width: u32,
    height: u32,
) -> IdBuffer {
    render(
        &terrain_layers(blocks, &[terrain]),
        camera,
        width,
        height,
        false,
    )
    .0
}

/// [`visible_blocks_supersampled`] with an optional `terrain` occluder (see
/// [`render_ids_with_terrain`]); without one it is [`visible_blocks_supersampled`] itself.
pub fn visible_blocks_with_terrain(
    blocks: &[(BlockId, &Mesh)],
    terrain: Option<&Mesh>,
    camera: &Camera,
    width: u32,
    height: u32,
    samples: u32,
) -> BTreeSet<BlockId> {
    let Some(terrain) = terrain else {
        return visible_blocks_supersampled(blocks, camera, width, height, samples);
    };
    let s = samples.max(1);
    render_ids_with_terrain(
        blocks,
        terrain,
        camera,
        width.saturating_mul(s),
        height.saturating_mul(s),
    )
    .visible()
}

/// A lit image of the blocks on a terrain given as meshes (`terrain`: the tiles to draw, local
/// frame), and the depth buffer: the terrain in [`appearance::TERRAIN`] lit by
/// [`appearance::shade`] with the normal of each triangle's first vertex, then the blocks, both
/// with the `<` depth test, under the sky. No ground plane and no flat ground layers
/// ([`crate::visibility::draws_flat_ground`]). The GPU mesh renderer's terrain frames, pixel for
/// pixel up to rounding.
pub fn shade_with_terrain_depth(
    blocks: &[(BlockId, &Mesh)],
    terrain: &[&Mesh],
    camera: &Camera,
    width: u32,
    height: u32,
) -> (image::RgbaImage, Vec<f32>) {
    let (buf, colors) = render(
        &terrain_layers(blocks, terrain),
        camera,
        width,
        height,
        true,
    );
    (lit_image(&buf, &colors), buf.depth)
}

/// [`shade_with_terrain_depth`]'s image.
pub fn shade_with_terrain(
    blocks: &[(BlockId, &Mesh)],
    terrain: &[&Mesh],
    camera: &Camera,
    width: u32,
    height: u32,
) -> image::RgbaImage {
    shade_with_terrain_depth(blocks, terrain, camera, width, height).0
}

/// The lit image of a colour pass: the colours where something was drawn, sky elsewhere.
fn lit_image(buf: &IdBuffer, colors: &[[u8; 3]]) -> image::RgbaImage {
    let [r, g, b] = appearance::SKY;
    let mut img = image::RgbaImage::from_pixel(buf.width, buf.height, image::Rgba([r, g, b, 255]));
    for (k, px) in img.pixels_mut().enumerate() {
        if buf.ids[k] != SKY {
            let [r, g, b] = colors[k];
            *px = image::Rgba([r, g, b, 255]);
        }
    }
    img
}

/// A lit image of the blocks on the ground plane under the sky: the CPU fallback of the GPU
/// mesh renderer's lit frames, with the same appearance ([`crate::city::appearance`]: facade
/// windows, roofs, ground floors, the same sun and ambient term). See [`shade_with_ground`].
pub fn shade(
    blocks: &[(BlockId, &Mesh)],
    camera: &Camera,
    width: u32,
    height: u32,
) -> image::RgbaImage {
    shade_with_ground(blocks, &Mesh::default(), camera, width, height)
}

/// As [`shade`], with ground layers (streets, blocks' ground; e.g.
/// [`appearance::ground_mesh`]) drawn as the GPU renderer draws them: the ground plane, then
/// `ground`'s triangles in order with the depth test always passing, then the blocks with the
/// `<` depth test. Pixel colours are `appearance::shade(appearance::surface_color(..))` at the
/// perspective-correct (u, z) of the pixel centre, rounded to 8 bits.
pub fn shade_with_ground(
    blocks: &[(BlockId, &Mesh)],
    ground: &Mesh,
    camera: &Camera,
    width: u32,
    height: u32,
) -> image::RgbaImage {
    shade_with_ground_depth(blocks, ground, camera, width, height).0
}

/// As [`shade_with_ground`], also returning the depth buffer (row-major from the top-left,
/// `z/w` in `[0, 1]`, 1.0 where only sky is): what the GPU mesh pass leaves in its depth target,
/// for compositing a later pass (the far field) by depth.
pub fn shade_with_ground_depth(
    blocks: &[(BlockId, &Mesh)],
    ground: &Mesh,
    camera: &Camera,
    width: u32,
    height: u32,
) -> (image::RgbaImage, Vec<f32>) {
    let plane = appearance::ground_plane(appearance::GROUND_PLANE_HALF_M);
    let mut layers: Vec<Layer<'_>> = vec![(GROUND_ID, true, &plane), (GROUND_ID, true, ground)];
    layers.extend(block_layers(blocks));
    let (buf, colors) = render(&layers, camera, width, height, true);
    (lit_image(&buf, &colors), buf.depth)
}

/// A closed box mesh (12 triangles, outward normals) in the local frame: a test and fallback
/// primitive.
pub fn box_mesh(min: glam::Vec3, max: glam::Vec3) -> Mesh {
    use glam::Vec3;
    let mut m = Mesh::default();
    let faces: [(Vec3, [Vec3; 4]); 6] = {
        let (a, b) = (min, max);
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        [
            (
                Vec3::NEG_X,
                [
                    p(a.x, a.y, a.z),
                    p(a.x, a.y, b.z),
                    p(a.x, b.y, b.z),
                    p(a.x, b.y, a.z),
                ],
            ),
            (
                Vec3::X,
                [
                    p(b.x, a.y, a.z),
                    p(b.x, b.y, a.z),
                    p(b.x, b.y, b.z),
                    p(b.x, a.y, b.z),
                ],
            ),
            (
                Vec3::NEG_Y,
                [
                    p(a.x, a.y, a.z),
                    p(b.x, a.y, a.z),
                    p(b.x, a.y, b.z),
                    p(a.x, a.y, b.z),
                ],
            ),
            (
                Vec3::Y,
                [
                    p(a.x, b.y, a.z),
                    p(a.x, b.y, b.z),
                    p(b.x, b.y, b.z),
                    p(b.x, b.y, a.z),
                ],
            ),
            (
                Vec3::NEG_Z,
                [
                    p(a.x, a.y, a.z),
                    p(a.x, b.y, a.z),
                    p(b.x, b.y, a.z),
                    p(b.x, a.y, a.z),
                ],
            ),
            (
                Vec3::Z,
                [
                    p(a.x, a.y, b.z),
                    p(b.x, a.y, b.z),
                    p(b.x, b.y, b.z),
                    p(a.x, b.y, b.z),
                ],
            ),
        ]
    };
    for (n, q) in faces {
        let base = m.positions.len() as u32;
        m.positions.extend_from_slice(&q);
        m.normals.extend_from_slice(&[n; 4]);
        m.indices
            .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn box_mesh_is_outward() {
        let m = box_mesh(Vec3::ZERO, Vec3::ONE);
        let c = Vec3::splat(0.5);
        for t in m.indices.chunks(3) {
            let p: Vec<Vec3> = t.iter().map(|&i| m.positions[i as usize]).collect();
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            assert!(n.dot(p[0] - c) > 0.0);
        }
    }

    #[test]
    fn near_box_hides_far_box_and_sky_stays_sky() {
        let near = box_mesh(Vec3::new(10.0, -20.0, 0.0), Vec3::new(12.0, 20.0, 30.0));
        let far = box_mesh(Vec3::new(30.0, -5.0, 0.0), Vec3::new(35.0, 5.0, 10.0));
        let tall = box_mesh(Vec3::new(30.0, 30.0, 0.0), Vec3::new(35.0, 35.0, 10.0));
        let cam = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.0, 0.0);
        let blocks = [(BlockId(0), &near), (BlockId(1), &far), (BlockId(2), &tall)];
        let buf = render_ids(&blocks, &cam, 160, 90);
        let vis = buf.visible();
        assert!(vis.contains(&BlockId(0)));
        assert!(!vis.contains(&BlockId(1)), "hidden behind the wall");
        // The top row is wall (its top is 71° above the horizon, beyond the 30° half-fov); the
        // bottom row is sky (no ground; the wall's foot is 9.6° below the horizon).
        assert_eq!(buf.ids[0], 0);
        assert_eq!(buf.ids[(89 * 160) as usize], SKY);
        // Without the wall, the far box shows.
        let vis2 = visible_blocks(&blocks[1..], &cam, 160, 90);
        assert!(vis2.contains(&BlockId(1)));
        // The centre pixel's depth matches the wall's distance: view z = -10.
        let k = (45 * 160 + 80) as usize;
        let (n, f) = (cam.near, cam.far);
        let expect = f / (n - f) * (-10.0 + n) / 10.0;
        assert!(
            ((buf.depth[k] as f64) - (-expect)).abs() < 1e-3
                || ((buf.depth[k] as f64) - expect).abs() < 1e-3,
            "{}",
            buf.depth[k]
        );
    }

    #[test]
    fn shared_edges_leave_no_cracks_and_no_double_pixels() {
        // A wall made of two boxes side by side: no sky pixel may appear on the seam.
        let a = box_mesh(Vec3::new(10.0, -20.0, 0.0), Vec3::new(12.0, 0.0, 30.0));
        let b = box_mesh(Vec3::new(10.0, 0.0, 0.0), Vec3::new(12.0, 20.0, 30.0));
        let cam = Camera::new(DVec3::new(0.0, 0.3, 1.7), 0.0, 0.0);
        let buf = render_ids(&[(BlockId(0), &a), (BlockId(1), &b)], &cam, 320, 180);
        // The upper half of the image (0° to 30° up) sees only the wall, across the seam.
        let upper = &buf.ids[..(90 * 320)];
        assert!(upper.iter().all(|&i| i != SKY));
        assert!(upper.contains(&0) && upper.contains(&1));
    }

    #[test]
    fn near_plane_clipping_keeps_geometry_crossing_the_eye() {
        // A long wall beside the viewer, starting behind the eye: must be drawn, without NaN.
        let wall = box_mesh(Vec3::new(-50.0, 3.0, 0.0), Vec3::new(50.0, 4.0, 10.0));
        let cam = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.3, 0.0);
        let buf = render_ids(&[(BlockId(7), &wall)], &cam, 64, 36);
        assert!(buf.visible().contains(&BlockId(7)));
        assert!(buf
            .depth
            .iter()
            .all(|d| d.is_finite() && (0.0..=1.0).contains(d)));
        let img = shade(&[(BlockId(7), &wall)], &cam, 64, 36);
        assert_eq!(img.dimensions(), (64, 36));
    }
}
