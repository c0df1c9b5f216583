//! Fuzz-style robustness: mutated bytes (bit flips, truncations, insertions, overwritten words)
//! of every real file in `data/` go to every importer that reads that kind of file, for a fixed
//! number of seeded iterations. A reader may refuse anything, but must not panic, hang or
//! account wrongly for what it read (a panic fails the test; no `catch_unwind`).

use blockwalk_importers::{geojson_reader, gpkg, osm, shp, Layer, Theme};
use std::path::{Path, PathBuf};

/// SplitMix64 (Steele, Lea & Flood 2014): a small seeded generator, enough for mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One mutation of `b`: flip 1–8 bits, truncate, insert 1–16 random bytes, or overwrite a
/// 4-byte word with an extreme value (lengths, counts and offsets live in such words).
fn mutate(b: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = b.to_vec();
    match rng.below(4) {
        0 => {
            for _ in 0..=rng.below(8) {
                let i = rng.below(out.len());
                if let Some(x) = out.get_mut(i) {
                    *x ^= 1 << rng.below(8);
                }
            }
        }
        1 => out.truncate(rng.below(out.len())),
        2 => {
            let at = rng.below(out.len() + 1);
            let n = 1 + rng.below(16);
            let ins: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            out.splice(at..at, ins);
        }
        _ => {
            let at = rng.below(out.len().saturating_sub(4));
            let word: [u8; 4] = match rng.below(4) {
                0 => [0xff; 4],
                1 => [0; 4],
                2 => [0x7f, 0xff, 0xff, 0xff],
                _ => (rng.next() as u32).to_le_bytes(),
            };
            for (k, w) in word.iter().enumerate() {
                if let Some(x) = out.get_mut(at + k) {
                    *x = *w;
                }
            }
        }
    }
    out
}

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data")
}

/// Every file under `data/`, sorted (deterministic order).
fn real_files() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![data_dir()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// What a successful read must still satisfy.
fn accounted(l: &Layer) {
    assert_eq!(l.report.imported, l.features.len());
    assert!(l.report.refused.len() <= l.report.read);
    let grouped: usize = l.report.refused_by_reason.iter().map(|g| g.count).sum();
    assert_eq!(grouped, l.report.refused.len());
}

/// Iterations per file: more for small files, fewer for large ones (the whole test stays within
/// about 20 s in the test profile).
fn iterations(len: usize) -> usize {
    (200_000 / len.max(1)).clamp(3, 30)
}

#[test]
fn mutated_real_files_never_panic() {
    let mut rng = Rng(0x5EED_B10C_4A1C);
    let dir = tempfile::tempdir().unwrap();
    let mut runs = 0usize;
    let mut files = 0usize;
    for path in real_files() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let ext = name.rsplit('.').next().unwrap_or("").to_ascii_lowercase();
        if !matches!(
            ext.as_str(),
            "shp" | "shx" | "dbf" | "prj" | "geojson" | "gpkg" | "pbf"
        ) {
            continue;
        }
        let bytes = std::fs::read(&path).unwrap();
        files += 1;
        for _ in 0..iterations(bytes.len()) {
            let bad = mutate(&bytes, &mut rng);
            runs += 1;
            match ext.as_str() {
                "shp" | "shx" | "dbf" | "prj" => {
                    // The layer's other parts, intact, beside the mutated one.
                    let stem = path.with_extension("");
                    for e in ["shp", "shx", "dbf", "prj"] {
                        let src = stem.with_extension(e);
                        let dst = dir.path().join(format!("l.{e}"));
                        if e == ext {
                            std::fs::write(&dst, &bad).unwrap();
                        } else if src.exists() {
                            std::fs::copy(&src, &dst).unwrap();
                        } else {
                            let _ = std::fs::remove_file(&dst);
                        }
                    }
                    if let Ok(l) = shp::read(&dir.path().join("l.shp")) {
                        accounted(&l);
                    }
                }
                "geojson" => {
                    let p = dir.path().join("l.geojson");
                    std::fs::write(&p, &bad).unwrap();
                    if let Ok(l) = geojson_reader::read(&p) {
                        accounted(&l);
                    }
                }
                "gpkg" => {
                    let p = dir.path().join("l.gpkg");
                    std::fs::write(&p, &bad).unwrap();
                    for theme in [Theme::Buildings, Theme::Streets] {
                        if let Ok(l) = gpkg::read(&p, &theme) {
                            accounted(&l);
                        }
                    }
                }
                _ => {
                    let p = dir.path().join("l.osm.pbf");
                    std::fs::write(&p, &bad).unwrap();
                    for theme in [Theme::Buildings, Theme::Streets] {
                        if let Ok(l) = osm::read(&p, &theme) {
                            accounted(&l);
                        }
                    }
                }
            }
        }
    }
    eprintln!("{runs} mutated inputs from {files} real files");
    assert!(files >= 40, "{files} files");
    assert!(runs >= 500, "{runs} runs");
}
