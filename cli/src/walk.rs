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
    #[command(flatten)]
    pub stream: super::common::StreamArgs,
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
    if let [one] = args.city.inputs.as_slice() {
        let loc = one.to_string_lossy();
        if blockwalk::stream::is_tiled_city(&loc) {
            return run_streamed(&args, &loc);
        }
    }
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

/// A walk over a tiled city, streamed.
fn run_streamed(args: &Args, location: &str) -> anyhow::Result<()> {
    use blockwalk::stream::job;
    anyhow::ensure!(
        !args.oracle && !args.reference,
        "--oracle and --reference measure a city held in memory; a streamed walk compares every frame with its fully resident twin with --check (and farfield-sweep measures the far field against meshes)"
    );
    let mut options = args.stream.options(&args.far, args.size.pair())?;
    options.check = args.stream.check;
    options.keep_every = args.render.then_some(args.image_every);
    let job = job::StreamJob {
        location: location.to_string(),
        route: args.route.clone(),
        frames: args.frames.map(|f| f as usize),
        streets: args.city.streets.clone(),
        options,
    };
    let bar = super::common::spinner("streaming");
    if args.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let record = job::run_job(&job, &mut |d, n| bar.set_message(format!("frame {d}/{n}")))?;
    bar.finish_and_clear();
    let files = report::stream::write(&record, &args.out)
        .with_context(|| format!("writing the report to {}", args.out.display()))?;
    let s = &record.run.summary;
    if args.json {
        let mut j = report::stream::json(&record);
        j["out"] = serde_json::json!(args.out);
        j["files"] = serde_json::json!(files);
        outln!("{}", serde_json::to_string(&j)?);
        return Ok(());
    }
    let st = &record.city.startup;
    let mib = |b: u64| b as f64 / 1048576.0;
    outln!(
        "{}: {} tiles, {} blocks, {} buildings, {} maps ({:.1} MiB of content) from {}",
        record.city.index.city,
        st.tiles,
        st.blocks,
        st.buildings,
        st.maps,
        mib(st.content_bytes),
        st.source
    );
    for n in &record.notes {
        outln!("note: {n}");
    }
    for r in &st.refused {
        outln!(
            "refused: tile {} ({} buildings not drawn): {}",
            r.tile,
            r.buildings,
            r.why
        );
    }
    outln!(
        "opened in {:.0} ms ({:.2} MiB read, hierarchy {:.2} MiB in memory); first frame at {:.0} ms",
        st.seconds * 1e3,
        mib(st.bytes_read),
        mib(st.hierarchy_bytes),
        s.first_frame_s * 1e3
    );
    outln!(
        "route {} with {} frames, {:?} mode, budget {:.0} MiB{}: {} frames with stand-ins in {} episodes (the longest that ended: {} frames; still open at the end: {}){}",
        record.route,
        s.frames,
        s.options.mode,
        mib(s.options.budget_bytes),
        match s.options.link.bits_per_s {
            Some(b) => format!(", link {:.1} Mb/s + {:.0} ms", b / 1e6, s.options.link.latency_s * 1e3),
            None => String::new(),
        },
        s.frames_with_standins,
        s.episodes,
        s.episode_max_frames,
        s.unfinished_episodes,
        match s.first_converged {
            Some((f, t)) => format!(", first converged frame {f} at {t:.2} s"),
            None => ", never converged".into(),
        }
    );
    outln!(
        "loaded {} items ({:.1} MiB), hit rate {:.1} %, {} evicted, resident max {:.0} MiB; render-thread wait {:.3} s in all (max {:.3} s per frame); draw {:.0} ms per frame; peak RSS {}",
        s.loads,
        mib(s.bytes_loaded),
        s.hit_rate * 100.0,
        s.evictions,
        mib(s.resident_max_bytes),
        s.wait_total_s,
        s.wait_max_s,
        s.draw_mean_s * 1e3,
        s.peak_rss_bytes.map(|b| format!("{:.0} MiB", mib(b))).unwrap_or("unknown".into())
    );
    if let Some(d) = s.differing_max {
        outln!(
            "against fully resident frames: at most {:.2} % of pixels differ, PSNR min {}; converged frames that differ: {}",
            d * 100.0,
            s.psnr_min_db.map_or("∞ (identical)".into(), |p| format!("{p:.1} dB")),
            s.converged_but_different.unwrap_or(0)
        );
    }
    for r in s.refusals.iter().take(10) {
        outln!("frame {}: {}", r.frame, r.error);
    }
    if s.refusals.len() > 10 {
        outln!("… {} more refusals in stream.json", s.refusals.len() - 10);
    }
    outln!("report: {}", args.out.join("stream.json").display());
    Ok(())
}
