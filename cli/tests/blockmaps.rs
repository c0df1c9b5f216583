//! `blockwalk blockmaps` end to end: the figures it prints and the lists it writes.

#[path = "../../tests/support/mod.rs"]
mod support;
use support::data::data;

#[test]
fn the_blockmaps_command_prints_the_figures_and_writes_the_lists() {
    let out = std::env::temp_dir().join(format!("blockwalk-blockmaps-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(["blockmaps"])
        .arg(data("bubenec_utm33n/buildings.shp"))
        .arg("--streets")
        .arg(data("bubenec_utm33n/streets.shp"))
        .args(["--check", "100", "--json", "-o"])
        .arg(&out)
        .output()
        .expect("run blockwalk");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    for key in [
        "maps",
        "bytes",
        "build_s",
        "eps_declared_max",
        "eps_measured_max",
        "bound_violations",
        "thin_features",
        "thin_by_kind",
        "coverage_error_max",
        "coverage_error_p95",
        "coverage_over_target",
    ] {
        assert!(
            s.get(key).is_some_and(|v| !v.is_null()),
            "{key} missing: {s}"
        );
    }
    // The lists stay in the file the summary names, complete.
    assert!(s.get("thin").is_none());
    let full: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s["details"].as_str().unwrap()).unwrap())
            .unwrap();
    assert_eq!(full["thin"].as_array().unwrap().len(), s["thin_features"]);
    let by_kind: u64 = s["thin_by_kind"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(Some(by_kind), s["thin_features"].as_u64());
    // Every map checked (`--check` above the map count): one check per map.
    assert_eq!(full["checks"].as_array().unwrap().len(), s["maps"]);
    assert_eq!(s["bound_violations"], 0);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn the_blockmaps_command_builds_parents_from_children() {
    let out = tempfile::tempdir().unwrap();
    let run = |parents: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
            .args(["blockmaps"])
            .arg(data("helsinki/buildings.shp"))
            .arg("--streets")
            .arg(data("helsinki/streets_blockclass.shp"))
            .args(["--parents", parents, "--check", "100", "--json", "-o"])
            .arg(out.path())
            .output()
            .expect("run blockwalk")
    };
    let o = run("children");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert!(s["parents_from_children"].as_u64().unwrap() > 0, "{s}");
    assert_eq!(s["measured_over_derived"], 0, "{s}");
    assert!(s["eps_derived_max"].as_f64().unwrap() > 0.0);
    assert_eq!(s["bound_violations"], 0, "{s}");
    eprintln!(
        "Helsinki, parents from children, one view per map: coverage error max {}, mean {}",
        s["coverage_error_max"], s["coverage_error_mean"]
    );
    let o = run("polygons");
    assert!(o.status.success());
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["parents_from_children"], 0);
    eprintln!(
        "Helsinki, parents from polygons, one view per map: coverage error max {}, mean {}",
        s["coverage_error_max"], s["coverage_error_mean"]
    );
    let o = run("kids");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("kids") && err.contains("children"), "{err}");
}
