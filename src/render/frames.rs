//! The wgpu renderer as the walk's [`FrameRenderer`]: block meshes, and with
//! [`GpuFrameRenderer::with_far`] the far field ray-cast on the GPU (BlockMaps or relief
//! impostors, [`FarRenderer`]) composited with them by depth.

use super::blockmap::{BlockMapRenderer, FarPass, FarReadback};
use super::relief::ReliefRenderer;
use super::{Gpu, MeshRenderer, RenderError, RenderOptions};
use crate::blockmap::BlockMap;
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::relief::ReliefField;
use crate::visibility::{DrawError, DrawnFrame, FrameRenderer, SharedTerrain};
use crate::walk::{FarField, FarGpu};

/// The far-field pass of one representation, uploaded once: what [`GpuFrameRenderer`] and the
/// viewer draw after the meshes.
#[derive(Debug)]
pub enum FarRenderer {
    /// BlockMaps ([`BlockMapRenderer`]).
    BlockMaps(BlockMapRenderer),
    /// Relief impostors ([`ReliefRenderer`]).
    Relief(ReliefRenderer),
}

impl FarRenderer {
    /// Uploads the far field `far` to `gpu` for frames of `size` pixels.
    ///
    /// # Errors
    /// The representation's upload errors ([`RenderError::BadBlockMap`],
    /// [`RenderError::FarField`], [`RenderError::EmptyImage`]).
    pub fn new(gpu: &Gpu, far: &dyn FarField, size: (u32, u32)) -> Result<Self, RenderError> {
        match far.gpu() {
            FarGpu::BlockMaps(maps) => BlockMapRenderer::new(gpu, &maps, size).map(Self::BlockMaps),
            FarGpu::Relief(field) => ReliefRenderer::new(gpu, field, size).map(Self::Relief),
        }
    }

    /// Draws the nodes `far` (indices into the far field's nodes) from `camera` into the mesh
    /// pass's `color` and `depth` targets and reads back what `read` asks for (see
    /// [`BlockMapRenderer::draw`] and [`ReliefRenderer::draw`]).
    ///
    /// # Errors
    /// [`RenderError::NoSuchMap`] for an index out of range; read-back failures.
    pub fn draw(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        far: &[usize],
        color: &wgpu::Texture,
        depth: &wgpu::Texture,
        read: FarReadback,
    ) -> Result<FarPass, RenderError> {
        match self {
            Self::BlockMaps(r) => r.draw(gpu, camera, far, color, depth, read),
            Self::Relief(r) => r.draw(gpu, camera, far, color, depth, read),
        }
    }

    /// Nodes uploaded (maps, or relief nodes).
    pub fn nodes(&self) -> usize {
        match self {
            Self::BlockMaps(r) => r.maps(),
            Self::Relief(r) => r.nodes(),
        }
    }

    /// What is uploaded, in words.
    pub fn describe(&self) -> String {
        match self {
            Self::BlockMaps(r) => format!("{} far-field maps in {} pages", r.maps(), r.pages()),
            Self::Relief(r) => format!(
                "{} relief-impostor nodes ({} oblique maps, {:.1} MB) in {} pages",
                r.nodes(),
                r.obliques(),
                r.bytes() as f64 / 1e6,
                r.pages()
            ),
        }
    }
}

/// A headless GPU renderer of a scene's block meshes (and far field), uploaded once.
pub struct GpuFrameRenderer {
    gpu: Gpu,
    renderer: MeshRenderer,
    far: Option<FarRenderer>,
    /// The terrain whose cut each frame draws (its tiles uploaded in `renderer`).
    terrain: Option<SharedTerrain>,
}

impl std::fmt::Debug for GpuFrameRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuFrameRenderer")
            .field("gpu", &self.gpu)
            .field("far", &self.far)
            .field("terrain_tiles", &self.renderer.terrain_tiles())
            .finish()
    }
}

