//! Parameters out of range are refused when the command line is read, naming the flag and the
//! range, before any data is loaded.

fn refused(args: &[&str], wants: &[&str]) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} was accepted: {err}");
    assert_eq!(o.status.code(), Some(2), "{args:?}: a usage error: {err}");
    for w in wants {
        assert!(err.contains(w), "{args:?}: {w:?} missing from: {err}");
    }
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

#[test]
fn out_of_range_values_are_refused_with_the_range() {
    // The city does not exist: a refusal must come from the value, not from loading.
    let city = "no-such-city/buildings.shp";
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap", "1e9"],
        &["--snap", "out of range", "0.001 to 5"],
    );
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap=-1"],
        &["--snap", "0.001 to 5"],
    );
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap", "0"],
        &["--snap", "0.001 to 5", "below 1 mm"],
    );
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap", "NaN"],
        &["--snap", "0.001 to 5"],
    );
    refused(
        &["walk", city, "--out", "w", "--image-every", "0"],
        &["--image-every", "at least 1"],
    );
    refused(
        &["generate", "--buildings", "0", "-o", "g"],
        &["--buildings", "at least 1"],
    );
    refused(
        &["blockmaps", city, "-o", "m", "--ao", "--ao-radius", "1e6"],
        &["--ao-radius", "out of range", "200"],
    );
    refused(
        &["blockmaps", city, "-o", "m", "--ao-radius", "0"],
        &["--ao-radius", "above 0"],
    );
    refused(
        &["blockmaps", city, "-o", "m", "--check", "0"],
        &["--check", "at least 1"],
    );
    refused(
        &["blockmaps", city, "-o", "m", "--leaf-blocks", "0"],
        &["--leaf-blocks", "at least 1"],
    );
}

#[test]
fn values_in_range_pass_the_parser() {
    // In range, the command goes on to read the (missing) city and fails there, naming it.
    for args in [
        &[
            "blocks",
            "no-such-city/buildings.shp",
            "-o",
            "b.geojson",
            "--snap",
            "5",
        ][..],
        &[
            "blockmaps",
            "no-such-city/buildings.shp",
            "-o",
            "m",
            "--check",
            "1",
            "--leaf-blocks",
            "1",
            "--ao-radius",
            "200",
        ][..],
    ] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
            .args(args)
            .output()
            .expect("run blockwalk");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("no-such-city"), "{args:?}: {err}");
    }
}

fn run(args: &[&std::ffi::OsStr]) -> (std::process::ExitStatus, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk");
    (o.status, String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
fn demo_astana_on_another_citys_folder_is_refused_naming_the_count() {
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/helsinki");
    for ext in ["shp", "shx", "dbf", "prj"] {
        std::fs::copy(
            data.join(format!("buildings.{ext}")),
            dir.path().join(format!("buildings.{ext}")),
        )
        .unwrap();
        std::fs::copy(
            data.join(format!("streets_blockclass.{ext}")),
            dir.path().join(format!("streets_blockclass.{ext}")),
        )
        .unwrap();
    }
    let out = dir.path().join("out");
    let (status, err) = run(&[
        "demo".as_ref(),
        "--astana".as_ref(),
        dir.path().as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!status.success(), "{err}");
    assert!(err.contains("not Astana's 32056"), "{err}");
    assert!(err.contains("buildings.shp"), "{err}");
    assert!(!out.join("astana.glb").exists());
}

#[test]
fn jobs_plan_on_a_missing_folder_says_it_does_not_exist() {
    let dir = tempfile::tempdir().unwrap();
    let gone = dir.path().join("no-such-city");
    let (status, err) = run(&[
        "jobs".as_ref(),
        "plan".as_ref(),
        gone.as_os_str(),
        "-o".as_ref(),
        dir.path().join("plan").as_os_str(),
    ]);
    assert!(!status.success(), "{err}");
    assert!(
        err.contains("no-such-city: no such file or folder"),
        "{err}"
    );
    assert!(!err.contains("give a .shp"), "{err}");
}
