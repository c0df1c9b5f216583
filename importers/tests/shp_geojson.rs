//! Shapefile and GeoJSON readers on the bundled real data (`data/`), and on broken files.

use blockwalk_importers::{
    geojson_reader, read_layer, shp, AttrValue, Crs, ImportError, Layer, Theme,
};
use geo_types::{Geometry, LineString, Polygon};
use std::path::{Path, PathBuf};

fn data(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data")).join(rel)
}

fn accounted(l: &Layer) {
    assert_eq!(
        l.report.read,
        l.report.imported + l.report.refused.len(),
        "every record is imported or refused"
    );
    assert_eq!(l.report.imported, l.features.len());
}

fn polygons(g: &Geometry) -> Vec<&Polygon> {
    match g {
        Geometry::Polygon(p) => vec![p],
        Geometry::MultiPolygon(m) => m.0.iter().collect(),
        _ => vec![],
    }
}

#[test]
fn bubenec_buildings_shp() {
    let l = shp::read(&data("bubenec/buildings.shp")).unwrap();
    accounted(&l);
    assert_eq!(l.crs, Crs::WebMercator);
    assert_eq!(l.features.len(), 144);
    assert!(l.report.refused.is_empty());
    assert!(l
        .features
        .iter()
        .all(|f| matches!(f.geometry, Geometry::Polygon(_))));
    let with_holes = l
        .features
        .iter()
        .filter(|f| {
            polygons(&f.geometry)
                .iter()
                .any(|p| !p.interiors().is_empty())
        })
        .count();
    assert_eq!(with_holes, 1, "data/README.md: 1 building with a hole");
    let vertices: usize = l
        .features
        .iter()
        .flat_map(|f| polygons(&f.geometry))
        .map(|p| p.exterior().0.len() + p.interiors().iter().map(|r| r.0.len()).sum::<usize>())
        .sum();
    assert_eq!(vertices, 1807, "data/README.md: 1,807 vertices");
    let mut uids: Vec<i64> = l
        .features
        .iter()
        .map(|f| match f.attributes.get("uID") {
            Some(AttrValue::Int(i)) => *i,
            other => panic!("uID is {other:?}"),
        })
        .collect();
    uids.sort();
    assert_eq!(uids, (1..=144).collect::<Vec<_>>());
    assert_eq!(l.kind(), blockwalk_importers::LayerKind::Polygons);
}

#[test]
fn bubenec_streets_and_plots() {
    let s = shp::read(&data("bubenec/streets.shp")).unwrap();
    accounted(&s);
    assert_eq!(s.features.len(), 35);
    assert!(s
        .features
        .iter()
        .all(|f| matches!(f.geometry, Geometry::LineString(_))));
    let p = read_layer(&data("bubenec/plots.shp"), &Theme::Any).unwrap();
    accounted(&p);
    assert_eq!(p.features.len(), 407);
    let holes: usize = p
        .features
        .iter()
        .flat_map(|f| polygons(&f.geometry))
        .map(|p| p.interiors().len())
        .sum();
    assert_eq!(holes, 25, "data/README.md: plots have 25 holes");
    assert!(p.features[0].attributes.contains_key("KATUZE_KOD"));
}

#[test]
fn helsinki_buildings_and_streets_shp() {
    let l = shp::read(&data("helsinki/buildings.shp")).unwrap();
    accounted(&l);
    assert_eq!(l.report.read, 486);
    assert_eq!(l.features.len(), 486);
    assert!(
        matches!(
            l.crs,
            Crs::Projected {
                epsg: Some(3067),
                ..
            }
        ),
        "{:?}",
        l.crs
    );
    let multi = l
        .features
        .iter()
        .filter(|f| matches!(f.geometry, Geometry::MultiPolygon(_)))
        .count();
    assert_eq!(multi, 1);
    let holes: usize = l
        .features
        .iter()
        .flat_map(|f| polygons(&f.geometry))
        .map(|p| p.interiors().len())
        .sum();
    assert_eq!(holes, 72, "data/README.md: 72 holes");
    for f in &l.features {
        assert!(f.attributes.contains_key("height") && f.attributes.contains_key("levels"));
    }
    // README: 163 have levels, 17 have a height; `*****`/blank numbers are null.
    let with_levels = l
        .features
        .iter()
        .filter(|f| f.attributes["levels"].as_f64().is_some())
        .count();
    let with_height = l
        .features
        .iter()
        .filter(|f| f.attributes["height"].as_f64().is_some())
        .count();
    assert_eq!((with_levels, with_height), (163, 17));
    let s = shp::read(&data("helsinki/streets_blockclass.shp")).unwrap();
    accounted(&s);
    assert_eq!(s.features.len(), 738);
    assert!(s
        .features
        .iter()
        .all(|f| matches!(f.attributes.get("highway"), Some(AttrValue::Text(_)))));
}

