//! `blockwalk walk`: a camera route through the city with every spatial structure (Pina, Serón and Cerezo, §5.1).

use super::common::{load_scene, CityArgs, Size};
use anyhow::Context;
use blockwalk::blockmap::MapTree;
use blockwalk::index::Structure;
use blockwalk::report;
use blockwalk::route::{RouteChoice, RouteContext};
use blockwalk::scene::{BuildingsMode, Scene, SceneOptions};
use blockwalk::visibility::{CullerOptions, FrameRenderer};
use blockwalk::walk::{
    run_walk_with_far, Drawing, FarMode, FarSetup, OcclusionMode, WalkParams, WalkRecord,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

use blockwalk::route::MAX_FRAMES;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route: `paper` (Pina, Serón and Cerezo, §5), `orbit`, `street` (a walk across the street graph),
    /// `flyover` (high, most of the city in view), or a route file (.toml / .json, see
    /// examples/routes/).
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
    #[arg(long, default_value_t = 30)]
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

/// The BlockMaps of `scene` at `k` (Cignoni et al., §4's competitive stop), with a spinner.
pub fn build_far_maps(scene: &Scene, k: u32, quiet: bool) -> anyhow::Result<MapTree> {
    let build = blockwalk::blockmap::BuildOptions {
        k,
        ..Default::default()
    };
    build_far_maps_with(scene, build, quiet)
}

/// [`build_far_maps`] with the given map options (the side K is `build.k`).
pub fn build_far_maps_with(
    scene: &Scene,
    build: blockwalk::blockmap::BuildOptions,
    quiet: bool,
) -> anyhow::Result<MapTree> {
    use blockwalk::blockmap::{CityMapsOptions, Stop, TreeOptions};
    let k = build.k;
    let opts = CityMapsOptions {
        tree: TreeOptions {
            build,
            stop: Stop::Competitive,
            ..TreeOptions::default()
        },
        checks: 0,
        ..CityMapsOptions::default()
    };
    let pb = super::common::spinner(format!(
        "building the BlockMaps of {} (K = {k})",
        scene.name
    ));
    if quiet {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let maps = scene
        .blockmaps(&opts, &|done, total| {
            pb.set_message(format!("BlockMaps {done}/{total}"))
        })
        .with_context(|| format!("building the BlockMaps of {}", scene.name))?;
    pb.finish_and_clear();
    Ok(maps.maps)
}

/// The route `choice` over `scene` at `size`, and the frames a route file asks for.
pub fn resolve_route(
    choice: &RouteChoice,
    scene: &Scene,
    size: Size,
) -> anyhow::Result<(blockwalk::route::CameraRoute, Option<usize>)> {
    let ctx = RouteContext {
        city: &scene.name,
        bounds: scene.city_bounds(),
        street_edges: &scene.layout.street_edges,
        buildings: &scene.city.buildings,
        frame: &scene.city.frame,
        aspect: size.aspect(),
    };
    choice
        .resolve(&ctx)
        .with_context(|| format!("making the {choice} route over {}", scene.name))
}

/// A GPU renderer for the scene (drawing the far field `far` when given), or why there is none.
#[cfg(feature = "render")]
pub fn gpu_renderer(
    scene: &Scene,
    size: Size,
    far: Option<&MapTree>,
) -> Result<Box<dyn FrameRenderer>, String> {
    let r =
        blockwalk::render::GpuFrameRenderer::new(scene.draw_meshes(), &scene.ground, size.pair())
            .map_err(|e| e.to_string())?;
    match far {
        None => Ok(Box::new(r)),
        Some(m) => Ok(Box::new(r.with_far(m).map_err(|e| e.to_string())?)),
    }
}

/// Without the `render` feature there is no GPU renderer.
#[cfg(not(feature = "render"))]
pub fn gpu_renderer(
    _scene: &Scene,
    _size: Size,
    _far: Option<&MapTree>,
) -> Result<Box<dyn FrameRenderer>, String> {
    Err("built without the `render` feature".into())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = SceneOptions {
        structures: args.structures.clone(),
        occlusion: (args.occlusion != OcclusionMode::Off).then(CullerOptions::default),
        ..SceneOptions::default()
    };
    let mut scene = load_scene(&args.city, args.seed, &opts)?;
    // Pages (the scene graph asked for) and buildings as draw units.
    let pages = blockwalk::index::SceneGraphParams {
        leaf_capacity: args.page_capacity as usize,
        ..Default::default()
    };
    scene
        .set_pages(&pages, args.buildings)
        .with_context(|| format!("splitting {} into pages and buildings", scene.name))?;
    let (route, file_frames) = resolve_route(&args.route, &scene, args.size)?;
    let frames = args
        .frames
        .map(|f| f as usize)
        .or(file_frames)
        .unwrap_or(300);
    let frames = blockwalk::route::check_frames(&args.route.to_string(), frames)?;
    let params = WalkParams {
        route,
        frames,
        occlusion: args.occlusion,
        image_every: if args.render { args.image_every } else { 0 },
        oracle: args.oracle,
        size: args.size.pair(),
    };
    let select = args.far.select()?;
    anyhow::ensure!(
        !args.reference || args.render,
        "--reference compares drawn frames: add --render"
    );
    let maps = match args.far.mode {
        FarMode::None => None,
        FarMode::Blockmaps => Some(build_far_maps(&scene, args.far.k, args.json)?),
    };
    // The exact prisms the silhouette bound is checked with (only with the reference).
    let source = if args.reference && maps.is_some() {
        Some(
            blockwalk::blockmap::Source::new(&scene.city, &scene.layout, &scene.building_meshes)
                .with_context(|| format!("preparing the buildings of {}", scene.name))?,
        )
    } else {
        None
    };
    let far = maps.as_ref().map(|m| FarSetup {
        field: m,
        select,
        reference: args.reference,
        leave_out: !args.keep_far,
        probe_frames: 8,
        source: source.as_ref(),
    });
    let gpu = args
        .render
        .then(|| gpu_renderer(&scene, args.size, maps.as_ref()));
    let drawing = match &gpu {
        None => Drawing::Off,
        Some(Ok(r)) => Drawing::With(r.as_ref()),
        Some(Err(reason)) => Drawing::CpuFallback {
            reason: reason.clone(),
        },
    };
    let bar = ProgressBar::new(frames as u64).with_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} frames ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(format!("walk {}", params.route.name));
    if args.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let record = run_walk_with_far(&scene, &params, drawing, far, &mut |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
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
    out!(
        "{}",
        report::walk::markdown::summary_markdown(&record.summary)
    );
    if let Some(f) = record.far_summary() {
        let g = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or("–".into());
        let n = |v: Option<u64>| v.map(|v| v.to_string()).unwrap_or("–".into());
        outln!(
            "far field (τ = {} px): {}; far nodes {} per frame, mesh triangles {}, frame time hybrid/mesh {}, coverage error max {}, PSNR min {} dB, silhouette max {} px (raw), bound ratio max {}, bound violations {} (sub-pixel {}, thin {}), popping max {} px",
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
