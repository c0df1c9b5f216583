//! `blockwalk blockmaps`: BlockMaps for the nodes of the block quadtree (seed 000 §3–5, seed 002
//! ch. 4), their measured error, written as PNG + JSON.

use super::common::{load_city, spinner, CityArgs};
use anyhow::Context;
use blockwalk::blockmap::compare::{compare_view, random_views, ViewCompare};
use blockwalk::blockmap::{build_tree, BuildOptions, MapTree, Source, Stop, TreeOptions};
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::index::{block_bounds, BqrParams, BqrTree};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Height-map side K: 32, 64 or 128.
    #[arg(long, default_value_t = 64)]
    pub k: u32,
    /// Maps for the first N levels of the quadtree.
    #[arg(long, conflicts_with = "leaf_blocks")]
    pub levels: Option<u32>,
    /// Maps down to nodes of at most M blocks. Without --levels or --leaf-blocks, maps stop
    /// where a node's meshes take fewer bytes than a map (seed 000 §4).
    #[arg(long)]
    pub leaf_blocks: Option<usize>,
    /// Output directory.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Write every map as NAME.png (lossless RGBA8) + NAME.json (box, Zmin/Zmax, K, slices, ε).
    #[arg(long)]
    pub png: bool,
    /// Maps to check against the oracle's mesh image (one random view each, 160x90, projected
    /// error 1 px), spread evenly over the list.
    #[arg(long, default_value_t = 8)]
    pub check: usize,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        blockwalk::blockmap::layout::ALLOWED_K.contains(&args.k),
        "--k {}: expected 32, 64 or 128",
        args.k
    );
    if let Some(l) = args.levels {
        anyhow::ensure!(l >= 1, "--levels must be at least 1");
    }
    let stop = match (args.levels, args.leaf_blocks) {
        (Some(l), _) => Stop::Levels(l),
        (None, Some(m)) => Stop::LeafBlocks(m),
        (None, None) => Stop::Competitive,
    };
    let city = load_city(&args.city)?;
    let pb = spinner("detecting blocks");
    let layout = detect(&city, &BlockOptions::default())
        .with_context(|| format!("detecting blocks of {}", city.name))?;
    pb.set_message("extruding buildings");
    let meshes = extrude_city(&city);
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default())
        .with_context(|| format!("building the block quadtree of {}", city.name))?;
    pb.finish_and_clear();
    let source = Source::new(&city, &layout, &meshes)?;
    let opts = TreeOptions {
        build: BuildOptions {
            k: args.k,
            ..BuildOptions::default()
        },
        stop,
    };
    let bar = if args.json || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr())
    };
    bar.set_style(
        ProgressStyle::with_template("blockmaps [{bar:40}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let t0 = Instant::now();
    let maps = build_tree(&source, &layout, &tree, &opts, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    let build_s = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    maps.check_invariants();

    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if args.png {
        for m in &maps.maps {
            m.map
                .write(&args.out, &format!("node_{:x}", m.key))
                .with_context(|| format!("writing the map of node {}", m.key))?;
        }
    }
    // Checks against the meshes.
    let mut checks: Vec<(u64, ViewCompare)> = Vec::new();
    if args.check > 0 && !maps.maps.is_empty() {
        let n = args.check.min(maps.maps.len());
        for q in 0..n {
            let m = &maps.maps[q * maps.maps.len() / n];
            let cam = random_views(&m.map, 1, m.key, 90)[0];
            checks.push((
                m.key,
                compare_view(&m.map, &source, &m.buildings, &cam, 160, 90),
            ));
        }
    }
    let area_km2 = {
        let b = bounds
            .iter()
            .fold(blockwalk::geom::Aabb3::EMPTY, |a, b| a.union(b.aabb));
        let e = b.extent();
        (e.x * e.y / 1e6).max(1e-9)
    };
    let summary = summarize(&maps, build_s, area_km2, &checks, &city.name, args.k);
    std::fs::write(
        args.out.join("blockmaps.json"),
        serde_json::to_string_pretty(&summary)?,
    )
    .with_context(|| format!("writing {}", args.out.join("blockmaps.json").display()))?;
    if args.json {
        outln!("{}", serde_json::to_string(&summary)?);
    } else {
        print_summary(&summary)?;
    }
    Ok(())
}

fn summarize(
    maps: &MapTree,
    build_s: f64,
    area_km2: f64,
    checks: &[(u64, ViewCompare)],
    name: &str,
    k: u32,
) -> serde_json::Value {
    let bytes: usize = maps.maps.iter().map(|m| m.map.bytes()).sum();
    let mut levels: BTreeMap<u32, serde_json::Value> = BTreeMap::new();
    let max_level = maps.maps.iter().map(|m| m.level).max().unwrap_or(0);
    for l in 0..=max_level {
        let at: Vec<_> = maps.maps.iter().filter(|m| m.level == l).collect();
        if at.is_empty() {
            continue;
        }
        let f = |g: &dyn Fn(&&blockwalk::blockmap::NodeMap) -> f64| {
            at.iter().map(g).fold(0.0, f64::max)
        };
        levels.insert(
            l,
            serde_json::json!({
                "level": l,
                "maps": at.len(),
                "texel_m_max": f(&|m| m.map.texel_m()),
                "eps_declared_max_m": f(&|m| m.map.meta.eps_m),
                "eps_measured_max_m": f(&|m| m.error.measured_m),
                "half_voxel_diagonal_max_m": f(&|m| m.error.half_voxel_diagonal_m),
                "exposed_texels": at.iter().map(|m| m.stats.exposed_texels).sum::<usize>(),
                "shared_columns": at.iter().map(|m| m.stats.shared_columns).sum::<usize>(),
                "slices_max": at.iter().map(|m| m.stats.slices).max().unwrap_or(1),
                "thin_features": at.iter().map(|m| m.error.thin.len()).sum::<usize>(),
            }),
        );
    }
    let thin: Vec<serde_json::Value> = maps
        .maps
        .iter()
        .flat_map(|m| {
            m.error.thin.iter().map(move |t| {
                serde_json::json!({"node": m.key, "level": m.level, "kind": t.kind,
                    "building": t.building, "source_id": t.source_id, "error_m": t.error_m, "at": t.at})
            })
        })
        .collect();
    let eps_declared_max = maps
        .maps
        .iter()
        .map(|m| m.map.meta.eps_m)
        .fold(0.0, f64::max);
    let eps_measured_max = maps
        .maps
        .iter()
        .map(|m| m.error.measured_m)
        .fold(0.0, f64::max);
    let bound_violations: usize = checks
        .iter()
        .map(|(_, c)| c.point_violations + c.beyond_bound)
        .sum();
    let cov_max = checks
        .iter()
        .map(|(_, c)| c.coverage_error)
        .fold(0.0, f64::max);
    let psnr_min = checks
        .iter()
        .map(|(_, c)| c.psnr_db)
        .fold(f64::INFINITY, f64::min);
    serde_json::json!({
        "city": name,
        "k": k,
        "maps": maps.maps.len(),
        "bytes": bytes,
        "bytes_per_map": maps.maps.first().map(|m| m.map.bytes()).unwrap_or(0),
        "area_km2": area_km2,
        "mib_per_km2": bytes as f64 / 1048576.0 / area_km2,
        "build_s": build_s,
        "eps_declared_max": eps_declared_max,
        "eps_measured_max": eps_measured_max,
        "bound_violations": bound_violations,
        "thin_features": thin.len(),
        "thin": thin,
        "raised_parts": maps.maps.iter().map(|m| m.error.raised_parts).sum::<usize>(),
        "bridges": maps.maps.iter().map(|m| m.error.bridges).sum::<usize>(),
        "dropped_buildings": maps.maps.iter().map(|m| m.stats.dropped_buildings.len()).sum::<usize>(),
        "levels": levels.into_values().collect::<Vec<_>>(),
        "checks": checks.iter().map(|(k, c)| serde_json::json!({"node": k, "view": c})).collect::<Vec<_>>(),
        "coverage_error_max": cov_max,
        "psnr_min_db": if psnr_min.is_finite() { serde_json::json!(psnr_min) } else { serde_json::Value::Null },
    })
}

fn print_summary(s: &serde_json::Value) -> anyhow::Result<()> {
    outln!(
        "{}: {} BlockMaps at K = {} ({} KiB each), {:.1} MiB, {:.2} MiB per km² over {:.2} km², built in {:.1} s",
        s["city"].as_str().unwrap_or(""),
        s["maps"],
        s["k"],
        s["bytes_per_map"].as_u64().unwrap_or(0) / 1024,
        s["bytes"].as_f64().unwrap_or(0.0) / 1048576.0,
        s["mib_per_km2"].as_f64().unwrap_or(0.0),
        s["area_km2"].as_f64().unwrap_or(0.0),
        s["build_s"].as_f64().unwrap_or(0.0)
    );
    outln!("| level | maps | texel m | ½ voxel diag m | ε measured m | ε declared m | exposed | shared cols | slices | thin |");
    outln!("|---|---|---|---|---|---|---|---|---|---|");
    for l in s["levels"].as_array().into_iter().flatten() {
        outln!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} |",
            l["level"],
            l["maps"],
            l["texel_m_max"].as_f64().unwrap_or(0.0),
            l["half_voxel_diagonal_max_m"].as_f64().unwrap_or(0.0),
            l["eps_measured_max_m"].as_f64().unwrap_or(0.0),
            l["eps_declared_max_m"].as_f64().unwrap_or(0.0),
            l["exposed_texels"],
            l["shared_columns"],
            l["slices_max"],
            l["thin_features"]
        );
    }
    outln!(
        "thin features: {} ({} raised parts, {} bridges, {} buildings dropped by point sampling)",
        s["thin_features"],
        s["raised_parts"],
        s["bridges"],
        s["dropped_buildings"]
    );
    for t in s["thin"].as_array().into_iter().flatten().take(10) {
        outln!(
            "  node {} level {}: {} building {} ({}) error {:.2} m",
            t["node"],
            t["level"],
            t["kind"].as_str().unwrap_or(""),
            t["building"],
            t["source_id"].as_str().unwrap_or(""),
            t["error_m"].as_f64().unwrap_or(0.0)
        );
    }
    let checks = s["checks"].as_array().map(|a| a.len()).unwrap_or(0);
    if checks > 0 {
        outln!(
            "checked {} maps against the meshes: coverage error max {:.4}, bound violations {}, PSNR min {} dB",
            checks,
            s["coverage_error_max"].as_f64().unwrap_or(0.0),
            s["bound_violations"],
            s["psnr_min_db"]
        );
    }
    Ok(())
}
