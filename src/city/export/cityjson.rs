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
//! - Vertex z is world height: the building's base (its ground; 0 without terrain) plus its
//!   heights above that ground.
//! - Attributes: the source attributes as they were read, then `source_id`, `height_m`, `base_m`,
//!   `min_height_m`, `height_source` (`height`, `levels` or `default`) and `storeysAboveGround`
//!   (the first levels field, when there is one); a source attribute of the same name as one of
//!   these is kept as `source:<name>`.
//! - Vertices are quantised with `transform`: `translate` is the minimum corner of the model and
//!   the scale a power of ten chosen from the data ([`choose_scale`]: 1 mm, finer when the
//!   footprints have shorter edges, as long as the extent fits in 32-bit integers). Vertices are shared between surfaces and buildings; none is
//!   repeated or unused.
//! - CRS: `metadata.referenceSystem` is always an EPSG code
//!   (`https://www.opengis.net/def/crs/EPSG/0/<code>`) when the city has a place on the globe,
//!   so that readers can place it. A city whose metric frame is a projected CRS with an EPSG code
//!   is written in that CRS, coordinates unchanged. Footprints in Web Mercator,
//!   longitude/latitude or a projected CRS in feet are imported into a local transverse Mercator
//!   centred on the data, which
//!   has no EPSG code; such a city (and one in a projected CRS known only by its definition) is
//!   written in the WGS 84 UTM zone of its centre (EPSG 326zz north, 327zz south), each vertex
//!   reprojected through longitude/latitude ([`ExportFrame`]). Beyond 84° of latitude, where UTM
//!   is not defined, and for a city in an unnamed local frame, no `referenceSystem` is written
//!   and [`CityJsonStats::crs_note`] says why; the local projection is then written as a PROJ
//!   string in `metadata["+proj"]`, a property the CityJSON schema allows and readers ignore.
//! - Terrain (optional, the `*_with_terrain` forms): one `TINRelief` city object (id `terrain`,
//!   or `terrain#2`, … when a building has that id) whose LoD1 geometry is a `CompositeSurface`
//!   (the only geometry CityJSON 2.0 allows a `TINRelief`) of one triangle per surface, sharing
//!   the quantised vertices and `transform` with the buildings: the scale and `translate` are
//!   chosen over the terrain's extent and heights too, so a building's base vertices and the
//!   terrain vertex at the same place are one vertex. A triangle whose corners collapse at the
//!   quantisation step is left out and counted ([`CityJsonStats::terrain_dropped`]). In
//!   CityJSONSeq the terrain is its own feature, the last line.
//! - `write_cityjson` streams the document: objects are written as they are made; only the
//!   shared vertex list is held until the end.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use blockwalk_importers::{AttrValue, Crs, MetricTransform};
use geo_types::{Coord, LineString};
use serde_json::{json, Map, Value};
use std::borrow::Cow;

use super::terrain::TerrainTin;
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
    /// Why the coordinates are not those of the city's own frame (reprojected into a UTM zone),
    /// or why no `referenceSystem` is written; `None` when the frame is written as it is.
    pub crs_note: Option<String>,
    /// Footprint rings left out because they collapsed at the quantisation step (a courtyard
    /// smaller than a step), with the building's source id; a building whose outer ring
    /// collapses is left out whole and named here too.
    pub dropped_rings: Vec<String>,
    /// Terrain triangles written (0 without terrain).
    pub terrain_triangles: usize,
    /// Terrain triangles left out because two of their corners are one vertex at the
    /// quantisation step.
    pub terrain_dropped: usize,
    /// Bytes written.
    pub bytes: u64,
}

/// The CRS a CityJSON export is written in, and the map into it from the city's metric frame.
pub struct ExportFrame {
    /// `metadata.referenceSystem`: an OGC EPSG URL, `None` when no EPSG CRS can be given.
    pub reference_system: Option<String>,
    /// The PROJ string of the coordinates written when there is no `referenceSystem`.
    pub local_projection: Option<String>,
    /// Why the coordinates were reprojected, or why there is no `referenceSystem`.
    pub note: Option<String>,
    /// World (metric frame) → UTM, for a frame without EPSG code.
    to_utm: Option<(MetricTransform, MetricTransform)>,
}

