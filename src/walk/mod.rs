//! The walk (seed 003 §5.1): plays a camera route over a [`Scene`]. Per frame and per structure
//! and culling mode: cull → (far-field selection, with BlockMaps) → draw → check against the
//! oracle → one [`FrameRecord`]. It knows nothing of files or formats: `report` writes records.
//!
//! Seed 003 measured seconds per rendered frame in OpenGL Performer. Here a frame's time is the
//! culling time plus, when drawing, the time of drawing the blocks the structure kept (GPU time
//! from timestamp queries when the renderer has them, else wall time).

pub mod bound;
mod far;
mod summary;

pub use bound::{BoundFigures, BoundGeometry, FrameBound};
pub use far::{
    changed_pixels, coverage, far_json, image_error, image_error_with_bound, FarDecision, FarField,
    FarMode, FarRecord, ImageError, OcclusionDecision,
};
pub use summary::{summarise, SummaryRow};

use crate::blocks::BlockId;
use crate::geom::Camera;
use crate::index::{CityIndex, CullQuery, CullStats, Structure};
use crate::route::CameraRoute;
use crate::scene::{BuildingsMode, DrawOrder, DrawUnits, Scene};
use crate::visibility::{
    CpuFrameRenderer, FrameRenderer, MeshOracle, OcclusionCulling, VisibilityOracle,
};
use serde::Serialize;
use std::collections::HashSet;
use std::time::Instant;

/// Whether occlusion culling runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OcclusionMode {
    /// Frustum culling only.
    Off,
    /// Frustum and occlusion culling (fails without an occlusion culler).
    On,
    /// Both modes, side by side, when the scene has an occlusion culler; frustum only otherwise.
    #[default]
    Auto,
}

crate::choice::choices!(OcclusionMode, "occlusion mode",
    Off => "off", "Frustum culling only";
    On => "on", "Frustum and occlusion culling (fails without an occlusion culler)";
    Auto => "auto", "Both modes, side by side, when the scene has an occlusion culler; frustum only otherwise";
);

/// How one frame was culled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum CullMode {
    /// View-frustum culling.
    #[serde(rename = "frustum")]
    Frustum,
    /// View-frustum and occlusion culling.
    #[serde(rename = "frustum+occlusion")]
    FrustumOcclusion,
    /// View-frustum culling of the blocks, then of each building of the surviving blocks
    /// (seed 004 §3.2.8, [`crate::visibility::buildings`]).
    #[serde(rename = "frustum+buildings")]
    FrustumBuildings,
    /// Frustum and occlusion culling of the blocks, then of each building of the surviving
    /// blocks against the frustum and the same cull map.
    #[serde(rename = "frustum+occlusion+buildings")]
    FrustumOcclusionBuildings,
}

impl CullMode {
    /// The mode's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            CullMode::Frustum => "frustum",
            CullMode::FrustumOcclusion => "frustum+occlusion",
            CullMode::FrustumBuildings => "frustum+buildings",
            CullMode::FrustumOcclusionBuildings => "frustum+occlusion+buildings",
        }
    }

    /// Whether the mode uses the cull map.
    pub fn occlusion(self) -> bool {
        matches!(
            self,
            CullMode::FrustumOcclusion | CullMode::FrustumOcclusionBuildings
        )
    }

    /// Whether the mode tests the buildings inside the surviving blocks.
    pub fn buildings(self) -> bool {
        matches!(
            self,
            CullMode::FrustumBuildings | CullMode::FrustumOcclusionBuildings
        )
    }

    /// The same block culling with the per-building test added.
    pub fn with_buildings(self) -> Self {
        match self {
            CullMode::Frustum | CullMode::FrustumBuildings => CullMode::FrustumBuildings,
            CullMode::FrustumOcclusion | CullMode::FrustumOcclusionBuildings => {
                CullMode::FrustumOcclusionBuildings
            }
        }
    }

    /// The same block culling without the per-building test.
    pub fn blocks_only(self) -> Self {
        match self {
            CullMode::Frustum | CullMode::FrustumBuildings => CullMode::Frustum,
            CullMode::FrustumOcclusion | CullMode::FrustumOcclusionBuildings => {
                CullMode::FrustumOcclusion
            }
        }
    }
}

impl std::fmt::Display for CullMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.name())
    }
}

/// Walk settings.
#[derive(Clone, Debug)]
pub struct WalkParams {
    /// The route.
    pub route: CameraRoute,
    /// Frames sampled along it.
    pub frames: usize,
    /// Occlusion culling.
    pub occlusion: OcclusionMode,
    /// Keep an image every this many frames (0: none); needs drawing.
    pub image_every: usize,
    /// Count false culls against the oracle.
    pub oracle: bool,
    /// Image size for drawing and the oracle.
    pub size: (u32, u32),
}

