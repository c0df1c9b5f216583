//! A whole walk as one call, as `blockwalk walk` runs it: the scene's draw units for the
//! per-building test and the pages asked for, the route, the far field built and its exact
//! geometry for the silhouette bound, the renderer (GPU when there is one, else the CPU
//! fallback, said aloud), and the walk itself ([`run_job`]). Every parameter is checked here,
//! where the job is built ([`WalkJob::check`]).

use super::far::{BlockMapsOptions, BuildFar, FarField, FarMode, FarSetup};
use super::{run_walk_with_far, Drawing, OcclusionMode, WalkError, WalkParams, WalkRecord};
use crate::blockmap::{MapTree, SelectOptions};
use crate::index::SceneGraphParams;
use crate::relief::{ReliefField, ReliefOptions};
use crate::route::{CameraRoute, RouteChoice, RouteContext, RouteError};
use crate::scene::{BuildingsMode, Scene, SceneError};
use crate::visibility::FrameRenderer;

pub use crate::route::MAX_FRAMES;

/// Frames along a route when neither the job nor the route file says.
pub const DEFAULT_FRAMES: usize = 300;

/// Frames of the timing probe before the far field may be left out.
pub const PROBE_FRAMES: usize = 8;

/// What a walk is asked to do.
#[derive(Clone, Debug)]
pub struct WalkJob {
    /// The route.
    pub route: RouteChoice,
    /// Frames along it (none: the route file's setting, else [`DEFAULT_FRAMES`]).
    pub frames: Option<usize>,
    /// Occlusion culling.
    pub occlusion: OcclusionMode,
    /// The per-building test inside surviving blocks.
    pub buildings: BuildingsMode,
    /// The scene graph's pages (its leaf capacity), when the scene has the structure.
    pub pages: SceneGraphParams,
    /// Draw every frame.
    pub render: bool,
    /// Keep every k-th drawn frame as a picture (0: none).
    pub image_every: usize,
    /// Count false culls against the visibility oracle.
    pub oracle: bool,
    /// Image size of the frames and the oracle.
    pub size: (u32, u32),
    /// The far field, when one is drawn.
    pub far: Option<FarJob>,
}

impl Default for WalkJob {
    /// The paper's route, occlusion and per-building test both ways, nothing drawn, 1280×720.
    fn default() -> Self {
        Self {
            route: RouteChoice::Paper,
            frames: None,
            occlusion: OcclusionMode::Auto,
            buildings: BuildingsMode::Auto,
            pages: SceneGraphParams::default(),
            render: false,
            image_every: 30,
            oracle: false,
            size: (1280, 720),
            far: None,
        }
    }
}

/// The far field of a walk job.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarJob {
    /// The representation.
    pub mode: FarMode,
    /// How BlockMaps are built (the side K is `maps.build.k`).
    pub maps: BlockMapsOptions,
    /// How relief impostors are built.
    pub relief: ReliefOptions,
    /// τ and hysteresis.
    pub select: SelectOptions,
    /// Compare every hybrid frame with the mesh-only frame (needs drawing), with the silhouette
    /// bound checked on the scene's exact prisms.
    pub reference: bool,
    /// Draw the far field even where the scene does not need it.
    pub keep: bool,
}

