//! A city in tiles (`blockwalk::jobs`) equals one run on the whole city: the same blocks, the
//! same buildings per block, the same meshes (read back from the tiles' `.glb` files and
//! compared vertex for vertex with the one-job run's `.glb`); and the errors of a missing tile,
//! a plan from another city and a tile out of range name their file and tile.

mod support;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use blockwalk::blocks::{detect, BlockKind, BlockOptions};
use blockwalk::city::export::gltf::glb_bytes;
use blockwalk::city::extrude::try_extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::jobs::{
    manifest_path, merge, plan, run_tile, write_plan, JobsError, Plan, PlanOptions, TileOptions,
};
use blockwalk::scene::CitySource;

/// Positions (glTF's y-up, as written) and indices of every building node, by node name.
type Nodes = HashMap<String, (Vec<[f32; 3]>, Vec<u32>)>;

fn glb_nodes(bytes: &[u8]) -> Nodes {
    let (doc, buffers, _) = gltf::import_slice(bytes).expect("a readable .glb");
    let root = doc.scenes().next().unwrap().nodes().next().unwrap();
    let mut out = HashMap::new();
    for node in root.children() {
        let name = node.name().expect("a named building node").to_string();
        let (pos, idx) = match node.mesh() {
            Some(mesh) => {
                let prim = mesh.primitives().next().unwrap();
                let r = prim.reader(|b| Some(&buffers[b.index()]));
                (
                    r.read_positions().unwrap().collect(),
                    r.read_indices().unwrap().into_u32().collect(),
                )
            }
            None => (Vec::new(), Vec::new()),
        };
        assert!(
            out.insert(name, (pos, idx)).is_none(),
            "one node per building"
        );
    }
    out
}

/// Blocks of the one-job run: id → (outskirts?, building source ids in order).
type Blocks = BTreeMap<u32, (bool, Vec<String>)>;

/// The one-job run on the whole city: its blocks and its `.glb`'s nodes.
fn whole_city(
    footprints: &Path,
    streets: &Path,
    ground: Option<blockwalk::city::build::GroundOptions>,
) -> (Blocks, Nodes, glam::DVec3) {
    let source = CitySource::parse(footprints, Some(streets.into()), None, &[], 0)
        .unwrap()
        .with_ground(ground);
    let city = source.load(&Default::default(), &mut |_| {}).unwrap().city;
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    let (meshes, failed) = try_extrude_city(&city);
    assert!(failed.is_empty());
    let (bytes, _) = glb_bytes(&city, &meshes).unwrap();
    let blocks = layout
        .blocks
        .iter()
        .map(|b| {
            (
                b.id.0,
                (
                    b.kind == BlockKind::Outskirts,
                    b.buildings
                        .iter()
                        .map(|i| city.buildings[i.0 as usize].source_id.clone())
                        .collect(),
                ),
            )
        })
        .collect();
    (blocks, glb_nodes(&bytes), city.frame.origin)
}

/// Plans `footprints` in tiles of at most `max` buildings into `dir`, runs every tile, merges,
/// and checks the result against the one-job run. Returns the number of tiles and of buildings
/// read by a tile they do not belong to.
fn tiles_equal_one_job(
    footprints: &Path,
    streets: &Path,
    dir: &Path,
    max: usize,
) -> (usize, usize) {
    tiles_on_ground_equal_one_job(footprints, streets, dir, max, None)
}

