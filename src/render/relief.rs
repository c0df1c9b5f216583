//! The far-field pass of relief impostors (Andujar et al., §5.2): every node's maps ray-cast on
//! the GPU into the colour and depth targets the mesh pass left, as the CPU reference
//! [`crate::relief::image::cast_image`] draws them.
//!
//! - **Storage**: every node's maps are uploaded once into 2D texture arrays, one set of arrays
//!   ("page") per map side `M` and per up to 256 nodes and 256 oblique maps (WebGPU's default
//!   `max_texture_array_layers`), all read with integer `textureLoad`s (`textureSample` is not
//!   allowed in the non-uniform loop): the zenithal colour (`Rgba8Uint`, a layer per node), the
//!   zenithal height (`R16Uint`, a layer per node) whose mip chain is the max pyramid
//!   ([`NodeMaps::levels`]: level 0 the map, then [`NodeMaps::upper`]), and the oblique maps'
//!   colour (`Rgba8Uint`) and depth (`R16Uint`), a layer per oblique map, a node's in a row.
//! - **Per frame**: the decisions of [`crate::relief::image::frame_nodes`] (horizon nodes drawn as
//!   the flat quad, the three obliques that colour the walls, the ray constants), made on the
//!   renderer's own copy of every node's [`NodeFrameInfo`], so that they are the CPU
//!   renderer's; they and the chosen obliques' [`ObliqueXform`] rows and tolerances go to the
//!   shader as per-instance constants.
//! - **Draw**: one instanced draw of 36 vertices per page that has nodes to draw, one instance
//!   per node, in the order `far` lists them within a page (so two nodes of different pages at
//!   exactly the same depth may resolve otherwise than the reference's "first listed wins";
//!   only with more than 256 nodes or oblique maps, or maps of several sides). Each instance
//!   rasterises its box's **back faces** (the node's box, which holds every covered texel's
//!   whole column, enlarged a little so that rasterisation never drops a pixel the walk keeps),
//!   clipped at the near plane only, so that
//!   the eye inside a box works and a box past the far plane still draws; the fragment walks the
//!   max pyramid from the near plane (the pyramidal displacement mapping of Oh, Ki and Lee, the
//!   same walk as [`crate::relief::cast::cast_f32`] operation for operation, or
//!   [`crate::relief::cast::cast_flat`] for a horizon node), colours the hit as
//!   [`crate::relief::node::shade`], writes `frag_depth` (so meshes and impostors composite with
//!   the `Less` test) and the node's index to a second, `R32Uint` target (counted for
//!   [`FarPass::far_pixels`]); misses `discard`.
//! - **Exactness**: the shader runs the reference's `f32` operations in its order, so an adapter
//!   whose arithmetic is IEEE `f32` draws the reference's image. One whose division is not
//!   correctly rounded in the last bit (lavapipe's) parts from it only at ties (of the walk, or
//!   of the colouring) and in the last bits of the depth (`tests/relief_gpu.rs` measures both).
//! - Writing depth disables early depth tests; the proxy's own depth is not used.

