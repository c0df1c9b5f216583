//! CityJSON 2.0 export (and CityJSONSeq, one feature per line, for large cities) of the buildings
//! as LoD1 solids with their LoD0 footprints, built from the f64 world footprints.
//!
//! - One `Building` per building, keyed by its source id (made unique with `#2`, `#3`, … when
//!   the source repeats an id). Geometry: an LoD0 `MultiSurface` (the footprint at the prism's
//!   bottom) and an LoD1 `Solid` (the extruded prism): a roof and a bottom surface carrying the
//!   courtyards as inner rings, and one wall per footprint edge, outer and courtyard rings alike.
//!   Surfaces are oriented so that their normals point out of the solid (exterior rings
//!   counter-clockwise seen from outside, inner rings the other way), as CityJSON requires, with
//!   semantics `RoofSurface`, `WallSurface` and `GroundSurface` (`OuterCeilingSurface` for a
//!   prism raised above the ground by its bottom height).
//! - Heights are metres above the ground (z = 0); there is no terrain.
//! - Attributes: the source attributes as they were read, then `source_id`, `height_m`,
//!   `min_height_m`, `height_source` (`height`, `levels` or `default`) and `storeysAboveGround`
//!   (the first levels field, when there is one); a source attribute of the same name as one of
//!   these is kept as `source:<name>`.
//! - Vertices are quantised with `transform`: `translate` is the minimum corner of the model and
//!   the scale a power of ten chosen from the data ([`choose_scale`]: 1 mm, finer when the
//!   footprints have shorter edges, as long as the extent fits in 32-bit integers). Vertices are shared between surfaces and buildings; none is
//!   repeated or unused.
//! - CRS: `metadata.referenceSystem` is `https://www.opengis.net/def/crs/EPSG/0/<code>` when the
//!   city's metric frame is a projected CRS with an EPSG code (coordinates are then that CRS's,
//!   unchanged). Footprints in Web Mercator or longitude/latitude are imported into a local
//!   transverse Mercator on WGS84 centred on the data, which has no EPSG code: then no
//!   `referenceSystem` is written (claiming EPSG:3857 or 4326 for these metres would be wrong);
//!   the local projection is written as a PROJ string in `metadata["+proj"]`, a property the
//!   CityJSON schema allows and readers ignore.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use blockwalk_importers::{AttrValue, Crs, MetricTransform};
use geo_types::{Coord, LineString};
use serde_json::{json, Map, Value};

use super::ExportError;
use crate::city::build::{source_name, HeightFields};
use crate::city::{Building, City};

/// A footprint edge is at least this many quantisation steps long (so that no edge collapses).
pub const STEPS_PER_SHORTEST_EDGE: f64 = 10.0;

/// What was written.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CityJsonStats {
    /// Buildings written.
    pub buildings: usize,
    /// Distinct vertices written.
    pub vertices: usize,
    /// The quantisation step, metres.
    pub scale_m: f64,
    /// `metadata.referenceSystem`, when written.
    pub reference_system: Option<String>,
    /// Footprint rings left out because they collapsed at the quantisation step (a courtyard
    /// smaller than a step), with the building's source id; a building whose outer ring
    /// collapses is left out whole and named here too.
    pub dropped_rings: Vec<String>,
    /// Bytes written.
    pub bytes: u64,
}

/// `metadata.referenceSystem` for a city's transform: an OGC EPSG URL when the metric frame is a
/// projected CRS with an EPSG code, `None` for the local transverse Mercator (no EPSG code) and
/// for unknown CRS.
pub fn reference_system(t: &MetricTransform) -> Option<String> {
    let frame = t.frame_crs.as_ref().unwrap_or(&t.crs);
    match frame {
        Crs::Projected { epsg: Some(e), .. } => {
            Some(format!("https://www.opengis.net/def/crs/EPSG/0/{e}"))
        }
        _ => None,
    }
}

/// The PROJ string of the metric frame when it has no EPSG code: the local transverse Mercator
/// of Web Mercator or geographic input, or a projected CRS known only by its definition; `None`
/// when [`reference_system`] names it or the CRS is unknown.
pub fn local_projection(t: &MetricTransform) -> Option<String> {
    if reference_system(t).is_some() {
        return None;
    }
    let frame = t.frame_crs.as_ref().unwrap_or(&t.crs);
    match (frame, t.center_lonlat) {
        (Crs::WebMercator | Crs::Geographic { .. }, Some([lon, lat])) => Some(format!(
            "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
        )),
        (Crs::Projected { proj4, .. }, _) => Some(proj4.clone()),
        _ => None,
    }
}