/// [`tiles_equal_one_job`] with the buildings put on `ground` in both runs.
fn tiles_on_ground_equal_one_job(
    footprints: &Path,
    streets: &Path,
    dir: &Path,
    max: usize,
    ground: Option<blockwalk::city::build::GroundOptions>,
) -> (usize, usize) {
    let p = plan(
        footprints,
        streets,
        &PlanOptions {
            max_buildings: max,
            build: blockwalk::city::build::BuildOptions {
                ground: ground.clone(),
                ..Default::default()
            },
        },
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(p.ground.is_some(), ground.is_some());
    let plan_path = write_plan(&p, dir).unwrap();
    let (want_blocks, want_nodes, origin) = whole_city(footprints, streets, ground);
    assert_eq!(
        p.frame().origin,
        origin,
        "the plan's frame is the whole city's"
    );
    assert_eq!(p.blocks.len(), want_blocks.len());
    assert!(p.tiles.len() >= 4, "{} tiles", p.tiles.len());

    let mut got_blocks: Blocks = BTreeMap::new();
    let mut got_nodes: Nodes = HashMap::new();
    let mut read_twice = 0;
    for t in 0..p.tiles.len() {
        let r = run_tile(&plan_path, t, &TileOptions::default()).unwrap();
        assert!(r.manifest.buildings <= max || r.manifest.blocks.len() == 1);
        read_twice += r.manifest.buildings_read - r.manifest.buildings;
        for b in &r.manifest.blocks {
            let prev = got_blocks.insert(b.id, (b.outskirts, b.buildings.clone()));
            assert!(prev.is_none(), "block {} in two tiles", b.id);
        }
        for f in r.manifest.files.iter().filter(|f| f.path.ends_with(".glb")) {
            let bytes = std::fs::read(dir.join(&f.path)).unwrap();
            for (name, mesh) in glb_nodes(&bytes) {
                assert!(
                    got_nodes.insert(name.clone(), mesh).is_none(),
                    "building {name} in two tiles"
                );
            }
        }
    }
    assert_eq!(
        got_blocks, want_blocks,
        "same blocks, same buildings per block"
    );
    assert_eq!(got_nodes.len(), want_nodes.len());
    let mut triangles = 0;
    for (name, (pos, idx)) in &want_nodes {
        let (gp, gi) = got_nodes
            .get(name)
            .unwrap_or_else(|| panic!("{name} missing"));
        assert_eq!(gi, idx, "{name}: indices");
        let same = gp.len() == pos.len()
            && gp
                .iter()
                .zip(pos)
                .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        assert!(same, "{name}: positions differ from the one-job run's");
        triangles += idx.len() / 3;
    }
    let (index, ipath) = merge(dir).unwrap();
    assert!(ipath.ends_with("index.json"));
    assert_eq!(index.tiles.len(), p.tiles.len());
    assert_eq!(index.buildings, p.buildings);
    assert_eq!(index.blocks, want_blocks.len());
    assert_eq!(index.triangles as usize, triangles);
    (p.tiles.len(), read_twice)
}

fn generated(dir: &Path, buildings: usize, seed: u64) -> PathBuf {
    let city = generate_city(&GenerateParams {
        buildings,
        seed,
        parcels: false,
        ..Default::default()
    })
    .unwrap();
    write_city(&city, dir).unwrap();
    dir.to_path_buf()
}

#[test]
fn generated_city_in_tiles_equals_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 3000, 7);
    let (n, _) = tiles_equal_one_job(
        &city.join("buildings.shp"),
        &city.join("streets.shp"),
        &tmp.path().join("jobs"),
        500,
    );
    assert!(n >= 6, "{n} tiles");
}

