//! Layers → [`City`]: CRS to metric world coordinates, footprint repair, heights, streets and
//! parcels, and the [`CityReport`] that accounts for every input feature (seed 003 §3: the
//! cadastral map is the input of the whole pipeline).
//!
//! # Footprints
//! Each footprint feature is transformed to metric world coordinates and repaired with
//! [`repair_polygon`]. A MultiPolygon, or a polygon that repair splits, gives one [`Building`]
//! per part; parts are numbered in order and get the source id `layer:fid.k`, a single polygon
//! gets `layer:fid`. In the report each *feature* counts once: imported (every part valid as it
//! was, up to winding), repaired (something was done, including parts refused), or refused (no
//! part left, or refused by the importer). So `imported + repaired + refused == read`.
//!
//! # Heights
//! From the first field of [`HeightFields`] that holds a usable number: a height in metres
//! ([`HeightSource::Height`]); else levels × storey height, plus roof levels × storey height when
//! given ([`HeightSource::Levels`]); else the default height ([`HeightSource::Default`], 9 m: three
//! storeys of 3 m, a typical low-rise city building). A value is usable when it is finite,
//! positive and at most 1000 m (the tallest building is 828 m); an unusable value is noted and
//! the next source is tried. The bottom of the prism is `min_height` (m) or `min_level` × storey
//! height, else 0; a bottom at or above the top is clamped to 0, with a note.

use std::collections::BTreeMap;

use blockwalk_importers::{AttrValue, Attributes, Layer};
use geo_types::{Coord, Geometry, LineString, Polygon};
use glam::DVec3;

use super::model::{
    Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Parcel, RefusalNote,
    RepairNote, Street,
};
use crate::geom::repair::{repair_polygon, Repaired};

/// Field names searched, in order, for each height attribute, and the rules that turn them into
/// metres. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightFields {
    /// Height in metres.
    pub height: Vec<String>,
    /// Number of storeys above ground.
    pub levels: Vec<String>,
    /// Storeys in the roof, added to `levels` when present.
    pub roof_levels: Vec<String>,
    /// Bottom of the prism in metres.
    pub min_height: Vec<String>,
    /// Bottom of the prism in storeys.
    pub min_level: Vec<String>,
    /// Metres per storey.
    pub storey_m: f64,
    /// Height when no field holds a usable value.
    pub default_height_m: f64,
}

impl Default for HeightFields {
    fn default() -> Self {
        let v = |s: &[&str]| s.iter().map(|x| x.to_string()).collect();
        HeightFields {
            height: v(&["height", "HEIGHT", "h", "Height"]),
            levels: v(&["levels", "building:levels", "LEVELS", "Levels"]),
            roof_levels: v(&["roof_lvls", "roof:levels"]),
            min_height: v(&["min_height", "MIN_HEIGHT"]),
            min_level: v(&["min_level", "building:min_level", "MIN_LEVEL"]),
            storey_m: 3.0,
            default_height_m: 9.0,
        }
    }
}

/// Options of [`build_city`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildOptions {
    /// Height fields and rules.
    pub heights: HeightFields,
    /// Leave out street features whose attribute `k` equals `v` (compared as text).
    pub exclude_street_tags: Vec<(String, String)>,
}

/// Why a city could not be built at all (single features never fail the build: they are
/// refused in the report).
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The footprint layer holds no building that could be imported.
    #[error("{file}: no usable building footprint ({read} feature(s) read, all refused)")]
    NoBuildings {
        /// The footprint file.
        file: String,
        /// Features read.
        read: usize,
    },
    /// The options are unusable.
    #[error("invalid build options: {0}")]
    Options(String),
}

/// How one feature's height was decided.
#[derive(Clone, Debug, PartialEq)]
pub struct Heights {
    /// Top, metres above ground.
    pub height_m: f64,
    /// Bottom, metres above ground.
    pub min_height_m: f64,
    /// Where the top came from.
    pub source: HeightSource,
    /// Anything noteworthy (unusable values, clamping).
    pub notes: Vec<String>,
}

fn first_number(attrs: &Attributes, names: &[String]) -> Option<(String, f64, bool)> {
    for n in names {
        match attrs.get(n) {
            None | Some(AttrValue::Null) => continue,
            Some(v) => {
                return Some(match v.as_f64() {
                    Some(x) => (n.clone(), x, true),
                    None => (n.clone(), f64::NAN, false),
                })
            }
        }
    }
    None
}

fn usable(x: f64) -> bool {
    x.is_finite() && x > 0.0 && x <= 1000.0
}

