//! `blockwalk farfield-sweep`: error against run time of the far field. For every representation
//! (BlockMaps at every K, relief impostors), route and τ, a hybrid walk with the reference (coverage error, PSNR, silhouette distance, popping) and
//! the mesh-only frames beside it ([`blockwalk::walk::sweep`]); the table (Markdown, JSON), the
//! Pareto plot of error against milliseconds, and the walk report of one configuration per
//! route, with frame time along the route (mesh-only vs hybrid) ([`blockwalk::report::sweep`]).
//! Not run in CI: it draws about four frames per camera.

use super::common::{choice, load_scene, spinner, CityArgs, ReliefArgs, Size};
use anyhow::Context;
use blockwalk::report::sweep::table_line;
use blockwalk::report::walk::{Machine, Plan, ReportContext};
use blockwalk::route::{RouteChoice, FLYOVER_NEAR_SHARE};
use blockwalk::scene::SceneOptions;
use blockwalk::walk::sweep::{run_sweep, SweepOptions};
use blockwalk::walk::{GpuRenderers, JobProgress, NoGpu};
use indicatif::ProgressBar;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Far-field representations side by side on the same routes, τ and image size:
    /// `blockmaps` (Cignoni et al.; at every K of --ks) and `relief` (multi-level relief
    /// impostors, Andujar et al.).
    #[arg(long = "far", value_delimiter = ',', default_value = "blockmaps", value_parser = choice::<blockwalk::walk::FarMode>())]
    pub fars: Vec<blockwalk::walk::FarMode>,
    #[command(flatten)]
    pub relief: ReliefArgs,
    /// Error thresholds τ, pixels.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8,16")]
    pub taus: Vec<f64>,
    /// BlockMaps' height-map sides K.
    #[arg(long, value_delimiter = ',', default_value = "32,64,128")]
    pub ks: Vec<u32>,
    /// Routes: `paper`, `orbit`, `flyover` (high, the whole city in view), `street`, or files.
    #[arg(long, value_delimiter = ',', default_value = "paper,orbit,flyover")]
    pub routes: Vec<RouteChoice>,
    /// Frames per route.
    #[arg(long, default_value_t = 12)]
    pub frames: usize,
    /// Image size.
    #[arg(long, default_value = "160x90")]
    pub size: Size,
    /// Draw with the GPU renderer when there is one (else the CPU hybrid renderer).
    #[arg(long)]
    pub gpu: bool,
    /// Output directory.
    #[arg(long, default_value = "farfield-sweep")]
    pub out: PathBuf,
    /// Seed of a `synthetic:` city.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Classify the coverage-mismatched pixels of each configuration's worst frames (largest
    /// coverage error, largest silhouette distance) by cause (`blockmap::diagnose`), into
    /// `OUT/diagnose_ROUTE_kK_tauT.{json,md}`.
    #[arg(long)]
    pub diagnose: bool,
    /// Half-planes per texel the maps store: 0 (whole texels), 1 (one footprint edge) or 2
    /// (a second where it fits the footprint more closely; the default), to measure each.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=2))]
    pub edges: u8,
    /// The fly-over's near plane as a share of its height above the highest roof (0: the
    /// lens's default, 0.5 m).
    #[arg(long, default_value_t = FLYOVER_NEAR_SHARE)]
    pub flyover_near_share: f64,
}

/// The sweep's stages on a spinner (hidden with `--json`).
struct Spinner(ProgressBar);

impl JobProgress for Spinner {
    fn stage(&self, what: &str) {
        self.0.set_message(what.to_string());
    }
}

impl Args {
    /// The sweep asked for.
    fn options(&self) -> anyhow::Result<SweepOptions> {
        Ok(SweepOptions {
            fars: self.fars.clone(),
            relief: self.relief.options()?,
            taus: self.taus.clone(),
            ks: self.ks.clone(),
            routes: self.routes.clone(),
            frames: self.frames,
            size: self.size.pair(),
            edges: self.edges,
            flyover_near_share: self.flyover_near_share,
            diagnose: self.diagnose,
        })
    }
}

