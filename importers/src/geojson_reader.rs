//! GeoJSON reader (RFC 7946, and GDAL's legacy form with a `crs` member).
//!
//! The file is parsed as JSON, then each feature separately with the `geojson` crate, so that one
//! malformed feature is refused in the report instead of failing the whole file. The top level may
//! be a `FeatureCollection`, a single `Feature` or a bare geometry.
//!
//! - Geometry maps one to one onto geo-types (positions keep x and y; z is dropped). Polygons are
//!   taken as written (first ring outer, then holes); winding is not changed.
//! - Properties → attributes: strings → text, integers → int, other numbers → float, booleans →
//!   bool, null → null, arrays and objects → their JSON text.
//! - A UTF-8 byte order mark before the JSON is skipped; an empty file is [`ImportError::Empty`].
//! - CRS: the legacy `"crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}}`
//!   member (also `EPSG:n` and `OGC:CRS84`) gives the CRS; a member that names an unknown code or
//!   nothing usable is an [`ImportError::Crs`]. Without it RFC 7946 says WGS84
//!   longitude/latitude; when most features clearly are not degrees (|x| > 360 or |y| > 180)
//!   the CRS is [`Crs::Unknown`] and a note says why. A few features beyond ±90° latitude do not
//!   make a layer metric: they stay degrees and are refused for it by the city build.
//! - A feature with null geometry, an empty geometry, NaN/infinite coordinates or an invalid
//!   structure is refused with its index and the reason.

use crate::crs::{Crs, CrsError};
use crate::{AttrValue, Feature, ImportError, ImportReport, Layer};
use geo_types::{
    Coord, Geometry, GeometryCollection, LineString, MultiLineString, MultiPoint, MultiPolygon,
    Point, Polygon,
};
use geojson::{GeometryValue, Position};
use serde_json::Value;
use std::path::Path;

/// Reads a GeoJSON layer.
///
/// # Errors
/// [`ImportError::Io`] when the file cannot be read; [`ImportError::Empty`] when it is empty;
/// [`ImportError::Json`] when it is not JSON; [`ImportError::Format`] when its top level is not a
/// GeoJSON object; [`ImportError::Crs`] for an unusable `crs` member.
pub fn read(path: &Path) -> Result<Layer, ImportError> {
    let text = std::fs::read(path).map_err(|source| ImportError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let format = |message: String| ImportError::Format {
        file: path.to_path_buf(),
        message,
    };
    if text.iter().all(u8::is_ascii_whitespace) {
        return Err(ImportError::Empty {
            file: path.to_path_buf(),
            what: "expected a GeoJSON object".into(),
        });
    }
    // A UTF-8 byte order mark (written by some Windows tools) is not JSON; RFC 8259 §8.1 lets a
    // parser ignore it.
    let body = text.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&text);
    let root: Value = serde_json::from_slice(body).map_err(|source| ImportError::Json {
        file: path.to_path_buf(),
        source,
    })?;
    let Value::Object(obj) = &root else {
        return Err(format("the top level is not a JSON object".into()));
    };
    let ty = obj.get("type").and_then(Value::as_str).unwrap_or("");
    let mut report = ImportReport::default();
    let mut features = Vec::new();
    let mut raw: Vec<Value> = Vec::new();
    match ty {
        "FeatureCollection" => match obj.get("features") {
            Some(Value::Array(a)) => raw.extend(a.iter().cloned()),
            _ => {
                return Err(format(
                    "FeatureCollection without a `features` array".into(),
                ))
            }
        },
        "Feature" => raw.push(root.clone()),
        "Point" | "MultiPoint" | "LineString" | "MultiLineString" | "Polygon" | "MultiPolygon"
        | "GeometryCollection" => {
            raw.push(serde_json::json!({"type": "Feature", "properties": {}, "geometry": root}))
        }
        other => {
            return Err(format(format!(
                "top-level `type` is {other:?}, not a GeoJSON object"
            )))
        }
    }
    report.read = raw.len();
    let mut bbox = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    // Features whose coordinates cannot be degrees even by mistake (beyond ±360, ±180).
    let mut metric_looking = 0usize;
    for (i, v) in raw.into_iter().enumerate() {
        let fid = i as u64;
        let feature = match serde_json::from_value::<geojson::Feature>(v) {
            Ok(f) => f,
            Err(e) => {
                report.refuse(fid, format!("not a valid GeoJSON feature: {e}"));
                continue;
            }
        };
        let Some(g) = feature.geometry else {
            report.refuse(fid, "null geometry");
            continue;
        };
        match convert(&g.value) {
            Ok(geometry) => {
                let mut own = [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ];
                grow_bbox(&geometry, &mut own);
                if own[0] < -360.0 || own[2] > 360.0 || own[1] < -180.0 || own[3] > 180.0 {
                    metric_looking += 1;
                }
                grow_bbox(&geometry, &mut bbox);
                let attributes = feature
                    .properties
                    .map(|p| p.into_iter().map(|(k, v)| (k, attr(v))).collect())
                    .unwrap_or_default();
                features.push(Feature {
                    fid,
                    geometry,
                    attributes,
                });
            }
            Err(reason) => report.refuse(fid, reason),
        }
    }
    report.imported = features.len();
    let crs = match obj.get("crs") {
        Some(c) => {
            let crs = crs_member(c).map_err(|source| ImportError::Crs {
                file: path.to_path_buf(),
                from: format!("the `crs` member {c}"),
                source,
            })?;
            report
                .notes
                .push(format!("CRS from the `crs` member: {}", crs.describe()));
            crs
        }
        None => {
            // Most features far beyond any degree value: metres without a CRS. Otherwise degrees
            // as RFC 7946 says; a latitude of 95 is then refused feature by feature downstream.
            let degrees = metric_looking * 2 <= features.len();
            if degrees {
                report
                    .notes
                    .push("no `crs` member: WGS84 longitude/latitude (RFC 7946)".into());
                Crs::Geographic { epsg: Some(4326) }
            } else {
                report.notes.push(format!(
                    "no `crs` member, but coordinates span x {:.1}..{:.1}, y {:.1}..{:.1}, which \
                     are not degrees: CRS unknown, coordinates taken as metres",
                    bbox[0], bbox[2], bbox[1], bbox[3]
                ));
                Crs::Unknown
            }
        }
    };
    report.group_refusals();
    let name = obj
        .get("name")
        .and_then(Value::as_str)
        .map(str::to_string)
        .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_default();
    Ok(Layer {
        name,
        source: path.to_path_buf(),
        crs,
        features,
        report,
    })
}

