//! `blockwalk walk`: a camera route through the city with every spatial structure (seed 003 §5.1).

use super::common::{load_scene, CityArgs, Size};
use anyhow::Context;
use blockwalk::index::Structure;
use blockwalk::report;
use blockwalk::route::{RouteChoice, RouteContext};
use blockwalk::scene::{Scene, SceneOptions};
use blockwalk::visibility::{CullerOptions, FrameRenderer};
use blockwalk::walk::{run_walk, Drawing, OcclusionMode, WalkParams, WalkRecord};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// Most frames a walk may sample (a route file or `--frames`): 100,000, about an hour at 30 fps.
pub const MAX_FRAMES: usize = 100_000;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route: `paper` (seed 003 §5), `orbit`, `street` (a walk across the street graph), or a
    /// route file (.toml / .json, see examples/routes/).
    #[arg(long, default_value = "paper")]
    pub route: RouteChoice,
    /// Frames along the route (default: the file's setting, else 300).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_FRAMES as u64))]
    pub frames: Option<u64>,
    /// Structures to compare, comma separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "none,flat,vamsplit,bqr,rstar"
    )]
    pub structures: Vec<Structure>,
    /// Occlusion culling: on, off, or auto (both modes side by side).
    #[arg(long, value_enum, default_value_t = OcclusionMode::Auto)]
    pub occlusion: OcclusionMode,
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

/// A GPU renderer for the scene, or why there is none.
#[cfg(feature = "render")]
fn gpu_renderer(scene: &Scene, size: Size) -> Result<Box<dyn FrameRenderer>, String> {
    match blockwalk::render::GpuFrameRenderer::new(&scene.meshes, &scene.ground, size.pair()) {
        Ok(r) => Ok(Box::new(r)),
        Err(e) => Err(e.to_string()),
    }
}

/// Without the `render` feature there is no GPU renderer.
#[cfg(not(feature = "render"))]
fn gpu_renderer(_scene: &Scene, _size: Size) -> Result<Box<dyn FrameRenderer>, String> {
    Err("built without the `render` feature".into())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = SceneOptions {
        structures: args.structures.clone(),
        occlusion: (args.occlusion != OcclusionMode::Off).then(CullerOptions::default),
        ..SceneOptions::default()
    };
    let scene = load_scene(&args.city, args.seed, &opts)?;
    let (route, file_frames) = resolve_route(&args.route, &scene, args.size)?;
    let frames = args
        .frames
        .map(|f| f as usize)
        .or(file_frames)
        .unwrap_or(300);
    anyhow::ensure!(
        (1..=MAX_FRAMES).contains(&frames),
        "{}: {frames} frames; expected 1..={MAX_FRAMES}",
        args.route
    );
    let params = WalkParams {
        route,
        frames,
        occlusion: args.occlusion,
        image_every: if args.render { args.image_every } else { 0 },
        oracle: args.oracle,
        size: args.size.pair(),
    };
    let gpu = args.render.then(|| gpu_renderer(&scene, args.size));
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
    let record = run_walk(&scene, &params, drawing, &mut |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    let files = report::walk::write(&record, &args.out, args.frames_dir.as_deref())
        .with_context(|| format!("writing the report to {}", args.out.display()))?;
    if args.json {
        let mut j = report::walk::json(&record);
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
    for n in &record.notes {
        outln!("note: {n}");
    }
    outln!(
        "report: {} ({:.1} s)",
        out.join("report.html").display(),
        record.total_s
    );
    Ok(())
}
