//! The occlusion benchmark: the culler against the oracle over random views, at several cull
//! map resolutions (Willmott et al., §3.2): time, effectiveness and false culls.

use super::culler::{CullerOptions, OcclusionCuller};
use super::cullmap::Resolution;
use super::oracle::render_ids;
use super::views::{random_views, View, ViewKind, ViewOptions};
use super::VisibilityError;
use crate::blocks::{BlockId, BlockLayout};
use crate::city::{City, Mesh};
use crate::geom::Camera;
use crate::index::{CityIndex, CullQuery};
use glam::DVec3;
use serde::Serialize;
use std::collections::BTreeSet;

/// Parameters of [`run_occlusion_bench`].
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Cull map cells along the longer side, one run each.
    pub resolutions: Vec<u32>,
    /// The random views.
    pub views: ViewOptions,
    /// Oracle image size (pixels).
    pub oracle_size: (u32, u32),
    /// Culler parameters (its resolution is replaced by each of `resolutions`).
    pub culler: CullerOptions,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            resolutions: vec![64, 128, 256, 512, 1024],
            views: ViewOptions::default(),
            oracle_size: (640, 360),
            culler: CullerOptions::default(),
        }
    }
}

/// A block the cull map removed although the oracle sees it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FalseCull {
    /// Index of the view.
    pub view: usize,
    /// Cull map cells along the longer side.
    pub resolution: u32,
    /// The block.
    pub block: BlockId,
}

/// Results for one cull map resolution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResolutionReport {
    /// Cells along the longer side.
    pub resolution: u32,
    /// Grid size.
    pub cells: (usize, usize),
    /// Cell side, metres.
    pub cell_m: f64,
    /// Median milliseconds per frame (select + draw + pyramid + index traversal).
    pub median_ms: f64,
    /// Median milliseconds to build the cull map.
    pub median_build_ms: f64,
    /// Median milliseconds of the index traversal with cull map tests.
    pub median_test_ms: f64,
    /// Mean occluders drawn per frame.
    pub mean_occluders: f64,
    /// Mean blocks removed by the cull map per frame.
    pub mean_culled: f64,
    /// Blocks removed that the oracle sees (must be 0).
    pub false_culls: u64,
    /// Blocks removed / blocks in the frustum the oracle proves hidden, over all views.
    pub effectiveness: f64,
    /// Effectiveness over street views only.
    pub effectiveness_street: f64,
    /// Effectiveness over flying views only.
    pub effectiveness_flying: f64,
    /// Frames where occlusion culling was skipped.
    pub skipped: u64,
}

/// What [`run_occlusion_bench`] measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OcclusionBenchReport {
    /// Views used.
    pub views: usize,
    /// Street-level views among them.
    pub street_views: usize,
    /// Blocks in the scene.
    pub blocks: usize,
    /// Mean blocks in the frustum per view.
    pub mean_in_frustum: f64,
    /// Mean blocks the oracle sees per view.
    pub mean_visible: f64,
    /// Oracle image size.
    pub oracle_size: (u32, u32),
    /// One entry per resolution.
    pub resolutions: Vec<ResolutionReport>,
    /// The first false culls found (at most 20).
    pub false_cull_examples: Vec<FalseCull>,
}

