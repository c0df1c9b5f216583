//! The per-frame roles a walk or a viewer plays, as traits, with their CPU implementations:
//!
//! - [`OcclusionCulling`]: culls a frame through a [`CityIndex`], dropping what is proven
//!   hidden ([`OcclusionCuller`], Willmott et al., §3.2).
//! - [`VisibilityOracle`]: the exact set of blocks a camera sees ([`MeshOracle`], the CPU
//!   z-buffer of [`super::oracle`]).
//! - [`FrameRenderer`]: draws a frame of the blocks a culler kept ([`CpuFrameRenderer`], the
//!   oracle's shading; the wgpu renderer lives in `render`).
//!
//! They live here, before the walk in the module chain, so that a walk can take any of them and
//! `visibility` never needs the GPU stack.

use super::oracle;
use super::terrain::TerrainDraw;
use super::OcclusionCuller;
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::index::{CityIndex, CullStats};
use std::collections::HashSet;
use std::time::Instant;

/// An occlusion culler for a walk or a viewer.
pub trait OcclusionCulling: Sync {
    /// What culls, for reports.
    fn describe(&self) -> String;
    /// One frame: builds what the culler needs for `camera` (its time counts as culling time),
    /// then frustum-culls through `index` while dropping what is proven hidden, pushing the blocks
    /// to draw to `out`.
    fn cull_frame(
        &self,
        index: &dyn CityIndex,
        camera: &Camera,
        out: &mut Vec<BlockId>,
    ) -> CullStats;
}

/// The occluder-shadow culler (Willmott et al., §3.2).
impl OcclusionCulling for OcclusionCuller {
    fn describe(&self) -> String {
        "occluder shadows + cull map (Willmott et al., §3.2)".into()
    }
    fn cull_frame(
        &self,
        index: &dyn CityIndex,
        camera: &Camera,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        self.cull(index, camera, out).cull
    }
}

/// The exact set of visible blocks for a camera, to count false culls.
pub trait VisibilityOracle: Sync {
    /// What decides, for reports (method and resolution).
    fn describe(&self, width: u32, height: u32) -> String;
    /// Blocks that cover at least one pixel of an image of `width` × `height` pixels.
    fn visible(&self, camera: &Camera, width: u32, height: u32) -> HashSet<BlockId>;
}

/// The CPU z-buffer oracle over block meshes ([`oracle::visible_blocks`]), optionally over a
/// terrain that occludes ([`MeshOracle::with_terrain`]).
#[derive(Clone, Copy, Debug)]
pub struct MeshOracle<'a> {
    meshes: &'a [(BlockId, Mesh)],
    samples: u32,
    terrain: Option<&'a Mesh>,
}

impl<'a> MeshOracle<'a> {
    /// An oracle over the meshes (local frame), one sample at each pixel centre.
    pub fn new(meshes: &'a [(BlockId, Mesh)]) -> Self {
        Self {
            meshes,
            samples: 1,
            terrain: None,
        }
    }

    /// The stricter oracle of the tests: `samples × samples` samples per pixel (at least 1;
    /// see [`oracle::visible_blocks_supersampled`]).
    pub fn supersampled(meshes: &'a [(BlockId, Mesh)], samples: u32) -> Self {
        Self {
            meshes,
            samples: samples.max(1),
            terrain: None,
        }
    }

    /// The same oracle with `terrain` (the full-resolution mesh, local frame: see
    /// [`TerrainDraw::full`]) drawn into the z-buffer as an occluder
    /// ([`oracle::render_ids_with_terrain`]): a block behind a hill is not visible; the terrain
    /// is never reported.
    pub fn with_terrain(self, terrain: &'a Mesh) -> Self {
        Self {
            terrain: Some(terrain),
            ..self
        }
    }

    /// Samples per pixel along each axis.
    pub fn samples(&self) -> u32 {
        self.samples
    }
}

