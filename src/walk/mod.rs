//! The walk (seed 003 §5.1): plays a camera route over a [`Scene`]. Per frame and per structure
//! and culling mode: cull → (far-field selection, with BlockMaps) → draw → check against the
//! oracle → one [`FrameRecord`]. It knows nothing of files or formats: `report` writes records.
//!
//! Seed 003 measured seconds per rendered frame in OpenGL Performer. Here a frame's time is the
//! culling time plus, when drawing, the time of drawing the blocks the structure kept (GPU time
//! from timestamp queries when the renderer has them, else wall time).

pub mod bound;
mod decide;
pub mod far;
mod hybrid;
pub mod job;
pub mod proof;
pub mod step;
mod summary;
pub mod sweep;
pub mod terrain;

pub use bound::{BoundFigures, BoundGeometry, FrameBound};
pub use far::{
    changed_pixels, coverage, image_error, image_error_with_bound, BlockMapsOptions, BuildFar,
    FarBuildSummary, FarDecision, FarField, FarGpu, FarMode, FarRecord, FarSetup, FarSummary,
    ImageError, OcclusionDecision, PixelBound, SilhouetteBound,
};
pub use job::{run_job, FarJob, GpuRenderers, JobError, JobProgress, NoGpu, Quiet, WalkJob};
pub use proof::{run_route_proof, RouteProofJob, RouteProofReport};
pub use step::{CullStep, Culled, FarPick, FarStep};
pub use summary::{summarise, SummaryRow};

use hybrid::{Hybrid, MeshFrame};

use crate::blocks::BlockId;
use crate::geom::Camera;
use crate::index::{CityIndex, CullStats, Structure};
use crate::route::CameraRoute;
use crate::scene::{BuildingsMode, DrawUnits, Scene, Unit};
use crate::visibility::{CpuFrameRenderer, FrameRenderer, MeshOracle, VisibilityOracle};
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

    /// The far field's figures over the walk, when a far field was given.
    pub fn far_summary(&self) -> Option<FarSummary> {
        match (&self.far_decision, &self.far_options) {
            (Some(d), Some(o)) => Some(FarSummary::new(&self.far, d, o)),
            _ => None,
        }
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

/// As [`run_walk`], with a far field: for every frame and culling mode, the reference
/// structure's frame is also drawn as a hybrid frame, near meshes plus far nodes chosen by
/// [`crate::blockmap::Selector`] (the renderer of `drawing` must have been built with
/// `far.field`; the CPU fallback uses the far field's CPU renderer), recorded in
/// [`WalkRecord::far`]. With [`FarSetup::leave_out`] the far field is left out when no node qualifies along the route or
/// when hybrid frames, timed on the GPU, are no faster than mesh-only ones over the first
/// frames; [`WalkRecord::far_decision`] says which.
///
/// # Errors
/// As [`run_walk`]; a far field whose maps do not fit the scene's blocks.
pub fn run_walk_with_far(
    scene: &Scene,
    params: &WalkParams,
    drawing: Drawing<'_>,
    far: Option<FarSetup<'_>>,
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
    let modes = cull_modes(scene, params.occlusion, &mut notes)?;
    let cameras = params.route.sample(params.frames);
    let mut cpu =
        CpuFrameRenderer::new(scene.draw_meshes(), params.size).with_ground(&scene.ground);
    if let Some(t) = scene.terrain_draw() {
        // The terrain's cut replaces the flat ground (visibility::draws_flat_ground).
        cpu = cpu.with_terrain(t);
    }
    let (renderer, renderer_desc) = pick_renderer(&drawing, &cpu, &mut notes);
    // The far field's hybrid renderer: the walk's own, or the far field's CPU reference for the
    // CPU fallback.
    let cpu_far = match (&far, &drawing) {
        (Some(f), Drawing::CpuFallback { .. }) => Some(f.field.cpu_renderer(
            scene.block_meshes(),
            &scene.ground,
            scene.terrain_draw(),
            params.size,
        )),
        _ => None,
    };
    let hybrid_renderer: Option<&dyn FrameRenderer> = match (&drawing, &cpu_far) {
        (Drawing::With(r), _) => Some(*r),
        (_, Some(r)) => Some(r.as_ref()),
        _ => None,
    };
    // The oracle judges the frames at their own resolution (the renderer's, when one draws).
    let size = renderer.map_or(params.size, |r| r.size());
    let mut hybrid = match far {
        Some(f) => Some(Hybrid::new(
            scene,
            f,
            &modes,
            &cameras,
            hybrid_renderer,
            size.1,
            &mut notes,
        )?),
        None => None,
    };
    let oracle = Oracles::new(scene, params.oracle.then_some(size), &mut notes);
    let mut walker = Walker {
        scene,
        params,
        modes: &modes,
        reference: reference_structure(scene),
        renderer,
        step: CullStep::new(scene),
        frames: Vec::with_capacity(cameras.len() * scene.indexes.len() * modes.len()),
        images: Vec::new(),
    };
    for (f, cam) in cameras.iter().enumerate() {
        walker.frame(f, cam, &oracle, hybrid.as_mut(), &mut notes);
        progress(f + 1, cameras.len());
        if let Some(h) = hybrid.as_mut() {
            h.probe(f, cameras.len(), &mut notes);
        }
    }
    let (far_records, far_decision, far_options) = match hybrid {
        Some(h) => {
            let (r, d, o) = h.finish(&mut notes);
            (r, Some(d), Some(o))
        }
        None => (Vec::new(), None, None),
    };
    let Walker {
        frames,
        images,
        reference,
        ..
    } = walker;
    let summary = summarise(&frames, reference);
    let occlusion_decision = decide::occlusion_decision(&frames, reference);
    if let Some(d) = &occlusion_decision {
        notes.push(d.note.clone());
    }
    let buildings_decision = decide::buildings_decisions(&frames, reference);
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
        far_options,
        occlusion_decision,
        buildings_decision,
    })
}