#[test]
fn a_city_on_terrain_in_tiles_equals_one_run() {
    let dem = support::data::shared_data("dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif");
    let Some(dem) = support::skip::or_skip(
        support::skip::Need::Dem,
        "a_city_on_terrain_in_tiles_equals_one_run",
        if dem.is_file() {
            Ok(dem)
        } else {
            Err("../shared/data/dem absent".into())
        },
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let c = generate_city(&GenerateParams {
        buildings: 1500,
        seed: 4,
        parcels: false,
        epsg: 32645,
        centre: Some((333_000.0, 3_110_000.0)),
        ..Default::default()
    })
    .unwrap();
    let city = tmp.path().join("city");
    write_city(&c, &city).unwrap();
    let (n, _) = tiles_on_ground_equal_one_job(
        &city.join("buildings.shp"),
        &city.join("streets.shp"),
        &tmp.path().join("jobs"),
        400,
        Some(blockwalk::city::build::GroundOptions::new(dem)),
    );
    assert!(n >= 4, "{n} tiles");
}

#[test]
fn helsinki_in_tiles_equals_one_run() {
    // Real data: repaired footprints, multipolygons, and 207 buildings in outskirts groups.
    let tmp = tempfile::tempdir().unwrap();
    let data = support::data::data("helsinki");
    let (_, read_twice) = tiles_equal_one_job(
        &data.join("buildings.shp"),
        &data.join("streets_blockclass.shp"),
        tmp.path(),
        100,
    );
    // Buildings straddling tile bounds are read by more than one tile, and still each is in
    // exactly one (checked above).
    assert!(read_twice > 0, "no building was read by two tiles");
}

fn small_plan(dir: &Path, city: &Path) -> (Plan, PathBuf) {
    let p = plan(
        &city.join("buildings.shp"),
        &city.join("streets.shp"),
        &PlanOptions {
            max_buildings: 150,
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let path = write_plan(&p, dir).unwrap();
    (p, path)
}

#[test]
fn merge_names_a_missing_tile() {
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 600, 1);
    let (p, plan_path) = small_plan(&tmp.path().join("jobs"), &city);
    assert!(p.tiles.len() >= 3);
    for t in (0..p.tiles.len()).filter(|&t| t != 1) {
        run_tile(&plan_path, t, &TileOptions::default()).unwrap();
    }
    match merge(&tmp.path().join("jobs")) {
        Err(JobsError::MissingTile { tile, file, .. }) => {
            assert_eq!(tile, 1);
            assert_eq!(file, manifest_path(&plan_path, 1));
        }
        other => panic!("expected MissingTile, got {other:?}"),
    }
    let msg = merge(&tmp.path().join("jobs")).unwrap_err().to_string();
    assert!(
        msg.contains("tile 1") && msg.contains("tile_00001.json"),
        "{msg}"
    );
    // Once it has run, the merge passes.
    run_tile(&plan_path, 1, &TileOptions::default()).unwrap();
    merge(&tmp.path().join("jobs")).unwrap();
}

#[test]
fn a_plan_from_another_city_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 600, 1);
    let jobs = tmp.path().join("jobs");
    let (p, plan_path) = small_plan(&jobs, &city);
    run_tile(&plan_path, 0, &TileOptions::default()).unwrap();
    // The city's files are replaced by another city's: running a tile of the old plan refuses,
    // naming the plan and the file.
    generated(&city, 600, 2);
    match run_tile(&plan_path, 1, &TileOptions::default()) {
        Err(JobsError::InputChanged { plan, file, .. }) => {
            assert_eq!(plan, plan_path);
            assert!(file.ends_with("buildings.shp"), "{}", file.display());
        }
        other => panic!("expected InputChanged, got {other:?}"),
    }
    // A new plan for the new city in the same folder: the old tile's manifest is refused by the
    // merge as another plan's.
    let (p2, plan_path2) = small_plan(&jobs, &city);
    assert_ne!(p.plan_id, p2.plan_id);
    for t in 1..p2.tiles.len() {
        run_tile(&plan_path2, t, &TileOptions::default()).unwrap();
    }
    match merge(&jobs) {
        Err(JobsError::OtherPlan {
            tile,
            file,
            expected,
            found,
        }) => {
            assert_eq!(tile, 0);
            assert_eq!(file, manifest_path(&plan_path2, 0));
            assert_eq!((expected, found), (p2.plan_id.clone(), p.plan_id.clone()));
        }
        other => panic!("expected OtherPlan, got {other:?}"),
    }
}

