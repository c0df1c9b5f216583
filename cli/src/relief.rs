//! `blockwalk relief`: multi-level relief impostors for the city (Andujar, Brunet, Chica and
//! Navazo, *Visualization of Large-Scale Urban Models through Multi-Level Relief Impostors*,
//! §3–4): the tree over whole blocks, every node's zenithal and oblique maps, what they cost and
//! the coverage error measured against the meshes.

use super::common::{load_scene, CityArgs, ReliefArgs};
use blockwalk::scene::SceneOptions;
use blockwalk::walk::JobProgress;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    #[command(flatten)]
    pub relief: ReliefArgs,
    /// Print one JSON object instead of the human summary (every node below the coverage
    /// target is listed there).
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = args.relief.options()?;
    let scene = load_scene(
        &args.city,
        0,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
    )?;
    let progress = super::common::Progress::new(args.json);
    progress.stage(&format!("building the relief impostors of {}", scene.name));
    let field = blockwalk::relief::build_field(
        &scene.city,
        &scene.layout,
        &scene.building_meshes,
        &opts,
        &|d, t| progress.count(d, t),
    )?;
    progress.finish();
    let r = field.report();
    if args.json {
        let mut v = serde_json::to_value(&r)?;
        v["city"] = serde_json::json!(scene.name);
        v["import"] = super::common::city_report_json(&scene.city);
        outln!("{}", serde_json::to_string(&v)?);
        return Ok(());
    }
    for line in super::common::city_report_lines(&scene.city) {
        outln!("{line}");
    }
    let s = &r.summary;
    let f = &r.formulas;
    outln!(
        "{}: {} buildings in {} groups (whole blocks, gap {} m); {} of the tree's {} nodes mapped ({}), M = {}{} for blocks of {:.0} m at {} m a texel",
        scene.name,
        scene.city.buildings.len(),
        r.groups,
        opts.tree.gap_m,
        s.nodes,
        s.tree_nodes,
        opts.stop,
        s.map_size,
        if !s.map_size_from_formula {
            " (given)"
        } else if s.map_size_capped {
            " (formula (9), capped)"
        } else {
            " (formula (9))"
        },
        f.largest_block_m,
        opts.texel_m
    );
    outln!(
        "oblique maps per node: {:.1} mean, {} max; coverage of the seeable walls {:.1} % mean, {:.1} % min ({} % of the wall area is seen from no direction)",
        s.obliques_mean,
        s.obliques_max,
        100.0 * s.coverage_mean,
        100.0 * s.coverage_min,
        format_args!("{:.1}", 100.0 * s.unseeable_share)
    );
    if !s.below_target.is_empty() {
        let list: Vec<String> = s
            .below_target
            .iter()
            .take(8)
            .map(|b| format!("node {} ({:.1} %)", b.node, 100.0 * b.coverage))
            .collect();
        outln!(
            "{} nodes below the {:.0} % coverage target: {}{}",
            s.below_target.len(),
            100.0 * opts.coverage_target,
            list.join(", "),
            if s.below_target.len() > 8 {
                ", … (all in --json)"
            } else {
                ""
            }
        );
    }
    outln!(
        "coverage error (orthographic views against the meshes, per node): max {:.2} %, p95 {:.2} %, mean {:.2} %; colour PSNR min {:.1} dB, at most {:.1} % of a node's pixels off by more than {} (sub-texel façade detail)",
        100.0 * s.coverage_error_max,
        100.0 * s.coverage_error_p95,
        100.0 * s.coverage_error_mean,
        s.psnr_min_db,
        100.0 * s.colour_mismatch_max,
        blockwalk::relief::error::COLOUR_TOLERANCE
    );
    outln!(
        "bytes: {:.1} MiB, {:.0} KiB a node, {:.2} MiB/km² of the root cell; deepest maps' texels {:.2}–{:.2} m; built in {:.1} s",
        s.bytes as f64 / (1024.0 * 1024.0),
        s.bytes_per_node / 1024.0,
        s.bytes_per_km2 / (1024.0 * 1024.0),
        s.leaf_texel_m[0],
        s.leaf_texel_m[1],
        s.build_s
    );
    outln!(
        "| level | nodes | texel m | δ | obliques | coverage | coverage error max | MiB | s/node |"
    );
    outln!("|---|---|---|---|---|---|---|---|---|");
    for (l, t) in r.levels.iter().zip(&r.tree_levels) {
        outln!(
            "| {} | {} | {:.2} | {} | {:.1} | {:.1} % | {:.2} % | {:.1} | {:.3} |",
            l.depth,
            l.nodes,
            l.texel_m,
            t.mean_delta.map_or("–".into(), |d| format!("{d:.3}")),
            l.obliques_mean,
            100.0 * l.coverage_mean,
            100.0 * l.coverage_error_max,
            l.bytes as f64 / (1024.0 * 1024.0),
            l.seconds_per_node
        );
    }
    outln!(
        "formulas: L = {:.0} m, ω = {:.3}, δ = {:.3}; depth built {}, (5) {}; nodes built {}, bound (7) {:.0}, (8) {:.0}",
        f.universe_m,
        f.coverage,
        f.delta,
        f.built_depth,
        f.predicted_depth
            .map_or("undefined (δ ≥ 1)".into(), |d| format!("{d:.2}")),
        f.nodes,
        f.node_bound,
        f.node_bound_two_virtual_levels
    );
    Ok(())
}
