//! Images of BlockMaps as the GPU draws them, on the CPU: the reference image the WGSL ray
//! caster (`render/blockmap.wgsl`) is tested against, and the CPU fallback of hybrid frames
//! (meshes near, maps far; Cignoni et al., §4, Di Benedetto, §4.2.2).
//!
//! # Rays exactly as the fragment shader makes them
//! Every value below is computed in `f32` in the same order as the shader (the per-frame and
//! per-map constants are computed once in `f64` and rounded, as the renderer uploads them):
//! - **Pixel → view direction** ([`FrameRays`]): the fragment's `@builtin(position).xy` is the
//!   pixel centre `(x + ½, y + ½)`; `v = (px·sx + cx, py·sy + cy, −1)` in view space, with
//!   `sx = 2·tx/W`, `cx = −tx`, `sy = −2·ty/H`, `cy = ty`, `tx = 1/P₀₀`, `ty = 1/P₁₁` of
//!   [`Camera::clip_from_view`]. `v` is not normalised: its view depth component is −1, so the
//!   point `o + t·v` lies at view depth `near + t` when `o` is on the near plane.
//! - **View → texture space** ([`MapXform`]): `d = ax·vx + ay·vy + af` and `o = b + d·near`, where
//!   `ax`, `ay`, `af` are the camera's right, up and forward vectors scaled to texels (x, y) and
//!   to `[0, 1]` over `[zmin, zmax]` (z), and `b` is the eye in texture space. The ray starts on
//!   the near plane, not at the eye: nothing nearer than `near` is drawn, as with meshes, and the
//!   eye inside a box works (the walk starts at `max(t_entry, 0)` of that ray, [`cast_f32`]).
//! - **Depth** ([`FrameRays::depth`]): the hit's view depth is `D = near + t`; the depth written
//!   is `max((rn − r·D)/D, 0)` with `r = P₂₂` and `rn = P₃₂`, which is `clip.z/clip.w` of the
//!   projection `render/mod.rs` documents (standard depth, 0 at `near`, 1 at `far`). A hit at
//!   depth ≥ 1 (beyond `far`) is not drawn.
//! - **Colour**: [`super::cast::surface`] lit by [`super::colors::lit`] (the mesh shader's sun and
//!   ambient term); ambient occlusion is not applied (BLOCKMAPS.md A.5: any difference from
//!   the mesh image stays geometric).
//!
//! Several maps: the nearest depth wins, the first listed on equal depth (the GPU draws them in
//! list order with the `Less` depth test).

use super::cast::{cast_f32, surface, CastOptions, Hit, TexRay};
use super::colors;
use super::layout::{BlockMap, BlockMapMeta};
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::{CpuFrameRenderer, DrawError, DrawnFrame, FrameRenderer, TerrainDraw};
use glam::DVec3;
use rayon::prelude::*;

/// The per-frame constants of the pixel rays and of the depth (see the module doc), as the
/// renderer uploads them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRays {
    /// View x of a pixel: `px·sx + cx`.
    pub sx: f32,
    /// See [`FrameRays::sx`].
    pub cx: f32,
    /// View y of a pixel: `py·sy + cy`.
    pub sy: f32,
    /// See [`FrameRays::sy`].
    pub cy: f32,
    /// Near plane distance, metres.
    pub near: f32,
    /// Projection entry `P₂₂` (`far/(near − far)`).
    pub r: f32,
    /// Projection entry `P₃₂` (`r·near`).
    pub rn: f32,
}

impl FrameRays {
    /// The constants of `camera` for a `width × height` image.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let p = camera.clip_from_view();
        let tx = 1.0 / p.x_axis.x;
        let ty = 1.0 / p.y_axis.y;
        Self {
            sx: (2.0 * tx / width.max(1) as f64) as f32,
            cx: (-tx) as f32,
            sy: (-2.0 * ty / height.max(1) as f64) as f32,
            cy: ty as f32,
            near: camera.near as f32,
            r: p.z_axis.z as f32,
            rn: p.w_axis.z as f32,
        }
    }

    /// View-space `(vx, vy)` of the centre of pixel `(x, y)` (row 0 at the top); the ray is
    /// `(vx, vy, −1)`.
    #[inline]
    pub fn view_dir(&self, x: u32, y: u32) -> [f32; 2] {
        let px = x as f32 + 0.5;
        let py = y as f32 + 0.5;
        [px * self.sx + self.cx, py * self.sy + self.cy]
    }

    /// The depth the shader writes for a hit at ray parameter `t` (view depth `near + t`).
    #[inline]
    pub fn depth(&self, t: f32) -> f32 {
        let d = self.near + t;
        ((self.rn - self.r * d) / d).max(0.0)
    }
}

