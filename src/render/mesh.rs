//! The block mesh renderer: one vertex and index buffer for the whole city, the units (blocks,
//! pages, buildings: [`crate::scene::units`]) laid out in their input order, and one indexed
//! draw per run of visible units that are neighbours in that order ([`Batching::Runs`]).
//!
//! Every vertex carries its unit's id and every index is absolute (no base vertex), so any
//! contiguous range of the index buffer is one `draw_indexed`, whatever units it spans. The
//! visible units are drawn in the order of the buffer; with one call per unit
//! ([`Batching::PerUnit`]) the triangles reach the rasteriser in the same order, so both give the
//! same image.

use super::pack::{pack_meshes, pack_terrain, BlockRange, PackedMeshes, Vertex, GROUND};
use super::{padded_row_bytes, Gpu, PassTimer, Readback, RenderError};
use crate::blocks::BlockId;
use crate::city::appearance;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::{draws_flat_ground, TerrainDraw};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;
use wgpu::util::DeviceExt;

/// Colour target format; not sRGB, so the bytes read back are what the shader wrote (block IDs
/// survive exactly).
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Depth target format (see the module docs of [`super`] for the depth convention).
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The ground's id (for naming its meshes in errors).
pub(crate) const GROUND_ID: u32 = GROUND;
/// Sky colour (linear RGB as written): [`appearance::SKY`].
fn sky() -> wgpu::Color {
    let [r, g, b] = appearance::unit_rgb(appearance::SKY);
    wgpu::Color {
        r: r as f64,
        g: g as f64,
        b: b as f64,
        a: 1.0,
    }
}

/// What a frame shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// Lit colours, ground and sky.
    #[default]
    Lit,
    /// Each block in a flat colour encoding `id + 1` in R (low byte), G, B; 0 where no block is
    /// (no ground, black background).
    Ids,
}

/// Image size and shading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

impl Default for RenderOptions {
    /// 1280 × 720.
    fn default() -> Self {
        Self {
            width: 1280,
            height: 720,
        }
    }
}

/// How long a frame took.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameTimings {
    /// GPU time of the render pass from timestamp queries, seconds (when the device has them).
    pub gpu_s: Option<f64>,
    /// Wall time from encoding to the image read back, seconds.
    pub wall_s: f64,
    /// Blocks drawn.
    pub blocks: u32,
    /// Triangles drawn (blocks only).
    pub triangles: u64,
    /// Draw calls of the units (the ground's call not counted).
    pub draws: u32,
}

impl FrameTimings {
    /// GPU time when measured, else wall time.
    pub fn best_s(&self) -> f64 {
        self.gpu_s.unwrap_or(self.wall_s)
    }
}

/// A rendered image (RGBA8, rows top to bottom, no padding) and its timings.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGBA bytes, `width * height * 4`.
    pub rgba: Vec<u8>,
    /// Timings.
    pub timings: FrameTimings,
}

impl Frame {
    /// The block id at each pixel of an [`Shading::Ids`] frame (`None` where no block is),
    /// row-major from the top-left.
    pub fn block_ids(&self) -> Vec<Option<BlockId>> {
        self.rgba
            .chunks_exact(4)
            .map(|p| {
                let v = p[0] as u32 | (p[1] as u32) << 8 | (p[2] as u32) << 16;
                v.checked_sub(1).map(BlockId)
            })
            .collect()
    }

    /// The image.
    pub fn to_image(&self) -> Option<image::RgbaImage> {
        image::RgbaImage::from_raw(self.width, self.height, self.rgba.clone())
    }

    /// Writes the frame as PNG.
    pub fn save_png(&self, path: &std::path::Path) -> Result<(), RenderError> {
        let img = self.to_image().ok_or(RenderError::FrameSize {
            width: self.width,
            height: self.height,
            bytes: self.rgba.len(),
        })?;
        crate::output::write_png(path, &img)
            .map(drop)
            .map_err(|source| RenderError::Image {
                file: path.to_path_buf(),
                source,
            })
    }
}

