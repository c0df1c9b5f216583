//! The city arguments `--name` and `--crs`, and the default name of a city folder.

#[path = "../../tests/support/mod.rs"]
mod support;
use std::process::Command;
use support::data::data;

fn import_json(args: &[&std::ffi::OsStr]) -> serde_json::Value {
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .arg("import")
        .args(args)
        .arg("--json")
        .output()
        .expect("run blockwalk");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("one JSON object")
}

#[test]
fn a_city_folder_names_the_city_and_name_replaces_it() {
    let shp = data("bubenec/buildings.shp");
    let j = import_json(&[shp.as_os_str()]);
    assert_eq!(j["name"], "bubenec", "{j}");
    let j = import_json(&[shp.as_os_str(), "--name".as_ref(), "Bubeneč".as_ref()]);
    assert_eq!(j["name"], "Bubeneč", "{j}");
}

#[test]
fn crs_states_the_crs_of_a_shapefile_without_prj() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["shp", "shx", "dbf"] {
        std::fs::copy(
            data(&format!("bubenec/buildings.{ext}")),
            dir.path().join(format!("houses.{ext}")),
        )
        .unwrap();
    }
    let shp = dir.path().join("houses.shp");
    let j = import_json(&[shp.as_os_str()]);
    let crs = j["crs"].as_str().unwrap_or_default().to_string();
    assert!(crs.contains("taken as metres in a local frame"), "{j}");
    let j = import_json(&[shp.as_os_str(), "--crs".as_ref(), "EPSG:3857".as_ref()]);
    let crs = j["crs"].as_str().unwrap_or_default().to_string();
    assert!(crs.contains("EPSG:3857"), "{j}");
    // The same CRS given as the .prj's WKT file.
    let prj = data("bubenec/buildings.prj");
    let j = import_json(&[shp.as_os_str(), "--crs".as_ref(), prj.as_os_str()]);
    assert_eq!(
        j["crs"].as_str().map(|s| s.contains("taken as metres")),
        Some(false),
        "{j}"
    );
}
