//! The far field's error against its run time, over a grid of settings: for every far-field
//! representation (BlockMaps at every height-map side K, relief impostors), route and threshold
//! τ, a hybrid walk compared with the mesh-only frames (coverage error, PSNR, silhouette
//! distance against the bound on the exact prisms, popping) and the frame times of both
//! ([`run_sweep`]), with what each representation costs to build and to hold. One row per configuration ([`SweepRow`]), the walk record
//! of one configuration per route, and, when asked, the classification of the mismatched pixels
//! of each configuration's worst frames ([`blockmap::diagnose`](crate::blockmap::diagnose)).
//! The Pareto front of error against time is [`pareto`]. It writes nothing: `report::sweep`
//! writes the tables, plots and reports.

use super::far::{
    BlockMapsOptions, BuildFar, FarDecision, FarField, FarMode, FarSetup, FarSummary,
};
use super::job::{resolve_route, GpuRenderers, JobError, JobProgress};
use super::{run_walk_with_far, Drawing, OcclusionMode, WalkError, WalkParams, WalkRecord};
use crate::blockmap::diagnose::{diagnose_frame, FrameDiagnosis, FrameInput};
use crate::blockmap::{BuildOptions, MapTree, SelectError, SelectOptions, Selector, Source};
use crate::relief::{ReliefField, ReliefOptions};
use crate::route::{
    flyover_route_with_near, CameraRoute, RouteChoice, FLYOVER_NEAR_SHARE, MAX_FRAMES,
};
use crate::scene::Scene;
use serde::Serialize;
use std::time::Instant;

/// What a sweep runs: every representation (BlockMaps at every K) × route × τ.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepOptions {
    /// The far-field representations, side by side on the same routes, τ and image size.
    pub fars: Vec<FarMode>,
    /// Error thresholds τ, pixels.
    pub taus: Vec<f64>,
    /// BlockMaps' height-map sides K.
    pub ks: Vec<u32>,
    /// How relief impostors are built.
    pub relief: ReliefOptions,
    /// Routes.
    pub routes: Vec<RouteChoice>,
    /// Frames per route.
    pub frames: usize,
    /// Image size, pixels.
    pub size: (u32, u32),
    /// Half-planes per texel the maps store: 0 (whole texels), 1 (one footprint edge) or 2 (a
    /// second where it fits the footprint more closely).
    pub edges: u8,
    /// The fly-over's near plane as a share of its height above the highest roof (0: the
    /// lens's default).
    pub flyover_near_share: f64,
    /// Classify the coverage-mismatched pixels of each configuration's worst frames by cause.
    pub diagnose: bool,
}

impl Default for SweepOptions {
    /// τ from 0.5 to 16 pixels, K of 32, 64 and 128, the paper's route, the orbit and the
    /// fly-over, 12 frames of 160×90, two edges per texel, no diagnosis.
    fn default() -> Self {
        Self {
            fars: vec![FarMode::Blockmaps],
            taus: vec![0.5, 1.0, 2.0, 4.0, 8.0, 16.0],
            ks: vec![32, 64, 128],
            relief: ReliefOptions::default(),
            routes: vec![RouteChoice::Paper, RouteChoice::Orbit, RouteChoice::Flyover],
            frames: 12,
            size: (160, 90),
            edges: 2,
            flyover_near_share: FLYOVER_NEAR_SHARE,
            diagnose: false,
        }
    }
}

