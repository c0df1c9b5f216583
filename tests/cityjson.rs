//! CityJSON export against the official validator (`cjval`: schema, vertex indices, duplicate
//! and unused vertices) and against our own checks of what `cjval` does not look at: every LoD1
//! solid closed (each edge used exactly twice, in opposite directions) and outward (positive
//! volume), and the file read back (building count, each solid's volume against its prism's
//! `area × (top − bottom)` within the quantisation).

mod support;

use std::collections::HashMap;
use std::path::Path;

use blockwalk::city::export::cityjson::{
    cityjson_value, reference_system, write_cityjson, write_cityjson_seq,
};
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::City;
use blockwalk::geom::predicates::polygon_area;
use geo::MapCoords;
use serde_json::Value;
use support::data::load_city;

/// Every check `cjval` makes, errors and warnings alike; the failing ones as "check: message".
fn cjval_failures(v: &cjval::CJValidator) -> Vec<String> {
    let mut out = Vec::new();
    for (check, summary) in v.validate() {
        if !summary.is_valid() {
            // A check that was not run (status None) after an earlier failure is named too.
            out.push(format!("{check}: {}", summary.get_errors().join("; ")));
        }
    }
    out
}

fn validate_cityjson(text: &str) -> Vec<String> {
    let v = cjval::CJValidator::from_str(text);
    assert!(v.is_cityjson());
    assert_eq!(v.get_input_cityjson_version(), 20);
    cjval_failures(&v)
}

/// Features of a CityJSONSeq file that `cjval` validates: all up to this many, else an even
/// sample of this many (cjval compiles its schema for every feature, about 0.1 s each; our own
/// checks read every feature).
const SEQ_FEATURES_VALIDATED: usize = 300;

/// Validates a CityJSONSeq file: the header, then features against it (see
/// [`SEQ_FEATURES_VALIDATED`]).
fn validate_seq(text: &str) -> Vec<String> {
    let mut lines = text.lines();
    let mut v = cjval::CJValidator::from_str(lines.next().unwrap());
    let mut out: Vec<String> = cjval_failures(&v)
        .into_iter()
        .map(|e| format!("header: {e}"))
        .collect();
    let features = text.lines().count() - 1;
    let step = features.div_ceil(SEQ_FEATURES_VALIDATED).max(1);
    for (i, l) in lines.enumerate().step_by(step) {
        v.from_str_cjfeature(l).unwrap();
        out.extend(
            cjval_failures(&v)
                .into_iter()
                .map(|e| format!("line {}: {e}", i + 2)),
        );
    }
    out
}

/// Decoded vertices (metres, relative to `translate`, so that f64 keeps the quantised values
/// exactly).
fn vertices(doc: &Value, header: &Value) -> Vec<[f64; 3]> {
    let s: Vec<f64> = header["transform"]["scale"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    doc["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let q: Vec<i64> = v
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_i64().unwrap())
                .collect();
            [q[0] as f64 * s[0], q[1] as f64 * s[1], q[2] as f64 * s[2]]
        })
        .collect()
}

fn rings(surface: &Value) -> Vec<Vec<usize>> {
    surface
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|i| i.as_u64().unwrap() as usize)
                .collect()
        })
        .collect()
}

/// The solid's shell: every directed edge exactly once and its reverse exactly once; returns
/// the enclosed volume (divergence theorem over fan triangles of every ring, holes included with
/// their own winding).
fn closed_volume(id: &str, shell: &Value, vs: &[[f64; 3]]) -> f64 {
    let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
    let mut six_v = 0.0;
    for surface in shell.as_array().unwrap() {
        for r in rings(surface) {
            assert!(r.len() >= 3, "{id}: a ring of {} vertices", r.len());
            for k in 0..r.len() {
                let (a, b) = (r[k], r[(k + 1) % r.len()]);
                assert_ne!(a, b, "{id}: a zero-length edge");
                *edges.entry((a, b)).or_default() += 1;
            }
            let p0 = vs[r[0]];
            for k in 1..r.len() - 1 {
                let (p1, p2) = (vs[r[k]], vs[r[k + 1]]);
                let c = [
                    p1[1] * p2[2] - p1[2] * p2[1],
                    p1[2] * p2[0] - p1[0] * p2[2],
                    p1[0] * p2[1] - p1[1] * p2[0],
                ];
                six_v += p0[0] * c[0] + p0[1] * c[1] + p0[2] * c[2];
            }
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{id}: edge {a}→{b} used {n} times in one direction");
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "{id}: edge {a}→{b} has no opposite edge"
        );
    }
    six_v / 6.0
}

