//! The far-field pass: BlockMaps ray-cast on the GPU (Cignoni et al., §3.2, Di Benedetto, §4.2.2), drawn
//! into the colour and depth targets the mesh pass left (see the module docs of [`super`]).
//!
//! - **Storage**: maps are uploaded once as `Rgba8Uint` 2D texture arrays, one array ("page")
//!   per K and per up to 256 maps (WebGPU's default `max_texture_array_layers`, BLOCKMAPS.md
//!   C.3); the shader reads them with integer `textureLoad`s (`textureSample` is not allowed in
//!   the non-uniform loop). Each layer is the whole `(4K + 256) × K` image, so a texel's
//!   footprint edge ([`crate::blockmap::layout`]) is one more load at `2K + 256 + i`, only in
//!   non-empty cells, and its second edge one more at `3K + 256 + i`, only where a first exists.
//! - **Draw**: one instanced draw of 36 vertices per page that has selected maps, one instance per
//!   map, in the order `far` lists them within a page (so two maps of different pages at exactly
//!   the same depth may resolve otherwise than [`crate::blockmap::cast_image`]'s "first listed
//!   wins"; only exact depth ties between maps of different K or of more than 256 maps). Each instance rasterises its box's **back
//!   faces**, clipped at the near plane only, so that the eye inside a box works and a box past
//!   the far plane still draws; the fragment walks the height field from the near plane
//!   ([`crate::blockmap::image`] gives the rays and the depth, `blockmap.wgsl` the walk, the same
//!   as [`crate::blockmap::cast::cast_f32`]), shades the hit, writes `frag_depth` (so meshes and
//!   maps composite with the `Less` test) and the map's index to a second, `R32Uint` target
//!   (counted for [`FarPass::far_pixels`]); misses `discard`.
//! - Writing depth disables early depth tests; the proxy's own depth is not used.

pub use super::far_pass::FarReadback;
use super::far_pass::{FarTargets, ID_FORMAT};
use super::PassTimer;
use super::{Gpu, RenderError};
use crate::blockmap::layout::ALLOWED_K;
use crate::blockmap::{BlockMap, BlockMapMeta, FrameRays, MapXform};
use crate::city::appearance;
use crate::geom::Camera;
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Colour target format (as the mesh pass's).
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Depth target format (as the mesh pass's).
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Texel format of the maps: the bytes, read as integers.
const MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Uint;
/// Layers of one page at most.
const PAGE_LAYERS: u32 = 256;
/// Value of the map-index target where no map was drawn.
pub const NO_MAP: u32 = u32::MAX;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    clip_from_world: [[f32; 4]; 4],
    /// sx, cx, sy, cy.
    pix: [f32; 4],
    /// near, r, rn.
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
    /// layer, K, slices, map index.
    info: [u32; 4],
}

/// One texture array of maps of the same K.
struct Page {
    bind_group: wgpu::BindGroup,
}

/// Where a map lives and what its box is.
#[derive(Clone, Debug)]
struct Slot {
    page: usize,
    layer: u32,
    meta: BlockMapMeta,
    /// The proxy box (local frame, f32), enlarged a little so that rasterisation never drops a
    /// pixel the walk's exact box test keeps.
    box_min: [f32; 3],
    box_max: [f32; 3],
}

/// The result of one far pass.
#[derive(Clone, Debug)]
pub struct FarPass {
    /// GPU time of the pass from timestamp queries, seconds (when the device has them).
    pub gpu_s: Option<f64>,
    /// Wall time from encoding to the read-back, seconds.
    pub wall_s: f64,
    /// Maps drawn (instances).
    pub maps: u32,
    /// Draw calls.
    pub draws: u32,
    /// Per pixel (row-major from the top-left), the index of the map that won the depth test,
    /// [`NO_MAP`] elsewhere.
    pub map_ids: Vec<u32>,
    /// Pixels a map won.
    pub far_pixels: u64,
    /// RGBA bytes of the colour target after the pass, when asked for.
    pub rgba: Option<Vec<u8>>,
    /// The depth buffer after the pass, when asked for.
    pub depth: Option<Vec<f32>>,
}

/// The uploaded maps and the far-field pipeline.
pub struct BlockMapRenderer {
    size: (u32, u32),
    pipeline: wgpu::RenderPipeline,
    frame: wgpu::Buffer,
    instances: wgpu::Buffer,
    capacity: usize,
    globals: wgpu::BindGroup,
    pages: Vec<Page>,
    slots: Vec<Slot>,
    targets: FarTargets,
    queries: Option<PassTimer>,
}

impl std::fmt::Debug for BlockMapRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlockMapRenderer")
            .field("size", &self.size)
            .field("maps", &self.slots.len())
            .field("pages", &self.pages.len())
            .finish()
    }
}