/// Why a sweep cannot run.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A parameter is out of range.
    #[error("{0}")]
    Parameter(String),
    /// A route, the maps or the exact prisms cannot be made.
    #[error(transparent)]
    Job(#[from] JobError),
    /// A walk failed.
    #[error(transparent)]
    Walk(#[from] WalkError),
    /// The selection replayed for the diagnosis failed.
    #[error("replaying the selection for the diagnosis")]
    Diagnose(#[source] SelectError),
}

impl SweepOptions {
    /// The maps' construction settings at side `k`.
    pub fn build(&self, k: u32) -> BuildOptions {
        BuildOptions {
            k,
            edges: self.edges > 0,
            two_edges: self.edges > 1,
            ..Default::default()
        }
    }

    /// Checks the parameters: no empty list, representations that are far fields (not
    /// `none`), each once, every τ a positive finite number of pixels ([`SelectOptions::new`]),
    /// every K one the maps can be built with ([`BuildOptions::validate`]), the relief
    /// impostors' settings ([`ReliefOptions::validate`]), frames in `1..=MAX_FRAMES`, an image
    /// with pixels, edges in `0..=2`.
    ///
    /// # Errors
    /// [`SweepError::Parameter`] naming the parameter.
    pub fn check(&self) -> Result<(), SweepError> {
        let bad = |m: String| Err(SweepError::Parameter(m));
        for (name, empty) in [
            ("fars", self.fars.is_empty()),
            ("taus", self.taus.is_empty()),
            ("ks", self.ks.is_empty()),
            ("routes", self.routes.is_empty()),
        ] {
            if empty {
                return bad(format!("{name}: the list is empty"));
            }
        }
        for (i, f) in self.fars.iter().enumerate() {
            if *f == FarMode::None {
                return bad(
                    "fars: `none` is not a far field (mesh-only frames are in every row)".into(),
                );
            }
            if self.fars[..i].contains(f) {
                return bad(format!("fars: {f} is listed twice"));
            }
        }
        self.relief
            .validate()
            .map_err(|e| SweepError::Parameter(e.to_string()))?;
        for &tau in &self.taus {
            SelectOptions::new(tau, SelectOptions::default().hysteresis)
                .map_err(|e| SweepError::Parameter(e.to_string()))?;
        }
        for &k in &self.ks {
            self.build(k)
                .validate()
                .map_err(|e| SweepError::Parameter(e.to_string()))?;
        }
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return bad(format!("{} frames; expected 1..={MAX_FRAMES}", self.frames));
        }
        if self.size.0 == 0 || self.size.1 == 0 {
            return bad(format!(
                "image size {}x{}: both sides must be at least 1 pixel",
                self.size.0, self.size.1
            ));
        }
        if self.edges > 2 {
            return bad(format!("edges {}: expected 0, 1 or 2", self.edges));
        }
        Ok(())
    }
}

/// One configuration's figures (those of [`FarSummary`], times in milliseconds).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepRow {
    /// City name.
    pub city: String,
    /// Route name.
    pub route: String,
    /// The far-field representation.
    pub far: FarMode,
    /// Map side: the BlockMaps' height-map side K, the relief impostors' M.
    pub k: u32,
    /// Error threshold, pixels.
    pub tau_px: f64,
    /// Nodes with maps in the representation.
    pub maps: usize,
    /// Frames walked.
    pub frames: usize,
    /// Mean far nodes drawn per frame.
    pub far_nodes: f64,
    /// Mean mesh triangles per hybrid frame.
    pub mesh_triangles: f64,
    /// Largest share of pixels whose coverage differs from the mesh-only frame.
    pub coverage_error_max: Option<f64>,
    /// Mean of that share.
    pub coverage_error_mean: Option<f64>,
    /// Smallest colour PSNR, dB.
    pub psnr_min: Option<f64>,
    /// Largest raw silhouette distance of a mismatched pixel, pixels.
    pub silhouette_px_max: Option<f64>,
    /// Largest distance over allowed distance after the second look (≤ 1: the bound holds).
    pub silhouette_ratio_max: Option<f64>,
    /// Pixels beyond the bound after the second look, summed over the frames.
    pub silhouette_bound_violations: Option<u64>,
    /// Pixels beyond the bound at pixel spacing settled as sub-pixel features.
    pub silhouette_subpixel: Option<u64>,
    /// Pixels of buildings the maps declare thin or dropped, within the bound of their own
    /// mesh silhouette.
    pub silhouette_thin: Option<u64>,
    /// Largest count of pixels whose coverage changed with the selection.
    pub popping_px_max: Option<f64>,
    /// Mean hybrid frame time, ms.
    pub hybrid_ms: Option<f64>,
    /// Mean mesh-only frame time over the same frames, ms.
    pub mesh_ms: Option<f64>,
    /// `hybrid_ms / mesh_ms`.
    pub frame_time_ratio_vs_mesh: Option<f64>,
}

