//! The far field's figures over a walk, as one typed record ([`FarSummary`]) that the walk
//! report, the command line and the sweep read field by field.

use super::{FarDecision, FarRecord, ImageError};
use crate::blockmap::SelectOptions;
use crate::walk::CullMode;
use serde::Serialize;
use std::collections::BTreeMap;

/// The figures of a walk's hybrid frames (the frames of the last culling mode walked).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FarSummary {
    /// The representation ("BlockMaps", "relief impostors").
    pub representation: String,
    /// Whether the far field was drawn.
    pub used: bool,
    /// Why it was left out, when it was.
    pub reason: Option<String>,
    /// The frame after which the timing probe left it out.
    pub left_out_after: Option<usize>,
    /// τ, pixels.
    pub tau_px: f64,
    /// The selection's hysteresis.
    pub hysteresis: f64,
    /// The culling mode the figures are of (the last one walked).
    pub mode: Option<CullMode>,
    /// Hybrid frames summarised.
    pub frames: usize,
    /// Largest share of pixels whose coverage differs from the mesh-only frame.
    pub coverage_error_max: Option<f64>,
    /// Mean of that share.
    pub coverage_error_mean: Option<f64>,
    /// Smallest colour PSNR, dB (none when every measured frame is identical).
    pub psnr_min: Option<f64>,
    /// Largest raw silhouette distance of a mismatched pixel, pixels.
    pub silhouette_px_max: Option<f64>,
    /// Largest distance over allowed distance after the second look (≤ 1: the bound holds);
    /// none unless every measured frame was checked with the exact geometry.
    pub silhouette_ratio_max: Option<f64>,
    /// Pixels beyond the bound after the second look, summed over the frames.
    pub silhouette_bound_violations: Option<u64>,
    /// Pixels beyond the bound at pixel spacing that the second look settled.
    pub silhouette_subpixel: Option<u64>,
    /// Pixels of buildings the maps declare thin or dropped, within their own bound.
    pub silhouette_thin: Option<u64>,
    /// Largest count of pixels whose coverage changed with the selection (popping).
    pub popping_px_max: Option<f64>,
    /// Mean of that count.
    pub popping_px_mean: Option<f64>,
    /// Largest count of pixels whose colour changed with the selection.
    pub popping_colour_px_max: Option<f64>,
    /// Mean far nodes drawn per frame.
    pub far_nodes: Option<f64>,
    /// Mean pixels the far nodes covered, where the renderer counts them.
    pub far_pixels: Option<f64>,
    /// Mean mesh triangles per hybrid frame.
    pub mesh_triangles: Option<f64>,
    /// Mean blocks drawn as meshes per hybrid frame.
    pub mesh_blocks: Option<f64>,
    /// Mean selection seconds per frame.
    pub select_s: Option<f64>,
    /// Mean hybrid frame seconds.
    pub frame_s: Option<f64>,
    /// Mean mesh-only frame seconds over the same frames.
    pub mesh_frame_s: Option<f64>,
    /// `frame_s / mesh_frame_s` (none when the frames were not drawn).
    pub frame_time_ratio_vs_mesh: Option<f64>,
    /// Mean seconds per pass of the hybrid draw, where the renderer measures them.
    pub passes_s: BTreeMap<String, f64>,
}

impl FarSummary {
    /// The figures of `records` (the frames of the last culling mode), with the walk's
    /// `decision` and selection settings `opts`.
    pub fn new(records: &[FarRecord], decision: &FarDecision, opts: &SelectOptions) -> Self {
        let mean = |v: &mut dyn Iterator<Item = f64>| {
            let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
            (n > 0).then(|| s / n as f64)
        };
        let last_mode = records.last().map(|r| r.mode);
        let sel: Vec<&FarRecord> = records
            .iter()
            .filter(|r| Some(r.mode) == last_mode)
            .collect();
        let hyb = mean(&mut sel.iter().map(|r| r.frame_s));
        let mesh = mean(&mut sel.iter().map(|r| r.mesh_frame_s));
        // Only drawn frames compare times (without drawing, both are selection or culling alone).
        let drawn = !sel.is_empty() && sel.iter().all(|r| r.render_s.is_some());
        let ratio = match (hyb, mesh) {
            (Some(a), Some(b)) if b > 0.0 && drawn => Some(a / b),
            _ => None,
        };
        let imgs: Vec<&ImageError> = sel.iter().filter_map(|r| r.image.as_ref()).collect();
        let fold_max = |g: &dyn Fn(&ImageError) -> f64| {
            (!imgs.is_empty()).then(|| imgs.iter().map(|i| g(i)).fold(0.0, f64::max))
        };
        // The bound's figures need every measured frame checked with the geometry.
        let bounded = !imgs.is_empty() && imgs.iter().all(|i| i.silhouette_ratio_max.is_some());
        let sum = |g: &dyn Fn(&ImageError) -> Option<u64>| {
            bounded.then(|| imgs.iter().filter_map(|i| g(i)).sum::<u64>())
        };
        let psnr_min = (!imgs.is_empty())
            .then(|| imgs.iter().map(|i| i.psnr_db).fold(f64::INFINITY, f64::min))
            .filter(|x| x.is_finite());
        let mut passes: BTreeMap<String, (f64, usize)> = BTreeMap::new();
        for r in &sel {
            for (name, s) in &r.passes {
                let p = passes.entry(name.clone()).or_default();
                p.0 += s;
                p.1 += 1;
            }
        }
        Self {
            representation: decision.representation.clone(),
            used: decision.used,
            reason: decision.reason.clone(),
            left_out_after: decision.left_out_after,
            tau_px: opts.tau_px,
            hysteresis: opts.hysteresis,
            mode: last_mode,
            frames: sel.len(),
            coverage_error_max: fold_max(&|i| i.coverage_error),
            coverage_error_mean: mean(&mut imgs.iter().map(|i| i.coverage_error)),
            psnr_min,
            silhouette_px_max: fold_max(&|i| i.silhouette_px),
            silhouette_ratio_max: bounded.then(|| {
                imgs.iter()
                    .filter_map(|i| i.silhouette_ratio_max)
                    .fold(0.0, f64::max)
            }),
            silhouette_bound_violations: sum(&|i| i.beyond_bound),
            silhouette_subpixel: sum(&|i| i.beyond_bound_subpixel),
            silhouette_thin: sum(&|i| i.beyond_bound_thin),
            popping_px_max: fold_max(&|i| i.popping_px as f64),
            popping_px_mean: mean(&mut imgs.iter().map(|i| i.popping_px as f64)),
            popping_colour_px_max: fold_max(&|i| i.popping_colour_px as f64),
            far_nodes: mean(&mut sel.iter().map(|r| r.far_nodes as f64)),
            far_pixels: mean(&mut sel.iter().filter_map(|r| r.far_pixels.map(|p| p as f64))),
            mesh_triangles: mean(&mut sel.iter().map(|r| r.mesh_triangles as f64)),
            mesh_blocks: mean(&mut sel.iter().map(|r| r.mesh_blocks as f64)),
            select_s: mean(&mut sel.iter().map(|r| r.select_s)),
            frame_s: hyb,
            mesh_frame_s: mesh,
            frame_time_ratio_vs_mesh: ratio,
            passes_s: passes
                .into_iter()
                .map(|(n, (s, c))| (n, s / c as f64))
                .collect(),
        }
    }
}
