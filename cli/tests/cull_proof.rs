//! `blockwalk cull-proof`: a short run on Bubeneč (summary and `--json`), and its refusals.

#[path = "../../tests/support/mod.rs"]
mod support;
use std::process::{Command, Output};
use support::data::data;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .arg("cull-proof")
        .args(args)
        .output()
        .expect("run blockwalk")
}

fn bubenec() -> String {
    format!(
        "{},{}",
        data("bubenec/buildings.shp").display(),
        data("bubenec/streets.shp").display()
    )
}

#[test]
fn a_short_run_reports_every_route_and_no_false_cull() {
    let city = bubenec();
    let o = run(&[
        &city,
        "--frames",
        "3",
        "--routes",
        "street,corners",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(j["frames"], 6, "{j}");
    assert_eq!(j["false_culls"], 0, "{j}");
    let routes = j["cities"][0]["routes"].as_array().unwrap();
    let names: Vec<&str> = routes
        .iter()
        .map(|r| r["route"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["street", "corners"]);
    // 5 structures × 3 cull maps per route.
    assert!(routes
        .iter()
        .all(|r| r["tallies"].as_array().unwrap().len() == 15));

    let o = run(&[&city, "--frames", "2", "--routes", "corners"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("bubenec: 144 buildings"), "{out}");
    assert!(out.contains("corners"), "{out}");
    assert!(out.contains("0 false culls"), "{out}");
}

#[test]
fn bad_arguments_are_refused_with_the_reason() {
    let city = bubenec();
    for (args, needle) in [
        (vec![city.as_str(), "--frames", "0"], "0 frames"),
        (vec![city.as_str(), "--frames", "2,3"], "one per city"),
        (vec![city.as_str(), "--samples", "0"], "samples"),
        (vec![city.as_str(), "--resolutions", "0"], "out of range"),
        (vec![city.as_str(), "--oracle", "3000x54"], "8192"),
        (vec!["a.shp,"], "FOOTPRINTS,STREETS"),
        (
            vec![city.as_str(), "--routes", "nowhere"],
            "not a route name",
        ),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
