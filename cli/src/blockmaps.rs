//! `blockwalk blockmaps`: BlockMaps for the nodes of the block quadtree (Cignoni et al., §3–5, Di Benedetto's thesis
//! ch. 4), their measured error, written as PNG + JSON.

use super::common::{load_scene, CityArgs};
use blockwalk::blockmap::{BuildOptions, CityMapsOptions, Stop, TreeOptions};
use blockwalk::scene::SceneOptions;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Height-map side K: 32, 64 or 128.
    #[arg(long, default_value_t = 64)]
    pub k: u32,
    /// Maps for the first N levels of the quadtree.
    #[arg(long, conflicts_with = "leaf_blocks", value_parser = clap::value_parser!(u32).range(1..))]
    pub levels: Option<u32>,
    /// Maps down to nodes of at most M blocks. Without --levels or --leaf-blocks, maps stop
    /// where a node's meshes take fewer bytes than a map (Cignoni et al., §4).
    #[arg(long, value_parser = super::common::at_least_one)]
    pub leaf_blocks: Option<usize>,
    /// Output directory.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Write every map as NAME.png (lossless RGBA8) + NAME.json (box, Zmin/Zmax, K, slices, ε).
    #[arg(long)]
    pub png: bool,
    /// Maps to check against the oracle's mesh image (one random view each, 160x90, projected
    /// error 1 px), spread evenly over the list.
    #[arg(long, default_value_t = 8, value_parser = super::common::at_least_one)]
    pub check: usize,
    /// Height-map samples per texel side: 1 samples each texel's centre; N > 1 takes N×N samples
    /// and fills a texel when at least --fill-share of them hit a building.
    #[arg(long, default_value_t = BuildOptions::default().fill_samples)]
    pub fill_samples: u32,
    /// Share of a texel's samples that must hit a building to fill it.
    #[arg(long, default_value_t = BuildOptions::default().fill_share)]
    pub fill_share: f64,
    /// Compute ambient occlusion (Di Benedetto's thesis, §4.2.1), horizon-based over each map's height map.
    #[arg(long)]
    pub ao: bool,
    /// How far ambient occlusion looks for occluders, metres.
    #[arg(long, default_value_t = 30.0, value_parser = ao_radius)]
    pub ao_radius: f64,
    /// How inner nodes' maps are built: `polygons` (from the source footprints, as every leaf)
    /// or `children` (from their children's maps, max-filtered, with a derived ε that is also
    /// measured against the footprints).
    #[arg(long, default_value = "polygons", value_parser = ["polygons", "children"])]
    pub parents: String,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let stop = match (args.levels, args.leaf_blocks) {
        (Some(l), _) => Stop::Levels(l),
        (None, Some(m)) => Stop::LeafBlocks(m),
        (None, None) => Stop::Competitive,
    };
    let opts = CityMapsOptions {
        tree: TreeOptions {
            build: BuildOptions {
                k: args.k,
                ao: args.ao,
                ao_radius_m: args.ao_radius,
                fill_samples: args.fill_samples,
                fill_share: args.fill_share,
                ..BuildOptions::default()
            },
            parents: args.parents.parse()?,
            stop,
        },
        checks: args.check,
        check_size: (160, 90),
    };
    opts.tree.build.validate()?;
    let scene = load_scene(
        &args.city,
        0,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
    )?;
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
    let maps = scene.blockmaps(&opts, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    let path = maps.write(&args.out, args.png)?;
    let summary = maps.summary();
    if args.json {
        // The per-feature and per-check lists (148,098 thin features on Astana) stay in the
        // file; stdout gets the figures and where the lists are.
        let mut short = summary.clone();
        if let Some(o) = short.as_object_mut() {
            for key in ["thin", "dropped", "checks"] {
                o.remove(key);
            }
            o.insert(
                "details".into(),
                serde_json::json!(path.display().to_string()),
            );
            o.insert(
                "import".into(),
                super::common::city_report_json(&scene.city),
            );
        }
        outln!("{}", serde_json::to_string(&short)?);
    } else {
        for line in super::common::city_report_lines(&scene.city) {
            outln!("{line}");
        }
        print_summary(&summary, &path)?;
    }
    Ok(())
}

fn print_summary(s: &serde_json::Value, path: &std::path::Path) -> anyhow::Result<()> {
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
    let from_children = s["parents_from_children"].as_u64().unwrap_or(0);
    if from_children > 0 {
        outln!(
            "{from_children} parents built from their children's maps: derived ε max {:.2} m, {} measured above their derived ε",
            s["eps_derived_max"].as_f64().unwrap_or(0.0),
            s["measured_over_derived"]
        );
    }
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
        "thin features: {} ({}; {} raised parts, {} bridges, {} buildings no texel holds); all of them in {}",
        s["thin_features"],
        s["thin_by_kind"]
            .as_object()
            .map(|o| o
                .iter()
                .map(|(k, v)| format!("{v} {}", k.replace('_', " ")))
                .collect::<Vec<_>>()
                .join(", "))
            .unwrap_or_default(),
        s["raised_parts"],
        s["bridges"],
        s["dropped_buildings"],
        path.display()
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
    if !s["ao"].is_null() {
        outln!(
            "ambient occlusion: mean openness roofs {:.3}, ground {:.3}, walls {:.3}; {:.1} % of texels below 0.9",
            s["ao"]["roof_mean"].as_f64().unwrap_or(0.0),
            s["ao"]["ground_mean"].as_f64().unwrap_or(0.0),
            s["ao"]["wall_mean"].as_f64().unwrap_or(0.0),
            100.0 * s["ao"]["occluded_share"].as_f64().unwrap_or(0.0)
        );
    }
    let checks = s["checks"].as_array().map(|a| a.len()).unwrap_or(0);
    if checks > 0 {
        outln!(
            "checked {} maps against the meshes (one view each): coverage error mean {:.2} %, p95 {:.2} %, max {:.2} % ({} above {:.0} %); bound violations {} (apart: {} pixels of sub-pixel features, {} of reported thin or vanished buildings); PSNR min {} dB",
            checks,
            100.0 * s["coverage_error_mean"].as_f64().unwrap_or(0.0),
            100.0 * s["coverage_error_p95"].as_f64().unwrap_or(0.0),
            100.0 * s["coverage_error_max"].as_f64().unwrap_or(0.0),
            s["coverage_over_target"],
            100.0 * s["coverage_target"].as_f64().unwrap_or(0.0),
            s["bound_violations"],
            s["bound_subpixel_pixels"],
            s["bound_thin_pixels"],
            s["psnr_min_db"]
        );
    }
    Ok(())
}

fn ao_radius(s: &str) -> Result<f64, String> {
    let max = blockwalk::blockmap::build::MAX_AO_RADIUS_M;
    let v = super::common::f64_in(s, 0.0, max, "metres")?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "{v} is out of range: expected a radius above 0, at most {max} (metres)"
        ))
    }
}
