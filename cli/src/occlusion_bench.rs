//! `blockwalk occlusion-bench`: occlusion culling with the cull map at several resolutions over
//! random street-level and flying views, checked against the CPU visibility oracle (Willmott et al.
//! §3.2): ms per frame, occluders, blocks culled, false culls, effectiveness, and a plot of
//! effectiveness against time.

use super::common::{load_scene, CityArgs, Size};
use anyhow::{bail, Context};
use blockwalk::index::Structure;
use blockwalk::report::plot::{write_plot, PlotKind, Series};
use blockwalk::scene::SceneOptions;
use blockwalk::visibility::bench::{run_occlusion_bench, BenchOptions, BenchScene};
use blockwalk::visibility::views::ViewOptions;
use blockwalk::visibility::CullerOptions;
use std::path::PathBuf;

/// The most views.
pub const MAX_VIEWS: u64 = 1_000_000;

/// A fraction in 0..=1 (NaN and values outside are refused).
fn fraction(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not in 0..=1"))
    }
}

/// A positive, finite number.
fn positive(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a positive finite number"))
    }
}

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The city. `synthetic:COLSxROWS` instead of a file generates a street grid of box buildings
    /// (about 27 buildings per block; `synthetic:55x55` has about 80,000).
    #[command(flatten)]
    pub city: CityArgs,
    /// Cull map cells along the longer side, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "64,128,256,512,1024")]
    pub resolution: Vec<u32>,
    /// Number of random views.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=MAX_VIEWS))]
    pub views: u64,
    /// Fraction of street-level views (the rest fly).
    #[arg(long, default_value_t = 0.7, value_parser = fraction)]
    pub street_fraction: f64,
    /// Seed of the views (and of a synthetic city).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Oracle image size, WxH.
    #[arg(long, default_value = "640x360")]
    pub oracle: Size,
    /// Blocks within this distance of the eye give occluders, metres.
    #[arg(long, default_value_t = 300.0, value_parser = positive)]
    pub local_radius: f64,
    /// At most this many occluders per frame.
    #[arg(long, default_value_t = 256)]
    pub max_occluders: usize,
    /// Spatial structure frustum culling runs on.
    #[arg(long, value_parser = super::common::choice::<Structure>(), default_value_t = Structure::Bqr)]
    pub index: Structure,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Plot of effectiveness against milliseconds per frame (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let oracle_size = args.oracle.pair();
    if args.resolution.is_empty() {
        bail!("--resolution: give at least one");
    }
    if !args.index.culls_blocks() {
        bail!(
            "--index {}: the occlusion bench culls blocks, and `{}` culls pages of buildings",
            args.index,
            args.index
        );
    }
    let opts = SceneOptions {
        structures: vec![args.index],
        ..SceneOptions::default()
    };
    let scene_data = load_scene(&args.city, args.seed, &opts)?;
    let refs: Vec<_> = scene_data
        .block_meshes()
        .iter()
        .map(|(id, m)| (*id, m))
        .collect();
    let index = scene_data
        .index(args.index)
        .expect("the scene builds the structure asked for");
    let city = &scene_data.city;
    let scene = BenchScene {
        city,
        layout: &scene_data.layout,
        meshes: &refs,
        index,
    };
    let opts = BenchOptions {
        resolutions: args.resolution.clone(),
        views: ViewOptions {
            views: args.views as usize,
            street_fraction: args.street_fraction,
            seed: args.seed,
            ..ViewOptions::default()
        },
        oracle_size,
        culler: CullerOptions {
            local_radius: args.local_radius,
            max_occluders: args.max_occluders,
            ..Default::default()
        },
    };
    let bar = indicatif::ProgressBar::new(args.views);
    if args.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let report = run_occlusion_bench(&scene, &opts, &mut |done, _| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    if let Some(p) = &args.plot {
        let series = vec![Series {
            name: format!("cull map ({} views, index {})", report.views, args.index),
            points: report
                .resolutions
                .iter()
                .map(|r| (r.median_ms, r.effectiveness * 100.0))
                .collect(),
        }];
        write_plot(
            p,
            "Occlusion culling: effectiveness against time per frame",
            "median ms per frame (cull map build + test)",
            "hidden blocks culled, %",
            &series,
            PlotKind::Points,
        )
        .with_context(|| format!("writing {}", p.display()))?;
    }
    if args.json {
        outln!("{}", serde_json::to_string(&report)?);
    } else {
        outln!(
            "{}: {} buildings, {} blocks; {} views ({} street); oracle {}x{}: {:.1} blocks in frustum, {:.1} visible per view",
            city.name,
            city.buildings.len(),
            report.blocks,
            report.views,
            report.street_views,
            oracle_size.0,
            oracle_size.1,
            report.mean_in_frustum,
            report.mean_visible
        );
        outln!("  res   cells      ms(med)  build  test   occl  culled  false  effect  street  flying  skipped");
        for r in &report.resolutions {
            outln!(
                "  {:<5} {:>4}x{:<4} {:>7.3} {:>6.3} {:>6.3} {:>6.1} {:>7.1} {:>6} {:>6.1}% {:>6.1}% {:>6.1}% {:>7}",
                r.resolution,
                r.cells.0,
                r.cells.1,
                r.median_ms,
                r.median_build_ms,
                r.median_test_ms,
                r.mean_occluders,
                r.mean_culled,
                r.false_culls,
                r.effectiveness * 100.0,
                r.effectiveness_street * 100.0,
                r.effectiveness_flying * 100.0,
                r.skipped
            );
        }
        if !report.false_cull_examples.is_empty() {
            outln!("  FALSE CULLS (first): {:?}", report.false_cull_examples);
        }
    }
    if report.resolutions.iter().any(|r| r.false_culls > 0) {
        bail!("the cull map removed blocks the oracle sees");
    }
    Ok(())
}
