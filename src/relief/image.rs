//! Images of relief impostors as the GPU draws them, on the CPU: the reference the WGSL caster
//! (`render/relief.wgsl`) is tested against, and the CPU fallback of hybrid frames.
//!
//! Rays are made exactly as for BlockMaps ([`crate::blockmap::image`]): the pixel's view
//! direction from [`FrameRays`], taken into the node's texture space by per-node, per-frame
//! constants ([`MapXform::from_texture_space`], computed in `f64` and rounded), starting on the near
//! plane; the depth written is [`FrameRays::depth`]. What a frame draws of each node
//! ([`frame_nodes`]): whether it is a horizon node (its height projects under
//! [`super::ReliefOptions::flat_px`] pixels: the flat quad) and which three obliques colour its
//! walls, decided once
//! per frame on the CPU in `f64` and handed to both renderers. Several nodes: the nearest depth
//! wins, the first listed on equal depth.

use super::build::ReliefField;
use super::cast::{cast_f32, cast_flat, Hit};
use super::node::{shade_blended, NodeFrameInfo, ObliqueXform, CHOSEN};
use crate::blockmap::{FrameRays, MapXform};
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::{CpuFrameRenderer, DrawError, DrawnFrame, FrameRenderer, TerrainDraw};
use glam::{DVec3, DVec4};
use rayon::prelude::*;

/// The paper's threshold for horizon nodes: a node whose height projects to fewer than two
/// pixels is drawn as a flat quad (§5.2). Not the default (see [`super::ReliefOptions::flat_px`]).
pub const PAPER_FLAT_PX: f64 = 2.0;

/// What a frame draws of one node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameNode {
    /// The node (index into [`ReliefField::nodes`]).
    pub node: usize,
    /// Drawn as the flat quad.
    pub flat: bool,
    /// The obliques colouring its walls.
    pub chosen: [Option<u32>; CHOSEN],
    /// While a switch of obliques is blended, the previous three ([`MapSets`]).
    pub previous: Option<[Option<u32>; CHOSEN]>,
    /// The share of `chosen` in the blend, of 256 (256: `chosen` alone).
    pub weight: u32,
    /// Its ray constants.
    pub xform: MapXform,
}

/// The obliques each node drew with, frame after frame, and the blends of their switches
/// (Andujar et al., §5.2: both sets during a few frames, with varying weights). When a node's
/// choice changes, its colours move from the old three to the new three over `frames` frames
/// in equal steps (the new set's weight `(k + 1)·256 / (frames + 1)` on the `k`-th frame after the
/// switch); a choice that changes during a blend is taken when the blend ends, so the drawn
/// colours never jump (they may lag the choice by `frames` frames). The state advances once per
/// camera: drawing the same camera again (the walk's reference and popping frames) sees the same
/// blends. Both renderers keep one, so they draw the same colours.
#[derive(Clone, Debug, Default)]
pub struct MapSets {
    frames: u32,
    last: Option<[f64; 5]>,
    nodes: std::collections::HashMap<usize, SetState>,
}

#[derive(Clone, Copy, Debug)]
struct SetState {
    current: [Option<u32>; CHOSEN],
    previous: [Option<u32>; CHOSEN],
    /// Frames since the switch.
    age: u32,
}

impl MapSets {
    /// Blends over `frames` frames (0: switches at once).
    pub fn new(frames: u32) -> Self {
        Self {
            frames,
            ..Self::default()
        }
    }

    /// Sets each frame node's previous set and weight for `camera`, advancing the state when
    /// `camera` is not the one last seen.
    pub fn apply(&mut self, nodes: &mut [FrameNode], camera: &Camera) {
        let key = [
            camera.position.x,
            camera.position.y,
            camera.position.z,
            camera.yaw,
            camera.pitch,
        ];
        let advance = self.last != Some(key);
        self.last = Some(key);
        let frames = self.frames;
        for f in nodes.iter() {
            let st = self.nodes.entry(f.node).or_insert(SetState {
                current: f.chosen,
                previous: f.chosen,
                age: frames,
            });
            if advance {
                if st.age < frames {
                    // A choice that changes during a blend waits for it to end: the drawn colours
                    // move in equal steps, never jump.
                    st.age += 1;
                } else if st.current != f.chosen {
                    st.previous = st.current;
                    st.current = f.chosen;
                    st.age = 0;
                }
            }
        }
        self.peek(nodes);
    }