/// The quantisation step for these buildings: the coarsest of 1 mm, 0.1 mm, 10 µm and 1 µm at
/// which every footprint edge is at least [`STEPS_PER_SHORTEST_EDGE`] steps long, but never so
/// fine that the model's extent exceeds `i32::MAX` steps (what 32-bit readers hold).
pub fn choose_scale(buildings: &[Building]) -> f64 {
    let mut shortest = f64::INFINITY;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut top = 0.0f64;
    for b in buildings {
        for r in rings(b) {
            for w in r.0.windows(2) {
                let d = ((w[1].x - w[0].x).powi(2) + (w[1].y - w[0].y).powi(2)).sqrt();
                if d > 0.0 {
                    shortest = shortest.min(d);
                }
            }
            for c in &r.0 {
                lo = [lo[0].min(c.x), lo[1].min(c.y)];
                hi = [hi[0].max(c.x), hi[1].max(c.y)];
            }
        }
        top = top.max(b.height_m);
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(top).max(0.0);
    const STEPS: [f64; 4] = [1e-3, 1e-4, 1e-5, 1e-6];
    let mut s = STEPS[0];
    for &finer in &STEPS[1..] {
        if shortest >= STEPS_PER_SHORTEST_EDGE * s || extent / finer > i32::MAX as f64 {
            break;
        }
        s = finer;
    }
    s
}

fn rings(b: &Building) -> impl Iterator<Item = &LineString<f64>> {
    std::iter::once(b.footprint.exterior()).chain(b.footprint.interiors().iter())
}

/// Quantised vertices, each stored once.
struct Vertices {
    scale: f64,
    translate: [f64; 3],
    index: HashMap<[i64; 3], u32>,
    list: Vec<[i64; 3]>,
}

impl Vertices {
    fn new(scale: f64, translate: [f64; 3]) -> Self {
        Vertices {
            scale,
            translate,
            index: HashMap::new(),
            list: Vec::new(),
        }
    }
    fn quantise(&self, c: Coord<f64>, z: f64) -> [i64; 3] {
        let q = |v: f64, t: f64| ((v - t) / self.scale).round() as i64;
        [
            q(c.x, self.translate[0]),
            q(c.y, self.translate[1]),
            q(z, self.translate[2]),
        ]
    }
    fn id(&mut self, q: [i64; 3]) -> u32 {
        let next = self.list.len() as u32;
        *self.index.entry(q).or_insert_with(|| {
            self.list.push(q);
            next
        })
    }
    fn clear(&mut self) {
        self.index.clear();
        self.list.clear();
    }
}

/// A footprint ring as quantised plan positions, without the closing point and without
/// consecutive repeats; `None` when fewer than three positions are left.
fn quantised_ring(v: &Vertices, r: &LineString<f64>) -> Option<Vec<Coord<f64>>> {
    let mut pts: Vec<(Coord<f64>, [i64; 2])> = Vec::new();
    let n = if r.is_closed() && r.0.len() > 1 {
        r.0.len() - 1
    } else {
        r.0.len()
    };
    for &c in &r.0[..n] {
        let q = v.quantise(c, 0.0);
        let q = [q[0], q[1]];
        if pts.last().map(|p| p.1) != Some(q) {
            pts.push((c, q));
        }
    }
    while pts.len() > 1 && pts.first().map(|p| p.1) == pts.last().map(|p| p.1) {
        pts.pop();
    }
    (pts.len() >= 3).then(|| pts.into_iter().map(|p| p.0).collect())
}

/// One building as a CityJSON city object, its vertices added to `v`; `None` when its outer
/// ring collapses (named in `dropped`).
fn building_object(
    b: &Building,
    v: &mut Vertices,
    levels_fields: &[String],
    dropped: &mut Vec<String>,
) -> Option<Value> {
    let outer = match quantised_ring(v, b.footprint.exterior()) {
        Some(r) => r,
        None => {
            dropped.push(format!("{} (outer ring: building left out)", b.source_id));
            return None;
        }
    };
    let mut all = vec![outer];
    for (k, h) in b.footprint.interiors().iter().enumerate() {
        match quantised_ring(v, h) {
            Some(r) => all.push(r),
            None => dropped.push(format!("{} (courtyard {})", b.source_id, k + 1)),
        }
    }
    let (z0, z1) = (b.min_height_m, b.height_m);
    // Rings as vertex indices at the bottom and at the top, in the footprint's own winding
    // (outer counter-clockwise, courtyards clockwise, seen from above).
    let mut bottom: Vec<Vec<u32>> = Vec::with_capacity(all.len());
    let mut top: Vec<Vec<u32>> = Vec::with_capacity(all.len());
    for r in &all {
        bottom.push(r.iter().map(|&c| v.id(v.quantise(c, z0))).collect());
        top.push(r.iter().map(|&c| v.id(v.quantise(c, z1))).collect());
    }
    let reversed = |r: &Vec<u32>| -> Vec<u32> { r.iter().rev().copied().collect() };
    // Roof: normal up, so the footprint's winding as it is. Bottom: normal down, every ring
    // reversed. Walls: the solid lies left of each ring edge a → b (for the outer ring and the
    // courtyards alike), so the quad a₀ b₀ b₁ a₁ is counter-clockwise seen from outside.
    let mut surfaces: Vec<Vec<Vec<u32>>> = vec![top.clone(), bottom.iter().map(reversed).collect()];
    for (rb, rt) in bottom.iter().zip(&top) {
        let n = rb.len();
        for i in 0..n {
            let j = (i + 1) % n;
            surfaces.push(vec![vec![rb[i], rb[j], rt[j], rt[i]]]);
        }
    }
    let mut values = vec![0u32, 1];
    values.extend(std::iter::repeat_n(2, surfaces.len() - 2));
    let bottom_type = if z0 > 0.0 {
        "OuterCeilingSurface"
    } else {
        "GroundSurface"
    };
    let lod0: Vec<Vec<Vec<u32>>> = vec![bottom.clone()];

    let mut attributes = Map::new();
    for (k, a) in &b.attributes {
        attributes.insert(k.clone(), attr_json(a));
    }
    let mut ours = vec![
        ("source_id", json!(b.source_id)),
        ("height_m", json!(b.height_m)),
        ("min_height_m", json!(b.min_height_m)),
        ("height_source", json!(source_name(b.height_source))),
    ];
    if let Some(l) = levels_fields
        .iter()
        .find_map(|f| b.attributes.get(f).and_then(AttrValue::as_f64))
        .filter(|l| l.is_finite() && *l >= 0.0 && l.fract() == 0.0)
    {
        ours.push(("storeysAboveGround", json!(l as u64)));
    }
    for (k, val) in ours {
        if let Some(src) = attributes.remove(k) {
            attributes.insert(format!("source:{k}"), src);
        }
        attributes.insert(k.to_string(), val);
    }
    Some(json!({
        "type": "Building",
        "attributes": attributes,
        "geometry": [
            { "type": "MultiSurface", "lod": "0", "boundaries": lod0 },
            {
                "type": "Solid",
                "lod": "1",
                "boundaries": [surfaces],
                "semantics": {
                    "surfaces": [
                        { "type": "RoofSurface" },
                        { "type": bottom_type },
                        { "type": "WallSurface" },
                    ],
                    "values": [values],
                },
            },
        ],
    }))
}

fn attr_json(a: &AttrValue) -> Value {
    match a {
        AttrValue::Null => Value::Null,
        AttrValue::Bool(b) => json!(b),
        AttrValue::Int(i) => json!(i),
        AttrValue::Float(f) if f.is_finite() => json!(f),
        AttrValue::Float(_) => Value::Null,
        AttrValue::Text(t) => json!(t),
    }
}

/// The model's minimum and maximum corners (x, y over the footprints, z over the prisms).
fn bounds(city: &City) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for b in &city.buildings {
        for r in rings(b) {
            for c in &r.0 {
                lo[0] = lo[0].min(c.x);
                lo[1] = lo[1].min(c.y);
                hi[0] = hi[0].max(c.x);
                hi[1] = hi[1].max(c.y);
            }
        }
        lo[2] = lo[2].min(b.min_height_m);
        hi[2] = hi[2].max(b.height_m);
    }
    if lo[0] > hi[0] {
        return ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}

/// Unique city-object ids: the source id, with `#2`, `#3`, … for repeats.
fn object_ids(city: &City) -> Vec<String> {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    city.buildings
        .iter()
        .map(|b| {
            let n = seen.entry(b.source_id.as_str()).or_insert(0);
            *n += 1;
            if *n == 1 && !b.source_id.is_empty() {
                b.source_id.clone()
            } else {
                format!("{}#{}", b.source_id, n)
            }
        })
        .collect()
}

/// The header shared by both forms: `type`, `version`, `transform`, `metadata`.
fn header(city: &City, scale: f64, lo: [f64; 3], hi: [f64; 3]) -> Value {
    let mut metadata = json!({
        "title": city.name,
        "geographicalExtent": [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]],
    });
    if let Some(rs) = reference_system(&city.transform) {
        metadata["referenceSystem"] = json!(rs);
    } else if let Some(p) = local_projection(&city.transform) {
        metadata["+proj"] = json!(p);
    }
    json!({
        "type": "CityJSON",
        "version": "2.0",
        "transform": { "scale": [scale, scale, scale], "translate": lo },
        "metadata": metadata,
        "CityObjects": {},
        "vertices": [],
    })
}

