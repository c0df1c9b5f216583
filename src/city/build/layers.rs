//! Street and parcel layers → [`Street`]s and [`Parcel`]s in the footprints' metric frame, with
//! every refusal accounted for and a layer that yields nothing said to be unusable (and why).

use blockwalk_importers::{format_groups, group_reasons, Layer, MetricTransform};
use geo_types::LineString;
use rayon::prelude::*;

use super::geometry::{
    geometry_kind, has_tag, line_box, lines_of, polygons_of, to_metric_line_checked,
    to_metric_polygon, truthy, BoxCheck,
};
use super::BuildOptions;
use crate::city::model::{CityReport, Parcel, RefusalNote, Street};
use crate::geom::repair::repair_polygon;

/// The attributes that make a street a bridge or a tunnel ([`Street::grade_separated`]) when
/// their value is true (`1`, `yes`, `true`, …).
pub const GRADE_SEPARATION_KEYS: [&str; 4] = ["bridge", "tunnel", "BRIDGE", "TUNNEL"];

/// The street attributes a city is built from with `opts`: [`GRADE_SEPARATION_KEYS`] and the
/// keys of [`BuildOptions::exclude_street_tags`]. Reading only these gives the same streets.
pub fn street_columns(opts: &BuildOptions) -> blockwalk_importers::Columns {
    blockwalk_importers::Columns::only(
        GRADE_SEPARATION_KEYS
            .iter()
            .map(|k| k.to_string())
            .chain(opts.exclude_street_tags.iter().map(|(k, _)| k.clone())),
    )
}

/// Why a layer that was given yields nothing, or `None` when it yields something.
fn unusable(
    layer: &Layer,
    kept: usize,
    excluded: usize,
    refused: &[(String, String)],
    what: &str,
) -> Option<String> {
    if kept > 0 {
        return None;
    }
    let read = layer.report.read.max(layer.features.len());
    let groups = group_reasons(refused.iter().map(|(id, r)| (id.clone(), r.as_str())));
    Some(if read == 0 {
        format!("{}: the layer holds no feature", layer.source.display())
    } else if refused.is_empty() {
        format!(
            "{}: all {read} feature(s) were excluded by tag ({excluded}); no {what} is left",
            layer.source.display()
        )
    } else {
        format!(
            "{}: none of its {read} feature(s) gives a {what} ({} refused, {excluded} excluded \
             by tag): {}",
            layer.source.display(),
            refused.len(),
            format_groups(&groups)
        )
    })
}

fn summary_note(
    kind: &str,
    name: &str,
    read: usize,
    kept: &str,
    refused: &[(String, String)],
) -> String {
    format!(
        "{kind} {name}: {read} read, {kept}, {} refused{}",
        refused.len(),
        if refused.is_empty() {
            String::new()
        } else {
            let list: Vec<String> = refused
                .iter()
                .map(|(id, r)| format!("{id} ({r})"))
                .collect();
            format!(": {}", list.join(", "))
        }
    )
}

