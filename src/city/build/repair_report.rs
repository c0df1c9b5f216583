//! Footprint features → buildings: transform (checked against the CRS), repair, heights, and
//! the account of every feature (imported, repaired with what was done, or refused with why).

use blockwalk_importers::{Layer, MetricTransform};
use rayon::prelude::*;

use super::geometry::{
    geometry_kind, polygon_box, polygons_of, to_metric_polygon_checked, BoxCheck,
};
use super::heights::{heights_from_attributes, source_name, HeightFields, Heights};
use super::HeightNote;
use crate::city::model::{Building, BuildingId, CityReport, HeightSource, RefusalNote, RepairNote};
use crate::geom::repair::{repair_polygon, Repaired};

fn repair_outcome(r: &Repaired) -> String {
    r.actions
        .iter()
        .filter(|a| !a.is_normalization())
        .map(|a| a.to_string())
        .collect::<Vec<_>>()
        .join("; ")
}

/// The feature id in a building's source id: `layer:fid` for a feature that gave one building,
/// `layer:fid.k` for its part `k` when it gave several (a MultiPolygon, a polygon that repair
/// split). `None` for an id of another form.
pub fn source_fid(source_id: &str) -> Option<u64> {
    let (_, tail) = source_id.rsplit_once(':')?;
    tail.split('.').next()?.parse().ok()
}

/// One footprint feature's polygons, transformed and repaired (or why not), and its heights.
type Outcome = (Vec<Result<Repaired, String>>, Heights);

