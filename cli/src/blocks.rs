//! `blockwalk blocks`: streets and urban blocks (Pina, Serón and Cerezo, §3), GeoJSON in the input's own
//! coordinates, an SVG/PNG map, a summary.

use super::common::{load_city, spinner, CityArgs};
use blockwalk::blocks::export::{summary, write_geojson, write_map};
use blockwalk::blocks::{detect, BlockOptions, BlockSource};
use std::path::PathBuf;
use std::time::Instant;

/// Where the blocks come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SourceArg {
    /// Faces of the street graph.
    Streets,
    /// Unions of touching parcels.
    Parcels,
    /// Inferred from the gaps between footprints.
    Footprints,
}

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The city: footprints, `--streets`, `--parcels`, `--exclude-tag`.
    #[command(flatten)]
    pub city: CityArgs,
    /// Output GeoJSON (blocks and outskirts groups, in the input's coordinates).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Write an SVG map.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Write a PNG map.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Use this source instead of streets → parcels → footprints.
    #[arg(long, value_enum)]
    pub source: Option<SourceArg>,
    /// Snap tolerance, metres.
    #[arg(long, default_value_t = blockwalk::blocks::noding::DEFAULT_SNAP_TOLERANCE,
          value_parser = snap_tolerance)]
    pub snap: f64,
    /// Bridges and tunnels (a `bridge` or `tunnel` attribute) do not bound blocks. By default
    /// every street line bounds blocks, as in a plain polygonize of the lines (momepy, shapely), so
    /// a bridge over water or a railway closes the blocks beside it. Use this flag when the layer
    /// holds flyovers or tunnels that cross the middle of built blocks, which would otherwise be
    /// split in two.
    #[arg(long)]
    pub grade_separated_bridges: bool,
    /// Former name of today's default (bridges and tunnels cut blocks); accepted, does nothing.
    #[arg(long, hide = true, conflicts_with = "grade_separated_bridges")]
    pub bridges_cut: bool,
    /// Street width threshold for blocks from footprints, metres.
    #[arg(long, default_value_t = blockwalk::blocks::infer::DEFAULT_STREET_WIDTH)]
    pub street_width: f64,
    /// Outskirts buildings closer than this are one group, metres.
    #[arg(long, default_value_t = blockwalk::blocks::assign::DEFAULT_OUTSKIRTS_LINK)]
    pub outskirts_link: f64,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let city = load_city(&args.city)?;
    let opts = BlockOptions {
        snap_tolerance: args.snap,
        force_source: args.source.map(|s| match s {
            SourceArg::Streets => BlockSource::Streets,
            SourceArg::Parcels => BlockSource::Parcels,
            SourceArg::Footprints => BlockSource::Footprints,
        }),
        grade_separation: args.grade_separated_bridges,
        outskirts_link: args.outskirts_link,
        street_width: args.street_width,
    };
    let pb = spinner(format!("blocks of {} buildings", city.buildings.len()));
    let t1 = Instant::now();
    let layout = detect(&city, &opts);
    let ms = t1.elapsed().as_secs_f64() * 1e3;
    pb.finish_and_clear();
    let layout = layout?;
    if let Some(o) = &args.output {
        write_geojson(o, &layout, &city.transform)?;
    }
    let footprints: Vec<_> = city.buildings.iter().map(|b| b.footprint.clone()).collect();
    for p in [&args.svg, &args.png].into_iter().flatten() {
        write_map(p, &layout, &footprints, 1600)?;
    }
    let s = summary(&layout, &city.transform);
    // A layer given but unusable: the blocks come from the next source, said aloud.
    let r = &city.report;
    let fallback = match layout.source {
        BlockSource::Streets => None,
        BlockSource::Parcels => r.street_layer_unusable.as_ref().map(|why| {
            format!("blocks from parcels, not streets: the street layer is unusable ({why})")
        }),
        BlockSource::Footprints => match (&r.street_layer_unusable, &r.parcel_layer_unusable) {
            (_, Some(why)) => Some(format!(
                "blocks from footprints, not parcels: the parcel layer is unusable ({why})"
            )),
            (Some(why), None) => Some(format!(
                "blocks from footprints, not streets: the street layer is unusable ({why})"
            )),
            (None, None) => None,
        },
    };
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        v["ms"] = serde_json::json!(ms);
        v["total_ms"] = serde_json::json!(t0.elapsed().as_secs_f64() * 1e3);
        v["buildings"] = serde_json::json!(city.buildings.len());
        v["crs"] = serde_json::json!(city.transform.describe());
        v["street_layer_unusable"] = serde_json::json!(city.report.street_layer_unusable);
        v["fallback"] = serde_json::json!(fallback);
        v["import"] = super::common::city_report_json(&city);
        outln!("{}", serde_json::to_string(&v)?);
    } else {
        for line in super::common::city_report_lines(&city) {
            outln!("{line}");
        }
        if let Some(f) = &fallback {
            outln!("{f}");
        }
        outln!(
            "{}: {} blocks from {:?} ({:.0} m², {:.1} in the input's units), {} outskirts groups",
            city.name,
            s.blocks,
            s.source,
            s.total_area_m2,
            s.total_area,
            s.outskirts_groups
        );
        outln!(
            "buildings: {} in blocks, {} in outskirts; street graph: {} edges, {} dangles; {ms:.1} ms",
            s.buildings_assigned, s.buildings_outskirts, s.street_edges, s.dangles
        );
    }
    Ok(())
}

fn snap_tolerance(s: &str) -> Result<f64, String> {
    super::common::f64_in(
        s,
        blockwalk::blocks::noding::MIN_SNAP_TOLERANCE,
        blockwalk::blocks::noding::MAX_SNAP_TOLERANCE,
        "metres; below 1 mm rounded crossings can leave streets unnoded, above 5 m street corners merge and blocks collapse",
    )
}
