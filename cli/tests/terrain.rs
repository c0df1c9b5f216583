//! `--dem` end to end: a city generated on the Nepal grid, imported onto it (the ground report in
//! `--json`), measured by `blockwalk terrain`; and the refusals (a synthetic grid, a bad rule).

#[path = "../../tests/support/mod.rs"]
mod support;
use support::data::shared_data;
use support::skip::{or_skip, Need};

fn blockwalk(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk")
}

#[test]
fn a_city_generated_on_a_dem_is_imported_onto_it_and_its_terrain_measured() {
    let dem = shared_data("dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif");
    let Some(dem) = or_skip(
        Need::Dem,
        "a_city_generated_on_a_dem_is_imported_onto_it_and_its_terrain_measured",
        if dem.is_file() {
            Ok(dem)
        } else {
            Err("../shared/data/dem absent".into())
        },
    ) else {
        return;
    };
    let dem = dem.to_str().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let city = tmp.path().join("nep");
    let c = city.to_str().unwrap();
    let o = blockwalk(&[
        "generate",
        "--buildings",
        "150",
        "--seed",
        "2",
        "--on-dem",
        dem,
        "--centre",
        "333000,3110000",
        "-o",
        c,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let prj = std::fs::read_to_string(city.join("buildings.prj")).unwrap();
    assert!(prj.contains("45N"), "the DEM's CRS: {prj}");

    let glb = tmp.path().join("nep.glb");
    let o = blockwalk(&[
        "import",
        c,
        "--dem",
        dem,
        "--base",
        "p10",
        "--json",
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let g = &v["ground"];
    assert_eq!(g["placed"], 150);
    assert_eq!(g["rule"], "p10");
    assert_eq!(g["refused_count"], 0);
    let (lo, hi) = (
        g["base_m"]["min"].as_f64().unwrap(),
        g["base_m"]["max"].as_f64().unwrap(),
    );
    assert!(
        1000.0 < lo && lo <= hi && hi < 6400.0,
        "bases {lo}..{hi} m on the Nepal grid"
    );
    assert!(g["terrain"]["source"]
        .as_str()
        .unwrap()
        .ends_with("nepal_30m_32645.tif"));
    // The .glb's JSON chunk: length at bytes 12..16, the JSON from byte 20.
    let bytes = std::fs::read(&glb).unwrap();
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + n]).unwrap();
    assert!(
        doc["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n["name"] == "terrain"),
        "the terrain node"
    );

    let o = blockwalk(&[
        "terrain", c, "--dem", dem, "--route", "orbit", "--frames", "3", "--tau", "1,8", "--size",
        "96x54", "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for r in rows {
        let tau = r["tau_px"].as_f64().unwrap();
        assert!(r["declared_px_max"].as_f64().unwrap() <= tau * (1.0 + 1e-9));
        assert_eq!(r["frames"], 3);
    }
    assert!(
        rows[1]["triangles_mean"].as_f64().unwrap() <= rows[0]["triangles_mean"].as_f64().unwrap(),
        "a larger τ draws no more"
    );
}

#[test]
fn dem_options_are_checked_and_a_synthetic_grid_is_refused() {
    let o = blockwalk(&["import", "synthetic:2x2", "--dem", "x.tif"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("synthetic grid has no CRS"));
    let o = blockwalk(&[
        "import",
        "synthetic:2x2",
        "--dem",
        "x.tif",
        "--base",
        "p150",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("expected min or pNN"));
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("none.tif");
    let c = tmp.path().join("c");
    let o = blockwalk(&["generate", "--buildings", "20", "-o", c.to_str().unwrap()]);
    assert!(o.status.success());
    let o = blockwalk(&[
        "import",
        c.to_str().unwrap(),
        "--dem",
        missing.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("none.tif"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}