#[test]
fn a_tile_out_of_range_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 300, 1);
    let (p, plan_path) = small_plan(&tmp.path().join("jobs"), &city);
    let n = p.tiles.len();
    match run_tile(&plan_path, n, &TileOptions::default()) {
        Err(e @ JobsError::TileOutOfRange { .. }) => {
            let JobsError::TileOutOfRange { plan, tile, tiles } = &e else {
                unreachable!()
            };
            assert_eq!((plan, *tile, *tiles), (&plan_path, n, n));
            let msg = e.to_string();
            assert!(
                msg.contains("plan.json") && msg.contains(&format!("tile {n}")),
                "{msg}"
            );
        }
        other => panic!("expected TileOutOfRange, got {other:?}"),
    }
    // A file that is not a plan is refused as such.
    let not_plan = tmp.path().join("x.json");
    std::fs::write(&not_plan, "{\"format\": \"something else\"}").unwrap();
    assert!(matches!(
        run_tile(&not_plan, 0, &TileOptions::default()),
        Err(JobsError::Format { file, .. }) if file == not_plan
    ));
}

#[test]
fn streaming_reader_gives_the_features_of_the_whole_reader() {
    use blockwalk::importers::shp;
    let path = support::data::data("helsinki/buildings.shp");
    let whole = shp::read(&path).unwrap();
    // Everything, in chunks of 100: the same features in the same order, the same refusals.
    let mut chunks = Vec::new();
    let n = shp::read_streaming(&path, &mut |_, _| true, 100, &mut |l| chunks.push(l)).unwrap();
    assert_eq!(n, whole.report.read);
    assert!(chunks.len() >= 5 && chunks.iter().all(|c| c.features.len() <= 100));
    let fids: Vec<u64> = chunks
        .iter()
        .flat_map(|c| c.features.iter().map(|f| f.fid))
        .collect();
    let want: Vec<u64> = whole.features.iter().map(|f| f.fid).collect();
    assert_eq!(fids, want);
    let streamed: Vec<_> = chunks.iter().flat_map(|c| &c.features).collect();
    for (a, b) in streamed.iter().zip(&whole.features) {
        assert_eq!(a.geometry, b.geometry);
        assert_eq!(a.attributes, b.attributes);
    }
    let refused: usize = chunks.iter().map(|c| c.report.refused.len()).sum();
    assert_eq!(refused, whole.report.refused.len());
    // A box: exactly the features whose box meets it, checked against the whole layer.
    let (x0, y0) = (385_900.0, 6_672_200.0);
    let meets = |b: [f64; 4]| b[0] <= x0 + 250.0 && x0 <= b[2] && b[1] <= y0 + 250.0 && y0 <= b[3];
    let mut kept = Vec::new();
    shp::read_streaming(&path, &mut |_, b| meets(b), usize::MAX, &mut |l| {
        kept.extend(l.features.into_iter().map(|f| f.fid))
    })
    .unwrap();
    let brute: Vec<u64> = whole
        .features
        .iter()
        .filter(|f| {
            use geo::BoundingRect;
            let r = f.geometry.bounding_rect().unwrap();
            meets([r.min().x, r.min().y, r.max().x, r.max().y])
        })
        .map(|f| f.fid)
        .collect();
    assert!(
        !brute.is_empty() && brute.len() < whole.features.len() / 2,
        "{}",
        brute.len()
    );
    assert_eq!(kept, brute);
}