use super::blockmap::FarPass;
use super::far_pass::{FarReadback, FarTargets, ID_FORMAT};
use super::{Gpu, PassTimer, RenderError};
use crate::blockmap::FrameRays;
use crate::geom::Camera;
use crate::relief::cast::step_limit;
use crate::relief::image::frame_nodes;
use crate::relief::node::{NodeFrameInfo, ObliqueXform, CHOSEN};
use crate::relief::{NodeMaps, ReliefField};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Colour target format (as the mesh pass's).
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Depth target format (as the mesh pass's).
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Colour maps: the bytes, read as integers.
const COLOR_MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Uint;
/// Height and depth maps: the 16-bit values, read as integers.
const DEPTH_MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Uint;
/// The node-index target.
/// Layers of one array of a page at most.
const PAGE_LAYERS: u32 = 256;
/// Value of a chosen-oblique slot with no map.
const NONE: u32 = u32::MAX;
/// Textures a page binds to the fragment stage.
const PAGE_TEXTURES: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    clip_from_world: [[f32; 4]; 4],
    /// sx, cx, sy, cy.
    pix: [f32; 4],
    /// near, r, rn, one height quantum.
    depth: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Instance {
    ax: [f32; 4],
    ay: [f32; 4],
    af: [f32; 4],
    b: [f32; 4],
    box_min: [f32; 4],
    box_max: [f32; 4],
    /// Zenithal layer, M, pyramid levels, flat.
    info: [u32; 4],
    /// Step limit, node index.
    extra: [u32; 4],
    /// Oblique layers of the chosen maps ([`NONE`] where none).
    chosen: [u32; 4],
    /// Rows of the chosen maps' affine maps, three per map.
    rows: [[f32; 4]; 9],
    /// Their tolerances.
    tol: [f32; 4],
    /// While a switch is blended: the previous three's oblique layers ([`NONE`] where none),
    /// and in `w` the new set's weight of 256 (256: no blend).
    prev: [u32; 4],
    /// Rows of the previous maps' affine maps.
    prev_rows: [[f32; 4]; 9],
    /// Their tolerances.
    prev_tol: [f32; 4],
}

/// One set of texture arrays.
struct Page {
    bind_group: wgpu::BindGroup,
}

/// Where a node's maps live and what its proxy is.
#[derive(Clone, Debug)]
struct Slot {
    page: usize,
    /// Its layer in the zenithal arrays.
    layer: u32,
    /// The layer of its first oblique map in the oblique arrays.
    oblique_layer: u32,
    m: u32,
    levels: u32,
    /// The proxy box (local frame, f32): every hit of the walk lies in it, with a margin so
    /// that rasterisation never drops a pixel the walk keeps.
    box_min: [f32; 3],
    box_max: [f32; 3],
}

/// The uploaded relief impostors and their pipeline.
pub struct ReliefRenderer {
    size: (u32, u32),
    pipeline: wgpu::RenderPipeline,
    frame: wgpu::Buffer,
    instances: wgpu::Buffer,
    capacity: usize,
    globals: wgpu::BindGroup,
    pages: Vec<Page>,
    slots: Vec<Slot>,
    infos: Vec<NodeFrameInfo>,
    xforms: Vec<Vec<ObliqueXform>>,
    sets: std::sync::Mutex<crate::relief::image::MapSets>,
    bytes: u64,
    obliques: usize,
    targets: FarTargets,
    queries: Option<PassTimer>,
}

impl std::fmt::Debug for ReliefRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReliefRenderer")
            .field("size", &self.size)
            .field("nodes", &self.slots.len())
            .field("obliques", &self.obliques)
            .field("pages", &self.pages.len())
            .field("bytes", &self.bytes)
            .finish()
    }
}

/// Checks that a node's maps have the shapes the arrays hold: a power-of-two side, `M × M`
/// colour and height, the pyramid halving down to one texel, obliques of the same side, and a
/// finite box and height range.
fn check_node(index: usize, n: &NodeMaps) -> Result<(), String> {
    let bad = |what: String| Err(format!("relief node {index}: {what}"));
    let m = n.m();
    if m == 0 || !m.is_power_of_two() {
        return bad(format!("map side {m} is not a power of two"));
    }
    let texels = (m as usize) * (m as usize);
    if n.zenithal.color.len() != texels || n.zenithal.depth.len() != texels {
        return bad(format!(
            "zenithal map holds {} colours and {} heights, M = {m} needs {texels}",
            n.zenithal.color.len(),
            n.zenithal.depth.len()
        ));
    }
    if n.upper.len() != m.ilog2() as usize {
        return bad(format!(
            "{} pyramid levels above the map, M = {m} needs {}",
            n.upper.len(),
            m.ilog2()
        ));
    }
    for (k, l) in n.upper.iter().enumerate() {
        let side = (m >> (k + 1)) as usize;
        if l.len() != side * side {
            return bad(format!(
                "pyramid level {} holds {} texels, not {side} × {side}",
                k + 1,
                l.len()
            ));
        }
    }
    for (k, o) in n.obliques.iter().enumerate() {
        if o.frame.m != m || o.color.len() != texels || o.depth.len() != texels {
            return bad(format!(
                "oblique map {k} is {} texels a side with {} colours and {} depths, not M = {m}",
                o.frame.m,
                o.color.len(),
                o.depth.len()
            ));
        }
    }
    let finite = n.aabb.min.is_finite()
        && n.aabb.max.is_finite()
        && n.z_range.iter().all(|z| z.is_finite())
        && n.z_range[1] > n.z_range[0];
    if !finite {
        return bad(format!(
            "box {:?}..{:?}, height range {:?}: need finite, with a positive height",
            n.aabb.min, n.aabb.max, n.z_range
        ));
    }
    Ok(())
}

