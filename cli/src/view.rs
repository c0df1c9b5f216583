//! `blockwalk view`: fly through the city in a window (feature `window`), culling every frame
//! with one spatial structure and optionally the occlusion culler (Pina, Serón and Cerezo, §4, Willmott et al., §3).
//!
//! Without a display: `xvfb-run -s "-screen 0 1280x720x24" blockwalk view CITY --frames 30
//! --screenshot view.png` renders 30 frames along the route and saves the last one.

use super::common::{CityArgs, Size};
use blockwalk::index::Structure;
use blockwalk::route::RouteChoice;
#[cfg(feature = "window")]
use blockwalk::walk::FarMode;
use std::path::PathBuf;

/// The viewer's keys, shown by `blockwalk view --help` and printed to standard error when the
/// window opens.
pub const KEYS: &str = "Keys:
  W A S D, arrow keys   move
  left mouse drag       look around
  Q / E, PageDown / Up  move down / up
  Shift                 move five times faster
  P                     play or pause the route
  Esc                   quit
The title shows frames per second, blocks and triangles drawn, and the structure.";

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route P plays: `paper`, `orbit`, `street`, `flyover`, `corners`, or a route file
    /// (.toml / .json).
    #[arg(long, default_value = "paper")]
    pub route: RouteChoice,
    /// The spatial structure that culls each frame.
    #[arg(long, value_parser = super::common::choice::<Structure>(), default_value_t = Structure::Bqr)]
    pub structure: Structure,
    /// Occlusion culling (occluder shadows + cull map).
    #[arg(long, value_enum, default_value_t = Switch::Off)]
    pub occlusion: Switch,
    /// Initial window size, e.g. 1280x720.
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Render `--frames` frames along the route, save the last as this PNG, and quit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Frames along the route in `--screenshot` mode.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub frames: u64,
    /// Flying speed, metres per second (Shift: five times).
    #[arg(long, default_value_t = 20.0)]
    pub speed: f64,
    /// Seed of a `synthetic:` city.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub far: super::common::FarArgs,
    #[command(flatten)]
    pub stream: super::common::StreamArgs,
    /// Print one JSON object at the end instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

/// On or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

#[cfg(feature = "window")]
impl Args {
    /// The window's size, screenshot mode and speed, checked.
    fn viewer_options(&self) -> anyhow::Result<blockwalk::render::window::ViewerOptions> {
        anyhow::ensure!(
            self.speed.is_finite() && self.speed > 0.0,
            "--speed {}: expected a positive number",
            self.speed
        );
        Ok(blockwalk::render::window::ViewerOptions {
            width: self.size.width,
            height: self.size.height,
            screenshot: self.screenshot.clone(),
            frames: self.frames as usize,
            speed: self.speed,
        })
    }
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
    use super::common::load_scene;
    use anyhow::Context;
    use blockwalk::render::window::{run_viewer, ViewerFar, ViewerScene};
    use blockwalk::scene::SceneOptions;
    use blockwalk::visibility::CullerOptions;

    if let [one] = args.city.inputs.as_slice() {
        let loc = one.to_string_lossy();
        if blockwalk::stream::is_tiled_city(&loc) {
            return run_streamed(&args, &loc);
        }
    }
    let occlusion = args.occlusion == Switch::On;
    anyhow::ensure!(
        args.structure.culls_blocks(),
        "--structure {}: the viewer draws blocks, and `{}` culls pages of buildings (use `blockwalk walk --structures {}`)",
        args.structure,
        args.structure,
        args.structure
    );
    let select = args.far.select()?;
    let opts = SceneOptions {
        structures: vec![args.structure],
        occlusion: occlusion.then(CullerOptions::default),
        ..SceneOptions::default()
    };
    let scene = load_scene(&args.city, args.seed, &opts)?;
    let (route, _) = blockwalk::walk::job::resolve_route(&args.route, &scene, args.size.aspect())?;
    let name = scene.name.clone();
    let far = match args.far.mode {
        FarMode::None => None,
        mode => Some(ViewerFar {
            field: {
                let progress = super::common::Progress::new(args.json);
                let f = blockwalk::walk::job::build_far(
                    &scene,
                    mode,
                    &args.far.blockmaps(),
                    &args.far.relief.options()?,
                    &progress,
                )?
                .ok_or_else(|| anyhow::anyhow!("no far field was asked for"))?;
                progress.finish();
                f
            },
            select,
        }),
    };
    let far_on = far.is_some();
    eprintln!("{KEYS}");
    let viewer_scene = ViewerScene {
        scene,
        structure: args.structure,
        occlusion,
        route,
        far,
    };
    let summary = run_viewer(viewer_scene, args.viewer_options()?)
        .with_context(|| format!("viewing {name}"))?;
    if args.json {
        let mut j = serde_json::to_value(&summary)?;
        j["city"] = serde_json::json!(name);
        j["structure"] = serde_json::json!(args.structure);
        j["occlusion"] = serde_json::json!(occlusion);
        j["far"] = serde_json::json!(args.far.mode);
        if far_on {
            j["tau"] = serde_json::json!(args.far.tau);
            j["k"] = serde_json::json!(args.far.k);
        }
        outln!("{}", serde_json::to_string(&j)?);
    } else {
        outln!(
            "{name}: {} frames at {:.1} fps on {}; last frame {} blocks, {} triangles ({}{})",
            summary.frames,
            summary.fps,
            summary.adapter,
            summary.blocks,
            summary.triangles,
            args.structure,
            if occlusion { " + occlusion" } else { "" }
        );
        if far_on {
            let which = match args.far.mode {
                FarMode::Blockmaps => format!("BlockMaps K = {}", args.far.k),
                _ => "relief impostors".to_string(),
            };
            outln!(
                "far field: {which} at τ = {} px; {} nodes in the last frame ({} pixels), {:.1} per frame",
                args.far.tau,
                summary.far_nodes,
                summary.far_pixels,
                summary.far_nodes_mean
            );
        }
        if let Some(p) = &summary.screenshot {
            outln!("screenshot: {}", p.display());
        }
    }
    Ok(())
}

/// The viewer over a tiled city, streamed.
#[cfg(feature = "window")]
fn run_streamed(args: &Args, location: &str) -> anyhow::Result<()> {
    use anyhow::Context;
    use blockwalk::render::window_stream::run_stream_viewer;
    let opts = args.stream.options(&args.far, args.size.pair())?;
    let city = blockwalk::stream::StreamCity::open(location)?;
    let (route, _, notes) = blockwalk::stream::job::route_for(
        &city,
        &args.route,
        args.city.streets.as_deref(),
        args.size.aspect(),
    )?;
    for n in notes {
        eprintln!("note: {n}");
    }
    eprintln!("{KEYS}");
    let summary = run_stream_viewer(&city, &opts, route, args.viewer_options()?)
        .with_context(|| format!("viewing {location}"))?;
    let name = &city.index.city;
    if args.json {
        let mut j = serde_json::to_value(&summary)?;
        j["city"] = serde_json::json!(name);
        j["streamed"] = serde_json::json!(city.startup);
        outln!("{}", serde_json::to_string(&j)?);
    } else {
        outln!(
            "{name} (streamed from {}): {} frames at {:.1} fps on {} (frames drawn by the CPU hybrid renderer), {:.1} maps per frame",
            city.startup.source,
            summary.frames,
            summary.fps,
            summary.adapter,
            summary.far_nodes_mean
        );
        if let Some(p) = &summary.screenshot {
            outln!("screenshot: {}", p.display());
        }
    }
    Ok(())
}
