//! What both far-field passes ([`super::blockmap`], [`super::relief`]) share: the node-id target
//! they write beside the mesh pass's colour and depth, the render pass over the three, and the
//! read-back of the ids (and, when asked, the colour and depth) after it.

use super::mesh::map_read;
use super::{padded_row_bytes, PassTimer, Readback, RenderError, NO_MAP};

/// Format of the node-id target.
pub(super) const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// What to read back after a far pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FarReadback {
    /// The colour image.
    pub color: bool,
    /// The depth buffer.
    pub depth: bool,
}

/// The id target and the read-back buffer of a far pass of one image size.
pub(super) struct FarTargets {
    ids: wgpu::Texture,
    readback: wgpu::Buffer,
    padded_row: u32,
    size: (u32, u32),
}

/// What a far pass read back.
pub(super) struct FarImages {
    /// Per pixel (row-major from the top-left), the node or map index that won the depth test,
    /// [`NO_MAP`] elsewhere.
    pub(super) map_ids: Vec<u32>,
    /// Pixels a node or map won.
    pub(super) far_pixels: u64,
    /// RGBA bytes of the colour target, when asked for.
    pub(super) rgba: Option<Vec<u8>>,
    /// The depth buffer, when asked for.
    pub(super) depth: Option<Vec<f32>>,
}

impl FarTargets {
    /// The targets of a `size` image (`label` names them for wgpu's messages).
    pub(super) fn new(device: &wgpu::Device, size: (u32, u32), label: &str) -> Self {
        let ids = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(&format!("{label} ids")),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: ID_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let padded_row = padded_row_bytes(size.0);
        // Three images of 4 bytes per pixel: ids, colour, depth.
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{label} read-back")),
            size: 3 * padded_row as u64 * size.1 as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self {
            ids,
            readback,
            padded_row,
            size,
        }
    }

    /// Encodes one pass into `encoder` over `color` and `depth` (loaded, not cleared: the mesh
    /// pass's targets) and the id target (cleared to [`NO_MAP`]), timed by `timer` when given;
    /// `draw` records the draws.
    pub(super) fn pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        color: &wgpu::Texture,
        depth: &wgpu::Texture,
        timer: Option<&PassTimer>,
        label: &str,
        draw: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) {
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let id_view = self.ids.create_view(&Default::default());
        fn load<V>() -> wgpu::Operations<V> {
            wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            }
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[
                Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: load(),
                }),
                Some(wgpu::RenderPassColorAttachment {
                    view: &id_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: NO_MAP as f64,
                            g: 0.0,
                            b: 0.0,
                            a: 0.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                }),
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(load()),
                stencil_ops: None,
            }),
            timestamp_writes: timer.map(PassTimer::writes),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        draw(&mut pass);
    }

    /// Copies the ids, and `color` and `depth` as `read` asks, into the read-back buffer,
    /// submits `encoder` and reads them back.
    ///
    /// # Errors
    /// Read-back failures.
    pub(super) fn read(
        &self,
        gpu: &super::Gpu,
        mut encoder: wgpu::CommandEncoder,
        color: &wgpu::Texture,
        depth: &wgpu::Texture,
        read: FarReadback,
    ) -> Result<FarImages, RenderError> {
        let (w, h) = self.size;
        let plane = self.padded_row as u64 * h as u64;
        let copy = |encoder: &mut wgpu::CommandEncoder,
                    texture: &wgpu::Texture,
                    aspect: wgpu::TextureAspect,
                    slot: u64| {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: slot * plane,
                        bytes_per_row: Some(self.padded_row),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        };
        copy(&mut encoder, &self.ids, wgpu::TextureAspect::All, 0);
        if read.color {
            copy(&mut encoder, color, wgpu::TextureAspect::All, 1);
        }
        if read.depth {
            copy(&mut encoder, depth, wgpu::TextureAspect::DepthOnly, 2);
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = map_read(gpu, &self.readback, Readback::FarField)?;
        let expected = 3 * plane as usize;
        if bytes.len() < expected {
            return Err(RenderError::ShortReadback {
                what: Readback::FarField,
                got: bytes.len(),
                expected,
            });
        }
        let unpad = |slot: usize| -> Vec<u8> {
            let row = (w * 4) as usize;
            let mut out = Vec::with_capacity(row * h as usize);
            for y in 0..h as usize {
                let s = slot * plane as usize + y * self.padded_row as usize;
                out.extend_from_slice(&bytes[s..s + row]);
            }
            out
        };
        let words = |b: Vec<u8>| -> Vec<[u8; 4]> {
            b.chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect()
        };
        let map_ids: Vec<u32> = words(unpad(0))
            .into_iter()
            .map(u32::from_le_bytes)
            .collect();
        let far_pixels = map_ids.iter().filter(|&&m| m != NO_MAP).count() as u64;
        Ok(FarImages {
            map_ids,
            far_pixels,
            rgba: read.color.then(|| unpad(1)),
            depth: read.depth.then(|| {
                words(unpad(2))
                    .into_iter()
                    .map(f32::from_le_bytes)
                    .collect()
            }),
        })
    }
}