/// Checks the device limits the pass depends on for `nodes` nodes of largest map side `m` and
/// at most `obliques` oblique maps a node; names the limit that is too small.
fn check_limits(
    limits: &wgpu::Limits,
    m: u32,
    obliques: usize,
    nodes: usize,
) -> Result<(), String> {
    if m > limits.max_texture_dimension_2d {
        return Err(format!(
            "relief maps of {m} × {m} texels exceed the device's max_texture_dimension_2d = {}",
            limits.max_texture_dimension_2d
        ));
    }
    if obliques as u64 > u64::from(limits.max_texture_array_layers) {
        return Err(format!(
            "a node's {obliques} oblique maps exceed the device's max_texture_array_layers = {}",
            limits.max_texture_array_layers
        ));
    }
    let bytes = (nodes.max(1) * std::mem::size_of::<Instance>()) as u64;
    if bytes > limits.max_storage_buffer_binding_size {
        return Err(format!(
            "the constants of {nodes} nodes ({bytes} bytes) exceed the device's \
             max_storage_buffer_binding_size = {}",
            limits.max_storage_buffer_binding_size
        ));
    }
    if limits.max_sampled_textures_per_shader_stage < PAGE_TEXTURES {
        return Err(format!(
            "the pass reads {PAGE_TEXTURES} texture arrays, more than the device's \
             max_sampled_textures_per_shader_stage = {}",
            limits.max_sampled_textures_per_shader_stage
        ));
    }
    if limits.max_bind_groups < 2 {
        return Err(format!(
            "the pass uses 2 bind groups, more than the device's max_bind_groups = {}",
            limits.max_bind_groups
        ));
    }
    Ok(())
}

/// A 2D texture array of `layers` layers (at least one) of `side × side` texels with `mips`
/// levels.
fn array_texture(
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    side: u32,
    layers: u32,
    mips: u32,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: layers.max(1),
        },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// Writes `bytes` (`side × side` texels of `texel` bytes) into `layer`, mip `mip` of `texture`.
fn write_layer(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    layer: u32,
    mip: u32,
    side: u32,
    texel: u32,
    bytes: &[u8],
) {
    gpu.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: mip,
            origin: wgpu::Origin3d {
                x: 0,
                y: 0,
                z: layer,
            },
            aspect: wgpu::TextureAspect::All,
        },
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(side * texel),
            rows_per_image: Some(side),
        },
        wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
    );
}