fn quantised_json(v: &Vertices) -> Value {
    Value::Array(v.list.iter().map(|q| json!(q)).collect())
}

/// The city as one CityJSON 2.0 document, with what was written (`bytes` is 0).
pub fn cityjson_value(city: &City) -> (Value, CityJsonStats) {
    let scale = choose_scale(&city.buildings);
    let (lo, hi) = bounds(city);
    let mut doc = header(city, scale, lo, hi);
    let mut v = Vertices::new(scale, lo);
    let levels = HeightFields::default().levels;
    let mut dropped = Vec::new();
    let mut objects = Map::new();
    for (b, id) in city.buildings.iter().zip(object_ids(city)) {
        if let Some(o) = building_object(b, &mut v, &levels, &mut dropped) {
            objects.insert(id, o);
        }
    }
    let stats = CityJsonStats {
        buildings: objects.len(),
        vertices: v.list.len(),
        scale_m: scale,
        reference_system: reference_system(&city.transform),
        dropped_rings: dropped,
        bytes: 0,
    };
    doc["CityObjects"] = Value::Object(objects);
    doc["vertices"] = quantised_json(&v);
    (doc, stats)
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> ExportError + '_ {
    move |source| ExportError::Io {
        file: path.to_path_buf(),
        source,
    }
}

