//! Geometry and attribute helpers of the build: kinds of geometry, tags, and the transform of
//! a polygon or line into the metric world with every vertex checked against its CRS.

use std::collections::{HashMap, HashSet};

use blockwalk_importers::crs::BOX_CHECK_MAX;
use blockwalk_importers::{AttrValue, Attributes, Crs, MetricTransform};
use std::borrow::Cow;

use geo_types::{Coord, Geometry, LineString, Polygon};

use crate::geom::tolerance::MAX_WORLD_COORD_M;
use crate::geom::Rect;

/// The polygons of a geometry (borrowed where the geometry holds them); `None` for a kind
/// that is not a polygon.
pub(crate) fn polygons_of(g: &Geometry<f64>) -> Option<Vec<Cow<'_, Polygon<f64>>>> {
    match g {
        Geometry::Polygon(p) => Some(vec![Cow::Borrowed(p)]),
        Geometry::MultiPolygon(m) => Some(m.0.iter().map(Cow::Borrowed).collect()),
        Geometry::Rect(r) => Some(vec![Cow::Owned(r.to_polygon())]),
        Geometry::Triangle(t) => Some(vec![Cow::Owned(t.to_polygon())]),
        _ => None,
    }
}

/// The lines of a geometry (borrowed where the geometry holds them); `None` for a kind that is
/// not a line.
pub(crate) fn lines_of(g: &Geometry<f64>) -> Option<Vec<Cow<'_, LineString<f64>>>> {
    match g {
        Geometry::LineString(l) => Some(vec![Cow::Borrowed(l)]),
        Geometry::MultiLineString(m) => Some(m.0.iter().map(Cow::Borrowed).collect()),
        Geometry::Line(l) => Some(vec![Cow::Owned(LineString::from(vec![l.start, l.end]))]),
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

/// The box `[xmin, ymin, xmax, ymax]` of the given rings when every coordinate is finite.
fn finite_box<'a>(rings: impl IntoIterator<Item = &'a LineString<f64>>) -> Option<[f64; 4]> {
    let mut b: Option<Rect> = None;
    for c in rings.into_iter().flat_map(|r| &r.0) {
        if !(c.x.is_finite() && c.y.is_finite()) {
            return None;
        }
        b = Some(Rect::grow(b, Rect::point([c.x, c.y])));
    }
    b.map(Rect::to_array)
}

/// [`MetricTransform::box_fits`] for many small boxes, decided once per block of a grid.
///
/// The grid's cells are half of [`BOX_CHECK_MAX`] wide; a box at most one cell wide lies in
/// the 2 × 2 block of cells whose lower-left cell holds its lower-left corner, a box of
/// [`BOX_CHECK_MAX`] per side, and when that block fits, so does every box inside it (the
/// property `box_fits` rests on). The blocks of a layer's boxes are checked once, in parallel,
/// so that a city's footprints cost a few checks per square kilometre instead of four per
/// footprint; a box in a block that does not fit (or too large for one) is checked on its own.
pub(crate) struct BoxCheck<'a> {
    t: &'a MetricTransform,
    blocks: HashMap<[i64; 2], bool>,
}

impl<'a> BoxCheck<'a> {
    const CELL: f64 = 0.5 * BOX_CHECK_MAX;

    /// The checks of the blocks that `boxes` fall in.
    pub(crate) fn new(t: &'a MetricTransform, boxes: impl Iterator<Item = [f64; 4]>) -> Self {
        use rayon::prelude::*;
        // Geographic and unknown CRSs check bounds, which a box's corners decide for any size.
        let by_block = matches!(t.crs, Crs::Projected { .. } | Crs::WebMercator);
        let keys: HashSet<[i64; 2]> = if by_block {
            boxes.filter_map(Self::block).collect()
        } else {
            HashSet::new()
        };
        let blocks = keys
            .into_par_iter()
            .map(|k| (k, t.box_fits(Self::block_box(k))))
            .collect();
        BoxCheck { t, blocks }
    }

    /// The block of a box at most one cell wide (its lower-left cell), if any.
    fn block(b: [f64; 4]) -> Option<[i64; 2]> {
        let c = Self::CELL;
        let fits = b.iter().all(|v| v.is_finite() && v.abs() < 1e15)
            && b[2] - b[0] <= c
            && b[3] - b[1] <= c;
        fits.then(|| [(b[0] / c).floor() as i64, (b[1] / c).floor() as i64])
    }