impl ReliefRenderer {
    /// Uploads every node of `field` (checked: map shapes, box, and the device's limits) for
    /// frames of `size` pixels.
    ///
    /// # Errors
    /// [`RenderError::FarField`] naming the node or the device limit; [`RenderError::EmptyImage`].
    pub fn new(gpu: &Gpu, field: &ReliefField, size: (u32, u32)) -> Result<Self, RenderError> {
        if size.0 == 0 || size.1 == 0 {
            return Err(RenderError::EmptyImage {
                width: size.0,
                height: size.1,
            });
        }
        let refuse = |what: String| RenderError::FarField {
            adapter: gpu.adapter_name(),
            what,
        };
        let nodes = &field.nodes;
        for (i, n) in nodes.iter().enumerate() {
            check_node(i, n).map_err(refuse)?;
        }
        let device = &gpu.device;
        let limits = device.limits();
        check_limits(
            &limits,
            nodes.iter().map(NodeMaps::m).max().unwrap_or(1),
            nodes.iter().map(|n| n.obliques.len()).max().unwrap_or(0),
            nodes.len(),
        )
        .map_err(refuse)?;
        let page_layers = PAGE_LAYERS.min(limits.max_texture_array_layers).max(1) as usize;
        let tex_entry = |binding: u32| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Uint,
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        };
        let page_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief page"),
            entries: &[tex_entry(0), tex_entry(1), tex_entry(2), tex_entry(3)],
        });
        // Pages: nodes grouped by map side in their order, as many per page as keep both the
        // zenithal and the oblique arrays within `page_layers`.
        let mut sides: Vec<u32> = nodes.iter().map(NodeMaps::m).collect();
        sides.sort_unstable();
        sides.dedup();
        let mut chunks: Vec<(u32, Vec<usize>)> = Vec::new();
        for &m in &sides {
            let mut chunk: Vec<usize> = Vec::new();
            let mut obl = 0usize;
            for i in (0..nodes.len()).filter(|&i| nodes[i].m() == m) {
                let k = nodes[i].obliques.len();
                if !chunk.is_empty() && (chunk.len() + 1 > page_layers || obl + k > page_layers) {
                    chunks.push((m, std::mem::take(&mut chunk)));
                    obl = 0;
                }
                chunk.push(i);
                obl += k;
            }
            if !chunk.is_empty() {
                chunks.push((m, chunk));
            }
        }
        let mut slots: Vec<Option<Slot>> = vec![None; nodes.len()];
        let mut pages = Vec::with_capacity(chunks.len());
        let mut bytes = 0u64;
        for (m, chunk) in &chunks {
            let m = *m;
            let levels = m.ilog2() + 1;
            let total_obl: usize = chunk.iter().map(|&i| nodes[i].obliques.len()).sum();
            let zc = array_texture(
                device,
                "relief zenithal colour",
                COLOR_MAP_FORMAT,
                m,
                chunk.len() as u32,
                1,
            );
            let zh = array_texture(
                device,
                "relief pyramid",
                DEPTH_MAP_FORMAT,
                m,
                chunk.len() as u32,
                levels,
            );
            let oc = array_texture(
                device,
                "relief oblique colour",
                COLOR_MAP_FORMAT,
                m,
                total_obl as u32,
                1,
            );
            let od = array_texture(
                device,
                "relief oblique depth",
                DEPTH_MAP_FORMAT,
                m,
                total_obl as u32,
                1,
            );
            let mut next_obl = 0u32;
            for (layer, &i) in chunk.iter().enumerate() {
                let n = &nodes[i];
                let layer = layer as u32;
                write_layer(
                    gpu,
                    &zc,
                    layer,
                    0,
                    m,
                    4,
                    bytemuck::cast_slice(&n.zenithal.color),
                );
                for (level, heights) in n.levels().into_iter().enumerate() {
                    let side = m >> level;
                    write_layer(
                        gpu,
                        &zh,
                        layer,
                        level as u32,
                        side,
                        2,
                        bytemuck::cast_slice(heights),
                    );
                }
                for (k, o) in n.obliques.iter().enumerate() {
                    let l = next_obl + k as u32;
                    write_layer(gpu, &oc, l, 0, m, 4, bytemuck::cast_slice(&o.color));
                    write_layer(gpu, &od, l, 0, m, 2, bytemuck::cast_slice(&o.depth));
                }
                bytes += n.bytes();
                let b = n.aabb;
                // Enlarge by a millionth of the box's size plus 1 cm.
                let pad = 1e-6 * b.extent().max_element() + 0.01;
                slots[i] = Some(Slot {
                    page: pages.len(),
                    layer,
                    oblique_layer: next_obl,
                    m,
                    levels,
                    box_min: (b.min - pad).as_vec3().to_array(),
                    box_max: (b.max + pad).as_vec3().to_array(),
                });
                next_obl += n.obliques.len() as u32;
            }
            let view = |t: &wgpu::Texture| {
                t.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2Array),
                    ..Default::default()
                })
            };
            let views = [view(&zc), view(&zh), view(&oc), view(&od)];
            let entries: Vec<wgpu::BindGroupEntry> = views
                .iter()
                .enumerate()
                .map(|(k, v)| wgpu::BindGroupEntry {
                    binding: k as u32,
                    resource: wgpu::BindingResource::TextureView(v),
                })
                .collect();
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("relief page"),
                layout: &page_layout,
                entries: &entries,
            });
            pages.push(Page { bind_group });
        }
        let slots: Vec<Slot> = slots.into_iter().flatten().collect();
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relief frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let capacity = nodes.len().max(1);
        let instances = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relief instances"),
            size: (capacity * std::mem::size_of::<Instance>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let buffer_entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let globals_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief globals"),
            entries: &[
                buffer_entry(0, wgpu::BufferBindingType::Uniform),
                buffer_entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let globals = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("relief globals"),
            layout: &globals_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: instances.as_entire_binding(),
                },
            ],
        });
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("relief.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("relief.wgsl").into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relief"),
            bind_group_layouts: &[Some(&globals_layout), Some(&page_layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("relief"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Back faces: every pixel whose ray meets the box gets one fragment, also with
                // the eye inside the box.
                cull_mode: Some(wgpu::Face::Front),
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[
                    Some(wgpu::ColorTargetState {
                        format: COLOR_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    }),
                    Some(wgpu::ColorTargetState {
                        format: ID_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    }),
                ],
            }),
            multiview_mask: None,
            cache: None,
        });
        let targets = FarTargets::new(device, size, "relief");
        let queries = PassTimer::new(gpu, "relief pass");
        Ok(Self {
            size,
            pipeline,
            frame,
            instances,
            capacity,
            globals,
            pages,
            slots,
            infos: nodes.iter().map(NodeMaps::frame_info).collect(),
            xforms: nodes.iter().map(NodeMaps::oblique_xforms).collect(),
            sets: std::sync::Mutex::new(crate::relief::image::MapSets::new(
                field.options.blend_frames,
            )),
            bytes,
            obliques: nodes.iter().map(|n| n.obliques.len()).sum(),
            targets,
            queries,
        })
    }

    /// Nodes uploaded.
    pub fn nodes(&self) -> usize {
        self.slots.len()
    }

    /// Oblique maps uploaded, over all nodes.
    pub fn obliques(&self) -> usize {
        self.obliques
    }

    /// Texture pages (one per map side and per 256 nodes or oblique maps).
    pub fn pages(&self) -> usize {
        self.pages.len()
    }

    /// Bytes of the maps uploaded ([`NodeMaps::bytes`] summed).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Draws the nodes `far` (indices into the field's nodes given to [`Self::new`]) from
    /// `camera` into `color` and `depth` (loaded, not cleared: the mesh pass's targets, of this
    /// renderer's size), and reads back the node ids and what `read` asks for. The result's
    /// `maps` counts the nodes drawn and `map_ids` holds node indices.
    ///
    /// # Errors
    /// [`RenderError::NoSuchMap`] for an index out of range or a list longer than the nodes;
    /// read-back failures.
    pub fn draw(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        far: &[usize],
        color: &wgpu::Texture,
        depth: &wgpu::Texture,
        read: FarReadback,
    ) -> Result<FarPass, RenderError> {
        let start = Instant::now();
        if let Some(&index) = far.iter().find(|&&m| m >= self.slots.len()) {
            return Err(RenderError::NoSuchMap {
                index,
                maps: self.slots.len(),
            });
        }
        if far.len() > self.capacity {
            return Err(RenderError::NoSuchMap {
                index: far.len(),
                maps: self.slots.len(),
            });
        }
        let (w, h) = self.size;
        let fr = FrameRays::new(camera, w, h);
        let m = crate::city::LocalFrame::round_matrix_to_f32(camera.clip_from_world());
        let uniform = FrameUniform {
            clip_from_world: m.to_cols_array_2d(),
            pix: [fr.sx, fr.cx, fr.sy, fr.cy],
            depth: [fr.near, fr.r, fr.rn, (1.0 / 65535.0) as f32],
        };
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniform));
        // The CPU renderer's decisions, instances grouped by page, in `far` order within a page.
        let mut decided = frame_nodes(&self.infos, far, camera, h);
        self.sets
            .lock()
            .map_err(|_| RenderError::FarField {
                adapter: gpu.adapter_name(),
                what: "the relief map sets' lock is poisoned".into(),
            })?
            .apply(&mut decided, camera);
        let mut inst = Vec::with_capacity(far.len());
        let mut ranges = Vec::new();
        for p in 0..self.pages.len() {
            let first = inst.len() as u32;
            for fnode in decided.iter().filter(|f| self.slots[f.node].page == p) {
                let s = &self.slots[fnode.node];
                let xf = &self.xforms[fnode.node];
                let x = &fnode.xform;
                let v4 = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
                let set = |maps: &[Option<u32>; CHOSEN]| {
                    let mut layers = [NONE; 4];
                    let mut rows = [[0.0f32; 4]; 9];
                    let mut tol = [0.0f32; 4];
                    for (k, c) in maps.iter().enumerate().take(CHOSEN) {
                        if let Some(o) = c.and_then(|o| xf.get(o as usize).map(|x| (o, x))) {
                            layers[k] = s.oblique_layer + o.0;
                            rows[3 * k..3 * k + 3].copy_from_slice(&o.1.rows);
                            tol[k] = o.1.tol_q;
                        }
                    }
                    (layers, rows, tol)
                };
                let (chosen, rows, tol) = set(&fnode.chosen);
                let (mut prev, prev_rows, prev_tol) =
                    set(&fnode.previous.unwrap_or([None; CHOSEN]));
                prev[3] = if fnode.previous.is_some() {
                    fnode.weight
                } else {
                    256
                };
                inst.push(Instance {
                    ax: v4(x.ax),
                    ay: v4(x.ay),
                    af: v4(x.af),
                    b: v4(x.b),
                    box_min: v4(s.box_min),
                    box_max: v4(s.box_max),
                    info: [s.layer, s.m, s.levels, u32::from(fnode.flat)],
                    extra: [step_limit(s.m), fnode.node as u32, 0, 0],
                    chosen,
                    rows,
                    tol,
                    prev,
                    prev_rows,
                    prev_tol,
                });
            }
            if inst.len() as u32 > first {
                ranges.push((p, first..inst.len() as u32));
            }
        }
        if !inst.is_empty() {
            gpu.queue
                .write_buffer(&self.instances, 0, bytemuck::cast_slice(&inst));
        }
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("relief far field"),
            });
        self.targets.pass(
            &mut encoder,
            color,
            depth,
            self.queries.as_ref(),
            "relief far field",
            |pass| {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.globals, &[]);
                for (p, r) in &ranges {
                    pass.set_bind_group(1, &self.pages[*p].bind_group, &[]);
                    pass.draw(0..36, r.clone());
                }
            },
        );
        if let Some(t) = &self.queries {
            t.resolve(&mut encoder);
        }
        let images = self.targets.read(gpu, encoder, color, depth, read)?;
        let gpu_s = self.queries.as_ref().map(|t| t.seconds(gpu)).transpose()?;
        Ok(FarPass {
            gpu_s,
            wall_s: start.elapsed().as_secs_f64(),
            maps: inst.len() as u32,
            draws: ranges.len() as u32,
            map_ids: images.map_ids,
            far_pixels: images.far_pixels,
            rgba: images.rgba,
            depth: images.depth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader parses and validates without a device (naga, as wgpu does at pipeline
    /// creation), so a CI without an adapter still checks it.
    #[test]
    fn shader_is_valid_wgsl() {
        let src = include_str!("relief.wgsl");
        let module = super::super::validated_wgsl(src);
        for name in ["vs_main", "fs_main"] {
            assert!(module.entry_points.iter().any(|e| e.name == name), "{name}");
        }
    }

    #[test]
    fn layouts_match_the_shader() {
        // Frame: mat4 + 2 vec4; Inst: 6 vec4 + 3 vec4<u32> + 9 vec4 + vec4.
        assert_eq!(std::mem::size_of::<FrameUniform>(), 96);
        assert_eq!(std::mem::size_of::<Instance>(), 480);
    }

    #[test]
    fn limits_too_small_are_named() {
        let l = wgpu::Limits::default();
        assert!(check_limits(&l, 128, 16, 1000).is_ok());
        let small = wgpu::Limits {
            max_texture_dimension_2d: 64,
            ..wgpu::Limits::default()
        };
        let e = check_limits(&small, 128, 16, 10).unwrap_err();
        assert!(e.contains("max_texture_dimension_2d = 64"), "{e}");
        let few = wgpu::Limits {
            max_texture_array_layers: 8,
            ..wgpu::Limits::default()
        };
        let e = check_limits(&few, 128, 16, 10).unwrap_err();
        assert!(e.contains("max_texture_array_layers = 8"), "{e}");
        let e = check_limits(&l, 128, 16, 1 << 30).unwrap_err();
        assert!(e.contains("max_storage_buffer_binding_size"), "{e}");
    }
}
