//! End-to-end tests of the city stage on the bundled real data (`data/`) and on generated
//! cities: import, repair, heights, extrusion, glTF and GeoJSON export.

mod support;
use std::collections::BTreeSet;
use support::data::data;

use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::export::{geojson_value, glb_bytes, write_geojson};
use blockwalk::city::extrude::{check_closed, roof_area, signed_volume, try_extrude_city};
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::{City, HeightSource};
use blockwalk::geom::predicates::polygon_area;
use blockwalk::geom::repair::check_polygon;
use blockwalk::importers::{read_layer, AttrValue, Crs, Layer, Theme};
use geo_types::{Coord, Geometry, LineString, Polygon};
use glam::DVec3;

fn load(p: &str) -> (Layer, City) {
    let layer = read_layer(&data(p), &Theme::Buildings).expect("read");
    let city = build_city(&layer, None, None, &BuildOptions::default()).expect("build");
    (layer, city)
}

/// Footprint area as the f32 mesh sees it: local coordinates rounded to f32.
fn rounded_area(p: &Polygon<f64>, o: DVec3) -> f64 {
    let r = |l: &LineString<f64>| -> LineString<f64> {
        l.0.iter()
            .map(|c| Coord {
                x: ((c.x - o.x) as f32) as f64,
                y: ((c.y - o.y) as f32) as f64,
            })
            .collect::<Vec<_>>()
            .into()
    };
    polygon_area(&Polygon::new(
        r(p.exterior()),
        p.interiors().iter().map(r).collect(),
    ))
}

/// Every mesh closed, outward, with volume = footprint area × (height − bottom).
fn check_meshes(city: &City) -> usize {
    let (meshes, errors) = try_extrude_city(city);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(meshes.len(), city.buildings.len());
    let mut tris = 0;
    for (b, m) in city.buildings.iter().zip(&meshes) {
        check_closed(m).unwrap_or_else(|e| panic!("{}: {e}", b.source_id));
        let area = rounded_area(&b.footprint, city.frame.origin);
        let dz = b.height_m as f32 as f64 - b.min_height_m as f32 as f64;
        let v = signed_volume(m);
        assert!(v > 0.0, "{}", b.source_id);
        assert!(
            ((v - area * dz) / (area * dz)).abs() < 1e-6,
            "{}: volume {v} vs {}",
            b.source_id,
            area * dz
        );
        assert!(
            ((roof_area(m) - area) / area).abs() < 1e-6,
            "{}",
            b.source_id
        );
        tris += m.triangle_count();
    }
    tris
}

#[test]
fn bubenec_utm_area_courtyard_and_meshes() {
    let (_, city) = load("bubenec_utm33n/buildings.shp");
    let r = &city.report;
    assert_eq!(r.buildings_read, 144);
    assert_eq!(r.buildings_imported, 144);
    assert_eq!(city.buildings.len(), 144);
    assert_eq!(r.height_sources.get("default"), Some(&144));
    let area: f64 = city
        .buildings
        .iter()
        .map(|b| polygon_area(&b.footprint))
        .sum();
    assert!((area / 43_151.0 - 1.0).abs() < 0.005, "area {area}");
    for b in &city.buildings {
        check_polygon(&b.footprint).unwrap();
        assert_eq!(b.height_source, HeightSource::Default);
        assert_eq!(b.height_m, 9.0);
    }
    // The one courtyard survives import and extrusion.
    let with_hole: Vec<_> = city
        .buildings
        .iter()
        .filter(|b| !b.footprint.interiors().is_empty())
        .collect();
    assert_eq!(with_hole.len(), 1);
    let b = with_hole[0];
    assert_eq!(b.footprint.interiors().len(), 1);
    let (meshes, _) = try_extrude_city(&city);
    let m = &meshes[b.id.0 as usize];
    let shell = polygon_area(&Polygon::new(b.footprint.exterior().clone(), vec![]));
    let hole = polygon_area(&Polygon::new(b.footprint.interiors()[0].clone(), vec![]));
    assert!(hole > 1.0);
    let cap = roof_area(m);
    assert!(
        ((cap - (shell - hole)) / (shell - hole)).abs() < 1e-5,
        "cap {cap} shell {shell} hole {hole}"
    );
    // The frame origin is the median of the buildings' bounding-box centres (x and y apart):
    // half of the centres lie on either side of it.
    let centres: Vec<[f64; 2]> = city
        .buildings
        .iter()
        .map(|b| {
            let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
            for c in &b.footprint.exterior().0 {
                lo = [lo[0].min(c.x), lo[1].min(c.y)];
                hi = [hi[0].max(c.x), hi[1].max(c.y)];
            }
            [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0]
        })
        .collect();
    let o = city.frame.origin;
    for axis in 0..2 {
        let at = if axis == 0 { o.x } else { o.y };
        let below = centres.iter().filter(|c| c[axis] < at).count();
        let above = centres.iter().filter(|c| c[axis] > at).count();
        assert_eq!(below, above, "axis {axis}");
    }
    assert!(city.report.frame.f32_ok && city.report.frame.outliers.is_empty());
    assert!(check_meshes(&city) > 144 * 10);
}