/// The `appearance` constants `mesh.wgsl` uses, as WGSL declarations printed from the Rust
/// values (`{:?}` prints the shortest decimal that reads back as the same f32).
fn wgsl_constants() -> String {
    use appearance::*;
    let u = unit_rgb(UNDERSIDE);
    let t = unit_rgb(TERRAIN);
    let terrain_id = crate::visibility::TERRAIN_ID;
    format!(
        "const SILL: f32 = {SILL:?};\n\
         const LINTEL: f32 = {LINTEL:?};\n\
         const GROUND_SILL: f32 = {GROUND_SILL:?};\n\
         const GROUND_LINTEL: f32 = {GROUND_LINTEL:?};\n\
         const GROUND_FLOOR_SHADE: f32 = {GROUND_FLOOR_SHADE:?};\n\
         const UNDERSIDE: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});\n\
         const TERRAIN: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});\n\
         const TERRAIN_ID: u32 = {terrain_id}u;\n",
        u[0], u[1], u[2], t[0], t[1], t[2]
    )
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Globals {
    clip_from_world: [[f32; 4]; 4],
    sun: [f32; 4],
    mode: [u32; 4],
}

/// How the visible units are turned into draw calls.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Batching {
    /// One call per run of visible units that are neighbours in the index buffer (the units'
    /// input order): a block whose buildings are all visible is one call.
    #[default]
    Runs,
    /// One call per visible unit, in the same order (the reference the runs are checked
    /// against; as many calls as units).
    PerUnit,
}

/// The draw calls for `visible`: their ranges (unknown ids, empty units and repeats left out),
/// in index-buffer order, neighbours merged with [`Batching::Runs`]. Returns the units drawn.
fn draw_ranges(
    ranges: &[Option<BlockRange>],
    visible: &[BlockId],
    batching: Batching,
    out: &mut Vec<BlockRange>,
) -> u32 {
    out.clear();
    out.extend(
        visible
            .iter()
            .filter_map(|id| ranges.get(id.0 as usize).copied().flatten())
            .filter(|r| r.index_count > 0),
    );
    out.sort_unstable();
    out.dedup();
    let units = out.len() as u32;
    if batching == Batching::Runs {
        let mut w = 0;
        for i in 0..out.len() {
            let r = out[i];
            if w > 0 && out[w - 1].first_index + out[w - 1].index_count == r.first_index {
                out[w - 1].index_count += r.index_count;
            } else {
                out[w] = r;
                w += 1;
            }
        }
        out.truncate(w);
    }
    units
}

/// A terrain's tiles on the GPU: one vertex and one index buffer, a range of indices per tile.
struct TerrainBuffers {
    /// `None` when the tiles hold no triangle (nothing to bind).
    buffers: Option<(wgpu::Buffer, wgpu::Buffer)>,
    ranges: Vec<BlockRange>,
}

/// Uploaded block meshes and the render targets.
pub struct MeshRenderer {
    options: RenderOptions,
    pipeline: wgpu::RenderPipeline,
    /// The ground layers: same shader, depth test always passing (painter's order).
    ground_pipeline: wgpu::RenderPipeline,
    /// The ground plane, drawn after the buildings where nothing else is (see [`Self::plane`]).
    plane_pipeline: wgpu::RenderPipeline,
    globals: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// Indexed by `BlockId.0`.
    ranges: Vec<Option<BlockRange>>,
    /// The ground plane's triangles.
    ///
    /// The plane lies under everything else, so it is drawn last, with the depth test (`Less`)
    /// and a depth bias that moves it back by two depth steps and one pixel's depth slope:
    /// where a ground layer (coplanar, drawn first) or a building was drawn it fails the test
    /// before its fragment is shaded, and elsewhere the depth buffer still holds the clear value
    /// and it passes. The picture is the painter's order's (plane, layers, buildings), the
    /// depth of a plane pixel is the plane's, moved back by the bias; but only the plane's
    /// visible pixels are shaded. On lavapipe the full-screen plane cost about 50 ms of a
    /// 1280×1024 fly-over frame of the 80k generated city drawn first.
    plane: BlockRange,
    /// The ground layers' triangles, in drawing order.
    ground: BlockRange,
    batching: Batching,
    /// The terrain's tiles, when uploaded ([`Self::with_terrain`]).
    terrain: Option<TerrainBuffers>,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    readback: wgpu::Buffer,
    padded_row: u32,
    queries: Option<PassTimer>,
}

impl std::fmt::Debug for MeshRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshRenderer")
            .field("options", &self.options)
            .field("blocks", &self.ranges.iter().flatten().count())
            .finish()
    }
}