/// A scene to benchmark: the city, its blocks, one mesh per block (local frame) and an index.
#[derive(Clone, Copy)]
pub struct BenchScene<'a> {
    /// The city.
    pub city: &'a City,
    /// Its blocks.
    pub layout: &'a BlockLayout,
    /// Geometry per block, local frame (what the oracle draws).
    pub meshes: &'a [(BlockId, &'a Mesh)],
    /// The structure frustum culling runs on.
    pub index: &'a dyn CityIndex,
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Runs the occlusion culler at every resolution over random views and compares each frame with
/// the oracle: false culls (the oracle sees a removed block; must be 0), effectiveness (removed /
/// in the frustum but hidden in the oracle) and time. `progress(done, total)` is called per view.
pub fn run_occlusion_bench(
    scene: &BenchScene<'_>,
    opts: &BenchOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<OcclusionBenchReport, VisibilityError> {
    let views = random_views(scene.city, scene.layout, &opts.views);
    run_on_views(scene, opts, &views, progress)
}

/// As [`run_occlusion_bench`] on given views.
pub fn run_on_views(
    scene: &BenchScene<'_>,
    opts: &BenchOptions,
    views: &[View],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<OcclusionBenchReport, VisibilityError> {
    if opts.resolutions.is_empty() {
        return Err(VisibilityError::NoResolutions);
    }
    let base = OcclusionCuller::new(scene.city, scene.layout, opts.culler)?;
    let cullers: Vec<OcclusionCuller> = opts
        .resolutions
        .iter()
        .map(|&r| base.with_resolution(Resolution::Cells(r)))
        .collect::<Result<_, _>>()?;
    struct Acc {
        ms: Vec<f64>,
        build: Vec<f64>,
        test: Vec<f64>,
        occ: u64,
        culled: u64,
        culled_hidden: [u64; 2],
        hidden: [u64; 2],
        false_culls: u64,
        skipped: u64,
    }
    let mut acc: Vec<Acc> = cullers
        .iter()
        .map(|_| Acc {
            ms: vec![],
            build: vec![],
            test: vec![],
            occ: 0,
            culled: 0,
            culled_hidden: [0; 2],
            hidden: [0; 2],
            false_culls: 0,
            skipped: 0,
        })
        .collect();
    let mut examples = Vec::new();
    let (mut in_frustum_sum, mut visible_sum) = (0u64, 0u64);
    for (vi, view) in views.iter().enumerate() {
        progress(vi, views.len());
        let cam = &view.camera;
        let kind = (view.kind == ViewKind::Flying) as usize;
        let mut frustum_out = Vec::new();
        let frustum = cam.frustum();
        scene
            .index
            .cull(&CullQuery::new(&frustum), None, &mut frustum_out);
        let in_frustum: BTreeSet<BlockId> = frustum_out.into_iter().collect();
        let visible =
            render_ids(scene.meshes, cam, opts.oracle_size.0, opts.oracle_size.1).visible();
        in_frustum_sum += in_frustum.len() as u64;
        visible_sum += visible.len() as u64;
        let hidden: BTreeSet<BlockId> = in_frustum.difference(&visible).copied().collect();
        for (c, a) in cullers.iter().zip(acc.iter_mut()) {
            let mut out = Vec::new();
            let st = c.cull(scene.index, cam, &mut out);
            let kept: BTreeSet<BlockId> = out.into_iter().collect();
            let culled: Vec<BlockId> = in_frustum.difference(&kept).copied().collect();
            a.ms.push(st.build_ms + st.test_ms);
            a.build.push(st.build_ms);
            a.test.push(st.test_ms);
            a.occ += st.occluders_used;
            a.culled += culled.len() as u64;
            a.hidden[kind] += hidden.len() as u64;
            a.skipped += st.skipped.is_some() as u64;
            for b in culled {
                if visible.contains(&b) {
                    a.false_culls += 1;
                    if examples.len() < 20 {
                        examples.push(FalseCull {
                            view: vi,
                            resolution: match c.options().resolution {
                                Resolution::Cells(n) => n,
                                Resolution::CellSize(_) => 0,
                            },
                            block: b,
                        });
                    }
                } else {
                    a.culled_hidden[kind] += 1;
                }
            }
        }
    }
    progress(views.len(), views.len());
    let n = views.len().max(1) as f64;
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let resolutions = cullers
        .iter()
        .zip(acc.iter_mut())
        .zip(&opts.resolutions)
        .map(|((c, a), &r)| {
            let g = *c
                .cull_map_for(&Camera::new(DVec3::new(0.0, 0.0, -1.0), 0.0, 0.0))
                .grid();
            ResolutionReport {
                resolution: r,
                cells: (g.nx, g.ny),
                cell_m: g.cell,
                median_ms: median(&mut a.ms),
                median_build_ms: median(&mut a.build),
                median_test_ms: median(&mut a.test),
                mean_occluders: a.occ as f64 / n,
                mean_culled: a.culled as f64 / n,
                false_culls: a.false_culls,
                effectiveness: ratio(
                    a.culled_hidden[0] + a.culled_hidden[1],
                    a.hidden[0] + a.hidden[1],
                ),
                effectiveness_street: ratio(a.culled_hidden[0], a.hidden[0]),
                effectiveness_flying: ratio(a.culled_hidden[1], a.hidden[1]),
                skipped: a.skipped,
            }
        })
        .collect();
    Ok(OcclusionBenchReport {
        views: views.len(),
        street_views: views.iter().filter(|v| v.kind == ViewKind::Street).count(),
        blocks: scene.layout.blocks.len(),
        mean_in_frustum: in_frustum_sum as f64 / n,
        mean_visible: visible_sum as f64 / n,
        oracle_size: opts.oracle_size,
        resolutions,
        false_cull_examples: examples,
    })
}