/// The culling modes of a walk with occlusion setting `occlusion` over `scene`.
fn cull_modes(
    scene: &Scene,
    occlusion: OcclusionMode,
    notes: &mut Vec<String>,
) -> Result<Vec<CullMode>, WalkError> {
    Ok(match (occlusion, scene.occlusion.is_some()) {
        (OcclusionMode::Off, _) => vec![CullMode::Frustum],
        (OcclusionMode::On, true) => vec![CullMode::FrustumOcclusion],
        (OcclusionMode::On, false) => return Err(WalkError::NoOcclusion(scene.name.clone())),
        (OcclusionMode::Auto, true) => vec![CullMode::Frustum, CullMode::FrustumOcclusion],
        (OcclusionMode::Auto, false) => {
            notes.push("no occlusion culler in the scene: frustum culling only".into());
            vec![CullMode::Frustum]
        }
    })
}

/// Who draws the mesh frames (the CPU renderer `cpu` for the fallback), and how the report
/// describes it.
fn pick_renderer<'r>(
    drawing: &Drawing<'r>,
    cpu: &'r CpuFrameRenderer<'r>,
    notes: &mut Vec<String>,
) -> (Option<&'r dyn FrameRenderer>, String) {
    match drawing {
        Drawing::Off => (None, "none (drawing not asked for)".to_string()),
        Drawing::With(r) => (Some(*r), r.describe()),
        Drawing::CpuFallback { reason } => {
            notes.push(format!(
                "GPU rendering unavailable ({reason}); draw times are CPU times and not comparable with GPU numbers"
            ));
            (
                Some(cpu as &dyn FrameRenderer),
                format!("CPU fallback ({reason}): {}", cpu.describe()),
            )
        }
    }
}

/// The visibility oracles of a walk: blocks, and buildings when the scene has draw units.
struct Oracles<'s> {
    scene: &'s Scene,
    /// The image size the oracle judges at, when false culls are counted.
    size: Option<(u32, u32)>,
    blocks: MeshOracle<'s>,
    buildings: Option<MeshOracle<'s>>,
}

impl<'s> Oracles<'s> {
    fn new(scene: &'s Scene, size: Option<(u32, u32)>, notes: &mut Vec<String>) -> Self {
        // The terrain, at full resolution, occludes in both oracles.
        let terrain = scene.terrain.as_ref().map(|t| t.full());
        let with_terrain = |o: MeshOracle<'s>| match terrain {
            Some(t) => o.with_terrain(t),
            None => o,
        };
        let blocks = with_terrain(MeshOracle::new(scene.block_meshes()));
        if let Some((w, h)) = size {
            notes.push(format!(
                "false culls counted against the {}",
                blocks.describe(w, h)
            ));
        }
        Self {
            scene,
            size,
            blocks,
            buildings: scene
                .units
                .as_ref()
                .map(|u| with_terrain(MeshOracle::new(u.building_meshes()))),
        }
    }

    /// What the oracles see from `camera`: blocks, and buildings (as unit ids).
    fn truth(&self, camera: &Camera) -> Truth {
        let Some((w, h)) = self.size else {
            return Truth::default();
        };
        Truth {
            blocks: Some(self.blocks.visible(camera, w, h)),
            buildings: self.buildings.as_ref().map(|o| o.visible(camera, w, h)),
        }
    }

    /// Oracle-visible units that `draw_ids` (drawn as `pages` or `buildings`) left out.
    fn false_culls(
        &self,
        truth: &Truth,
        draw_ids: &[BlockId],
        pages: bool,
        buildings: bool,
    ) -> Option<usize> {
        match (self.scene.units.as_ref(), buildings || pages) {
            // Building level: the oracle's buildings against the buildings drawn.
            (Some(u), true) => truth.buildings.as_ref().map(|t| {
                let kept: HashSet<BlockId> = if pages {
                    draw_ids
                        .iter()
                        .flat_map(|&d| u.buildings_of(d, &self.scene.layout))
                        .map(|b| u.id(Unit::Building(b)))
                        .collect()
                } else {
                    draw_ids.iter().copied().collect()
                };
                t.iter().filter(|b| !kept.contains(b)).count()
            }),
            _ => truth.blocks.as_ref().map(|t| {
                let kept: HashSet<BlockId> = draw_ids.iter().copied().collect();
                t.iter().filter(|b| !kept.contains(b)).count()
            }),
        }
    }
}

