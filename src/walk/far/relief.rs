//! Relief impostors ([`crate::relief`], Andujar et al.) behind the far-field interface: the
//! selector over the relief tree's nodes (each holds whole blocks; drawn where its texel, its
//! declared error, projects to at most τ pixels: the paper's §5.1 test), the CPU renderer, the
//! GPU data and the silhouette bound's casts.

use super::field::{BuildFar, FarBuildSummary, FarField, FarGpu, SilhouetteBound};
use crate::blockmap::error::BuildingGrid;
use crate::blockmap::{FrameRays, SelectError, SelectNode, SelectOptions, Selector, Source};
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::{Aabb3, Camera};
use crate::index::BlockBounds;
use crate::relief::cast::{cast_f32, cast_f64, cast_flat};
use crate::relief::{CpuReliefRenderer, NodeMaps, ReliefError, ReliefField, ReliefOptions};
use crate::scene::Scene;
use crate::visibility::{FrameRenderer, TerrainDraw};
use crate::walk::bound::{BoundGeometry, BoundMaps, FrameCaster};
use glam::{DVec2, DVec3};

impl FarField for ReliefField {
    fn name(&self) -> &'static str {
        "relief impostors"
    }

    fn len(&self) -> usize {
        self.nodes.len()
    }

    fn build_summary(&self) -> FarBuildSummary {
        FarBuildSummary {
            representation: self.name().to_string(),
            nodes: self.nodes.len(),
            bytes: self.summary.bytes,
            max_error_m: self.summary.max_error_m,
        }
    }

    fn selector(
        &self,
        blocks: &[BlockBounds],
        opts: SelectOptions,
    ) -> Result<Selector, SelectError> {
        let nodes: Vec<SelectNode> = self
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| SelectNode {
                key: i as u64,
                eps_m: n.eps_m,
                aabb: n.aabb,
                parent: n.parent,
                blocks: n.blocks.clone(),
            })
            .collect();
        Selector::from_nodes(&nodes, blocks, opts)
    }

    fn cpu_renderer<'a>(
        &'a self,
        meshes: &'a [(BlockId, Mesh)],
        ground: &'a Mesh,
        terrain: Option<&'a dyn TerrainDraw>,
        size: (u32, u32),
    ) -> Box<dyn FrameRenderer + 'a> {
        let r = CpuReliefRenderer::new(meshes, ground, self, size);
        match terrain {
            Some(t) => Box::new(r.with_terrain(t)),
            None => Box::new(r),
        }
    }

    fn gpu(&self) -> FarGpu<'_> {
        FarGpu::Relief(self)
    }

    fn silhouette_bound<'a>(&'a self, source: &'a Source<'a>) -> Box<dyn SilhouetteBound + 'a> {
        Box::new(BoundGeometry::new(source, self))
    }
}

impl BuildFar for ReliefField {
    type Options = ReliefOptions;
    type Error = ReliefError;

    fn build(
        scene: &Scene,
        opts: &ReliefOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, Self::Error> {
        crate::relief::build_field(
            &scene.city,
            &scene.layout,
            &scene.building_meshes,
            opts,
            progress,
        )
    }
}

/// One node's casts in one frame, as the frame draws it (flat or walked).
struct ReliefCaster<'s> {
    node: &'s NodeMaps,
    levels: Vec<&'s [u16]>,
    xform: crate::blockmap::MapXform,
    rays: FrameRays,
    camera: Camera,
    flat: bool,
    w: u32,
    h: u32,
}

impl FrameCaster for ReliefCaster<'_> {
    fn hit_depth(&self, px: f64, py: f64) -> Option<f32> {
        let fr = &self.rays;
        let v = [px as f32 * fr.sx + fr.cx, py as f32 * fr.sy + fr.cy];
        let ray = self.xform.ray(v, fr.near);
        let m = self.node.m();
        let c = if self.flat {
            cast_flat(&self.levels, m, &ray)
        } else {
            cast_f32(&self.levels, m, &ray)
        };
        c.hit.map(|h| fr.depth(h.t as f32))
    }
    fn twin_point(&self, x: u32, y: u32) -> Option<DVec3> {
        let ray = self.node.twin_ray(&self.camera, self.w, self.h, x, y);
        let m = self.node.m();
        let c = if self.flat {
            cast_flat(&self.levels, m, &ray)
        } else {
            cast_f64(&self.levels, m, &ray)
        };
        c.hit.map(|h| self.node.local_point(&ray, h.t))
    }
}

impl BoundMaps for ReliefField {
    fn count(&self) -> usize {
        self.nodes.len()
    }
    fn aabb(&self, m: usize) -> Aabb3 {
        self.nodes[m].aabb
    }
    fn buildings(&self, m: usize) -> &[u32] {
        &self.nodes[m].buildings
    }
    fn declared(&self, m: usize) -> Vec<u32> {
        self.nodes[m].declared.clone()
    }
    fn eps_m(&self, m: usize) -> f64 {
        self.nodes[m].eps_m
    }
    fn frame_caster<'s>(
        &'s self,
        m: usize,
        camera: &Camera,
        w: u32,
        h: u32,
    ) -> Box<dyn FrameCaster + 's> {
        let node = &self.nodes[m];
        let info = node.frame_info();
        Box::new(ReliefCaster {
            node,
            levels: node.levels(),
            xform: crate::blockmap::MapXform::from_texture_space(
                info.tex_origin,
                info.tex_scale,
                camera,
            ),
            rays: FrameRays::new(camera, w, h),
            camera: *camera,
            flat: info.is_flat(camera, h),
            w,
            h,
        })
    }
    fn building_grid<'s>(&self, m: usize, source: &'s Source<'s>) -> BuildingGrid<'s> {
        let n = &self.nodes[m];
        let f = &n.zenithal.frame;
        BuildingGrid::over_square(
            DVec2::new(f.origin.x, f.origin.y),
            f.texel_m(),
            f.m as usize,
            source,
            &n.buildings,
        )
    }
}
