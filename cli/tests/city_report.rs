//! Commands that read a city repeat its import report: refused street and parcel features with
//! their reasons, a fallback from an unusable layer, and the import's warnings (a far outlier).

use std::path::Path;

fn square(lon: f64, lat: f64, d: f64) -> String {
    format!(
        r#"{{"type":"Feature","properties":{{}},"geometry":{{"type":"Polygon","coordinates":[[[{lon},{lat}],[{},{lat}],[{},{}],[{lon},{}],[{lon},{lat}]]]}}}}"#,
        lon + d,
        lon + d,
        lat + d,
        lat + d
    )
}

fn line(coords: &[(f64, f64)]) -> String {
    let c: Vec<String> = coords.iter().map(|(x, y)| format!("[{x},{y}]")).collect();
    format!(
        r#"{{"type":"Feature","properties":{{}},"geometry":{{"type":"LineString","coordinates":[{}]}}}}"#,
        c.join(",")
    )
}

fn collection(features: &[String]) -> String {
    format!(
        r#"{{"type":"FeatureCollection","features":[{}]}}"#,
        features.join(",")
    )
}

fn city(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf, std::path::PathBuf) {
    let (x, y) = (14.40, 50.10);
    let mut fp: Vec<String> = (0..6)
        .map(|i| square(x + 0.0004 * i as f64, y, 0.0002))
        .collect();
    // One building about 4,300 km east of the rest.
    fp.push(square(74.4, 50.1, 0.0002));
    let streets = vec![
        line(&[(x - 0.001, y - 0.001), (x + 0.004, y - 0.001)]),
        line(&[(x + 0.004, y - 0.001), (x + 0.004, y + 0.001)]),
        line(&[(x + 0.004, y + 0.001), (x - 0.001, y + 0.001)]),
        line(&[(x - 0.001, y + 0.001), (x - 0.001, y - 0.001)]),
        // One vertex: refused, counted, with its reason.
        line(&[(x, y)]),
    ];
    // A parcel layer whose only feature is a line, not a polygon: unusable.
    let parcels = vec![line(&[(x, y), (x + 0.001, y)])];
    let paths = (
        dir.join("buildings.geojson"),
        dir.join("streets.geojson"),
        dir.join("parcels.geojson"),
    );
    std::fs::write(&paths.0, collection(&fp)).unwrap();
    std::fs::write(&paths.1, collection(&streets)).unwrap();
    std::fs::write(&paths.2, collection(&parcels)).unwrap();
    paths
}

fn run(args: &[&std::ffi::OsStr]) -> (String, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    (String::from_utf8_lossy(&o.stdout).into_owned(), err)
}

#[test]
fn blocks_reports_refused_street_features_and_the_fallback() {
    let dir = tempfile::tempdir().unwrap();
    let (fp, st, pa) = city(dir.path());
    let base = |json: bool| {
        let mut v: Vec<&std::ffi::OsStr> = vec!["blocks".as_ref(), fp.as_os_str()];
        v.extend(["--streets".as_ref(), st.as_os_str()]);
        v.extend(["--parcels".as_ref(), pa.as_os_str()]);
        if json {
            v.push("--json".as_ref());
        }
        v
    };
    let (human, _) = run(&base(false));
    assert!(
        human.contains("street features: 5 read, 1 refused"),
        "{human}"
    );
    assert!(human.contains("warning:"), "{human}");
    let (json, _) = run(&base(true));
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    let refused = v["import"]["streets_refused"].as_array().unwrap();
    assert_eq!(refused.len(), 1, "{v}");
    assert!(refused[0]["reason"].as_str().unwrap().len() > 3, "{v}");
    assert_eq!(v["import"]["streets_read"], 5);
    assert_eq!(v["import"]["parcels_refused"].as_array().unwrap().len(), 1);
    assert!(
        !v["import"]["warnings"].as_array().unwrap().is_empty(),
        "{v}"
    );
    // Forced to parcels' successor: without streets the unusable parcel layer is said aloud.
    let (human, _) = run(&[
        "blocks".as_ref(),
        fp.as_os_str(),
        "--parcels".as_ref(),
        pa.as_os_str(),
    ]);
    assert!(
        human.contains("blocks from footprints, not parcels: the parcel layer is unusable"),
        "{human}"
    );
}

#[test]
fn blockmaps_and_tileset_repeat_the_import_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let (fp, st, _) = city(dir.path());
    for cmd in ["blockmaps", "tileset"] {
        let out = dir.path().join(cmd);
        let args: Vec<&std::ffi::OsStr> = vec![
            cmd.as_ref(),
            fp.as_os_str(),
            "--streets".as_ref(),
            st.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
        ];
        let (human, _) = run(&args);
        assert!(
            human.contains("lie far from all the others"),
            "{cmd}: {human}"
        );
        let mut with_json = args.clone();
        with_json.push("--json".as_ref());
        let (json, _) = run(&with_json);
        let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
        let warnings = v["import"]["warnings"].as_array().unwrap();
        assert!(
            warnings
                .iter()
                .any(|w| w.as_str().unwrap().contains("lie far from all the others")),
            "{cmd}: {v}"
        );
    }
}