/// What the oracles saw in one frame.
#[derive(Default)]
struct Truth {
    blocks: Option<HashSet<BlockId>>,
    buildings: Option<HashSet<BlockId>>,
}

/// The walk's per-frame state: the cull, who draws, and what was recorded.
struct Walker<'w> {
    scene: &'w Scene,
    params: &'w WalkParams,
    modes: &'w [CullMode],
    /// The structure ratios, images and the far field refer to.
    reference: Structure,
    renderer: Option<&'w dyn FrameRenderer>,
    step: CullStep,
    frames: Vec<FrameRecord>,
    images: Vec<(usize, image::RgbaImage)>,
}

impl Walker<'_> {
    /// Frame `f` from `cam`: every structure in every mode culled, drawn, checked and recorded,
    /// and the reference structure's hybrid frames.
    fn frame(
        &mut self,
        f: usize,
        cam: &Camera,
        oracle: &Oracles<'_>,
        mut hybrid: Option<&mut Hybrid<'_>>,
        notes: &mut Vec<String>,
    ) {
        let truth = oracle.truth(cam);
        let last_mode = *self.modes.last().expect("at least one mode");
        for index in &self.scene.indexes {
            let index: &dyn CityIndex = index.as_ref();
            let pages = index.structure() == Structure::SceneGraph;
            for mode in index_modes(self.modes, self.scene.units.as_ref(), pages) {
                let culled = self.step.cull(self.scene, index, mode, cam);
                let is_reference = index.structure() == self.reference;
                let keep_image = self.params.image_every > 0
                    && f.is_multiple_of(self.params.image_every)
                    && is_reference
                    && mode == last_mode;
                let far_here = is_reference
                    && !mode.buildings()
                    && hybrid.as_ref().is_some_and(|h| h.active());
                let want_reference = far_here && hybrid.as_ref().is_some_and(|h| h.reference());
                let mut render_s = None;
                let mut mesh_image = None;
                if let Some(r) = self.renderer {
                    match r.draw(cam, self.step.draw_ids(), keep_image || want_reference) {
                        Ok(drawn) => {
                            render_s = Some(drawn.seconds);
                            if let Some(img) = drawn.image {
                                if keep_image {
                                    self.images.push((f, img.clone()));
                                }
                                mesh_image = Some(img);
                            }
                        }
                        Err(e) => notes.push(format!("frame {f}: drawing failed: {e}")),
                    }
                }
                if let Some(h) = hybrid.as_deref_mut().filter(|_| far_here) {
                    let step = &self.step;
                    h.frame(
                        self.scene,
                        MeshFrame {
                            frame: f,
                            mode,
                            camera: cam,
                            image: mesh_image.as_ref().filter(|_| want_reference),
                            seconds: culled.seconds + render_s.unwrap_or(0.0),
                            triangles: &|b| step.block_triangles(b),
                        },
                        notes,
                    );
                }
                let false_culls = oracle.false_culls(
                    &truth,
                    self.step.draw_ids(),
                    pages,
                    culled.buildings.is_some(),
                );
                self.frames.push(FrameRecord {
                    frame: f,
                    structure: index.structure(),
                    mode,
                    cull_s: culled.seconds,
                    render_s,
                    frame_s: culled.seconds + render_s.unwrap_or(0.0),
                    stats: culled.stats,
                    blocks: culled.blocks,
                    buildings: culled.buildings,
                    triangles: culled.triangles,
                    draws: culled.draws,
                    false_culls,
                });
            }
        }
    }
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
