//! `blockwalk cull-bench`: compare the spatial structures on frustum culling (seed 003 §5.1).

use super::common::{load_scene, spinner, CityArgs};
use anyhow::{bail, Context};
use blockwalk::index::bench::{run_cull_bench, CullBenchParams, CullBenchReport};
use blockwalk::index::{synthetic::block_grid, BlockBounds, Structure};
use blockwalk::scene::SceneOptions;

/// The most blocks of a `--synthetic` grid.
pub const MAX_SYNTHETIC_BLOCKS: usize = 10_000_000;
/// The most views.
pub const MAX_VIEWS: u64 = 1_000_000;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The city (footprints, streets, parcels). Leave out with `--synthetic`.
    #[command(flatten)]
    pub city: Option<CityArgs>,
    /// Use a synthetic jittered grid of this many blocks instead of a city.
    #[arg(long, conflicts_with = "inputs", value_parser = clap::value_parser!(u64).range(1..=MAX_SYNTHETIC_BLOCKS as u64))]
    pub synthetic: Option<u64>,
    /// Structures to compare, comma separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "bqr,vamsplit,flat,none,rstar"
    )]
    pub structures: Vec<Structure>,
    /// Number of random views (half street level, half flying).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=MAX_VIEWS))]
    pub views: u64,
    /// Seed of the views (and of a synthetic city).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Skip the brute-force check (false culls are then not counted).
    #[arg(long)]
    pub no_check: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (name, bounds): (String, Vec<BlockBounds>) = match (&args.city, args.synthetic) {
        (_, Some(n)) => (
            format!("synthetic grid of {n} blocks"),
            block_grid(n as usize, args.seed),
        ),
        (Some(city_args), None) => {
            let opts = SceneOptions {
                structures: Vec::new(),
                ..SceneOptions::default()
            };
            let scene = load_scene(city_args, args.seed, &opts)?;
            (scene.name, scene.bounds)
        }
        (None, None) => bail!("give a city (footprint files) or --synthetic N"),
    };
    let params = CullBenchParams {
        structures: args.structures.clone(),
        views: args.views as usize,
        seed: args.seed,
        check: !args.no_check,
        ..CullBenchParams::default()
    };
    let pb = spinner(format!(
        "culling {} views over {} blocks",
        args.views,
        bounds.len()
    ));
    let report = run_cull_bench(&bounds, &params).context("building the structures")?;
    pb.finish_and_clear();
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["city"] = serde_json::Value::String(name);
        if let Some(r) = report.bqr_over_vamsplit() {
            v["bqr_over_vamsplit"] = serde_json::json!({
                "cull_time_median": r[0], "nodes_visited": r[1], "plane_tests": r[2],
                "triangles_accepted": r[3],
            });
        }
        outln!("{}", serde_json::to_string(&v)?);
    } else {
        print_summary(&name, &report)?;
    }
    let false_culls: u64 = report.structures.iter().map(|s| s.false_culls).sum();
    if false_culls > 0 {
        bail!("{false_culls} false culls (visible blocks dropped): a structure is broken");
    }
    Ok(())
}

fn print_summary(name: &str, r: &CullBenchReport) -> anyhow::Result<()> {
    outln!(
        "{name}: {} blocks, {} triangles, {} views (seed {}){}",
        r.blocks,
        r.triangles,
        r.views,
        r.seed,
        r.visible_blocks_mean
            .map(|v| format!(", {v:.1} blocks intersect a view on average"))
            .unwrap_or_default()
    );
    outln!(
        "{:<9} {:>9} {:>7} {:>10} {:>10} {:>10} {:>10} {:>9} {:>12} {:>7}",
        "structure",
        "build ms",
        "nodes",
        "cull µs md",
        "cull µs 95",
        "visited",
        "planes",
        "blocks",
        "triangles",
        "f.culls"
    );
    for s in &r.structures {
        outln!(
            "{:<9} {:>9.2} {:>7} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>9.1} {:>12.0} {:>7}",
            s.name,
            s.build_ms,
            s.nodes,
            s.cull_us_median,
            s.cull_us_p95,
            s.nodes_visited_mean,
            s.plane_tests_mean,
            s.blocks_accepted_mean,
            s.triangles_accepted_mean,
            s.false_culls
        );
    }
    if let Some(x) = r.bqr_over_vamsplit() {
        outln!(
            "BqR/VAMSplit: cull time {:.3}, nodes visited {:.3}, plane tests {:.3}, triangles {:.3} (seed 003 Table 1: frame time 0.638)",
            x[0], x[1], x[2], x[3]
        );
    }
    for v in &r.volumes {
        outln!(
            "per-block {:<10} false accepts {:>6.2} % of {} accepted",
            v.volume,
            100.0 * v.false_accept_rate,
            v.accepted
        );
    }
    Ok(())
}