/// One building: its LoD1 solid closed and outward, its volume the prism's within the
/// quantisation; its LoD0 footprint the prism's bottom area.
fn check_building(id: &str, o: &Value, vs: &[[f64; 3]], prism: Option<(f64, f64, f64, f64)>) {
    assert_eq!(o["type"], "Building");
    let geoms = o["geometry"].as_array().unwrap();
    let solid = geoms.iter().find(|g| g["type"] == "Solid").unwrap();
    assert_eq!(solid["lod"], "1");
    let shells = solid["boundaries"].as_array().unwrap();
    assert_eq!(shells.len(), 1, "{id}: one outer shell, no voids");
    let v = closed_volume(id, &shells[0], vs);
    assert!(v > 0.0, "{id}: volume {v} ≤ 0 (inward shell)");
    let lod0 = geoms.iter().find(|g| g["type"] == "MultiSurface").unwrap();
    assert_eq!(lod0["lod"], "0");
    if let Some((area, height, perimeter, scale)) = prism {
        let expected = area * height;
        // Each vertex moves by at most half a step per axis: the footprint area by about
        // perimeter × step, the height by a step.
        let tol = (perimeter * height + 2.0 * area) * scale + 1e-9;
        assert!(
            (v - expected).abs() <= tol,
            "{id}: volume {v} against the prism's {expected} (tolerance {tol})"
        );
    }
}

fn perimeter(p: &geo_types::Polygon<f64>) -> f64 {
    std::iter::once(p.exterior())
        .chain(p.interiors())
        .flat_map(|r| r.0.windows(2))
        .map(|w| ((w[1].x - w[0].x).powi(2) + (w[1].y - w[0].y).powi(2)).sqrt())
        .sum()
}

/// Writes both forms, validates both with cjval and checks every building of both; returns the
/// CityJSON document.
/// The footprint in the CRS the CityJSON is written in: the city's own, or, for a city in a
/// local transverse Mercator (Web Mercator or lon/lat input), the UTM zone the export chose,
/// reprojected here by proj4rs alone (local tmerc → UTM), independently of the exporter's path.
fn written_footprint(
    city: &City,
    rs: Option<&str>,
    p: &geo_types::Polygon<f64>,
) -> geo_types::Polygon<f64> {
    let (Some([lon, lat]), Some(rs)) = (city.transform.center_lonlat, rs) else {
        return p.clone();
    };
    use proj4rs::proj::Proj;
    let code: u32 = rs.rsplit('/').next().unwrap().parse().unwrap();
    let (zone, south) = (code % 100, code / 100 == 327);
    let from = Proj::from_proj_string(&format!(
        "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
    ))
    .unwrap();
    let to = Proj::from_proj_string(&format!(
        "+proj=utm +zone={zone} {}+datum=WGS84 +units=m +no_defs",
        if south { "+south " } else { "" }
    ))
    .unwrap();
    p.map_coords(|c| {
        let mut q = (c.x, c.y, 0.0);
        proj4rs::transform::transform(&from, &to, &mut q).unwrap();
        geo_types::Coord { x: q.0, y: q.1 }
    })
}

