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
        matches!(e, ImportError::Format { .. }) && e.to_string().contains("x.gpkg"),
        "{e}"
    );
    let e = gpkg::read(&dir.path().join("missing.gpkg"), &Theme::Any).unwrap_err();
    assert!(matches!(e, ImportError::Io { .. }));
}
