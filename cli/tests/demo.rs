//! The README's first command in its quick form (`demo --quick`) and a two-frame
//! `farfield-sweep`, run as a user runs them, into a temporary folder: what they write exists and
//! parses, and the figures in it are those the tests of the library check.

#[path = "../../tests/support/mod.rs"]
mod support;
use std::path::Path;
use std::process::Command;
use support::data::data;

fn json(p: &Path) -> serde_json::Value {
    let s = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&s).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn glb(p: &Path) {
    let b = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(&b[0..4], b"glTF", "{}", p.display());
    assert_eq!(
        u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
        b.len(),
        "{}: header length",
        p.display()
    );
}

fn png(p: &Path) -> (u32, u32) {
    let img = image::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    (img.width(), img.height())
}

/// About 30 s in a debug build (the dependencies are optimised) on 2 cores.
#[test]
fn demo_quick_writes_the_models_blocks_maps_and_walk_report() {
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(["demo", "--quick", "--size", "320x180", "--data"])
        .arg(data(""))
        .arg("--out")
        .arg(out.path())
        .output()
        .expect("run blockwalk");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("demo done in"), "{stdout}");
    let d = out.path();
    glb(&d.join("bubenec.glb"));
    glb(&d.join("helsinki.glb"));
    // The blocks the library tests check against momepy and shapely: 7 and 70 street faces.
    for (name, faces) in [("bubenec", 7), ("helsinki", 70)] {
        let fc = json(&d.join(format!("{name}_blocks.geojson")));
        let feats = fc["features"].as_array().unwrap();
        assert!(feats.len() >= faces, "{name}: {} features", feats.len());
        assert!(
            stdout.contains(&format!("{name}: {faces} blocks from Streets")),
            "{stdout}"
        );
        let (w, h) = png(&d.join(format!("{name}_blocks.png")));
        assert!(w > 0 && h > 0);
    }
    let fp = json(&d.join("bubenec_footprints.geojson"));
    assert_eq!(fp["features"].as_array().unwrap().len(), 144);
    // Every map checked, none beyond its bound.
    let maps = json(&d.join("helsinki_maps/blockmaps.json"));
    let n = maps["maps"].as_u64().unwrap();
    assert!(n > 3, "{n} maps");
    assert_eq!(maps["checks"].as_array().unwrap().len() as u64, n);
    assert_eq!(maps["bound_violations"], 0);
    png(&d.join("helsinki_occlusion.png"));
    // The walk: 40 frames, no false cull, a summary row per structure and mode.
    let walk = d.join("helsinki_walk");
    let r = json(&walk.join("report.json"));
    assert_eq!(r["frames"], 40);
    assert_eq!(r["false_culls"], 0, "{}", r["false_culls"]);
    let rows = r["summary"].as_array().unwrap();
    assert!(rows.len() >= 4, "{} summary rows", rows.len());
    for row in rows {
        assert_eq!(row["false_culls"], 0, "{row}");
        assert!(row["seconds_per_frame"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["blocks"].as_f64().unwrap() > 0.0, "{row}");
    }
    let csv = std::fs::read_to_string(walk.join("frames.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(header.starts_with("frame,structure,mode"), "{header}");
    assert_eq!(
        csv.lines().count() - 1,
        40 * rows.len(),
        "one row per frame and row"
    );
    let html = std::fs::read_to_string(walk.join("report.html")).unwrap();
    assert!(html.contains("<html") && html.contains("data:image/png;base64,"));
    assert!(std::fs::read_to_string(walk.join("summary.md"))
        .unwrap()
        .contains('|'));
}

/// A sweep of one configuration over two frames: the files it lists exist, and its row says
/// what the far-field tests check (the bound holds, the coverage error is small).
#[test]
fn a_two_frame_farfield_sweep_writes_its_table_and_row() {
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(["farfield-sweep"])
        .arg(data("helsinki/buildings.shp"))
        .arg("--streets")
        .arg(data("helsinki/streets_blockclass.shp"))
        // Every relief node mapped: the default stop leaves Helsinki's blocks to the meshes.
        .args([
            "--far",
            "blockmaps,relief",
            "--relief-stop",
            "all",
            "--taus",
            "1",
            "--ks",
            "32",
            "--routes",
            "orbit",
            "--frames",
            "2",
            "--size",
            "160x90",
            "--json",
            "--out",
        ])
        .arg(out.path())
        .output()
        .expect("run blockwalk");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(s["frames"], 2);
    for f in s["files"].as_array().unwrap() {
        let p = Path::new(f.as_str().unwrap());
        assert!(p.starts_with(out.path()), "{}", p.display());
        assert!(
            p.metadata().is_ok_and(|m| m.len() > 0),
            "{} missing or empty",
            p.display()
        );
    }
    let rows = s["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2, "(BlockMaps K 32, relief) × τ 1 × orbit");
    for (row, far) in rows.iter().zip(["blockmaps", "relief"]) {
        assert_eq!(row["far"], far, "{row}");
        assert_eq!(row["tau_px"].as_f64(), Some(1.0));
        assert_eq!(row["frames"], 2);
        assert_eq!(row["silhouette_bound_violations"], 0, "{row}");
        assert!(row["far_nodes"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["maps"].as_u64().unwrap() > 0, "{row}");
        let cov = row["coverage_error_max"].as_f64().unwrap();
        assert!((0.0..=0.01).contains(&cov), "{far}: coverage error {cov}");
        assert!(row["hybrid_ms"].as_f64().unwrap() > 0.0 && row["mesh_ms"].as_f64().unwrap() > 0.0);
    }
    assert_eq!(rows[0]["k"].as_u64(), Some(32));
    // Both builds are stated with their bytes and time.
    let builds = s["builds"].as_array().unwrap();
    assert_eq!(builds.len(), 2, "{builds:?}");
    for b in builds {
        assert!(b["bytes"].as_u64().unwrap() > 0 && b["seconds"].as_f64().unwrap() > 0.0);
    }
    // The file matches the printed rows, and the table has one line per row.
    let file = json(&out.path().join("sweep.json"));
    assert_eq!(file["rows"].as_array().map(|a| a.len()), Some(2), "{file}");
    assert_eq!(file["rows"][1]["silhouette_bound_violations"], 0);
    let md = std::fs::read_to_string(out.path().join("sweep.md")).unwrap();
    assert!(md.contains("orbit") && md.contains("relief"), "{md}");
    png(&out.path().join("pareto.png"));
}