/// The GPU renderers when `--gpu` asks for them and the build has them.
fn gpu(asked: bool) -> Box<dyn GpuRenderers> {
    if !asked {
        return Box::new(NoGpu("farfield-sweep"));
    }
    #[cfg(feature = "render")]
    {
        Box::new(blockwalk::render::WgpuRenderers)
    }
    #[cfg(not(feature = "render"))]
    {
        Box::new(NoGpu("built without the `render` feature"))
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let [one] = args.city.inputs.as_slice() {
        let loc = one.to_string_lossy();
        if blockwalk::stream::is_tiled_city(&loc) {
            return run_tiled(&args, &loc);
        }
    }
    let sweep_opts = args.options()?;
    sweep_opts.check()?;
    let opts = SceneOptions {
        structures: vec![blockwalk::index::Structure::Bqr],
        occlusion: None,
        ..SceneOptions::default()
    };
    let scene = load_scene(&args.city, args.seed, &opts)?;
    let pb = spinner(format!("sweeping {}", scene.name));
    if args.json {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let sweep = run_sweep(
        &scene,
        &sweep_opts,
        gpu(args.gpu).as_ref(),
        &Spinner(pb.clone()),
    )
    .with_context(|| format!("sweeping the far field of {}", scene.name))?;
    pb.finish_and_clear();
    let ctx = ReportContext {
        plan: Plan::from_scene(&scene),
        machine: Some(Machine::detect()),
        command: std::env::args().collect(),
        extra_plots: Vec::new(),
    };
    let files = blockwalk::report::sweep::write(&sweep, &args.out, &ctx)
        .with_context(|| format!("writing the sweep into {}", args.out.display()))?;
    if args.json {
        outln!(
            "{}",
            serde_json::to_string(&serde_json::json!({
                "city": sweep.city, "size": [sweep.size.0, sweep.size.1],
                "frames": sweep.frames, "builds": sweep.builds, "rows": sweep.rows,
                "notes": sweep.notes, "files": files,
            }))?
        );
        return Ok(());
    }
    outln!("{}:", sweep.city);
    outln!("{}", blockwalk::report::sweep::builds_table(&sweep.builds));
    for r in &sweep.rows {
        outln!("{}", table_line(r));
    }
    for d in &sweep.diagnoses {
        for f in &d.frames {
            outln!(
                "{} K = {} τ = {}: frame {}:\n{}",
                d.route,
                d.k,
                d.tau_px,
                f.frame,
                f.diagnosis.table()
            );
        }
    }
    for n in &sweep.notes {
        outln!("note: {n}");
    }
    outln!("table: {}", args.out.join("sweep.md").display());
    Ok(())
}

/// The sweep over a tiled city, streamed: its BlockMaps (the K its tiles were built with) at
/// every τ and route, against the mesh-only frames.
fn run_tiled(args: &Args, location: &str) -> anyhow::Result<()> {
    use blockwalk::stream::{LinkSpec, Mode, StreamCity, StreamOptions};
    if args
        .fars
        .iter()
        .any(|f| *f != blockwalk::walk::FarMode::Blockmaps)
    {
        anyhow::bail!("--far: a tiled city carries BlockMaps only (jobs run --blockmaps K)");
    }
    let city = StreamCity::open(location)?;
    let base = StreamOptions::new(
        1 << 30,
        4,
        LinkSpec::default(),
        Mode::Deterministic,
        1.0,
        args.size.pair(),
        0,
        None,
    )?;
    let pb = spinner(format!("sweeping {}", city.index.city));
    if args.json {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let rows = blockwalk::stream::sweep::run_sweep(
        &city,
        &args.routes,
        &args.taus,
        args.frames,
        &base,
        &mut |s| pb.set_message(s.to_string()),
    )?;
    pb.finish_and_clear();
    let j = serde_json::json!({
        "city": city.index.city,
        "source": city.startup.source,
        "tiles": city.startup.tiles,
        "maps": city.startup.maps,
        "rows": rows,
    });
    let path = args.out.join("sweep.json");
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    blockwalk::output::write_bytes(&path, serde_json::to_string_pretty(&j)?)?;
    if args.json {
        outln!("{}", serde_json::to_string(&j)?);
        return Ok(());
    }
    outln!(
        "{}: {} tiles, {} maps, streamed from {}; frames {}x{}",
        city.index.city,
        city.startup.tiles,
        city.startup.maps,
        city.startup.source,
        args.size.pair().0,
        args.size.pair().1
    );
    outln!("| route | τ px | frames (measured) | maps | meshes | hybrid ms | mesh ms | differing mean | differing max | PSNR min |");
    outln!("|---|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        outln!(
            "| {} | {} | {} ({}) | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} % | {:.2} % | {} |",
            r.route,
            r.tau_px,
            r.frames,
            r.measured,
            r.maps_mean,
            r.meshes_mean,
            r.hybrid_ms,
            r.mesh_ms,
            r.differing_mean * 100.0,
            r.differing_max * 100.0,
            r.psnr_min_db.map_or("∞".into(), |p| format!("{p:.1} dB"))
        );
    }
    outln!("report: {}", path.display());
    Ok(())
}