#[test]
fn utm_copy_crs() {
    let l = shp::read(&data("bubenec_utm33n/buildings.shp")).unwrap();
    assert_eq!(l.features.len(), 144);
    assert!(matches!(
        l.crs,
        Crs::Projected {
            epsg: Some(32633),
            ..
        }
    ));
}

/// Same vertices within `tol`, in the same order or reversed: GDAL writes Shapefile rings
/// clockwise (outer) / counter-clockwise (holes) but leaves GeoJSON rings as they were in the
/// source, so a ring can be reversed between the two copies (data/README.md, gotchas).
fn same_ring(a: &LineString, b: &LineString, tol: f64) {
    assert_eq!(a.0.len(), b.0.len());
    let close = |p: &geo_types::Coord, q: &geo_types::Coord| {
        (p.x - q.x).abs() <= tol && (p.y - q.y).abs() <= tol
    };
    let forward = a.0.iter().zip(&b.0).all(|(p, q)| close(p, q));
    let backward = a.0.iter().zip(b.0.iter().rev()).all(|(p, q)| close(p, q));
    assert!(
        forward || backward,
        "{:?} vs {:?}",
        a.0.first(),
        b.0.first()
    );
}

fn same_geometry(a: &Geometry, b: &Geometry, tol: f64) {
    match (a, b) {
        (Geometry::LineString(a), Geometry::LineString(b)) => same_ring(a, b, tol),
        _ => {
            let (pa, pb) = (polygons(a), polygons(b));
            assert!(!pa.is_empty(), "{a:?}");
            assert_eq!(pa.len(), pb.len());
            for (p, q) in pa.iter().zip(&pb) {
                same_ring(p.exterior(), q.exterior(), tol);
                assert_eq!(p.interiors().len(), q.interiors().len());
                for (r, s) in p.interiors().iter().zip(q.interiors()) {
                    same_ring(r, s, tol);
                }
            }
        }
    }
}

/// The GeoJSON copies hold the same coordinates rounded to 1 mm (data/README.md).
#[test]
fn shp_and_geojson_agree() {
    for name in [
        "bubenec/buildings",
        "bubenec/streets",
        "bubenec/plots",
        "helsinki/buildings",
    ] {
        let a = shp::read(&data(&format!("{name}.shp"))).unwrap();
        let b = geojson_reader::read(&data(&format!("{name}.geojson"))).unwrap();
        accounted(&b);
        // Same CRS; the names differ (the .prj's own name vs the EPSG name).
        let code = |c: &Crs| match c {
            Crs::Projected { epsg, .. } => *epsg,
            Crs::WebMercator => Some(3857),
            _ => None,
        };
        assert!(code(&a.crs).is_some());
        assert_eq!(code(&a.crs), code(&b.crs), "{name}");
        assert_eq!(a.features.len(), b.features.len(), "{name}");
        for (f, g) in a.features.iter().zip(&b.features) {
            same_geometry(&f.geometry, &g.geometry, 0.0005 + 1e-6);
        }
    }
    let a = shp::read(&data("helsinki/buildings.shp")).unwrap();
    let b = geojson_reader::read(&data("helsinki/buildings.geojson")).unwrap();
    for (f, g) in a.features.iter().zip(&b.features) {
        assert_eq!(f.attributes["osm_id"], g.attributes["osm_id"]);
        assert_eq!(
            f.attributes["levels"].as_f64(),
            g.attributes["levels"].as_f64()
        );
    }
}

