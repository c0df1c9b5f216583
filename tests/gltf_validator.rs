//! Every `.glb` that the bundled data exports, checked by the Khronos glTF-Validator (npm
//! `gltf-validator`, run by `tests/tools/validate_gltf.js` under Node): 0 errors and 0 warnings.
//!
//! Needs `node` and `npm ci --prefix tests/tools` (what `.ci/run` does). Without them the tests
//! skip loudly, unless the validators are required (`BLOCKWALK_REQUIRE=validators`, as `.ci/run`
//! sets), where they fail.

use std::path::Path;

use blockwalk::city::export::glb_bytes;
use blockwalk::city::extrude::try_extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::City;
use serde_json::Value;
use support::data::load_city;

mod support;

/// `Some(node)` when node and the validator are installed; otherwise a loud skip and
/// `None`, or a failure when the validators are required.
fn validator_or_skip(test: &str) -> Option<String> {
    support::node::or_skip(test, support::node::node_with(&["gltf-validator"]))
}

/// The validator's JSON report on one file.
fn validate(node: &str, file: &Path) -> Value {
    support::node::run_json(node, "validate_gltf.js", file)
}

fn counts(report: &Value) -> [u64; 4] {
    let i = &report["issues"];
    ["numErrors", "numWarnings", "numInfos", "numHints"].map(|k| i[k].as_u64().unwrap())
}

fn glb_of(city: &City) -> Vec<u8> {
    let (meshes, errors) = try_extrude_city(city);
    assert!(errors.is_empty(), "{}: {errors:?}", city.name);
    glb_bytes(city, &meshes).unwrap().0
}