/// One far field built: a representation at one map side.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SweepBuild {
    /// The representation.
    pub far: FarMode,
    /// Map side (K of BlockMaps, M of relief impostors).
    pub k: u32,
    /// Nodes with maps.
    pub maps: usize,
    /// Bytes of all maps.
    pub bytes: u64,
    /// Bytes per km² of the city's box.
    pub bytes_per_km2: f64,
    /// Wall time of the build, seconds.
    pub seconds: f64,
}

/// The walk of one configuration of a route, kept whole for its walk report: τ = 1 at K = 64
/// when swept, else the first τ and K.
#[derive(Debug)]
pub struct SweepWalk {
    /// Route name.
    pub route: String,
    /// The representation.
    pub far: FarMode,
    /// Map side.
    pub k: u32,
    /// Error threshold, pixels.
    pub tau_px: f64,
    /// The walk (its far records hold the hybrid and mesh-only frame times along the route).
    pub record: WalkRecord,
}

/// One diagnosed frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiagnosedFrame {
    /// Frame number along the route.
    pub frame: usize,
    /// Its mismatched pixels by cause.
    pub diagnosis: FrameDiagnosis,
}

/// The diagnosis of one configuration: its frames with the largest coverage error and the
/// largest silhouette distance.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepDiagnosis {
    /// Route name.
    pub route: String,
    /// Height-map side.
    pub k: u32,
    /// Error threshold, pixels.
    pub tau_px: f64,
    /// The frames, in route order.
    pub frames: Vec<DiagnosedFrame>,
}

/// What a sweep measured.
#[derive(Debug)]
pub struct Sweep {
    /// City name.
    pub city: String,
    /// Image size, pixels.
    pub size: (u32, u32),
    /// Frames per route.
    pub frames: usize,
    /// The maps built, one per K.
    pub builds: Vec<SweepBuild>,
    /// One row per configuration, K-major, then route, then τ.
    pub rows: Vec<SweepRow>,
    /// The walk of one configuration per route.
    pub walks: Vec<SweepWalk>,
    /// The diagnoses, when asked for, in the order of the rows.
    pub diagnoses: Vec<SweepDiagnosis>,
    /// Notes for the reader (fallbacks).
    pub notes: Vec<String>,
}

/// The route `choice` over `scene`: the fly-over with its near plane at `near_share`, the others
/// as [`resolve_route`] makes them.
fn route_of(
    choice: &RouteChoice,
    scene: &Scene,
    aspect: f64,
    near_share: f64,
) -> Result<CameraRoute, JobError> {
    if *choice == RouteChoice::Flyover {
        return flyover_route_with_near(scene.city_bounds(), aspect, near_share).map_err(|e| {
            JobError::Route {
                route: choice.to_string(),
                city: scene.name.clone(),
                source: Box::new(e),
            }
        });
    }
    Ok(resolve_route(choice, scene, aspect)?.0)
}

