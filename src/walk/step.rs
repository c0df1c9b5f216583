//! One frame's culling, shared by the walk and the viewer: the blocks through a structure (and,
//! with occlusion, the cull map), the per-building test inside the surviving blocks (Willmott et
//! al., §3.2.8), and the draw ids the renderer takes; and the far field's selection for a view,
//! pruned by the same cull map.

use super::CullMode;
use crate::blockmap::{Selection, Selector};
use crate::blocks::BlockId;
use crate::city::BuildingId;
use crate::geom::Camera;
use crate::index::{CityIndex, CullQuery, CullStats, Structure};
use crate::scene::{DrawOrder, Scene, Unit};
use crate::visibility::{CullMap, OcclusionCuller, OcclusionCulling};
use std::time::Instant;

/// What one cull kept, with its cost.
#[derive(Clone, Copy, Debug)]
pub struct Culled {
    /// Work counters of the block cull.
    pub stats: CullStats,
    /// Culling seconds (blocks and, in the per-building modes, buildings).
    pub seconds: f64,
    /// Blocks kept (pages for the scene graph).
    pub blocks: usize,
    /// Buildings kept by the per-building test, in the modes that run it.
    pub buildings: Option<usize>,
    /// Triangles of what is drawn.
    pub triangles: u64,
    /// Draw calls for what is drawn ([`DrawOrder::calls`]).
    pub draws: usize,
}

/// The per-frame cull of one scene, with its buffers kept from frame to frame.
pub struct CullStep {
    /// Triangles per block id.
    triangles: Vec<u64>,
    /// The renderer's layout of the block meshes, to count calls (the draw units keep their
    /// own when the scene has them).
    order: Option<DrawOrder>,
    /// The per-building modes' own cull map (the block culling's is the culler's).
    building_map: Option<CullMap>,
    visible: Vec<BlockId>,
    kept_buildings: Vec<BuildingId>,
    draw_ids: Vec<BlockId>,
}

impl CullStep {
    /// The cull of `scene`'s frames (each [`CullStep::cull`] takes the same scene).
    pub fn new(scene: &Scene) -> Self {
        Self {
            triangles: scene.triangles_by_block(),
            order: scene
                .units
                .is_none()
                .then(|| DrawOrder::new(scene.draw_meshes())),
            building_map: scene.occlusion.as_ref().map(|c| c.new_map()),
            visible: Vec::new(),
            kept_buildings: Vec::new(),
            draw_ids: Vec::new(),
        }
    }

    /// Culls the frame of `camera` through `index` in `mode`; what to draw is then
    /// [`CullStep::draw_ids`]. The per-building modes need the scene's draw units (without them
    /// the blocks are drawn whole); occlusion modes need its culler (without one the frustum
    /// alone culls).
    pub fn cull(
        &mut self,
        scene: &Scene,
        index: &dyn CityIndex,
        mode: CullMode,
        camera: &Camera,
    ) -> Culled {
        let units = scene.units.as_ref();
        let pages = index.structure() == Structure::SceneGraph;
        self.visible.clear();
        self.kept_buildings.clear();
        let frustum = camera.frustum();
        let frustum_only = |visible: &mut Vec<BlockId>| {
            index.cull(
                &CullQuery::with_eye(&frustum, camera.position),
                None,
                visible,
            )
        };
        let t0 = Instant::now();
        let (stats, buildings) = match (units, mode.buildings()) {
            (Some(u), true) => {
                // Blocks through the structure (and the cull map), then each building of the
                // surviving blocks against the frustum and the same map.
                let map = match (mode.occlusion(), scene.occlusion.as_ref()) {
                    (true, Some(c)) => self.building_map.as_mut().map(|m| {
                        let st = c.build(camera, m);
                        let usable = st.skipped.is_none() && st.cells_covered > 0;
                        let st = c.traverse(index, camera, m, st, &mut self.visible);
                        (st.cull, usable)
                    }),
                    _ => None,
                };
                let (stats, map) = match map {
                    Some((stats, usable)) => (stats, self.building_map.as_ref().filter(|_| usable)),
                    None => (frustum_only(&mut self.visible), None),
                };
                u.buildings
                    .refine(&frustum, map, &self.visible, &mut self.kept_buildings);
                (stats, Some(self.kept_buildings.len()))
            }
            _ => {
                let culler = scene.occlusion.as_ref().map(|c| c as &dyn OcclusionCulling);
                let stats = match (mode, culler) {
                    (CullMode::FrustumOcclusion, Some(c)) => {
                        c.cull_frame(index, camera, &mut self.visible)
                    }
                    _ => frustum_only(&mut self.visible),
                };
                (stats, None)
            }
        };
        let seconds = t0.elapsed().as_secs_f64();
        // What the renderer draws: blocks, pages or buildings (unit ids, see `scene::units`).
        self.draw_ids.clear();
        match (units, buildings.is_some(), pages) {
            (Some(u), true, _) => self
                .draw_ids
                .extend(self.kept_buildings.iter().map(|&b| u.id(Unit::Building(b)))),
            (Some(u), false, true) => self
                .draw_ids
                .extend(self.visible.iter().map(|&p| u.id(Unit::Page(p.0)))),
            _ => self.draw_ids.extend_from_slice(&self.visible),
        }
        let triangles = match units {
            Some(u) => self.draw_ids.iter().map(|&d| u.unit_triangles(d)).sum(),
            None => self
                .draw_ids
                .iter()
                .map(|b| self.triangles.get(b.0 as usize).copied().unwrap_or(0))
                .sum(),
        };
        Culled {
            stats,
            seconds,
            blocks: self.visible.len(),
            buildings,
            triangles,
            draws: match (units, &self.order) {
                (Some(u), _) => u.draw_calls(&self.draw_ids),
                (None, Some(o)) => o.calls(&self.draw_ids),
                (None, None) => DrawOrder::new(scene.draw_meshes()).calls(&self.draw_ids),
            },
        }
    }

