//! Input that must not be misplaced, end to end through the city build:
//! layers in different CRS, coordinates that do not fit their CRS, a stray building far away,
//! street layers with nothing usable, every feature refused, implausible heights. Each case
//! asserts the specific error variant or the documented repair.

mod support;
use blockwalk::blocks::{detect, BlockKind, BlockOptions, BlockSource};
use blockwalk::city::build::{build_city, BuildError, BuildOptions};
use blockwalk::city::City;
use blockwalk::geom::predicates::polygon_area;
use blockwalk::importers::{read_layer, Crs, Layer, Theme};
use geo::BooleanOps;
use geo_types::Polygon;
use std::path::{Path, PathBuf};
use support::data::data;

fn layer(p: &Path, theme: Theme) -> Layer {
    read_layer(p, &theme).unwrap()
}

fn city(fp: &Path, streets: Option<&Path>) -> Result<City, BuildError> {
    let f = layer(fp, Theme::Buildings);
    let s = streets.map(|s| layer(s, Theme::Streets));
    build_city(&f, s.as_ref(), None, &BuildOptions::default())
}

fn iou(a: &Polygon<f64>, b: &Polygon<f64>) -> f64 {
    let i: f64 = a.intersection(b).0.iter().map(polygon_area).sum();
    let u: f64 = a.union(b).0.iter().map(polygon_area).sum();
    if u > 0.0 {
        i / u
    } else {
        0.0
    }
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn square(x: f64, y: f64, d: f64, props: &str) -> String {
    format!(
        r#"{{"type":"Feature","properties":{{{props}}},"geometry":{{"type":"Polygon","coordinates":[[[{x},{y}],[{},{y}],[{},{}],[{x},{}],[{x},{y}]]]}}}}"#,
        x + d,
        x + d,
        y + d,
        y + d
    )
}

fn collection(crs: Option<&str>, features: &[String]) -> String {
    let crs = crs
        .map(|c| format!(r#""crs":{{"type":"name","properties":{{"name":"{c}"}}}},"#))
        .unwrap_or_default();
    format!(
        r#"{{"type":"FeatureCollection",{crs}"features":[{}]}}"#,
        features.join(",")
    )
}

/// Bubeneč footprints in Web Mercator with the UTM 33N copy of the streets give the same 7 faces
/// (IoU ≥ 0.999) and the same 96 buildings in blocks as with the Web Mercator streets; before
/// the streets were reprojected, no building landed in a block.
#[test]
fn bubenec_web_mercator_footprints_with_utm_streets_give_the_same_blocks() {
    let fp = data("bubenec/buildings.shp");
    let same = city(&fp, Some(&data("bubenec/streets.shp"))).unwrap();
    let mixed = city(&fp, Some(&data("bubenec_utm33n/streets.shp"))).unwrap();
    assert!(mixed
        .report
        .notes
        .iter()
        .any(|n| n.contains("reprojected into the frame")));
    let opts = BlockOptions::default();
    let a = detect(&same, &opts).unwrap();
    let b = detect(&mixed, &opts).unwrap();
    assert_eq!(b.source, BlockSource::Streets);
    let faces = |l: &blockwalk::blocks::BlockLayout| -> Vec<Polygon<f64>> {
        l.blocks
            .iter()
            .filter(|b| b.kind == BlockKind::Block)
            .map(|b| b.polygon.clone())
            .collect()
    };
    let (fa, fb) = (faces(&a), faces(&b));
    assert_eq!((fa.len(), fb.len()), (7, 7));
    for f in &fa {
        let best = fb.iter().map(|g| iou(f, g)).fold(0.0, f64::max);
        assert!(best >= 0.999, "IoU {best}");
    }
    let in_blocks = |l: &blockwalk::blocks::BlockLayout| -> usize {
        l.blocks
            .iter()
            .filter(|b| b.kind == BlockKind::Block)
            .map(|b| b.buildings.len())
            .sum()
    };
    assert_eq!(in_blocks(&a), 96);
    assert_eq!(in_blocks(&b), 96);
}

/// The UTM copy as footprints with the Web Mercator streets: the other way round.
#[test]
fn bubenec_utm_footprints_with_web_mercator_streets() {
    let mixed = city(
        &data("bubenec_utm33n/buildings.shp"),
        Some(&data("bubenec/streets.shp")),
    )
    .unwrap();
    let l = detect(&mixed, &BlockOptions::default()).unwrap();
    let n: usize = l
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Block)
        .map(|b| b.buildings.len())
        .sum();
    assert_eq!(n, 96);
}

/// Helsinki's metres under a lon/lat `.prj` (once 717 buildings of 1.6e26 m², exit 0): every
/// feature is refused for its latitude, and the error groups the reasons with counts.
#[test]
fn metres_under_a_lon_lat_prj_are_refused_with_grouped_reasons() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["shp", "shx", "dbf"] {
        std::fs::copy(
            data(&format!("helsinki/buildings.{ext}")),
            dir.path().join(format!("b.{ext}")),
        )
        .unwrap();
    }
    write(
        dir.path(),
        "b.prj",
        r#"GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]"#,
    );
    let e = city(&dir.path().join("b.shp"), None).unwrap_err();
    match &e {
        BuildError::NoBuildings { read, reasons, .. } => {
            assert_eq!(*read, 486);
            let total: usize = reasons.iter().map(|g| g.count).sum();
            assert_eq!(total, 486);
            assert!(reasons[0].reason.contains("beyond"), "{:?}", reasons[0]);
            assert!(reasons[0].count > 400, "{reasons:?}");
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("b.shp"), "{e}");
}

#[test]
fn latitude_95_refuses_that_feature_only() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "b.geojson",
        &collection(
            None,
            &[
                square(24.94, 60.17, 0.0002, ""),
                square(24.94, 95.0, 0.0002, ""),
                square(24.95, 60.17, 0.0002, ""),
            ],
        ),
    );
    let c = city(&p, None).unwrap();
    assert_eq!(c.buildings.len(), 2);
    assert_eq!(c.report.buildings_refused.len(), 1);
    let r = &c.report.buildings_refused[0];
    assert!(r.id.ends_with(":1"), "{}", r.id);
    assert!(r.reason.contains("latitude 95"), "{}", r.reason);
}

