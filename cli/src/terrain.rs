//! `blockwalk terrain`: a city on an elevation model, its terrain as a level-of-detail tree
//! (tiles of a regular grid, a strict L∞ error per level measured at build, as Di Benedetto's
//! C-BDAM bounds it: *Multiresolution Techniques for Real-Time Visualization of Urban
//! Environments and Terrains*, ch. 3), cut per frame at a projected error of τ pixels along a
//! route, and measured against the full-resolution terrain in the same images.

use std::path::PathBuf;

use super::common::{load_scene, CityArgs, Size};
use blockwalk::route::RouteChoice;
use blockwalk::scene::SceneOptions;
use blockwalk::walk::terrain::{terrain_job, TerrainJob};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// The route the frames are sampled on (as `walk --route`).
    #[arg(long, default_value = "street")]
    pub route: RouteChoice,
    /// Frames along the route.
    #[arg(long, default_value_t = 40, value_parser = super::common::at_least_one)]
    pub frames: usize,
    /// Projected errors to cut the terrain at, pixels, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8")]
    pub tau: Vec<f64>,
    /// Image size.
    #[arg(long, default_value = "640x360")]
    pub size: Size,
    /// Write a frame strip here (PNG): the full-resolution terrain, the cut at --strip-tau, and
    /// the pixels whose id differs in red.
    #[arg(long)]
    pub strip: Option<PathBuf>,
    /// Frames in the strip.
    #[arg(long, default_value_t = 5, value_parser = super::common::at_least_one)]
    pub strip_frames: usize,
    /// The τ of the strip's middle row, pixels.
    #[arg(long, default_value_t = 1.0)]
    pub strip_tau: f64,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.city.dem.is_none() {
        anyhow::bail!("terrain needs an elevation model: --dem FILE");
    }
    let scene = load_scene(
        &args.city,
        0,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
    )?;
    let job = TerrainJob {
        route: args.route.clone(),
        frames: args.frames,
        taus: args.tau.clone(),
        size: args.size.pair(),
        strip: args.strip.clone().map(|p| (p, args.strip_frames)),
        strip_tau: args.strip_tau,
    };
    let sweep = terrain_job(&scene, &job)?
        .ok_or_else(|| anyhow::anyhow!("{} has no terrain", scene.name))?;
    if args.json {
        let mut v = serde_json::to_value(&sweep)?;
        v["city"] = serde_json::json!(scene.name);
        v["route"] = serde_json::json!(args.route.to_string());
        v["import"] = super::common::city_report_json(&scene.city);
        outln!("{}", serde_json::to_string(&v)?);
        return Ok(());
    }
    for line in super::common::city_report_lines(&scene.city) {
        outln!("{line}");
    }
    let t = &sweep.tree;
    outln!(
        "terrain tree: {}×{} nodes at {:.1} m, tiles of {} cells, depth {}, {} nodes; {:.1} MiB beside the grid's {:.1} MiB ({:.2}×)",
        t.grid[0],
        t.grid[1],
        t.spacing_m[0],
        t.tile_cells,
        t.depth,
        t.nodes,
        t.heap_bytes as f64 / 1048576.0,
        t.terrain_heap_bytes as f64 / 1048576.0,
        t.heap_bytes as f64 / t.terrain_heap_bytes.max(1) as f64
    );
    outln!("| level | stride | nodes | declared L∞ (m) | largest measured (m) |");
    outln!("|---:|---:|---:|---:|---:|");
    for l in &sweep.levels {
        outln!(
            "| {} | {} | {} | {:.3} | {:.3} |",
            l.level,
            l.stride,
            l.nodes,
            l.declared_error_m,
            l.max_measured_error_m
        );
    }
    outln!(
        "{} frames of the {} route at {}x{}, against the full-resolution terrain ({} triangles):",
        sweep.rows.first().map_or(0, |r| r.frames),
        args.route,
        sweep.size.0,
        sweep.size.1,
        sweep.rows.first().map_or(0, |r| r.full_triangles)
    );
    outln!("| τ (px) | tiles/frame | triangles/frame | select ms (mean / max) | declared px (max) | ids differing (mean / max) | PSNR dB (mean / min) | identical frames |");
    outln!("|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &sweep.rows {
        outln!(
            "| {} | {:.1} | {:.0} | {:.3} / {:.3} | {:.2} | {:.3} % / {:.3} % | {:.1} / {:.1} | {} |",
            r.tau_px,
            r.tiles_mean,
            r.triangles_mean,
            r.select_ms_mean,
            r.select_ms_max,
            r.declared_px_max,
            100.0 * r.mismatched_mean,
            100.0 * r.mismatched_max,
            r.psnr_db_mean,
            r.psnr_db_min,
            r.identical_frames
        );
    }
    if let Some(p) = &args.strip {
        outln!("wrote {}", p.display());
    }
    Ok(())
}