/// Who draws the frames.
pub enum Drawing<'a> {
    /// Nothing is drawn: culling alone is timed.
    Off,
    /// This renderer draws (e.g. the wgpu renderer of `render`).
    With(&'a dyn FrameRenderer),
    /// The CPU fallback ([`CpuFrameRenderer`]) draws, for the reason given (said in the notes).
    CpuFallback {
        /// Why there is no GPU renderer.
        reason: String,
    },
}

/// One frame of one structure in one culling mode.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    /// Frame number along the route.
    pub frame: usize,
    /// The structure.
    pub structure: Structure,
    /// The culling mode.
    pub mode: CullMode,
    /// Culling time, seconds.
    pub cull_s: f64,
    /// Drawing time, seconds (GPU when measured), when drawing.
    pub render_s: Option<f64>,
    /// Culling + drawing, seconds.
    pub frame_s: f64,
    /// Work counters of the cull.
    pub stats: CullStats,
    /// Blocks kept (pages for [`Structure::SceneGraph`]).
    pub blocks: usize,
    /// Buildings kept by the per-building test, in the modes that run it.
    pub buildings: Option<usize>,
    /// Triangles drawn: of the kept blocks (pages), or of the kept buildings.
    pub triangles: u64,
    /// Draw calls for what is drawn: one per run of kept units that are neighbours in the
    /// renderer's buffer ([`DrawOrder::calls`]), counted whether or not frames are drawn.
    pub draws: usize,
    /// Oracle-visible blocks the structure dropped (must be 0), when checked; oracle-visible
    /// *buildings* dropped for [`Structure::SceneGraph`] and the per-building modes.
    pub false_culls: Option<usize>,
}

/// What a walk recorded.
#[derive(Debug)]
pub struct WalkRecord {
    /// City name.
    pub city: String,
    /// Route name.
    pub route: String,
    /// The cameras, one per frame.
    pub cameras: Vec<Camera>,
    /// Per-frame records (frame-major, then structure, then mode).
    pub frames: Vec<FrameRecord>,
    /// Table 1: averages per structure and mode.
    pub summary: Vec<SummaryRow>,
    /// What drew, or why nothing did.
    pub renderer: String,
    /// Kept images: frame number and picture (of the reference structure in the last mode).
    pub images: Vec<(usize, image::RgbaImage)>,
    /// Notes for the reader (fallbacks, skipped checks).
    pub notes: Vec<String>,
    /// Wall time of the whole walk, seconds.
    pub total_s: f64,
    /// Hybrid frames (near meshes + far maps), when a far field was given and used.
    pub far: Vec<FarRecord>,
    /// Whether the far field ran (none when no far field was given).
    pub far_decision: Option<FarDecision>,
    /// The far field's selection settings, when one was given.
    pub far_options: Option<crate::blockmap::SelectOptions>,
    /// Whether occlusion culling saved time on this route (both modes walked).
    pub occlusion_decision: Option<OcclusionDecision>,
    /// Whether testing the buildings inside the surviving blocks paid, per block culling mode
    /// (both walked).
    pub buildings_decision: Vec<BuildingsDecision>,
}

/// Whether the per-building test paid on the route, for one block culling mode: the reference
/// structure's mean frame time and triangles with and without it.
#[derive(Clone, Debug, Serialize)]
pub struct BuildingsDecision {
    /// The block culling mode (without the per-building test).
    pub mode: CullMode,
    /// Mean seconds per frame without / with the per-building test.
    pub blocks_s: f64,
    /// Mean seconds per frame with it.
    pub buildings_s: f64,
    /// Mean culling seconds per frame without / with it.
    pub blocks_cull_s: f64,
    /// Mean culling seconds per frame with it.
    pub buildings_cull_s: f64,
    /// Mean triangles drawn per frame without it.
    pub blocks_triangles: f64,
    /// Mean triangles drawn per frame with it.
    pub buildings_triangles: f64,
    /// Mean draw calls per frame without it.
    pub blocks_draws: f64,
    /// Mean draw calls per frame with it.
    pub buildings_draws: f64,
    /// Whether frames were drawn (else only triangles can decide).
    pub drawn: bool,
    /// Keep it: drawn frames are faster with it, or (nothing drawn) it removes triangles.
    pub pays: bool,
    /// The sentence for the report.
    pub note: String,
}

impl WalkRecord {
    /// The structures in order of first appearance.
    pub fn structures(&self) -> Vec<Structure> {
        let mut v: Vec<Structure> = Vec::new();
        for r in &self.frames {
            if !v.contains(&r.structure) {
                v.push(r.structure);
            }
        }
        v
    }