/// Why a walk job cannot run.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// A parameter is out of range.
    #[error("{0}")]
    Parameter(String),
    /// The route cannot be made or read.
    #[error("making the {route} route over {city}")]
    Route {
        /// The route asked for.
        route: String,
        /// City name.
        city: String,
        /// What went wrong.
        #[source]
        source: Box<RouteError>,
    },
    /// The draw units cannot be built.
    #[error(transparent)]
    Units(#[from] SceneError),
    /// The far field cannot be built.
    #[error("building the {what} of {city}")]
    Far {
        /// What was being built.
        what: &'static str,
        /// City name.
        city: String,
        /// What went wrong.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The walk failed.
    #[error(transparent)]
    Walk(#[from] WalkError),
    /// The culling check over routes could not be set up.
    #[error("checking the culling over routes of {city}")]
    Proof {
        /// City name.
        city: String,
        /// What went wrong.
        #[source]
        source: crate::visibility::VisibilityError,
    },
}

impl WalkJob {
    /// Checks the parameters that do not depend on the scene: frames in `1..=MAX_FRAMES`, an
    /// image with pixels, a reference only with drawing, τ and the hysteresis in range.
    ///
    /// # Errors
    /// [`JobError::Parameter`] naming the parameter.
    pub fn check(&self) -> Result<(), JobError> {
        if let Some(f) = self.frames {
            if !(1..=MAX_FRAMES).contains(&f) {
                return Err(JobError::Parameter(format!(
                    "{}: {f} frames; expected 1..={MAX_FRAMES}",
                    self.route
                )));
            }
        }
        if self.size.0 == 0 || self.size.1 == 0 {
            return Err(JobError::Parameter(format!(
                "image size {}x{}: both sides must be at least 1 pixel",
                self.size.0, self.size.1
            )));
        }
        if let Some(f) = &self.far {
            if f.reference && !self.render {
                return Err(JobError::Parameter(
                    "the reference compares drawn frames: drawing must be on".into(),
                ));
            }
            check_select(&f.select)?;
            f.maps
                .build
                .validate()
                .map_err(|e| JobError::Parameter(e.to_string()))?;
            f.relief
                .validate()
                .map_err(|e| JobError::Parameter(e.to_string()))?;
        }
        Ok(())
    }
}

/// τ a positive number of pixels, the hysteresis in `[0, 1)` ([`SelectOptions::new`]'s rule).
fn check_select(s: &SelectOptions) -> Result<(), JobError> {
    SelectOptions::new(s.tau_px, s.hysteresis)
        .map(|_| ())
        .map_err(|e| JobError::Parameter(e.to_string()))
}

/// Who can draw on a GPU: the `render` module's renderers, or none.
pub trait GpuRenderers {
    /// A renderer of `scene`'s draw meshes and ground at `size`, drawing the far field `far`
    /// when given, or why there is none.
    ///
    /// # Errors
    /// Why no GPU renderer can be made (no adapter, not built with `render`, …).
    fn renderer<'a>(
        &self,
        scene: &'a Scene,
        size: (u32, u32),
        far: Option<&'a dyn FarField>,
    ) -> Result<Box<dyn FrameRenderer + 'a>, String>;
}

/// No GPU: every drawn walk falls back to the CPU renderers, for the reason given.
#[derive(Clone, Copy, Debug)]
pub struct NoGpu(pub &'static str);

impl GpuRenderers for NoGpu {
    fn renderer<'a>(
        &self,
        _scene: &'a Scene,
        _size: (u32, u32),
        _far: Option<&'a dyn FarField>,
    ) -> Result<Box<dyn FrameRenderer + 'a>, String> {
        Err(self.0.to_string())
    }
}

/// What a long job reports while it runs.
pub trait JobProgress: Sync {
    /// A stage starts ("building the BlockMaps of …").
    fn stage(&self, _what: &str) {}
    /// `done` of `total` items of the current stage (maps, frames).
    fn count(&self, _done: usize, _total: usize) {}
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet;

impl JobProgress for Quiet {}

/// The route context of `scene` for an image of aspect `aspect`.
pub fn route_context(scene: &Scene, aspect: f64) -> RouteContext<'_> {
    RouteContext {
        city: &scene.name,
        bounds: scene.city_bounds(),
        street_edges: &scene.layout.street_edges,
        buildings: &scene.city.buildings,
        frame: &scene.city.frame,
        aspect,
        terrain: scene.city.terrain.as_ref(),
    }
}