/// The per-map, per-frame constants taking a view direction to a texture-space ray (see the
/// module doc), as the renderer uploads them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapXform {
    /// The camera's right vector in texture units.
    pub ax: [f32; 3],
    /// The camera's up vector in texture units.
    pub ay: [f32; 3],
    /// The camera's forward vector in texture units.
    pub af: [f32; 3],
    /// The eye in texture space.
    pub b: [f32; 3],
}

/// The `f64` values behind a [`MapXform`] of the texture space `p = origin + scale ⊙ q`
/// (local frame `p`, texture coordinates `q`).
fn texture_xform64(origin: DVec3, scale: DVec3, camera: &Camera) -> [DVec3; 4] {
    let inv = DVec3::ONE / scale;
    let f = camera.forward();
    let u = camera.up();
    let r = f.cross(u);
    [r * inv, u * inv, f * inv, (camera.position - origin) * inv]
}

/// A BlockMap's texture space: `(origin, scale)` of [`texture_xform64`].
fn map_space(meta: &BlockMapMeta) -> (DVec3, DVec3) {
    let s = meta.side / meta.k as f64;
    (
        DVec3::new(meta.min[0], meta.min[1], meta.zmin),
        DVec3::new(s, s, meta.zmax - meta.zmin),
    )
}

/// The `f64` values behind a BlockMap's [`MapXform`].
fn xform64(meta: &BlockMapMeta, camera: &Camera) -> [DVec3; 4] {
    let (origin, scale) = map_space(meta);
    texture_xform64(origin, scale, camera)
}

impl MapXform {
    /// The constants of `map` seen from `camera`.
    pub fn new(map: &BlockMap, camera: &Camera) -> Self {
        Self::from_meta(&map.meta, camera)
    }

    /// The constants of the map with box and quantisation `meta` seen from `camera`.
    pub fn from_meta(meta: &BlockMapMeta, camera: &Camera) -> Self {
        let [ax, ay, af, b] = xform64(meta, camera).map(|v| v.as_vec3().to_array());
        Self { ax, ay, af, b }
    }

    /// The constants of any texture space `p = origin + scale ⊙ q` (local frame `p`) seen from
    /// `camera`: what a far field other than BlockMaps casts its rays with.
    pub fn from_texture_space(origin: DVec3, scale: DVec3, camera: &Camera) -> Self {
        let [ax, ay, af, b] =
            texture_xform64(origin, scale, camera).map(|v| v.as_vec3().to_array());
        Self { ax, ay, af, b }
    }

    /// The texture-space ray of view direction `v` ([`FrameRays::view_dir`]) from the near
    /// plane at `near`.
    #[inline]
    pub fn ray(&self, v: [f32; 2], near: f32) -> TexRay<f32> {
        let d = [0, 1, 2].map(|c| self.ax[c] * v[0] + self.ay[c] * v[1] + self.af[c]);
        let o = [0, 1, 2].map(|c| self.b[c] + d[c] * near);
        TexRay { o, d }
    }
}

/// The `f64` twin of the ray [`cast_image`] casts through pixel `(x, y)` of `map` (same
/// construction, no rounding): for [`super::cast::cast_f64`], which names the ties.
pub fn twin_ray(
    map: &BlockMap,
    camera: &Camera,
    width: u32,
    height: u32,
    x: u32,
    y: u32,
) -> TexRay<f64> {
    let (origin, scale) = map_space(&map.meta);
    twin_ray_in(origin, scale, camera, width, height, x, y)
}

