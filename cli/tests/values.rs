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
        &["--snap", "out of range", "0 to 5"],
    );
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap=-1"],
        &["--snap", "0 to 5"],
    );
    refused(
        &["blocks", city, "-o", "b.geojson", "--snap", "NaN"],
        &["--snap", "0 to 5"],
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
