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
    /// The city's CRS, a projected CRS in metres: `EPSG:NNNN` (default EPSG:32633).
    #[arg(long)]
    crs: Option<String>,
    /// Put the centre of the city's box here, `X,Y` in the CRS's metres.
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true)]
    centre: Option<(f64, f64)>,
    /// Put the city on this elevation model (GeoTIFF): its CRS and, unless `--centre` is
    /// given, its centre.
    #[arg(long)]
    on_dem: Option<PathBuf>,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

fn parse_xy(s: &str) -> Result<(f64, f64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: expected X,Y"))?;
    let num = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{t:?} in {s:?} is not a finite number"))
    };
    Ok((num(x)?, num(y)?))
}

fn parse_epsg(s: &str) -> anyhow::Result<u32> {
    let code = s
        .trim()
        .strip_prefix("EPSG:")
        .or_else(|| s.trim().strip_prefix("epsg:"))
        .unwrap_or(s.trim());
    code.parse::<u32>()
        .with_context(|| format!("--crs {s:?}: expected EPSG:NNNN"))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut params = GenerateParams {
        buildings: args.buildings,
        seed: args.seed,
        parcels: !args.no_parcels,
        centre: args.centre,
        ..Default::default()
    };
    if let Some(c) = &args.crs {
        params.epsg = parse_epsg(c)?;
    }
    if let Some(dem) = &args.on_dem {
        let place = blockwalk::city::generate::place_on_dem(dem)?;
        if args.crs.is_none() {
            params.epsg = place.epsg;
        } else if params.epsg != place.epsg {
            anyhow::bail!(
                "--crs EPSG:{} differs from {}'s EPSG:{}",
                params.epsg,
                dem.display(),
                place.epsg
            );
        }
        params.centre = params.centre.or(Some(place.centre));
    }
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
