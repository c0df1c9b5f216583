//! `blockwalk occlusion-bench`: occlusion culling with the cull map at several resolutions over
//! random street-level and flying views, checked against the CPU visibility oracle (seed 004
//! §3.2): ms per frame, occluders, blocks culled, false culls, effectiveness, and a plot of
//! effectiveness against time.

use super::common::{spinner, CityArgs};
use anyhow::{bail, Context};
use blockwalk::blocks::{detect, BlockId, BlockLayout, BlockOptions};
use blockwalk::city::extrude::extrude_building;
use blockwalk::city::{City, Mesh};
use blockwalk::index::CityIndex;
use blockwalk::report::plot::{write_plot, PlotKind, Series};
use blockwalk::visibility::bench::{
    block_bounds, run_occlusion_bench, BenchOptions, BenchScene, ListIndex, SyntheticCity,
};
use blockwalk::visibility::CullerOptions;
use std::path::PathBuf;

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
    #[arg(long, default_value_t = 200)]
    pub views: usize,
    /// Fraction of street-level views (the rest fly).
    #[arg(long, default_value_t = 0.7)]
    pub street_fraction: f64,
    /// Seed of the views (and of a synthetic city).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Oracle image size, WxH.
    #[arg(long, default_value = "640x360")]
    pub oracle: String,
    /// Blocks within this distance of the eye give occluders, metres.
    #[arg(long, default_value_t = 300.0)]
    pub local_radius: f64,
    /// At most this many occluders per frame.
    #[arg(long, default_value_t = 256)]
    pub max_occluders: usize,
    /// Spatial structure frustum culling runs on (bqr, vamsplit, flat, none, rstar, or `list`:
    /// every block tested on its own).
    #[arg(long, default_value = "bqr")]
    pub index: String,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Plot of effectiveness against milliseconds per frame (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// The city, its blocks and one mesh per block.
type Scene = (City, BlockLayout, Vec<(BlockId, Mesh)>);

fn load(args: &Args) -> anyhow::Result<Scene> {
    let c = &args.city;
    let first = c.inputs[0].to_string_lossy().to_string();
    if let Some(spec) = first.strip_prefix("synthetic:") {
        let (cols, rows) = spec
            .split_once(['x', 'X'])
            .and_then(|(a, b)| Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?)))
            .with_context(|| format!("{first}: expected synthetic:COLSxROWS"))?;
        if cols == 0 || rows == 0 || cols * rows > 1_000_000 {
            bail!("{first}: between 1 and 1,000,000 blocks");
        }
        let s = SyntheticCity::generate(
            cols,
            rows,
            args.seed,
            glam::DVec2::new(500_000.0, 6_600_000.0),
        );
        return Ok((s.city, s.layout, s.meshes));
    }
    let city = super::common::load_city(c)?;
    let pb = spinner(format!(
        "blocks and meshes for {} buildings",
        city.buildings.len()
    ));
    let layout = detect(&city, &BlockOptions::default()).context("detecting blocks")?;
    let meshes = layout
        .blocks
        .iter()
        .map(|block| {
            let mut m = Mesh::default();
            for b in &block.buildings {
                let part = extrude_building(&city.buildings[b.0 as usize], &city.frame);
                let base = m.positions.len() as u32;
                m.positions.extend_from_slice(&part.positions);
                m.normals.extend_from_slice(&part.normals);
                m.indices.extend(part.indices.iter().map(|k| k + base));
            }
            (block.id, m)
        })
        .collect();
    pb.finish_and_clear();
    Ok((city, layout, meshes))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let oracle_size = super::walk::parse_size("--oracle", &args.oracle)?;
    if args.resolution.is_empty() {
        bail!("--resolution: give at least one");
    }
    let (city, layout, meshes) = load(&args)?;
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(id, m)| (*id, m)).collect();
    let index: Box<dyn CityIndex> = if args.index == "list" {
        Box::new(ListIndex::new(block_bounds(&city, &layout, &refs)))
    } else {
        let bounds = blockwalk::index::block_bounds(&city, &layout);
        blockwalk::index::build_by_name(&args.index, &bounds)
            .with_context(|| format!("building the {} index", args.index))?
    };
    let scene = BenchScene {
        city: &city,
        layout: &layout,
        meshes: &refs,
        index: index.as_ref(),
    };
    let opts = BenchOptions {
        resolutions: args.resolution.clone(),
        views: args.views,
        street_fraction: args.street_fraction,
        seed: args.seed,
        oracle_size,
        culler: CullerOptions {
            local_radius: args.local_radius,
            max_occluders: args.max_occluders,
            ..Default::default()
        },
        ..Default::default()
    };
    let bar = indicatif::ProgressBar::new(args.views as u64);
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
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
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
        println!("  res   cells      ms(med)  build  test   occl  culled  false  effect  street  flying  skipped");
        for r in &report.resolutions {
            println!(
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
            println!("  FALSE CULLS (first): {:?}", report.false_cull_examples);
        }
    }
    if report.resolutions.iter().any(|r| r.false_culls > 0) {
        bail!("the cull map removed blocks the oracle sees");
    }
    Ok(())
}