#[test]
fn coordinates_beyond_a_projections_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "b.geojson",
        &collection(
            Some("EPSG:32633"),
            &[
                square(457_000.0, 5_550_000.0, 10.0, ""),
                square(4.6e7, 5_550_000.0, 10.0, ""),
            ],
        ),
    );
    let c = city(&p, None).unwrap();
    assert_eq!(c.buildings.len(), 1);
    let r = &c.report.buildings_refused[0];
    assert!(
        r.reason.contains("outside the valid range") || r.reason.contains("beyond"),
        "{}",
        r.reason
    );
}

#[test]
fn web_mercator_beyond_the_pole_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "b.geojson",
        &collection(
            Some("EPSG:3857"),
            &[
                square(1_603_600.0, 6_464_400.0, 10.0, ""),
                square(1_603_600.0, 3.0e7, 10.0, ""),
            ],
        ),
    );
    let c = city(&p, None).unwrap();
    assert_eq!(c.buildings.len(), 1);
    assert!(c.report.buildings_refused[0].reason.contains("valid range"));
}

/// One stray building at (0, 0), 3,300 km from Bubeneč: the origin stays in the city (within a
/// few metres of where it is without the stray) and the stray is named.
#[test]
fn a_stray_building_does_not_move_the_origin() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(data("bubenec/buildings.geojson")).unwrap();
    let clean = write(dir.path(), "clean.geojson", &text);
    let stray = square(0.0, 0.0, 10.0, r#""uID":999"#);
    let pos = text.rfind(']').unwrap();
    let with = format!("{},{}{}", &text[..pos], stray, &text[pos..]);
    let p = write(dir.path(), "stray.geojson", &with);
    let a = city(&clean, None).unwrap();
    let b = city(&p, None).unwrap();
    assert_eq!(b.buildings.len(), 145);
    let d = (a.frame.origin - b.frame.origin).length();
    assert!(d < 10.0, "origin moved {d} m");
    let names: Vec<&str> = b
        .report
        .frame
        .outliers
        .iter()
        .map(|o| o.0.as_str())
        .collect();
    assert_eq!(names, ["buildings:144"]);
    assert!(!b.report.frame.f32_ok);
    assert!(a.report.frame.f32_ok && a.report.frame.outliers.is_empty());
    assert!(b
        .report
        .notes
        .iter()
        .any(|n| n.contains("buildings:144") && n.contains("f32")));
    // Every vertex of the city proper keeps millimetres in f32.
    let far = b
        .buildings
        .iter()
        .filter(|x| x.source_id != "buildings:144");
    for x in far {
        for c in x.footprint.exterior().0.iter() {
            let l = b.frame.to_local(glam::DVec3::new(c.x, c.y, 0.0));
            let back = l.as_dvec3() + b.frame.origin;
            assert!((back.x - c.x).abs() < 1e-3 && (back.y - c.y).abs() < 1e-3);
        }
    }
}