#[test]
fn geojson_variants() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.geojson");
    std::fs::write(
        &p,
        r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","properties":{"h":"12.5 m","n":3,"ok":true,"z":null},
             "geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.91,60.1],[24.91,60.11],[24.9,60.1]]]}},
            {"type":"Feature","properties":{},"geometry":null},
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[]}},
            {"type":"Feature","properties":{},"geometry":{"type":"Bogus","coordinates":[]}}
        ]}"#,
    )
    .unwrap();
    let l = geojson_reader::read(&p).unwrap();
    accounted(&l);
    assert_eq!(l.crs, Crs::Geographic { epsg: Some(4326) });
    assert_eq!(l.features.len(), 1);
    assert_eq!(l.features[0].attributes["h"].as_f64(), Some(12.5));
    assert_eq!(l.features[0].attributes["n"], AttrValue::Int(3));
    assert_eq!(l.features[0].attributes["ok"], AttrValue::Bool(true));
    assert_eq!(l.features[0].attributes["z"], AttrValue::Null);
    let fids: Vec<u64> = l.report.refused.iter().map(|r| r.fid).collect();
    assert_eq!(fids, vec![1, 2, 3]);
    assert!(l.report.refused[0].reason.contains("null geometry"));

    // A bare geometry in metres without a crs member: not degrees, so Unknown with a note.
    std::fs::write(
        &p,
        r#"{"type":"LineString","coordinates":[[385000.0,6672000.0],[385100.0,6672000.0]]}"#,
    )
    .unwrap();
    let l = geojson_reader::read(&p).unwrap();
    assert_eq!(l.crs, Crs::Unknown);
    assert_eq!(l.features.len(), 1);
    assert!(l.report.notes.iter().any(|n| n.contains("not degrees")));

    // A single Feature with a legacy crs member.
    std::fs::write(
        &p,
        r#"{"type":"Feature","crs":{"type":"name","properties":{"name":"EPSG:3067"}},"properties":null,"geometry":{"type":"Point","coordinates":[385000.0,6672000.0]}}"#,
    )
    .unwrap();
    let l = geojson_reader::read(&p).unwrap();
    assert!(matches!(
        l.crs,
        Crs::Projected {
            epsg: Some(3067),
            ..
        }
    ));

    std::fs::write(&p, "this is not json").unwrap();
    let e = geojson_reader::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Json { .. }), "{e:?}");
    assert!(e.to_string().contains("a.geojson"), "{e}");
}

fn copy_layer(stem: &str, to: &Path) -> PathBuf {
    for ext in ["shp", "shx", "dbf", "prj", "cpg"] {
        std::fs::copy(data(&format!("{stem}.{ext}")), to.join(format!("l.{ext}"))).unwrap();
    }
    to.join("l.shp")
}

#[test]
fn missing_companions() {
    let dir = tempfile::tempdir().unwrap();
    let shp_path = copy_layer("bubenec/streets", dir.path());
    std::fs::remove_file(dir.path().join("l.shx")).unwrap();
    let l = shp::read(&shp_path).unwrap();
    assert_eq!(l.features.len(), 35, "read in sequence without the index");
    assert!(l.report.notes.iter().any(|n| n.contains("l.shx")));
    std::fs::remove_file(dir.path().join("l.dbf")).unwrap();
    let e = shp::read(&shp_path).unwrap_err();
    match &e {
        ImportError::MissingCompanion { file, missing, .. } => {
            assert_eq!(file, &shp_path);
            assert_eq!(missing, &dir.path().join("l.dbf"));
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("l.dbf") && e.to_string().contains("l.shp"));
    std::fs::remove_file(dir.path().join("l.prj")).unwrap();
    std::fs::remove_file(&shp_path).unwrap();
    assert!(matches!(shp::read(&shp_path), Err(ImportError::Io { .. })));
}

#[test]
fn no_prj_is_unknown_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let shp_path = copy_layer("bubenec/streets", dir.path());
    std::fs::remove_file(dir.path().join("l.prj")).unwrap();
    let l = shp::read(&shp_path).unwrap();
    assert_eq!(l.crs, Crs::Unknown);
    assert!(l.report.notes.iter().any(|n| n.contains("l.prj")));
}