/// [`twin_ray`] in any texture space `p = origin + scale ⊙ q` ([`MapXform::from_texture_space`]).
pub fn twin_ray_in(
    origin: DVec3,
    scale: DVec3,
    camera: &Camera,
    width: u32,
    height: u32,
    x: u32,
    y: u32,
) -> TexRay<f64> {
    let p = camera.clip_from_view();
    let tx = 1.0 / p.x_axis.x;
    let ty = 1.0 / p.y_axis.y;
    let vx = (x as f64 + 0.5) * (2.0 * tx / width.max(1) as f64) - tx;
    let vy = (y as f64 + 0.5) * (-2.0 * ty / height.max(1) as f64) + ty;
    let [ax, ay, af, b] = texture_xform64(origin, scale, camera);
    let d = ax * vx + ay * vy + af;
    let o = b + d * camera.near;
    TexRay {
        o: o.to_array(),
        d: d.to_array(),
    }
}

/// The ray-cast image of some maps (see the module doc). Pixels without a hit have
/// `hit = false`, `t = ∞`, `depth = 1`, colour `[0, 0, 0, 0]` and `map = u32::MAX`.
#[derive(Clone, Debug, PartialEq)]
pub struct MapImage {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Whether a map was hit, row-major from the top-left pixel.
    pub hit: Vec<bool>,
    /// Distance from the eye to the hit along the pixel ray, metres (from the f32 cast).
    pub t: Vec<f64>,
    /// The depth the GPU writes for the hit ([`FrameRays::depth`]).
    pub depth: Vec<f32>,
    /// Lit colour, RGBA8 (A = 255 on a hit).
    pub color: Vec<[u8; 4]>,
    /// Index into the maps of the hit's map, `u32::MAX` when none.
    pub map: Vec<u32>,
}

impl MapImage {
    /// Pixels with a hit.
    pub fn hits(&self) -> usize {
        self.hit.iter().filter(|&&h| h).count()
    }
}

/// One pixel of a [`MapImage`].
#[derive(Clone, Copy)]
struct Px {
    t: f64,
    depth: f32,
    color: [u8; 4],
    map: u32,
}

const NO_HIT: Px = Px {
    t: f64::INFINITY,
    depth: 1.0,
    color: [0; 4],
    map: u32::MAX,
};

/// The pixel rectangle `[x0, y0, x1, y1]` (pixel units, row 0 at the top, one pixel of margin
/// for rounding) holding the projection of `b` seen from `camera`; the whole image when a corner
/// lies nearer than the near plane (its projection is unbounded).
fn screen_rect(b: &crate::geom::Aabb3, camera: &Camera, width: u32, height: u32) -> [f64; 4] {
    let all = [
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::INFINITY,
    ];
    let m = camera.clip_from_world();
    let (w, h) = (width as f64, height as f64);
    let mut r = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for i in 0..8 {
        let p = DVec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        let c = m * p.extend(1.0);
        if !c.is_finite() || c.w < camera.near * 0.5 {
            return all;
        }
        let (x, y) = ((c.x / c.w + 1.0) * 0.5 * w, (1.0 - c.y / c.w) * 0.5 * h);
        r = [r[0].min(x), r[1].min(y), r[2].max(x), r[3].max(y)];
    }
    [r[0] - 1.0, r[1] - 1.0, r[2] + 1.0, r[3] + 1.0]
}

/// Casts, per pixel of a `width × height` image from `camera`, the f32 reference caster
/// ([`cast_f32`], the GPU's walk) through the maps `maps[far[..]]` and keeps the nearest hit
/// (see the module doc for the rays, the depth and the colour). Parallel over rows,
/// deterministic.
///
/// # Panics
/// When an index in `far` is not below `maps.len()` (callers validate, e.g.
/// [`CpuHybridRenderer`]).
pub fn cast_image(
    maps: &[&BlockMap],
    far: &[usize],
    camera: &Camera,
    width: u32,
    height: u32,
) -> MapImage {
    cast_image_in(maps, far, camera, width, height, true)
}

