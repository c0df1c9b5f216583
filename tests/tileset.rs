//! The 3D Tiles 1.1 export (`blockwalk::tiles`) on the bundled Helsinki and Bubeneč data: the
//! tile tree against the block quadtree (every block in one leaf, every building in one leaf
//! `.glb`, geometric errors, boxes), the feature ids and property tables read back from the
//! binary, the root transform against an independent geodetic implementation (proj4rs) and
//! against the projection of the buildings' own corners, determinism, and the Khronos
//! glTF-Validator on every content file (skipped loudly without node, unless
//! the validators are required: `BLOCKWALK_REQUIRE=validators`).

mod support;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use blockwalk::city::extrude::extrude_city;
use blockwalk::city::Mesh;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::tiles::geodesy::{ecef_from_geodetic, geodetic_from_ecef};
use blockwalk::tiles::{
    build_tileset, local_from_gltf, local_to_ecef, ContentEncoding, TileKind, Tileset,
    TilesetOptions, TilesetSummary,
};
use glam::{DVec3, Vec3};
use serde_json::Value;

struct Built {
    scene: Scene,
    meshes: Vec<Mesh>,
    set: Tileset,
    summary: TilesetSummary,
    dir: tempfile::TempDir,
}

fn build(input: &str, streets: Option<&str>) -> Built {
    build_with(input, streets, &TilesetOptions::default(), |c| c)
}