#[test]
fn truncated_and_garbage_files() {
    let dir = tempfile::tempdir().unwrap();
    let shp_path = copy_layer("bubenec/buildings", dir.path());
    let bytes = std::fs::read(&shp_path).unwrap();
    std::fs::write(&shp_path, &bytes[..bytes.len() / 2]).unwrap();
    let e = shp::read(&shp_path).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ImportError::Shapefile { .. }), "{e:?}");
    assert!(msg.contains("l.shp") && msg.contains("record"), "{msg}");

    std::fs::write(&shp_path, b"garbage, not a shapefile at all, really not").unwrap();
    let e = shp::read(&shp_path).unwrap_err();
    assert!(matches!(e, ImportError::Shapefile { .. }), "{e:?}");
    assert!(e.to_string().contains("l.shp"));

    // Header intact, no .shx: cut in the middle of a record.
    std::fs::remove_file(dir.path().join("l.shx")).unwrap();
    std::fs::write(&shp_path, &bytes[..200]).unwrap();
    let e = shp::read(&shp_path).unwrap_err();
    assert!(
        matches!(&e, ImportError::Shapefile { file, what, .. } if file == &shp_path && what.contains("record 0")),
        "{e:?}"
    );
    assert!(e.to_string().contains("record 0"), "{e}");

    // A .dbf with fewer records than the .shp: an error, not a silent loss.
    let shp_path = copy_layer("bubenec/streets", dir.path());
    std::fs::copy(data("bubenec/buildings.dbf"), dir.path().join("l.dbf")).unwrap();
    let e = shp::read(&shp_path).unwrap_err();
    assert!(
        matches!(&e, ImportError::Format { file, .. } if file == &shp_path),
        "{e:?}"
    );
    assert!(e.to_string().contains("35 shapes"), "{e}");
}

#[test]
fn nan_and_infinite_coordinates_are_refused() {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    use shapefile::{Point, Polyline};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.shp");
    {
        let table = TableWriterBuilder::new()
            .add_numeric_field("id".try_into().unwrap(), 10, 0)
            .add_character_field("name".try_into().unwrap(), 20);
        let mut w = shapefile::Writer::from_path(&p, table).unwrap();
        let rec = |id: f64| {
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(id)));
            r.insert("name".into(), FieldValue::Character(Some(format!("n{id}"))));
            r
        };
        let good = Polyline::new(vec![Point::new(0.0, 0.0), Point::new(1.0, 1.0)]);
        let bad = Polyline::new(vec![Point::new(0.0, 0.0), Point::new(f64::NAN, 1.0)]);
        let inf = Polyline::new(vec![Point::new(f64::INFINITY, 0.0), Point::new(2.0, 1.0)]);
        w.write_shape_and_record(&good, &rec(1.0)).unwrap();
        w.write_shape_and_record(&bad, &rec(2.0)).unwrap();
        w.write_shape_and_record(&inf, &rec(3.0)).unwrap();
        w.write_shape_and_record(&good, &rec(4.0)).unwrap();
    }
    let l = shp::read(&p).unwrap();
    accounted(&l);
    assert_eq!(l.report.read, 4);
    assert_eq!(
        l.features.iter().map(|f| f.fid).collect::<Vec<_>>(),
        vec![0, 3]
    );
    assert_eq!(l.features[1].attributes["id"], AttrValue::Int(4));
    assert_eq!(
        l.features[1].attributes["name"],
        AttrValue::Text("n4".into())
    );
    assert_eq!(l.report.refused[0].fid, 1);
    assert!(
        l.report.refused[0].reason.contains("vertex 1"),
        "{:?}",
        l.report.refused
    );
    assert_eq!(l.report.refused[1].fid, 2);
}

