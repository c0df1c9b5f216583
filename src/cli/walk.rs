//! `blockwalk walk`: a camera route through the city with every spatial structure (seed 003 §5.1).

use super::common::{load_city, spinner, CityArgs};
use anyhow::Context;
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::index::{block_bounds, build_by_name, STRUCTURES};
use blockwalk::report::walk::{run_walk, OcclusionMode, WalkParams, WalkReport, WalkScene};
use blockwalk::route::{self, CameraRoute, Lens, PaperRouteParams, RouteFile, StreetGraph};
use blockwalk::visibility::{CullerOptions, OcclusionCuller};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route: `paper` (seed 003 §5), `orbit`, `street` (a walk across the street graph), or a
    /// route file (.toml / .json, see examples/routes/).
    #[arg(long, default_value = "paper")]
    pub route: String,
    /// Frames along the route (default: the file's setting, else 300).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Structures to compare, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "none,flat,vamsplit,bqr,rstar"
    )]
    pub structures: Vec<String>,
    /// Occlusion culling: on, off, or auto (both modes when an occlusion culler is built).
    #[arg(long, default_value = "auto")]
    pub occlusion: String,
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
    pub size: String,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

/// Parses `WIDTHxHEIGHT` (also used by `view`).
pub fn parse_size(flag: &str, s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("{flag} {s}: expected WIDTHxHEIGHT, e.g. 1280x720"))?;
    let w: u32 = w
        .trim()
        .parse()
        .with_context(|| format!("{flag} {s}: bad width"))?;
    let h: u32 = h
        .trim()
        .parse()
        .with_context(|| format!("{flag} {s}: bad height"))?;
    anyhow::ensure!(
        w > 0 && h > 0 && w <= 8192 && h <= 8192,
        "{flag} {s}: each side must be in 1..=8192"
    );
    Ok((w, h))
}

fn parse_occlusion(s: &str) -> anyhow::Result<OcclusionMode> {
    Ok(match s {
        "on" => OcclusionMode::On,
        "off" => OcclusionMode::Off,
        "auto" => OcclusionMode::Auto,
        _ => anyhow::bail!("--occlusion {s}: expected on, off or auto"),
    })
}

/// The route named on the command line, for `scene`, with the image's aspect.
pub fn choose_route(
    spec: &str,
    scene: &WalkScene,
    aspect: f64,
) -> anyhow::Result<(CameraRoute, Option<usize>)> {
    let lens = Lens {
        aspect,
        ..Lens::default()
    };
    let bounds = scene.city_bounds();
    let graph = StreetGraph::from_world_lines(&scene.street_edges, &scene.frame);
    Ok(match spec {
        "paper" => (
            route::paper_route(
                &bounds,
                Some(&graph).filter(|g| !g.is_empty()),
                &PaperRouteParams::default(),
                lens,
            )?,
            None,
        ),
        "orbit" => (route::orbit_route(&bounds, 1.3, 80.0, 60.0, lens)?, None),
        "street" => {
            anyhow::ensure!(
                !graph.is_empty(),
                "--route street: {} has no street graph",
                scene.name
            );
            let from = bounds.min.truncate();
            let to = bounds.max.truncate();
            (route::street_walk(&graph, from, to, 1.7, 1.4, lens)?, None)
        }
        file => {
            let f = RouteFile::read(std::path::Path::new(file))?;
            let mut r = f.to_route(Some(&scene.frame))?;
            r.lens.aspect = aspect;
            let frames = match f.frame_spec() {
                route::FrameSpec::Count(n) => n,
                route::FrameSpec::Rate(fps) => r.sample_rate(fps).len(),
            };
            (r, Some(frames))
        }
    })
}

/// Loads the city and builds the walk scene: blocks, one mesh per building, block bounds, the
/// structures asked for, and the occlusion culler unless occlusion is off.
fn build_scene(args: &Args, occlusion: OcclusionMode) -> anyhow::Result<WalkScene> {
    for s in &args.structures {
        anyhow::ensure!(
            STRUCTURES.contains(&s.as_str()),
            "unknown structure `{s}`; expected one of {}",
            STRUCTURES.join(", ")
        );
    }
    let city = load_city(&args.city)?;
    let pb = spinner("detecting blocks");
    let layout = detect(&city, &BlockOptions::default())
        .with_context(|| format!("detecting blocks of {}", city.name))?;
    pb.set_message("extruding buildings");
    let meshes = extrude_city(&city);
    pb.set_message("building the structures");
    let bounds = block_bounds(&city, &layout);
    let mut scene = WalkScene::from_city(&city, &layout, meshes, bounds);
    for s in &args.structures {
        let index = build_by_name(s, &scene.bounds)
            .with_context(|| format!("building structure {s} over {}", city.name))?;
        scene.structures.push(index);
    }
    if occlusion != OcclusionMode::Off {
        pb.set_message("extracting occluders");
        let culler = OcclusionCuller::new(&city, &layout, CullerOptions::default())
            .with_context(|| format!("occlusion culler for {}", city.name))?;
        scene.occlusion = Some(Box::new(culler));
    }
    pb.finish_and_clear();
    Ok(scene)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let size = parse_size("--size", &args.size)?;
    let occlusion = parse_occlusion(&args.occlusion)?;
    let scene = build_scene(&args, occlusion)?;
    let (route, file_frames) = choose_route(&args.route, &scene, size.0 as f64 / size.1 as f64)?;
    let frames = args.frames.or(file_frames).unwrap_or(300);
    anyhow::ensure!(frames > 0, "--frames must be at least 1");
    let params = WalkParams {
        route,
        frames,
        occlusion,
        render: args.render,
        image_every: if args.render { args.image_every } else { 0 },
        oracle: args.oracle,
        size,
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
    let report = run_walk(&scene, &params, &mut |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    let files = report
        .write(&args.out, args.frames_dir.as_deref())
        .with_context(|| format!("writing the report to {}", args.out.display()))?;
    if args.json {
        let mut j = report.json();
        j["out"] = serde_json::json!(args.out);
        j["files"] = serde_json::json!(files);
        println!("{}", serde_json::to_string(&j)?);
    } else {
        print_summary(&report, &args.out);
    }
    Ok(())
}

fn print_summary(report: &WalkReport, out: &std::path::Path) {
    println!(
        "{}: route {} with {} frames; renderer: {}",
        report.city,
        report.route,
        report.cameras.len(),
        report.renderer
    );
    print!("{}", report.summary_markdown());
    for n in &report.notes {
        println!("note: {n}");
    }
    println!(
        "report: {} ({:.1} s)",
        out.join("report.html").display(),
        report.total_s
    );
}
