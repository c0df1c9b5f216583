//! GPU rendering with wgpu (feature `render`): headless, to a texture, read back to RGBA.
//!
//! - [`Gpu`]: adapter and device, created apart from the renderers so that tests and tools can
//!   bring their own (`Gpu::new_headless`, or [`Gpu::from_parts`]).
//! - [`GpuFrameRenderer`]: the walk's [`crate::visibility::FrameRenderer`] on a headless device.
//! - [`BlockMapRenderer`]: the far field, BlockMaps ray-cast on the GPU into the mesh pass's
//!   targets (`blockmap.wgsl`; the CPU reference is [`crate::blockmap::image`]).
//! - [`ReliefRenderer`]: the other far field, relief impostors ray-cast on the GPU over each
//!   node's max pyramid into the same targets (`relief.wgsl`; the CPU reference is
//!   [`crate::relief::image`]); [`FarRenderer`] holds either.
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
//! pass (ray-cast BlockMaps, Cignoni et al.) can either load them as attachments (`LoadOp::Load`) and
//! depth-test its fragments with `Less`, writing `@builtin(frag_depth)` computed with the same
//! projection, or sample the depth texture. Pixels no block covers keep depth 1.0 and the sky
//! colour; the ground plane writes its depth too.

mod blockmap;
mod far_pass;
mod frames;
mod mesh;
mod pack;
mod relief;
#[cfg(feature = "window")]
pub mod window;
#[cfg(feature = "window")]
pub mod window_stream;

pub use blockmap::{BlockMapRenderer, FarPass, FarReadback, NO_MAP};
pub use frames::{FarRenderer, GpuFrameRenderer, HybridFrame, WgpuRenderers};
pub use mesh::{Batching, Frame, FrameTimings, MeshRenderer, RenderOptions, Shading};
pub use relief::ReliefRenderer;

use crate::blocks::BlockId;

/// Names a mesh in errors: `block N`, or `the ground` for the renderer's own ground meshes
/// (which carry the ground's id).
fn mesh_name(block: crate::blocks::BlockId) -> String {
    if block.0 == mesh::GROUND_ID {
        "the ground".to_string()
    } else if block.0 == pack::TERRAIN {
        "the terrain".to_string()
    } else {
        format!("block {}", block.0)
    }
}