/// Runs the sweep `opts` over `scene`: builds the maps at every K, walks every route at every
/// τ with the reference and the silhouette bound checked on the scene's exact prisms, drawing
/// with `gpu` when it has a renderer (else the CPU hybrid renderer, said in the notes).
///
/// # Errors
/// [`SweepError`]: a bad parameter, route, build, walk or diagnosis.
pub fn run_sweep(
    scene: &Scene,
    opts: &SweepOptions,
    gpu: &dyn GpuRenderers,
    progress: &dyn JobProgress,
) -> Result<Sweep, SweepError> {
    opts.check()?;
    let aspect = opts.size.0 as f64 / opts.size.1 as f64;
    let routes: Vec<(String, CameraRoute)> = opts
        .routes
        .iter()
        .map(|r| {
            Ok((
                r.to_string(),
                route_of(r, scene, aspect, opts.flyover_near_share)?,
            ))
        })
        .collect::<Result<_, JobError>>()?;
    // The exact prisms: the walk checks the silhouette bound with them, and the diagnosis
    // classifies pixels with them.
    let source = scene.exact_prisms().map_err(|e| JobError::Far {
        what: "exact prisms",
        city: scene.name.clone(),
        source: Box::new(e),
    })?;
    let show_k = if opts.ks.contains(&64) {
        64
    } else {
        opts.ks[0]
    };
    let show_t = if opts.taus.contains(&1.0) {
        1.0
    } else {
        opts.taus[0]
    };
    let mut sweep = Sweep {
        city: scene.name.clone(),
        size: opts.size,
        frames: opts.frames,
        builds: Vec::new(),
        rows: Vec::new(),
        walks: Vec::new(),
        diagnoses: Vec::new(),
        notes: Vec::new(),
    };
    let bounds = scene.city_bounds();
    let ext = bounds.extent();
    let km2 = (ext.x * ext.y / 1e6).max(1e-9);
    let mut builds: Vec<(FarMode, u32)> = Vec::new();
    for far in &opts.fars {
        match far {
            FarMode::Blockmaps => builds.extend(opts.ks.iter().map(|&k| (*far, k))),
            _ => builds.push((*far, 0)),
        }
    }
    for (mode, k) in builds {
        let t0 = Instant::now();
        let built = match mode {
            FarMode::Relief => {
                Built::Relief(Box::new(build_relief(scene, &opts.relief, progress)?))
            }
            _ => Built::BlockMaps(Box::new(build_maps(scene, opts.build(k), progress)?)),
        };
        let field = built.field();
        let side = match &built {
            Built::Relief(r) => r.m,
            Built::BlockMaps(_) => k,
        };
        let summary = field.build_summary();
        sweep.builds.push(SweepBuild {
            far: mode,
            k: side,
            maps: field.len(),
            bytes: summary.bytes,
            bytes_per_km2: summary.bytes as f64 / km2,
            seconds: t0.elapsed().as_secs_f64(),
        });
        let renderer = gpu.renderer(scene, opts.size, Some(field));
        if let Err(e) = &renderer {
            sweep.notes.push(format!(
                "{} ({side}): no GPU renderer ({e}); CPU hybrid renderer",
                field.name()
            ));
        }
        let show = match mode {
            FarMode::Blockmaps => k == show_k,
            _ => true,
        };
        for (rname, route) in &routes {
            for &tau in &opts.taus {
                let params = WalkParams {
                    route: route.clone(),
                    frames: opts.frames,
                    occlusion: OcclusionMode::Off,
                    image_every: 0,
                    oracle: false,
                    size: opts.size,
                };
                let drawing = match &renderer {
                    Ok(r) => Drawing::With(r.as_ref()),
                    Err(reason) => Drawing::CpuFallback {
                        reason: reason.clone(),
                    },
                };
                let far = FarSetup {
                    select: SelectOptions {
                        tau_px: tau,
                        ..SelectOptions::default()
                    },
                    reference: true,
                    leave_out: false,
                    source: Some(&source),
                    ..FarSetup::new(field)
                };
                progress.stage(&format!("walk {rname}, {} {side}, τ = {tau}", field.name()));
                let rec = run_walk_with_far(scene, &params, drawing, Some(far), &mut |d, t| {
                    progress.count(d, t)
                })?;
                let decision = rec.far_decision.clone().unwrap_or(FarDecision {
                    representation: field.name().to_string(),
                    used: false,
                    reason: None,
                    left_out_after: None,
                });
                let s = FarSummary::new(&rec.far, &decision, &far.select);
                if let (true, Built::BlockMaps(maps)) = (opts.diagnose, &built) {
                    sweep.diagnoses.push(SweepDiagnosis {
                        route: rname.clone(),
                        k,
                        tau_px: tau,
                        frames: diagnose(scene, &source, maps, route, opts, &rec, far.select)?,
                    });
                }
                sweep.rows.push(SweepRow::new(
                    &scene.name,
                    rname,
                    (mode, side, tau),
                    field.len(),
                    opts.frames,
                    &s,
                ));
                if show && tau == show_t {
                    sweep.walks.push(SweepWalk {
                        route: rname.clone(),
                        far: mode,
                        k: side,
                        tau_px: tau,
                        record: rec,
                    });
                }
            }
        }
    }
    Ok(sweep)
}