/// The CRS named by a legacy GeoJSON `crs` member.
fn crs_member(c: &Value) -> Result<Crs, CrsError> {
    let name = c
        .get("properties")
        .and_then(|p| p.get("name"))
        .and_then(Value::as_str)
        .ok_or_else(|| CrsError::NotWkt {
            why: "a `crs` member needs properties.name".into(),
        })?;
    crs_from_name(name)
}

/// Recognises `urn:ogc:def:crs:EPSG::3857`, `EPSG:3857`, `urn:ogc:def:crs:OGC:1.3:CRS84`.
///
/// # Errors
/// [`CrsError::UnknownEpsg`] for a code not in the registry, [`CrsError::NotWkt`] for a name
/// that is neither.
pub(crate) fn crs_from_name(name: &str) -> Result<Crs, CrsError> {
    let n = name.trim().to_ascii_uppercase();
    if n.ends_with("CRS84") || n.ends_with("CRS:84") {
        return Ok(Crs::Geographic { epsg: Some(4326) });
    }
    let code = n.find("EPSG").and_then(|pos| {
        let digits: String = n[pos + 4..]
            .chars()
            .skip_while(|c| !c.is_ascii_digit())
            .take_while(|c| c.is_ascii_digit())
            .collect();
        digits.parse::<u32>().ok()
    });
    match code {
        Some(code) => Crs::from_epsg(code),
        None => Err(CrsError::NotWkt {
            why: format!("{name:?} names no EPSG code or CRS84"),
        }),
    }
}

fn attr(v: Value) -> AttrValue {
    match v {
        Value::Null => AttrValue::Null,
        Value::Bool(b) => AttrValue::Bool(b),
        Value::Number(n) => match n.as_i64() {
            Some(i) => AttrValue::Int(i),
            None => n.as_f64().map(AttrValue::Float).unwrap_or(AttrValue::Null),
        },
        Value::String(s) => AttrValue::Text(s),
        other => AttrValue::Text(other.to_string()),
    }
}

fn grow_bbox(g: &Geometry, b: &mut [f64; 4]) {
    let mut add = |c: &Coord| {
        b[0] = b[0].min(c.x);
        b[1] = b[1].min(c.y);
        b[2] = b[2].max(c.x);
        b[3] = b[3].max(c.y);
    };
    visit_coords(g, &mut add);
}

