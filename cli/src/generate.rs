//! `blockwalk generate`: a deterministic procedural city written as Shapefiles.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use serde_json::json;

use super::common::spinner;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Number of buildings.
    #[arg(long, default_value_t = 1000, value_parser = super::common::at_least_one)]
    buildings: usize,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory (buildings.shp, streets.shp, parcels.shp).
    #[arg(short, long)]
    output: PathBuf,
    /// Do not write parcels.
    #[arg(long)]
    no_parcels: bool,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let params = GenerateParams {
        buildings: args.buildings,
        seed: args.seed,
        parcels: !args.no_parcels,
        ..Default::default()
    };
    let t0 = Instant::now();
    let pb = spinner(format!("generating {} buildings", args.buildings));
    let city = generate_city(&params).context("generating the city")?;
    let gen_ms = t0.elapsed().as_secs_f64() * 1e3;
    pb.set_message(format!("writing {}", args.output.display()));
    let t1 = Instant::now();
    let w = write_city(&city, &args.output).context("writing the city")?;
    let write_ms = t1.elapsed().as_secs_f64() * 1e3;
    pb.finish_and_clear();
    if args.json {
        outln!(
            "{}",
            json!({
                "output": args.output,
                "seed": args.seed,
                "buildings": w.buildings,
                "streets": w.streets,
                "parcels": w.parcels,
                "blocks": w.blocks,
                "files": w.files,
                "generate_ms": gen_ms,
                "write_ms": write_ms,
            })
        );
    } else {
        outln!(
            "wrote {}: {} buildings, {} street segments, {} parcels in {} blocks ({:.0} ms + {:.0} ms)",
            args.output.display(),
            w.buildings,
            w.streets,
            w.parcels,
            w.blocks,
            gen_ms,
            write_ms
        );
    }
    Ok(())
}