/// A far field the sweep built.
enum Built {
    BlockMaps(Box<MapTree>),
    Relief(Box<ReliefField>),
}

impl Built {
    fn field(&self) -> &dyn FarField {
        match self {
            Built::BlockMaps(m) => m.as_ref(),
            Built::Relief(r) => r.as_ref(),
        }
    }
}

/// The relief impostors of `scene` built with `opts`.
fn build_relief(
    scene: &Scene,
    opts: &ReliefOptions,
    progress: &dyn JobProgress,
) -> Result<ReliefField, JobError> {
    progress.stage(&format!("building the relief impostors of {}", scene.name));
    ReliefField::build(scene, opts, &|done, total| progress.count(done, total)).map_err(|e| {
        JobError::Far {
            what: "relief impostors",
            city: scene.name.clone(),
            source: Box::new(e),
        }
    })
}

impl SweepRow {
    /// The row of configuration `(far, k, tau)` on route `route` of `city`, with `maps` maps
    /// and `frames` frames, from the walk's far-field figures `s`.
    fn new(
        city: &str,
        route: &str,
        (far, k, tau_px): (FarMode, u32, f64),
        maps: usize,
        frames: usize,
        s: &FarSummary,
    ) -> Self {
        Self {
            city: city.to_string(),
            route: route.to_string(),
            far,
            k,
            tau_px,
            maps,
            frames,
            far_nodes: s.far_nodes.unwrap_or(0.0),
            mesh_triangles: s.mesh_triangles.unwrap_or(0.0),
            coverage_error_max: s.coverage_error_max,
            coverage_error_mean: s.coverage_error_mean,
            psnr_min: s.psnr_min,
            silhouette_px_max: s.silhouette_px_max,
            silhouette_ratio_max: s.silhouette_ratio_max,
            silhouette_bound_violations: s.silhouette_bound_violations,
            silhouette_subpixel: s.silhouette_subpixel,
            silhouette_thin: s.silhouette_thin,
            popping_px_max: s.popping_px_max,
            hybrid_ms: s.frame_s.map(|s| s * 1e3),
            mesh_ms: s.mesh_frame_s.map(|s| s * 1e3),
            frame_time_ratio_vs_mesh: s.frame_time_ratio_vs_mesh,
        }
    }
}

/// The maps of `scene` built with `build`, kept as a [`MapTree`] (the diagnosis reads the maps
/// themselves, not only the far field they draw).
fn build_maps(
    scene: &Scene,
    build: BuildOptions,
    progress: &dyn JobProgress,
) -> Result<MapTree, JobError> {
    progress.stage(&format!(
        "building the BlockMaps of {} (K = {})",
        scene.name, build.k
    ));
    MapTree::build(scene, &BlockMapsOptions { build }, &|done, total| {
        progress.count(done, total)
    })
    .map_err(|e| JobError::Far {
        what: "BlockMaps",
        city: scene.name.clone(),
        source: Box::new(e),
    })
}