    /// Sets each frame node's obliques, previous set and weight from the state as it is,
    /// without advancing it: what the last frame drew its nodes with (a node the state does not
    /// know keeps its own choice, unblended). Drawn beside [`MapSets::apply`]'s frame for the same
    /// camera, the two differ only by what this frame's switches and blend steps changed.
    pub fn peek(&self, nodes: &mut [FrameNode]) {
        for f in nodes.iter_mut() {
            f.previous = None;
            f.weight = 256;
            let Some(st) = self.nodes.get(&f.node) else {
                continue;
            };
            f.chosen = st.current;
            if st.age < self.frames && st.previous != st.current {
                f.previous = Some(st.previous);
                f.weight = (st.age + 1) * 256 / (self.frames + 1);
            }
        }
    }
}

/// What a frame draws of each node of `far` (indices into `nodes`) from `camera` on an image
/// `height_px` high: the one decision both renderers use.
pub fn frame_nodes(
    nodes: &[NodeFrameInfo],
    far: &[usize],
    camera: &Camera,
    height_px: u32,
) -> Vec<FrameNode> {
    far.iter()
        .map(|&i| {
            let n = &nodes[i];
            FrameNode {
                node: i,
                flat: n.is_flat(camera, height_px),
                chosen: n.choose(camera.position),
                previous: None,
                weight: 256,
                xform: MapXform::from_texture_space(n.tex_origin, n.tex_scale, camera),
            }
        })
        .collect()
}

/// The ray-cast image of some nodes. Pixels without a hit: `hit = None`, depth 1, colour 0,
/// node `u32::MAX`.
#[derive(Clone, Debug, PartialEq)]
pub struct ReliefImage {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The hit per pixel (row-major from the top-left).
    pub hit: Vec<Option<Hit>>,
    /// The depth the GPU writes.
    pub depth: Vec<f32>,
    /// RGBA8 (alpha 255 on a hit).
    pub color: Vec<[u8; 4]>,
    /// The node hit, `u32::MAX` where none.
    pub node: Vec<u32>,
}

impl ReliefImage {
    /// Pixels with a hit.
    pub fn hits(&self) -> usize {
        self.hit.iter().filter(|h| h.is_some()).count()
    }
}

/// Per-node data the casts read, prepared once per field.
pub struct Prepared<'a> {
    levels: Vec<Vec<&'a [u16]>>,
    xforms: Vec<Vec<ObliqueXform>>,
    infos: Vec<NodeFrameInfo>,
}

impl<'a> Prepared<'a> {
    /// Pyramid slices and oblique constants of every node of `field`.
    pub fn new(field: &'a ReliefField) -> Self {
        Self {
            levels: field.nodes.iter().map(|n| n.levels()).collect(),
            xforms: field.nodes.iter().map(|n| n.oblique_xforms()).collect(),
            infos: field.nodes.iter().map(|n| n.frame_info()).collect(),
        }
    }

    /// What the per-frame decisions need of every node.
    pub fn infos(&self) -> &[NodeFrameInfo] {
        &self.infos
    }

    /// The oblique constants of node `i`.
    pub fn xforms(&self, i: usize) -> &[ObliqueXform] {
        &self.xforms[i]
    }

    /// The pyramid of node `i`, level 0 first.
    pub fn levels(&self, i: usize) -> &[&'a [u16]] {
        &self.levels[i]
    }
}

/// The pixel rectangle `[x0, x1) × [y0, y1)` a box may cover (the whole image when it reaches
/// behind the near plane); `None` when it is off the image.
fn screen_rect(min: DVec3, max: DVec3, camera: &Camera, w: u32, h: u32) -> Option<[i64; 4]> {
    let cfw = camera.clip_from_world();
    let (wf, hf) = (f64::from(w), f64::from(h));
    let (mut a, mut b) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in crate::geom::Aabb3::new(min, max).corners() {
        let q = cfw * DVec4::new(c.x, c.y, c.z, 1.0);
        if q.w < camera.near {
            return Some([0, 0, i64::from(w), i64::from(h)]);
        }
        let px = (q.x / q.w + 1.0) * 0.5 * wf;
        let py = (1.0 - q.y / q.w) * 0.5 * hf;
        a = [a[0].min(px), a[1].min(py)];
        b = [b[0].max(px), b[1].max(py)];
    }
    let r = [
        (a[0] - 1.0).floor().max(0.0) as i64,
        (a[1] - 1.0).floor().max(0.0) as i64,
        (b[0] + 2.0).ceil().min(wf) as i64,
        (b[1] + 2.0).ceil().min(hf) as i64,
    ];
    (r[0] < r[2] && r[1] < r[3]).then_some(r)
}

