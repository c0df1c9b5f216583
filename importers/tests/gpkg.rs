//! GeoPackage reader on momepy's original `bubenec.gpkg`, checked against the Shapefile copies.
#![cfg(feature = "gpkg")]

use blockwalk_importers::{gpkg, read_layer, shp, Crs, ImportError, Theme};
use geo_types::{Geometry, LineString, Polygon};
use std::path::{Path, PathBuf};

fn data(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data")).join(rel)
}

fn polygons(g: &Geometry) -> Vec<&Polygon> {
    match g {
        Geometry::Polygon(p) => vec![p],
        Geometry::MultiPolygon(m) => m.0.iter().collect(),
        _ => vec![],
    }
}

/// Same vertices to 1e-6, forwards or reversed (GDAL rewinds rings when writing a Shapefile).
fn same_ring(a: &LineString, b: &LineString) {
    assert_eq!(a.0.len(), b.0.len());
    let close = |p: &geo_types::Coord, q: &geo_types::Coord| {
        (p.x - q.x).abs() <= 1e-6 && (p.y - q.y).abs() <= 1e-6
    };
    let fwd = a.0.iter().zip(&b.0).all(|(p, q)| close(p, q));
    let back = a.0.iter().zip(b.0.iter().rev()).all(|(p, q)| close(p, q));
    assert!(fwd || back);
}

#[test]
fn tables_and_counts() {
    let path = data("originals/bubenec.gpkg");
    let tables = gpkg::feature_tables(&path).unwrap();
    let names: Vec<&str> = tables.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["tessellation", "buildings", "streets", "plots"]);
    for (theme, n, name) in [
        (Theme::Buildings, 144, "buildings"),
        (Theme::Streets, 35, "streets"),
        (Theme::Parcels, 407, "plots"),
        (Theme::Table("tessellation".into()), 144, "tessellation"),
        (Theme::Any, 144, "tessellation"),
    ] {
        let l = gpkg::read(&path, &theme).unwrap();
        assert_eq!(l.name, name);
        assert_eq!(l.features.len(), n, "{name}");
        assert_eq!(l.report.read, l.report.imported + l.report.refused.len());
        assert!(l.report.refused.is_empty());
        assert_eq!(l.crs, Crs::WebMercator);
    }
    let p = read_layer(Path::new(&format!("{}:plots", path.display())), &Theme::Any).unwrap();
    assert_eq!(p.features.len(), 407);
    assert!(p.features[0].attributes.contains_key("KATUZE_KOD"));
    assert!(!p.features[0].attributes.contains_key("fid"));
}