    /// The draw ids of the last cull: blocks, pages or buildings as the renderer of
    /// [`Scene::draw_meshes`] takes them.
    pub fn draw_ids(&self) -> &[BlockId] {
        &self.draw_ids
    }

    /// Triangles of block `b` (0 for an unknown id).
    pub fn block_triangles(&self, b: BlockId) -> u64 {
        self.triangles.get(b.0 as usize).copied().unwrap_or(0)
    }
}

/// The far field's selection of one view, and what it cost.
#[derive(Clone, Debug)]
pub struct FarPick {
    /// The nodes and meshes to draw.
    pub selection: Selection,
    /// With [`FarStep::select`]'s `frozen`: the same camera with the previous frame's decisions
    /// kept (the popping measure's frame).
    pub frozen: Option<Selection>,
    /// Seconds of the selection (with the cull map's construction).
    pub seconds: f64,
}

/// The far field's per-frame selection: the selector (which keeps the previous frame for its
/// hysteresis) and the cull map that prunes nodes in occlusion mode.
#[derive(Clone)]
pub struct FarStep {
    selector: Selector,
    cull_map: Option<CullMap>,
}

impl FarStep {
    /// The selection of `selector`, with a cull map when `culler` is given.
    pub fn new(selector: Selector, culler: Option<&OcclusionCuller>) -> Self {
        Self {
            selector,
            cull_map: culler.map(|c| c.new_map()),
        }
    }

    /// Selects the far field of `camera` on an image `height_px` tall. With `culler`, the cull
    /// map of this camera prunes nodes, as it prunes the structures' nodes (used only when the
    /// culler drew something, as `OcclusionCuller::traverse` does). With `frozen`, also the
    /// selection with the previous frame's decisions kept.
    pub fn select(
        &mut self,
        culler: Option<&OcclusionCuller>,
        camera: &Camera,
        height_px: u32,
        frozen: bool,
    ) -> FarPick {
        let t0 = Instant::now();
        let map: Option<&CullMap> = match (culler, self.cull_map.as_mut()) {
            (Some(c), Some(m)) => {
                let st = c.build(camera, m);
                (st.skipped.is_none() && st.cells_covered > 0).then_some(&*m)
            }
            _ => None,
        };
        let frozen = frozen.then(|| self.selector.select_frozen(camera, height_px, map));
        let selection = self.selector.select(camera, height_px, map);
        FarPick {
            selection,
            frozen,
            seconds: t0.elapsed().as_secs_f64(),
        }
    }

    /// Forgets the previous frame (the next selection is a fresh one).
    pub fn reset(&mut self) {
        self.selector.reset();
    }
}