/// A street layer whose features are all refused: the city says why, and blocks come from the
/// footprints with that reason on record.
#[test]
fn an_unusable_street_layer_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "s.geojson",
        &collection(
            Some("EPSG:3857"),
            &[
                square(1_603_600.0, 6_464_400.0, 10.0, ""),
                square(1_603_700.0, 6_464_400.0, 10.0, ""),
            ],
        ),
    );
    let c = city(&data("bubenec/buildings.shp"), Some(&s)).unwrap();
    assert!(c.streets.is_empty());
    let why = c.report.street_layer_unusable.as_deref().unwrap();
    assert!(
        why.contains("s.geojson") && why.contains("2 × Polygon is not a line"),
        "{why}"
    );
    assert!(c.report.notes.iter().any(|n| n.starts_with("warning:")));
    let l = detect(&c, &BlockOptions::default()).unwrap();
    assert_eq!(l.source, BlockSource::Footprints);
}

#[test]
fn a_street_layer_with_points_outside_its_crs_is_unusable() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "s.geojson",
        r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[14.4,50.1],[14.4,91.0]]}}]}"#,
    );
    let c = city(&data("bubenec/buildings.shp"), Some(&s)).unwrap();
    let why = c.report.street_layer_unusable.as_deref().unwrap();
    assert!(why.contains("latitude 91"), "{why}");
}

#[test]
fn a_usable_street_layer_is_not_flagged() {
    let c = city(
        &data("bubenec/buildings.shp"),
        Some(&data("bubenec/streets.shp")),
    )
    .unwrap();
    assert_eq!(c.report.street_layer_unusable, None);
    assert_eq!(c.streets.len(), 35);
}

#[test]
fn every_feature_refused_groups_the_reasons() {
    let dir = tempfile::tempdir().unwrap();
    let line = r#"{"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[24.9,60.1],[24.91,60.1]]}}"#;
    let flat = r#"{"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[24.9,60.1],[24.9,60.1],[24.9,60.1],[24.9,60.1]]]}}"#;
    let p = write(
        dir.path(),
        "b.geojson",
        &collection(
            None,
            &[
                line.into(),
                line.into(),
                line.into(),
                flat.into(),
                r#"{"type":"Feature","properties":{},"geometry":null}"#.into(),
            ],
        ),
    );
    let e = city(&p, None).unwrap_err();
    let BuildError::NoBuildings { read, reasons, .. } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(*read, 5);
    let counts: Vec<usize> = reasons.iter().map(|g| g.count).collect();
    assert_eq!(counts, [3, 1, 1]);
    assert_eq!(reasons[0].reason, "LineString is not a polygon");
    assert_eq!(reasons[0].examples, ["b:0", "b:1", "b:2"]);
    assert!(
        e.to_string().contains("3 × LineString is not a polygon"),
        "{e}"
    );
}

#[test]
fn implausible_heights_are_counted_with_ids() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "b.geojson",
        &collection(
            Some("EPSG:3067"),
            &[
                square(385_000.0, 6_672_000.0, 10.0, r#""height":"1e9""#),
                square(385_100.0, 6_672_000.0, 10.0, r#""height":-5"#),
                square(385_200.0, 6_672_000.0, 10.0, r#""height":"12.5 m""#),
                square(385_300.0, 6_672_000.0, 10.0, r#""height":1500,"levels":4"#),
            ],
        ),
    );
    let c = city(&p, None).unwrap();
    let h: Vec<f64> = c.buildings.iter().map(|b| b.height_m).collect();
    assert_eq!(h, [9.0, 9.0, 12.5, 12.0]);
    let ids: Vec<&str> = c
        .report
        .implausible_heights
        .iter()
        .map(|n| n.id.as_str())
        .collect();
    assert_eq!(ids, ["b:0", "b:1", "b:3"]);
    assert!(c.report.implausible_heights[0].why.contains("above 1000"));
    assert!(c.report.implausible_heights[1].why.contains("negative"));
}

#[test]
fn streets_in_an_unknown_epsg_code_are_an_import_error() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "s.geojson",
        &collection(Some("EPSG:99999"), &[]),
    );
    let e = read_layer(&s, &Theme::Streets).unwrap_err();
    assert!(
        matches!(e, blockwalk::importers::ImportError::Crs { .. }),
        "{e:?}"
    );
}