impl ExportFrame {
    /// Maps a world plan position into the written CRS; `None` when the projection refuses it.
    fn map(&self, p: Coord<f64>) -> Option<Coord<f64>> {
        let Some((world, utm)) = &self.to_utm else {
            return Some(p);
        };
        let ll = world.to_wgs84_lonlat([p.x, p.y])?;
        let [x, y] = utm.to_metric(ll);
        (x.is_finite() && y.is_finite()).then_some(Coord { x, y })
    }
}

fn epsg_url(code: u32) -> String {
    format!("https://www.opengis.net/def/crs/EPSG/0/{code}")
}

/// The WGS 84 UTM zone's EPSG code for a longitude and latitude (degrees): 32601–32660 north,
/// 32701–32760 south; `None` beyond ±84°, where UTM is not defined.
pub fn utm_epsg(lon: f64, lat: f64) -> Option<u32> {
    if !(lon.is_finite() && lat.is_finite()) || lat.abs() > 84.0 {
        return None;
    }
    let lon = (lon + 180.0).rem_euclid(360.0) - 180.0;
    let zone = (((lon + 180.0) / 6.0).floor() as u32 + 1).clamp(1, 60);
    Some(if lat >= 0.0 { 32600 } else { 32700 } + zone)
}

/// The frame a city's CityJSON is written in (see the module documentation).
pub fn export_frame(t: &MetricTransform) -> ExportFrame {
    let frame = t.frame_crs.as_ref().unwrap_or(&t.crs);
    let local = local_projection_of(t, frame);
    let none = |note: String| ExportFrame {
        reference_system: None,
        local_projection: local.clone(),
        note: Some(note),
        to_utm: None,
    };
    match frame {
        Crs::Projected { epsg: Some(e), .. } if frame.is_metric_projected() => {
            return ExportFrame {
                reference_system: Some(epsg_url(*e)),
                local_projection: None,
                note: None,
                to_utm: None,
            }
        }
        Crs::Unknown => {
            return none(
                "the city is in an unnamed local frame (no CRS was given or found): no \
                 referenceSystem can be written"
                    .into(),
            )
        }
        _ => {}
    }
    let centre = t.center_lonlat.or_else(|| t.to_wgs84_lonlat([0.0, 0.0]));
    let Some([lon, lat]) = centre else {
        return none("the city's frame has no known place on the globe".into());
    };
    let Some(code) = utm_epsg(lon, lat) else {
        return none(format!(
            "the city lies at latitude {lat:.2}°, beyond the 84° where UTM zones are defined: \
             written in its local transverse Mercator, without referenceSystem"
        ));
    };
    let utm = Crs::from_epsg(code)
        .and_then(|c| c.try_metric_transform([0.0, 0.0]))
        .and_then(|f| Crs::from_epsg(4326).and_then(|ll| f.for_layer(&ll)));
    match utm {
        Ok(utm) => ExportFrame {
            reference_system: Some(epsg_url(code)),
            local_projection: None,
            note: Some(format!(
                "the city's metric frame ({}) has no EPSG code: written in UTM (EPSG:{code}), \
                 every vertex reprojected",
                frame_name(frame)
            )),
            to_utm: Some((t.clone(), utm)),
        },
        Err(e) => none(format!("UTM (EPSG:{code}) could not be set up: {e}")),
    }
}

fn frame_name(c: &Crs) -> &'static str {
    match c {
        Crs::WebMercator | Crs::Geographic { .. } => {
            "a local transverse Mercator made for Web Mercator or longitude/latitude input"
        }
        _ => "a projected CRS known only by its definition",
    }
}

/// `metadata.referenceSystem` for a city's transform (see [`export_frame`]).
pub fn reference_system(t: &MetricTransform) -> Option<String> {
    export_frame(t).reference_system
}

fn local_projection_of(t: &MetricTransform, frame: &Crs) -> Option<String> {
    match (frame, t.center_lonlat) {
        (Crs::WebMercator | Crs::Geographic { .. }, Some([lon, lat])) => Some(format!(
            "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
        )),
        (Crs::Projected { .. }, Some([lon, lat])) if !frame.is_metric_projected() => Some(format!(
            "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
        )),
        (Crs::Projected { proj4, .. }, _) => Some(proj4.clone()),
        _ => None,
    }
}