fn check_city(city: &City, label: &str) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.city.json");
    let stats = write_cityjson(city, &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let failures = validate_cityjson(&text);
    assert!(failures.is_empty(), "{label}: cjval: {failures:#?}");
    assert!(stats.dropped_rings.is_empty(), "{:?}", stats.dropped_rings);

    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["type"], "CityJSON");
    assert_eq!(doc["version"], "2.0");
    let objects = doc["CityObjects"].as_object().unwrap();
    assert_eq!(
        objects.len(),
        city.buildings.len(),
        "{label}: building count"
    );
    assert_eq!(stats.buildings, city.buildings.len());
    let vs = vertices(&doc, &doc);
    assert_eq!(vs.len(), stats.vertices);
    let scale = stats.scale_m;
    let by_source: HashMap<&str, &blockwalk::city::Building> = city
        .buildings
        .iter()
        .map(|b| (b.source_id.as_str(), b))
        .collect();
    let rs = doc["metadata"]["referenceSystem"].as_str();
    assert_eq!(rs.map(str::to_string), stats.reference_system);
    for (id, o) in objects {
        let b = by_source[o["attributes"]["source_id"].as_str().unwrap()];
        assert_eq!(o["attributes"]["height_m"].as_f64(), Some(b.height_m));
        let fp = written_footprint(city, rs, &b.footprint);
        let prism = (
            polygon_area(&fp),
            b.height_m - b.min_height_m,
            perimeter(&fp),
            scale,
        );
        check_building(id, o, &vs, Some(prism));
    }

    // CityJSONSeq: the same buildings, one per line, each feature valid and closed.
    let seq = dir.path().join("city.city.jsonl");
    let sstats = write_cityjson_seq(city, &seq).unwrap();
    assert_eq!(sstats.buildings, city.buildings.len());
    let text = std::fs::read_to_string(&seq).unwrap();
    let failures = validate_seq(&text);
    assert!(failures.is_empty(), "{label}: cjval (seq): {failures:#?}");
    let mut lines = text.lines();
    let header: Value = serde_json::from_str(lines.next().unwrap()).unwrap();
    assert_eq!(header["transform"], doc["transform"]);
    assert_eq!(header["metadata"], doc["metadata"]);
    let mut n = 0;
    for l in lines {
        let f: Value = serde_json::from_str(l).unwrap();
        assert_eq!(f["type"], "CityJSONFeature");
        let vs = vertices(&f, &header);
        let id = f["id"].as_str().unwrap();
        let o = &f["CityObjects"][id];
        // The same object as in the CityJSON file, up to vertex numbering: same volume.
        check_building(id, o, &vs, None);
        n += 1;
    }
    assert_eq!(n, city.buildings.len());
    doc
}

#[test]
fn bubenec_is_valid_closed_and_has_no_wrong_epsg() {
    let city = load_city(
        Path::new("data/bubenec/buildings.shp"),
        Some("data/bubenec/streets.shp"),
    );
    let doc = check_city(&city, "Bubeneč");
    // Web Mercator input is imported into a local transverse Mercator, which has no EPSG code:
    // the export is written in the UTM zone of Prague (33 N), every vertex reprojected (the
    // volumes above are checked against footprints reprojected by proj4rs alone), and neither
    // EPSG:3857 nor the local projection is claimed.
    assert_eq!(
        reference_system(&city.transform).as_deref(),
        Some("https://www.opengis.net/def/crs/EPSG/0/32633")
    );
    assert_eq!(
        doc["metadata"]["referenceSystem"],
        "https://www.opengis.net/def/crs/EPSG/0/32633"
    );
    assert!(doc["metadata"].get("+proj").is_none());
    // Placed where Bubeneč is: UTM 33 N easting ≈ 457 km, northing ≈ 5 551 km.
    let ext = doc["metadata"]["geographicalExtent"].as_array().unwrap();
    let (x, y) = (ext[0].as_f64().unwrap(), ext[1].as_f64().unwrap());
    assert!(
        (440_000.0..470_000.0).contains(&x) && (5_540_000.0..5_560_000.0).contains(&y),
        "{x} {y}"
    );
}