#[test]
fn a_tile_with_blockmaps_lists_and_merges_its_maps() {
    use blockwalk::blockmap::CityMapsOptions;
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 300, 1);
    let (p, plan_path) = small_plan(&tmp.path().join("jobs"), &city);
    let opts = CityMapsOptions {
        checks: 0,
        ..Default::default()
    };
    let r = run_tile(
        &plan_path,
        0,
        &TileOptions {
            maps: Some(opts),
            ..TileOptions::default()
        },
    )
    .unwrap();
    let maps = r.manifest.blockmaps.as_ref().expect("map figures");
    let n = maps["maps"].as_u64().unwrap() as usize;
    assert!(n >= 1);
    // The .glb, the block mesh pack, the maps' summary (blockmaps.json), a PNG and a JSON per
    // map, and the hierarchy, each listed with its size and hash.
    assert_eq!(r.manifest.files.len(), 4 + 2 * n);
    assert!(r
        .manifest
        .files
        .iter()
        .any(|f| f.path.ends_with("_maps/blockmaps.json")));
    for f in &r.manifest.files {
        let bytes = std::fs::read(tmp.path().join("jobs").join(&f.path)).unwrap();
        assert_eq!(bytes.len() as u64, f.bytes, "{}", f.path);
    }
    for t in 1..p.tiles.len() {
        run_tile(&plan_path, t, &TileOptions::default()).unwrap();
    }
    let (index, _) = merge(&tmp.path().join("jobs")).unwrap();
    assert_eq!(index.tiles[0].files.len(), 4 + 2 * n);
}

/// Content URIs of a tileset JSON tile tree, depth first.
fn content_uris(tile: &serde_json::Value, out: &mut Vec<String>) {
    if let Some(u) = tile["content"]["uri"].as_str() {
        out.push(u.to_string());
    }
    for c in tile["children"].as_array().into_iter().flatten() {
        content_uris(c, out);
    }
}

/// The 8 corners of a 3D Tiles `box` (centre and three half-axes).
fn box_corners(b: &serde_json::Value) -> Vec<glam::DVec3> {
    let v: Vec<f64> = b
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let c = glam::DVec3::new(v[0], v[1], v[2]);
    let ax = [3, 6, 9].map(|i| glam::DVec3::new(v[i], v[i + 1], v[i + 2]));
    let mut out = Vec::new();
    for s in 0..8 {
        let sign = |k: usize| if s >> k & 1 == 1 { 1.0 } else { -1.0 };
        out.push(c + sign(0) * ax[0] + sign(1) * ax[1] + sign(2) * ax[2]);
    }
    out
}

/// `p` inside the box `b` within `tol` metres along each half-axis.
fn box_holds(b: &serde_json::Value, p: glam::DVec3, tol: f64) -> bool {
    let v: Vec<f64> = b
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let c = glam::DVec3::new(v[0], v[1], v[2]);
    [3, 6, 9].iter().all(|&i| {
        let a = glam::DVec3::new(v[i], v[i + 1], v[i + 2]);
        let len = a.length();
        len == 0.0 || ((p - c).dot(a) / len).abs() <= len + tol
    })
}

/// Every child's box inside its parent's, every child's geometric error at most its parent's.
fn check_nesting(tile: &serde_json::Value, groups: &mut usize) {
    for c in tile["children"].as_array().into_iter().flatten() {
        *groups += 1;
        for p in box_corners(&c["boundingVolume"]["box"]) {
            assert!(
                box_holds(&tile["boundingVolume"]["box"], p, 1e-6),
                "a child's box leaves its parent's"
            );
        }
        assert!(c["geometricError"].as_f64().unwrap() <= tile["geometricError"].as_f64().unwrap());
        check_nesting(c, groups);
    }
}