/// A street layer without CRS beside footprints with one is taken to be in the footprints' CRS,
/// and says so.
#[test]
fn a_street_layer_without_crs_is_taken_to_be_in_the_footprints_crs() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["shp", "shx", "dbf"] {
        std::fs::copy(
            data(&format!("bubenec/streets.{ext}")),
            dir.path().join(format!("s.{ext}")),
        )
        .unwrap();
    }
    let c = city(
        &data("bubenec/buildings.shp"),
        Some(&dir.path().join("s.shp")),
    )
    .unwrap();
    assert!(c.report.notes.iter().any(|n| n.contains("no CRS given")));
    let l = detect(&c, &BlockOptions::default()).unwrap();
    let n: usize = l
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Block)
        .map(|b| b.buildings.len())
        .sum();
    assert_eq!(n, 96);
}

/// British National Grid on OSGB36 without an EPSG code (as ESRI writes it) for the buildings,
/// Web Mercator for a street drawn along the building's south side: the street lands on the
/// building within centimetres (the datum shift there is about 100 m).
#[test]
fn british_national_grid_buildings_with_web_mercator_streets() {
    let dir = tempfile::tempdir().unwrap();
    let bng = r#"PROJCS["British_National_Grid",GEOGCS["GCS_OSGB_1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",400000.0],PARAMETER["False_Northing",-100000.0],PARAMETER["Central_Meridian",-2.0],PARAMETER["Scale_Factor",0.9996012717],PARAMETER["Latitude_Of_Origin",49.0],UNIT["Meter",1.0]]"#;
    let crs = Crs::from_wkt(bng).unwrap();
    let fp = Layer {
        name: "b".into(),
        source: dir.path().join("b.shp"),
        crs: crs.clone(),
        features: vec![blockwalk::importers::Feature {
            fid: 0,
            geometry: geo_types::Geometry::Polygon(Polygon::new(
                vec![
                    (530_000.0, 180_000.0),
                    (530_020.0, 180_000.0),
                    (530_020.0, 180_020.0),
                    (530_000.0, 180_020.0),
                    (530_000.0, 180_000.0),
                ]
                .into(),
                vec![],
            )),
            attributes: Default::default(),
        }],
        report: Default::default(),
    };
    // The street's Web Mercator coordinates, from EPSG:27700's own definition (the registry's
    // datum), not from the WKT above.
    let to_merc = Crs::WebMercator
        .metric_transform([-14_200.0, 6_711_000.0])
        .for_layer(&Crs::from_epsg(27700).unwrap())
        .unwrap();
    let merc_frame = Crs::WebMercator.metric_transform([-14_200.0, 6_711_000.0]);
    let to_3857 = |p: [f64; 2]| merc_frame.from_metric(to_merc.to_metric(p));
    let (a, b) = (
        to_3857([530_000.0, 180_000.0]),
        to_3857([530_020.0, 180_000.0]),
    );
    let street = Layer {
        name: "s".into(),
        source: dir.path().join("s.geojson"),
        crs: Crs::WebMercator,
        features: vec![blockwalk::importers::Feature {
            fid: 0,
            geometry: geo_types::Geometry::LineString(vec![(a[0], a[1]), (b[0], b[1])].into()),
            attributes: Default::default(),
        }],
        report: Default::default(),
    };
    let c = build_city(&fp, Some(&street), None, &BuildOptions::default()).unwrap();
    let s = &c.streets[0].line.0;
    assert!(
        (s[0].x - 530_000.0).abs() < 0.05 && (s[0].y - 180_000.0).abs() < 0.05,
        "{s:?}"
    );
    assert!(
        (s[1].x - 530_020.0).abs() < 0.05 && (s[1].y - 180_000.0).abs() < 0.05,
        "{s:?}"
    );
}
