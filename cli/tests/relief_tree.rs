//! `blockwalk relief-tree`: the human summary and the JSON agree with the tree's own identities.

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

#[test]
fn bubenec_tree_summary_and_json() {
    let (ok, out, err) = run(&["relief-tree", "data/bubenec/buildings.shp", "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let f = &v["formulas"];
    let levels = v["levels"].as_array().unwrap();
    assert_eq!(levels.len() as u64, v["depth"].as_u64().unwrap() + 1);
    let nodes: u64 = levels.iter().map(|l| l["nodes"].as_u64().unwrap()).sum();
    assert_eq!(nodes, v["nodes"].as_u64().unwrap());
    assert_eq!(f["nodes"], v["nodes"]);
    // Formula (6): I = (T + W − 1) / 3, as the tree counts them.
    let i = f["interior"][0].as_f64().unwrap();
    assert!((i - f["interior"][1].as_f64().unwrap()).abs() < 1e-9, "{f}");
    assert!(v["groups"].as_u64().unwrap() <= v["buildings"].as_u64().unwrap());
    assert!(v["import"].is_object());
    let (ok, out, _) = run(&["relief-tree", "data/bubenec/buildings.shp"]);
    assert!(ok);
    assert!(out.contains("| level | nodes |"), "{out}");
    assert!(out.contains("formula (6)"), "{out}");
    // Parameters are checked: a negative gap is refused, naming it.
    let (ok, _, err) = run(&["relief-tree", "data/bubenec/buildings.shp", "--gap=-1"]);
    assert!(!ok && err.contains("gap_m"), "{err}");
}