    /// The culling modes in order of first appearance.
    pub fn modes(&self) -> Vec<CullMode> {
        let mut v: Vec<CullMode> = Vec::new();
        for r in &self.frames {
            if !v.contains(&r.mode) {
                v.push(r.mode);
            }
        }
        v
    }

    /// False culls over the whole walk, when the oracle was consulted.
    pub fn false_culls(&self) -> Option<usize> {
        self.frames
            .iter()
            .map(|r| r.false_culls)
            .try_fold(0usize, |a, x| x.map(|x| a + x))
    }
}

/// What went wrong in the walk.
#[derive(Debug, thiserror::Error)]
pub enum WalkError {
    /// The scene has no structure to walk with.
    #[error("{0}: no spatial structure to compare")]
    NoStructures(String),
    /// Occlusion was asked for but the scene has no culler.
    #[error("{0}: occlusion culling asked for, but the scene has no occlusion culler")]
    NoOcclusion(String),
    /// No frames to walk.
    #[error("{0}: a walk needs at least one frame")]
    NoFrames(String),
    /// The far field's maps do not fit the scene.
    #[error("{city}: the far field's maps do not fit the scene")]
    Far {
        /// City name.
        city: String,
        /// What is wrong.
        #[source]
        source: crate::blockmap::SelectError,
    },
}

/// The structure ratios and images refer to: the BqR-tree when present, else the first.
fn reference_structure(scene: &Scene) -> Structure {
    scene
        .index(Structure::Bqr)
        .map(|i| i.structure())
        .or_else(|| scene.indexes.first().map(|i| i.structure()))
        .unwrap_or(Structure::Bqr)
}

/// Plays the walk: for every frame, every structure of the scene and every culling mode,
/// culls, optionally draws and checks against the oracle. `progress(done, total)` is called
/// after every frame.
///
/// # Errors
/// [`WalkError`]: no structure, occlusion asked for without a culler, no frames.
pub fn run_walk(
    scene: &Scene,
    params: &WalkParams,
    drawing: Drawing<'_>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<WalkRecord, WalkError> {
    run_walk_with_far(scene, params, drawing, None, progress)
}

/// The CPU hybrid renderer (meshes by the oracle's z-buffer, maps by the reference caster) for
/// the CPU fallback, or why there is none.
fn cpu_hybrid<'a>(
    scene: &'a Scene,
    maps: &'a crate::blockmap::MapTree,
    size: (u32, u32),
) -> Result<Box<dyn FrameRenderer + 'a>, String> {
    Ok(Box::new(crate::blockmap::CpuHybridRenderer::new(
        &scene.meshes,
        &scene.ground,
        maps.maps.iter().map(|m| &m.map).collect(),
        size,
    )))
}