/// The WGSL constants the shader shares with [`appearance::shade`], printed from the Rust values.
fn wgsl_constants() -> String {
    let s = appearance::sun_direction();
    format!(
        "const AMBIENT: f32 = {:?};\nconst SUN: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});\n",
        appearance::AMBIENT,
        s.x,
        s.y,
        s.z
    )
}

/// Checks that a map's image matches its K and slices.
fn check_map(index: usize, m: &BlockMap) -> Result<(), RenderError> {
    let bad = |what: String| RenderError::BadBlockMap { index, what };
    let k = m.meta.k;
    if !ALLOWED_K.contains(&k) {
        return Err(bad(format!("K = {k} is not 32, 64 or 128")));
    }
    if m.texels.len() != (m.width() * k) as usize {
        return Err(bad(format!(
            "{} texels, K = {k} needs {}",
            m.texels.len(),
            m.width() * k
        )));
    }
    let s = m.meta.slices;
    if s == 0 || !s.is_power_of_two() || k / s < 2 {
        return Err(bad(format!("slice count {s} is invalid for K = {k}")));
    }
    let finite = m.meta.min.iter().all(|v| v.is_finite())
        && m.meta.side.is_finite()
        && m.meta.side > 0.0
        && m.meta.zmax.is_finite()
        && m.meta.zmax > m.meta.zmin;
    if !finite {
        return Err(bad(format!(
            "box min {:?}, side {}, z {}..{}: need finite, side > 0, zmax > zmin",
            m.meta.min, m.meta.side, m.meta.zmin, m.meta.zmax
        )));
    }
    Ok(())
}