/// What can go wrong on the GPU side. Failures of wgpu and `image` keep their error as the
/// [`source`](std::error::Error::source); bad input says what input and what is wrong with it.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter (GPU or software rasteriser such as lavapipe) is available.
    #[error("no GPU adapter found: {source}")]
    NoAdapter {
        /// What wgpu said (the fallback-adapter request's error).
        #[source]
        source: wgpu::RequestAdapterError,
    },
    /// The only adapters found lack what the renderer needs (an OpenGL fallback without depth
    /// copies or compute, say): drawing falls back to the CPU as with no adapter.
    #[error("no usable GPU adapter: {adapter} lacks {missing:?}")]
    Unsupported {
        /// Adapter name and backend.
        adapter: String,
        /// The downlevel capabilities it lacks.
        missing: wgpu::DownlevelFlags,
    },
    /// The far field cannot be uploaded to this device (a map larger than its texture limit,
    /// say).
    #[error("the far field cannot be drawn on {adapter}: {what}")]
    FarField {
        /// Adapter name and backend.
        adapter: String,
        /// What is wrong.
        what: String,
    },
    /// The adapter refused to create a device.
    #[error("GPU device request on {adapter} failed: {source}")]
    Device {
        /// Adapter name and backend.
        adapter: String,
        /// What wgpu said.
        #[source]
        source: wgpu::RequestDeviceError,
    },
    /// Waiting for the device to finish before a read-back failed.
    #[error("GPU read-back of the {what}: waiting for the device failed: {source}")]
    Poll {
        /// What was being read back.
        what: Readback,
        /// What wgpu said.
        #[source]
        source: wgpu::PollError,
    },
    /// Mapping a read-back buffer failed.
    #[error("GPU read-back of the {what}: mapping the buffer failed: {source}")]
    Map {
        /// What was being read back.
        what: Readback,
        /// What wgpu said.
        #[source]
        source: wgpu::BufferAsyncError,
    },
    /// The buffer-map callback was dropped without reporting (the device was lost).
    #[error("GPU read-back of the {what}: the buffer-map callback never ran: {source}")]
    MapCallbackLost {
        /// What was being read back.
        what: Readback,
        /// The closed channel.
        #[source]
        source: std::sync::mpsc::RecvError,
    },
    /// The mapped range of a read-back buffer could not be viewed.
    #[error("GPU read-back of the {what}: {source}")]
    MapRange {
        /// What was being read back.
        what: Readback,
        /// What wgpu said.
        #[source]
        source: wgpu::MapRangeError,
    },
    /// A read-back buffer holds fewer bytes than expected.
    #[error("GPU read-back of the {what}: {got} bytes, expected {expected}")]
    ShortReadback {
        /// What was being read back.
        what: Readback,
        /// Bytes read.
        got: usize,
        /// Bytes needed.
        expected: usize,
    },
    /// An image could not be encoded or written.
    #[error("{file}: writing the image failed: {source}")]
    Image {
        /// The image file.
        file: std::path::PathBuf,
        /// What `image` said.
        #[source]
        source: image::ImageError,
    },
    /// A frame's pixel buffer does not match its size.
    #[error("frame of {width}x{height} pixels holds {bytes} bytes, not width × height × 4")]
    FrameSize {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
        /// Bytes in the buffer.
        bytes: usize,
    },
    /// The requested image size has no pixels.
    #[error("render: image size {width}x{height} is empty")]
    EmptyImage {
        /// Width asked for, pixels.
        width: u32,
        /// Height asked for, pixels.
        height: u32,
    },
    /// The requested image size exceeds what the adapter can render.
    #[error("render: image size {width}x{height} exceeds the adapter's {limit} pixels per side")]
    ImageTooLarge {
        /// Width asked for, pixels.
        width: u32,
        /// Height asked for, pixels.
        height: u32,
        /// The adapter's `max_texture_dimension_2d`.
        limit: u32,
    },
    /// A BlockMap given to the far-field renderer is not valid.
    #[error("render: far-field map {index}: {what}")]
    BadBlockMap {
        /// Index of the map in the list given.
        index: usize,
        /// What is wrong.
        what: String,
    },
    /// A far-field map index that the renderer does not hold.
    #[error("render: far-field map {index} does not exist ({maps} maps uploaded)")]
    NoSuchMap {
        /// The index asked for (or the length of a list longer than the maps).
        index: usize,
        /// Maps the renderer holds.
        maps: usize,
    },
    /// A terrain tile index (from a terrain's cut) that the renderer does not hold.
    #[error("render: terrain tile {index} does not exist ({tiles} tiles uploaded)")]
    NoSuchTile {
        /// The index asked for.
        index: usize,
        /// Tiles the renderer holds.
        tiles: usize,
    },
    /// A block id does not fit the id encoding (24 bits, less the ground's id; less the
    /// terrain's too when a terrain is drawn).
    #[error("render: block id {id} is too large (limit {limit})")]
    BlockIdTooLarge {
        /// The largest id given.
        id: u32,
        /// The largest id allowed.
        limit: u32,
    },
    /// A block mesh's arrays disagree: positions and normals differ in length, or the index
    /// count is not a multiple of 3.
    #[error(
        "render: {}: mesh has {positions} positions, {normals} normals, {indices} indices",
        mesh_name(*block)
    )]
    BadMesh {
        /// The block.
        block: BlockId,
        /// Positions.
        positions: usize,
        /// Normals.
        normals: usize,
        /// Indices.
        indices: usize,
    },
    /// A block mesh's appearance array does not match its vertices.
    #[error(
        "render: {}: mesh has {positions} positions but {appearance} appearance entries",
        mesh_name(*block)
    )]
    BadAppearance {
        /// The block.
        block: BlockId,
        /// Positions.
        positions: usize,
        /// Appearance entries.
        appearance: usize,
    },
    /// A vertex names a style the mesh does not have.
    #[error("render: {}: style {style} out of range ({styles} styles)", mesh_name(*block))]
    StyleOutOfRange {
        /// The block.
        block: BlockId,
        /// The style index.
        style: u32,
        /// Styles in the mesh.
        styles: usize,
    },
    /// A block mesh's index points past its vertices.
    #[error("render: {}: index {index} out of range ({vertices} vertices)", mesh_name(*block))]
    IndexOutOfRange {
        /// The block.
        block: BlockId,
        /// The bad index.
        index: u32,
        /// Vertices in the mesh.
        vertices: usize,
    },
    /// The meshes together have more vertices than a draw call can address.
    #[error("render: {vertices} vertices up to block {}, more than 32-bit indices address", block.0)]
    TooManyVertices {
        /// The block whose first vertex is out of reach.
        block: BlockId,
        /// Vertices before it.
        vertices: usize,
    },
}

/// What a GPU read-back was fetching (for [`RenderError`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Readback {
    /// The colour image of a frame.
    Frame,
    /// The render pass's timestamp queries.
    Timestamps,
    /// The far-field pass's map ids, colour and depth.
    FarField,
}

impl std::fmt::Display for Readback {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Readback::Frame => "frame",
            Readback::Timestamps => "timestamps",
            Readback::FarField => "far-field images",
        })
    }
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

