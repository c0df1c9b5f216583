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
