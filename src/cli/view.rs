//! `blockwalk view`: fly through the city in a window (feature `window`), culling every frame
//! with one spatial structure and optionally the occlusion culler (seed 003 §4, seed 004 §3).
//!
//! Without a display: `xvfb-run -s "-screen 0 1280x720x24" blockwalk view CITY --frames 30
//! --screenshot view.png` renders 30 frames along the route and saves the last one.

use super::common::CityArgs;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route P plays: `paper`, `orbit`, `street`, or a route file (.toml / .json).
    #[arg(long, default_value = "paper")]
    pub route: String,
    /// The spatial structure that culls each frame (none, flat, vamsplit, bqr, rstar).
    #[arg(long, default_value = "bqr")]
    pub structure: String,
    /// Occlusion culling (occluder shadows + cull map): on or off.
    #[arg(long, default_value = "off")]
    pub occlusion: String,
    /// Initial window size, e.g. 1280x720.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Render `--frames` frames along the route, save the last as this PNG, and quit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Frames along the route in `--screenshot` mode.
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Flying speed, metres per second (Shift: five times).
    #[arg(long, default_value_t = 20.0)]
    pub speed: f64,
    /// Print one JSON object at the end instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

#[cfg(not(feature = "window"))]
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::bail!(
        "`blockwalk view {}` needs the interactive window: rebuild with `--features window` \
         (cargo run --features window -- view ...)",
        args.city
            .inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(" ")
    )
}

#[cfg(feature = "window")]
pub fn run(args: Args) -> anyhow::Result<()> {
    use super::common::{load_city, spinner};
    use anyhow::Context;
    use blockwalk::blocks::{detect, BlockOptions};
    use blockwalk::city::extrude::extrude_city;
    use blockwalk::index::{block_bounds, build_by_name, STRUCTURES};
    use blockwalk::render::window::{run_viewer, ViewerOptions, ViewerScene};
    use blockwalk::report::walk::{OcclusionProvider, WalkScene};
    use blockwalk::visibility::{CullerOptions, OcclusionCuller};

    let (width, height) = super::walk::parse_size("--size", &args.size)?;
    let occlusion = match args.occlusion.as_str() {
        "on" => true,
        "off" => false,
        o => anyhow::bail!("--occlusion {o}: expected on or off"),
    };
    anyhow::ensure!(
        STRUCTURES.contains(&args.structure.as_str()),
        "unknown structure `{}`; expected one of {}",
        args.structure,
        STRUCTURES.join(", ")
    );
    anyhow::ensure!(args.frames > 0, "--frames must be at least 1");
    anyhow::ensure!(
        args.speed.is_finite() && args.speed > 0.0,
        "--speed {}: expected a positive number",
        args.speed
    );
    let city = load_city(&args.city)?;
    let pb = spinner("detecting blocks");
    let layout = detect(&city, &BlockOptions::default())
        .with_context(|| format!("detecting blocks of {}", city.name))?;
    pb.set_message("extruding buildings");
    let meshes = extrude_city(&city);
    pb.set_message(format!("building {}", args.structure));
    let bounds = block_bounds(&city, &layout);
    let scene = WalkScene::from_city(&city, &layout, meshes, bounds);
    let index = build_by_name(&args.structure, &scene.bounds)
        .with_context(|| format!("building structure {} over {}", args.structure, city.name))?;
    let occluder: Option<Box<dyn OcclusionProvider>> = if occlusion {
        pb.set_message("extracting occluders");
        let culler = OcclusionCuller::new(&city, &layout, CullerOptions::default())
            .with_context(|| format!("occlusion culler for {}", city.name))?;
        Some(Box::new(culler))
    } else {
        None
    };
    pb.finish_and_clear();
    let (route, _) = super::walk::choose_route(&args.route, &scene, width as f64 / height as f64)?;
    let name = scene.name.clone();
    let viewer_scene = ViewerScene {
        name: name.clone(),
        meshes: scene.meshes,
        index,
        occlusion: occluder,
        route,
    };
    let summary = run_viewer(
        viewer_scene,
        ViewerOptions {
            width,
            height,
            screenshot: args.screenshot.clone(),
            frames: args.frames,
            speed: args.speed,
        },
    )
    .with_context(|| format!("viewing {name}"))?;
    if args.json {
        let mut j = serde_json::to_value(&summary)?;
        j["city"] = serde_json::json!(name);
        j["structure"] = serde_json::json!(args.structure);
        j["occlusion"] = serde_json::json!(occlusion);
        println!("{}", serde_json::to_string(&j)?);
    } else {
        println!(
            "{name}: {} frames at {:.1} fps on {}; last frame {} blocks, {} triangles ({}{})",
            summary.frames,
            summary.fps,
            summary.adapter,
            summary.blocks,
            summary.triangles,
            args.structure,
            if occlusion { " + occlusion" } else { "" }
        );
        if let Some(p) = &summary.screenshot {
            println!("screenshot: {}", p.display());
        }
    }
    Ok(())
}
