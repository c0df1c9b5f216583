//! The Helsinki tileset loaded by CesiumJS (npm `cesium`) in headless Chromium (Debian
//! `chromium`, software WebGL 2 through SwiftShader), driven by `tests/tools/cesium_tileset.mjs`
//! (npm `puppeteer-core`) from a static server on 127.0.0.1: no network, no Ion token, no
//! imagery, ellipsoid terrain. From far away only inner tiles (BlockMap height fields) are drawn;
//! close up, leaf tiles (building meshes) are loaded and drawn: REPLACE refinement happens, and no
//! tile fails. Each view is saved as `cesium_<view>.png` beside our own CPU rendering of the same
//! camera (`visibility::oracle::shade`, `ours_<view>.png`) and a side-by-side `pair_<view>.png`,
//! in `target/tileset-cesium/` (or `$BLOCKWALK_SCREENSHOT_DIR`).
//!
//! The same tiles are loaded in three forms, each held to the same assertions: the explicit
//! folder, the implicit quadtree (subtree files of 3 levels, so that child subtrees are read
//! too) and that implicit tileset as one `.3tz` served by our own server
//! ([`blockwalk::stream::serve`], which reads the entries through the archive's index; CesiumJS
//! reads no `.3tz` itself). Screenshots of the implicit and `.3tz` forms are prefixed
//! `implicit_` and `3tz_`.
//!
//! The city stands on a terrain (gentle hills within about a metre of the ground, 20 m cells, a
//! hole) written as the second tileset beside the buildings': both views draw terrain tiles too,
//! and both trees' files are requested.
//!
//! Needs `node`, `chromium` and `npm ci --prefix tests/tools` (what `.ci/run` does). Without them
//! the test skips loudly, unless the validators are required (`BLOCKWALK_REQUIRE=validators`).

use std::path::Path;

use blockwalk::city::appearance;
use blockwalk::city::extrude::extrude_city;
use blockwalk::geom::Camera;
use blockwalk::jobs::{merge, plan, run_tile, write_plan, PlanOptions, TileOptions};
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::tiles::{build_tileset, Georef, TilesetOptions};
use blockwalk::visibility::oracle::shade;
use glam::DVec3;
use serde_json::{json, Value};

mod support;

const W: u32 = 480;

/// One headless Chromium at a time: two software-rendered CesiumJS pages side by side on a
/// small machine would each run into the page's time limits.
static CHROMIUM: std::sync::Mutex<()> = std::sync::Mutex::new(());
const H: u32 = 270;

/// Share of pixels on which both images agree about "sky" (the sky colour, ±12 per channel).
fn sky_agreement(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let sky = appearance::SKY;
    let is_sky = |p: &image::Rgba<u8>| (0..3).all(|c| (p[c] as i32 - sky[c] as i32).abs() <= 12);
    let same = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| is_sky(p) == is_sky(q))
        .count();
    same as f64 / (a.width() * a.height()) as f64
}

