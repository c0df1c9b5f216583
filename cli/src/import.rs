//! `blockwalk import`: footprints (+ streets, parcels) → city → extruded meshes → glTF /
//! GeoJSON, with a report of what happened to every feature.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use blockwalk::city::build::{footprint_columns, BuildError, BuildOptions, HeightFields};
use blockwalk::city::export::cityjson::{is_cityjson_seq, write_cityjson, write_cityjson_seq};
use blockwalk::city::export::{write_geojson, write_glb};
use blockwalk::city::extrude::try_extrude_city;
use blockwalk::geom::predicates::polygon_area;
use blockwalk::importers::Columns;
use serde_json::json;

use super::common::{spinner, CityArgs};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    city: CityArgs,
    /// Write the extruded city as glTF binary.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the footprints with their heights as GeoJSON (input coordinates).
    #[arg(long)]
    geojson: Option<PathBuf>,
    /// Write the buildings as CityJSON 2.0 (LoD1 solids, LoD0 footprints); CityJSONSeq, one
    /// building per line, when the name ends in `.jsonl` or with --cityjson-seq.
    #[arg(long)]
    cityjson: Option<PathBuf>,
    /// Write --cityjson as CityJSONSeq whatever its extension.
    #[arg(long = "cityjson-seq", requires = "cityjson")]
    cityjson_seq: bool,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
    /// Height field name(s) in metres, tried in order (replaces the defaults).
    #[arg(long = "height-field")]
    height_field: Vec<String>,
    /// Levels field name(s), tried in order (replaces the defaults).
    #[arg(long = "levels-field")]
    levels_field: Vec<String>,
    /// Metres per storey.
    #[arg(long = "storey-height", default_value_t = 3.0)]
    storey_height: f64,
    /// Height of buildings with no usable height or levels, metres.
    #[arg(long = "default-height", default_value_t = 9.0)]
    default_height: f64,
}