/// Classifies the mismatched pixels of the frames of `rec` with the largest coverage error and
/// the largest silhouette distance, replaying the walk's selection up to them (the selector's
/// hysteresis depends on the frames before).
fn diagnose(
    scene: &Scene,
    source: &Source,
    maps: &MapTree,
    route: &CameraRoute,
    opts: &SweepOptions,
    rec: &WalkRecord,
    select: SelectOptions,
) -> Result<Vec<DiagnosedFrame>, SweepError> {
    let key = |f: &dyn Fn(&super::ImageError) -> f64| {
        rec.far
            .iter()
            .filter_map(|r| r.image.as_ref().map(|i| (r.frame, f(i))))
            .fold(None, |a: Option<(usize, f64)>, (fr, v)| match a {
                Some((_, b)) if b >= v => a,
                _ => Some((fr, v)),
            })
            .map(|x| x.0)
    };
    let mut frames: Vec<usize> = [
        key(&|i| i.coverage_error),
        // The frame farthest beyond the bound after the second look, else the raw distance.
        key(&|i| i.silhouette_ratio_max.unwrap_or(i.silhouette_px)),
    ]
    .into_iter()
    .flatten()
    .collect();
    frames.dedup();
    let mut sel = Selector::new(maps, &scene.bounds, select).map_err(SweepError::Diagnose)?;
    let (w, h) = opts.size;
    let mut out = Vec::new();
    for (f, cam) in route.sample(opts.frames).iter().enumerate() {
        let s = sel.select(cam, h, None);
        if !frames.contains(&f) {
            continue;
        }
        out.push(DiagnosedFrame {
            frame: f,
            diagnosis: diagnose_frame(&FrameInput {
                source,
                ground: Some(&scene.ground),
                tree: maps,
                selection: &s,
                camera: cam,
                width: w,
                height: h,
                tau_px: select.tau_px,
            }),
        });
    }
    Ok(out)
}

