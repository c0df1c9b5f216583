//! `blockwalk cull-bench`: compare the spatial structures on frustum culling (Pina, Serón and Cerezo, §5.1).

use super::common::{load_scene, spinner, CityArgs};
use anyhow::{bail, Context};
use blockwalk::index::bench::{
    random_views, run_cull_bench, CullBenchParams, CullBenchReport, StructureReport,
};
use blockwalk::index::{synthetic::block_grid, BlockBounds, Structure};
use blockwalk::scene::{Scene, SceneOptions};
use blockwalk::visibility::CullerOptions;
use serde::Serialize;
use std::time::Instant;

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
        value_parser = super::common::choice::<Structure>(),
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
    /// Also cull every view through each structure with the occlusion culler (cull map, Willmott et al.,
    /// §3.2) and report it beside frustum-only culling. Needs a city (e.g. `synthetic:30x30`),
    /// not `--synthetic N`, which has blocks but no buildings to cast shadows.
    #[arg(long, conflicts_with = "synthetic")]
    pub occlusion: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(s) = args.structures.iter().find(|s| !s.culls_blocks()) {
        anyhow::bail!(
            "--structures {s}: cull-bench compares structures over blocks, and `{s}` culls pages of buildings (compare it with `blockwalk walk --structures bqr,{s}`)"
        );
    }
    let mut scene: Option<Scene> = None;
    let (name, bounds): (String, Vec<BlockBounds>) = match (&args.city, args.synthetic) {
        (_, Some(n)) => (
            format!("synthetic grid of {n} blocks"),
            block_grid(n as usize, args.seed),
        ),
        (Some(city_args), None) => {
            let opts = SceneOptions {
                structures: Vec::new(),
                occlusion: args.occlusion.then(CullerOptions::default),
                ..SceneOptions::default()
            };
            let s = load_scene(city_args, args.seed, &opts)?;
            let out = (s.name.clone(), s.bounds.clone());
            scene = Some(s);
            out
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
    let occlusion = match scene.as_ref().filter(|_| args.occlusion) {
        Some(scene) => occlusion_side_by_side(scene, &params)?,
        None => Vec::new(),
    };
    pb.finish_and_clear();
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        if args.occlusion {
            v["occlusion"] = serde_json::to_value(&occlusion)?;
        }
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
        print_side_by_side(&report, &occlusion)?;
    }
    let false_culls: u64 = report.structures.iter().map(|s| s.false_culls).sum();
    if false_culls > 0 {
        bail!("{false_culls} false culls (visible blocks dropped): a structure is broken");
    }
    Ok(())
}

/// One structure culled with the occlusion culler over the bench's views.
#[derive(Clone, Debug, Serialize)]
struct OcclusionRow {
    name: Structure,
    /// Median per-view time, cull map build and traversal with cull map tests, microseconds.
    total_us_median: f64,
    /// Median per-view time of the traversal with cull map tests alone, microseconds.
    traversal_us_median: f64,
    /// Mean nodes (and block volumes) visited per view.
    nodes_visited_mean: f64,
    /// Mean blocks kept per view.
    blocks_mean: f64,
    /// Mean volumes the cull map was asked about per view.
    map_tests_mean: f64,
    /// Views where the culler drew no map (e.g. the eye inside a building) and so filtered
    /// nothing.
    skipped: usize,
}

/// Every structure of `params` through the scene's occlusion culler, over the same seeded views
/// as the frustum-only bench.
fn occlusion_side_by_side(
    scene: &Scene,
    params: &CullBenchParams,
) -> anyhow::Result<Vec<OcclusionRow>> {
    let culler = scene
        .occlusion
        .as_ref()
        .context("the scene was loaded without an occlusion culler")?;
    let cams = random_views(
        &scene.bounds,
        params.views,
        params.seed,
        params.street_far_m,
        params.flying_far_m,
    );
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let mut rows = Vec::new();
    for &name in &params.structures {
        let index = name.build(&scene.bounds)?;
        let (mut total, mut traversal) = (Vec::new(), Vec::new());
        let (mut nodes, mut blocks, mut tests, mut skipped) = (0u64, 0u64, 0u64, 0usize);
        let mut out = Vec::new();
        for cam in &cams {
            out.clear();
            let t0 = Instant::now();
            let st = culler.cull(index.as_ref(), cam, &mut out);
            total.push(t0.elapsed().as_secs_f64() * 1e6);
            traversal.push(st.test_ms * 1e3);
            nodes += st.cull.nodes_visited;
            blocks += st.blocks_out;
            tests += st.volumes_tested;
            skipped += usize::from(st.skipped.is_some() || st.cells_covered == 0);
        }
        let n = cams.len().max(1) as f64;
        rows.push(OcclusionRow {
            name,
            total_us_median: median(&mut total),
            traversal_us_median: median(&mut traversal),
            nodes_visited_mean: nodes as f64 / n,
            blocks_mean: blocks as f64 / n,
            map_tests_mean: tests as f64 / n,
            skipped,
        });
    }
    Ok(rows)
}

fn print_side_by_side(r: &CullBenchReport, occ: &[OcclusionRow]) -> anyhow::Result<()> {
    if occ.is_empty() {
        return Ok(());
    }
    outln!(
        "frustum only vs frustum + occlusion (cull map at the culler's default resolution), same views; {} views drew no map",
        occ.first().map_or(0, |o| o.skipped)
    );
    outln!(
        "{:<9} | {:>10} {:>9} {:>8} | {:>10} {:>10} {:>9} {:>9} {:>8}",
        "structure",
        "µs md",
        "visited",
        "blocks",
        "µs md",
        "travers.",
        "visited",
        "map tests",
        "blocks"
    );
    for o in occ {
        let Some(s) = r.structures.iter().find(|s| s.name == o.name) else {
            continue;
        };
        outln!(
            "{:<9} | {:>10.1} {:>9.1} {:>8.1} | {:>10.1} {:>10.1} {:>9.1} {:>9.1} {:>8.1}",
            o.name,
            s.cull_us_median,
            s.nodes_visited_mean,
            s.blocks_accepted_mean,
            o.total_us_median,
            o.traversal_us_median,
            o.nodes_visited_mean,
            o.map_tests_mean,
            o.blocks_mean
        );
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
    let row = |name: &dyn std::fmt::Display, s: &StructureReport, note: &str| {
        outln!(
            "{:<9} {:>9.2} {:>7} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>9.1} {:>12.0} {:>7}{note}",
            name.to_string(),
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
        Ok::<(), anyhow::Error>(())
    };
    for s in &r.structures {
        row(&s.name, s, "")?;
    }
    if let Some(s) = &r.bqr_box_leaves {
        row(
            &"bqr-box",
            s,
            "   (bqr with box-only leaves: each block's sphere replaced by its box's)",
        )?;
    }
    if let Some(x) = r.bqr_over_vamsplit() {
        outln!(
            "BqR/VAMSplit: cull time {:.3}, nodes visited {:.3}, plane tests {:.3}, triangles {:.3} (Pina, Serón and Cerezo Table 1: frame time 0.638)",
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