fn json_err(path: &Path) -> impl Fn(serde_json::Error) -> ExportError + '_ {
    move |source| ExportError::Json {
        file: path.to_path_buf(),
        source,
    }
}

/// Writes the city as one CityJSON 2.0 file.
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_cityjson(city: &City, path: &Path) -> Result<CityJsonStats, ExportError> {
    let (doc, mut stats) = cityjson_value(city);
    let f = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(f);
    serde_json::to_writer(&mut w, &doc).map_err(json_err(path))?;
    w.flush().map_err(io_err(path))?;
    stats.bytes = std::fs::metadata(path).map_err(io_err(path))?.len();
    Ok(stats)
}

/// Writes the city as CityJSONSeq (CityJSON text sequence): the header (a `CityJSON` object with
/// the transform and metadata, no objects) on the first line, then one `CityJSONFeature` per
/// building with its own vertex list, all quantised with the header's transform.
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_cityjson_seq(city: &City, path: &Path) -> Result<CityJsonStats, ExportError> {
    let scale = choose_scale(&city.buildings);
    let (lo, hi) = bounds(city);
    let f = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(f);
    serde_json::to_writer(&mut w, &header(city, scale, lo, hi)).map_err(json_err(path))?;
    w.write_all(b"\n").map_err(io_err(path))?;
    let mut v = Vertices::new(scale, lo);
    let levels = HeightFields::default().levels;
    let mut dropped = Vec::new();
    let (mut buildings, mut vertices) = (0, 0);
    for (b, id) in city.buildings.iter().zip(object_ids(city)) {
        v.clear();
        let Some(o) = building_object(b, &mut v, &levels, &mut dropped) else {
            continue;
        };
        let mut objects = Map::new();
        objects.insert(id.clone(), o);
        let feature = json!({
            "type": "CityJSONFeature",
            "id": id,
            "CityObjects": objects,
            "vertices": quantised_json(&v),
        });
        serde_json::to_writer(&mut w, &feature).map_err(json_err(path))?;
        w.write_all(b"\n").map_err(io_err(path))?;
        buildings += 1;
        vertices += v.list.len();
    }
    w.flush().map_err(io_err(path))?;
    Ok(CityJsonStats {
        buildings,
        vertices,
        scale_m: scale,
        reference_system: reference_system(&city.transform),
        dropped_rings: dropped,
        bytes: std::fs::metadata(path).map_err(io_err(path))?.len(),
    })
}

/// True when `path` names a CityJSONSeq file (`.jsonl`, e.g. `city.city.jsonl`).
pub fn is_cityjson_seq(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("jsonl"))
}