/// A frame of meshes and far-field maps with everything the tests and tools look at.
#[derive(Clone, Debug)]
pub struct HybridFrame {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGBA bytes, rows top to bottom.
    pub rgba: Vec<u8>,
    /// The depth buffer, when asked for.
    pub depth: Option<Vec<f32>>,
    /// Per pixel, the index of the far-field node (map or relief node) drawn there
    /// ([`super::NO_MAP`] where meshes, ground or sky won).
    pub map_ids: Vec<u32>,
    /// Pixels a far-field node won.
    pub far_pixels: u64,
    /// Seconds per pass, `"meshes"` then `"far"` (GPU time when [`HybridFrame::gpu_time`]).
    pub passes: Vec<(&'static str, f64)>,
    /// True when the passes' seconds come from GPU timestamps.
    pub gpu_time: bool,
    /// Nodes (maps or relief nodes) drawn by the far pass.
    pub far_maps: u32,
    /// Draw calls of the far pass.
    pub far_draws: u32,
}

impl HybridFrame {
    /// The image.
    pub fn to_image(&self) -> Option<image::RgbaImage> {
        image::RgbaImage::from_raw(self.width, self.height, self.rgba.clone())
    }
}

impl GpuFrameRenderer {
    /// A headless device ([`Gpu::new_headless`]) and the meshes (local frame) uploaded to it,
    /// with the ground layers `ground` (see [`MeshRenderer::with_ground`]; an empty mesh for
    /// the plain ground plane), drawing `size` pixels.
    ///
    /// # Errors
    /// No adapter, no device, or meshes the renderer refuses.
    pub fn new(
        meshes: &[(BlockId, Mesh)],
        ground: &Mesh,
        size: (u32, u32),
    ) -> Result<Self, RenderError> {
        Self::with_gpu(Gpu::new_headless()?, meshes, ground, size)
    }

    /// As [`Self::new`] on a device made elsewhere.
    ///
    /// # Errors
    /// Meshes the renderer refuses.
    pub fn with_gpu(
        gpu: Gpu,
        meshes: &[(BlockId, Mesh)],
        ground: &Mesh,
        size: (u32, u32),
    ) -> Result<Self, RenderError> {
        let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
        let renderer = MeshRenderer::with_ground(
            &gpu,
            &refs,
            ground,
            RenderOptions {
                width: size.0,
                height: size.1,
            },
        )?;
        Ok(Self {
            gpu,
            renderer,
            far: None,
            terrain: None,
        })
    }

    /// The same renderer drawing `terrain`: its tiles uploaded once
    /// ([`MeshRenderer::with_terrain`]), and on every frame its cut for the frame's camera and
    /// size drawn depth-tested before the meshes and before the far pass (which depth-tests
    /// against it, so hills hide far-field nodes). The ground plane and the ground layers are
    /// then not drawn ([`crate::visibility::draws_flat_ground`]).
    ///
    /// # Errors
    /// A malformed tile.
    pub fn with_terrain(self, terrain: SharedTerrain) -> Result<Self, RenderError> {
        let renderer = self.renderer.with_terrain(&self.gpu, terrain.as_ref())?;
        Ok(Self {
            renderer,
            terrain: Some(terrain),
            ..self
        })
    }

    /// The terrain tiles a frame from `camera` draws: the terrain's cut (none without one).
    fn cut(&self, camera: &Camera) -> Vec<usize> {
        let mut cut = Vec::new();
        if let Some(t) = &self.terrain {
            let o = self.renderer.options();
            t.cut(camera, (o.width, o.height), &mut cut);
        }
        cut
    }

    /// Draws `visible` (and the terrain's cut) with `shading`, reading the image back: the
    /// frames tests compare with the CPU oracle ([`Shading::Ids`]) and the CPU renderer.
    ///
    /// # Errors
    /// GPU failures; a cut naming a tile that does not exist.
    pub fn draw_shaded(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        shading: super::Shading,
    ) -> Result<super::Frame, RenderError> {
        let cut = self.cut(camera);
        self.renderer
            .draw_tiles(&self.gpu, camera, visible, &cut, shading, true)
    }