/// The city of `args` without a city folder's parcels, which `import` does not use (an explicit
/// `--parcels` file is still read and reported), and with only the footprint columns the
/// buildings are made from unless `all_columns` (CityJSON exports the source attributes).
fn load_buildings(
    args: &CityArgs,
    opts: &BuildOptions,
    all_columns: bool,
) -> anyhow::Result<blockwalk::city::City> {
    let source = args.source(0)?.without_folder_parcels()?;
    let columns = if all_columns {
        Columns::All
    } else {
        footprint_columns(&opts.heights)
    };
    let pb = spinner("loading the city");
    let loaded = source.load_with_columns(opts, &columns, &mut |m| pb.set_message(m.to_string()));
    pb.finish_and_clear();
    Ok(loaded?.city)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut heights = HeightFields::default();
    if !args.height_field.is_empty() {
        heights.height = args.height_field.clone();
    }
    if !args.levels_field.is_empty() {
        heights.levels = args.levels_field.clone();
    }
    heights.storey_m = args.storey_height;
    heights.default_height_m = args.default_height;
    let opts = BuildOptions {
        heights,
        ..Default::default()
    };

    let t0 = Instant::now();
    let city = match load_buildings(&args.city, &opts, args.cityjson.is_some()) {
        Ok(c) => c,
        Err(e) => {
            // With --json, nothing usable left still gives one JSON object (with the reasons).
            if args.json {
                let reasons = match e.downcast_ref::<BuildError>() {
                    Some(BuildError::NoBuildings { reasons, .. }) => json!(reasons),
                    _ => json!([]),
                };
                outln!(
                    "{}",
                    json!({"error": format!("{e:#}"), "refused_by_reason": reasons})
                );
            }
            return Err(e);
        }
    };
    let import_ms = t0.elapsed().as_secs_f64() * 1e3;

    let t1 = Instant::now();
    let pb = spinner(format!("extruding {} buildings", city.buildings.len()));
    let (meshes, errors) = try_extrude_city(&city);
    pb.finish_and_clear();
    let extrude_ms = t1.elapsed().as_secs_f64() * 1e3;

    let t2 = Instant::now();
    let mut glb = None;
    if let Some(out) = &args.output {
        let pb = spinner(format!("writing {}", out.display()));
        glb = Some(write_glb(&city, &meshes, out).context("writing glTF")?);
        pb.finish_and_clear();
    }
    if let Some(out) = &args.geojson {
        write_geojson(&city, out).context("writing GeoJSON")?;
    }
    let mut cityjson = None;
    if let Some(out) = &args.cityjson {
        let pb = spinner(format!("writing {}", out.display()));
        cityjson = Some(if args.cityjson_seq || is_cityjson_seq(out) {
            write_cityjson_seq(&city, out).context("writing CityJSONSeq")?
        } else {
            write_cityjson(&city, out).context("writing CityJSON")?
        });
        pb.finish_and_clear();
    }
    let export_ms = t2.elapsed().as_secs_f64() * 1e3;

    let r = &city.report;
    let area: f64 = city
        .buildings
        .iter()
        .map(|b| polygon_area(&b.footprint))
        .sum();
    let triangles: usize = meshes.iter().map(|m| m.triangle_count()).sum();
    let peak = blockwalk::process::peak_rss_bytes();
    if args.json {
        let v = json!({
            "name": city.name,
            "buildings_read": r.buildings_read,
            "buildings_imported": r.buildings_imported,
            "buildings_repaired": r.buildings_repaired.len(),
            "buildings_refused": r.buildings_refused,
            "refused_by_reason": r.refused_by_reason,
            "implausible_heights": r.implausible_heights,
            "street_layer_unusable": r.street_layer_unusable,
            "parcel_layer_unusable": r.parcel_layer_unusable,
            "frame": r.frame,
            "repaired": r.buildings_repaired,
            "buildings": city.buildings.len(),
            "streets": city.streets.len(),
            "parcels": city.parcels.len(),
            "footprint_area_m2": area,
            "triangles": triangles,
            "extrude_errors": errors.iter().map(|e| e.to_string()).collect::<Vec<_>>(),
            "crs": r.crs,
            "origin": [city.frame.origin.x, city.frame.origin.y, city.frame.origin.z],
            "height_sources": r.height_sources,
            "ground": r.ground,
            "notes": r.notes,
            "glb": glb,
            "cityjson": cityjson,
            "import_ms": import_ms,
            "extrude_ms": extrude_ms,
            "export_ms": export_ms,
            "peak_memory_bytes": peak,
        });
        outln!("{v}");
    } else {
        outln!("{}: {}", city.name, r.crs);
        outln!(
            "footprints: {} read, {} imported, {} repaired, {} refused → {} buildings, {:.0} m²",
            r.buildings_read,
            r.buildings_imported,
            r.buildings_repaired.len(),
            r.buildings_refused.len(),
            city.buildings.len(),
            area
        );
        for n in r.buildings_repaired.iter().take(5) {
            outln!("  repaired {}: {}", n.id, n.what);
        }
        if let Some(g) = &r.ground {
            for line in super::common::ground_lines(g) {
                outln!("{line}");
            }
        }
        for g in &r.refused_by_reason {
            outln!(
                "  refused {} × {} (e.g. {})",
                g.count,
                g.reason,
                g.examples.join(", ")
            );
        }
        if !r.implausible_heights.is_empty() {
            let ids: Vec<String> = r
                .implausible_heights
                .iter()
                .take(5)
                .map(|h| format!("{} {}={}", h.id, h.field, h.value))
                .collect();
            outln!(
                "implausible heights: {} ({}{})",
                r.implausible_heights.len(),
                ids.join(", "),
                if r.implausible_heights.len() > 5 {
                    ", …"
                } else {
                    ""
                }
            );
        }
        for n in r.notes.iter().filter(|n| n.starts_with("warning:")) {
            outln!("{n}");
        }
        let hs: Vec<String> = r
            .height_sources
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        outln!("heights: {}", hs.join(", "));
        if !city.streets.is_empty() || !city.parcels.is_empty() {
            outln!(
                "streets: {} lines, parcels: {}",
                city.streets.len(),
                city.parcels.len()
            );
        }
        outln!(
            "meshes: {} triangles{}",
            triangles,
            if errors.is_empty() {
                String::new()
            } else {
                format!(", {} building(s) not extruded", errors.len())
            }
        );
        for e in errors.iter().take(5) {
            outln!("  {e}");
        }
        if let (Some(out), Some(g)) = (&args.output, glb) {
            outln!(
                "wrote {} ({} nodes, {} bytes)",
                out.display(),
                g.nodes,
                g.bytes
            );
        }
        if let Some(out) = &args.geojson {
            outln!("wrote {}", out.display());
        }
        if let (Some(out), Some(c)) = (&args.cityjson, &cityjson) {
            outln!(
                "wrote {} ({} buildings, {} vertices at {} m, {} bytes)",
                out.display(),
                c.buildings,
                c.vertices,
                c.scale_m,
                c.bytes
            );
            for d in c.dropped_rings.iter().take(5) {
                outln!("  collapsed at the quantisation step: {d}");
            }
        }
        outln!(
            "time: import {import_ms:.0} ms, extrude {extrude_ms:.0} ms, export {export_ms:.0} ms{}",
            peak.map(|p| format!("; peak memory {:.0} MiB", p as f64 / 1048576.0))
                .unwrap_or_default()
        );
    }
    Ok(())
}
