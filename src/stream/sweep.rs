//! The far field of a tiled city measured against its time: for every route and τ, a
//! deterministic streamed walk whose every frame is drawn again with meshes only
//! ([`StreamOptions::mesh_reference`]); per configuration the hybrid frame's time against the
//! mesh-only frame's, and the error (pixels differing, PSNR).

use crate::geom::Camera;
use crate::route::{RouteChoice, RouteContext};

use super::city::StreamCity;
use super::play::{play, Mode, StreamOptions};
use super::StreamError;

/// One configuration's figures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SweepRow {
    /// The route.
    pub route: String,
    /// τ, pixels.
    pub tau_px: f64,
    /// Frames drawn, and of these measured against the mesh-only frame (its content fit the
    /// budget).
    pub frames: usize,
    /// Frames measured.
    pub measured: usize,
    /// Maps and block meshes drawn per frame, mean.
    pub maps_mean: f64,
    /// Block meshes per frame, mean.
    pub meshes_mean: f64,
    /// Milliseconds per hybrid frame, mean.
    pub hybrid_ms: f64,
    /// Milliseconds per mesh-only frame, mean (measured frames).
    pub mesh_ms: f64,
    /// Share of pixels differing from the mesh-only frame: mean and largest.
    pub differing_mean: f64,
    /// Largest share.
    pub differing_max: f64,
    /// Lowest PSNR against the mesh-only frame, dB (`None` when every frame is identical).
    pub psnr_min_db: Option<f64>,
}

/// Runs the sweep over `city` (see the module doc) with `base`'s budget and image size.
///
/// # Errors
/// A route that cannot be made; a τ the walk refuses.
pub fn run_sweep(
    city: &StreamCity,
    routes: &[RouteChoice],
    taus: &[f64],
    frames: usize,
    base: &StreamOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<SweepRow>, StreamError> {
    let mut rows = Vec::new();
    for r in routes {
        let ctx = RouteContext {
            city: &city.index.city,
            bounds: city.city_box(),
            street_edges: &[],
            buildings: &[],
            frame: &city.frame,
            aspect: base.size.0 as f64 / base.size.1 as f64,
            terrain: None,
        };
        let (route, _) = r
            .resolve(&ctx)
            .map_err(|e| StreamError::Bad(e.to_string()))?;
        let cams: Vec<Camera> = route.sample(frames);
        for &tau in taus {
            progress(&format!("{r}, τ = {tau} px"));
            let mut o = base.clone();
            o.mode = Mode::Deterministic;
            o.tau_px = tau;
            o.far = true;
            o.mesh_reference = true;
            o.check = false;
            o.keep_every = None;
            if !(tau.is_finite() && tau > 0.0) {
                return Err(StreamError::Bad(format!("tau {tau}: expected pixels > 0")));
            }
            let run = play(city, &cams, &o, &mut |_, _| {})?;
            let px = (o.size.0 as f64 * o.size.1 as f64).max(1.0);
            let n = run.frames.len().max(1) as f64;
            let measured: Vec<_> = run
                .frames
                .iter()
                .filter(|f| f.mesh_differing_pixels.is_some())
                .collect();
            let m = measured.len().max(1) as f64;
            rows.push(SweepRow {
                route: r.to_string(),
                tau_px: tau,
                frames: run.frames.len(),
                measured: measured.len(),
                maps_mean: run.frames.iter().map(|f| f.maps as f64).sum::<f64>() / n,
                meshes_mean: run.frames.iter().map(|f| f.meshes as f64).sum::<f64>() / n,
                hybrid_ms: run.frames.iter().map(|f| f.draw_s).sum::<f64>() / n * 1e3,
                mesh_ms: measured.iter().filter_map(|f| f.mesh_draw_s).sum::<f64>() / m * 1e3,
                differing_mean: measured
                    .iter()
                    .filter_map(|f| f.mesh_differing_pixels)
                    .sum::<u64>() as f64
                    / m
                    / px,
                differing_max: measured
                    .iter()
                    .filter_map(|f| f.mesh_differing_pixels)
                    .max()
                    .unwrap_or(0) as f64
                    / px,
                psnr_min_db: measured
                    .iter()
                    .filter_map(|f| f.mesh_psnr_db)
                    .filter(|p| p.is_finite())
                    .reduce(f64::min),
            });
        }
    }
    Ok(rows)
}