/// Decides a building's heights from its attributes (see the module documentation).
pub fn heights_from_attributes(attrs: &Attributes, f: &HeightFields) -> Heights {
    let mut notes = Vec::new();
    let mut chosen = None;
    if let Some((name, h, _)) = first_number(attrs, &f.height) {
        if usable(h) {
            chosen = Some((h, HeightSource::Height));
        } else {
            notes.push(format!("unusable {name}={:?}", attrs.get(&name)));
        }
    }
    if chosen.is_none() {
        if let Some((name, l, _)) = first_number(attrs, &f.levels) {
            let roof = first_number(attrs, &f.roof_levels)
                .filter(|(_, r, _)| r.is_finite() && *r >= 0.0)
                .map(|(_, r, _)| r)
                .unwrap_or(0.0);
            let h = (l + roof) * f.storey_m;
            if l.is_finite() && l > 0.0 && usable(h) {
                chosen = Some((h, HeightSource::Levels));
            } else {
                notes.push(format!("unusable {name}={:?}", attrs.get(&name)));
            }
        }
    }
    let (height_m, source) = chosen.unwrap_or((f.default_height_m, HeightSource::Default));
    let mut min_height_m = 0.0;
    if let Some((name, m, _)) = first_number(attrs, &f.min_height) {
        if m.is_finite() && m >= 0.0 {
            min_height_m = m;
        } else {
            notes.push(format!("unusable {name}={:?}", attrs.get(&name)));
        }
    } else if let Some((name, l, _)) = first_number(attrs, &f.min_level) {
        if l.is_finite() && l >= 0.0 {
            min_height_m = l * f.storey_m;
        } else {
            notes.push(format!("unusable {name}={:?}", attrs.get(&name)));
        }
    }
    if min_height_m >= height_m {
        notes.push(format!(
            "bottom {min_height_m} m at or above top {height_m} m: bottom clamped to 0"
        ));
        min_height_m = 0.0;
    }
    Heights {
        height_m,
        min_height_m,
        source,
        notes,
    }
}

/// True for attribute values that mean "yes" (`yes`, `true`, `1`, any non-zero number, and OSM
/// values such as `viaduct` or `building_passage`); false for `no`, `0`, `false`, null, empty.
pub fn truthy(v: &AttrValue) -> bool {
    match v {
        AttrValue::Null => false,
        AttrValue::Bool(b) => *b,
        AttrValue::Int(i) => *i != 0,
        AttrValue::Float(f) => *f != 0.0 && !f.is_nan(),
        AttrValue::Text(s) => {
            let t = s.trim().to_ascii_lowercase();
            !(t.is_empty() || t == "no" || t == "0" || t == "false" || t == "none")
        }
    }
}

fn attr_text(v: &AttrValue) -> String {
    match v {
        AttrValue::Null => String::new(),
        AttrValue::Bool(b) => b.to_string(),
        AttrValue::Int(i) => i.to_string(),
        AttrValue::Float(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{}", *f as i64),
        AttrValue::Float(f) => f.to_string(),
        AttrValue::Text(s) => s.clone(),
    }
}

/// True when the feature carries attribute `k` with value `v` (compared as text; a float 1.0
/// matches "1").
pub fn has_tag(attrs: &Attributes, k: &str, v: &str) -> bool {
    attrs.get(k).map(|x| attr_text(x) == v).unwrap_or(false)
}

fn polygons_of(g: &Geometry<f64>) -> Option<Vec<Polygon<f64>>> {
    match g {
        Geometry::Polygon(p) => Some(vec![p.clone()]),
        Geometry::MultiPolygon(m) => Some(m.0.clone()),
        Geometry::Rect(r) => Some(vec![r.to_polygon()]),
        Geometry::Triangle(t) => Some(vec![t.to_polygon()]),
        _ => None,
    }
}

fn lines_of(g: &Geometry<f64>) -> Option<Vec<LineString<f64>>> {
    match g {
        Geometry::LineString(l) => Some(vec![l.clone()]),
        Geometry::MultiLineString(m) => Some(m.0.clone()),
        Geometry::Line(l) => Some(vec![LineString::from(vec![l.start, l.end])]),
        _ => None,
    }
}

fn geometry_kind(g: &Geometry<f64>) -> &'static str {
    match g {
        Geometry::Point(_) => "Point",
        Geometry::MultiPoint(_) => "MultiPoint",
        Geometry::LineString(_) => "LineString",
        Geometry::MultiLineString(_) => "MultiLineString",
        Geometry::Line(_) => "Line",
        Geometry::Polygon(_) => "Polygon",
        Geometry::MultiPolygon(_) => "MultiPolygon",
        Geometry::Rect(_) => "Rect",
        Geometry::Triangle(_) => "Triangle",
        Geometry::GeometryCollection(_) => "GeometryCollection",
    }
}

