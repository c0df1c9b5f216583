//! Culling checked over whole routes on several cities, as one call (`blockwalk cull-proof`):
//! each city's scene with every block structure, every route asked for made over it and sampled,
//! then every frame checked by [`crate::visibility::route_proof::prove_routes`].

use super::job::{resolve_route, JobError, JobProgress};
use crate::index::{CityIndex, Structure};
use crate::route::{check_frames, RouteChoice};
use crate::scene::{CitySource, Scene, SceneOptions};
use crate::visibility::route_proof::{
    prove_routes, CityProof, ProofOptions, ProofRoute, ProofScene,
};
use serde::Serialize;
use std::time::Instant;

/// What [`run_route_proof`] checks.
#[derive(Clone, Debug)]
pub struct RouteProofJob {
    /// The cities, each with the frames sampled along every route over it.
    pub cities: Vec<(CitySource, usize)>,
    /// The routes (by default every generated route, [`RouteChoice::GENERATED`]).
    pub routes: Vec<RouteChoice>,
    /// The oracle, the cull maps and the culler.
    pub proof: ProofOptions,
}

impl RouteProofJob {
    /// Checks what can be checked before loading anything.
    ///
    /// # Errors
    /// [`JobError::Parameter`] for no city, no route, a frame count out of
    /// `1..=`[`crate::route::MAX_FRAMES`], or bad proof options.
    pub fn check(&self) -> Result<(), JobError> {
        if self.cities.is_empty() {
            return Err(JobError::Parameter("give at least one city".into()));
        }
        if self.routes.is_empty() {
            return Err(JobError::Parameter("give at least one route".into()));
        }
        for (source, frames) in &self.cities {
            check_frames(&describe(source), *frames)
                .map_err(|e| JobError::Parameter(e.to_string()))?;
        }
        self.proof
            .check()
            .map_err(|e| JobError::Parameter(e.to_string()))
    }
}

/// A city source as a user named it: the footprints' path, or `synthetic:COLSxROWS`.
fn describe(source: &CitySource) -> String {
    match source {
        CitySource::Files { footprints, .. } => footprints.display().to_string(),
        CitySource::Synthetic { cols, rows, .. } => format!("synthetic:{cols}x{rows}"),
    }
}

/// What [`run_route_proof`] found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RouteProofReport {
    /// One entry per city, in the order given.
    pub cities: Vec<CityProof>,
    /// The structures culled through.
    pub structures: Vec<Structure>,
    /// Cull map cells along the longer side.
    pub resolutions: Vec<u32>,
    /// Frames over every city and route.
    pub frames: u64,
    /// Vacuous frames among them.
    pub vacuous: u64,
    /// False culls, blocks and buildings, checked and vacuous frames (must be 0).
    pub false_culls: u64,
    /// Seconds, loading included.
    pub seconds: f64,
}

impl RouteProofReport {
    /// True when no frame of any route dropped anything the oracle sees.
    pub fn passed(&self) -> bool {
        self.false_culls == 0
    }
}

/// Loads each city with every block structure, makes every route over it (sampled at the
/// city's frame count, whatever the route's own default), and checks every frame. `progress`
/// hears the stages and the frames done.
///
/// # Errors
/// [`JobError::Parameter`] ([`RouteProofJob::check`]), [`JobError::Units`] for a city that
/// cannot be loaded, [`JobError::Route`] for a route that cannot be made over a city (naming
/// both), [`JobError::Proof`] for a culler that cannot be built.
pub fn run_route_proof(
    job: &RouteProofJob,
    progress: &dyn JobProgress,
) -> Result<RouteProofReport, JobError> {
    job.check()?;
    let t0 = Instant::now();
    let opts = SceneOptions {
        structures: Structure::ALL.to_vec(),
        occlusion: None,
        ..SceneOptions::default()
    };
    let (w, h) = job.proof.oracle_size;
    let aspect = f64::from(w) / f64::from(h);
    let mut cities = Vec::with_capacity(job.cities.len());
    for (source, frames) in &job.cities {
        progress.stage(&format!("loading {}", describe(source)));
        let scene = Scene::load(source, &opts, &mut |m| progress.stage(m))?;
        let mut routes = Vec::with_capacity(job.routes.len());
        for choice in &job.routes {
            progress.stage(&format!("making the {choice} route over {}", scene.name));
            let (route, _) = resolve_route(choice, &scene, aspect)?;
            routes.push(ProofRoute {
                name: choice.to_string(),
                cameras: route.sample(*frames),
            });
        }
        let indexes: Vec<&dyn CityIndex> = scene.indexes.iter().map(|i| i.as_ref()).collect();
        let proof_scene = ProofScene {
            name: &scene.name,
            city: &scene.city,
            layout: &scene.layout,
            building_meshes: &scene.building_meshes,
            indexes: &indexes,
        };
        progress.stage(&format!(
            "checking {} frames over {}",
            frames * routes.len(),
            scene.name
        ));
        let city = prove_routes(&proof_scene, &routes, &job.proof, &mut |d, t| {
            progress.count(d, t)
        })
        .map_err(|source| JobError::Proof {
            city: scene.name.clone(),
            source,
        })?;
        cities.push(city);
    }
    let frames = cities.iter().map(CityProof::frames).sum();
    let vacuous = cities
        .iter()
        .flat_map(|c| &c.routes)
        .map(|r| r.vacuous.total())
        .sum();
    let false_culls = cities.iter().map(CityProof::false_culls).sum();
    Ok(RouteProofReport {
        cities,
        structures: Structure::ALL.to_vec(),
        resolutions: job.proof.resolutions.clone(),
        frames,
        vacuous,
        false_culls,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