/// [`build`] with options, the city changed by `edit` first (e.g. stood on a terrain).
fn build_with(
    input: &str,
    streets: Option<&str>,
    opts: &TilesetOptions<'_>,
    edit: impl FnOnce(blockwalk::city::City) -> blockwalk::city::City,
) -> Built {
    let source = CitySource::parse(Path::new(input), streets.map(PathBuf::from), None, &[], 0)
        .expect("source");
    let scene = Scene::load(
        &source,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .expect("scene");
    let mut scene = scene;
    scene.city = edit(scene.city);
    let meshes = extrude_city(&scene.city);
    let dir = tempfile::tempdir().unwrap();
    let (set, summary) = build_tileset(
        &scene.city,
        &scene.layout,
        &scene.bounds,
        &meshes,
        dir.path(),
        opts,
        &|_, _| {},
    )
    .expect("tileset");
    Built {
        scene,
        meshes,
        set,
        summary,
        dir,
    }
}

fn helsinki() -> Built {
    build(
        "data/helsinki/buildings.shp",
        Some("data/helsinki/streets_blockclass.shp"),
    )
}

fn bubenec() -> Built {
    build(
        "data/bubenec/buildings.shp",
        Some("data/bubenec/streets.shp"),
    )
}

/// A content `.glb` read back (plain or compact) by the tests' own reader.
fn read_glb(path: &Path) -> support::glb::Glb {
    support::glb::Glb::read(path)
}

/// glTF content position (Y-up, dequantised) → local frame (3D Tiles' Y-up → Z-up rotation).
fn local_of(p: [f64; 3]) -> DVec3 {
    DVec3::new(p[0], -p[2], p[1])
}

/// Every tile of the JSON tree with its parent (index in preorder).
fn json_tiles(doc: &Value) -> Vec<(Option<usize>, Value)> {
    fn walk(t: &Value, parent: Option<usize>, out: &mut Vec<(Option<usize>, Value)>) {
        let me = out.len();
        out.push((parent, t.clone()));
        for c in t["children"].as_array().into_iter().flatten() {
            walk(c, Some(me), out);
        }
    }
    let mut out = Vec::new();
    walk(&doc["root"], None, &mut out);
    out
}

/// A tile box as (min, max): centre ± half-axes (our boxes are axis-aligned).
fn box_of(t: &Value) -> (DVec3, DVec3) {
    let b: Vec<f64> = t["boundingVolume"]["box"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(b.len(), 12);
    for k in [4, 5, 6, 8, 9, 10] {
        assert_eq!(b[k], 0.0, "axis-aligned box");
    }
    let c = DVec3::new(b[0], b[1], b[2]);
    let h = DVec3::new(b[3], b[7], b[11]);
    assert!(h.min_element() > 0.0);
    (c - h, c + h)
}

fn check_structure(name: &str, b: &Built) {
    let doc: Value =
        serde_json::from_slice(&std::fs::read(b.dir.path().join("tileset.json")).unwrap()).unwrap();
    assert_eq!(doc["asset"]["version"], "1.1");
    let tiles = json_tiles(&doc);
    assert_eq!(tiles.len(), b.set.tiles.len(), "{name}");
    assert!(b.set.tiles.len() > 1, "{name}: a tree, not one tile");
    let root_ge = tiles[0].1["geometricError"].as_f64().unwrap();
    assert!(doc["geometricError"].as_f64().unwrap() >= root_ge, "{name}");
    let mut block_leaf: BTreeMap<u32, usize> = BTreeMap::new();
    let mut building_leaf: BTreeMap<u32, usize> = BTreeMap::new();
    for (i, (parent, t)) in tiles.iter().enumerate() {
        assert_eq!(t["refine"], "REPLACE", "{name}");
        let ge = t["geometricError"].as_f64().unwrap();
        assert!(ge.is_finite() && ge >= 0.0);
        let leaf = t.get("children").is_none();
        let rust = &b.set.tiles[i];
        if leaf {
            assert_eq!(ge, 0.0, "{name}: leaf geometric error");
            assert_eq!(rust.kind, TileKind::Buildings);
            for bl in t["extras"]["blocks"].as_array().unwrap() {
                let id = bl.as_u64().unwrap() as u32;
                assert!(
                    block_leaf.insert(id, i).is_none(),
                    "{name}: block {id} in two leaves"
                );
            }
        } else {
            assert!(
                matches!(rust.kind, TileKind::Map(_)),
                "{name}: inner tiles are maps"
            );
            assert!(ge > 0.0, "{name}: inner tile with error 0");
        }
        if let Some(p) = parent {
            let pt = &tiles[*p].1;
            assert!(
                pt["geometricError"].as_f64().unwrap() >= ge,
                "{name}: parent error below child"
            );
            let (pa, pb) = box_of(pt);
            let (ca, cb) = box_of(t);
            let s = 1e-6 * (1.0 + pb.abs().max_element());
            assert!(
                ca.cmpge(pa - s).all() && cb.cmple(pb + s).all(),
                "{name}: child box {ca:?}..{cb:?} outside parent {pa:?}..{pb:?}"
            );
            // An inner tile's blocks are the union of its children's.
        }
        // The content: leaves hold the meshes of their buildings, one feature each.
        let Some(uri) = t["content"]["uri"].as_str() else {
            assert!(rust.buildings.is_empty() || !leaf);
            continue;
        };
        let glb = read_glb(&b.dir.path().join(uri));
        let (lo, hi) = box_of(t);
        for p in glb.positions() {
            let q = local_of(p);
            assert!(
                q.cmpge(lo - 1e-3).all() && q.cmple(hi + 1e-3).all(),
                "{name}: {uri}: vertex {q:?} outside its box"
            );
        }
        if !leaf {
            assert!(glb.primitive()["attributes"]["COLOR_0"].is_number());
            continue;
        }
        let fids = glb.feature_ids().expect("_FEATURE_ID_0");
        let props = glb.properties().expect("a property table");
        let (ids, heights) = (props.source_id, props.height_m);
        assert_eq!(ids.len(), rust.buildings.len(), "{name}: {uri}");
        let mut per_feature = vec![0usize; ids.len()];
        for f in &fids {
            per_feature[*f as usize] += 1;
        }
        for (f, &bi) in rust.buildings.iter().enumerate() {
            let bd = &b.scene.city.buildings[bi as usize];
            assert_eq!(ids[f], bd.source_id, "{name}: {uri} feature {f}");
            assert_eq!(heights[f], bd.height_m);
            assert_eq!(
                per_feature[f],
                b.meshes[bi as usize].positions.len(),
                "{name}: {uri}: feature {f} ({}) does not cover its building's vertices",
                bd.source_id
            );
            assert!(
                building_leaf.insert(bi, i).is_none(),
                "{name}: building {bi} in two leaves"
            );
            // Its block's leaf is this one.
            let block = b
                .scene
                .layout
                .blocks
                .iter()
                .find(|bl| bl.buildings.iter().any(|x| x.0 == bi))
                .unwrap();
            assert_eq!(block_leaf.get(&block.id.0), Some(&i));
        }
    }
    // Every block in exactly one leaf, every building with a mesh in exactly one leaf .glb.
    let all_blocks: BTreeSet<u32> = b.scene.bounds.iter().map(|x| x.id.0).collect();
    assert_eq!(
        block_leaf.keys().copied().collect::<BTreeSet<_>>(),
        all_blocks,
        "{name}"
    );
    let with_mesh: BTreeSet<u32> = (0..b.meshes.len() as u32)
        .filter(|&i| b.meshes[i as usize].triangle_count() > 0)
        .filter(|&i| {
            b.scene
                .layout
                .blocks
                .iter()
                .any(|bl| bl.buildings.iter().any(|x| x.0 == i))
        })
        .collect();
    assert_eq!(
        building_leaf.keys().copied().collect::<BTreeSet<_>>(),
        with_mesh,
        "{name}"
    );
    assert_eq!(b.summary.buildings, with_mesh.len());
    println!(
        "{name}: {} tiles ({} maps, {} leaves), depth {}, {} bytes, root ε {:.2} m",
        b.summary.tiles,
        b.summary.map_tiles,
        b.summary.leaf_tiles,
        b.summary.depth,
        b.summary.bytes,
        b.summary.root_geometric_error
    );
}

#[test]
fn helsinki_tileset_is_the_block_quadtree_with_every_building_once() {
    check_structure("helsinki", &helsinki());
}

#[test]
fn bubenec_tileset_is_the_block_quadtree_with_every_building_once() {
    check_structure("bubenec", &bubenec());
}

/// ECEF of a geodetic point by proj4rs (`+proj=geocent`): an implementation independent of ours.
fn proj4rs_ecef(lon: f64, lat: f64, h: f64) -> DVec3 {
    use proj4rs::proj::Proj;
    let from = Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs").unwrap();
    let to = Proj::from_proj_string("+proj=geocent +datum=WGS84 +units=m +no_defs").unwrap();
    let mut p = (lon.to_radians(), lat.to_radians(), h);
    proj4rs::transform::transform(&from, &to, &mut p).unwrap();
    DVec3::new(p.0, p.1, p.2)
}

#[test]
fn our_ecef_matches_proj4rs_and_round_trips_within_a_millimetre() {
    for &(lon, lat, h) in &[
        (24.946, 60.169, 0.0),
        (14.392, 50.104, 250.0),
        (71.43, 51.13, 350.0),
        (-58.38, -34.60, 25.0),
        (0.0, 0.0, 0.0),
    ] {
        let ours = ecef_from_geodetic(lon, lat, h);
        let theirs = proj4rs_ecef(lon, lat, h);
        assert!(
            (ours - theirs).length() < 1e-3,
            "({lon}, {lat}, {h}): {ours:?} vs proj4rs {theirs:?}"
        );
        let (lo, la, hh) = geodetic_from_ecef(ours);
        assert!((ecef_from_geodetic(lo, la, hh) - ours).length() < 1e-3);
    }
}

/// The root transform puts the origin and every building corner where the CRS says they are:
/// the origin's ECEF round-trips to the CRS's longitude/latitude within 1 mm, and the roof
/// vertices read back from the leaf `.glb` files (glTF Y-up, turned Z-up as 3D Tiles does, then
/// the root transform) land on their footprint corners projected through the CRS. Plain contents:
/// their f32 positions are the extruded ones, so this measures the transform alone (compact ones
/// add their stated error, under 1 mm: `tests/tileset_compact.rs`).
#[test]
fn root_transform_places_the_buildings_where_the_crs_says() {
    let plain = TilesetOptions {
        content: ContentEncoding::Plain,
        ..TilesetOptions::default()
    };
    let helsinki = build_with(
        "data/helsinki/buildings.shp",
        Some("data/helsinki/streets_blockclass.shp"),
        &plain,
        |c| c,
    );
    let bubenec = build_with(
        "data/bubenec/buildings.shp",
        Some("data/bubenec/streets.shp"),
        &plain,
        |c| c,
    );
    for (name, b) in [("helsinki", helsinki), ("bubenec", bubenec)] {
        let g = b.set.georef.expect("a projected CRS is georeferenced");
        let city = &b.scene.city;
        let o = city.frame.origin;
        let [lon, lat] = city.transform.to_wgs84_lonlat([o.x, o.y]).unwrap();
        let origin = local_to_ecef(&g, DVec3::ZERO);
        let (lo, la, h) = geodetic_from_ecef(origin);
        let m_per_deg = 6_378_137.0f64.to_radians();
        assert!((la - lat).abs() * m_per_deg < 1e-3, "{name}: latitude");
        assert!(
            (lo - lon).abs() * m_per_deg * lat.to_radians().cos() < 1e-3,
            "{name}: longitude"
        );
        assert!((h - o.z).abs() < 1e-3, "{name}: height");
        assert!(
            (origin - proj4rs_ecef(lon, lat, o.z)).length() < 1e-3,
            "{name}"
        );

        // Roof corners of every leaf's buildings.
        let (mut worst_h, mut worst_v, mut n) = (0.0f64, 0.0f64, 0usize);
        for t in b.set.tiles.iter().filter(|t| t.kind == TileKind::Buildings) {
            let Some(uri) = &t.content else { continue };
            let glb = read_glb(&b.dir.path().join(uri));
            assert!(!glb.compressed);
            let pos = glb.positions();
            let fids = glb.feature_ids().expect("_FEATURE_ID_0");
            for (p, f) in pos.iter().zip(&fids) {
                let bd = &city.buildings[t.buildings[*f as usize] as usize];
                let local = local_from_gltf(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32));
                if (local.z - bd.height_m).abs() > 1e-3 {
                    continue; // roof vertices only
                }
                let (plon, plat, ph) = geodetic_from_ecef(local_to_ecef(&g, local));
                // The footprint corner through the CRS.
                let world = [o.x + local.x, o.y + local.y];
                let [clon, clat] = city.transform.to_wgs84_lonlat(world).unwrap();
                let dn = (plat - clat) * m_per_deg;
                let de = (plon - clon) * m_per_deg * clat.to_radians().cos();
                worst_h = worst_h.max((dn * dn + de * de).sqrt());
                // A flat local frame rises above the curved ellipsoid by d²/2R.
                let d2 = local.x * local.x + local.y * local.y;
                worst_v = worst_v.max((ph - (o.z + bd.height_m) - d2 / (2.0 * 6_371_000.0)).abs());
                n += 1;
            }
        }
        println!("{name}: {n} roof vertices: horizontal error ≤ {worst_h:.4} m, vertical ≤ {worst_v:.4} m");
        assert!(n > 100, "{name}");
        // The README and docs/tiles.md quote this bound (6 mm; measured 5.5 mm on Helsinki).
        assert!(worst_h < 0.006, "{name}: horizontal {worst_h} m");
        assert!(worst_v < 0.01, "{name}: vertical {worst_v} m");
    }
}

#[test]
fn a_city_without_a_crs_gets_no_transform() {
    let b = build("synthetic:3x3", None);
    assert!(b.set.georef.is_none());
    let doc: Value =
        serde_json::from_slice(&std::fs::read(b.dir.path().join("tileset.json")).unwrap()).unwrap();
    assert!(doc["root"].get("transform").is_none());
    assert_eq!(doc["asset"]["extras"]["georeferenced"], false);
    assert!(b.summary.placement().contains("no transform"));
}

#[test]
fn same_city_same_bytes() {
    let a = bubenec();
    let b = bubenec();
    let files = |d: &Path| -> Vec<(String, Vec<u8>)> {
        let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(d.join("tiles"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .chain(std::iter::once(d.join("tileset.json")))
            .map(|p| {
                (
                    p.file_name().unwrap().to_string_lossy().into_owned(),
                    std::fs::read(&p).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    };
    let (fa, fb) = (files(a.dir.path()), files(b.dir.path()));
    assert!(fa.len() > 2);
    assert!(fa == fb, "two exports of the same city differ");
}

#[test]
fn every_tile_is_valid_gltf() {
    let Some(node) = support::node::or_skip(
        "every_tile_is_valid_gltf",
        support::node::node_with(&["gltf-validator"]),
    ) else {
        return;
    };
    for (name, b) in [("helsinki", helsinki()), ("bubenec", bubenec())] {
        let mut totals = [0u64; 4];
        let mut files = 0;
        for t in &b.set.tiles {
            let Some(uri) = &t.content else { continue };
            let f = b.dir.path().join(uri);
            let r = support::node::run_json(&node, "validate_gltf.js", &f);
            let i = &r["issues"];
            let c = ["numErrors", "numWarnings", "numInfos", "numHints"]
                .map(|k| i[k].as_u64().unwrap());
            assert_eq!(c[..2], [0, 0], "{name}: {uri}: {:#}", i["messages"]);
            // Infos allowed: the validator does not know EXT_mesh_features /
            // EXT_structural_metadata, and so calls the property buffer views unused.
            for m in i["messages"].as_array().unwrap() {
                let code = m["code"].as_str().unwrap();
                assert!(
                    code == "UNSUPPORTED_EXTENSION" || code == "UNUSED_OBJECT",
                    "{name}: {uri}: {m}"
                );
            }
            for k in 0..4 {
                totals[k] += c[k];
            }
            files += 1;
        }
        println!(
            "{name}: {files} .glb validated: {} errors, {} warnings, {} infos, {} hints",
            totals[0], totals[1], totals[2], totals[3]
        );
        assert!(files > 1);
    }
}

/// Helsinki on a terrain of 20 m cells (with a hole), cut into terrain leaves of at most 1000
/// triangles: the main `tileset.json` holds both trees under a root refined by `ADD`, the
/// terrain's own `tileset.json` stands where the buildings do (same root transform), its leaves
/// together hold every input triangle exactly once (matched by its three vertices, orientation
/// kept) in the cell holding its centroid, boxes hold the positions read back, errors are 0 at
/// the leaves and never grow downwards; every terrain `.glb` passes the Khronos validator.
#[test]
fn terrain_tileset_holds_every_triangle_once_beside_the_buildings() {
    let base = support::data::load_city(Path::new("data/helsinki/buildings.shp"), None);
    let (_, tin) = support::terrain::terrain_city(&base, 20.0);
    // Plain contents: the triangles are matched by their exact f32 vertices.
    let opts = TilesetOptions {
        terrain: Some(&tin),
        terrain_leaf_triangles: 1000,
        content: ContentEncoding::Plain,
        ..TilesetOptions::default()
    };
    let b = build_with(
        "data/helsinki/buildings.shp",
        Some("data/helsinki/streets_blockclass.shp"),
        &opts,
        |c| support::terrain::terrain_city(&c, 20.0).0,
    );
    let g = b.set.georef.expect("Helsinki is georeferenced");
    let terrain = b.set.terrain.as_ref().expect("a terrain tileset");
    assert_eq!(b.summary.terrain_triangles, tin.triangles.len());

    // The main tileset: a group of the buildings' tree (with the transform) and the terrain's.
    let main: Value =
        serde_json::from_slice(&std::fs::read(b.dir.path().join("tileset.json")).unwrap()).unwrap();
    let root = &main["root"];
    assert_eq!(root["refine"], "ADD");
    assert!(root.get("content").is_none() && root.get("transform").is_none());
    let kids = root["children"].as_array().unwrap();
    assert_eq!(kids.len(), 2);
    let t: Vec<f64> = kids[0]["transform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(t, g.ecef_from_local.to_vec());
    assert_eq!(kids[0]["refine"], "REPLACE");
    assert_eq!(kids[1]["content"]["uri"], "terrain/tileset.json");
    assert!(kids[1].get("transform").is_none() && kids[1].get("children").is_none());
    let ge = |v: &Value| v["geometricError"].as_f64().unwrap();
    assert!(ge(&main) >= ge(root) && ge(root) >= ge(&kids[0]) && ge(root) >= ge(&kids[1]));
    // The reference's box (ECEF) holds the terrain's corners placed by the transform.
    let ecef_box = |v: &Value| -> (DVec3, [DVec3; 3]) {
        let b: Vec<f64> = v["boundingVolume"]["box"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        (
            DVec3::new(b[0], b[1], b[2]),
            [
                DVec3::new(b[3], b[4], b[5]),
                DVec3::new(b[6], b[7], b[8]),
                DVec3::new(b[9], b[10], b[11]),
            ],
        )
    };
    let inside = |(c, axes): &(DVec3, [DVec3; 3]), p: DVec3| {
        axes.iter()
            .all(|a| ((p - *c).dot(*a) / a.length_squared()).abs() <= 1.0 + 1e-6)
    };
    let o = b.scene.city.frame.origin;
    let (lo, hi) = tin.bounds().unwrap();
    for corner in 0..8 {
        let pick = |k: usize, l: f64, h: f64| if corner >> k & 1 == 1 { h } else { l };
        let w = DVec3::new(
            pick(0, lo.x, hi.x),
            pick(1, lo.y, hi.y),
            pick(2, lo.z, hi.z),
        );
        let p = local_to_ecef(&g, w - o);
        assert!(
            inside(&ecef_box(&kids[1]), p),
            "terrain corner {w:?} outside the reference box"
        );
        assert!(
            inside(&ecef_box(root), p),
            "terrain corner {w:?} outside the root box"
        );
    }

    // The terrain's own tileset.
    let tdir = b.dir.path().join("terrain");
    let doc: Value =
        serde_json::from_slice(&std::fs::read(tdir.join("tileset.json")).unwrap()).unwrap();
    assert_eq!(doc["asset"]["version"], "1.1");
    let t: Vec<f64> = doc["root"]["transform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(t, g.ecef_from_local.to_vec(), "the same root transform");
    let tiles = json_tiles(&doc);
    assert_eq!(tiles.len(), terrain.tiles.len());
    // Input vertices by their f32 local position (world − origin, rounded once), input
    // triangles by their vertices starting from the smallest (orientation kept).
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let vertex_of: std::collections::HashMap<[u32; 3], u32> = tin
        .vertices
        .iter()
        .enumerate()
        .map(|(i, w)| (key((*w - o).as_vec3()), i as u32))
        .collect();
    assert_eq!(
        vertex_of.len(),
        tin.vertices.len(),
        "distinct f32 positions"
    );
    let canon = |t: [u32; 3]| {
        let k = (0..3).min_by_key(|&k| t[k]).unwrap();
        [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
    };
    let triangle_of: std::collections::HashMap<[u32; 3], usize> = tin
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| (canon(*t), i))
        .collect();
    let mut seen = vec![0u32; tin.triangles.len()];
    let (mut leaves, mut bytes) = (0, 0);
    for (i, (parent, t)) in tiles.iter().enumerate() {
        assert_eq!(t["extras"]["kind"], "terrain");
        let leaf = t.get("children").is_none();
        assert_eq!(leaf, terrain.tiles[i].children.is_empty());
        if leaf {
            assert_eq!(ge(t), 0.0, "terrain leaves are full resolution");
        } else {
            assert!(ge(t) > 0.0 && t.get("content").is_none());
        }
        let (blo, bhi) = box_of(t);
        if let Some(p) = parent {
            assert!(ge(&tiles[*p].1) >= ge(t));
            let (plo, phi) = box_of(&tiles[*p].1);
            assert!(blo.cmpge(plo - 1e-6).all() && bhi.cmple(phi + 1e-6).all());
        }
        let Some(uri) = t["content"]["uri"].as_str() else {
            continue;
        };
        leaves += 1;
        bytes += std::fs::metadata(tdir.join(uri)).unwrap().len();
        let (doc, buffers, _) =
            gltf::import_slice(std::fs::read(tdir.join(uri)).unwrap()).expect("import");
        let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|buf| Some(&buffers[buf.index()]));
        let pos: Vec<Vec3> = reader.read_positions().unwrap().map(Vec3::from).collect();
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        let (cell_sw, side) = terrain.tiles[i].cell;
        for tri in idx.chunks(3) {
            let vs = [0, 1, 2].map(|k| {
                let local = local_from_gltf(pos[tri[k] as usize]);
                assert!(
                    local.cmpge(blo - 1e-3).all() && local.cmple(bhi + 1e-3).all(),
                    "{uri}: vertex {local:?} outside its box"
                );
                *vertex_of
                    .get(&key(local.as_vec3()))
                    .unwrap_or_else(|| panic!("{uri}: {local:?} is no input vertex"))
            });
            let n = *triangle_of
                .get(&canon(vs))
                .unwrap_or_else(|| panic!("{uri}: {vs:?} is no input triangle (or turned over)"));
            seen[n] += 1;
            let c = (tin.centroid(n) - o).truncate();
            assert!(
                c.cmpge(cell_sw - 1e-6).all() && c.cmple(cell_sw + side + 1e-6).all(),
                "{uri}: triangle {n}'s centroid outside the tile's cell"
            );
        }
    }
    assert!(
        seen.iter().all(|&n| n == 1),
        "every input triangle exactly once"
    );
    assert!(leaves > 4, "the terrain is cut into tiles: {leaves} leaves");
    println!(
        "helsinki terrain: {} triangles in {} tiles ({leaves} leaves, {bytes} bytes of .glb), root error {:.1} m; whole tileset {} bytes",
        tin.triangles.len(),
        tiles.len(),
        terrain.geometric_error,
        b.summary.bytes
    );

    // Deterministic: a second export gives the same bytes, terrain files included.
    let again = build_with(
        "data/helsinki/buildings.shp",
        Some("data/helsinki/streets_blockclass.shp"),
        &opts,
        |c| support::terrain::terrain_city(&c, 20.0).0,
    );
    let files = |d: &Path| -> Vec<(PathBuf, Vec<u8>)> {
        let mut v: Vec<(PathBuf, Vec<u8>)> = ["tileset.json", "terrain/tileset.json"]
            .iter()
            .map(|f| d.join(f))
            .chain(
                std::fs::read_dir(d.join("terrain/tiles"))
                    .unwrap()
                    .map(|e| e.unwrap().path()),
            )
            .map(|p| {
                (
                    p.strip_prefix(d).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    };
    assert!(
        files(b.dir.path()) == files(again.dir.path()),
        "two exports differ"
    );

    let Some(node) = support::node::or_skip(
        "terrain_tileset_holds_every_triangle_once_beside_the_buildings",
        support::node::node_with(&["gltf-validator"]),
    ) else {
        return;
    };
    let mut totals = [0u64; 4];
    for (_, t) in &tiles {
        let Some(uri) = t["content"]["uri"].as_str() else {
            continue;
        };
        let r = support::node::run_json(&node, "validate_gltf.js", &tdir.join(uri));
        let i = &r["issues"];
        let c =
            ["numErrors", "numWarnings", "numInfos", "numHints"].map(|k| i[k].as_u64().unwrap());
        assert_eq!(c[..2], [0, 0], "{uri}: {:#}", i["messages"]);
        for k in 0..4 {
            totals[k] += c[k];
        }
    }
    println!(
        "terrain tiles validated: {} errors, {} warnings, {} infos, {} hints",
        totals[0], totals[1], totals[2], totals[3]
    );
}
