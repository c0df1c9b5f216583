//! Street and parcel layers → [`Street`]s and [`Parcel`]s in the footprints' metric frame, with
//! every refusal accounted for and a layer that yields nothing said to be unusable (and why).

use blockwalk_importers::{format_groups, group_reasons, Layer, MetricTransform};
use geo_types::{Coord, LineString};

use super::geometry::{
    geometry_kind, has_tag, lines_of, polygons_of, to_metric_line, to_metric_polygon, truthy,
};
use super::BuildOptions;
use crate::city::model::{CityReport, Parcel, RefusalNote, Street};
use crate::geom::repair::repair_polygon;

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
    for f in &layer.features {
        let id = format!("{name}:{}", f.fid);
        if opts
            .exclude_street_tags
            .iter()
            .any(|(k, v)| has_tag(&f.attributes, k, v))
        {
            excluded += 1;
            continue;
        }
        let Some(lines) = lines_of(&f.geometry) else {
            refused.push((id, format!("{} is not a line", geometry_kind(&f.geometry))));
            continue;
        };
        let grade_separated = ["bridge", "tunnel", "BRIDGE", "TUNNEL"]
            .iter()
            .any(|k| f.attributes.get(*k).map(truthy).unwrap_or(false));
        let n = lines.len();
        for (k, l) in lines.iter().enumerate() {
            let part = if n == 1 {
                id.clone()
            } else {
                format!("{id}.{k}")
            };
            let mut pts: Vec<Coord<f64>> = match to_metric_line(l, t) {
                Ok(p) => p,
                Err(e) => {
                    refused.push((part, e));
                    continue;
                }
            };
            pts.dedup();
            if pts.len() < 2 {
                refused.push((part, "fewer than 2 distinct points".into()));
                continue;
            }
            out.push(Street {
                source_id: part,
                line: LineString::from(pts),
                grade_separated,
                attributes: f.attributes.clone(),
            });
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