/// The route `choice` over `scene` for an image of aspect `aspect`, and the frames a route
/// file asks for.
///
/// # Errors
/// [`JobError::Route`].
pub fn resolve_route(
    choice: &RouteChoice,
    scene: &Scene,
    aspect: f64,
) -> Result<(CameraRoute, Option<usize>), JobError> {
    choice
        .resolve(&route_context(scene, aspect))
        .map_err(|source| JobError::Route {
            route: choice.to_string(),
            city: scene.name.clone(),
            source: Box::new(source),
        })
}

/// The far field `mode` of `scene` built with `maps` (BlockMaps) or `relief` (relief
/// impostors); none for [`FarMode::None`].
///
/// # Errors
/// [`JobError::Far`] naming the city.
pub fn build_far(
    scene: &Scene,
    mode: FarMode,
    maps: &BlockMapsOptions,
    relief: &ReliefOptions,
    progress: &dyn JobProgress,
) -> Result<Option<Box<dyn FarField + Send>>, JobError> {
    let count = |done, total| progress.count(done, total);
    match mode {
        FarMode::None => Ok(None),
        FarMode::Blockmaps => {
            progress.stage(&format!(
                "building the BlockMaps of {} (K = {})",
                scene.name, maps.build.k
            ));
            let built = MapTree::build(scene, maps, &count).map_err(|e| JobError::Far {
                what: "BlockMaps",
                city: scene.name.clone(),
                source: Box::new(e),
            })?;
            Ok(Some(Box::new(built)))
        }
        FarMode::Relief => {
            progress.stage(&format!(
                "building the relief impostors of {} (texel {} m)",
                scene.name, relief.texel_m
            ));
            let built = ReliefField::build(scene, relief, &count).map_err(|e| JobError::Far {
                what: "relief impostors",
                city: scene.name.clone(),
                source: Box::new(e),
            })?;
            Ok(Some(Box::new(built)))
        }
    }
}