/// The downlevel capabilities the renderer uses: compute shaders (the ray caster's probes) and
/// copies out of depth textures (the depth read-back).
pub const REQUIRED_DOWNLEVEL: wgpu::DownlevelFlags = wgpu::DownlevelFlags::COMPUTE_SHADERS
    .union(wgpu::DownlevelFlags::DEPTH_TEXTURE_AND_BUFFER_COPIES);

/// What of [`REQUIRED_DOWNLEVEL`] an adapter lacks (empty when it has all).
pub fn missing_capabilities(adapter: &wgpu::Adapter) -> wgpu::DownlevelFlags {
    REQUIRED_DOWNLEVEL.difference(adapter.get_downlevel_capabilities().flags)
}

impl Gpu {
    /// A headless device on the best available adapter (backends from `WGPU_BACKEND`, else all);
    /// takes a software adapter (e.g. lavapipe) when there is no hardware one, and refuses one
    /// that lacks [`REQUIRED_DOWNLEVEL`] ([`RenderError::Unsupported`]). Requests
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
        .map_err(|source| RenderError::NoAdapter { source })?;
        let adapter = match missing_capabilities(&adapter) {
            m if m.is_empty() => adapter,
            missing => {
                // A fallback (software) adapter that has them, else the first one's refusal.
                let info = adapter.get_info();
                let fallback =
                    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                        power_preference: wgpu::PowerPreference::None,
                        force_fallback_adapter: true,
                        compatible_surface: None,
                        apply_limit_buckets: false,
                    }))
                    .ok()
                    .filter(|a| missing_capabilities(a).is_empty());
                fallback.ok_or(RenderError::Unsupported {
                    adapter: format!("{} ({:?})", info.name, info.backend),
                    missing,
                })?
            }
        };
        Self::from_adapter(adapter)
    }

    /// A device on the given adapter.
    pub fn from_adapter(adapter: wgpu::Adapter) -> Result<Gpu, RenderError> {
        let info = adapter.get_info();
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
        .map_err(|source| RenderError::Device {
            adapter: format!("{} ({:?})", info.name, info.backend),
            source,
        })?;
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

/// Bytes per row of an RGBA8 (or other 4-byte) image `width` pixels wide in a read-back buffer:
/// texture-to-buffer copies need every row to start at a multiple of 256 bytes
/// (`COPY_BYTES_PER_ROW_ALIGNMENT`), so rows are padded and the padding is dropped on read-back.
pub(crate) fn padded_row_bytes(width: u32) -> u32 {
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    (width * 4).div_ceil(align) * align
}

/// GPU time of one render pass from two timestamp queries (beginning and end of the pass).
#[derive(Debug)]
pub(crate) struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
}

impl PassTimer {
    /// A timer for passes named `label`, or `None` when the device has no timestamp queries.
    pub(crate) fn new(gpu: &Gpu, label: &str) -> Option<Self> {
        gpu.timestamps.then(|| {
            let size = 2 * wgpu::QUERY_SIZE as u64;
            let set = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(label),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let buffer = |what: &str, usage| {
                gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("{label} {what}")),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            Self {
                set,
                resolve: buffer(
                    "timestamps",
                    wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                ),
                read: buffer(
                    "timestamps read-back",
                    wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                ),
            }
        })
    }

    /// The pass's timestamp writes: query 0 at its beginning, 1 at its end.
    pub(crate) fn writes(&self) -> wgpu::RenderPassTimestampWrites<'_> {
        wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// Resolves the queries into the read-back buffer (after the pass, in the same encoder).
    pub(crate) fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.read, 0, 2 * wgpu::QUERY_SIZE as u64);
    }

    /// Seconds between the two timestamps (after the encoder was submitted).
    ///
    /// # Errors
    /// Mapping the buffer failed, or it held fewer than two timestamps.
    pub(crate) fn seconds(&self, gpu: &Gpu) -> Result<f64, RenderError> {
        let bytes = mesh::map_read(gpu, &self.read, Readback::Timestamps)?;
        let stamp = |i: usize| -> Result<u64, RenderError> {
            bytes
                .get(i * 8..i * 8 + 8)
                .and_then(|b| b.try_into().ok())
                .map(u64::from_le_bytes)
                .ok_or(RenderError::ShortReadback {
                    what: Readback::Timestamps,
                    got: bytes.len(),
                    expected: 16,
                })
        };
        let ticks = stamp(1)?.wrapping_sub(stamp(0)?);
        Ok(ticks as f64 * gpu.queue.get_timestamp_period() as f64 * 1e-9)
    }
}

/// Parses and validates WGSL without a device (naga, as wgpu does at pipeline creation), so a
/// CI without an adapter still checks every shader; panics with naga's message.
#[cfg(test)]
pub(crate) fn validated_wgsl(src: &str) -> wgpu::naga::Module {
    use wgpu::naga;
    let module = naga::front::wgsl::parse_str(src).unwrap_or_else(|e| {
        panic!("{}", e.emit_to_string(src));
    });
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{e:?}"));
    module
}
