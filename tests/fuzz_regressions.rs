//! Replays the inputs of the library's cargo-fuzz targets on the stable toolchain: every file
//! under `tests/fuzz/regressions/TARGET/` (inputs that once crashed, hung or broke a property)
//! and `tests/fuzz/seeds/TARGET/` goes through the same check as the target
//! (`blockwalk::fuzzing`), which panics when a property breaks.

use blockwalk::fuzzing::{self, Outcome};
use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz")
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

fn replay(target: &str, check: impl Fn(&Path, &[u8]) -> Outcome) -> Vec<Outcome> {
    let dir = tempfile::tempdir().unwrap();
    inputs(target)
        .iter()
        .map(|f| {
            let out = check(dir.path(), &std::fs::read(f).unwrap());
            eprintln!("{target} {}: {out:?}", f.display());
            out
        })
        .collect()
}

#[test]
fn tile_inputs() {
    let out = replay("tile", fuzzing::check_tile);
    assert!(
        out.iter()
            .filter(|o| matches!(o, Outcome::Made(n) if *n > 0))
            .count()
            >= 3,
        "the seed record (zlib and raw) and hierarchy are read: {out:?}"
    );
}

#[test]
fn route_inputs() {
    replay("route", fuzzing::check_route);
    // The bundled example routes resolve.
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/routes");
    for e in std::fs::read_dir(examples).unwrap() {
        let p = e.unwrap().path();
        let out = fuzzing::check_route(dir.path(), &std::fs::read(&p).unwrap());
        assert!(
            matches!(out, Outcome::Made(n) if n > 0),
            "{}: {out:?}",
            p.display()
        );
    }
}

#[test]
fn plan_inputs() {
    let out = replay("plan", fuzzing::check_plan);
    assert!(
        out.contains(&Outcome::Made(1)),
        "the seed plan is read: {out:?}"
    );
}

#[test]
fn repair_inputs() {
    replay("repair", |_, b| fuzzing::check_repair(b));
}

#[test]
fn faces_inputs() {
    replay("faces", |_, b| fuzzing::check_faces(b));
}

#[test]
fn extrude_inputs() {
    replay("extrude", |_, b| fuzzing::check_extrude(b));
}

/// i16 eighths of a metre, as `fuzzing::Decoder` reads them.
fn ring(points: &[(i16, i16)]) -> Vec<u8> {
    let mut out = vec![points.len() as u8];
    for (x, y) in points {
        out.extend((x * 8).to_le_bytes());
        out.extend((y * 8).to_le_bytes());
    }
    out
}

/// The checks themselves see what they should: a square is one part, a bow tie two, a grid of
/// three by three lines four faces, a walled square a prism, a broken plan a refusal.
#[test]
fn checks_see_good_and_bad_inputs() {
    let square = [(0, 0), (20, 0), (20, 10), (0, 10)];
    let mut poly = vec![0u8];
    poly.extend(ring(&square));
    assert_eq!(fuzzing::check_repair(&poly), Outcome::Made(1));
    let mut bowtie = vec![0u8];
    bowtie.extend(ring(&[(0, 0), (10, 10), (10, 0), (0, 10)]));
    assert_eq!(fuzzing::check_repair(&bowtie), Outcome::Made(2));
    let mut line = vec![0u8];
    line.extend(ring(&[(0, 0), (10, 0)]));
    assert!(matches!(fuzzing::check_repair(&line), Outcome::Refused(_)));
    // 3 × 3 lines: 4 faces. Each line is a point count − 1 byte and its points.
    let mut grid = vec![1u8];
    for k in [0i16, 10, 20] {
        for l in [[(k, -1), (k, 21)], [(-1, k), (21, k)]] {
            let mut r = ring(&l);
            r[0] = 1;
            grid.extend(r);
        }
    }
    assert_eq!(fuzzing::check_faces(&grid), Outcome::Made(4));
    // A 20 × 10 m footprint, 12 m tall: 2 × 4 wall and 2 × 2 cap triangles.
    let mut b = poly.clone();
    b.extend([12, 0]);
    assert_eq!(fuzzing::check_extrude(&b), Outcome::Made(12));
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        fuzzing::check_plan(dir.path(), b"{\"format\": \"blockwalk-jobs-plan/1\"}"),
        Outcome::Refused(m) if m.contains("plan.json")
    ));
}