/// Runs `job` over `scene`: sets up its draw units, resolves the route, builds the far field,
/// picks the renderer (`gpu`, else the CPU fallback, said in the notes) and walks.
///
/// # Errors
/// [`JobError`]: a bad parameter, route, draw units, far field or walk.
pub fn run_job(
    scene: &mut Scene,
    job: &WalkJob,
    gpu: &dyn GpuRenderers,
    progress: &dyn JobProgress,
) -> Result<WalkRecord, JobError> {
    job.check()?;
    scene.set_pages(&job.pages, job.buildings)?;
    let scene = &*scene;
    let aspect = job.size.0 as f64 / job.size.1 as f64;
    let (route, file_frames) = resolve_route(&job.route, scene, aspect)?;
    let frames = crate::route::check_frames(
        &job.route.to_string(),
        job.frames.or(file_frames).unwrap_or(DEFAULT_FRAMES),
    )
    .map_err(|e| JobError::Parameter(e.to_string()))?;
    let params = WalkParams {
        route,
        frames,
        occlusion: job.occlusion,
        image_every: if job.render { job.image_every } else { 0 },
        oracle: job.oracle,
        size: job.size,
    };
    let far_job = job.far.filter(|f| f.mode != FarMode::None);
    let field = match &far_job {
        Some(f) => build_far(scene, f.mode, &f.maps, &f.relief, progress)?,
        None => None,
    };
    let field_ref: Option<&dyn FarField> = field.as_deref().map(|f| f as &dyn FarField);
    // The exact prisms the silhouette bound is checked with (only with the reference).
    let source = match (&far_job, field_ref) {
        (Some(f), Some(_)) if f.reference => {
            Some(scene.exact_prisms().map_err(|e| JobError::Far {
                what: "exact prisms",
                city: scene.name.clone(),
                source: Box::new(e),
            })?)
        }
        _ => None,
    };
    let far = match (&far_job, field_ref) {
        (Some(f), Some(field)) => Some(FarSetup {
            field,
            select: f.select,
            reference: f.reference,
            leave_out: !f.keep,
            probe_frames: PROBE_FRAMES,
            source: source.as_ref(),
        }),
        _ => None,
    };
    let renderer = job.render.then(|| gpu.renderer(scene, job.size, field_ref));
    let drawing = match &renderer {
        None => Drawing::Off,
        Some(Ok(r)) => Drawing::With(r.as_ref()),
        Some(Err(reason)) => Drawing::CpuFallback {
            reason: reason.clone(),
        },
    };
    progress.stage(&format!("walk {}", params.route.name));
    Ok(run_walk_with_far(
        scene,
        &params,
        drawing,
        far,
        &mut |done, total| progress.count(done, total),
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_parameters_are_refused_with_their_name() {
        let far = FarJob {
            mode: FarMode::Blockmaps,
            maps: BlockMapsOptions::default(),
            relief: ReliefOptions::default(),
            select: SelectOptions::default(),
            reference: false,
            keep: false,
        };
        let ok = WalkJob {
            far: Some(far),
            ..WalkJob::default()
        };
        assert!(ok.check().is_ok());
        let cases = [
            (
                WalkJob {
                    frames: Some(0),
                    ..ok.clone()
                },
                "frames",
            ),
            (
                WalkJob {
                    frames: Some(MAX_FRAMES + 1),
                    ..ok.clone()
                },
                "frames",
            ),
            (
                WalkJob {
                    size: (0, 10),
                    ..ok.clone()
                },
                "image size",
            ),
        ];
        for (job, word) in cases {
            let e = job.check().unwrap_err().to_string();
            assert!(e.contains(word), "{e}");
        }
        for (tau, h, word) in [
            (f64::NAN, 0.25, "tau"),
            (-1.0, 0.25, "tau"),
            (0.0, 0.25, "tau"),
            (f64::INFINITY, 0.25, "tau"),
            (1.0, -0.1, "hysteresis"),
            (1.0, 1.0, "hysteresis"),
            (1.0, f64::NAN, "hysteresis"),
        ] {
            let job = WalkJob {
                far: Some(FarJob {
                    select: SelectOptions {
                        tau_px: tau,
                        hysteresis: h,
                    },
                    ..far
                }),
                ..ok.clone()
            };
            let e = job.check().unwrap_err().to_string();
            assert!(e.contains(word), "τ {tau}, h {h}: {e}");
        }
        let job = WalkJob {
            far: Some(FarJob {
                reference: true,
                ..far
            }),
            render: false,
            ..ok.clone()
        };
        assert!(job.check().unwrap_err().to_string().contains("drawing"));
    }

    #[test]
    fn a_synthetic_walk_runs_in_one_call() {
        let source = crate::scene::CitySource::parse(
            std::path::Path::new("synthetic:3x3"),
            None,
            None,
            &[],
            2,
        )
        .unwrap();
        let opts = crate::scene::SceneOptions {
            occlusion: Some(Default::default()),
            ..Default::default()
        };
        let mut scene = Scene::load(&source, &opts, &mut |_| {}).unwrap();
        let job = WalkJob {
            route: RouteChoice::Orbit,
            frames: Some(4),
            render: true,
            size: (64, 36),
            far: Some(FarJob {
                mode: FarMode::Blockmaps,
                maps: BlockMapsOptions::default(),
                relief: ReliefOptions::default(),
                select: SelectOptions {
                    tau_px: 8.0,
                    ..SelectOptions::default()
                },
                reference: true,
                keep: true,
            }),
            ..WalkJob::default()
        };
        let rec = run_job(&mut scene, &job, &NoGpu("test"), &Quiet).unwrap();
        assert_eq!(rec.cameras.len(), 4);
        assert!(rec.renderer.starts_with("CPU fallback (test)"));
        let far = rec.far_summary().expect("a far field was given");
        assert_eq!(far.frames, 4, "a hybrid frame per frame in the last mode");
        assert!(far.silhouette_ratio_max.is_some(), "bound checked: {far:?}");
    }
}
