//! `blockwalk relief-tree`: the relief-impostor tree over the city's buildings (Andujar,
//! Brunet, Chica and Navazo, *Visualization of Large-Scale Urban Models through Multi-Level
//! Relief Impostors*, §3 and §4.1): building groups, levels, the overlap ratio δ, and formulas
//! (3)–(9) beside the built tree.

use super::common::{load_scene, CityArgs};
use blockwalk::relief::tree::{TreeParams, TreeReport, DEFAULT_GAP_M, DEFAULT_MAX_DEPTH};
use blockwalk::scene::SceneOptions;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Footprints at most this far apart (metres, plan view) are one building group.
    #[arg(long, default_value_t = DEFAULT_GAP_M)]
    pub gap: f64,
    /// Deepest level of the tree (the root is 0).
    #[arg(long, default_value_t = DEFAULT_MAX_DEPTH)]
    pub max_depth: u32,
    /// Texel size asked for, metres (`ts` of formulas (5) and (9); the paper's finest is 0.17).
    #[arg(long, default_value_t = 0.17)]
    pub texel: f64,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let params = TreeParams::new(args.gap, args.max_depth)?;
    let scene = load_scene(
        &args.city,
        0,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
    )?;
    let r = TreeReport::new(&scene.city, &scene.layout, params, args.texel)?;
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
    let f = &r.formulas;
    outln!(
        "{}: {} buildings in {} groups (gap {} m), {} nodes, depth {}, {} median splits",
        scene.name,
        r.buildings,
        r.groups,
        r.params.gap_m,
        r.nodes,
        r.depth,
        r.median_splits
    );
    outln!("| level | nodes | leaves | mean edge m | mean δ | δ range | texel m (2ē/M) | formula (3) m |");
    outln!("|---|---|---|---|---|---|---|---|");
    for (l, t) in r.levels.iter().zip(&f.texel_by_level) {
        outln!(
            "| {} | {} | {} | {:.1} | {} | {} | {:.3} | {:.3} |",
            l.depth,
            l.nodes,
            l.leaves,
            l.mean_edge_m,
            l.mean_delta.map_or("–".into(), |d| format!("{d:.3}")),
            l.delta_range
                .map_or("–".into(), |[a, b]| format!("{a:.2} … {b:.2}")),
            t.1,
            t.2
        );
    }
    outln!(
        "L = {:.0} m, ω = {:.3}, δ = {:.3}; M = {} for blocks of {:.0} m at {} m a texel (9)",
        f.universe_m,
        f.coverage,
        f.delta,
        f.map_size,
        f.largest_block_m,
        f.texel_m
    );
    outln!(
        "depth: built {}, formula (5) {}, first level at the texel asked for {}",
        f.built_depth,
        f.predicted_depth
            .map_or("undefined (δ ≥ 1)".into(), |d| format!("{d:.2}")),
        f.texel_depth.map_or("none".into(), |d| d.to_string())
    );
    outln!(
        "nodes: built {} (I = {} = (T + W − 1)/3 = {:.0}, formula (6)); bound (7) {:.0}; (8), two levels by wavelets, {:.0}",
        f.nodes,
        f.interior.0,
        f.interior.1,
        f.node_bound,
        f.node_bound_two_virtual_levels
    );
    Ok(())
}