    /// The box of a block: 2 × 2 cells from its lower-left cell.
    fn block_box(k: [i64; 2]) -> [f64; 4] {
        let c = Self::CELL;
        let (x, y) = (k[0] as f64 * c, k[1] as f64 * c);
        [x, y, x + 2.0 * c, y + 2.0 * c]
    }

    /// [`MetricTransform::box_fits`] of `b`, through its block when that was checked and fits.
    pub(crate) fn fits(&self, b: [f64; 4]) -> bool {
        let by_block = Self::block(b).and_then(|k| self.blocks.get(&k).copied());
        by_block == Some(true) || self.t.box_fits(b)
    }

    /// The transform.
    pub(crate) fn transform(&self) -> &MetricTransform {
        self.t
    }
}

/// The box of a line when every coordinate is finite.
pub(crate) fn line_box(l: &LineString<f64>) -> Option<[f64; 4]> {
    finite_box(std::iter::once(l))
}

/// The box of a polygon's rings when every coordinate is finite.
pub(crate) fn polygon_box(p: &Polygon<f64>) -> Option<[f64; 4]> {
    finite_box(std::iter::once(p.exterior()).chain(p.interiors()))
}

/// The rings in the metric world when their box fits the CRS as a whole
/// ([`MetricTransform::box_fits`], through `check` when given): the same coordinates
/// [`to_metric_line`] gives, without a check per vertex. `None` when the box does not fit or a
/// vertex does not transform (the caller then checks vertex by vertex, to name the one at
/// fault).
fn to_metric_rings_by_box<'a>(
    rings: impl IntoIterator<Item = &'a LineString<f64>> + Clone,
    t: &MetricTransform,
    check: Option<&BoxCheck<'_>>,
) -> Option<Vec<Vec<Coord<f64>>>> {
    let b = finite_box(rings.clone())?;
    let fits = match check {
        Some(c) => c.fits(b),
        None => t.box_fits(b),
    };
    if !fits {
        return None;
    }
    if t.is_identity() && b.iter().any(|v| v.abs() > MAX_WORLD_COORD_M) {
        return None;
    }
    if t.is_identity() {
        return Some(rings.into_iter().map(|r| r.0.clone()).collect());
    }
    rings
        .into_iter()
        .map(|r| {
            r.0.iter()
                .map(|c| {
                    let [x, y] = t.to_metric([c.x, c.y]);
                    (x.is_finite() && y.is_finite()).then_some(Coord { x, y })
                })
                .collect()
        })
        .collect()
}

/// A line's vertices in the metric world, each checked against the layer's CRS (a line whose
/// box fits the CRS as a whole is checked by the box, see [`MetricTransform::box_fits`]).
///
/// # Errors
/// The first vertex that does not fit, in words (`vertex 3: latitude 95° is beyond ±90° in …`),
/// or that lies beyond [`MAX_WORLD_COORD_M`].
pub(crate) fn to_metric_line(
    l: &LineString<f64>,
    t: &MetricTransform,
) -> Result<Vec<Coord<f64>>, String> {
    to_metric_line_checked(l, t, None)
}

/// [`to_metric_line`] with the box checked through `check` when given.
pub(crate) fn to_metric_line_checked(
    l: &LineString<f64>,
    t: &MetricTransform,
    check: Option<&BoxCheck<'_>>,
) -> Result<Vec<Coord<f64>>, String> {
    if let Some(mut r) = to_metric_rings_by_box(std::iter::once(l), t, check) {
        return Ok(r.pop().expect("one line"));
    }
    l.0.iter()
        .enumerate()
        .map(|(k, c)| {
            let [x, y] = t
                .try_to_metric([c.x, c.y])
                .map_err(|e| format!("vertex {k}: {e}"))?;
            if x.abs() > MAX_WORLD_COORD_M || y.abs() > MAX_WORLD_COORD_M {
                return Err(format!(
                    "vertex {k}: ({x:e}, {y:e}) m is more than {MAX_WORLD_COORD_M:e} m from the \
                     frame's origin, further than any place on Earth (coordinates in another \
                     unit?)"
                ));
            }
            Ok(Coord { x, y })
        })
        .collect()
}

/// A polygon in the metric world, every vertex checked against the layer's CRS (by the box of
/// all its rings when that fits the CRS as a whole, see [`MetricTransform::box_fits`]).
///
/// # Errors
/// The first vertex that does not fit, with its ring.
pub(crate) fn to_metric_polygon(
    p: &Polygon<f64>,
    t: &MetricTransform,
) -> Result<Polygon<f64>, String> {
    to_metric_polygon_checked(p, t, None)
}