/// The Pareto front of `pts` (milliseconds, error), by milliseconds: the points that no other
/// point beats in both time and error. A point that ties another in time or in error is kept
/// (it is not beaten in both), equal points included; points with a coordinate that is not
/// finite are left out.
pub fn pareto(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.retain(|p| p.0.is_finite() && p.1.is_finite());
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out = Vec::new();
    // The smallest error among the points strictly faster than the current group of equal times.
    let mut best_faster = f64::INFINITY;
    let mut i = 0;
    while i < pts.len() {
        let t = pts[i].0;
        let group_end = pts[i..]
            .iter()
            .position(|p| p.0 != t)
            .map_or(pts.len(), |n| i + n);
        let group = &pts[i..group_end];
        out.extend(group.iter().filter(|p| p.1 <= best_faster));
        best_faster = best_faster.min(group[0].1);
        i = group_end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{CitySource, SceneOptions};
    use crate::walk::{NoGpu, Quiet};
    use std::path::Path;

    #[test]
    fn the_pareto_front_drops_dominated_points() {
        let front = pareto(vec![
            (2.0, 0.5),
            (1.0, 1.0),
            (3.0, 0.1),
            // Slower and worse than (2.0, 0.5).
            (2.5, 0.6),
            (f64::NAN, 0.0),
        ]);
        assert_eq!(front, vec![(1.0, 1.0), (2.0, 0.5), (3.0, 0.1)]);
        // Ties in time, in error, and equal points are not beaten in both: kept.
        let front = pareto(vec![
            (2.0, 0.5),
            (1.0, 1.0),
            (1.0, 1.5),
            (3.0, 0.5),
            (2.0, 0.5),
        ]);
        assert_eq!(
            front,
            vec![(1.0, 1.0), (1.0, 1.5), (2.0, 0.5), (2.0, 0.5), (3.0, 0.5)]
        );
    }

    #[test]
    fn bad_options_are_refused_with_their_name() {
        assert!(SweepOptions::default().check().is_ok());
        let ok = SweepOptions::default();
        let cases = [
            (
                SweepOptions {
                    taus: vec![],
                    ..ok.clone()
                },
                "taus",
            ),
            (
                SweepOptions {
                    ks: vec![],
                    ..ok.clone()
                },
                "ks",
            ),
            (
                SweepOptions {
                    routes: vec![],
                    ..ok.clone()
                },
                "routes",
            ),
            (
                SweepOptions {
                    taus: vec![1.0, f64::NAN],
                    ..ok.clone()
                },
                "tau",
            ),
            (
                SweepOptions {
                    taus: vec![0.0],
                    ..ok.clone()
                },
                "tau",
            ),
            (
                SweepOptions {
                    frames: 0,
                    ..ok.clone()
                },
                "frames",
            ),
            (
                SweepOptions {
                    edges: 3,
                    ..ok.clone()
                },
                "edges",
            ),
            (
                SweepOptions {
                    fars: vec![],
                    ..ok.clone()
                },
                "fars",
            ),
            (
                SweepOptions {
                    fars: vec![FarMode::None],
                    ..ok.clone()
                },
                "none",
            ),
            (
                SweepOptions {
                    fars: vec![FarMode::Relief, FarMode::Relief],
                    ..ok.clone()
                },
                "twice",
            ),
            (
                SweepOptions {
                    relief: ReliefOptions {
                        coverage_target: 0.0,
                        ..ReliefOptions::default()
                    },
                    ..ok.clone()
                },
                "coverage_target",
            ),
        ];
        for (o, word) in cases {
            let e = o.check().unwrap_err().to_string();
            assert!(e.contains(word), "{word}: {e}");
        }
        assert!(SweepOptions {
            ks: vec![33],
            ..ok.clone()
        }
        .check()
        .is_err());
    }

    #[test]
    fn a_small_sweep_checks_the_bound_on_every_row() {
        let source = CitySource::parse(Path::new("synthetic:3x3"), None, None, &[], 2).unwrap();
        let scene = Scene::load(&source, &SceneOptions::default(), &mut |_| {}).unwrap();
        let opts = SweepOptions {
            taus: vec![1.0, 8.0],
            ks: vec![32],
            routes: vec![RouteChoice::Orbit],
            frames: 2,
            size: (64, 36),
            ..SweepOptions::default()
        };
        let sweep = run_sweep(&scene, &opts, &NoGpu("test"), &Quiet).unwrap();
        assert_eq!(
            sweep.rows.len(),
            opts.ks.len() * opts.routes.len() * opts.taus.len()
        );
        for r in &sweep.rows {
            assert!(r.silhouette_ratio_max.is_some(), "bound checked: {r:?}");
            assert_eq!(r.frames, 2);
        }
        for a in &sweep.rows {
            for b in &sweep.rows {
                if a.route == b.route && a.k == b.k && a.tau_px < b.tau_px {
                    assert!(
                        b.far_nodes >= a.far_nodes,
                        "τ {} draws {} far nodes, τ {} draws {}",
                        b.tau_px,
                        b.far_nodes,
                        a.tau_px,
                        a.far_nodes
                    );
                }
            }
        }
        assert_eq!(sweep.walks.len(), 1, "one walk report per route");
        assert_eq!(sweep.walks[0].tau_px, 1.0);
        assert_eq!(sweep.builds.len(), 1);
        assert!(sweep.notes.iter().any(|n| n.contains("test")));
    }

    #[test]
    fn both_representations_run_on_the_same_routes_and_thresholds() {
        let source = CitySource::parse(Path::new("synthetic:3x3"), None, None, &[], 2).unwrap();
        let scene = Scene::load(&source, &SceneOptions::default(), &mut |_| {}).unwrap();
        let opts = SweepOptions {
            fars: vec![FarMode::Blockmaps, FarMode::Relief],
            taus: vec![1.0, 8.0],
            ks: vec![32],
            routes: vec![RouteChoice::Orbit],
            frames: 2,
            size: (64, 36),
            ..SweepOptions::default()
        };
        let sweep = run_sweep(&scene, &opts, &NoGpu("test"), &Quiet).unwrap();
        assert_eq!(sweep.builds.len(), 2);
        assert_eq!(sweep.rows.len(), 2 * opts.taus.len());
        for far in [FarMode::Blockmaps, FarMode::Relief] {
            let rows: Vec<&SweepRow> = sweep.rows.iter().filter(|r| r.far == far).collect();
            assert_eq!(rows.len(), 2, "{far}");
            for r in rows {
                assert!(r.silhouette_ratio_max.is_some(), "bound checked: {r:?}");
                assert!(r.mesh_ms.is_some());
            }
            let b = sweep.builds.iter().find(|b| b.far == far).unwrap();
            assert!(b.bytes > 0 && b.bytes_per_km2 > 0.0 && b.maps > 0, "{b:?}");
        }
        assert_eq!(
            sweep.walks.len(),
            2,
            "one walk per representation and route"
        );
    }
}