/// The buildings (footprints) and the terrain (vertices) in the written CRS, borrowed when it is
/// the city's own; a building or terrain vertex the projection refuses is named in the error.
#[allow(clippy::type_complexity)]
fn in_frame<'a>(
    city: &'a City,
    terrain: Option<&'a TerrainTin>,
    f: &ExportFrame,
) -> Result<(Cow<'a, [Building]>, Option<Cow<'a, TerrainTin>>), String> {
    if f.to_utm.is_none() {
        return Ok((Cow::Borrowed(&city.buildings), terrain.map(Cow::Borrowed)));
    }
    let terrain = match terrain {
        None => None,
        Some(t) => {
            let mut t2 = t.clone();
            for (k, p) in t2.vertices.iter_mut().enumerate() {
                let c = f
                    .map(Coord { x: p.x, y: p.y })
                    .ok_or_else(|| format!("terrain vertex {k} could not be reprojected"))?;
                (p.x, p.y) = (c.x, c.y);
            }
            Some(Cow::Owned(t2))
        }
    };
    let ring = |r: &LineString<f64>, id: &str| -> Result<LineString<f64>, String> {
        r.0.iter()
            .map(|&c| {
                f.map(c)
                    .ok_or_else(|| format!("building {id}: a vertex could not be reprojected"))
            })
            .collect::<Result<Vec<_>, _>>()
            .map(LineString)
    };
    let mut out = Vec::with_capacity(city.buildings.len());
    for b in &city.buildings {
        let mut b2 = b.clone();
        b2.footprint = geo_types::Polygon::new(
            ring(b.footprint.exterior(), &b.source_id)?,
            b.footprint
                .interiors()
                .iter()
                .map(|r| ring(r, &b.source_id))
                .collect::<Result<_, _>>()?,
        );
        out.push(b2);
    }
    Ok((Cow::Owned(out), terrain))
}

/// The quantisation step for these buildings: the coarsest of 1 mm, 0.1 mm, 10 µm and 1 µm at
/// which every footprint edge is at least [`STEPS_PER_SHORTEST_EDGE`] steps long, but never so
/// fine that the model's extent exceeds `i32::MAX` steps (what 32-bit readers hold).
pub fn choose_scale(buildings: &[Building]) -> f64 {
    choose_scale_with_terrain(buildings, None)
}