impl VisibilityOracle for MeshOracle<'_> {
    fn describe(&self, width: u32, height: u32) -> String {
        if self.samples > 1 {
            let s = self.samples;
            format!(
                "CPU z-buffer oracle at {width}x{height}, {s}x{s} samples per pixel{}",
                self.terrain_words()
            )
        } else {
            format!(
                "CPU z-buffer oracle at {width}x{height}{}",
                self.terrain_words()
            )
        }
    }
    fn visible(&self, camera: &Camera, width: u32, height: u32) -> HashSet<BlockId> {
        let refs: Vec<(BlockId, &Mesh)> = self.meshes.iter().map(|(b, m)| (*b, m)).collect();
        oracle::visible_blocks_with_terrain(
            &refs,
            self.terrain,
            camera,
            width,
            height,
            self.samples,
        )
        .into_iter()
        .collect()
    }
}

impl MeshOracle<'_> {
    fn terrain_words(&self) -> &'static str {
        if self.terrain.is_some() {
            ", terrain occluding"
        } else {
            ""
        }
    }
}

/// Why a frame could not be drawn.
pub type DrawError = Box<dyn std::error::Error + Send + Sync>;

/// A drawn frame: how long it took and, when asked for, the picture.
#[derive(Clone, Debug)]
pub struct DrawnFrame {
    /// Seconds the drawing took (GPU time when [`DrawnFrame::gpu_time`]).
    pub seconds: f64,
    /// True when `seconds` comes from GPU timestamps, false for wall time.
    pub gpu_time: bool,
    /// The image, when asked for.
    pub image: Option<image::RgbaImage>,
    /// Seconds per pass (`"meshes"`, `"far"`, …) when the renderer measures passes apart.
    pub passes: Vec<(&'static str, f64)>,
    /// Pixels the far field covered, when far-field maps were drawn.
    pub far_pixels: Option<u64>,
}

/// Draws frames of the blocks a culler kept.
pub trait FrameRenderer {
    /// What renders, for the report (e.g. `GPU: llvmpipe (Vulkan), timestamps, 640x360`).
    fn describe(&self) -> String;
    /// Image size in pixels.
    fn size(&self) -> (u32, u32);
    /// Draws `visible` for `camera`.
    ///
    /// # Errors
    /// What the renderer reports (device lost, read-back failed, …).
    fn draw(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError>;
    /// Draws `visible` as meshes and the far-field maps `far` (indices into the maps the
    /// renderer was built with, see `blockmap`), composited by depth. Renderers without a far
    /// field draw the meshes alone when `far` is empty and refuse otherwise.
    ///
    /// # Errors
    /// As [`FrameRenderer::draw`]; a renderer without far field given maps to draw.
    fn draw_with_far(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        far: &[usize],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError> {
        if far.is_empty() {
            self.draw(camera, visible, want_image)
        } else {
            Err(format!("{}: draws no far field", self.describe()).into())
        }
    }
}

/// The CPU fallback: the oracle's shaded z-buffer image of the listed blocks, wall time.
#[derive(Clone, Copy)]
pub struct CpuFrameRenderer<'a> {
    meshes: &'a [(BlockId, Mesh)],
    ground: Option<&'a Mesh>,
    terrain: Option<&'a dyn TerrainDraw>,
    size: (u32, u32),
}

impl std::fmt::Debug for CpuFrameRenderer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CpuFrameRenderer")
            .field("meshes", &self.meshes.len())
            .field("ground", &self.ground.is_some())
            .field("terrain_tiles", &self.terrain.map(|t| t.tiles().len()))
            .field("size", &self.size)
            .finish()
    }
}

impl<'a> CpuFrameRenderer<'a> {
    /// A renderer of `meshes` (local frame) at `size` pixels.
    pub fn new(meshes: &'a [(BlockId, Mesh)], size: (u32, u32)) -> Self {
        Self {
            meshes,
            ground: None,
            terrain: None,
            size,
        }
    }