impl BlockMapRenderer {
    /// Uploads `maps` (checked: K, image size, slices, box) for frames of `size` pixels.
    ///
    /// # Errors
    /// [`RenderError::BadBlockMap`] naming the map; [`RenderError::EmptyImage`].
    pub fn new(gpu: &Gpu, maps: &[&BlockMap], size: (u32, u32)) -> Result<Self, RenderError> {
        if size.0 == 0 || size.1 == 0 {
            return Err(RenderError::EmptyImage {
                width: size.0,
                height: size.1,
            });
        }
        for (i, m) in maps.iter().enumerate() {
            check_map(i, m)?;
        }
        let device = &gpu.device;
        let page_layers = PAGE_LAYERS
            .min(device.limits().max_texture_array_layers)
            .max(1);
        let page_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blockmap page"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
                count: None,
            }],
        });
        // Pages: maps grouped by K in their order, `page_layers` per page.
        let mut slots: Vec<Option<Slot>> = vec![None; maps.len()];
        let mut pages = Vec::new();
        for &k in &ALLOWED_K {
            let of_k: Vec<usize> = (0..maps.len()).filter(|&i| maps[i].meta.k == k).collect();
            for chunk in of_k.chunks(page_layers as usize) {
                let width = crate::blockmap::layout::image_width(k);
                let tex = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("blockmap page"),
                    size: wgpu::Extent3d {
                        width,
                        height: k,
                        depth_or_array_layers: chunk.len() as u32,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: MAP_FORMAT,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                    view_formats: &[],
                });
                for (layer, &i) in chunk.iter().enumerate() {
                    let m = maps[i];
                    gpu.queue.write_texture(
                        wgpu::TexelCopyTextureInfo {
                            texture: &tex,
                            mip_level: 0,
                            origin: wgpu::Origin3d {
                                x: 0,
                                y: 0,
                                z: layer as u32,
                            },
                            aspect: wgpu::TextureAspect::All,
                        },
                        bytemuck::cast_slice(&m.texels),
                        wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(width * 4),
                            rows_per_image: Some(k),
                        },
                        wgpu::Extent3d {
                            width,
                            height: k,
                            depth_or_array_layers: 1,
                        },
                    );
                    let b = m.aabb();
                    // Enlarge by a millionth of the box's size plus 1 cm.
                    let pad = 1e-6 * b.extent().max_element() + 0.01;
                    slots[i] = Some(Slot {
                        page: pages.len(),
                        layer: layer as u32,
                        meta: m.meta.clone(),
                        box_min: (b.min - pad).as_vec3().to_array(),
                        box_max: (b.max + pad).as_vec3().to_array(),
                    });
                }
                let view = tex.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2Array),
                    ..Default::default()
                });
                let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("blockmap page"),
                    layout: &page_layout,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    }],
                });
                pages.push(Page { bind_group });
            }
        }
        let slots: Vec<Slot> = slots.into_iter().flatten().collect();
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blockmap frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let capacity = maps.len().max(1);
        let instances = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blockmap instances"),
            size: (capacity * std::mem::size_of::<Instance>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let globals_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blockmap globals"),
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
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let globals = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blockmap globals"),
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
            label: Some("blockmap.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                (wgsl_constants() + include_str!("blockmap.wgsl")).into(),
            ),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("blockmap"),
            bind_group_layouts: &[Some(&globals_layout), Some(&page_layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blockmap"),
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
        let targets = FarTargets::new(device, size, "blockmap");
        let queries = PassTimer::new(gpu, "far pass");
        Ok(Self {
            size,
            pipeline,
            frame,
            instances,
            capacity,
            globals,
            pages,
            slots,
            targets,
            queries,
        })
    }

    /// Maps uploaded.
    pub fn maps(&self) -> usize {
        self.slots.len()
    }

    /// Texture pages (one per K and per 256 maps).
    pub fn pages(&self) -> usize {
        self.pages.len()
    }

    /// Draws the maps `far` (indices into the maps given to [`Self::new`]) from `camera` into
    /// `color` and `depth` (loaded, not cleared: the mesh pass's targets, of this renderer's
    /// size), and reads back the map ids and what `read` asks for.
    ///
    /// # Errors
    /// [`RenderError::NoSuchMap`] for an index out of range or a list longer than the maps;
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
            depth: [fr.near, fr.r, fr.rn, 0.0],
        };
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniform));
        // Instances grouped by page, in `far` order within a page.
        let mut inst = Vec::with_capacity(far.len());
        let mut ranges = Vec::new();
        for p in 0..self.pages.len() {
            let first = inst.len() as u32;
            for &i in far.iter().filter(|&&i| self.slots[i].page == p) {
                let s = &self.slots[i];
                let x = MapXform::from_meta(&s.meta, camera);
                let v4 = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
                inst.push(Instance {
                    ax: v4(x.ax),
                    ay: v4(x.ay),
                    af: v4(x.af),
                    b: v4(x.b),
                    box_min: v4(s.box_min),
                    box_max: v4(s.box_max),
                    info: [s.layer, s.meta.k, s.meta.slices, i as u32],
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
                label: Some("far field"),
            });
        self.targets.pass(
            &mut encoder,
            color,
            depth,
            self.queries.as_ref(),
            "far field",
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
        let src = wgsl_constants() + include_str!("blockmap.wgsl");
        let module = super::super::validated_wgsl(&src);
        for name in ["vs_main", "fs_main"] {
            assert!(module.entry_points.iter().any(|e| e.name == name), "{name}");
        }
    }

    #[test]
    fn layouts_match_the_shader() {
        // Frame: mat4 + 2 vec4; Inst: 6 vec4 + vec4<u32>.
        assert_eq!(std::mem::size_of::<FrameUniform>(), 96);
        assert_eq!(std::mem::size_of::<Instance>(), 112);
    }

    #[test]
    fn bad_maps_are_named() {
        let mut m = BlockMap::empty(64, glam::DVec3::ZERO, 100.0, 30.0).unwrap();
        assert!(check_map(0, &m).is_ok());
        m.meta.slices = 3;
        let e = check_map(4, &m).unwrap_err();
        assert!(
            matches!(e, RenderError::BadBlockMap { index: 4, .. }),
            "{e}"
        );
        m.meta.slices = 1;
        m.texels.pop();
        let e = check_map(2, &m).unwrap_err().to_string();
        assert!(e.contains("far-field map 2") && e.contains("texels"), "{e}");
    }
}