#[test]
fn utm_zones_and_their_limits() {
    use blockwalk::city::export::cityjson::utm_epsg;
    assert_eq!(utm_epsg(14.39, 50.10), Some(32633));
    assert_eq!(utm_epsg(24.94, 60.17), Some(32635));
    assert_eq!(utm_epsg(-58.38, -34.60), Some(32721));
    assert_eq!(utm_epsg(-180.0, 0.0), Some(32601));
    assert_eq!(utm_epsg(179.99, 0.0), Some(32660));
    assert_eq!(utm_epsg(180.0, 1.0), Some(32601), "180° is -180°");
    assert_eq!(utm_epsg(0.0, 84.5), None, "no UTM beyond 84°");
    assert_eq!(utm_epsg(f64::NAN, 0.0), None);
}

#[test]
fn the_streamed_document_is_the_document() {
    // `write_cityjson` streams; `cityjson_value` builds the whole tree. Both must be the same
    // JSON (objects compare by member, not by order).
    for (fp, st) in [
        (
            "data/bubenec/buildings.shp",
            Some("data/bubenec/streets.shp"),
        ),
        ("data/helsinki/buildings.shp", None),
    ] {
        let city = load_city(Path::new(fp), st);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.city.json");
        let stats = write_cityjson(&city, &path).unwrap();
        let streamed: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let (doc, vstats) = cityjson_value(&city);
        if streamed != doc {
            std::fs::write(
                "/tmp/a.json",
                serde_json::to_string_pretty(&streamed).unwrap(),
            )
            .unwrap();
            std::fs::write("/tmp/b.json", serde_json::to_string_pretty(&doc).unwrap()).unwrap();
        }
        assert!(streamed == doc, "{fp}: the streamed document differs");
        assert_eq!(stats.bytes, std::fs::metadata(&path).unwrap().len());
        assert_eq!(
            CityJsonStatsNoBytes::from(&stats),
            CityJsonStatsNoBytes::from(&vstats)
        );
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "no temporary left beside the file");
    }
}

#[derive(Debug, PartialEq)]
struct CityJsonStatsNoBytes(usize, usize, Option<String>, Option<String>);
impl From<&blockwalk::city::export::cityjson::CityJsonStats> for CityJsonStatsNoBytes {
    fn from(s: &blockwalk::city::export::cityjson::CityJsonStats) -> Self {
        Self(
            s.buildings,
            s.vertices,
            s.reference_system.clone(),
            s.crs_note.clone(),
        )
    }
}

#[test]
fn helsinki_is_valid_closed_with_its_crs() {
    let city = load_city(Path::new("data/helsinki/buildings.shp"), None);
    let doc = check_city(&city, "Helsinki");
    // ETRS-TM35FIN: the coordinates are that CRS's, written with its EPSG code.
    assert_eq!(
        doc["metadata"]["referenceSystem"],
        "https://www.opengis.net/def/crs/EPSG/0/3067"
    );
    // Courtyards become inner rings of the roof and bottom surfaces.
    let with_courtyard = city
        .buildings
        .iter()
        .filter(|b| !b.footprint.interiors().is_empty())
        .count();
    let roofs_with_holes = doc["CityObjects"]
        .as_object()
        .unwrap()
        .values()
        .filter(|o| {
            o["geometry"][1]["boundaries"][0][0]
                .as_array()
                .unwrap()
                .len()
                > 1
        })
        .count();
    assert_eq!(roofs_with_holes, with_courtyard);
}

#[test]
fn generated_city_is_valid_and_closed() {
    let dir = tempfile::tempdir().unwrap();
    let g = generate_city(&GenerateParams {
        buildings: 3000,
        seed: 7,
        ..Default::default()
    })
    .unwrap();
    write_city(&g, dir.path()).unwrap();
    let city = load_city(&dir.path().join("buildings.shp"), None);
    assert_eq!(city.buildings.len(), 3000);
    let doc = check_city(&city, "generated");
    assert_eq!(
        doc["metadata"]["referenceSystem"],
        "https://www.opengis.net/def/crs/EPSG/0/32633"
    );
    // Storeys kept as the standard attribute.
    assert!(doc["CityObjects"]
        .as_object()
        .unwrap()
        .values()
        .all(|o| o["attributes"]["storeysAboveGround"].as_u64().is_some()));
}