    /// The same renderer drawing the ground layers `ground` (streets, blocks' ground: see
    /// [`oracle::shade_with_ground`]) under the buildings.
    pub fn with_ground(self, ground: &'a Mesh) -> Self {
        Self {
            ground: Some(ground),
            ..self
        }
    }

    /// The same renderer drawing `terrain`: each frame the tiles of its cut
    /// ([`TerrainDraw::cut`]), lit and depth-tested before the blocks
    /// ([`oracle::shade_with_terrain_depth`]). The ground plane and the ground layers are then
    /// not drawn ([`super::draws_flat_ground`]).
    pub fn with_terrain(self, terrain: &'a dyn TerrainDraw) -> Self {
        Self {
            terrain: Some(terrain),
            ..self
        }
    }

    /// The lit image and depth of the listed blocks: over the terrain's cut when there is a
    /// terrain, else on the ground plane and the ground layers.
    fn shade_depth(&self, camera: &Camera, visible: &[BlockId]) -> (image::RgbaImage, Vec<f32>) {
        let (w, h) = self.size;
        let keep: HashSet<BlockId> = visible.iter().copied().collect();
        let list: Vec<(BlockId, &Mesh)> = self
            .meshes
            .iter()
            .filter(|(b, _)| keep.contains(b))
            .map(|(b, m)| (*b, m))
            .collect();
        match self.terrain {
            // A terrain replaces the flat ground (`draws_flat_ground`).
            Some(t) => {
                let mut cut = Vec::new();
                t.cut(camera, self.size, &mut cut);
                let tiles: Vec<&Mesh> = cut.iter().filter_map(|&i| t.tiles().get(i)).collect();
                oracle::shade_with_terrain_depth(&list, &tiles, camera, w, h)
            }
            None => {
                let empty = Mesh::default();
                let ground = self.ground.unwrap_or(&empty);
                oracle::shade_with_ground_depth(&list, ground, camera, w, h)
            }
        }
    }

    /// The CPU hybrid frame every far field's fallback draws: the `visible` blocks and the
    /// ground through the oracle's shaded z-buffer, then `far(w, h)` (per pixel, row-major, the
    /// far field's depth and colour where it hit) composited over them by depth (a far pixel wins
    /// where its depth is less than the mesh pass's, the GPU's `Less` test); wall time, the two
    /// passes timed apart.
    ///
    /// # Errors
    /// What `far` returns.
    pub fn draw_composited(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
        far: impl FnOnce(u32, u32) -> Result<Vec<Option<(f32, [u8; 4])>>, DrawError>,
    ) -> Result<DrawnFrame, DrawError> {
        let (w, h) = self.size;
        let t0 = Instant::now();
        let (mut img, mesh_depth) = self.shade_depth(camera, visible);
        let meshes_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let layer = far(w, h)?;
        let mut won = 0u64;
        for ((px, f), &md) in img.pixels_mut().zip(&layer).zip(&mesh_depth) {
            if let Some((depth, color)) = *f {
                if depth < md {
                    *px = image::Rgba(color);
                    won += 1;
                }
            }
        }
        let far_s = t1.elapsed().as_secs_f64();
        Ok(DrawnFrame {
            seconds: meshes_s + far_s,
            gpu_time: false,
            image: want_image.then_some(img),
            passes: vec![("meshes", meshes_s), ("far", far_s)],
            far_pixels: Some(won),
        })
    }
}

impl FrameRenderer for CpuFrameRenderer<'_> {
    fn describe(&self) -> String {
        format!(
            "CPU z-buffer shading (visibility::oracle::shade), wall time, {}x{}{}",
            self.size.0,
            self.size.1,
            if self.terrain.is_some() {
                ", terrain"
            } else {
                ""
            }
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
        let t0 = Instant::now();
        let img = self.shade_depth(camera, visible).0;
        Ok(DrawnFrame {
            seconds: t0.elapsed().as_secs_f64(),
            gpu_time: false,
            image: want_image.then_some(img),
            passes: Vec::new(),
            far_pixels: None,
        })
    }
}
