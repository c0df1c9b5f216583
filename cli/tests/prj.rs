//! A `.prj` that cannot be used: the error says how to state the CRS, and `--crs` really
//! overrides it.

#[test]
fn a_garbage_prj_names_the_override_and_crs_overrides_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/bubenec_utm33n");
    for ext in ["shp", "shx", "dbf"] {
        std::fs::copy(
            data.join(format!("buildings.{ext}")),
            dir.path().join(format!("buildings.{ext}")),
        )
        .unwrap();
    }
    std::fs::write(dir.path().join("buildings.prj"), "metres, probably").unwrap();
    let shp = dir.path().join("buildings.shp");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
            .arg("import")
            .arg(&shp)
            .args(extra)
            .arg("--json")
            .output()
            .expect("run blockwalk")
    };
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("buildings.prj"), "{err}");
    assert!(err.contains("--crs EPSG:XXXX"), "{err}");
    let o = run(&["--crs", "EPSG:32633"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "--crs must override the unreadable .prj: {err}"
    );
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert!(s.to_string().contains("32633"), "{s}");
    assert!(s.to_string().contains("CRS stated"), "{s}");
}