/// [`cast_image`], skipping maps by their pixel rectangles when `rects` (else every map is
/// cast at every pixel).
fn cast_image_in(
    maps: &[&BlockMap],
    far: &[usize],
    camera: &Camera,
    width: u32,
    height: u32,
    rects: bool,
) -> MapImage {
    let fr = FrameRays::new(camera, width, height);
    let xf: Vec<(usize, MapXform)> = far
        .iter()
        .map(|&m| (m, MapXform::new(maps[m], camera)))
        .collect();
    // Each map's pixel rectangle: a hit lies in the map's box, so its pixel lies in the box's
    // projection; maps whose rectangle misses a pixel are not cast there (the image is the same).
    let all = [
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::INFINITY,
    ];
    let rects: Vec<[f64; 4]> = far
        .iter()
        .map(|&m| {
            if rects {
                screen_rect(&maps[m].aabb(), camera, width, height)
            } else {
                all
            }
        })
        .collect();
    let opts = CastOptions::default();
    let rows: Vec<Vec<Px>> = (0..height)
        .into_par_iter()
        .map(|y| {
            (0..width)
                .map(|x| {
                    let v = fr.view_dir(x, y);
                    let mut best: Option<(f32, usize, TexRay<f32>, Hit)> = None;
                    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                    for (&(m, ref x), r) in xf.iter().zip(&rects) {
                        if px < r[0] || px > r[2] || py < r[1] || py > r[3] {
                            continue;
                        }
                        let ray = x.ray(v, fr.near);
                        let c = cast_f32(maps[m], &ray, &opts);
                        if let Some(t) = c.hit.t() {
                            let depth = fr.depth(t as f32);
                            if depth < 1.0 && best.as_ref().is_none_or(|b| depth < b.0) {
                                best = Some((depth, m, ray, c.hit));
                            }
                        }
                    }
                    let Some((depth, m, ray, hit)) = best else {
                        return NO_HIT;
                    };
                    let wide = TexRay {
                        o: ray.o.map(f64::from),
                        d: ray.d.map(f64::from),
                    };
                    let [r, g, b] = surface(maps[m], &wide, &hit)
                        .map_or([0; 3], |s| colors::lit(s.color, s.normal));
                    let t = hit.t().unwrap_or(0.0);
                    let (vx, vy) = (f64::from(v[0]), f64::from(v[1]));
                    Px {
                        t: (f64::from(fr.near) + t) * (vx * vx + vy * vy + 1.0).sqrt(),
                        depth,
                        color: [r, g, b, 255],
                        map: m as u32,
                    }
                })
                .collect()
        })
        .collect();
    let n = width as usize * height as usize;
    let mut img = MapImage {
        width,
        height,
        hit: Vec::with_capacity(n),
        t: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        color: Vec::with_capacity(n),
        map: Vec::with_capacity(n),
    };
    for p in rows.into_iter().flatten() {
        img.hit.push(p.map != u32::MAX);
        img.t.push(p.t);
        img.depth.push(p.depth);
        img.color.push(p.color);
        img.map.push(p.map);
    }
    img
}

/// The CPU fallback of hybrid frames: block meshes through the oracle's shaded z-buffer
/// ([`oracle::shade_with_ground_depth`]) and far-field maps through [`cast_image`], composited
/// per pixel by depth (a map pixel wins where its depth is less than the mesh pass's, the GPU's
/// `Less` test). Wall time.
#[derive(Clone)]
pub struct CpuHybridRenderer<'a> {
    meshes: &'a [(BlockId, Mesh)],
    ground: &'a Mesh,
    terrain: Option<&'a dyn TerrainDraw>,
    maps: Vec<&'a BlockMap>,
    size: (u32, u32),
}

impl std::fmt::Debug for CpuHybridRenderer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CpuHybridRenderer")
            .field("meshes", &self.meshes.len())
            .field("maps", &self.maps.len())
            .field("terrain", &self.terrain.is_some())
            .field("size", &self.size)
            .finish()
    }
}

impl<'a> CpuHybridRenderer<'a> {
    /// A renderer of `meshes` (local frame) on the ground layers `ground` and of the far-field
    /// `maps` (which `draw_with_far`'s `far` indexes), drawing `size` pixels.
    pub fn new(
        meshes: &'a [(BlockId, Mesh)],
        ground: &'a Mesh,
        maps: Vec<&'a BlockMap>,
        size: (u32, u32),
    ) -> Self {
        Self {
            meshes,
            ground,
            terrain: None,
            maps,
            size,
        }
    }

    /// The same renderer drawing `terrain`'s cut under the meshes instead of the flat ground
    /// ([`CpuFrameRenderer::with_terrain`]); the maps then composite over it by depth.
    pub fn with_terrain(self, terrain: &'a dyn TerrainDraw) -> Self {
        Self {
            terrain: Some(terrain),
            ..self
        }
    }