impl MeshRenderer {
    /// Uploads the meshes at 1280 × 720 ([`RenderOptions::default`]).
    pub fn new(gpu: &Gpu, blocks: &[(BlockId, &Mesh)]) -> Result<Self, RenderError> {
        Self::with_options(gpu, blocks, RenderOptions::default())
    }

    /// Uploads the meshes (local frame, f32, as in [`Mesh`]); a block may appear several times
    /// (one mesh per building), its meshes are drawn together. The blocks are laid out in the
    /// order of their first appearance, which is the order they are drawn in and the order
    /// whose neighbours [`Batching::Runs`] merges. Lit frames show the ground plane only; see
    /// [`Self::with_ground`] for streets and blocks on the ground.
    pub fn with_options(
        gpu: &Gpu,
        blocks: &[(BlockId, &Mesh)],
        options: RenderOptions,
    ) -> Result<Self, RenderError> {
        Self::with_ground(gpu, blocks, &Mesh::default(), options)
    }

    /// As [`Self::with_options`], with ground layers (streets, blocks' ground: a mesh such as
    /// [`appearance::ground_mesh`] gives, flat at z = 0) drawn in lit frames: first the ground
    /// plane, then `ground`'s triangles in their order, with the depth test always passing (so
    /// later layers cover earlier ones without z-fighting and without z offsets), then the
    /// blocks with the `Less` depth test. The ground is never drawn in [`Shading::Ids`] frames.
    pub fn with_ground(
        gpu: &Gpu,
        blocks: &[(BlockId, &Mesh)],
        ground_layers: &Mesh,
        options: RenderOptions,
    ) -> Result<Self, RenderError> {
        if options.width == 0 || options.height == 0 {
            return Err(RenderError::EmptyImage {
                width: options.width,
                height: options.height,
            });
        }
        let limit = gpu.device.limits().max_texture_dimension_2d;
        if options.width > limit || options.height > limit {
            return Err(RenderError::ImageTooLarge {
                width: options.width,
                height: options.height,
                limit,
            });
        }
        let device = &gpu.device;
        let PackedMeshes {
            vertices,
            indices,
            styles,
            ranges,
            plane,
            ground,
        } = pack_meshes(blocks, ground_layers)?;

        let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("block vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("block indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let style_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("styles"),
            contents: bytemuck::cast_slice(&styles),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: style_buffer.as_entire_binding(),
                },
            ],
        });
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mesh.wgsl"),
            source: wgpu::ShaderSource::Wgsl((wgsl_constants() + include_str!("mesh.wgsl")).into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("mesh"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let attributes = wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32, 3 => Uint32, 4 => Uint32
        ];
        let make_pipeline = |label, depth_compare, bias| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: std::mem::size_of::<Vertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &attributes,
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    front_face: wgpu::FrontFace::Ccw,
                    // Meshes are closed and outward-oriented; no culling keeps open or flipped input
                    // visible rather than silently missing.
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias,
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: COLOR_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let pipeline = make_pipeline("mesh", wgpu::CompareFunction::Less, Default::default());
        let ground_pipeline =
            make_pipeline("ground", wgpu::CompareFunction::Always, Default::default());
        let plane_pipeline = make_pipeline(
            "ground plane",
            wgpu::CompareFunction::Less,
            wgpu::DepthBiasState {
                constant: 2,
                slope_scale: 1.0,
                clamp: 0.0,
            },
        );

        let size = wgpu::Extent3d {
            width: options.width,
            height: options.height,
            depth_or_array_layers: 1,
        };
        let target = |label, format| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let color = target("colour", COLOR_FORMAT);
        let depth = target("depth", DEPTH_FORMAT);
        let padded_row = padded_row_bytes(options.width);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: padded_row as u64 * options.height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let queries = PassTimer::new(gpu, "mesh pass");
        Ok(Self {
            options,
            pipeline,
            ground_pipeline,
            plane_pipeline,
            globals,
            bind_group,
            vertices: vertex_buffer,
            indices: index_buffer,
            ranges,
            plane,
            ground,
            batching: Batching::default(),
            terrain: None,
            color,
            depth,
            readback,
            padded_row,
            queries,
        })
    }

    /// The same renderer with `terrain`'s tiles uploaded (once: one vertex and one index
    /// buffer, a range per tile). Frames then draw terrain tiles depth-tested and writing depth,
    /// after the ground layers would be and before the units, in both shadings: lit in
    /// [`appearance::TERRAIN`] with the first vertex's normal (as
    /// [`crate::visibility::oracle::shade_with_terrain`]), and with the terrain's id
    /// ([`crate::visibility::TERRAIN_ID`]) in [`Shading::Ids`] frames. The ground plane and the
    /// ground layers are no longer drawn ([`draws_flat_ground`]). [`Self::draw`] and its kin draw
    /// every tile; [`Self::draw_tiles`] draws a terrain's cut.
    ///
    /// # Errors
    /// A malformed tile ([`RenderError::BadMesh`], …, naming the terrain);
    /// [`RenderError::BlockIdTooLarge`] when a unit's id is the terrain's or above (ids
    /// must stay below [`crate::visibility::TERRAIN_ID`] when a terrain is drawn).
    pub fn with_terrain(self, gpu: &Gpu, terrain: &dyn TerrainDraw) -> Result<Self, RenderError> {
        let terrain_id = crate::visibility::TERRAIN_ID;
        if let Some(id) = self.ranges.len().checked_sub(1) {
            if id >= terrain_id as usize {
                return Err(RenderError::BlockIdTooLarge {
                    id: id as u32,
                    limit: terrain_id - 1,
                });
            }
        }
        let (vertices, indices, ranges) = pack_terrain(terrain.tiles())?;
        let buffers = (!indices.is_empty()).then(|| {
            let v = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("terrain vertices"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                });
            let i = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("terrain indices"),
                    contents: bytemuck::cast_slice(&indices),
                    usage: wgpu::BufferUsages::INDEX,
                });
            (v, i)
        });
        Ok(Self {
            terrain: Some(TerrainBuffers { buffers, ranges }),
            ..self
        })
    }

    /// Terrain tiles uploaded (`None` without a terrain).
    pub fn terrain_tiles(&self) -> Option<usize> {
        self.terrain.as_ref().map(|t| t.ranges.len())
    }

    /// The same renderer turning visible units into calls as `batching` says.
    pub fn with_batching(self, batching: Batching) -> Self {
        Self { batching, ..self }
    }

    /// How visible units become draw calls.
    pub fn batching(&self) -> Batching {
        self.batching
    }

    /// Image size.
    pub fn options(&self) -> RenderOptions {
        self.options
    }

    /// The colour target of the last frame (for a later pass; see the module docs).
    pub fn color_texture(&self) -> &wgpu::Texture {
        &self.color
    }

    /// The depth target of the last frame (for a later pass; see the module docs).
    pub fn depth_texture(&self) -> &wgpu::Texture {
        &self.depth
    }

    /// Draws the blocks in `visible` (others are not drawn; unknown ids and repeats are skipped)
    /// lit, with ground and sky, and reads the image back; the blocks are drawn in the order of
    /// the buffer (see [`Self::with_options`]), not of `visible`. The camera's aspect should
    /// match the image's.
    pub fn draw(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        visible: &[BlockId],
    ) -> Result<Frame, RenderError> {
        self.draw_shaded(gpu, camera, visible, Shading::Lit)
    }

    /// As [`Self::draw`], with the given shading.
    pub fn draw_shaded(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        visible: &[BlockId],
        shading: Shading,
    ) -> Result<Frame, RenderError> {
        let all = self.all_tiles();
        self.render(gpu, camera, visible, &all, shading, true)
    }

    /// As [`Self::draw_shaded`], drawing the terrain tiles `tiles` (a terrain's cut: indices
    /// into the tiles given to [`Self::with_terrain`]; ignored without a terrain); with `read`
    /// false the image stays in the targets as with [`Self::draw_in_place`].
    ///
    /// # Errors
    /// [`RenderError::NoSuchTile`] for a tile index that was not uploaded; GPU failures.
    pub fn draw_tiles(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        visible: &[BlockId],
        tiles: &[usize],
        shading: Shading,
        read: bool,
    ) -> Result<Frame, RenderError> {
        self.render(gpu, camera, visible, tiles, shading, read)
    }

    /// Every uploaded terrain tile (none without a terrain).
    fn all_tiles(&self) -> Vec<usize> {
        (0..self.terrain_tiles().unwrap_or(0)).collect()
    }

    /// As [`Self::draw`], but the image stays in [`Self::color_texture`] and
    /// [`Self::depth_texture`] (the returned frame's `rgba` is empty; the GPU has finished when
    /// it returns): for a pass that draws on top of it and reads the result back itself, such as
    /// the far field's.
    pub fn draw_in_place(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        visible: &[BlockId],
    ) -> Result<Frame, RenderError> {
        let all = self.all_tiles();
        self.render(gpu, camera, visible, &all, Shading::Lit, false)
    }

    fn render(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        visible: &[BlockId],
        tiles: &[usize],
        shading: Shading,
        read: bool,
    ) -> Result<Frame, RenderError> {
        let start = Instant::now();
        // The terrain's calls (checked before anything is encoded).
        let mut terrain_calls: Vec<BlockRange> = Vec::new();
        if let Some(t) = &self.terrain {
            for &index in tiles {
                let r = *t.ranges.get(index).ok_or(RenderError::NoSuchTile {
                    index,
                    tiles: t.ranges.len(),
                })?;
                if r.index_count > 0 {
                    terrain_calls.push(r);
                }
            }
        }
        let flat_ground = draws_flat_ground(self.terrain.is_some());
        let m = crate::city::LocalFrame::round_matrix_to_f32(camera.clip_from_world());
        // appearance::shade: the sun and the ambient term.
        let sun = appearance::sun_direction();
        let globals = Globals {
            clip_from_world: m.to_cols_array_2d(),
            sun: [sun.x, sun.y, sun.z, appearance::AMBIENT],
            mode: [matches!(shading, Shading::Ids) as u32, 0, 0, 0],
        };
        gpu.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
        let color_view = self.color.create_view(&Default::default());
        let depth_view = self.depth.create_view(&Default::default());
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        let mut calls: Vec<BlockRange> = Vec::new();
        let blocks = draw_ranges(&self.ranges, visible, self.batching, &mut calls);
        let draws = calls.len() as u32;
        let triangles: u64 = calls.iter().map(|r| r.index_count as u64 / 3).sum();
        {
            let clear = match shading {
                Shading::Lit => sky(),
                Shading::Ids => wgpu::Color::BLACK,
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("blocks"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(clear),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: self.queries.as_ref().map(PassTimer::writes),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            let lit = shading == Shading::Lit;
            if lit && flat_ground && self.ground.index_count > 0 {
                // Ground layers in order, depth test always passing.
                pass.set_pipeline(&self.ground_pipeline);
                let g = self.ground;
                pass.draw_indexed(g.first_index..g.first_index + g.index_count, 0, 0..1);
            }
            pass.set_pipeline(&self.pipeline);
            if let Some((tv, ti)) = self.terrain.as_ref().and_then(|t| t.buffers.as_ref()) {
                // The terrain's tiles, depth-tested like the units (its vertices carry the
                // terrain's id: mesh.wgsl colours them as terrain), then back to the units.
                if !terrain_calls.is_empty() {
                    pass.set_vertex_buffer(0, tv.slice(..));
                    pass.set_index_buffer(ti.slice(..), wgpu::IndexFormat::Uint32);
                    for r in &terrain_calls {
                        pass.draw_indexed(r.first_index..r.first_index + r.index_count, 0, 0..1);
                    }
                    pass.set_vertex_buffer(0, self.vertices.slice(..));
                    pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
                }
            }
            // Unit ids travel with the vertices (see mesh.wgsl): a call may span many units.
            for r in &calls {
                pass.draw_indexed(r.first_index..r.first_index + r.index_count, 0, 0..1);
            }
            if lit && flat_ground {
                // The plane under everything, where nothing else was drawn (see `plane`).
                pass.set_pipeline(&self.plane_pipeline);
                let p = self.plane;
                pass.draw_indexed(p.first_index..p.first_index + p.index_count, 0, 0..1);
            }
        }
        if let Some(t) = &self.queries {
            t.resolve(&mut encoder);
        }
        if !read {
            gpu.queue.submit([encoder.finish()]);
            gpu.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|source| RenderError::Poll {
                    what: Readback::Frame,
                    source,
                })?;
            let gpu_s = self.queries.as_ref().map(|t| t.seconds(gpu)).transpose()?;
            return Ok(Frame {
                width: self.options.width,
                height: self.options.height,
                rgba: Vec::new(),
                timings: FrameTimings {
                    gpu_s,
                    wall_s: start.elapsed().as_secs_f64(),
                    blocks,
                    triangles,
                    draws,
                },
            });
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    // Padded to 256 bytes per row (see `padded_row_bytes`).
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.options.height),
                },
            },
            wgpu::Extent3d {
                width: self.options.width,
                height: self.options.height,
                depth_or_array_layers: 1,
            },
        );
        gpu.queue.submit([encoder.finish()]);

        let rgba = self.read_image(gpu)?;
        let gpu_s = self.queries.as_ref().map(|t| t.seconds(gpu)).transpose()?;
        Ok(Frame {
            width: self.options.width,
            height: self.options.height,
            rgba,
            timings: FrameTimings {
                gpu_s,
                wall_s: start.elapsed().as_secs_f64(),
                blocks,
                triangles,
                draws,
            },
        })
    }

    /// Maps the read-back buffer and strips the row padding.
    fn read_image(&self, gpu: &Gpu) -> Result<Vec<u8>, RenderError> {
        let bytes = map_read(gpu, &self.readback, Readback::Frame)?;
        let row = (self.options.width * 4) as usize;
        let mut rgba = Vec::with_capacity(row * self.options.height as usize);
        for y in 0..self.options.height as usize {
            let start = y * self.padded_row as usize;
            rgba.extend_from_slice(&bytes[start..start + row]);
        }
        Ok(rgba)
    }
}

