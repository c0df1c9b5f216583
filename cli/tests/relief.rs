//! `blockwalk relief`: the report's JSON agrees with itself (nodes per level, coverage against
//! the target, every node below it listed), the human summary names what was built, and bad
//! settings are refused naming the setting.

use std::process::Command;

fn run(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(args)
        .output()
        .expect("run blockwalk");
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

const HELSINKI: [&str; 3] = [
    "data/helsinki/buildings.shp",
    "--streets",
    "data/helsinki/streets_blockclass.shp",
];

#[test]
fn helsinki_report_agrees_with_itself() {
    let mut args = vec!["relief"];
    args.extend(HELSINKI);
    args.extend(["--relief-stop", "all", "--relief-texel", "1", "--json"]);
    let (ok, out, err) = run(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let s = &v["summary"];
    let nodes = s["nodes"].as_u64().unwrap();
    assert_eq!(
        nodes,
        s["tree_nodes"].as_u64().unwrap(),
        "every node mapped"
    );
    let per_level: u64 = v["levels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["nodes"].as_u64().unwrap())
        .sum();
    assert_eq!(per_level, nodes);
    let target = v["options"]["coverage_target"].as_f64().unwrap();
    let below = s["below_target"].as_array().unwrap();
    assert_eq!(
        s["coverage_min"].as_f64().unwrap() < target,
        !below.is_empty(),
        "{s}"
    );
    assert!(s["obliques_max"].as_u64().unwrap() <= 16);
    assert!(s["bytes"].as_u64().unwrap() > 0);
    let e = s["coverage_error_max"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&e), "{e}");
    assert_eq!(v["formulas"]["nodes"].as_u64(), Some(nodes));
    assert!(v["import"].is_object());
    // The human summary, with the competitive stop: fewer nodes, named.
    let mut args = vec!["relief"];
    args.extend(HELSINKI);
    let (ok, out, err) = run(&args);
    assert!(ok, "{err}");
    assert!(out.contains("nodes mapped (competitive)"), "{out}");
    assert!(out.contains("| level | nodes |"), "{out}");
}

#[test]
fn bad_settings_are_refused_by_name() {
    for (flag, value, says) in [
        ("--relief-map-size", "100", "map_size"),
        ("--relief-coverage", "0", "coverage_target"),
        ("--relief-coverage", "1.5", "coverage_target"),
        ("--relief-texel", "-1", "texel_m"),
        ("--relief-gap", "-1", "gap_m"),
        ("--relief-flat-px", "-2", "flat_px"),
    ] {
        let arg = format!("{flag}={value}");
        let (ok, _, err) = run(&["relief", "data/bubenec/buildings.shp", &arg]);
        assert!(!ok && err.contains(says), "{flag} {value}: {err}");
    }
}