fn visit_coords(g: &Geometry, f: &mut impl FnMut(&Coord)) {
    match g {
        Geometry::Point(p) => f(&p.0),
        Geometry::MultiPoint(m) => m.0.iter().for_each(|p| f(&p.0)),
        Geometry::LineString(l) => l.0.iter().for_each(f),
        Geometry::MultiLineString(m) => m.0.iter().flat_map(|l| l.0.iter()).for_each(f),
        Geometry::Polygon(p) => poly_coords(p).for_each(f),
        Geometry::MultiPolygon(m) => m.0.iter().flat_map(poly_coords).for_each(f),
        Geometry::GeometryCollection(c) => c.0.iter().for_each(|g| visit_coords(g, f)),
        _ => {}
    }
}

fn poly_coords(p: &Polygon) -> impl Iterator<Item = &Coord> {
    p.exterior()
        .0
        .iter()
        .chain(p.interiors().iter().flat_map(|r| r.0.iter()))
}

fn coord(p: &Position, what: &str) -> Result<Coord, String> {
    let s = p.as_slice();
    if s.len() < 2 {
        return Err(format!("{what}: a position has fewer than 2 numbers"));
    }
    if !(s[0].is_finite() && s[1].is_finite()) {
        return Err(format!("{what}: non-finite coordinate (NaN or infinity)"));
    }
    Ok(Coord { x: s[0], y: s[1] })
}

fn line(ps: &[Position], what: &str) -> Result<LineString, String> {
    if ps.is_empty() {
        return Err(format!("{what}: empty"));
    }
    ps.iter()
        .map(|p| coord(p, what))
        .collect::<Result<Vec<_>, _>>()
        .map(LineString::new)
}

fn polygon(rings: &[Vec<Position>], what: &str) -> Result<Polygon, String> {
    let Some((outer, holes)) = rings.split_first() else {
        return Err(format!("{what}: no rings"));
    };
    let ext = line(outer, &format!("{what} outer ring"))?;
    let ints = holes
        .iter()
        .enumerate()
        .map(|(k, h)| line(h, &format!("{what} hole {k}")))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Polygon::new(ext, ints))
}

/// Converts a GeoJSON geometry, refusing empty geometry and non-finite coordinates.
pub(crate) fn convert(v: &GeometryValue) -> Result<Geometry, String> {
    Ok(match v {
        GeometryValue::Point { coordinates } => {
            Geometry::Point(Point(coord(coordinates, "Point")?))
        }
        GeometryValue::MultiPoint { coordinates } => {
            if coordinates.is_empty() {
                return Err("empty MultiPoint".into());
            }
            Geometry::MultiPoint(MultiPoint(
                coordinates
                    .iter()
                    .map(|p| coord(p, "MultiPoint").map(Point))
                    .collect::<Result<_, _>>()?,
            ))
        }
        GeometryValue::LineString { coordinates } => {
            Geometry::LineString(line(coordinates, "LineString")?)
        }
        GeometryValue::MultiLineString { coordinates } => {
            if coordinates.is_empty() {
                return Err("empty MultiLineString".into());
            }
            Geometry::MultiLineString(MultiLineString(
                coordinates
                    .iter()
                    .enumerate()
                    .map(|(k, l)| line(l, &format!("MultiLineString part {k}")))
                    .collect::<Result<_, _>>()?,
            ))
        }
        GeometryValue::Polygon { coordinates } => {
            Geometry::Polygon(polygon(coordinates, "Polygon")?)
        }
        GeometryValue::MultiPolygon { coordinates } => {
            if coordinates.is_empty() {
                return Err("empty MultiPolygon".into());
            }
            Geometry::MultiPolygon(MultiPolygon(
                coordinates
                    .iter()
                    .enumerate()
                    .map(|(k, p)| polygon(p, &format!("MultiPolygon part {k}")))
                    .collect::<Result<_, _>>()?,
            ))
        }
        GeometryValue::GeometryCollection { geometries } => {
            if geometries.is_empty() {
                return Err("empty GeometryCollection".into());
            }
            Geometry::GeometryCollection(GeometryCollection(
                geometries
                    .iter()
                    .map(|g| convert(&g.value))
                    .collect::<Result<_, _>>()?,
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crs_names() {
        assert_eq!(
            crs_from_name("urn:ogc:def:crs:EPSG::3857").unwrap(),
            Crs::WebMercator
        );
        assert_eq!(
            crs_from_name("EPSG:3067").unwrap(),
            Crs::from_epsg(3067).unwrap()
        );
        assert_eq!(
            crs_from_name("urn:ogc:def:crs:OGC:1.3:CRS84").unwrap(),
            Crs::Geographic { epsg: Some(4326) }
        );
        assert!(matches!(
            crs_from_name("local"),
            Err(CrsError::NotWkt { .. })
        ));
        assert!(matches!(
            crs_from_name("EPSG:99999"),
            Err(CrsError::UnknownEpsg { code: 99999 })
        ));
    }
}