    /// The maps `far` indexes.
    pub fn maps(&self) -> &[&'a BlockMap] {
        &self.maps
    }

    fn meshes_only(&self) -> CpuFrameRenderer<'a> {
        let r = CpuFrameRenderer::new(self.meshes, self.size).with_ground(self.ground);
        match self.terrain {
            Some(t) => r.with_terrain(t),
            None => r,
        }
    }
}

impl FrameRenderer for CpuHybridRenderer<'_> {
    fn describe(&self) -> String {
        format!(
            "CPU hybrid: z-buffer meshes (visibility::oracle) + f32 reference BlockMap caster, \
             {} maps, wall time, {}x{}",
            self.maps.len(),
            self.size.0,
            self.size.1
        )
    }
    fn size(&self) -> (u32, u32) {
        self.size
    }
    fn draw(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError> {
        self.meshes_only().draw(camera, visible, want_image)
    }
    fn draw_with_far(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        far: &[usize],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError> {
        if let Some(&bad) = far.iter().find(|&&m| m >= self.maps.len()) {
            return Err(format!(
                "{}: far-field map {bad} does not exist ({} maps)",
                self.describe(),
                self.maps.len()
            )
            .into());
        }
        self.meshes_only()
            .draw_composited(camera, visible, want_image, |w, h| {
                let maps = cast_image(&self.maps, far, camera, w, h);
                Ok(maps
                    .hit
                    .iter()
                    .zip(maps.depth.iter().zip(&maps.color))
                    .map(|(&hit, (&d, &c))| hit.then_some((d, c)))
                    .collect())
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blockmap::cast::cast_f64;
    use crate::blockmap::compare::pixel_ray;
    use crate::visibility::oracle;
    use rand::{Rng, SeedableRng};

    /// A map with random heights over `[x0, x0 + 160] × [y0, y0 + 160]`, heights to 50 m.
    fn random_map(seed: u64, x0: f64, y0: f64) -> BlockMap {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let k = 32;
        let mut m = BlockMap::empty(k, DVec3::new(x0, y0, 0.0), 160.0, 50.0).unwrap();
        for j in 0..k {
            for i in 0..k {
                if rng.random_bool(0.35) {
                    let t = m.texel_mut(i, j);
                    t[0] = rng.random_range(1..=255);
                    t[1] = rng.random_range(0..=255);
                    *m.texel_mut(k + i, j) = [rng.random(), rng.random(), rng.random(), 255];
                }
            }
        }
        m
    }

    #[test]
    fn pixel_rectangles_leave_the_image_unchanged() {
        let maps: Vec<BlockMap> = (0..6)
            .map(|k| random_map(40 + k, (k % 3) as f64 * 170.0, (k / 3) as f64 * 170.0))
            .collect();
        let refs: Vec<&BlockMap> = maps.iter().collect();
        let far: Vec<usize> = (0..refs.len()).collect();
        let mut skipped = 0;
        for cam in cameras() {
            let a = cast_image_in(&refs, &far, &cam, 96, 54, true);
            let b = cast_image_in(&refs, &far, &cam, 96, 54, false);
            assert!(a == b, "{cam:?}");
            skipped += far
                .iter()
                .filter(|&&m| screen_rect(&refs[m].aabb(), &cam, 96, 54)[2] < 96.0)
                .count();
        }
        assert!(skipped > 0, "some rectangle was smaller than the image");
    }

    fn cameras() -> Vec<Camera> {
        let mut cams = vec![
            Camera::looking_at(
                DVec3::new(-120.0, -90.0, 140.0),
                DVec3::new(80.0, 80.0, 0.0),
            ),
            // Eye inside the box, looking across it.
            Camera::looking_at(DVec3::new(20.0, 30.0, 45.0), DVec3::new(150.0, 120.0, 10.0)),
            // Grazing, low over the roofs.
            Camera::looking_at(DVec3::new(-60.0, 80.0, 30.0), DVec3::new(300.0, 70.0, 25.0)),
            // Straight down.
            Camera::new(
                DVec3::new(80.0, 80.0, 300.0),
                0.3,
                -std::f64::consts::FRAC_PI_2,
            ),
        ];
        for c in &mut cams {
            c.aspect = 4.0 / 3.0;
        }
        cams
    }

    #[test]
    fn pixel_rays_are_the_unprojected_pixel_centres() {
        let cam = cameras()[0];
        let (w, h) = (64, 48);
        let fr = FrameRays::new(&cam, w, h);
        let (f, u) = (cam.forward(), cam.up());
        let r = f.cross(u);
        for (x, y) in [(0, 0), (63, 0), (17, 30), (63, 47), (32, 24)] {
            let v = fr.view_dir(x, y);
            let dir = (r * v[0] as f64 + u * v[1] as f64 + f).normalize();
            let (_, want) = pixel_ray(&cam, x, y, w, h);
            assert!(
                (dir - want).length() < 1e-6,
                "pixel ({x}, {y}): {dir} vs {want}"
            );
        }
        // The near plane is depth 0, the far plane depth 1 (within f32 rounding).
        assert!(fr.depth(0.0).abs() < 1e-6);
        let far = (cam.far - cam.near) as f32;
        assert!((fr.depth(far) - 1.0).abs() < 1e-5, "{}", fr.depth(far));
        // The depth of a point is clip.z/clip.w of the camera's matrix.
        let p = cam.position + cam.forward() * 37.0 + cam.up() * 3.0;
        let c = cam.clip_from_world() * p.extend(1.0);
        assert!((fr.depth(37.0 - cam.near as f32) as f64 - c.z / c.w).abs() < 1e-6);
    }

    #[test]
    fn cast_image_agrees_with_the_f64_twin_except_ties() {
        let map = random_map(3, 0.0, 0.0);
        let (w, h) = (96, 72);
        for (n, cam) in cameras().iter().enumerate() {
            let img = cast_image(&[&map], &[0], cam, w, h);
            let (mut ties, mut hits) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    let k = (y * w + x) as usize;
                    let twin = twin_ray(&map, cam, w, h, x, y);
                    let c = cast_f64(&map, &twin, &CastOptions::default());
                    if c.is_tie(1e-4) {
                        ties += 1;
                        continue;
                    }
                    let t64 = c.hit.t().filter(|&t| {
                        let d = cam.near + t;
                        (cam.far / (cam.near - cam.far)) * (cam.near - d) / d < 1.0
                    });
                    assert_eq!(
                        img.hit[k],
                        t64.is_some(),
                        "view {n} pixel ({x}, {y}): {c:?}"
                    );
                    if let Some(t) = t64 {
                        hits += 1;
                        let d = cam.near + t;
                        let r = cam.far / (cam.near - cam.far);
                        let depth64 = (r * cam.near - r * d) / d;
                        assert!(
                            (img.depth[k] as f64 - depth64).abs() < 2e-6,
                            "view {n} pixel ({x}, {y}): depth {} vs {depth64}",
                            img.depth[k]
                        );
                        let (vx, vy) = {
                            let v = FrameRays::new(cam, w, h).view_dir(x, y);
                            (v[0] as f64, v[1] as f64)
                        };
                        let dist = d * (vx * vx + vy * vy + 1.0).sqrt();
                        assert!(
                            (img.t[k] - dist).abs() < 1e-3 * (1.0 + dist),
                            "{} vs {dist}",
                            img.t[k]
                        );
                        assert_eq!(img.map[k], 0);
                        assert_eq!(img.color[k][3], 255);
                    } else {
                        assert_eq!(img.map[k], u32::MAX);
                        assert_eq!(img.depth[k], 1.0);
                    }
                }
            }
            assert!(ties * 20 < (w * h) as usize, "view {n}: {ties} ties");
            eprintln!("view {n}: {hits} hits, {ties} ties of {} pixels", w * h);
            assert!(hits > 0, "view {n} sees no map");
        }
    }

    #[test]
    fn the_nearest_of_several_maps_wins() {
        let near_map = random_map(5, 0.0, 0.0);
        let far_map = random_map(6, 200.0, 0.0);
        let cam = {
            let mut c =
                Camera::looking_at(DVec3::new(-100.0, 80.0, 60.0), DVec3::new(400.0, 80.0, 0.0));
            c.aspect = 4.0 / 3.0;
            c
        };
        let (w, h) = (80, 60);
        let maps = [&far_map, &near_map];
        let both = cast_image(&maps, &[0, 1], &cam, w, h);
        let a = cast_image(&maps, &[0], &cam, w, h);
        let b = cast_image(&maps, &[1], &cam, w, h);
        let mut from = [0usize; 2];
        for k in 0..(w * h) as usize {
            let want = match (a.hit[k], b.hit[k]) {
                (false, false) => u32::MAX,
                (true, false) => 0,
                (false, true) => 1,
                (true, true) => {
                    if b.depth[k] < a.depth[k] {
                        1
                    } else {
                        0
                    }
                }
            };
            assert_eq!(both.map[k], want, "pixel {k}");
            if want != u32::MAX {
                from[want as usize] += 1;
                let src = if want == 0 { &a } else { &b };
                assert_eq!(both.color[k], src.color[k]);
                assert_eq!(both.depth[k], src.depth[k]);
            }
        }
        assert!(from[0] > 0 && from[1] > 0, "{from:?}");
        // Determinism.
        assert_eq!(both, cast_image(&maps, &[0, 1], &cam, w, h));
    }

    #[test]
    fn the_hybrid_composite_hides_a_map_behind_a_mesh() {
        let map = random_map(9, 0.0, 0.0);
        let cam = {
            let mut c =
                Camera::looking_at(DVec3::new(-150.0, 80.0, 90.0), DVec3::new(80.0, 80.0, 0.0));
            c.aspect = 4.0 / 3.0;
            c
        };
        // A wall between the eye and the map, covering part of the view.
        let wall = oracle::box_mesh(
            glam::Vec3::new(-60.0, 60.0, 0.0),
            glam::Vec3::new(-55.0, 100.0, 70.0),
        );
        let meshes = vec![(BlockId(0), wall)];
        let ground = Mesh::default();
        let (w, h) = (80, 60);
        let r = CpuHybridRenderer::new(&meshes, &ground, vec![&map], (w, h));
        let maps_only = cast_image(&[&map], &[0], &cam, w, h);
        let with_wall = r.draw_with_far(&cam, &[BlockId(0)], &[0], true).unwrap();
        let without = r.draw_with_far(&cam, &[], &[0], true).unwrap();
        let meshes_only = r.draw(&cam, &[BlockId(0)], true).unwrap();
        assert!(meshes_only.far_pixels.is_none());
        let (img_w, img_n, img_m) = (
            with_wall.image.unwrap(),
            without.image.unwrap(),
            meshes_only.image.unwrap(),
        );
        let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
        let ids = oracle::render_ids(&refs, &cam, w, h);
        let (mut hidden, mut shown) = (0, 0);
        for k in 0..(w * h) as usize {
            let (x, y) = (k as u32 % w, k as u32 / w);
            if !maps_only.hit[k] {
                assert_eq!(img_w.get_pixel(x, y), img_m.get_pixel(x, y));
                continue;
            }
            // The map is behind the wall wherever both cover a pixel.
            if ids.ids[k] != oracle::SKY {
                assert!(ids.depth[k] < maps_only.depth[k], "pixel ({x}, {y})");
                assert_eq!(
                    img_w.get_pixel(x, y),
                    img_m.get_pixel(x, y),
                    "pixel ({x}, {y})"
                );
                hidden += 1;
            } else {
                assert_eq!(
                    img_w.get_pixel(x, y).0,
                    maps_only.color[k],
                    "pixel ({x}, {y})"
                );
                shown += 1;
            }
            assert_eq!(
                img_n.get_pixel(x, y).0,
                maps_only.color[k],
                "pixel ({x}, {y})"
            );
        }
        assert!(hidden > 0 && shown > 0, "hidden {hidden}, shown {shown}");
        assert_eq!(with_wall.far_pixels, Some(shown as u64));
        assert_eq!(without.far_pixels, Some((hidden + shown) as u64));
        let names: Vec<&str> = with_wall.passes.iter().map(|p| p.0).collect();
        assert_eq!(names, ["meshes", "far"]);
    }

    #[test]
    fn an_unknown_far_map_is_refused() {
        let map = random_map(1, 0.0, 0.0);
        let ground = Mesh::default();
        let r = CpuHybridRenderer::new(&[], &ground, vec![&map], (8, 6));
        let err = r
            .draw_with_far(&cameras()[0], &[], &[0, 1], false)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("far-field map 1 does not exist (1 maps)"),
            "{err}"
        );
    }
}
