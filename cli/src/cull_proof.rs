//! `blockwalk cull-proof`: every frame of every route on each city drawn by the supersampled
//! oracle and culled through every block structure, with the cull map at several resolutions
//! and the per-building test (Willmott et al., §3.2, §3.2.8): false culls (must be 0), vacuous
//! frames apart, the share culled and the time. Exits with an error on any false cull.

use super::common::{Progress, Size};
use anyhow::bail;
use blockwalk::route::RouteChoice;
use blockwalk::scene::CitySource;
use blockwalk::visibility::route_proof::{CityProof, Dropped, ProofOptions, ProofTally};
use blockwalk::walk::{run_route_proof, RouteProofJob, RouteProofReport};
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cities: a footprint file, a footprint file and its street lines joined by a comma
    /// (`buildings.shp,streets.shp`), a city folder (as `blockwalk generate` writes), or
    /// `synthetic:COLSxROWS`.
    #[arg(required = true)]
    pub cities: Vec<String>,
    /// Routes to walk, comma-separated: generated routes or route files.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "paper,orbit,street,flyover,corners"
    )]
    pub routes: Vec<RouteChoice>,
    /// Frames along every route: one count for every city, or one per city (comma-separated, in
    /// the cities' order).
    #[arg(long, value_delimiter = ',', default_value = "100")]
    pub frames: Vec<usize>,
    /// Oracle image size, WxH.
    #[arg(long, default_value = "96x54")]
    pub oracle: Size,
    /// Oracle samples per pixel along each axis.
    #[arg(long, default_value_t = 4)]
    pub samples: u32,
    /// Cull map cells along the longer side, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "64,256,1024")]
    pub resolutions: Vec<u32>,
    /// Seed of a synthetic city.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// False culls to describe, at most.
    #[arg(long, default_value_t = 20)]
    pub examples: usize,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// A city argument: `FOOTPRINTS[,STREETS]`, a folder or `synthetic:COLSxROWS`.
fn source(arg: &str, seed: u64) -> anyhow::Result<CitySource> {
    let (footprints, streets) = match arg.split_once(',') {
        Some((f, s)) if !f.is_empty() && !s.is_empty() => (f, Some(PathBuf::from(s))),
        Some(_) => bail!("city {arg:?}: expected FOOTPRINTS or FOOTPRINTS,STREETS"),
        None => (arg, None),
    };
    Ok(CitySource::parse(
        &PathBuf::from(footprints),
        streets,
        None,
        &[],
        seed,
    )?)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let frames: Vec<usize> = match args.frames.as_slice() {
        [n] => vec![*n; args.cities.len()],
        f if f.len() == args.cities.len() => f.to_vec(),
        f => bail!(
            "--frames: give one count, or one per city ({} cities, {} counts)",
            args.cities.len(),
            f.len()
        ),
    };
    let cities = args
        .cities
        .iter()
        .zip(frames)
        .map(|(c, n)| Ok((source(c, args.seed)?, n)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let job = RouteProofJob {
        cities,
        routes: args.routes.clone(),
        proof: ProofOptions {
            oracle_size: args.oracle.pair(),
            samples: args.samples,
            resolutions: args.resolutions.clone(),
            max_examples: args.examples,
            ..ProofOptions::default()
        },
    };
    let progress = Progress::new(args.json);
    let report = run_route_proof(&job, &progress);
    progress.finish();
    let report = report?;
    if args.json {
        outln!("{}", serde_json::to_string(&report)?);
    } else {
        print_summary(&report)?;
    }
    if !report.passed() {
        bail!(
            "{} false culls (blocks or buildings the oracle sees were culled)",
            report.false_culls
        );
    }
    Ok(())
}

/// The least and the largest culled share over the structures of `tallies`: blocks (least,
/// largest), then buildings (least, largest).
fn shares(tallies: &[&ProofTally]) -> (f64, f64, f64, f64) {
    let (mut bmin, mut bmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut gmin, mut gmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for t in tallies {
        bmin = bmin.min(t.block_culled_share());
        bmax = bmax.max(t.block_culled_share());
        gmin = gmin.min(t.building_culled_share());
        gmax = gmax.max(t.building_culled_share());
    }
    (bmin, bmax, gmin, gmax)
}

fn range(lo: f64, hi: f64) -> String {
    if (hi - lo).abs() < 5e-4 {
        format!("{:.1} %", 100.0 * lo)
    } else {
        format!("{:.1}–{:.1} %", 100.0 * lo, 100.0 * hi)
    }
}

fn print_city(c: &CityProof, resolutions: &[u32]) -> anyhow::Result<()> {
    let (w, h, s) = c.oracle;
    outln!(
        "{}: {} buildings in {} blocks; oracle {w}x{h} with {s}x{s} samples per pixel; {:.0} s",
        c.city,
        c.buildings,
        c.blocks,
        c.seconds
    );
    outln!(
        "  {:<8} {:>7} {:>8} {:>8} {:>8} {:>8} {:>7}  culled by the cull map (blocks / buildings of the frustum), per resolution",
        "route",
        "frames",
        "vacuous",
        "(inside",
        "empty",
        "unseen)",
        "false"
    );
    for r in &c.routes {
        let per_res: Vec<String> = resolutions
            .iter()
            .map(|&res| {
                let ts: Vec<&ProofTally> =
                    r.tallies.iter().filter(|t| t.resolution == res).collect();
                let (b0, b1, g0, g1) = shares(&ts);
                format!("{res}: {} / {}", range(b0, b1), range(g0, g1))
            })
            .collect();
        outln!(
            "  {:<8} {:>7} {:>8} {:>8} {:>8} {:>8} {:>7}  {}",
            r.route,
            r.frames,
            r.vacuous.total(),
            r.vacuous.inside_building,
            r.vacuous.empty_view,
            r.vacuous.nothing_seen,
            r.false_culls(),
            per_res.join("; ")
        );
    }
    Ok(())
}

fn print_summary(report: &RouteProofReport) -> anyhow::Result<()> {
    for c in &report.cities {
        print_city(c, &report.resolutions)?;
    }
    let structures: Vec<String> = report.structures.iter().map(|s| s.name()).collect();
    outln!(
        "{} frames ({} vacuous, {} checked) × {} structures ({}) × cull maps {:?}: {} false culls; {:.0} s",
        report.frames,
        report.vacuous,
        report.frames - report.vacuous,
        structures.len(),
        structures.join(", "),
        report.resolutions,
        report.false_culls,
        report.seconds
    );
    for c in &report.cities {
        for e in &c.false_cull_examples {
            let what = match e.dropped {
                Dropped::Block(b) => format!("block {}", b.0),
                Dropped::Building(b) => format!("building {}", b.0),
            };
            let cam = &e.camera;
            outln!(
                "  false cull: {} {} frame {} {} at {}: {what}{} from eye ({:.3}, {:.3}, {:.3}) yaw {:.4} pitch {:.4} near {}",
                e.city,
                e.route,
                e.frame,
                e.structure,
                e.resolution,
                if e.vacuous { " (vacuous frame)" } else { "" },
                cam.position.x,
                cam.position.y,
                cam.position.z,
                cam.yaw,
                cam.pitch,
                cam.near
            );
        }
    }
    Ok(())
}