/// As [`run_walk`], with a far field: for every frame and culling mode, the reference
/// structure's frame is also drawn as a hybrid frame, near meshes plus far BlockMaps chosen by
/// [`crate::blockmap::Selector`] (the renderer of `drawing` must have been built with
/// `far.maps`; the CPU fallback builds its own), recorded in [`WalkRecord::far`]. With
/// [`FarField::leave_out`] the far field is left out when no node qualifies along the route or
/// when hybrid frames, timed on the GPU, are no faster than mesh-only ones over the first
/// frames; [`WalkRecord::far_decision`] says which.
///
/// # Errors
/// As [`run_walk`]; a far field whose maps do not fit the scene's blocks.
pub fn run_walk_with_far(
    scene: &Scene,
    params: &WalkParams,
    drawing: Drawing<'_>,
    far: Option<FarField<'_>>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<WalkRecord, WalkError> {
    let started = Instant::now();
    if scene.indexes.is_empty() {
        return Err(WalkError::NoStructures(scene.name.clone()));
    }
    if params.frames == 0 {
        return Err(WalkError::NoFrames(scene.name.clone()));
    }
    let mut notes = Vec::new();
    let culler: Option<&dyn OcclusionCulling> =
        scene.occlusion.as_ref().map(|c| c as &dyn OcclusionCulling);
    let modes: Vec<CullMode> = match (params.occlusion, culler.is_some()) {
        (OcclusionMode::Off, _) => vec![CullMode::Frustum],
        (OcclusionMode::On, true) => vec![CullMode::FrustumOcclusion],
        (OcclusionMode::On, false) => return Err(WalkError::NoOcclusion(scene.name.clone())),
        (OcclusionMode::Auto, true) => vec![CullMode::Frustum, CullMode::FrustumOcclusion],
        (OcclusionMode::Auto, false) => {
            notes.push("no occlusion culler in the scene: frustum culling only".into());
            vec![CullMode::Frustum]
        }
    };
    let cameras = params.route.sample(params.frames);
    let triangles = scene.triangles_by_block();
    let units = scene.units.as_ref();
    // The renderer's layout of the units, to count the calls of each frame.
    let draw_order = DrawOrder::new(scene.draw_meshes());
    let cpu = CpuFrameRenderer::new(scene.draw_meshes(), params.size).with_ground(&scene.ground);
    let renderer: Option<&dyn FrameRenderer> = match &drawing {
        Drawing::Off => None,
        Drawing::With(r) => Some(*r),
        Drawing::CpuFallback { reason } => {
            notes.push(format!(
                "GPU rendering unavailable ({reason}); draw times are CPU times and not comparable with GPU numbers"
            ));
            Some(&cpu)
        }
    };
    let renderer_desc = match (&drawing, renderer) {
        (Drawing::CpuFallback { reason }, Some(r)) => {
            format!("CPU fallback ({reason}): {}", r.describe())
        }
        (_, Some(r)) => r.describe(),
        (_, None) => "none (drawing not asked for)".to_string(),
    };
    // The far field: selectors (one per mode: each keeps its own previous frame), the hybrid
    // renderer, and the decision whether the scene needs it at all.
    let cpu_far = match (&far, &drawing) {
        (Some(f), Drawing::CpuFallback { .. }) => Some(cpu_hybrid(scene, f.maps, params.size)),
        _ => None,
    };
    let hybrid: Option<&dyn FrameRenderer> = match (&drawing, &cpu_far) {
        (Drawing::With(r), _) => Some(*r),
        (_, Some(Ok(r))) => Some(r.as_ref()),
        _ => None,
    };
    if let Some(Err(reason)) = &cpu_far {
        notes.push(format!("far field not drawn: {reason}"));
    }
    let mut far_decision = None;
    let mut selectors: Vec<(CullMode, crate::blockmap::Selector)> = Vec::new();
    if let Some(f) = &far {
        let base =
            crate::blockmap::Selector::new(f.maps, &scene.bounds, f.select).map_err(|source| {
                WalkError::Far {
                    city: scene.name.clone(),
                    source,
                }
            })?;
        let height = renderer.map_or(params.size, |r| r.size()).1;
        let qualifies = {
            let mut probe = base.clone();
            f.maps.maps.is_empty()
                || cameras.iter().any(|c| {
                    probe.reset();
                    !probe.select(c, height, None).maps.is_empty()
                })
        };
        let decision = if f.maps.maps.is_empty() {
            FarDecision {
                used: false,
                reason: Some(
                    "the city has no BlockMaps (meshes are cheaper for every node)".into(),
                ),
                left_out_after: None,
            }
        } else if f.leave_out && !qualifies {
            FarDecision {
                used: false,
                reason: Some(format!(
                    "no node qualifies on any frame of the route at τ = {} px: the walk runs without the far field",
                    f.select.tau_px
                )),
                left_out_after: None,
            }
        } else {
            FarDecision {
                used: true,
                reason: None,
                left_out_after: None,
            }
        };
        if let Some(r) = &decision.reason {
            notes.push(format!("far field left out: {r}"));
        }
        if decision.used {
            selectors = modes.iter().map(|&m| (m, base.clone())).collect();
        }
        far_decision = Some(decision);
    }
    // The exact geometry of the silhouette bound's second look, when given.
    let bound_geometry = far
        .as_ref()
        .and_then(|f| f.source.map(|s| bound::BoundGeometry::new(s, f.maps)));
    if far
        .as_ref()
        .is_some_and(|f| f.reference && f.source.is_none())
    {
        notes.push(
            "silhouette bound not checked: no building geometry was given to the far field \
             (silhouette_ratio_max and the bound's counts are null; silhouette_px_max is the raw \
             image distance)"
                .into(),
        );
    }
    let mut far_records: Vec<FarRecord> = Vec::new();
    // Seconds spent on the referenced frames' image measures with the bound's second look.
    let mut bound_s = 0.0;
    let mut cull_map = scene.occlusion.as_ref().map(|c| c.new_map());
    // The per-building modes draw their own cull map (the block culling's is the culler's).
    let mut building_map = scene.occlusion.as_ref().map(|c| c.new_map());
    let oracle = MeshOracle::new(&scene.meshes);
    let building_oracle = units.map(|u| MeshOracle::new(u.building_meshes()));
    // The oracle judges the frames at their own resolution (the renderer's, when one draws).
    let oracle_size = renderer.map_or(params.size, |r| r.size());
    if params.oracle {
        notes.push(format!(
            "false culls counted against the {}",
            oracle.describe(oracle_size.0, oracle_size.1)
        ));
    }
    let reference = reference_structure(scene);
    let last_mode = *modes.last().expect("at least one mode");
    let mut frames = Vec::with_capacity(cameras.len() * scene.indexes.len() * modes.len());
    let mut images = Vec::new();
    let mut visible: Vec<BlockId> = Vec::new();
    let mut kept_buildings: Vec<crate::city::BuildingId> = Vec::new();
    let mut draw_ids: Vec<BlockId> = Vec::new();
    for (f, cam) in cameras.iter().enumerate() {
        let frustum = cam.frustum();
        let truth: Option<HashSet<BlockId>> = params
            .oracle
            .then(|| oracle.visible(cam, oracle_size.0, oracle_size.1));
        let building_truth: Option<HashSet<BlockId>> = building_oracle
            .as_ref()
            .filter(|_| params.oracle)
            .map(|o| o.visible(cam, oracle_size.0, oracle_size.1));
        for index in &scene.indexes {
            let index: &dyn CityIndex = index.as_ref();
            let pages = index.structure() == Structure::SceneGraph;
            for mode in index_modes(&modes, units, pages) {
                visible.clear();
                kept_buildings.clear();
                let t0 = Instant::now();
                let (stats, buildings_kept) = match (units, mode.buildings()) {
                    (Some(u), true) => {
                        // Blocks through the structure (and the cull map), then each building
                        // of the surviving blocks against the frustum and the same map.
                        let map = match (mode.occlusion(), scene.occlusion.as_ref()) {
                            (true, Some(c)) => building_map.as_mut().map(|m| {
                                let st = c.build(cam, m);
                                let usable = st.skipped.is_none() && st.cells_covered > 0;
                                let st = c.traverse(index, cam, m, st, &mut visible);
                                (st.cull, usable)
                            }),
                            _ => None,
                        };
                        let (stats, map) = match map {
                            Some((stats, usable)) => {
                                (stats, building_map.as_ref().filter(|_| usable))
                            }
                            None => (
                                index.cull(
                                    &CullQuery::with_eye(&frustum, cam.position),
                                    None,
                                    &mut visible,
                                ),
                                None,
                            ),
                        };
                        u.buildings
                            .refine(&frustum, map, &visible, &mut kept_buildings);
                        (stats, Some(kept_buildings.len()))
                    }
                    _ => (
                        match (mode, culler) {
                            (CullMode::FrustumOcclusion, Some(c)) => {
                                c.cull_frame(index, cam, &mut visible)
                            }
                            _ => index.cull(
                                &CullQuery::with_eye(&frustum, cam.position),
                                None,
                                &mut visible,
                            ),
                        },
                        None,
                    ),
                };
                let cull_s = t0.elapsed().as_secs_f64();
                // What the renderer draws: blocks, pages or buildings (unit ids, see
                // `scene::units`).
                draw_ids.clear();
                match (units, buildings_kept.is_some(), pages) {
                    (Some(u), true, _) => {
                        draw_ids.extend(kept_buildings.iter().map(|&b| u.building_id(b)))
                    }
                    (Some(u), false, true) => {
                        draw_ids.extend(visible.iter().map(|&p| u.page_id(p)))
                    }
                    _ => draw_ids.extend_from_slice(&visible),
                }
                let tri: u64 = match units {
                    Some(u) => draw_ids.iter().map(|&d| u.unit_triangles(d)).sum(),
                    None => draw_ids
                        .iter()
                        .map(|b| triangles.get(b.0 as usize).copied().unwrap_or(0))
                        .sum(),
                };
                let draws = draw_order.calls(&draw_ids);
                let kept_blocks = visible.len();
                let visible = &draw_ids;
                let keep_image = params.image_every > 0
                    && f % params.image_every == 0
                    && index.structure() == reference
                    && mode == last_mode;
                let far_here =
                    index.structure() == reference && !selectors.is_empty() && !mode.buildings();
                let want_reference = far_here && far.as_ref().is_some_and(|x| x.reference);
                let mut render_s = None;
                let mut mesh_image = None;
                if let Some(r) = renderer {
                    match r.draw(cam, visible, keep_image || want_reference) {
                        Ok(drawn) => {
                            render_s = Some(drawn.seconds);
                            if let Some(img) = drawn.image {
                                if keep_image {
                                    images.push((f, img.clone()));
                                }
                                mesh_image = Some(img);
                            }
                        }
                        Err(e) => notes.push(format!("frame {f}: drawing failed: {e}")),
                    }
                }
                if far_here {
                    let mesh_frame_s = cull_s + render_s.unwrap_or(0.0);
                    let slot = selectors
                        .iter()
                        .position(|(m, _)| *m == mode)
                        .expect("a selector per mode");
                    let rec = far_frame(
                        &mut selectors[slot].1,
                        FarFrame {
                            frame: f,
                            mode,
                            camera: cam,
                            height: renderer.map_or(params.size, |r| r.size()).1,
                            culler: if mode == CullMode::FrustumOcclusion {
                                scene.occlusion.as_ref()
                            } else {
                                None
                            },
                            cull_map: cull_map.as_mut(),
                            bound_s: &mut bound_s,
                            hybrid,
                            mesh_image: if want_reference {
                                mesh_image.as_ref()
                            } else {
                                None
                            },
                            mesh_frame_s,
                            triangles: &triangles,
                            bound: bound_geometry.as_ref(),
                            tau_px: far.as_ref().map_or(1.0, |x| x.select.tau_px),
                        },
                        &mut notes,
                    );
                    far_records.push(rec);
                }
                let false_culls = match (units, buildings_kept.is_some() || pages) {
                    // Building level: the oracle's buildings against the buildings drawn.
                    (Some(u), true) => building_truth.as_ref().map(|t| {
                        let kept: HashSet<BlockId> = if pages {
                            draw_ids
                                .iter()
                                .flat_map(|&d| {
                                    u.scene_graph
                                        .page_items((d.0 - u.page_offset) as usize)
                                        .iter()
                                        .map(|&b| u.building_id(crate::city::BuildingId(b.0)))
                                })
                                .collect()
                        } else {
                            draw_ids.iter().copied().collect()
                        };
                        t.iter().filter(|b| !kept.contains(b)).count()
                    }),
                    _ => truth.as_ref().map(|t| {
                        let kept: HashSet<BlockId> = draw_ids.iter().copied().collect();
                        t.iter().filter(|b| !kept.contains(b)).count()
                    }),
                };
                frames.push(FrameRecord {
                    frame: f,
                    structure: index.structure(),
                    mode,
                    cull_s,
                    render_s,
                    frame_s: cull_s + render_s.unwrap_or(0.0),
                    stats,
                    blocks: kept_blocks,
                    buildings: buildings_kept,
                    triangles: tri,
                    draws,
                    false_culls,
                });
            }
        }
        progress(f + 1, cameras.len());
        // The timing probe: after the first frames, leave the far field out when hybrid frames
        // (GPU-timed) are no faster than mesh-only ones.
        if let (Some(fd), Some(x)) = (far_decision.as_mut(), far.as_ref()) {
            if fd.used
                && x.leave_out
                && f + 1 == x.probe_frames.max(1)
                && f + 1 < cameras.len()
                && !far_records.is_empty()
                && far_records.iter().all(|r| r.gpu_time)
            {
                let probe: Vec<&FarRecord> = far_records.iter().collect();
                let n = probe.len().max(1) as f64;
                let hyb = probe.iter().map(|r| r.frame_s).sum::<f64>() / n;
                let mesh = probe.iter().map(|r| r.mesh_frame_s).sum::<f64>() / n;
                if hyb >= mesh {
                    fd.used = false;
                    fd.left_out_after = Some(f);
                    fd.reason = Some(format!(
                        "meshes draw faster than maps here: {:.3} ms hybrid vs {:.3} ms mesh-only per frame over the first {} frames",
                        hyb * 1e3,
                        mesh * 1e3,
                        f + 1
                    ));
                    notes.push(format!(
                        "far field left out after frame {f}: {}",
                        fd.reason.as_deref().unwrap_or_default()
                    ));
                    selectors.clear();
                }
            }
        }
    }
    if bound_geometry.is_some() {
        let checked = far_records
            .iter()
            .filter(|r| r.image.is_some_and(|i| i.silhouette_ratio_max.is_some()))
            .count();
        if checked > 0 {
            notes.push(format!(
                "silhouette bound checked with the exact geometry on {checked} hybrid frames \
                 ({:.3} s for their image measures in all)",
                bound_s
            ));
        }
    }
    let summary = summarise(&frames, reference);
    let occlusion_decision = occlusion_decision(&frames, reference);
    if let Some(d) = &occlusion_decision {
        notes.push(d.note.clone());
    }
    let buildings_decision = buildings_decisions(&frames, reference);
    notes.extend(buildings_decision.iter().map(|d| d.note.clone()));
    Ok(WalkRecord {
        city: scene.name.clone(),
        route: params.route.name.clone(),
        cameras,
        frames,
        summary,
        renderer: renderer_desc,
        images,
        notes,
        total_s: started.elapsed().as_secs_f64(),
        far: far_records,
        far_decision,
        far_options: far.map(|f| f.select),
        occlusion_decision,
        buildings_decision,
    })
}