/// [`choose_scale`] over the buildings and a terrain: its triangles' plan edges count among the
/// edges, its plan extent and its height range in the model's extent.
pub fn choose_scale_with_terrain(buildings: &[Building], terrain: Option<&TerrainTin>) -> f64 {
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
        top = top.max(b.top_z().abs()).max(b.bottom_z().abs());
    }
    if let Some(t) = terrain {
        for tri in &t.triangles {
            for k in 0..3 {
                let (p, q) = (
                    t.vertices[tri[k] as usize],
                    t.vertices[tri[(k + 1) % 3] as usize],
                );
                let d = (q - p).truncate().length();
                if d > 0.0 {
                    shortest = shortest.min(d);
                }
            }
        }
        if let Some((l, h)) = t.bounds() {
            lo = [lo[0].min(l.x), lo[1].min(l.y)];
            hi = [hi[0].max(h.x), hi[1].max(h.y)];
            top = top.max(l.z.abs()).max(h.z.abs());
        }
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
    let (z0, z1) = (b.bottom_z(), b.top_z());
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
    // Raised above its own ground (not merely standing on ground above z = 0).
    let bottom_type = if z0 > b.base_m {
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
        ("base_m", json!(b.base_m)),
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

/// The model's minimum and maximum corners (x, y over the footprints and the terrain, z over the
/// prisms and the terrain).
fn bounds(buildings: &[Building], terrain: Option<&TerrainTin>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for b in buildings {
        for r in rings(b) {
            for c in &r.0 {
                lo[0] = lo[0].min(c.x);
                lo[1] = lo[1].min(c.y);
                hi[0] = hi[0].max(c.x);
                hi[1] = hi[1].max(c.y);
            }
        }
        lo[2] = lo[2].min(b.bottom_z());
        hi[2] = hi[2].max(b.top_z());
    }
    if let Some((l, h)) = terrain.and_then(TerrainTin::bounds) {
        lo = [lo[0].min(l.x), lo[1].min(l.y), lo[2].min(l.z)];
        hi = [hi[0].max(h.x), hi[1].max(h.y), hi[2].max(h.z)];
    }
    if lo[0] > hi[0] {
        return ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}

/// Unique city-object ids: the source id, with `#2`, `#3`, … for repeats.
fn object_ids(buildings: &[Building]) -> Vec<String> {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    buildings
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

/// The terrain's city-object id: `terrain`, or `terrain#2`, … when a building has that id.
fn terrain_id(building_ids: &[String]) -> String {
    let taken: std::collections::HashSet<&str> = building_ids.iter().map(String::as_str).collect();
    std::iter::once("terrain".to_string())
        .chain((2..).map(|n| format!("terrain#{n}")))
        .find(|id| !taken.contains(id.as_str()))
        .expect("an unused id exists")
}

/// The terrain as a `TINRelief` city object, its vertices added to `v`: one triangle per surface
/// of an LoD1 `CompositeSurface`. Returns the object, the triangles written and those left out
/// (collapsed at the quantisation step); `None` when none is left.
fn terrain_object(t: &TerrainTin, v: &mut Vertices) -> (Option<Value>, usize, usize) {
    let mut surfaces: Vec<Value> = Vec::with_capacity(t.triangles.len());
    let mut dropped = 0;
    for tri in &t.triangles {
        let q = tri.map(|k| {
            let p = t.vertices[k as usize];
            v.quantise(Coord { x: p.x, y: p.y }, p.z)
        });
        if q[0] == q[1] || q[1] == q[2] || q[0] == q[2] {
            dropped += 1;
            continue;
        }
        let ids = q.map(|q| v.id(q));
        surfaces.push(json!([ids]));
    }
    let n = surfaces.len();
    if n == 0 {
        return (None, 0, dropped);
    }
    let o = json!({
        "type": "TINRelief",
        "attributes": { "triangles": n },
        "geometry": [{ "type": "CompositeSurface", "lod": "1", "boundaries": surfaces }],
    });
    (Some(o), n, dropped)
}

/// What both forms share: the buildings in the written CRS, the frame, the quantisation.
struct Prepared<'a> {
    buildings: Cow<'a, [Building]>,
    terrain: Option<Cow<'a, TerrainTin>>,
    reference_system: Option<String>,
    local_projection: Option<String>,
    note: Option<String>,
    scale: f64,
    lo: [f64; 3],
    hi: [f64; 3],
}

fn prepare<'a>(
    city: &'a City,
    terrain: Option<&'a TerrainTin>,
    path: &Path,
) -> Result<Prepared<'a>, ExportError> {
    if let Some(t) = terrain {
        t.check().map_err(|source| ExportError::Terrain {
            file: path.to_path_buf(),
            source,
        })?;
    }
    let frame = export_frame(&city.transform);
    let (buildings, reference_system, local_projection, note) =
        match in_frame(city, terrain, &frame) {
            Ok(b) => (
                b,
                frame.reference_system,
                frame.local_projection,
                frame.note,
            ),
            Err(why) => (
                (
                    Cow::Borrowed(&city.buildings[..]),
                    terrain.map(Cow::Borrowed),
                ),
                None,
                local_projection_of(
                    &city.transform,
                    city.transform
                        .frame_crs
                        .as_ref()
                        .unwrap_or(&city.transform.crs),
                ),
                Some(format!(
                    "{why}: written in the city's own frame, without referenceSystem"
                )),
            ),
        };
    let (buildings, terrain) = buildings;
    let scale = choose_scale_with_terrain(&buildings, terrain.as_deref());
    let (lo, hi) = bounds(&buildings, terrain.as_deref());
    Ok(Prepared {
        buildings,
        terrain,
        reference_system,
        local_projection,
        note,
        scale,
        lo,
        hi,
    })
}

impl Prepared<'_> {
    fn stats(&self, buildings: usize, vertices: usize, dropped: Vec<String>) -> CityJsonStats {
        CityJsonStats {
            buildings,
            vertices,
            scale_m: self.scale,
            reference_system: self.reference_system.clone(),
            crs_note: self.note.clone(),
            dropped_rings: dropped,
            terrain_triangles: 0,
            terrain_dropped: 0,
            bytes: 0,
        }
    }

    /// The header shared by both forms: `type`, `version`, `transform`, `metadata`.
    fn header(&self, name: &str) -> Value {
        let (lo, hi) = (self.lo, self.hi);
        let mut metadata = json!({
            "title": name,
            "geographicalExtent": [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]],
        });
        if let Some(rs) = &self.reference_system {
            metadata["referenceSystem"] = json!(rs);
        } else if let Some(p) = &self.local_projection {
            metadata["+proj"] = json!(p);
        }
        json!({
            "type": "CityJSON",
            "version": "2.0",
            "transform": { "scale": [self.scale, self.scale, self.scale], "translate": lo },
            "metadata": metadata,
            "CityObjects": {},
            "vertices": [],
        })
    }
}