fn to_metric_polygon(p: &Polygon<f64>, f: &impl Fn([f64; 2]) -> [f64; 2]) -> Polygon<f64> {
    let ring = |l: &LineString<f64>| -> LineString<f64> {
        l.0.iter()
            .map(|c| {
                let [x, y] = f([c.x, c.y]);
                Coord { x, y }
            })
            .collect::<Vec<_>>()
            .into()
    };
    Polygon::new(ring(p.exterior()), p.interiors().iter().map(ring).collect())
}

fn layer_bbox_center(layer: &Layer) -> Option<[f64; 2]> {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for f in &layer.features {
        if let Some(ps) = polygons_of(&f.geometry) {
            for p in ps {
                for c in p.exterior().0.iter() {
                    if c.x.is_finite() && c.y.is_finite() {
                        b[0] = b[0].min(c.x);
                        b[1] = b[1].min(c.y);
                        b[2] = b[2].max(c.x);
                        b[3] = b[3].max(c.y);
                    }
                }
            }
        }
    }
    (b[0] <= b[2]).then(|| [(b[0] + b[2]) * 0.5, (b[1] + b[3]) * 0.5])
}

fn repair_outcome(r: &Repaired) -> String {
    r.actions
        .iter()
        .filter(|a| !a.is_normalization())
        .map(|a| a.to_string())
        .collect::<Vec<_>>()
        .join("; ")
}