/// The culling modes one index is walked in: the block modes, and with the scene's units the
/// per-building modes ([`BuildingsMode`]); pages (the scene graph) are drawn whole, never refined.
fn index_modes(modes: &[CullMode], units: Option<&DrawUnits>, pages: bool) -> Vec<CullMode> {
    let bm = match units {
        Some(u) if !pages => u.mode,
        _ => BuildingsMode::Off,
    };
    match bm {
        BuildingsMode::Off => modes.to_vec(),
        BuildingsMode::On => modes.iter().map(|m| m.with_buildings()).collect(),
        BuildingsMode::Auto => modes
            .iter()
            .flat_map(|&m| [m, m.with_buildings()])
            .collect(),
    }
}

/// Per block culling mode walked with and without the per-building test: whether the test paid
/// for the reference structure (drawn frames: mean frame time; nothing drawn: triangles).
fn buildings_decisions(frames: &[FrameRecord], reference: Structure) -> Vec<BuildingsDecision> {
    let per = |m: CullMode| -> Option<(f64, f64, f64, bool, f64)> {
        let v: Vec<&FrameRecord> = frames
            .iter()
            .filter(|r| r.structure == reference && r.mode == m)
            .collect();
        (!v.is_empty()).then(|| {
            let n = v.len() as f64;
            (
                v.iter().map(|r| r.frame_s).sum::<f64>() / n,
                v.iter().map(|r| r.cull_s).sum::<f64>() / n,
                v.iter().map(|r| r.triangles as f64).sum::<f64>() / n,
                v.iter().all(|r| r.render_s.is_some()),
                v.iter().map(|r| r.draws as f64).sum::<f64>() / n,
            )
        })
    };
    let mut out = Vec::new();
    for base in [CullMode::Frustum, CullMode::FrustumOcclusion] {
        let (Some((bs, bc, bt, bd, bn)), Some((ws, wc, wt, wd, wn))) =
            (per(base), per(base.with_buildings()))
        else {
            continue;
        };
        let drawn = bd && wd;
        let pays = if drawn { ws < bs } else { wt < bt };
        let saved = if bt > 0.0 { 1.0 - wt / bt } else { 0.0 };
        let note = format!(
            "per-building test after {base} ({reference}): {:.0} → {:.0} triangles per frame ({:.1} % fewer) in {:.1} → {:.1} draw calls, cull {:.3} → {:.3} ms{}: {}",
            bt,
            wt,
            saved * 100.0,
            bn,
            wn,
            bc * 1e3,
            wc * 1e3,
            if drawn {
                format!(", frame {:.3} → {:.3} ms", bs * 1e3, ws * 1e3)
            } else {
                String::new()
            },
            match (pays, drawn) {
                (true, true) => "it pays (faster frames): keep it",
                (false, true) => "it does not pay here (no faster frames): leave it out",
                (true, false) => "it removes triangles (nothing drawn to time)",
                (false, false) => "it removes nothing: leave it out",
            }
        );
        out.push(BuildingsDecision {
            mode: base,
            blocks_s: bs,
            buildings_s: ws,
            blocks_cull_s: bc,
            buildings_cull_s: wc,
            blocks_triangles: bt,
            buildings_triangles: wt,
            blocks_draws: bn,
            buildings_draws: wn,
            drawn,
            pays,
            note,
        });
    }
    out
}