fn quantised_json(v: &Vertices) -> Value {
    Value::Array(v.list.iter().map(|q| json!(q)).collect())
}

/// The city as one CityJSON 2.0 document, with what was written (`bytes` is 0). Holds the whole
/// document; [`write_cityjson`] streams the same document instead.
pub fn cityjson_value(city: &City) -> (Value, CityJsonStats) {
    cityjson_value_with_terrain(city, None).expect("without terrain nothing is refused")
}

/// [`cityjson_value`] with an optional terrain (a `TINRelief`, see the module documentation).
///
/// # Errors
/// [`ExportError::Terrain`] (file `<cityjson>`) when the terrain fails [`TerrainTin::check`].
pub fn cityjson_value_with_terrain(
    city: &City,
    terrain: Option<&TerrainTin>,
) -> Result<(Value, CityJsonStats), ExportError> {
    let p = prepare(city, terrain, Path::new("<cityjson>"))?;
    let mut doc = p.header(&city.name);
    let mut v = Vertices::new(p.scale, p.lo);
    let levels = HeightFields::default().levels;
    let mut dropped = Vec::new();
    let mut objects = Map::new();
    let ids = object_ids(&p.buildings);
    for (b, id) in p.buildings.iter().zip(&ids) {
        if let Some(o) = building_object(b, &mut v, &levels, &mut dropped) {
            objects.insert(id.clone(), o);
        }
    }
    let buildings = objects.len();
    let (mut t_written, mut t_dropped) = (0, 0);
    if let Some(t) = p.terrain.as_deref() {
        let (o, n, d) = terrain_object(t, &mut v);
        (t_written, t_dropped) = (n, d);
        if let Some(o) = o {
            objects.insert(terrain_id(&ids), o);
        }
    }
    let mut stats = p.stats(buildings, v.list.len(), dropped);
    (stats.terrain_triangles, stats.terrain_dropped) = (t_written, t_dropped);
    doc["CityObjects"] = Value::Object(objects);
    doc["vertices"] = quantised_json(&v);
    Ok((doc, stats))
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

/// Writes the city as one CityJSON 2.0 file, streamed: each city object is written as it is
/// made, and only the shared vertex list is held until it is written at the end. The file is
/// written under a temporary name and renamed when complete.
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_cityjson(city: &City, path: &Path) -> Result<CityJsonStats, ExportError> {
    let tin = crate::city::export::terrain::city_tin(city, path)?;
    write_cityjson_with_terrain(city, tin.as_ref(), path)
}

/// [`write_cityjson`] with an optional terrain: one `TINRelief` after the buildings, sharing
/// their vertices and transform (see the module documentation).
///
/// # Errors
/// [`ExportError`] naming the file; [`ExportError::Terrain`] when the terrain fails
/// [`TerrainTin::check`] (nothing is written then).
pub fn write_cityjson_with_terrain(
    city: &City,
    terrain: Option<&TerrainTin>,
    path: &Path,
) -> Result<CityJsonStats, ExportError> {
    let p = prepare(city, terrain, path)?;
    let mut head = p.header(&city.name);
    let head = head.as_object_mut().expect("the header is an object");
    head.remove("CityObjects");
    head.remove("vertices");
    let io = io_err(path);
    let js = json_err(path);
    let mut w = crate::output::AtomicFile::create(path)?;
    // The header's members, then `CityObjects` one by one, then `vertices`.
    w.write_all(b"{").map_err(&io)?;
    for (k, val) in head.iter() {
        serde_json::to_writer(&mut w, k).map_err(&js)?;
        w.write_all(b":").map_err(&io)?;
        serde_json::to_writer(&mut w, val).map_err(&js)?;
        w.write_all(b",").map_err(&io)?;
    }
    w.write_all(b"\"CityObjects\":{").map_err(&io)?;
    let mut v = Vertices::new(p.scale, p.lo);
    let levels = HeightFields::default().levels;
    let mut dropped = Vec::new();
    let mut buildings = 0;
    let ids = object_ids(&p.buildings);
    let mut objects = 0;
    let mut put = |w: &mut crate::output::AtomicFile, id: &str, o: &Value| {
        if objects > 0 {
            w.write_all(b",").map_err(&io)?;
        }
        serde_json::to_writer(&mut *w, id).map_err(&js)?;
        w.write_all(b":").map_err(&io)?;
        serde_json::to_writer(&mut *w, o).map_err(&js)?;
        objects += 1;
        Ok::<(), ExportError>(())
    };
    for (b, id) in p.buildings.iter().zip(&ids) {
        let Some(o) = building_object(b, &mut v, &levels, &mut dropped) else {
            continue;
        };
        put(&mut w, id, &o)?;
        buildings += 1;
    }
    let (mut t_written, mut t_dropped) = (0, 0);
    if let Some(t) = p.terrain.as_deref() {
        let (o, n, d) = terrain_object(t, &mut v);
        (t_written, t_dropped) = (n, d);
        if let Some(o) = o {
            put(&mut w, &terrain_id(&ids), &o)?;
        }
    }
    w.write_all(b"},\"vertices\":[").map_err(&io)?;
    for (i, q) in v.list.iter().enumerate() {
        if i > 0 {
            w.write_all(b",").map_err(&io)?;
        }
        write!(w, "[{},{},{}]", q[0], q[1], q[2]).map_err(&io)?;
    }
    w.write_all(b"]}").map_err(&io)?;
    let mut stats = p.stats(buildings, v.list.len(), dropped);
    (stats.terrain_triangles, stats.terrain_dropped) = (t_written, t_dropped);
    stats.bytes = w.commit()?;
    Ok(stats)
}

/// Writes the city as CityJSONSeq (CityJSON text sequence): the header (a `CityJSON` object with
/// the transform and metadata, no objects) on the first line, then one `CityJSONFeature` per
/// building with its own vertex list, all quantised with the header's transform. The file is
/// written under a temporary name and renamed when complete.
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_cityjson_seq(city: &City, path: &Path) -> Result<CityJsonStats, ExportError> {
    let tin = crate::city::export::terrain::city_tin(city, path)?;
    write_cityjson_seq_with_terrain(city, tin.as_ref(), path)
}

/// [`write_cityjson_seq`] with an optional terrain: its `TINRelief` is one more feature, the
/// last line, with its own vertex list quantised with the header's transform (chosen over the
/// terrain too).
///
/// # Errors
/// [`ExportError`] naming the file; [`ExportError::Terrain`] when the terrain fails
/// [`TerrainTin::check`] (nothing is written then).
pub fn write_cityjson_seq_with_terrain(
    city: &City,
    terrain: Option<&TerrainTin>,
    path: &Path,
) -> Result<CityJsonStats, ExportError> {
    let p = prepare(city, terrain, path)?;
    let io = io_err(path);
    let js = json_err(path);
    let mut w = crate::output::AtomicFile::create(path)?;
    serde_json::to_writer(&mut w, &p.header(&city.name)).map_err(&js)?;
    w.write_all(b"\n").map_err(&io)?;
    let mut v = Vertices::new(p.scale, p.lo);
    let levels = HeightFields::default().levels;
    let mut dropped = Vec::new();
    let (mut buildings, mut vertices) = (0, 0);
    let mut feature = |w: &mut crate::output::AtomicFile, id: &str, o: Value, v: &Vertices| {
        let mut objects = Map::new();
        objects.insert(id.to_string(), o);
        let feature = json!({
            "type": "CityJSONFeature",
            "id": id,
            "CityObjects": objects,
            "vertices": quantised_json(v),
        });
        serde_json::to_writer(&mut *w, &feature).map_err(&js)?;
        w.write_all(b"\n").map_err(&io)?;
        vertices += v.list.len();
        Ok::<(), ExportError>(())
    };
    let ids = object_ids(&p.buildings);
    for (b, id) in p.buildings.iter().zip(&ids) {
        v.clear();
        let Some(o) = building_object(b, &mut v, &levels, &mut dropped) else {
            continue;
        };
        feature(&mut w, id, o, &v)?;
        buildings += 1;
    }
    let (mut t_written, mut t_dropped) = (0, 0);
    if let Some(t) = p.terrain.as_deref() {
        v.clear();
        let (o, n, d) = terrain_object(t, &mut v);
        (t_written, t_dropped) = (n, d);
        if let Some(o) = o {
            feature(&mut w, &terrain_id(&ids), o, &v)?;
        }
    }
    let mut stats = p.stats(buildings, vertices, dropped);
    (stats.terrain_triangles, stats.terrain_dropped) = (t_written, t_dropped);
    stats.bytes = w.commit()?;
    Ok(stats)
}

/// True when `path` names a CityJSONSeq file (`.jsonl`, e.g. `city.city.jsonl`).
pub fn is_cityjson_seq(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("jsonl"))
}