/// Casts, per pixel of a `width × height` image from `camera`, the `f32` caster through the
/// frame's nodes `nodes` and keeps the nearest hit, coloured as the shader colours it. Parallel
/// over rows, deterministic.
pub fn cast_image(
    field: &ReliefField,
    prepared: &Prepared<'_>,
    nodes: &[FrameNode],
    camera: &Camera,
    width: u32,
    height: u32,
) -> ReliefImage {
    let fr = FrameRays::new(camera, width, height);
    let rects: Vec<Option<[i64; 4]>> = nodes
        .iter()
        .map(|f| {
            let a = &field.nodes[f.node].aabb;
            screen_rect(a.min, a.max, camera, width, height)
        })
        .collect();
    type Px = (Option<Hit>, f32, [u8; 4], u32);
    let rows: Vec<Vec<Px>> = (0..height)
        .into_par_iter()
        .map(|y| {
            let live: Vec<usize> = (0..nodes.len())
                .filter(|&k| rects[k].is_some_and(|r| r[1] <= i64::from(y) && i64::from(y) < r[3]))
                .collect();
            (0..width)
                .map(|x| {
                    let v = fr.view_dir(x, y);
                    let mut best: Option<(f32, usize, Hit, crate::blockmap::TexRay<f32>)> = None;
                    for &k in &live {
                        let r = rects[k].expect("live");
                        if i64::from(x) < r[0] || i64::from(x) >= r[2] {
                            continue;
                        }
                        let f = &nodes[k];
                        let n = &field.nodes[f.node];
                        let ray = f.xform.ray(v, fr.near);
                        let levels = prepared.levels(f.node);
                        let c = if f.flat {
                            cast_flat(levels, n.m(), &ray)
                        } else {
                            cast_f32(levels, n.m(), &ray)
                        };
                        if let Some(h) = c.hit {
                            let depth = fr.depth(h.t as f32);
                            if depth < 1.0 && best.as_ref().is_none_or(|b| depth < b.0) {
                                best = Some((depth, k, h, ray));
                            }
                        }
                    }
                    match best {
                        None => (None, 1.0, [0; 4], u32::MAX),
                        Some((depth, k, h, ray)) => {
                            let f = &nodes[k];
                            let n = &field.nodes[f.node];
                            let c = shade_blended(
                                n,
                                prepared.xforms(f.node),
                                &f.chosen,
                                f.previous.as_ref(),
                                f.weight,
                                &ray,
                                &h,
                            );
                            (Some(h), depth, c, f.node as u32)
                        }
                    }
                })
                .collect()
        })
        .collect();
    let n = (width * height) as usize;
    let mut img = ReliefImage {
        width,
        height,
        hit: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        color: Vec::with_capacity(n),
        node: Vec::with_capacity(n),
    };
    for (h, d, c, k) in rows.into_iter().flatten() {
        img.hit.push(h);
        img.depth.push(d);
        img.color.push(c);
        img.node.push(k);
    }
    img
}

/// The CPU fallback of hybrid frames with relief impostors: block meshes through the oracle's
/// shaded z-buffer and the frame's nodes through [`cast_image`], composited per pixel by depth
/// (the GPU's `Less` test). Wall time.
pub struct CpuReliefRenderer<'a> {
    meshes: &'a [(BlockId, Mesh)],
    ground: &'a Mesh,
    terrain: Option<&'a dyn TerrainDraw>,
    field: &'a ReliefField,
    prepared: Prepared<'a>,
    sets: std::sync::Mutex<MapSets>,
    size: (u32, u32),
}