/// Maps `buffer` (holding `what`) for reading, waits, copies its bytes out and unmaps it.
pub(super) fn map_read(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    what: Readback,
) -> Result<Vec<u8>, RenderError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|source| RenderError::Poll { what, source })?;
    rx.recv()
        .map_err(|source| RenderError::MapCallbackLost { what, source })?
        .map_err(|source| RenderError::Map { what, source })?;
    let bytes = buffer
        .get_mapped_range(..)
        .map_err(|source| RenderError::MapRange { what, source })?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader, with its constants, parses and validates without a device (naga, as wgpu
    /// does at pipeline creation).
    #[test]
    fn shader_is_valid_wgsl() {
        let src = wgsl_constants() + include_str!("mesh.wgsl");
        super::super::validated_wgsl(&src);
        assert!(src.contains(&format!(
            "const TERRAIN_ID: u32 = {}u;",
            crate::visibility::TERRAIN_ID
        )));
    }

    fn r(first_index: u32, index_count: u32) -> Option<BlockRange> {
        Some(BlockRange {
            first_index,
            index_count,
        })
    }

    #[test]
    fn neighbours_merge_into_one_call_in_buffer_order() {
        // Units 0..5 back to back (unit 2 empty), unit 5 absent.
        let ranges = [r(6, 3), r(9, 6), r(15, 0), r(15, 3), r(18, 9), None];
        let ids = |v: &[u32]| v.iter().map(|&i| BlockId(i)).collect::<Vec<_>>();
        let mut out = Vec::new();
        // 4, 0, 1, 3 (any order) with the empty 2 and unknown 5, 9 and a repeat: 0–1 and 3–4
        // are neighbours (the empty unit takes no room), so 0..4 is one call.
        let n = draw_ranges(
            &ranges,
            &ids(&[4, 0, 2, 1, 5, 9, 3, 0]),
            Batching::Runs,
            &mut out,
        );
        assert_eq!(n, 4);
        assert_eq!(out, vec![r(6, 21).unwrap()]);
        // A gap splits the run.
        let n = draw_ranges(&ranges, &ids(&[4, 0]), Batching::Runs, &mut out);
        assert_eq!(n, 2);
        assert_eq!(out, vec![r(6, 3).unwrap(), r(18, 9).unwrap()]);
        // One call per unit, in buffer order.
        let n = draw_ranges(&ranges, &ids(&[3, 1, 0]), Batching::PerUnit, &mut out);
        assert_eq!(n, 3);
        assert_eq!(
            out,
            vec![r(6, 3).unwrap(), r(9, 6).unwrap(), r(15, 3).unwrap()]
        );
        assert_eq!(draw_ranges(&ranges, &[], Batching::Runs, &mut out), 0);
        assert!(out.is_empty());
    }
}