    /// The same renderer with the far-field `maps` uploaded ([`BlockMapRenderer`]), which
    /// [`FrameRenderer::draw_with_far`]'s `far` indexes.
    ///
    /// # Errors
    /// [`RenderError::BadBlockMap`] naming a map that is not valid.
    pub fn with_far_field(self, maps: &[&BlockMap]) -> Result<Self, RenderError> {
        let o = self.renderer.options();
        let far = BlockMapRenderer::new(&self.gpu, maps, (o.width, o.height))?;
        Ok(Self {
            far: Some(FarRenderer::BlockMaps(far)),
            ..self
        })
    }

    /// The same renderer with the relief impostors of `field` uploaded ([`ReliefRenderer`]),
    /// which [`FrameRenderer::draw_with_far`]'s `far` indexes (the field's nodes).
    ///
    /// # Errors
    /// [`RenderError::FarField`] naming a node or a device limit.
    pub fn with_relief(self, field: &ReliefField) -> Result<Self, RenderError> {
        let o = self.renderer.options();
        let far = ReliefRenderer::new(&self.gpu, field, (o.width, o.height))?;
        Ok(Self {
            far: Some(FarRenderer::Relief(far)),
            ..self
        })
    }

    /// The same renderer with the far field `far` uploaded (its GPU pass: [`BlockMapRenderer`]
    /// for BlockMaps, [`ReliefRenderer`] for relief impostors), which
    /// [`FrameRenderer::draw_with_far`]'s `far` indexes.
    ///
    /// # Errors
    /// The far field's upload errors (e.g. [`RenderError::BadBlockMap`],
    /// [`RenderError::FarField`]).
    pub fn with_far(self, far: &dyn FarField) -> Result<Self, RenderError> {
        let o = self.renderer.options();
        let far = FarRenderer::new(&self.gpu, far, (o.width, o.height))?;
        Ok(Self {
            far: Some(far),
            ..self
        })
    }

    /// The device.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// The far-field pass, when a far field was given.
    pub fn far_renderer(&self) -> Option<&FarRenderer> {
        self.far.as_ref()
    }

    /// The BlockMap pass, when BlockMaps were given.
    pub fn far_field(&self) -> Option<&BlockMapRenderer> {
        match &self.far {
            Some(FarRenderer::BlockMaps(r)) => Some(r),
            _ => None,
        }
    }

    /// The relief-impostor pass, when relief impostors were given.
    pub fn relief(&self) -> Option<&ReliefRenderer> {
        match &self.far {
            Some(FarRenderer::Relief(r)) => Some(r),
            _ => None,
        }
    }

    /// Draws `visible` as meshes, then the far-field nodes `far` in a second pass on the same
    /// colour and depth targets; reads back the image, the node ids and, when `with_depth`, the
    /// depth.
    ///
    /// # Errors
    /// [`RenderError::NoSuchMap`] for a node index that was not uploaded (all of them without
    /// a far field); GPU failures.
    pub fn draw_hybrid(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        far: &[usize],
        with_depth: bool,
    ) -> Result<HybridFrame, RenderError> {
        self.hybrid(
            camera,
            visible,
            far,
            FarReadback {
                color: true,
                depth: with_depth,
            },
        )
    }

