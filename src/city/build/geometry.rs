//! Geometry and attribute helpers of the build: kinds of geometry, tags, and the transform of
//! a polygon or line into the metric world with every vertex checked against its CRS.

use blockwalk_importers::{AttrValue, Attributes, MetricTransform};
use geo_types::{Coord, Geometry, LineString, Polygon};

pub(crate) fn polygons_of(g: &Geometry<f64>) -> Option<Vec<Polygon<f64>>> {
    match g {
        Geometry::Polygon(p) => Some(vec![p.clone()]),
        Geometry::MultiPolygon(m) => Some(m.0.clone()),
        Geometry::Rect(r) => Some(vec![r.to_polygon()]),
        Geometry::Triangle(t) => Some(vec![t.to_polygon()]),
        _ => None,
    }
}

pub(crate) fn lines_of(g: &Geometry<f64>) -> Option<Vec<LineString<f64>>> {
    match g {
        Geometry::LineString(l) => Some(vec![l.clone()]),
        Geometry::MultiLineString(m) => Some(m.0.clone()),
        Geometry::Line(l) => Some(vec![LineString::from(vec![l.start, l.end])]),
        _ => None,
    }
}

pub(crate) fn geometry_kind(g: &Geometry<f64>) -> &'static str {
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

/// A line's vertices in the metric world, each checked against the layer's CRS.
///
/// # Errors
/// The first vertex that does not fit, in words (`vertex 3: latitude 95° is beyond ±90° in …`).
pub(crate) fn to_metric_line(
    l: &LineString<f64>,
    t: &MetricTransform,
) -> Result<Vec<Coord<f64>>, String> {
    l.0.iter()
        .enumerate()
        .map(|(k, c)| {
            t.try_to_metric([c.x, c.y])
                .map(|[x, y]| Coord { x, y })
                .map_err(|e| format!("vertex {k}: {e}"))
        })
        .collect()
}

/// A polygon in the metric world, every vertex checked against the layer's CRS.
///
/// # Errors
/// The first vertex that does not fit, with its ring.
pub(crate) fn to_metric_polygon(
    p: &Polygon<f64>,
    t: &MetricTransform,
) -> Result<Polygon<f64>, String> {
    let ext = to_metric_line(p.exterior(), t).map_err(|e| format!("outer ring {e}"))?;
    let holes = p
        .interiors()
        .iter()
        .enumerate()
        .map(|(h, r)| {
            to_metric_line(r, t)
                .map(LineString::from)
                .map_err(|e| format!("hole {h} {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Polygon::new(LineString::from(ext), holes))
}