#[test]
fn cjval_catches_what_we_check_for() {
    // The validator is not vacuous here: a wrong vertex index and a duplicate vertex are found.
    let city = load_city(Path::new("data/helsinki/buildings.shp"), None);
    let (doc, _) = cityjson_value(&city);
    let mut bad = doc.clone();
    let n = bad["vertices"].as_array().unwrap().len();
    let first = bad["CityObjects"]
        .as_object()
        .unwrap()
        .keys()
        .next()
        .unwrap()
        .clone();
    bad["CityObjects"][&first]["geometry"][0]["boundaries"][0][0][0] = serde_json::json!(n + 5);
    let f = validate_cityjson(&bad.to_string());
    assert!(
        f.iter().any(|e| e.starts_with("wrong_vertex_index")),
        "{f:?}"
    );

    let mut dup = doc;
    let v0 = dup["vertices"][0].clone();
    dup["vertices"].as_array_mut().unwrap().push(v0);
    let f = validate_cityjson(&dup.to_string());
    assert!(
        f.iter().any(|e| e.starts_with("duplicate_vertices")),
        "{f:?}"
    );
}

/// Validates a file given by `BLOCKWALK_CITYJSON_FILE` (`.city.json`, or `.jsonl` for
/// CityJSONSeq, every feature) with cjval and the closed-solid check, e.g. the 80k city written
/// by `blockwalk import city80k/ --cityjson`:
/// `BLOCKWALK_CITYJSON_FILE=f.city.json cargo test --test cityjson -- --ignored --nocapture`.
#[test]
#[ignore = "needs BLOCKWALK_CITYJSON_FILE"]
fn validate_given_file() {
    let path = std::env::var("BLOCKWALK_CITYJSON_FILE").expect("BLOCKWALK_CITYJSON_FILE");
    let text = std::fs::read_to_string(&path).unwrap();
    let t = std::time::Instant::now();
    if path.ends_with(".jsonl") {
        let mut lines = text.lines();
        let header: Value = serde_json::from_str(lines.next().unwrap()).unwrap();
        let mut v = cjval::CJValidator::from_str(&header.to_string());
        let mut failures = cjval_failures(&v);
        let mut n = 0;
        for l in lines {
            v.from_str_cjfeature(l).unwrap();
            failures.extend(cjval_failures(&v));
            let f: Value = serde_json::from_str(l).unwrap();
            let id = f["id"].as_str().unwrap();
            check_building(id, &f["CityObjects"][id], &vertices(&f, &header), None);
            n += 1;
        }
        println!("{path}: {n} features, cjval failures: {failures:?}");
        assert!(failures.is_empty());
    } else {
        let failures = validate_cityjson(&text);
        let cjval_s = t.elapsed().as_secs_f64();
        let doc: Value = serde_json::from_str(&text).unwrap();
        let vs = vertices(&doc, &doc);
        let objects = doc["CityObjects"].as_object().unwrap();
        for (id, o) in objects {
            check_building(id, o, &vs, None);
        }
        println!(
            "{path}: {} buildings, {} vertices, cjval {cjval_s:.1} s, failures: {failures:?}; \
             every solid closed and outward",
            objects.len(),
            vs.len()
        );
        assert!(failures.is_empty());
    }
}

/// WGS 84 / UTM zone 33N with US survey feet as its unit (no such EPSG entry exists: the name
/// says UTM zone 33N, the unit says it is not EPSG:32633).
const UTM33N_FEET: &str = r#"PROJCS["WGS 84 / UTM zone 33N (US survey feet)",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",15],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",1640416.666666667],PARAMETER["false_northing",0],UNIT["US survey foot",0.3048006096012192]]"#;