impl<'a> CpuReliefRenderer<'a> {
    /// A renderer of `meshes` on the ground layers `ground` and of `field`'s nodes.
    pub fn new(
        meshes: &'a [(BlockId, Mesh)],
        ground: &'a Mesh,
        field: &'a ReliefField,
        size: (u32, u32),
    ) -> Self {
        Self {
            meshes,
            ground,
            terrain: None,
            field,
            prepared: Prepared::new(field),
            sets: std::sync::Mutex::new(MapSets::new(field.options.blend_frames)),
            size,
        }
    }
}

impl<'a> CpuReliefRenderer<'a> {
    /// The same renderer drawing `terrain`'s cut under the meshes instead of the flat ground
    /// ([`CpuFrameRenderer::with_terrain`]); the nodes then composite over it by depth.
    pub fn with_terrain(self, terrain: &'a dyn TerrainDraw) -> Self {
        Self {
            terrain: Some(terrain),
            ..self
        }
    }

    fn meshes_only(&self) -> CpuFrameRenderer<'a> {
        let r = CpuFrameRenderer::new(self.meshes, self.size).with_ground(self.ground);
        match self.terrain {
            Some(t) => r.with_terrain(t),
            None => r,
        }
    }
}

impl FrameRenderer for CpuReliefRenderer<'_> {
    fn describe(&self) -> String {
        format!(
            "CPU hybrid: z-buffer meshes (visibility::oracle) + f32 reference relief caster, \
             {} nodes, wall time, {}x{}",
            self.field.nodes.len(),
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
        if let Some(&bad) = far.iter().find(|&&m| m >= self.field.nodes.len()) {
            return Err(format!(
                "{}: relief node {bad} does not exist ({} nodes)",
                self.describe(),
                self.field.nodes.len()
            )
            .into());
        }
        self.meshes_only()
            .draw_composited(camera, visible, want_image, |w, h| {
                let mut nodes = frame_nodes(self.prepared.infos(), far, camera, h);
                self.sets
                    .lock()
                    .map_err(|_| "relief map sets: a renderer thread panicked")?
                    .apply(&mut nodes, camera);
                let relief = cast_image(self.field, &self.prepared, &nodes, camera, w, h);
                Ok(relief
                    .hit
                    .iter()
                    .zip(relief.depth.iter().zip(&relief.color))
                    .map(|(hit, (&d, &c))| hit.map(|_| (d, c)))
                    .collect())
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn node(chosen: [Option<u32>; CHOSEN]) -> FrameNode {
        FrameNode {
            node: 7,
            flat: false,
            chosen,
            previous: None,
            weight: 256,
            xform: MapXform {
                ax: [0.0; 3],
                ay: [0.0; 3],
                af: [0.0; 3],
                b: [0.0; 3],
            },
        }
    }

    #[test]
    fn a_switch_is_blended_over_the_frames_asked_for() {
        let a = [Some(0), Some(1), Some(2)];
        let b = [Some(3), Some(1), Some(2)];
        let mut sets = MapSets::new(4);
        let cam = |x: f64| Camera::looking_at(DVec3::new(x, 0.0, 10.0), DVec3::ZERO);
        let mut weights = Vec::new();
        for (frame, chosen) in [a, a, b, b, b, b, b, b].into_iter().enumerate() {
            let mut n = [node(chosen)];
            sets.apply(&mut n, &cam(frame as f64));
            // The same camera again (a reference frame) sees the same blend.
            let mut again = [node(chosen)];
            sets.apply(&mut again, &cam(frame as f64));
            assert_eq!(again[0].weight, n[0].weight);
            assert_eq!(again[0].previous, n[0].previous);
            if n[0].previous.is_some() {
                assert_eq!(n[0].previous, Some(a));
            }
            weights.push(n[0].weight);
        }
        // New set's share: (k + 1)·256/5 on the k-th frame after the switch, then alone.
        assert_eq!(weights, [256, 256, 51, 102, 153, 204, 256, 256]);
        // Without blending a switch is immediate.
        let mut sets = MapSets::new(0);
        for (frame, chosen) in [a, b].into_iter().enumerate() {
            let mut n = [node(chosen)];
            sets.apply(&mut n, &cam(frame as f64));
            assert_eq!((n[0].previous, n[0].weight), (None, 256));
        }
    }
}
