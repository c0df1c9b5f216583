//! `blockwalk tileset` writes compact contents by default and plain ones with `--plain`: the
//! summary (`--json`) says which and states the position error, and every content reads back
//! (the tests' own reader) compressed or not accordingly, with the same triangle count.

#[path = "../../tests/support/mod.rs"]
mod support;

use std::path::Path;
use std::process::Command;

use support::data::data;
use support::glb::Glb;

fn tileset(out: &Path, plain: bool) -> serde_json::Value {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_blockwalk"));
    cmd.arg("tileset")
        .arg(data("bubenec/buildings.shp"))
        .arg("--streets")
        .arg(data("bubenec/streets.shp"))
        .arg("-o")
        .arg(out)
        .arg("--json");
    if plain {
        cmd.arg("--plain");
    }
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn plain_flag_writes_plain_contents_and_the_default_compact_ones() {
    let dir = tempfile::tempdir().unwrap();
    let (p, c) = (dir.path().join("plain"), dir.path().join("compact"));
    let (sp, sc) = (tileset(&p, true), tileset(&c, false));
    assert_eq!(sp["content"], "plain");
    assert_eq!(sc["content"], "compact");
    assert_eq!(sp["position_error_m"], 0.0);
    let err = sc["position_error_m"].as_f64().unwrap();
    assert!(err > 0.0 && err < 1e-3, "{err}");
    assert!(2 * sc["bytes"].as_u64().unwrap() <= sp["bytes"].as_u64().unwrap());
    let mut names: Vec<_> = std::fs::read_dir(p.join("tiles"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert!(names.len() > 2);
    for n in names {
        let a = Glb::read(&p.join("tiles").join(&n));
        let b = Glb::read(&c.join("tiles").join(&n));
        assert!(!a.compressed && b.compressed, "{n:?}");
        assert_eq!(a.indices().len(), b.indices().len(), "{n:?}");
        assert!(b.extras()["position_error_m"].as_f64().unwrap() <= err);
    }
}
