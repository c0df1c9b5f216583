//! The walk (seed 003 §5.1): plays a camera route over a [`Scene`]. Per frame and per structure
//! and culling mode: cull → (far-field selection, with BlockMaps) → draw → check against the
//! oracle → one [`FrameRecord`]. It knows nothing of files or formats: `report` writes records.
//!
//! Seed 003 measured seconds per rendered frame in OpenGL Performer. Here a frame's time is the
//! culling time plus, when drawing, the time of drawing the blocks the structure kept (GPU time
//! from timestamp queries when the renderer has them, else wall time).

mod summary;

pub use summary::{summarise, SummaryRow};

use crate::blocks::BlockId;
use crate::geom::Camera;
use crate::index::{CityIndex, CullQuery, CullStats, Structure};
use crate::route::CameraRoute;
use crate::scene::Scene;
use crate::visibility::{
    CpuFrameRenderer, FrameRenderer, MeshOracle, OcclusionCulling, VisibilityOracle,
};
use serde::Serialize;
use std::collections::HashSet;
use std::time::Instant;

/// Whether occlusion culling runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
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

/// How one frame was culled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum CullMode {
    /// View-frustum culling.
    #[serde(rename = "frustum")]
    Frustum,
    /// View-frustum and occlusion culling.
    #[serde(rename = "frustum+occlusion")]
    FrustumOcclusion,
}

impl CullMode {
    /// The mode's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            CullMode::Frustum => "frustum",
            CullMode::FrustumOcclusion => "frustum+occlusion",
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
    /// Blocks kept.
    pub blocks: usize,
    /// Triangles of the kept blocks.
    pub triangles: u64,
    /// Oracle-visible blocks the structure dropped (must be 0), when checked.
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
    let cpu = CpuFrameRenderer::new(&scene.meshes, params.size).with_ground(&scene.ground);
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
    let oracle = MeshOracle::new(&scene.meshes);
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
    for (f, cam) in cameras.iter().enumerate() {
        let frustum = cam.frustum();
        let truth: Option<HashSet<BlockId>> = params
            .oracle
            .then(|| oracle.visible(cam, oracle_size.0, oracle_size.1));
        for index in &scene.indexes {
            let index: &dyn CityIndex = index.as_ref();
            for &mode in &modes {
                visible.clear();
                let t0 = Instant::now();
                let stats = match (mode, culler) {
                    (CullMode::FrustumOcclusion, Some(c)) => c.cull_frame(index, cam, &mut visible),
                    _ => index.cull(
                        &CullQuery::with_eye(&frustum, cam.position),
                        None,
                        &mut visible,
                    ),
                };
                let cull_s = t0.elapsed().as_secs_f64();
                let tri: u64 = visible
                    .iter()
                    .map(|b| triangles.get(b.0 as usize).copied().unwrap_or(0))
                    .sum();
                let want_image = params.image_every > 0
                    && f % params.image_every == 0
                    && index.structure() == reference
                    && mode == last_mode;
                let mut render_s = None;
                if let Some(r) = renderer {
                    match r.draw(cam, &visible, want_image) {
                        Ok(drawn) => {
                            render_s = Some(drawn.seconds);
                            if let Some(img) = drawn.image {
                                images.push((f, img));
                            }
                        }
                        Err(e) => notes.push(format!("frame {f}: drawing failed: {e}")),
                    }
                }
                let false_culls = truth.as_ref().map(|t| {
                    let kept: HashSet<BlockId> = visible.iter().copied().collect();
                    t.iter().filter(|b| !kept.contains(b)).count()
                });
                frames.push(FrameRecord {
                    frame: f,
                    structure: index.structure(),
                    mode,
                    cull_s,
                    render_s,
                    frame_s: cull_s + render_s.unwrap_or(0.0),
                    stats,
                    blocks: visible.len(),
                    triangles: tri,
                    false_culls,
                });
            }
        }
        progress(f + 1, cameras.len());
    }
    let summary = summarise(&frames, reference);
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
    })
}