/// What one hybrid frame needs.
struct FarFrame<'a, 'm> {
    frame: usize,
    mode: CullMode,
    camera: &'a Camera,
    height: u32,
    culler: Option<&'a crate::visibility::OcclusionCuller>,
    cull_map: Option<&'m mut crate::visibility::CullMap>,
    hybrid: Option<&'a dyn FrameRenderer>,
    mesh_image: Option<&'a image::RgbaImage>,
    mesh_frame_s: f64,
    triangles: &'a [u64],
    /// The exact geometry of the bound's second look, when given.
    bound: Option<&'a bound::BoundGeometry<'a>>,
    /// τ of the bound `1 + τ/cos²θ`.
    tau_px: f64,
    /// Accumulates the seconds of the image measures with the bound.
    bound_s: &'m mut f64,
}

/// Selects, draws and (with a mesh image) measures one hybrid frame.
fn far_frame(
    selector: &mut crate::blockmap::Selector,
    x: FarFrame<'_, '_>,
    notes: &mut Vec<String>,
) -> FarRecord {
    let f = x.frame;
    let t0 = Instant::now();
    // In occlusion mode the cull map of this camera prunes nodes, as it prunes the structures'
    // nodes (used only when the culler drew something, as `OcclusionCuller::traverse` does).
    let map: Option<&crate::visibility::CullMap> = match (x.culler, x.cull_map) {
        (Some(c), Some(m)) => {
            let st = c.build(x.camera, m);
            (st.skipped.is_none() && st.cells_covered > 0).then_some(&*m)
        }
        _ => None,
    };
    let frozen = x
        .mesh_image
        .is_some()
        .then(|| selector.select_frozen(x.camera, x.height, map));
    let sel = selector.select(x.camera, x.height, map);
    let select_s = t0.elapsed().as_secs_f64();
    let mesh_triangles: u64 = sel
        .meshes
        .iter()
        .map(|b| x.triangles.get(b.0 as usize).copied().unwrap_or(0))
        .sum();
    let mut rec = FarRecord {
        frame: f,
        mode: x.mode,
        select_s,
        render_s: None,
        frame_s: select_s,
        mesh_frame_s: x.mesh_frame_s,
        passes: Vec::new(),
        mesh_blocks: sel.meshes.len(),
        mesh_triangles,
        far_nodes: sel.maps.len(),
        far_blocks: sel.stats.map_blocks,
        far_pixels: None,
        stats: sel.stats,
        image: None,
        gpu_time: false,
    };
    let Some(r) = x.hybrid else { return rec };
    let drawn = match r.draw_with_far(x.camera, &sel.meshes, &sel.maps, x.mesh_image.is_some()) {
        Ok(d) => d,
        Err(e) => {
            notes.push(format!("frame {f}: drawing the hybrid frame failed: {e}"));
            return rec;
        }
    };
    rec.render_s = Some(drawn.seconds);
    rec.gpu_time = drawn.gpu_time;
    rec.frame_s = select_s + drawn.seconds;
    rec.passes = drawn
        .passes
        .iter()
        .map(|(n, s)| (n.to_string(), *s))
        .collect();
    rec.far_pixels = drawn.far_pixels;
    if let (Some(mesh), Some(hyb)) = (x.mesh_image, drawn.image.as_ref()) {
        let bg = r.draw(x.camera, &[], true).ok().and_then(|d| d.image);
        let Some(bg) = bg else {
            notes.push(format!(
                "frame {f}: the background frame could not be drawn"
            ));
            return rec;
        };
        let fb = x
            .bound
            .map(|g| bound::FrameBound::new(g, &sel, x.camera, x.tau_px));
        let t_err = Instant::now();
        let mut err = far::image_error_with_bound(mesh, hyb, &bg, fb.as_ref());
        if fb.is_some() {
            *x.bound_s += t_err.elapsed().as_secs_f64();
        }
        if let Some(fr) = frozen.filter(|fr| !far::same_selection(fr, &sel)) {
            match r.draw_with_far(x.camera, &fr.meshes, &fr.maps, true) {
                Ok(d) => {
                    if let Some(img) = d.image {
                        err.popping_colour_px = changed_pixels(&img, hyb);
                        err.popping_px = far::coverage_changed(&img, hyb, &bg);
                    }
                }
                Err(e) => notes.push(format!("frame {f}: drawing the popping frame failed: {e}")),
            }
        }
        rec.image = Some(err);
    }
    rec
}