/// Accounts for the importer's own refusals and returns the buildings of the footprint layer,
/// recording every feature in `report` (see the module documentation of [`super`]).
pub(crate) fn build_footprints(
    footprints: &Layer,
    transform: &MetricTransform,
    hf: &HeightFields,
    report: &mut CityReport,
) -> Vec<Building> {
    let lname = &footprints.name;
    report.buildings_read = footprints
        .report
        .read
        .max(footprints.features.len() + footprints.report.refused.len());
    for n in &footprints.report.notes {
        report.notes.push(format!("{lname}: {n}"));
    }
    for r in &footprints.report.refused {
        report.buildings_refused.push(RefusalNote {
            id: format!("{lname}:{}", r.fid),
            reason: format!("importer: {}", r.reason),
        });
    }
    // Records the importer neither handed on nor refused (should not happen) are accounted for.
    let unaccounted = report
        .buildings_read
        .saturating_sub(footprints.features.len() + footprints.report.refused.len());
    if unaccounted > 0 {
        report.buildings_refused.push(RefusalNote {
            id: format!("{lname}:?"),
            reason: format!("{unaccounted} record(s) neither imported nor refused by the importer"),
        });
    }

    // Transform, repair and heights in parallel (the expensive part), account sequentially in
    // order.
    // The CRS check of the footprints' boxes, block by block of a grid.
    let check = BoxCheck::new(
        transform,
        footprints
            .features
            .iter()
            .filter_map(|f| polygons_of(&f.geometry))
            .flat_map(|ps| ps.into_iter().filter_map(|p| polygon_box(&p))),
    );
    let outcomes: Vec<Option<Outcome>> = footprints
        .features
        .par_iter()
        .map(|f| {
            let parts: Vec<Result<Repaired, String>> = polygons_of(&f.geometry)?
                .iter()
                .map(|p| {
                    let m = to_metric_polygon_checked(p, check.transform(), Some(&check))?;
                    repair_polygon(&m).map_err(|e| e.to_string())
                })
                .collect();
            Some((parts, heights_from_attributes(&f.attributes, hf)))
        })
        .collect();

    let mut buildings: Vec<Building> = Vec::with_capacity(footprints.features.len());
    // Buildings per height source, in the order of `HeightSource`.
    let mut per_source = [0usize; 3];
    for (f, outcome) in footprints.features.iter().zip(outcomes) {
        let base = format!("{lname}:{}", f.fid);
        let Some((parts, heights)) = outcome else {
            report.buildings_refused.push(RefusalNote {
                id: base,
                reason: format!("{} is not a polygon", geometry_kind(&f.geometry)),
            });
            continue;
        };
        if parts.is_empty() {
            report.buildings_refused.push(RefusalNote {
                id: base,
                reason: "empty geometry".into(),
            });
            continue;
        }
        let n_out: usize = parts
            .iter()
            .map(|r| r.as_ref().map(|r| r.polygons.len()).unwrap_or(0))
            .sum();
        let n_parts = parts.len();
        let single = n_out == 1 && n_parts == 1;
        let mut what = Vec::new();
        let mut k = 0usize;
        for (pi, part) in parts.into_iter().enumerate() {
            match part {
                Err(reason) => {
                    if n_parts > 1 {
                        what.push(format!("part {pi} refused: {reason}"));
                    } else {
                        what.push(reason);
                    }
                }
                Ok(rep) => {
                    if rep.was_repaired() {
                        let s = repair_outcome(&rep);
                        what.push(if n_parts > 1 {
                            format!("part {pi}: {s}")
                        } else {
                            s
                        });
                    }
                    for poly in rep.polygons {
                        let source_id = if single {
                            base.clone()
                        } else {
                            format!("{base}.{k}")
                        };
                        k += 1;
                        buildings.push(Building {
                            id: BuildingId(buildings.len() as u32),
                            source_id,
                            footprint: poly,
                            height_m: heights.height_m,
                            min_height_m: heights.min_height_m,
                            base_m: 0.0,
                            height_source: heights.source,
                            attributes: f.attributes.clone(),
                        });
                        per_source[heights.source as usize] += 1;
                    }
                }
            }
        }
        if k == 0 {
            report.buildings_refused.push(RefusalNote {
                id: base.clone(),
                reason: what.join("; "),
            });
        } else if what.is_empty() {
            report.buildings_imported += 1;
        } else {
            report.buildings_repaired.push(RepairNote {
                id: base.clone(),
                what: what.join("; "),
            });
        }
        if k > 0 {
            for n in &heights.notes {
                report.notes.push(format!("{base}: {n}"));
            }
            for h in heights.implausible {
                report.implausible_heights.push(HeightNote {
                    id: base.clone(),
                    field: h.field,
                    value: h.value,
                    why: h.why,
                });
            }
        }
    }
    for (source, n) in [
        HeightSource::Height,
        HeightSource::Levels,
        HeightSource::Default,
    ]
    .into_iter()
    .zip(per_source)
    {
        if n > 0 {
            *report
                .height_sources
                .entry(source_name(source).to_string())
                .or_insert(0) += n;
        }
    }
    report.refused_by_reason = blockwalk_importers::group_reasons(
        report
            .buildings_refused
            .iter()
            .map(|r| (r.id.clone(), r.reason.as_str())),
    );
    buildings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::importers::{Attributes, Crs, Feature, ImportReport};
    use geo_types::{polygon, Geometry, MultiPolygon};

    #[test]
    fn every_building_names_the_feature_it_came_from() {
        let sq = |x: f64| polygon![(x: x, y: 0.0), (x: x + 10.0, y: 0.0), (x: x + 10.0, y: 10.0), (x: x, y: 10.0), (x: x, y: 0.0)];
        let features = vec![
            Feature {
                fid: 7,
                geometry: Geometry::Polygon(sq(0.0)),
                attributes: Attributes::new(),
            },
            Feature {
                fid: 12,
                geometry: Geometry::MultiPolygon(MultiPolygon(vec![sq(50.0), sq(100.0)])),
                attributes: Attributes::new(),
            },
        ];
        let layer = Layer {
            name: "a:b".into(),
            source: "x".into(),
            crs: Crs::Unknown,
            features,
            report: ImportReport {
                read: 2,
                imported: 2,
                ..Default::default()
            },
        };
        let city = crate::city::build::build_city(&layer, None, None, &Default::default()).unwrap();
        let fids: Vec<Option<u64>> = city
            .buildings
            .iter()
            .map(|b| source_fid(&b.source_id))
            .collect();
        assert_eq!(fids, [Some(7), Some(12), Some(12)]);
        assert_eq!(source_fid("no id"), None);
    }
}