/// Bubeneč's UTM 33N footprints rewritten in US survey feet: imported into ground metres, they
/// are exported in EPSG:32633 at the metre copy's own coordinates, and their ground areas are
/// the Web Mercator copy's (both in a local transverse Mercator), not UTM's (scale 0.9996).
#[test]
fn a_city_in_us_feet_is_written_where_its_metre_copy_is() {
    use blockwalk::city::build::{build_city, BuildOptions};
    use blockwalk::importers::{read_layer, Crs, Theme};
    use support::data::data;
    let us_ft = 1200.0 / 3937.0;
    let metres = read_layer(&data("bubenec_utm33n/buildings.shp"), &Theme::Buildings).unwrap();
    let mut feet = metres.clone();
    for f in &mut feet.features {
        f.geometry = f.geometry.map_coords(|c| geo_types::Coord {
            x: c.x / us_ft,
            y: c.y / us_ft,
        });
    }
    feet.crs = Crs::from_wkt(UTM33N_FEET).unwrap();
    assert!(
        matches!(feet.crs, Crs::Projected { epsg: None, .. }),
        "{:?}",
        feet.crs
    );
    let opts = BuildOptions::default();
    let m_city = build_city(&metres, None, None, &opts).unwrap();
    let f_city = build_city(&feet, None, None, &opts).unwrap();
    assert_eq!(f_city.buildings.len(), m_city.buildings.len());
    let area = |c: &City| -> f64 { c.buildings.iter().map(|b| polygon_area(&b.footprint)).sum() };
    let wm_city = load_city(Path::new("data/bubenec/buildings.shp"), None);
    let (fa, ma, wa) = (area(&f_city), area(&m_city), area(&wm_city));
    assert!(
        (fa / wa - 1.0).abs() < 1e-4,
        "feet {fa} m², Web Mercator {wa} m²"
    );
    assert!(
        (fa / ma - 1.0).abs() > 5e-4,
        "UTM's scale error is gone: {fa} vs {ma} m²"
    );
    let fdoc = check_city(&f_city, "Bubeneč in feet");
    let mdoc = check_city(&m_city, "Bubeneč in UTM");
    for doc in [&fdoc, &mdoc] {
        assert_eq!(
            doc["metadata"]["referenceSystem"],
            "https://www.opengis.net/def/crs/EPSG/0/32633"
        );
    }
    let (fe, me) = (
        fdoc["metadata"]["geographicalExtent"].as_array().unwrap(),
        mdoc["metadata"]["geographicalExtent"].as_array().unwrap(),
    );
    for k in [0, 1, 3, 4] {
        let (a, b) = (fe[k].as_f64().unwrap(), me[k].as_f64().unwrap());
        assert!((a - b).abs() < 0.002, "extent {k}: {a} vs {b}");
    }
}