/// Builds a city from a footprint layer and optional street and parcel layers (all in their own
/// CRS; streets and parcels are taken to share the footprints' CRS).
///
/// # Errors
/// [`BuildError::NoBuildings`] when no footprint survives; [`BuildError::Options`] for a storey
/// or default height that is not positive.
pub fn build_city(
    footprints: &Layer,
    streets: Option<&Layer>,
    parcels: Option<&Layer>,
    opts: &BuildOptions,
) -> Result<City, BuildError> {
    let hf = &opts.heights;
    if !(hf.storey_m.is_finite() && hf.storey_m > 0.0) {
        return Err(BuildError::Options(format!(
            "storey height {} m is not positive",
            hf.storey_m
        )));
    }
    if !usable(hf.default_height_m) {
        return Err(BuildError::Options(format!(
            "default height {} m is not in (0, 1000]",
            hf.default_height_m
        )));
    }
    let center = layer_bbox_center(footprints).unwrap_or([0.0, 0.0]);
    let transform = footprints.crs.metric_transform(center);
    let to_m = |p: [f64; 2]| transform.to_metric(p);
    let lname = &footprints.name;

    let mut report = CityReport {
        buildings_read: footprints
            .report
            .read
            .max(footprints.features.len() + footprints.report.refused.len()),
        crs: transform.describe(),
        ..Default::default()
    };
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

    // Repair in parallel (the expensive part), account sequentially in input order.
    use rayon::prelude::*;
    let outcomes: Vec<Option<Vec<Result<Repaired, String>>>> = footprints
        .features
        .par_iter()
        .map(|f| {
            polygons_of(&f.geometry).map(|ps| {
                ps.iter()
                    .map(|p| {
                        repair_polygon(&to_metric_polygon(p, &to_m)).map_err(|e| e.to_string())
                    })
                    .collect()
            })
        })
        .collect();

    let mut buildings: Vec<Building> = Vec::with_capacity(footprints.features.len());
    for (f, outcome) in footprints.features.iter().zip(outcomes) {
        let base = format!("{lname}:{}", f.fid);
        let Some(parts) = outcome else {
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
        let heights = heights_from_attributes(&f.attributes, hf);
        let n_out: usize = parts
            .iter()
            .map(|r| r.as_ref().map(|r| r.polygons.len()).unwrap_or(0))
            .sum();
        let single = n_out == 1 && parts.len() == 1;
        let mut what = Vec::new();
        let mut k = 0usize;
        for (pi, part) in parts.iter().enumerate() {
            match part {
                Err(reason) => {
                    if parts.len() > 1 {
                        what.push(format!("part {pi} refused: {reason}"));
                    } else {
                        what.push(reason.clone());
                    }
                }
                Ok(rep) => {
                    if rep.was_repaired() {
                        let s = repair_outcome(rep);
                        what.push(if parts.len() > 1 {
                            format!("part {pi}: {s}")
                        } else {
                            s
                        });
                    }
                    for poly in &rep.polygons {
                        let source_id = if single {
                            base.clone()
                        } else {
                            format!("{base}.{k}")
                        };
                        k += 1;
                        buildings.push(Building {
                            id: BuildingId(buildings.len() as u32),
                            source_id,
                            footprint: poly.clone(),
                            height_m: heights.height_m,
                            min_height_m: heights.min_height_m,
                            height_source: heights.source,
                            attributes: f.attributes.clone(),
                        });
                        *report
                            .height_sources
                            .entry(source_name(heights.source).to_string())
                            .or_insert(0) += 1;
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
        }
    }
    if buildings.is_empty() {
        return Err(BuildError::NoBuildings {
            file: footprints.source.display().to_string(),
            read: report.buildings_read,
        });
    }

    // Local frame: centre of the footprints' metric bounding box, ground at z = 0.
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for bl in &buildings {
        for c in bl.footprint.exterior().0.iter() {
            b[0] = b[0].min(c.x);
            b[1] = b[1].min(c.y);
            b[2] = b[2].max(c.x);
            b[3] = b[3].max(c.y);
        }
    }
    let frame = LocalFrame {
        origin: DVec3::new((b[0] + b[2]) * 0.5, (b[1] + b[3]) * 0.5, 0.0),
    };

    let streets_out = match streets {
        Some(l) => build_streets(l, &to_m, opts, &mut report),
        None => Vec::new(),
    };
    let parcels_out = match parcels {
        Some(l) => build_parcels(l, &to_m, &mut report),
        None => Vec::new(),
    };

    Ok(City {
        name: footprints.name.clone(),
        transform,
        frame,
        buildings,
        streets: streets_out,
        parcels: parcels_out,
        report,
    })
}

/// The report key of a height source.
pub fn source_name(s: HeightSource) -> &'static str {
    match s {
        HeightSource::Height => "height",
        HeightSource::Levels => "levels",
        HeightSource::Default => "default",
    }
}

fn build_streets(
    layer: &Layer,
    to_m: &impl Fn([f64; 2]) -> [f64; 2],
    opts: &BuildOptions,
    report: &mut CityReport,
) -> Vec<Street> {
    let name = &layer.name;
    let mut out = Vec::new();
    let mut excluded = 0usize;
    let mut refused: Vec<String> = Vec::new();
    for r in &layer.report.refused {
        refused.push(format!("{name}:{} (importer: {})", r.fid, r.reason));
    }
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
            refused.push(format!(
                "{id} ({} is not a line)",
                geometry_kind(&f.geometry)
            ));
            continue;
        };
        let grade_separated = ["bridge", "tunnel", "BRIDGE", "TUNNEL"]
            .iter()
            .any(|k| f.attributes.get(*k).map(truthy).unwrap_or(false));
        let n = lines.len();
        let mut kept = 0;
        for (k, l) in lines.iter().enumerate() {
            let mut pts: Vec<Coord<f64>> = Vec::with_capacity(l.0.len());
            let mut finite = true;
            for c in &l.0 {
                if !(c.x.is_finite() && c.y.is_finite()) {
                    finite = false;
                    break;
                }
                let [x, y] = to_m([c.x, c.y]);
                pts.push(Coord { x, y });
            }
            pts.dedup();
            if !finite || pts.len() < 2 {
                refused.push(format!(
                    "{id}.{k} ({})",
                    if finite {
                        "fewer than 2 distinct points"
                    } else {
                        "non-finite coordinate"
                    }
                ));
                continue;
            }
            kept += 1;
            out.push(Street {
                source_id: if n == 1 {
                    id.clone()
                } else {
                    format!("{id}.{k}")
                },
                line: LineString::from(pts),
                grade_separated,
                attributes: f.attributes.clone(),
            });
        }
        let _ = kept;
    }
    report.notes.push(format!(
        "streets {name}: {} read, {} line(s) kept, {excluded} excluded by tag, {} refused{}",
        layer.report.read.max(layer.features.len()),
        out.len(),
        refused.len(),
        if refused.is_empty() {
            String::new()
        } else {
            format!(": {}", refused.join(", "))
        }
    ));
    out
}

fn build_parcels(
    layer: &Layer,
    to_m: &impl Fn([f64; 2]) -> [f64; 2],
    report: &mut CityReport,
) -> Vec<Parcel> {
    let name = &layer.name;
    let mut out = Vec::new();
    let mut refused: Vec<String> = layer
        .report
        .refused
        .iter()
        .map(|r| format!("{name}:{} (importer: {})", r.fid, r.reason))
        .collect();
    let mut repaired = 0usize;
    for f in &layer.features {
        let id = format!("{name}:{}", f.fid);
        let Some(ps) = polygons_of(&f.geometry) else {
            refused.push(format!(
                "{id} ({} is not a polygon)",
                geometry_kind(&f.geometry)
            ));
            continue;
        };
        let mut parts = Vec::new();
        for p in &ps {
            match repair_polygon(&to_metric_polygon(p, to_m)) {
                Ok(r) => {
                    if r.was_repaired() {
                        repaired += 1;
                    }
                    parts.extend(r.polygons);
                }
                Err(e) => refused.push(format!("{id} ({e})")),
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
    report.notes.push(format!(
        "parcels {name}: {} read, {} polygon(s) kept, {repaired} repaired, {} refused{}",
        layer.report.read.max(layer.features.len()),
        out.len(),
        refused.len(),
        if refused.is_empty() {
            String::new()
        } else {
            format!(": {}", refused.join(", "))
        }
    ));
    out
}

/// Buildings per height source, as the report counts them.
pub fn count_height_sources(buildings: &[Building]) -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for b in buildings {
        *m.entry(source_name(b.height_source).to_string())
            .or_insert(0) += 1;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::predicates::polygon_area;
    use crate::geom::repair::check_polygon;
    use blockwalk_importers::{Crs, Feature, ImportReport};
    use geo_types::{coord, MultiPolygon};

    fn attrs(kv: &[(&str, AttrValue)]) -> Attributes {
        kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
    }

    fn rect(x0: f64, y0: f64, w: f64, h: f64) -> Polygon<f64> {
        // Clockwise, as a Shapefile stores it.
        Polygon::new(
            LineString::from(vec![
                (x0, y0),
                (x0, y0 + h),
                (x0 + w, y0 + h),
                (x0 + w, y0),
                (x0, y0),
            ]),
            vec![],
        )
    }

    fn layer(features: Vec<Feature>, refused: usize) -> Layer {
        let mut report = ImportReport {
            read: features.len() + refused,
            imported: features.len(),
            ..Default::default()
        };
        for i in 0..refused {
            report.refuse(1000 + i as u64, "truncated record");
        }
        Layer {
            name: "b".into(),
            source: "b.shp".into(),
            crs: Crs::Projected {
                epsg: Some(32633),
                name: "UTM 33N".into(),
            },
            features,
            report,
        }
    }

    #[test]
    fn heights_follow_the_documented_rule() {
        let f = HeightFields::default();
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Float(12.5))]), &f);
        assert_eq!((h.height_m, h.source), (12.5, HeightSource::Height));
        let h = heights_from_attributes(
            &attrs(&[
                ("height", AttrValue::Null),
                ("levels", AttrValue::Int(4)),
                ("roof_lvls", AttrValue::Int(1)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.source), (15.0, HeightSource::Levels));
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("x".into()))]), &f);
        assert_eq!((h.height_m, h.source), (9.0, HeightSource::Default));
        assert_eq!(h.notes.len(), 1);
        let h = heights_from_attributes(
            &attrs(&[
                ("levels", AttrValue::Float(2.0)),
                ("min_level", AttrValue::Int(3)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.min_height_m), (6.0, 0.0));
        assert!(h.notes[0].contains("clamped"));
        let h = heights_from_attributes(
            &attrs(&[
                ("height", AttrValue::Float(30.0)),
                ("min_height", AttrValue::Float(10.0)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.min_height_m), (30.0, 10.0));
    }

    #[test]
    fn every_feature_is_accounted_for() {
        let bow = Polygon::new(
            LineString::from(vec![(0., 0.), (10., 10.), (10., 0.), (0., 10.), (0., 0.)]),
            vec![],
        );
        let feats = vec![
            Feature {
                fid: 0,
                geometry: Geometry::Polygon(rect(500000., 5.4e6, 10., 20.)),
                attributes: attrs(&[("height", AttrValue::Float(20.0))]),
            },
            Feature {
                fid: 1,
                geometry: Geometry::Polygon(bow),
                attributes: attrs(&[]),
            },
            Feature {
                fid: 2,
                geometry: Geometry::MultiPolygon(MultiPolygon::new(vec![
                    rect(500100., 5.4e6, 5., 5.),
                    rect(500200., 5.4e6, 5., 5.),
                ])),
                attributes: attrs(&[("levels", AttrValue::Int(2))]),
            },
            Feature {
                fid: 3,
                geometry: Geometry::Point(geo_types::Point::new(1.0, 2.0)),
                attributes: attrs(&[]),
            },
            Feature {
                fid: 4,
                geometry: Geometry::Polygon(Polygon::new(
                    LineString::from(vec![(1., 1.), (2., 2.), (3., 3.), (1., 1.)]),
                    vec![],
                )),
                attributes: attrs(&[]),
            },
        ];
        let l = layer(feats, 2);
        let city = build_city(&l, None, None, &BuildOptions::default()).unwrap();
        let r = &city.report;
        assert_eq!(r.buildings_read, 7);
        assert_eq!(
            r.buildings_imported + r.buildings_repaired.len() + r.buildings_refused.len(),
            r.buildings_read
        );
        assert_eq!(r.buildings_imported, 2); // fid 0 and the multipolygon fid 2
        assert_eq!(r.buildings_repaired.len(), 1); // bowtie
        assert_eq!(r.buildings_refused.len(), 4); // 2 importer, point, collinear
                                                  // 1 + 2 bowtie lobes + 2 parts
        assert_eq!(city.buildings.len(), 5);
        let ids: Vec<&str> = city
            .buildings
            .iter()
            .map(|b| b.source_id.as_str())
            .collect();
        assert_eq!(ids, ["b:0", "b:1.0", "b:1.1", "b:2.0", "b:2.1"]);
        for (i, b) in city.buildings.iter().enumerate() {
            assert_eq!(b.id, BuildingId(i as u32));
            check_polygon(&b.footprint).unwrap();
        }
        assert_eq!(polygon_area(&city.buildings[0].footprint), 200.0);
        assert_eq!(r.height_sources["height"], 1);
        assert_eq!(r.height_sources["levels"], 2);
        assert_eq!(r.height_sources["default"], 2);
        assert_eq!(count_height_sources(&city.buildings), r.height_sources);
        // Frame origin: centre of the metric bbox of the buildings (x 0..500205, y 0..5.4e6+20).
        let o = city.frame.origin;
        assert_eq!(o.z, 0.0);
        assert!(
            (o.x - 250102.5).abs() < 1e-6 && (o.y - 2.70001e6).abs() < 1e-6,
            "{o}"
        );
    }

    #[test]
    fn streets_grade_separation_and_exclusion() {
        let feats = vec![Feature {
            fid: 0,
            geometry: Geometry::Polygon(rect(0., 0., 10., 10.)),
            attributes: attrs(&[]),
        }];
        let fl = layer(feats, 0);
        let line = |fid, a: &[(&str, AttrValue)]| Feature {
            fid,
            geometry: Geometry::LineString(LineString::from(vec![(0., -5.), (10., -5.)])),
            attributes: attrs(a),
        };
        let sl = Layer {
            name: "s".into(),
            features: vec![
                line(0, &[("bridge", AttrValue::Text("yes".into()))]),
                line(1, &[("tunnel", AttrValue::Float(1.0))]),
                line(2, &[("bridge", AttrValue::Text("no".into()))]),
                line(3, &[("highway", AttrValue::Text("footway".into()))]),
                Feature {
                    fid: 4,
                    geometry: Geometry::Point(geo_types::Point::new(0., 0.)),
                    attributes: attrs(&[]),
                },
            ],
            ..layer(vec![], 0)
        };
        let opts = BuildOptions {
            exclude_street_tags: vec![("highway".into(), "footway".into())],
            ..Default::default()
        };
        let city = build_city(&fl, Some(&sl), None, &opts).unwrap();
        let gs: Vec<bool> = city.streets.iter().map(|s| s.grade_separated).collect();
        assert_eq!(gs, [true, true, false]);
        let note = city
            .report
            .notes
            .iter()
            .find(|n| n.starts_with("streets"))
            .unwrap();
        assert!(
            note.contains("1 excluded") && note.contains("1 refused"),
            "{note}"
        );
        let _ = coord! {x: 0.0, y: 0.0};
    }

    #[test]
    fn no_buildings_is_an_error() {
        let l = layer(vec![], 3);
        assert!(matches!(
            build_city(&l, None, None, &BuildOptions::default()),
            Err(BuildError::NoBuildings { read: 3, .. })
        ));
    }
}