#[test]
fn same_coordinates_as_the_shapefile() {
    let g = gpkg::read(&data("originals/bubenec.gpkg"), &Theme::Buildings).unwrap();
    let s = shp::read(&data("bubenec/buildings.shp")).unwrap();
    assert_eq!(g.features.len(), s.features.len());
    for (a, b) in g.features.iter().zip(&s.features) {
        assert_eq!(a.attributes["uID"], b.attributes["uID"]);
        let (pa, pb) = (polygons(&a.geometry), polygons(&b.geometry));
        assert_eq!(pa.len(), 1);
        assert_eq!(pa.len(), pb.len());
        same_ring(pa[0].exterior(), pb[0].exterior());
        assert_eq!(pa[0].interiors().len(), pb[0].interiors().len());
        for (r, q) in pa[0].interiors().iter().zip(pb[0].interiors()) {
            same_ring(r, q);
        }
    }
    let gs = gpkg::read(&data("originals/bubenec.gpkg"), &Theme::Streets).unwrap();
    let ss = shp::read(&data("bubenec/streets.shp")).unwrap();
    for (a, b) in gs.features.iter().zip(&ss.features) {
        match (&a.geometry, &b.geometry) {
            (Geometry::LineString(x), Geometry::LineString(y)) => same_ring(x, y),
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn errors_name_file_and_tables() {
    let e = gpkg::read(
        &data("originals/bubenec.gpkg"),
        &Theme::Table("blocks".into()),
    )
    .unwrap_err();
    assert!(matches!(e, ImportError::Format { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.contains("bubenec.gpkg") && msg.contains("buildings, streets"),
        "{msg}"
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.gpkg");
    std::fs::write(&p, b"definitely not sqlite").unwrap();
    let e = gpkg::read(&p, &Theme::Any).unwrap_err();
    assert!(
        matches!(e, ImportError::Sqlite { .. }) && e.to_string().contains("x.gpkg"),
        "{e}"
    );
    let e = gpkg::read(&dir.path().join("missing.gpkg"), &Theme::Any).unwrap_err();
    assert!(
        matches!(&e, ImportError::Io { file, .. } if file.ends_with("missing.gpkg")),
        "{e:?}"
    );
}

/// A hand-made GeoPackage: null, empty, NaN and corrupt geometries are refused with their fid;
/// a big-endian ISO LineString Z and an unknown srs_id still read.
#[test]
fn refusals_in_a_handmade_geopackage() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("roads.gpkg");
    {
        let c = rusqlite::Connection::open(&p).unwrap();
        c.execute_batch(
            "CREATE TABLE gpkg_spatial_ref_sys (srs_name TEXT, srs_id INTEGER PRIMARY KEY,
               organization TEXT, organization_coordsys_id INTEGER, definition TEXT);
             INSERT INTO gpkg_spatial_ref_sys VALUES ('ETRS89 / TM35FIN(E,N)', 3067, 'EPSG', 3067,
               'PROJCS[\"ETRS89 / TM35FIN(E,N)\",UNIT[\"metre\",1]]');
             CREATE TABLE gpkg_contents (table_name TEXT PRIMARY KEY, data_type TEXT, srs_id INTEGER);
             INSERT INTO gpkg_contents VALUES ('main_roads', 'features', 3067);
             CREATE TABLE gpkg_geometry_columns (table_name TEXT, column_name TEXT,
               geometry_type_name TEXT, srs_id INTEGER, z INTEGER, m INTEGER);
             INSERT INTO gpkg_geometry_columns VALUES ('main_roads', 'shape', 'LINESTRING', 3067, 1, 0);
             CREATE TABLE main_roads (fid INTEGER PRIMARY KEY, shape BLOB, name TEXT, lanes INTEGER,
               width REAL);",
        )
        .unwrap();
        let gp = |wkb: Vec<u8>| {
            let mut b = vec![b'G', b'P', 0, 0b0000_0001];
            b.extend(3067i32.to_le_bytes());
            b.extend(wkb);
            b
        };
        let line_z_be = |pts: &[(f64, f64)]| {
            let mut b = vec![0u8];
            b.extend(1002u32.to_be_bytes());
            b.extend((pts.len() as u32).to_be_bytes());
            for &(x, y) in pts {
                for v in [x, y, 5.0] {
                    b.extend(f64::to_be_bytes(v));
                }
            }
            b
        };
        let ins = "INSERT INTO main_roads VALUES (?1, ?2, ?3, ?4, ?5)";
        let good = gp(line_z_be(&[
            (385_000.0, 6_672_000.0),
            (385_100.0, 6_672_050.0),
        ]));
        let nan = gp(line_z_be(&[
            (385_000.0, f64::NAN),
            (385_100.0, 6_672_050.0),
        ]));
        let empty = vec![b'G', b'P', 0, 0x11, 0, 0, 0, 0];
        let corrupt = good[..20].to_vec();
        c.execute(ins, rusqlite::params![1, good, "Mannerheimintie", 4, 21.5])
            .unwrap();
        c.execute(ins, rusqlite::params![2, nan, "a", 1, 3.0])
            .unwrap();
        c.execute(
            ins,
            rusqlite::params![3, Option::<Vec<u8>>::None, "b", 1, 3.0],
        )
        .unwrap();
        c.execute(ins, rusqlite::params![4, empty, "c", 1, 3.0])
            .unwrap();
        c.execute(
            ins,
            rusqlite::params![5, corrupt, Option::<String>::None, 1, 3.0],
        )
        .unwrap();
    }
    let l = gpkg::read(&p, &Theme::Streets).unwrap();
    assert_eq!(l.name, "main_roads");
    assert!(
        matches!(
            &l.crs,
            Crs::Projected {
                epsg: Some(3067),
                name,
                ..
            } if name == "ETRS89 / TM35FIN(E,N)"
        ),
        "{:?}",
        l.crs
    );
    assert_eq!((l.report.read, l.report.imported), (5, 1));
    let f = &l.features[0];
    assert_eq!(f.fid, 1);
    assert_eq!(
        f.attributes["lanes"],
        blockwalk_importers::AttrValue::Int(4)
    );
    assert_eq!(f.attributes["width"].as_f64(), Some(21.5));
    let Geometry::LineString(ls) = &f.geometry else {
        panic!()
    };
    assert_eq!(ls.0[1].x, 385_100.0);
    let reasons: Vec<(u64, &str)> = l
        .report
        .refused
        .iter()
        .map(|r| (r.fid, r.reason.as_str()))
        .collect();
    assert_eq!(reasons.len(), 4);
    assert!(
        reasons[0].0 == 2 && reasons[0].1.contains("non-finite"),
        "{reasons:?}"
    );
    assert!(reasons[1].0 == 3 && reasons[1].1.contains("null geometry"));
    assert!(reasons[2].0 == 4 && reasons[2].1.contains("empty"));
    assert!(
        reasons[3].0 == 5 && reasons[3].1.contains("truncated"),
        "{reasons:?}"
    );
    let e = gpkg::read(&p, &Theme::Buildings).unwrap_err();
    assert!(
        matches!(&e, ImportError::Format { file, .. } if file == &p),
        "{e:?}"
    );
    assert!(e.to_string().contains("main_roads"), "{e}");
}