#[test]
fn tiles_with_tilesets_merge_under_one_root_tileset() {
    let tmp = tempfile::tempdir().unwrap();
    let city = generated(&tmp.path().join("city"), 1200, 5);
    let (p, plan_path) = small_plan(&tmp.path().join("jobs"), &city);
    assert!(p.tiles.len() >= 4, "{} tiles", p.tiles.len());
    let opts = TileOptions {
        tileset: Some(blockwalk::tiles::TilesetOptions {
            k: 32,
            ..Default::default()
        }),
        ..TileOptions::default()
    };
    let mut transforms = Vec::new();
    for t in 0..p.tiles.len() {
        let r = run_tile(&plan_path, t, &opts).unwrap();
        let ts = r.manifest.tileset.clone().expect("a tileset");
        // Its files are listed (and so checked by merge), its tileset.json among them.
        assert!(r.manifest.files.iter().any(|f| f.path == ts.path));
        assert_eq!(
            ts.bytes,
            r.manifest
                .files
                .iter()
                .filter(|f| f.path.starts_with(&format!("tiles/tile_{t:05}_tileset/")))
                .map(|f| f.bytes)
                .sum::<u64>()
        );
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("jobs").join(&ts.path)).unwrap())
                .unwrap();
        transforms.push(doc["root"]["transform"].clone());
        // The buildings with meshes of the tile, each in one leaf.
        let with_mesh = r.meshes.iter().filter(|m| m.triangle_count() > 0).count();
        assert_eq!(ts.buildings, with_mesh, "tile {t}");
    }
    let (index, _) = merge(&tmp.path().join("jobs")).unwrap();
    assert_eq!(index.tileset.as_deref(), Some("tileset.json"));
    let root: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("jobs/tileset.json")).unwrap())
            .unwrap();
    // Every tile's tileset is referenced exactly once, and nothing else.
    let mut uris = Vec::new();
    content_uris(&root["root"], &mut uris);
    uris.sort();
    let mut want: Vec<String> = index
        .tiles
        .iter()
        .map(|t| t.tileset.as_ref().unwrap().path.clone())
        .collect();
    want.sort();
    assert_eq!(uris, want);
    assert_eq!(
        index
            .tiles
            .iter()
            .map(|t| t.tileset.as_ref().unwrap().buildings)
            .sum::<usize>(),
        p.buildings,
        "every building of the plan in one tile's leaves"
    );
    // One placement for all tiles; the root adds, has none of its own, and nests its boxes.
    assert!(transforms.windows(2).all(|w| w[0] == w[1]));
    assert!(root["root"].get("transform").is_none());
    assert_eq!(root["root"]["refine"], "ADD");
    let mut n = 0;
    check_nesting(&root["root"], &mut n);
    assert!(n >= p.tiles.len(), "{n} tiles under the root");
    assert!(
        root["geometricError"].as_f64().unwrap()
            >= root["root"]["geometricError"].as_f64().unwrap()
    );
    // Each tile's box (local, through the shared transform) inside the leaf that references it.
    let m = glam::DMat4::from_cols_array(
        &serde_json::from_value::<[f64; 16]>(transforms[0].clone()).unwrap(),
    );
    fn leaves<'a>(t: &'a serde_json::Value, out: &mut Vec<&'a serde_json::Value>) {
        if t["content"]["uri"].is_string() {
            out.push(t);
        }
        for c in t["children"].as_array().into_iter().flatten() {
            leaves(c, out);
        }
    }
    let mut ls = Vec::new();
    leaves(&root["root"], &mut ls);
    for l in ls {
        let uri = l["content"]["uri"].as_str().unwrap();
        let t = index
            .tiles
            .iter()
            .find(|t| t.tileset.as_ref().unwrap().path == uri)
            .unwrap();
        let a = t.tileset.as_ref().unwrap().aabb;
        for s in 0..8 {
            let pick = |k: usize| if s >> k & 1 == 1 { a[k + 3] } else { a[k] };
            let q = m.transform_point3(glam::DVec3::new(pick(0), pick(1), pick(2)));
            assert!(box_holds(&l["boundingVolume"]["box"], q, 1e-6));
        }
    }

    // A tile run again without its tileset: merge refuses, naming the tile.
    run_tile(&plan_path, 1, &TileOptions::default()).unwrap();
    assert!(!tmp.path().join("jobs/tiles/tile_00001_tileset").exists());
    match merge(&tmp.path().join("jobs")) {
        Err(JobsError::TileMismatch { tile: 1, why, .. }) => {
            assert!(why.contains("no tileset"), "{why}")
        }
        other => panic!("expected tile 1 refused, got {other:?}"),
    }
}
