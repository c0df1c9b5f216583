//! GPU rendering with wgpu (feature `render`): headless, to a texture, read back to RGBA.
//!
//! - [`Gpu`]: adapter and device, created apart from the renderers so that tests and tools can
//!   bring their own (`Gpu::new_headless`, or [`Gpu::from_parts`]).
//! - [`MeshRenderer`]: uploads the block meshes once, then draws the blocks a culler lists, lit
//!   (the procedural appearance of [`crate::city::appearance`], mirrored in `mesh.wgsl`: facades
//!   with windows, roofs, ground plane, streets and blocks' ground; sun + ambient; sky) or as flat
//!   block IDs (for comparison with the CPU visibility oracle).
//!
//! ## Colour and depth for later passes
//! A frame leaves two targets in [`MeshRenderer`]: colour (`Rgba8Unorm`) and depth
//! (`Depth32Float`, cleared to 1.0, `Less`, standard — not reversed — depth of the same
//! `clip_from_world` that [`crate::geom::Camera::clip_from_world`] gives, depth range 0..1). Both
//! textures are created with `RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`, so a far-field
//! pass (ray-cast BlockMaps, seed 000) can either load them as attachments (`LoadOp::Load`) and
//! depth-test its fragments with `Less`, writing `@builtin(frag_depth)` computed with the same
//! projection, or sample the depth texture. Pixels no block covers keep depth 1.0 and the sky
//! colour; the ground plane writes its depth too.

mod mesh;
#[cfg(feature = "window")]
pub mod window;

pub use mesh::{Frame, FrameTimings, MeshRenderer, RenderOptions, Shading};

/// What can go wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter (GPU or software rasteriser such as lavapipe) is available.
    #[error("no GPU adapter found: {0}")]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("GPU device request failed: {0}")]
    Device(String),
    /// Reading the image back failed.
    #[error("GPU read-back failed: {0}")]
    Readback(String),
    /// Bad input to the renderer.
    #[error("render: {0}")]
    Input(String),
}

/// An adapter, device and queue, and what they can do.
pub struct Gpu {
    /// The adapter.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// True when the device was created with `TIMESTAMP_QUERY` (GPU timings available).
    pub timestamps: bool,
}

impl std::fmt::Debug for Gpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gpu")
            .field("adapter", &self.adapter_name())
            .field("timestamps", &self.timestamps)
            .finish()
    }
}

impl Gpu {
    /// A headless device on the best available adapter (backends from `WGPU_BACKEND`, else all);
    /// takes a software adapter (e.g. lavapipe) when there is no hardware one. Requests
    /// `TIMESTAMP_QUERY` when the adapter offers it.
    pub fn new_headless() -> Result<Gpu, RenderError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .or_else(|_| {
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::None,
                force_fallback_adapter: true,
                compatible_surface: None,
                apply_limit_buckets: false,
            }))
        })
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Self::from_adapter(adapter)
    }

    /// A device on the given adapter.
    pub fn from_adapter(adapter: wgpu::Adapter) -> Result<Gpu, RenderError> {
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("blockwalk"),
            required_features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device(e.to_string()))?;
        Ok(Gpu {
            adapter,
            device,
            queue,
            timestamps,
        })
    }

    /// Wraps an adapter, device and queue made elsewhere.
    pub fn from_parts(
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Result<Gpu, RenderError> {
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        Ok(Gpu {
            adapter,
            device,
            queue,
            timestamps,
        })
    }

    /// Adapter name and backend, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan)`.
    pub fn adapter_name(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?})", info.name, info.backend)
    }

    /// True for a CPU rasteriser (lavapipe, WARP, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.adapter.get_info().device_type == wgpu::DeviceType::Cpu
    }
}