/// Views over the middle of a city: from 3 km away (the root's map alone is fine enough) and
/// from 80 m up, 220 m from the middle (leaves needed nearby); and the point they look at.
fn views_of(scene: &Scene) -> ([(&'static str, DVec3); 2], DVec3) {
    let c = scene.city_bounds().center();
    let centre = DVec3::new(c.x, c.y, 0.0);
    (
        [
            ("far", centre + DVec3::new(0.0, -2600.0, 1500.0)),
            ("near", centre + DVec3::new(0.0, -220.0, 80.0)),
        ],
        centre,
    )
}

/// Our own rendering of each view (the scene's block meshes, lit as CesiumJS is asked to),
/// saved as `{prefix}ours_{view}.png`.
fn our_images(
    scene: &Scene,
    views: &[(&str, DVec3)],
    centre: DVec3,
    out: &Path,
    prefix: &str,
) -> Vec<image::RgbaImage> {
    let blocks: Vec<_> = scene
        .block_meshes()
        .iter()
        .map(|(id, m)| (*id, m))
        .collect();
    views
        .iter()
        .map(|(name, eye)| {
            let mut cam = Camera::looking_at(*eye, centre);
            cam.aspect = W as f64 / H as f64;
            cam.far = 20_000.0;
            let img = shade(&blocks, &cam, W, H);
            img.save(out.join(format!("{prefix}ours_{name}.png")))
                .unwrap();
            img
        })
        .collect()
}

/// What one CesiumJS page loads: the tileset's folder (served by the page's own server) or a
/// URL, the local frame's transform when the root has none, and the file prefix of its outputs.
struct Page<'a> {
    dir: &'a Path,
    url: Option<String>,
    local_to_ecef: Option<[f64; 16]>,
    prefix: &'a str,
}

/// Runs `tests/tools/cesium_tileset.mjs` on one page and returns its report (also saved as
/// `{prefix}cesium_report.json` in `out`).
fn run_page(
    (node, chromium): (&str, &str),
    page: &Page<'_>,
    views: &[(&str, DVec3)],
    centre: DVec3,
    work: &Path,
    out: &Path,
) -> Value {
    let spec = json!({
        "chromium": chromium,
        "tileset_dir": page.dir,
        "tileset_url": page.url,
        "local_to_ecef": page.local_to_ecef,
        "prefix": page.prefix,
        "out_dir": out,
        "width": W,
        "height": H,
        "maximum_screen_space_error": 16,
        "sky": appearance::SKY,
        "ground": appearance::GROUND,
        "sun_local": appearance::sun_direction().to_array(),
        "views": views.iter().map(|(name, eye)| json!({
            "name": name, "eye": eye.to_array(), "target": centre.to_array(), "fov_y_deg": 60.0,
        })).collect::<Vec<_>>(),
    });
    let spec_path = work.join(format!("spec{}.json", page.prefix));
    std::fs::write(&spec_path, serde_json::to_vec_pretty(&spec).unwrap()).unwrap();
    let report = support::node::run_json(node, "cesium_tileset.mjs", &spec_path);
    std::fs::write(
        out.join(format!("{}cesium_report.json", page.prefix)),
        serde_json::to_vec_pretty(&report).unwrap(),
    )
    .unwrap();
    report
}

#[test]
fn cesium_loads_the_helsinki_tileset_and_refines_it() {
    let _one = CHROMIUM.lock().unwrap_or_else(|e| e.into_inner());
    let Some((node, chromium)) = support::node::or_skip(
        "cesium_loads_the_helsinki_tileset_and_refines_it",
        support::node::node_with(&["cesium", "puppeteer-core"])
            .and_then(|n| Ok((n, support::node::chromium()?))),
    ) else {
        return;
    };
    let source = CitySource::parse(
        Path::new("data/helsinki/buildings.shp"),
        Some("data/helsinki/streets_blockclass.shp".into()),
        None,
        &[],
        0,
    )
    .unwrap();
    let scene = Scene::load(
        &source,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .unwrap();
    // Hills of ±1.3 m around the ground, so that our rendering (buildings on a flat ground)
    // still sees the same skyline; the buildings stand on them.
    let (city, tin) = support::terrain::terrain_city_with(&scene.city, 20.0, |o, x, y| {
        0.1 * (support::terrain::height(o, x, y) - 30.0)
    });
    let meshes = extrude_city(&city);
    let work = tempfile::tempdir().unwrap();
    let build = |name: &str, implicit: bool, archive: bool| {
        let out = work.path().join(name);
        let (set, summary) = build_tileset(
            &city,
            &scene.layout,
            &scene.bounds,
            &meshes,
            &out,
            &TilesetOptions {
                terrain: Some(&tin),
                terrain_leaf_triangles: 2000,
                implicit,
                subtree_levels: 3,
                archive,
                ..TilesetOptions::default()
            },
            &|_, _| {},
        )
        .unwrap();
        assert!(summary.terrain_tiles > 1);
        assert_eq!(summary.implicit, implicit);
        (out, set.georef.expect("Helsinki is georeferenced"))
    };
    let (explicit_dir, g) = build("tileset", false, false);
    let (implicit_dir, _) = build("implicit", true, false);
    let (archive, _) = build("tileset.3tz", true, true);
    assert!(archive.is_file());
    let server = blockwalk::stream::serve::Server::start(&archive, "127.0.0.1:0", 16).unwrap();

    let (views, centre) = views_of(&scene);
    let out = support::node::screenshot_dir("tileset-cesium");
    let ours = our_images(&scene, &views, centre, &out, "");
    let forms = [
        ("explicit", "", explicit_dir.clone(), None),
        ("implicit", "implicit_", implicit_dir, None),
        (
            ".3tz",
            "3tz_",
            work.path().to_path_buf(),
            Some(format!("{}tileset.json", server.url())),
        ),
    ];
    for (form, prefix, dir, url) in forms {
        let page = Page {
            dir: &dir,
            url,
            local_to_ecef: None,
            prefix,
        };
        let report = run_page((&node, &chromium), &page, &views, centre, work.path(), &out);
        check_report(form, prefix, &report, &g, &views, &ours, &out);
    }
    // The archive's entries were all served through its index.
    assert_eq!(
        server
            .counts()
            .missing
            .load(std::sync::atomic::Ordering::Relaxed),
        0
    );
}

/// The assertions on one form's report: no page error, every file asked for was there, both
/// trees requested, each view loaded without failure, far = maps only, near = leaves, and the
/// skyline as our rendering's.
fn check_report(
    form: &str,
    prefix: &str,
    report: &Value,
    g: &Georef,
    views: &[(&str, DVec3)],
    ours: &[image::RgbaImage],
    out: &Path,
) {
    let errors = report["page_errors"].as_array().unwrap();
    assert!(errors.is_empty(), "{form}: page errors: {errors:#?}");
    // Both trees were requested: the buildings' contents (and subtrees) and the terrain's
    // tileset and tiles; nothing asked for was missing.
    let files: Vec<&str> = report["requests"]["tileset_files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    let wanted: &[&str] = if form == "explicit" {
        &[
            "tileset.json",
            "tiles/leaf_",
            "terrain/tileset.json",
            "terrain/tiles/t_",
        ]
    } else {
        &[
            "tileset.json",
            "subtrees/0/0/0.subtree",
            "subtrees/3/",
            "tiles/0/0/0.glb",
            "terrain/tileset.json",
            "terrain/tiles/t_",
        ]
    };
    for want in wanted {
        assert!(
            files.iter().any(|f| f.starts_with(want)),
            "{form}: {want} never requested: {files:?}"
        );
    }
    let missing = report["requests"]["missing"].as_array().unwrap();
    assert!(
        missing
            .iter()
            .all(|m| !files.contains(&m.as_str().unwrap())),
        "{form}: tileset files missing: {missing:?}"
    );
    let setup = &report["setup"];
    assert_eq!(setup["webgl2"], true, "{setup}");
    // Cesium puts the local origin where our transform says.
    assert!((setup["origin_lon_deg"].as_f64().unwrap() - g.lon_deg).abs() < 1e-7);
    assert!((setup["origin_lat_deg"].as_f64().unwrap() - g.lat_deg).abs() < 1e-7);

    let kinds = |v: &Value, key: &str, kind: &str| -> usize {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s.as_str().unwrap().starts_with(kind))
            .count()
    };
    for (k, (name, _)) in views.iter().enumerate() {
        let v = &report["views"][k];
        assert_eq!(v["name"], *name);
        assert_eq!(
            v["tiles_loaded"], true,
            "{form} {name}: not every tile loaded: {v}"
        );
        assert!(
            v["failed"].as_array().unwrap().is_empty(),
            "{form} {name}: tiles failed: {}",
            v["failed"]
        );
        assert!(
            !v["loaded"].as_array().unwrap().is_empty(),
            "{form} {name}: nothing loaded"
        );
        let (maps, leaves, terrain) = (
            kinds(v, "visible", "blockmap"),
            kinds(v, "visible", "buildings"),
            kinds(v, "visible", "terrain:"),
        );
        assert!(terrain > 0, "{form} {name}: no terrain tile drawn: {v}");
        println!(
            "{form} {name}: {} tiles loaded, drawn: {maps} BlockMap tiles, {leaves} building leaves, {terrain} terrain tiles, {} triangles, {:.1} s",
            v["loaded"].as_array().unwrap().len(),
            v["triangles"],
            v["seconds"].as_f64().unwrap()
        );
        match *name {
            // Far: the inner tiles' coarse meshes only.
            "far" => assert!(maps > 0 && leaves == 0, "{form} {name}: {v}"),
            // Near: leaves replaced their parents' maps.
            _ => assert!(leaves > 0, "{form} {name}: no leaf drawn: {v}"),
        }

        // Our own rendering of the same camera, and the pair side by side.
        let ours = &ours[k];
        let theirs = image::open(out.join(format!("{prefix}cesium_{name}.png")))
            .unwrap()
            .to_rgba8();
        assert_eq!(theirs.dimensions(), (W, H));
        let mut pair = image::RgbaImage::new(2 * W, H);
        image::imageops::overlay(&mut pair, ours, 0, 0);
        image::imageops::overlay(&mut pair, &theirs, W as i64, 0);
        pair.save(out.join(format!("{prefix}pair_{name}.png")))
            .unwrap();
        let agree = sky_agreement(ours, &theirs);
        println!(
            "{form} {name}: sky/not-sky agreement with our rendering {:.3}; {}",
            agree,
            out.join(format!("{prefix}pair_{name}.png")).display()
        );
        // The same camera sees the same skyline: the horizon and the buildings against the sky
        // (the views differ in lighting and in the far field's coarse mesh, not in place). From
        // 1.5 km up our ground plane's edge (20 km away) sits below Cesium's curved horizon:
        // a band of a few rows that the far view allows for.
        let need = if *name == "far" { 0.9 } else { 0.98 };
        assert!(agree > need, "{form} {name}: sky agreement {agree}");
    }
}

/// A city built in tiles by `jobs` (`run --tileset`, then `merge`): CesiumJS opens the root
/// `tileset.json`, follows it into the tiles' own tilesets (external tilesets, each placed by its
/// own transform), and draws the city near and far with no failed tile and the skyline of our
/// rendering.
#[test]
fn cesium_loads_a_city_built_in_tiles_through_its_root_tileset() {
    let _one = CHROMIUM.lock().unwrap_or_else(|e| e.into_inner());
    let Some((node, chromium)) = support::node::or_skip(
        "cesium_loads_a_city_built_in_tiles_through_its_root_tileset",
        support::node::node_with(&["cesium", "puppeteer-core"])
            .and_then(|n| Ok((n, support::node::chromium()?))),
    ) else {
        return;
    };
    let (fp, st) = (
        Path::new("data/helsinki/buildings.shp"),
        Path::new("data/helsinki/streets_blockclass.shp"),
    );
    let work = tempfile::tempdir().unwrap();
    let jobs = work.path().join("jobs");
    let p = plan(
        fp,
        st,
        &PlanOptions {
            max_buildings: 100,
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let plan_path = write_plan(&p, &jobs).unwrap();
    assert!(p.tiles.len() >= 4, "{} tiles", p.tiles.len());
    let opts = TileOptions {
        tileset: Some(TilesetOptions::default()),
        ..TileOptions::default()
    };
    for t in 0..p.tiles.len() {
        run_tile(&plan_path, t, &opts).unwrap();
    }
    let (index, _) = merge(&jobs).unwrap();
    let transform = index.tiles[0]
        .tileset
        .as_ref()
        .and_then(|t| t.transform)
        .expect("Helsinki is georeferenced");

    // Our rendering of the same cameras, from the whole city in one process.
    let source = CitySource::parse(fp, Some(st.into()), None, &[], 0).unwrap();
    let scene = Scene::load(
        &source,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let (views, centre) = views_of(&scene);
    let out = support::node::screenshot_dir("tileset-cesium");
    let ours = our_images(&scene, &views, centre, &out, "jobs_");
    let page = Page {
        dir: &jobs,
        url: None,
        local_to_ecef: Some(transform),
        prefix: "jobs_",
    };
    let report = run_page((&node, &chromium), &page, &views, centre, work.path(), &out);
    let errors = report["page_errors"].as_array().unwrap();
    assert!(errors.is_empty(), "page errors: {errors:#?}");
    let files: Vec<&str> = report["requests"]["tileset_files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    // The root, and through it tiles' own tilesets and their contents.
    assert!(files.contains(&"tileset.json"), "{files:?}");
    let tile_sets = files
        .iter()
        .filter(|f| f.starts_with("tiles/tile_") && f.ends_with("_tileset/tileset.json"))
        .count();
    assert!(
        tile_sets >= 2,
        "{tile_sets} tiles' tilesets requested: {files:?}"
    );
    assert!(
        files
            .iter()
            .any(|f| f.starts_with("tiles/tile_") && f.contains("_tileset/tiles/")),
        "no tile content requested: {files:?}"
    );
    let missing = report["requests"]["missing"].as_array().unwrap();
    assert!(
        missing
            .iter()
            .all(|m| !files.contains(&m.as_str().unwrap())),
        "tileset files missing: {missing:?}"
    );
    for (k, (name, _)) in views.iter().enumerate() {
        let v = &report["views"][k];
        assert_eq!(
            v["tiles_loaded"], true,
            "{name}: not every tile loaded: {v}"
        );
        assert!(
            v["failed"].as_array().unwrap().is_empty(),
            "{name}: tiles failed: {}",
            v["failed"]
        );
        let drawn = v["visible"].as_array().unwrap();
        let leaves = drawn
            .iter()
            .filter(|s| s.as_str().unwrap().starts_with("buildings"))
            .count();
        assert!(!drawn.is_empty(), "{name}: nothing drawn: {v}");
        if *name == "near" {
            assert!(leaves > 0, "near: no leaf drawn: {v}");
        }
        println!(
            "jobs {name}: {} tiles loaded, {} drawn ({leaves} building leaves)",
            v["loaded"].as_array().unwrap().len(),
            drawn.len()
        );
        let theirs = image::open(out.join(format!("jobs_cesium_{name}.png")))
            .unwrap()
            .to_rgba8();
        let agree = sky_agreement(&ours[k], &theirs);
        println!("jobs {name}: sky/not-sky agreement with our rendering {agree:.3}");
        let need = if *name == "far" { 0.9 } else { 0.98 };
        assert!(agree > need, "jobs {name}: sky agreement {agree}");
    }
}
