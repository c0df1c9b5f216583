//! Replays the inputs of the importers' cargo-fuzz targets on the stable toolchain: every file
//! under `tests/fuzz/regressions/TARGET/` (inputs that once crashed, hung or broke a property)
//! and `tests/fuzz/seeds/TARGET/` goes through the same check as the target
//! (`blockwalk_importers::fuzzing`), which panics when a property breaks.

use blockwalk_importers::fuzzing::{self, Outcome};
use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fuzz")
}

/// The committed inputs of `target`, sorted.
fn inputs(target: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for kind in ["regressions", "seeds"] {
        let d = fuzz_dir().join(kind).join(target);
        if let Ok(rd) = std::fs::read_dir(&d) {
            out.extend(rd.map(|e| e.unwrap().path()).filter(|p| p.is_file()));
        }
    }
    out.sort();
    out
}

fn replay(target: &str, check: impl Fn(&Path, &[u8]) -> Vec<Outcome>) -> usize {
    let dir = tempfile::tempdir().unwrap();
    let files = inputs(target);
    for f in &files {
        let data = std::fs::read(f).unwrap();
        let out = check(dir.path(), &data);
        eprintln!("{target} {}: {out:?}", f.display());
    }
    files.len()
}

#[test]
fn shapefile_inputs() {
    replay("shapefile", |d, b| vec![fuzzing::check_shapefile(d, b)]);
}

#[test]
fn geojson_inputs() {
    assert!(replay("geojson", |d, b| vec![fuzzing::check_geojson(d, b)]) >= 2);
}

#[test]
fn gpkg_inputs() {
    replay("gpkg", fuzzing::check_gpkg);
}

#[test]
fn osm_pbf_inputs() {
    replay("osm_pbf", fuzzing::check_osm);
}

#[test]
fn wkb_inputs() {
    replay("wkb", |_, b| vec![fuzzing::check_wkb(b)]);
}

#[test]
fn prj_inputs() {
    assert!(replay("prj", |_, b| vec![fuzzing::check_prj(b)]) >= 4);
}

/// The checks themselves tell a good input from a bad one.
#[test]
fn checks_see_good_and_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/bubenec");
    let part = |e: &str| std::fs::read(data.join(format!("streets.{e}"))).unwrap();
    let (shp, shx, dbf, prj) = (part("shp"), part("shx"), part("dbf"), part("prj"));
    let whole = fuzzing::join_parts(&[&shp, &shx, &dbf, &prj]);
    match fuzzing::check_shapefile(dir.path(), &whole) {
        Outcome::Read { features, refused } => assert!(features > 10 && refused == 0),
        o => panic!("{o:?}"),
    }
    // No .dbf: refused, naming the file.
    let no_dbf = fuzzing::join_parts(&[&shp, &shx, b"", &prj]);
    match fuzzing::check_shapefile(dir.path(), &no_dbf) {
        Outcome::Refused(m) => assert!(m.contains("layer.shp") && m.contains("dbf"), "{m}"),
        o => panic!("{o:?}"),
    }
    assert!(matches!(
        fuzzing::check_geojson(dir.path(), b"{\"type\":"),
        Outcome::Refused(_)
    ));
    assert!(matches!(fuzzing::check_prj(&prj), Outcome::Read { .. }));
    assert!(matches!(
        fuzzing::check_prj(b"GEOGCS["),
        Outcome::Refused(_)
    ));
    assert!(matches!(
        fuzzing::check_wkb(b"GP\0\x01"),
        Outcome::Refused(_)
    ));
}