    /// [`Self::draw_hybrid`] reading back what `read` asks for (without the colour, `rgba` is
    /// the mesh pass's image, not the composite).
    fn hybrid(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        far: &[usize],
        read: FarReadback,
    ) -> Result<HybridFrame, RenderError> {
        let far_renderer = match (&self.far, far.first()) {
            (Some(r), _) => Some(r),
            (None, None) => None,
            (None, Some(&index)) => return Err(RenderError::NoSuchMap { index, maps: 0 }),
        };
        // The far pass reads the composite back: the mesh image alone is not needed then.
        let in_place = far_renderer.is_some() && read.color;
        let cut = self.cut(camera);
        let meshes = self.renderer.draw_tiles(
            &self.gpu,
            camera,
            visible,
            &cut,
            super::Shading::Lit,
            !in_place,
        )?;
        let o = self.renderer.options();
        let Some(fr) = far_renderer else {
            return Ok(HybridFrame {
                width: o.width,
                height: o.height,
                rgba: meshes.rgba,
                depth: None,
                map_ids: vec![super::NO_MAP; (o.width * o.height) as usize],
                far_pixels: 0,
                passes: vec![("meshes", meshes.timings.best_s()), ("far", 0.0)],
                gpu_time: meshes.timings.gpu_s.is_some(),
                far_maps: 0,
                far_draws: 0,
            });
        };
        let pass = fr.draw(
            &self.gpu,
            camera,
            far,
            self.renderer.color_texture(),
            self.renderer.depth_texture(),
            read,
        )?;
        let gpu_time = meshes.timings.gpu_s.is_some() && pass.gpu_s.is_some();
        let (mesh_s, far_s) = if gpu_time {
            (meshes.timings.best_s(), pass.gpu_s.unwrap_or(pass.wall_s))
        } else {
            (meshes.timings.wall_s, pass.wall_s)
        };
        Ok(HybridFrame {
            width: o.width,
            height: o.height,
            rgba: pass.rgba.unwrap_or(meshes.rgba),
            depth: pass.depth,
            map_ids: pass.map_ids,
            far_pixels: pass.far_pixels,
            passes: vec![("meshes", mesh_s), ("far", far_s)],
            gpu_time,
            far_maps: pass.maps,
            far_draws: pass.draws,
        })
    }
}

impl FrameRenderer for GpuFrameRenderer {
    fn describe(&self) -> String {
        let o = self.renderer.options();
        format!(
            "GPU: {}{}, {}x{}{}{}",
            self.gpu.adapter_name(),
            if self.gpu.timestamps {
                ", GPU timestamps"
            } else {
                ", wall time (no timestamp queries)"
            },
            o.width,
            o.height,
            if self.terrain.is_some() {
                ", terrain"
            } else {
                ""
            },
            match &self.far {
                Some(f) => format!(", {}", f.describe()),
                None => String::new(),
            }
        )
    }
    fn size(&self) -> (u32, u32) {
        let o = self.renderer.options();
        (o.width, o.height)
    }
    fn draw(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError> {
        let frame = self.draw_shaded(camera, visible, super::Shading::Lit)?;
        Ok(DrawnFrame {
            seconds: frame.timings.best_s(),
            gpu_time: frame.timings.gpu_s.is_some(),
            image: if want_image { frame.to_image() } else { None },
            passes: Vec::new(),
            far_pixels: None,
        })
    }
    fn draw_with_far(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        far: &[usize],
        want_image: bool,
    ) -> Result<DrawnFrame, DrawError> {
        if self.far.is_none() && far.is_empty() {
            return self.draw(camera, visible, want_image);
        }
        let f = self.hybrid(
            camera,
            visible,
            far,
            FarReadback {
                color: want_image,
                depth: false,
            },
        )?;
        Ok(DrawnFrame {
            seconds: f.passes.iter().map(|p| p.1).sum(),
            gpu_time: f.gpu_time,
            image: if want_image { f.to_image() } else { None },
            passes: f.passes,
            far_pixels: Some(f.far_pixels),
        })
    }
}

/// The walk's GPU renderers on wgpu ([`GpuFrameRenderer`], with the far field uploaded when
/// given): what `walk::run_job` draws with when the `render` feature is built.
#[derive(Clone, Copy, Debug, Default)]
pub struct WgpuRenderers;

impl crate::walk::GpuRenderers for WgpuRenderers {
    fn renderer<'a>(
        &self,
        scene: &'a crate::scene::Scene,
        size: (u32, u32),
        far: Option<&'a dyn crate::walk::FarField>,
    ) -> Result<Box<dyn FrameRenderer + 'a>, String> {
        let mut r = GpuFrameRenderer::new(scene.draw_meshes(), &scene.ground, size)
            .map_err(|e| e.to_string())?;
        if let Some(t) = &scene.terrain {
            r = r.with_terrain(t.clone()).map_err(|e| e.to_string())?;
        }
        match far {
            None => Ok(Box::new(r)),
            Some(f) => Ok(Box::new(r.with_far(f).map_err(|e| e.to_string())?)),
        }
    }
}