/// What one street feature gives: excluded by tag, not a line (its kind), or its lines in
/// metres (each, or why it was refused).
enum StreetOutcome {
    Excluded,
    NotLine(&'static str),
    Lines {
        grade_separated: bool,
        parts: Vec<Result<LineString<f64>, String>>,
    },
}

pub(crate) fn build_streets(
    layer: &Layer,
    t: &MetricTransform,
    opts: &BuildOptions,
    report: &mut CityReport,
) -> Vec<Street> {
    let name = &layer.name;
    let mut out = Vec::new();
    let mut excluded = 0usize;
    let mut refused = importer_refusals(layer);
    // The lines' transform and checks in parallel, the accounting in order; the CRS check of
    // the lines' boxes block by block of a grid, as for footprints.
    let check = BoxCheck::new(
        t,
        layer
            .features
            .iter()
            .filter_map(|f| lines_of(&f.geometry))
            .flat_map(|ls| ls.into_iter().filter_map(|l| line_box(&l))),
    );
    let outcomes: Vec<StreetOutcome> = layer
        .features
        .par_iter()
        .map(|f| {
            if opts
                .exclude_street_tags
                .iter()
                .any(|(k, v)| has_tag(&f.attributes, k, v))
            {
                return StreetOutcome::Excluded;
            }
            let Some(lines) = lines_of(&f.geometry) else {
                return StreetOutcome::NotLine(geometry_kind(&f.geometry));
            };
            let grade_separated = GRADE_SEPARATION_KEYS
                .iter()
                .any(|k| f.attributes.get(*k).map(truthy).unwrap_or(false));
            let parts = lines
                .iter()
                .map(|l| {
                    let mut pts = to_metric_line_checked(l, t, Some(&check))?;
                    pts.dedup();
                    if pts.len() < 2 {
                        return Err("fewer than 2 distinct points".to_string());
                    }
                    Ok(LineString::from(pts))
                })
                .collect();
            StreetOutcome::Lines {
                grade_separated,
                parts,
            }
        })
        .collect();
    for (f, outcome) in layer.features.iter().zip(outcomes) {
        let id = format!("{name}:{}", f.fid);
        let (grade_separated, parts) = match outcome {
            StreetOutcome::Excluded => {
                excluded += 1;
                continue;
            }
            StreetOutcome::NotLine(kind) => {
                refused.push((id, format!("{kind} is not a line")));
                continue;
            }
            StreetOutcome::Lines {
                grade_separated,
                parts,
            } => (grade_separated, parts),
        };
        let n = parts.len();
        for (k, line) in parts.into_iter().enumerate() {
            let part = if n == 1 {
                id.clone()
            } else {
                format!("{id}.{k}")
            };
            match line {
                Ok(line) => out.push(Street {
                    source_id: part,
                    line,
                    grade_separated,
                    attributes: f.attributes.clone(),
                }),
                Err(e) => refused.push((part, e)),
            }
        }
    }
    let read = layer.report.read.max(layer.features.len());
    report.notes.push(summary_note(
        "streets",
        name,
        read,
        &format!("{} line(s) kept, {excluded} excluded by tag", out.len()),
        &refused,
    ));
    report.street_layer_unusable = unusable(layer, out.len(), excluded, &refused, "street line");
    report.streets_read += read;
    report.streets_refused.extend(refusal_notes(&refused));
    out
}

pub(crate) fn build_parcels(
    layer: &Layer,
    t: &MetricTransform,
    report: &mut CityReport,
) -> Vec<Parcel> {
    let name = &layer.name;
    let mut out = Vec::new();
    let mut refused = importer_refusals(layer);
    let mut repaired = 0usize;
    for f in &layer.features {
        let id = format!("{name}:{}", f.fid);
        let Some(ps) = polygons_of(&f.geometry) else {
            refused.push((
                id,
                format!("{} is not a polygon", geometry_kind(&f.geometry)),
            ));
            continue;
        };
        let mut parts = Vec::new();
        for p in &ps {
            match to_metric_polygon(p, t)
                .and_then(|m| repair_polygon(&m).map_err(|e| e.to_string()))
            {
                Ok(r) => {
                    if r.was_repaired() {
                        repaired += 1;
                    }
                    parts.extend(r.polygons);
                }
                Err(e) => refused.push((id.clone(), e)),
            }
        }
        let n = parts.len();
        for (k, polygon) in parts.into_iter().enumerate() {
            out.push(Parcel {
                source_id: if n == 1 {
                    id.clone()
                } else {
                    format!("{id}.{k}")
                },
                polygon,
                attributes: f.attributes.clone(),
            });
        }
    }
    let read = layer.report.read.max(layer.features.len());
    report.notes.push(summary_note(
        "parcels",
        name,
        read,
        &format!("{} polygon(s) kept, {repaired} repaired", out.len()),
        &refused,
    ));
    report.parcel_layer_unusable = unusable(layer, out.len(), 0, &refused, "parcel");
    report.parcels_read += read;
    report.parcels_refused.extend(refusal_notes(&refused));
    out
}

fn refusal_notes(refused: &[(String, String)]) -> impl Iterator<Item = RefusalNote> + '_ {
    refused.iter().map(|(id, reason)| RefusalNote {
        id: id.clone(),
        reason: reason.clone(),
    })
}

/// The features the importer refused, as `(layer:fid, "importer: reason")`, the start of a
/// layer's refusal list.
fn importer_refusals(layer: &Layer) -> Vec<(String, String)> {
    layer
        .report
        .refused
        .iter()
        .map(|r| {
            (
                format!("{}:{}", layer.name, r.fid),
                format!("importer: {}", r.reason),
            )
        })
        .collect()
}