#[test]
fn bubenec_web_mercator_gives_ground_metres() {
    let (_, city) = load("bubenec/buildings.shp");
    assert_eq!(city.buildings.len(), 144);
    let area: f64 = city
        .buildings
        .iter()
        .map(|b| polygon_area(&b.footprint))
        .sum();
    // 104,843 Mercator units², 43,151 m² on the ground.
    assert!((area / 43_151.0 - 1.0).abs() < 0.005, "area {area}");
    check_meshes(&city);
}

#[test]
fn helsinki_every_feature_accounted_for() {
    let (layer, city) = load("helsinki/buildings.shp");
    let r = &city.report;
    assert_eq!(r.buildings_read, 486);
    assert_eq!(
        r.buildings_imported + r.buildings_repaired.len() + r.buildings_refused.len(),
        486
    );
    let invalid: BTreeSet<String> = layer
        .features
        .iter()
        .filter(|f| matches!(f.attributes.get("valid").and_then(AttrValue::as_f64), Some(v) if v == 0.0))
        .map(|f| format!("{}:{}", layer.name, f.fid))
        .collect();
    assert_eq!(invalid.len(), 12);
    let repaired: BTreeSet<String> = r.buildings_repaired.iter().map(|n| n.id.clone()).collect();
    let refused: BTreeSet<String> = r.buildings_refused.iter().map(|n| n.id.clone()).collect();
    for id in &invalid {
        assert!(
            repaired.contains(id) || refused.contains(id),
            "{id} is invalid but was imported as it was"
        );
    }
    // Valid features are imported as they are (winding aside); the invalid ones, and only
    // they, are repaired or refused, each with a reason.
    assert_eq!(r.buildings_imported, 486 - 12);
    for n in &r.buildings_repaired {
        assert!(invalid.contains(&n.id) && !n.what.is_empty(), "{n:?}");
    }
    for n in &r.buildings_refused {
        assert!(invalid.contains(&n.id) && !n.reason.is_empty(), "{n:?}");
    }
    // Heights: 17 features carry a height; levels for most of the rest that have them.
    assert_eq!(
        r.height_sources.values().sum::<usize>(),
        city.buildings.len()
    );
    assert!(r.height_sources["height"] >= 17);
    assert!(r.height_sources["levels"] >= 140);
    for b in &city.buildings {
        check_polygon(&b.footprint).unwrap_or_else(|e| panic!("{}: {e}", b.source_id));
        assert!(b.height_m > b.min_height_m);
    }
    let holes: usize = city
        .buildings
        .iter()
        .map(|b| b.footprint.interiors().len())
        .sum();
    assert!(holes >= 60, "{holes} holes");
    check_meshes(&city);
}