#[test]
fn null_shape_is_refused_and_holes_find_their_outer_ring() {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    use shapefile::{Point, Polygon, PolygonRing};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("poly.shp");
    let sq = |x0: f64, y0: f64, s: f64| {
        vec![
            Point::new(x0, y0),
            Point::new(x0, y0 + s),
            Point::new(x0 + s, y0 + s),
            Point::new(x0 + s, y0),
            Point::new(x0, y0),
        ]
    };
    {
        let table = TableWriterBuilder::new().add_numeric_field("id".try_into().unwrap(), 10, 0);
        let mut w = shapefile::Writer::from_path(&p, table).unwrap();
        // The hole comes first, before both outer rings, and lies in the second one.
        let poly = Polygon::with_rings(vec![
            PolygonRing::Inner(sq(22.0, 2.0, 6.0)),
            PolygonRing::Outer(sq(0.0, 0.0, 10.0)),
            PolygonRing::Outer(sq(20.0, 0.0, 10.0)),
        ]);
        for id in 0..2 {
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(id as f64)));
            w.write_shape_and_record(&poly, &r).unwrap();
        }
    }
    // Make the last record a null shape: its shape type (after the 8-byte record header) → 0.
    let shx = std::fs::read(dir.path().join("poly.shx")).unwrap();
    let off = 2 * i32::from_be_bytes(shx[108..112].try_into().unwrap()) as usize;
    let mut shp_bytes = std::fs::read(&p).unwrap();
    shp_bytes[off + 8..off + 12].copy_from_slice(&0i32.to_le_bytes());
    std::fs::write(&p, shp_bytes).unwrap();

    let l = shp::read(&p).unwrap();
    accounted(&l);
    assert_eq!(l.report.read, 2);
    assert_eq!(l.report.refused.len(), 1);
    assert_eq!(l.report.refused[0].fid, 1);
    assert!(l.report.refused[0].reason.contains("null shape"));
    let Geometry::MultiPolygon(m) = &l.features[0].geometry else {
        panic!("{:?}", l.features[0].geometry)
    };
    assert_eq!(m.0.len(), 2);
    assert!(m.0[0].interiors().is_empty());
    assert_eq!(m.0[1].interiors().len(), 1);
    assert_eq!(m.0[1].exterior().0[0].x, 20.0);
    assert_eq!(m.0[1].interiors()[0].0[0].x, 22.0);
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
        /// Cutting, extending or overwriting a valid .shp never panics: it reads, or errs naming
        /// the file; when it reads, every record is accounted for.
        #[test]
        fn corrupted_shp_never_panics(
            cut in 0usize..4100,
            tail in proptest::collection::vec(any::<u8>(), 0..64),
            flips in proptest::collection::vec((0usize..4100, any::<u8>()), 0..6),
        ) {
            let dir = tempfile::tempdir().unwrap();
            let shp_path = copy_layer("bubenec/streets", dir.path());
            let mut bytes = std::fs::read(&shp_path).unwrap();
            bytes.truncate(cut.min(bytes.len()));
            bytes.extend_from_slice(&tail);
            let n = bytes.len();
            for (at, v) in flips {
                if n > 0 {
                    bytes[at % n] = v;
                }
            }
            std::fs::write(&shp_path, &bytes).unwrap();
            match shp::read(&shp_path) {
                Ok(l) => prop_assert_eq!(l.report.read, l.report.imported + l.report.refused.len()),
                Err(e) => {
                    prop_assert!(
                        matches!(
                            e,
                            ImportError::Format { .. }
                                | ImportError::Io { .. }
                                | ImportError::Empty { .. }
                                | ImportError::Truncated { .. }
                                | ImportError::Shapefile { .. }
                                | ImportError::Dbase { .. }
                        ),
                        "{:?}",
                        e
                    );
                    prop_assert!(e.to_string().contains("l.shp") || e.to_string().contains("l.dbf"), "{}", e);
                }
            }
        }
    }
}