/// The messages of a report, for failure output.
fn messages(report: &Value) -> Vec<String> {
    report["issues"]["messages"]
        .as_array()
        .map(|m| {
            m.iter()
                .take(20)
                .map(|x| format!("{} {} {}", x["code"], x["pointer"], x["message"]))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn every_bundled_export_is_valid_gltf() {
    let Some(node) = validator_or_skip("every_bundled_export_is_valid_gltf") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let gen_dir = dir.path().join("generated");
    let g = generate_city(&GenerateParams {
        buildings: 500,
        seed: 5,
        ..Default::default()
    })
    .unwrap();
    write_city(&g, &gen_dir).unwrap();
    let cities = [
        (
            "bubenec",
            load_city(
                Path::new("data/bubenec/buildings.shp"),
                Some("data/bubenec/streets.shp"),
            ),
        ),
        (
            "bubenec_utm33n",
            load_city(Path::new("data/bubenec_utm33n/buildings.shp"), None),
        ),
        (
            "helsinki",
            load_city(Path::new("data/helsinki/buildings.shp"), None),
        ),
        (
            "helsinki_building_parts",
            load_city(Path::new("data/helsinki/building_parts.shp"), None),
        ),
        ("generated", load_city(&gen_dir.join("buildings.shp"), None)),
    ];
    for (name, city) in &cities {
        let file = dir.path().join(format!("{name}.glb"));
        std::fs::write(&file, glb_of(city)).unwrap();
        let report = validate(&node, &file);
        let [e, w, i, h] = counts(&report);
        println!("{name}.glb: {e} errors, {w} warnings, {i} infos, {h} hints");
        assert_eq!((e, w), (0, 0), "{name}.glb: {:#?}", messages(&report));
        // The validator read the whole asset: every building's mesh is there.
        let meshes = report["info"]["drawCallCount"].as_u64().unwrap();
        let expected = city.buildings.len() as u64;
        assert!(
            meshes > 0 && meshes <= expected,
            "{name}: {meshes} draw calls for {expected} buildings"
        );
    }
}

/// Rewrites a `.glb`'s JSON chunk (the binary chunk kept as it is).
fn with_json(glb: &[u8], edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let u32_at = |o: usize| u32::from_le_bytes(glb[o..o + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let mut doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    edit(&mut doc);
    let mut json = serde_json::to_vec(&doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin = &glb[20 + json_len..];
    let total = 12 + 8 + json.len() + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&glb[0..8]);
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(bin);
    out
}

#[test]
fn the_validator_is_not_vacuous() {
    let Some(node) = validator_or_skip("the_validator_is_not_vacuous") else {
        return;
    };
    let city = load_city(Path::new("data/helsinki/buildings.shp"), None);
    let glb = glb_of(&city);
    // A POSITION accessor whose declared maximum is not the data's: an error the validator
    // must report (the specification requires exact bounds).
    let bad = with_json(&glb, |doc| {
        let accessors = doc["accessors"].as_array_mut().unwrap();
        let pos = accessors
            .iter_mut()
            .find(|a| a.get("max").is_some())
            .unwrap();
        let x = pos["max"][0].as_f64().unwrap();
        pos["max"][0] = serde_json::json!(x + 1.0);
    });
    let dir = tempfile::tempdir().unwrap();
    let good_file = dir.path().join("good.glb");
    let bad_file = dir.path().join("bad.glb");
    std::fs::write(&good_file, &glb).unwrap();
    std::fs::write(&bad_file, bad).unwrap();
    assert_eq!(counts(&validate(&node, &good_file))[..2], [0, 0]);
    let report = validate(&node, &bad_file);
    assert!(counts(&report)[0] > 0, "{:#?}", messages(&report));
    assert!(
        messages(&report)
            .iter()
            .any(|m| m.contains("ACCESSOR_MAX_MISMATCH")),
        "{:#?}",
        messages(&report)
    );
}

/// Helsinki on a terrain (20 m cells with a hole): the `.glb` read back with the `gltf` crate
/// holds a node `terrain` whose mesh has the input's vertices (each at its local position, to
/// the f32 rounding), its triangles, unit normals pointing up, its accessor bounds the input's,
/// and a material of its own; the buildings are still there. Then the Khronos validator: 0 errors,
/// 0 warnings.
#[test]
fn a_glb_with_terrain_reads_back_and_is_valid_gltf() {
    use blockwalk::city::export::glb_bytes_with_terrain;
    let (city, tin) = support::terrain::terrain_city(
        &load_city(Path::new("data/helsinki/buildings.shp"), None),
        20.0,
    );
    let (meshes, errors) = try_extrude_city(&city);
    assert!(errors.is_empty());
    let (bytes, stats) = glb_bytes_with_terrain(&city, &meshes, Some(&tin)).unwrap();
    assert_eq!(stats.terrain_triangles, tin.triangles.len());
    assert_eq!(stats.nodes, city.buildings.len() + 1);
    let (doc, buffers, _) = gltf::import_slice(&bytes).expect("import");
    let root = doc.scenes().next().unwrap().nodes().next().unwrap();
    assert_eq!(root.children().count(), city.buildings.len() + 1);
    let terrain: Vec<_> = root
        .children()
        .filter(|n| n.name() == Some("terrain"))
        .collect();
    assert_eq!(terrain.len(), 1, "one terrain node");
    let mesh = terrain[0].mesh().unwrap();
    assert_eq!(mesh.name(), Some("terrain"));
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|buf| Some(&buffers[buf.index()]));
    let pos: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    assert_eq!(pos.len(), tin.vertices.len(), "terrain vertex count");
    // Every vertex where the input puts it: glTF (x, z, −y) of world − origin, to f32.
    let o = city.frame.origin;
    let mut worst = 0.0f64;
    for (p, w) in pos.iter().zip(&tin.vertices) {
        let local = glam::DVec3::new(p[0] as f64, -(p[2] as f64), p[1] as f64);
        worst = worst.max((local - (*w - o)).abs().max_element());
    }
    assert!(worst < 1e-3, "a terrain vertex {worst} m off");
    let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(idx, tin.triangles.concat());
    let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
    assert_eq!(normals.len(), pos.len());
    assert!(normals
        .iter()
        .all(|n| (glam::Vec3::from(*n).length() - 1.0).abs() < 1e-5 && n[1] > 0.5));
    // The accessor's bounds are the input's bounds, in the local frame.
    let (lo, hi) = tin.bounds().unwrap();
    let (lo, hi) = (lo - o, hi - o);
    let acc = prim.get(&gltf::Semantic::Positions).unwrap();
    let f = |v: serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (amin, amax) = (f(acc.min().unwrap()), f(acc.max().unwrap()));
    let want_min = [lo.x, hi.z.min(lo.z), -hi.y];
    let want_max = [hi.x, hi.z.max(lo.z), -lo.y];
    for k in 0..3 {
        assert!(
            (amin[k] - want_min[k]).abs() < 1e-3,
            "min {k}: {amin:?} vs {want_min:?}"
        );
        assert!(
            (amax[k] - want_max[k]).abs() < 1e-3,
            "max {k}: {amax:?} vs {want_max:?}"
        );
    }
    let mat = prim.material();
    assert_eq!(mat.name(), Some("terrain"));
    let building_mat = root.children().next().unwrap().mesh().unwrap();
    let building_mat = building_mat.primitives().next().unwrap().material();
    assert_ne!(
        mat.pbr_metallic_roughness().base_color_factor(),
        building_mat.pbr_metallic_roughness().base_color_factor()
    );

    let Some(node) = validator_or_skip("a_glb_with_terrain_reads_back_and_is_valid_gltf") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("helsinki_terrain.glb");
    std::fs::write(&file, &bytes).unwrap();
    let report = validate(&node, &file);
    let [e, w, i, h] = counts(&report);
    println!(
        "helsinki_terrain.glb: {} bytes, {} terrain triangles, {} vertices: {e} errors, {w} warnings, {i} infos, {h} hints",
        bytes.len(),
        tin.triangles.len(),
        tin.vertices.len()
    );
    assert_eq!((e, w), (0, 0), "{:#?}", messages(&report));
    assert_eq!(
        report["info"]["drawCallCount"].as_u64().unwrap(),
        city.buildings.len() as u64 + 1
    );
}