#[test]
fn far_away_copy_gives_the_same_local_meshes() {
    let mut layer = read_layer(&data("bubenec_utm33n/buildings.shp"), &Theme::Buildings).unwrap();
    let a = build_city(&layer, None, None, &BuildOptions::default()).unwrap();
    for f in &mut layer.features {
        if let Geometry::Polygon(p) = &mut f.geometry {
            use geo::MapCoordsInPlace;
            p.map_coords_in_place(|c| Coord {
                x: c.x + 1.0e7,
                y: c.y + 1.0e7,
            });
        }
    }
    let b = build_city(&layer, None, None, &BuildOptions::default()).unwrap();
    let (ma, _) = try_extrude_city(&a);
    let (mb, _) = try_extrude_city(&b);
    for (x, y) in ma.iter().zip(&mb) {
        assert_eq!(x.indices.len(), y.indices.len());
        for (p, q) in x.positions.iter().zip(&y.positions) {
            assert!((*p - *q).abs().max_element() < 1e-3, "{p} {q}");
        }
    }
}

#[test]
fn glb_reads_back_valid() {
    let (_, city) = load("helsinki/buildings.shp");
    let (meshes, _) = try_extrude_city(&city);
    let (bytes, stats) = glb_bytes(&city, &meshes).unwrap();
    assert_eq!(bytes.len() % 4, 0);
    assert_eq!(stats.nodes, city.buildings.len());
    let g = gltf::Gltf::from_slice(&bytes).expect("valid glTF");
    assert_eq!(g.nodes().count(), city.buildings.len() + 1);
    assert_eq!(g.meshes().count(), city.buildings.len());
    let (doc, buffers, _) = gltf::import_slice(&bytes).expect("import");
    let root = doc.scenes().next().unwrap().nodes().next().unwrap();
    assert_eq!(root.children().count(), city.buildings.len());
    let mut tris = 0;
    for (node, (b, m)) in root.children().zip(city.buildings.iter().zip(&meshes)) {
        assert_eq!(node.name(), Some(b.source_id.as_str()));
        let mesh = node.mesh().unwrap();
        let prim = mesh.primitives().next().unwrap();
        let reader = prim.reader(|buf| Some(&buffers[buf.index()]));
        let pos: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        assert_eq!(pos.len(), m.positions.len());
        // Y-up: (x, y, z) → (x, z, −y).
        assert_eq!(
            pos[0],
            [m.positions[0].x, m.positions[0].z, -m.positions[0].y]
        );
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(idx, m.indices);
        let acc = prim.get(&gltf::Semantic::Positions).unwrap();
        assert!(acc.min().is_some() && acc.max().is_some());
        tris += idx.len() / 3;
    }
    assert_eq!(tris, stats.triangles);
    // Extras: root carries the origin, nodes their heights.
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let v: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let o = &v["nodes"][0]["extras"]["origin"];
    assert_eq!(o[0].as_f64().unwrap(), city.frame.origin.x);
    assert_eq!(
        v["nodes"][1]["extras"]["height_m"].as_f64().unwrap(),
        city.buildings[0].height_m
    );
}

