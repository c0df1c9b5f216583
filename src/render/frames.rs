//! The wgpu renderer as the walk's [`FrameRenderer`].

use super::{Gpu, MeshRenderer, RenderError, RenderOptions};
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::{DrawError, DrawnFrame, FrameRenderer};

/// A headless GPU renderer of a scene's block meshes, uploaded once.
pub struct GpuFrameRenderer {
    gpu: Gpu,
    renderer: MeshRenderer,
}

impl std::fmt::Debug for GpuFrameRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuFrameRenderer")
            .field("gpu", &self.gpu)
            .finish()
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
        let gpu = Gpu::new_headless()?;
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
        Ok(Self { gpu, renderer })
    }

    /// The device.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }
}

impl FrameRenderer for GpuFrameRenderer {
    fn describe(&self) -> String {
        let o = self.renderer.options();
        format!(
            "GPU: {}{}, {}x{}",
            self.gpu.adapter_name(),
            if self.gpu.timestamps {
                ", GPU timestamps"
            } else {
                ", wall time (no timestamp queries)"
            },
            o.width,
            o.height
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
        let frame = self.renderer.draw(&self.gpu, camera, visible)?;
        Ok(DrawnFrame {
            seconds: frame.timings.best_s(),
            gpu_time: frame.timings.gpu_s.is_some(),
            image: if want_image { frame.to_image() } else { None },
            passes: Vec::new(),
            far_pixels: None,
        })
    }
}