/// The dequantised vertices of a document (world coordinates: `q · scale + translate`).
fn world_vertices(doc: &Value, header: &Value) -> Vec<[f64; 3]> {
    let t: Vec<f64> = header["transform"]["translate"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    vertices(doc, header)
        .into_iter()
        .map(|v| [v[0] + t[0], v[1] + t[1], v[2] + t[2]])
        .collect()
}

/// The `TINRelief`'s triangles, dequantised, against the input TIN: the same count, and each
/// surface a triangle whose corners are the input triangle's (same order) within half a step.
fn check_tin(
    label: &str,
    o: &Value,
    vs: &[[f64; 3]],
    tin: &blockwalk::city::export::TerrainTin,
    scale: f64,
) {
    assert_eq!(o["type"], "TINRelief", "{label}");
    let geoms = o["geometry"].as_array().unwrap();
    assert_eq!(geoms.len(), 1);
    assert_eq!(geoms[0]["type"], "CompositeSurface");
    assert_eq!(geoms[0]["lod"], "1");
    let surfaces = geoms[0]["boundaries"].as_array().unwrap();
    assert_eq!(
        surfaces.len(),
        tin.triangles.len(),
        "{label}: triangle count"
    );
    let mut worst = 0.0f64;
    for (k, s) in surfaces.iter().enumerate() {
        let r = rings(s);
        assert_eq!(r.len(), 1, "{label}: triangle {k} has holes");
        assert_eq!(r[0].len(), 3, "{label}: surface {k} is not a triangle");
        for (c, &vi) in r[0].iter().enumerate() {
            let want = tin.vertices[tin.triangles[k][c] as usize];
            let got = vs[vi];
            for (a, b) in got.iter().zip(want.to_array()) {
                worst = worst.max((a - b).abs());
            }
        }
    }
    // Half a step, and the f64 rounding of coordinates of a few hundred kilometres.
    assert!(
        worst <= 0.5 * scale + 1e-9,
        "{label}: a terrain vertex {worst} m off"
    );
    println!(
        "{label}: {} terrain triangles, vertices within {worst:.2e} m (step {scale} m)",
        surfaces.len()
    );
}

#[test]
fn terrain_is_a_valid_tin_relief_with_the_buildings_on_it() {
    use blockwalk::city::export::cityjson::{
        cityjson_value_with_terrain, write_cityjson_seq_with_terrain, write_cityjson_with_terrain,
    };
    // Helsinki (EPSG:3067, written as it is) on hills of 20 m cells with a hole.
    let (city, tin) = support::terrain::terrain_city(
        &load_city(Path::new("data/helsinki/buildings.shp"), None),
        20.0,
    );
    let (t_lo, _) = tin.bounds().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.city.json");
    let stats = write_cityjson_with_terrain(&city, Some(&tin), &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let t = std::time::Instant::now();
    let failures = validate_cityjson(&text);
    println!(
        "helsinki + terrain: {} bytes, {} buildings, {} terrain triangles, {} vertices; cjval {:.1} s: {failures:?}",
        stats.bytes,
        stats.buildings,
        stats.terrain_triangles,
        stats.vertices,
        t.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "cjval: {failures:#?}");
    assert_eq!(stats.terrain_triangles, tin.triangles.len());
    assert_eq!(stats.terrain_dropped, 0);
    let doc: Value = serde_json::from_str(&text).unwrap();
    // The transform covers the terrain: nothing below its lowest point is cut.
    let tr = &doc["transform"]["translate"];
    assert!(tr[2].as_f64().unwrap() <= t_lo.z);
    assert!(tr[0].as_f64().unwrap() <= t_lo.x);
    let vs = world_vertices(&doc, &doc);
    let objects = doc["CityObjects"].as_object().unwrap();
    assert_eq!(objects.len(), city.buildings.len() + 1);
    check_tin("city.json", &objects["terrain"], &vs, &tin, stats.scale_m);
    // Buildings stand at their bases: every solid's lowest vertex is its bottom, its LoD0
    // footprint lies there, and it is closed and outward as without terrain.
    let by_source: HashMap<&str, &blockwalk::city::Building> = city
        .buildings
        .iter()
        .map(|b| (b.source_id.as_str(), b))
        .collect();
    let rel = vertices(&doc, &doc);
    for (id, o) in objects.iter().filter(|(id, _)| id.as_str() != "terrain") {
        let b = by_source[o["attributes"]["source_id"].as_str().unwrap()];
        assert_eq!(o["attributes"]["base_m"].as_f64(), Some(b.base_m));
        check_building(id, o, &rel, None);
        let lod0 = &o["geometry"][0];
        let zs: Vec<f64> = rings(&lod0["boundaries"][0])
            .concat()
            .iter()
            .map(|&i| vs[i][2])
            .collect();
        for z in zs {
            assert!(
                (z - b.bottom_z()).abs() <= 0.5 * stats.scale_m + 1e-9,
                "{id}: {z} vs {}",
                b.bottom_z()
            );
        }
        let solid = o["geometry"][1]["boundaries"][0].as_array().unwrap();
        let zmin = solid
            .iter()
            .flat_map(|s| rings(s).concat())
            .map(|i| vs[i][2])
            .fold(f64::INFINITY, f64::min);
        assert!(
            (zmin - b.bottom_z()).abs() <= 0.5 * stats.scale_m + 1e-9,
            "{id}"
        );
        // On the ground (min height 0), the bottom stays a ground surface.
        if b.min_height_m == 0.0 {
            assert_eq!(
                o["geometry"][1]["semantics"]["surfaces"][1]["type"],
                "GroundSurface"
            );
        }
    }
    // The same document in memory.
    let (mem, _) = cityjson_value_with_terrain(&city, Some(&tin)).unwrap();
    assert!(mem == doc, "the streamed document with terrain differs");

    // CityJSONSeq: the terrain is the last feature, valid, with the same triangles.
    let seq = dir.path().join("city.city.jsonl");
    let sstats = write_cityjson_seq_with_terrain(&city, Some(&tin), &seq).unwrap();
    let text = std::fs::read_to_string(&seq).unwrap();
    let failures = validate_seq(&text);
    assert!(failures.is_empty(), "cjval (seq): {failures:#?}");
    let last = text.lines().last().unwrap();
    let mut v = cjval::CJValidator::from_str(text.lines().next().unwrap());
    v.from_str_cjfeature(last).unwrap();
    assert!(cjval_failures(&v).is_empty(), "the terrain feature");
    let header: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert_eq!(header["transform"], doc["transform"]);
    let f: Value = serde_json::from_str(last).unwrap();
    assert_eq!(f["id"], "terrain");
    check_tin(
        "city.jsonl",
        &f["CityObjects"]["terrain"],
        &world_vertices(&f, &header),
        &tin,
        sstats.scale_m,
    );
    assert_eq!(text.lines().count(), 1 + city.buildings.len() + 1);
    println!("CityJSONSeq with terrain: {} bytes", sstats.bytes);

    // Bubeneč (Web Mercator input, written in UTM 33N): the terrain is reprojected with the
    // buildings; its vertices land where proj4rs alone puts them (local tmerc → UTM).
    let (bcity, btin) = support::terrain::terrain_city(
        &load_city(
            Path::new("data/bubenec/buildings.shp"),
            Some("data/bubenec/streets.shp"),
        ),
        10.0,
    );
    let (bdoc, bstats) = cityjson_value_with_terrain(&bcity, Some(&btin)).unwrap();
    let failures = validate_cityjson(&bdoc.to_string());
    assert!(
        failures.is_empty(),
        "Bubeneč + terrain: cjval: {failures:#?}"
    );
    let rs = bdoc["metadata"]["referenceSystem"].as_str();
    assert_eq!(rs, Some("https://www.opengis.net/def/crs/EPSG/0/32633"));
    let ring: Vec<geo_types::Coord<f64>> = btin
        .vertices
        .iter()
        .map(|v| geo_types::Coord { x: v.x, y: v.y })
        .collect();
    let utm = written_footprint(
        &bcity,
        rs,
        &geo_types::Polygon::new(geo_types::LineString(ring), vec![]),
    );
    let expected: Vec<[f64; 3]> = utm
        .exterior()
        .0
        .iter()
        .zip(&btin.vertices)
        .map(|(c, v)| [c.x, c.y, v.z])
        .collect();
    let bvs = world_vertices(&bdoc, &bdoc);
    let surfaces = bdoc["CityObjects"]["terrain"]["geometry"][0]["boundaries"]
        .as_array()
        .unwrap();
    assert_eq!(surfaces.len(), btin.triangles.len());
    let (mut worst_xy, mut worst_z) = (0.0f64, 0.0f64);
    for (k, sf) in surfaces.iter().enumerate() {
        for (c, &vi) in rings(sf)[0].iter().enumerate() {
            let (got, want) = (bvs[vi], expected[btin.triangles[k][c] as usize]);
            worst_xy = worst_xy
                .max((got[0] - want[0]).abs())
                .max((got[1] - want[1]).abs());
            worst_z = worst_z.max((got[2] - want[2]).abs());
        }
    }
    println!("Bubeneč terrain in UTM: {} triangles, plan within {worst_xy:.2e} m, heights within {worst_z:.2e} m", surfaces.len());
    assert!(worst_xy <= 1e-4 + 0.5 * bstats.scale_m, "plan {worst_xy}");
    assert!(worst_z <= 0.5 * bstats.scale_m + 1e-9, "height {worst_z}");

    // A terrain the exporters cannot trust is refused before anything is written.
    let mut bad = tin.clone();
    bad.triangles[0].swap(1, 2);
    let refused = dir.path().join("refused.city.json");
    assert!(write_cityjson_with_terrain(&city, Some(&bad), &refused).is_err());
    assert!(!refused.exists());
}