#[test]
fn geojson_export_round_trips_in_input_coordinates() {
    let (layer, city) = load("bubenec/buildings.shp");
    let v = geojson_value(&city);
    assert_eq!(
        v["crs"]["properties"]["name"].as_str(),
        Some("urn:ogc:def:crs:EPSG::3857")
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.geojson");
    write_geojson(&city, &out).unwrap();
    let back = read_layer(&out, &Theme::Any).unwrap();
    assert_eq!(back.crs, Crs::WebMercator);
    assert_eq!(back.features.len(), 144);
    // Same footprint area in Mercator units as the input (the transform is inverted exactly
    // enough), and heights carried.
    let area_in: f64 = layer
        .features
        .iter()
        .map(|f| match &f.geometry {
            Geometry::Polygon(p) => polygon_area(p),
            _ => 0.0,
        })
        .sum();
    let area_back: f64 = back
        .features
        .iter()
        .map(|f| match &f.geometry {
            Geometry::Polygon(p) => polygon_area(p),
            _ => 0.0,
        })
        .sum();
    assert!(
        (area_back / area_in - 1.0).abs() < 1e-6,
        "{area_back} vs {area_in}"
    );
    assert_eq!(
        back.features[0]
            .attributes
            .get("height_m")
            .and_then(AttrValue::as_f64),
        Some(9.0)
    );
}

#[test]
fn generated_city_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let p = GenerateParams {
        buildings: 600,
        seed: 3,
        ..Default::default()
    };
    let g = generate_city(&p).unwrap();
    let w = write_city(&g, dir.path()).unwrap();
    assert_eq!(w.buildings, 600);
    // Deterministic files.
    let dir2 = tempfile::tempdir().unwrap();
    write_city(&generate_city(&p).unwrap(), dir2.path()).unwrap();
    for f in [
        "buildings.shp",
        "buildings.dbf",
        "streets.shp",
        "parcels.shp",
    ] {
        assert_eq!(
            std::fs::read(dir.path().join(f)).unwrap(),
            std::fs::read(dir2.path().join(f)).unwrap(),
            "{f}"
        );
    }
    let fl = read_layer(&dir.path().join("buildings.shp"), &Theme::Buildings).unwrap();
    assert!(
        matches!(
            fl.crs,
            Crs::Projected {
                epsg: Some(32633),
                ..
            }
        ),
        "{:?}",
        fl.crs
    );
    let sl = read_layer(&dir.path().join("streets.shp"), &Theme::Streets).unwrap();
    let pl = read_layer(&dir.path().join("parcels.shp"), &Theme::Parcels).unwrap();
    let city = build_city(&fl, Some(&sl), Some(&pl), &BuildOptions::default()).unwrap();
    assert_eq!(city.buildings.len(), 600);
    assert_eq!(city.report.buildings_imported, 600);
    assert_eq!(city.report.height_sources.get("height"), Some(&600));
    assert_eq!(city.streets.len(), g.streets.len());
    assert_eq!(city.parcels.len(), g.parcels.len());
    for (b, gb) in city.buildings.iter().zip(&g.buildings) {
        assert!((b.height_m - gb.height_m).abs() < 1e-9);
        assert!((polygon_area(&b.footprint) - polygon_area(&gb.footprint)).abs() < 1e-6);
    }
    check_meshes(&city);
}

#[test]
fn export_errors_name_the_file_and_keep_the_cause() {
    use blockwalk::city::export::{write_glb, ExportError};
    use std::error::Error;
    let (_, city) = load("bubenec/buildings.shp");
    let (meshes, _) = try_extrude_city(&city);
    let e = glb_bytes(&city, &meshes[1..]).unwrap_err();
    assert!(
        matches!(e, ExportError::MeshCount { meshes: m, buildings: b, .. }
            if m == meshes.len() - 1 && b == city.buildings.len()),
        "{e:?}"
    );
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("c.glb");
    let e = write_glb(&city, &meshes[1..], &glb).unwrap_err();
    assert!(
        matches!(&e, ExportError::MeshCount { file, .. } if file == &glb),
        "{e:?}"
    );
    assert!(e.to_string().contains("c.glb"), "{e}");
    let missing = dir.path().join("no such dir").join("c.glb");
    let e = write_glb(&city, &meshes, &missing).unwrap_err();
    match &e {
        ExportError::Output(blockwalk::output::OutputError::Io { path, source }) => {
            assert_eq!(path, &missing);
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("{other:?}"),
    }
    assert!(e.source().is_some());
    assert!(e.to_string().contains("c.glb"), "{e}");
    let missing = dir.path().join("no such dir").join("c.geojson");
    let e = write_geojson(&city, &missing).unwrap_err();
    assert!(
        matches!(&e, ExportError::Output(o) if o.path() == missing),
        "{e:?}"
    );
}
