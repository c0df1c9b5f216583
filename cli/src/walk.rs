//! `blockwalk walk`: a camera route through the city with every spatial structure (Pina, Serón and Cerezo, §5.1).

use super::common::{load_scene, CityArgs, Size};
use anyhow::Context;
use blockwalk::index::Structure;
use blockwalk::report;
use blockwalk::route::RouteChoice;
use blockwalk::scene::{BuildingsMode, SceneOptions};
use blockwalk::visibility::CullerOptions;
use blockwalk::walk::{run_job, FarJob, FarMode, GpuRenderers, OcclusionMode, WalkJob, WalkRecord};
use std::path::PathBuf;

use blockwalk::route::MAX_FRAMES;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route: `paper` (Pina, Serón and Cerezo, §5), `orbit`, `street` (a walk across the street graph),
    /// `flyover` (high, most of the city in view), `corners` (a street walk rounding building
    /// corners 0.3–1 m from their walls), or a route file (.toml / .json, see examples/routes/).
    #[arg(long, default_value = "paper")]
    pub route: RouteChoice,
    /// Frames along the route (default: the file's setting, else 300).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_FRAMES as u64))]
    pub frames: Option<u64>,
    /// Structures to compare, comma separated.
    #[arg(
        long,
        value_parser = super::common::choice::<Structure>(),
        value_delimiter = ',',
        default_value = "none,flat,vamsplit,bqr,rstar"
    )]
    pub structures: Vec<Structure>,
    /// Occlusion culling: on, off, or auto (both modes side by side).
    #[arg(long, value_parser = super::common::choice::<OcclusionMode>(), default_value_t = OcclusionMode::Auto)]
    pub occlusion: OcclusionMode,
    /// Test each building of the blocks that survive (frustum, and the cull map with
    /// occlusion; Willmott et al., §3.2.8): on, off, or auto (with and without, side by side, and
    /// which pays).
    #[arg(long, value_parser = super::common::choice::<BuildingsMode>(), default_value_t = BuildingsMode::Auto)]
    pub buildings: BuildingsMode,
    /// Buildings per leaf of the `scenegraph` structure (its pages, drawn whole).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub page_capacity: u32,
    /// Render every frame (GPU with the `render` feature and an adapter, else the CPU shader).
    #[arg(long)]
    pub render: bool,
    /// Keep every k-th rendered frame as PNG.
    #[arg(long, default_value_t = 30, value_parser = super::common::at_least_one)]
    pub image_every: usize,
    /// Where the PNG frames go (default: OUT/frames).
    #[arg(long)]
    pub frames_dir: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "walk-out")]
    pub out: PathBuf,
    /// Count false culls against the visibility oracle.
    #[arg(long)]
    pub oracle: bool,
    /// Image width × height for rendering and the oracle, e.g. 1280x720.
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Seed of a `synthetic:` city.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub far: super::common::FarArgs,
    /// Compare every hybrid frame with the mesh-only frame of the same camera (coverage error,
    /// PSNR, silhouette distance, popping); needs `--render`.
    #[arg(long)]
    pub reference: bool,
    /// Draw the far field even where the scene does not need it (no node qualifies, or meshes
    /// draw faster).
    #[arg(long)]
    pub keep_far: bool,
}

/// The walk's GPU renderers: wgpu's with the `render` feature, none without.
pub fn gpu() -> &'static dyn GpuRenderers {
    #[cfg(feature = "render")]
    {
        &blockwalk::render::WgpuRenderers
    }
    #[cfg(not(feature = "render"))]
    {
        &blockwalk::walk::NoGpu("built without the `render` feature")
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = SceneOptions {
        structures: args.structures.clone(),
        occlusion: (args.occlusion != OcclusionMode::Off).then(CullerOptions::default),
        ..SceneOptions::default()
    };
    let mut scene = load_scene(&args.city, args.seed, &opts)?;
    let far = match args.far.mode {
        FarMode::None => None,
        mode => Some(FarJob {
            mode,
            maps: args.far.blockmaps(),
            relief: args.far.relief.options()?,
            select: args.far.select()?,
            reference: args.reference,
            keep: args.keep_far,
        }),
    };
    let job = WalkJob {
        route: args.route.clone(),
        frames: args.frames.map(|f| f as usize),
        occlusion: args.occlusion,
        buildings: args.buildings,
        pages: blockwalk::index::SceneGraphParams {
            leaf_capacity: args.page_capacity as usize,
            ..Default::default()
        },
        render: args.render,
        image_every: args.image_every,
        oracle: args.oracle,
        size: args.size.pair(),
        far,
    };
    let progress = super::common::Progress::new(args.json);
    let record = run_job(&mut scene, &job, gpu(), &progress)?;
    progress.finish();
    let ctx = report::walk::ReportContext {
        plan: report::walk::Plan::from_scene(&scene),
        machine: Some(report::walk::Machine::detect()),
        command: std::env::args().collect(),
        extra_plots: Vec::new(),
    };
    let files = report::walk::write_with(&record, &args.out, args.frames_dir.as_deref(), &ctx)
        .with_context(|| format!("writing the report to {}", args.out.display()))?;
    if args.json {
        let mut j = report::walk::json_with(&record, &ctx);
        j["out"] = serde_json::json!(args.out);
        j["files"] = serde_json::json!(files);
        outln!("{}", serde_json::to_string(&j)?);
    } else {
        print_summary(&record, &args.out)?;
    }
    if let Some(n) = record.false_culls().filter(|&n| n > 0) {
        anyhow::bail!("{n} false culls (blocks the oracle sees were dropped): a culler is broken");
    }
    Ok(())
}

fn print_summary(record: &WalkRecord, out: &std::path::Path) -> anyhow::Result<()> {
    outln!(
        "{}: route {} with {} frames; renderer: {}",
        record.city,
        record.route,
        record.cameras.len(),
        record.renderer
    );
    for line in report::walk::verdict::conclusion(record) {
        outln!("{line}");
    }
    out!(
        "{}",
        report::walk::markdown::summary_markdown(&record.summary)
    );
    if let Some(f) = record.far_summary() {
        let g = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or("–".into());
        let n = |v: Option<u64>| v.map(|v| v.to_string()).unwrap_or("–".into());
        outln!(
            "far field ({}, τ = {} px): {}; far nodes {} per frame, mesh triangles {}, frame time hybrid/mesh {}, coverage error max {}, PSNR min {} dB, silhouette max {} px (raw), bound ratio max {}, bound violations {} (sub-pixel {}, thin {}), popping max {} px",
            f.representation,
            f.tau_px,
            if f.used { "drawn" } else { "left out" },
            g(f.far_nodes),
            g(f.mesh_triangles),
            g(f.frame_time_ratio_vs_mesh),
            g(f.coverage_error_max),
            g(f.psnr_min),
            g(f.silhouette_px_max),
            g(f.silhouette_ratio_max),
            n(f.silhouette_bound_violations),
            n(f.silhouette_subpixel),
            n(f.silhouette_thin),
            g(f.popping_px_max),
        );
    }
    for n in &record.notes {
        outln!("note: {n}");
    }
    outln!(
        "report: {} ({:.0} ms)",
        out.join("report.html").display(),
        record.total_s * 1e3
    );
    Ok(())
}