/// Whether occlusion culling saved time on the route: the reference structure's mean frame time
/// with and without it, and the blocks it dropped (none when only one mode was walked).
fn occlusion_decision(frames: &[FrameRecord], reference: Structure) -> Option<OcclusionDecision> {
    let per = |m: CullMode| -> Option<(f64, f64)> {
        let v: Vec<&FrameRecord> = frames
            .iter()
            .filter(|r| r.structure == reference && r.mode == m)
            .collect();
        (!v.is_empty()).then(|| {
            let n = v.len() as f64;
            (
                v.iter().map(|r| r.frame_s).sum::<f64>() / n,
                v.iter().map(|r| r.blocks as f64).sum::<f64>() / n,
            )
        })
    };
    let (fs, fb) = per(CullMode::Frustum)?;
    let (os, ob) = per(CullMode::FrustumOcclusion)?;
    let dropped = fb - ob;
    let saves = os < fs && dropped > 0.0;
    let note = if dropped <= 0.0 {
        format!(
            "occlusion culling drops no block on this route ({:.3} ms per frame with it, {:.3} ms without; the difference is noise): leave it out (--occlusion off)",
            os * 1e3,
            fs * 1e3
        )
    } else if saves {
        format!(
            "occlusion culling pays on this route: {:.3} ms vs {:.3} ms per frame, {dropped:.1} blocks dropped per frame",
            os * 1e3,
            fs * 1e3
        )
    } else {
        format!(
            "occlusion culling saves nothing on this route: {:.3} ms per frame with it vs {:.3} ms without, though it drops {dropped:.1} blocks per frame: leave it out (--occlusion off)",
            os * 1e3,
            fs * 1e3
        )
    };
    Some(OcclusionDecision {
        frustum_s: fs,
        occlusion_s: os,
        blocks_dropped: dropped,
        saves,
        note,
    })
}