/// [`to_metric_polygon`] with the boxes decided through `check` (of the transform `t`).
///
/// # Errors
/// As [`to_metric_polygon`].
pub(crate) fn to_metric_polygon_checked(
    p: &Polygon<f64>,
    t: &MetricTransform,
    check: Option<&BoxCheck<'_>>,
) -> Result<Polygon<f64>, String> {
    let rings = std::iter::once(p.exterior()).chain(p.interiors());
    if let Some(mut r) = to_metric_rings_by_box(rings, t, check) {
        let holes = r.split_off(1).into_iter().map(LineString::from).collect();
        let ext = r.pop().expect("the exterior");
        return Ok(Polygon::new(LineString::from(ext), holes));
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A square of side `s` at (x, y), as a footprint.
    fn square(x: f64, y: f64, s: f64) -> Polygon<f64> {
        Polygon::new(
            LineString::from(vec![(x, y), (x + s, y), (x + s, y + s), (x, y + s), (x, y)]),
            vec![],
        )
    }

    /// In a frame without a CRS nothing else bounds a coordinate: a vertex beyond a million
    /// kilometres is refused by its number, one just inside is kept, by box and by vertex.
    #[test]
    fn a_vertex_beyond_the_world_is_refused() {
        let t = Crs::Unknown.metric_transform([0.0, 0.0]);
        let far = LineString::from(vec![(0.0, 0.0), (10.0, 0.0), (2.0e9, 5.0)]);
        let e = to_metric_line(&far, &t).unwrap_err();
        assert!(
            e.starts_with("vertex 2: (2e9, 5e0) m is more than 1e9 m"),
            "{e}"
        );
        let near = LineString::from(vec![(0.0, 0.0), (-9.9e8, 5.0)]);
        assert_eq!(to_metric_line(&near, &t).unwrap(), near.0);
        let e = to_metric_polygon(&square(1.5e9, 0.0, 10.0), &t).unwrap_err();
        assert!(e.starts_with("outer ring vertex 0:"), "{e}");
    }

    /// Checking footprints by the blocks of a grid, by their own boxes, and vertex by vertex
    /// give the same polygons and the same refusals, in the city's range and across the edge
    /// of the projection's range.
    #[test]
    fn box_checks_by_block_agree_with_the_vertices() {
        let t = Crs::from_epsg(32633)
            .unwrap()
            .metric_transform([500_000.0, 5_400_000.0]);
        // The edge of the range along +x at the city's northing, by bisection.
        let (mut a, mut b) = (500_000.0f64, 1e9f64);
        assert!(t.check([a, 5.4e6]).is_ok() && t.check([b, 5.4e6]).is_err());
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if t.check([m, 5.4e6]).is_ok() {
                a = m;
            } else {
                b = m;
            }
        }
        // Squares of 1 to 700 m around the city and around the edge (a fixed sequence).
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut polys = Vec::new();
        for centre in [500_000.0, a] {
            for _ in 0..1000 {
                let s = 1.0 + 699.0 * next();
                let x = centre + 3_000.0 * (next() - 0.5);
                let y = 5.4e6 + 3_000.0 * (next() - 0.5);
                polys.push(square(x, y, s));
            }
        }
        let check = BoxCheck::new(&t, polys.iter().filter_map(polygon_box));
        let (mut ok, mut refused) = (0, 0);
        for p in &polys {
            let by_vertex: Result<Vec<Coord<f64>>, String> = p
                .exterior()
                .0
                .iter()
                .map(|c| {
                    t.try_to_metric([c.x, c.y])
                        .map(|[x, y]| Coord { x, y })
                        .map_err(|e| e.to_string())
                })
                .collect();
            let by_block = to_metric_polygon_checked(p, &t, Some(&check));
            let by_box = to_metric_polygon(p, &t);
            assert_eq!(by_block, by_box, "{p:?}");
            match (by_vertex, by_block) {
                (Ok(v), Ok(q)) => {
                    assert_eq!(v, q.exterior().0);
                    ok += 1;
                }
                (Err(_), Err(e)) => {
                    assert!(e.starts_with("outer ring vertex"), "{e}");
                    refused += 1;
                }
                (v, q) => panic!("{p:?}: by vertex {v:?}, by block {q:?}"),
            }
        }
        assert!(ok > 1000 && refused > 100, "{ok} fitted, {refused} refused");
        // The blocks do the work: far fewer than the footprints.
        assert!(
            check.blocks.len() < polys.len() / 4,
            "{}",
            check.blocks.len()
        );
    }
}
