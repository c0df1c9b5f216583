//! Time and peak memory of import + extrusion against the number of buildings, with the fitted
//! exponents (issue 13, item 2).
//!
//! For each N a generated city (seed 1) is written to a temporary folder, then a child process
//! (this bench binary run again) imports it as `blockwalk import` does (the footprint and street
//! layers read and built into a `City`) and extrudes every building. The child reports seconds
//! and peak resident memory per stage: the peak is `VmHWM` from `/proc/self/status`, reset
//! between stages by writing `5` to `/proc/self/clear_refs` where the kernel allows it (else
//! the peaks are cumulative and the table says so). One process per N keeps one N's peak out of
//! the next one's.
//!
//! `cargo bench --bench scale` runs N = 10k, 20k, 50k, 100k, 200k, 400k; set
//! `BLOCKWALK_SCALE_N=10000,100000,1000000` for other sizes. The exponent `b` of `y = a·N^b`
//! is fitted by least squares on the logarithms; 1 is linear.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use blockwalk::city::build::BuildOptions;
use blockwalk::city::extrude::try_extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::scene::CitySource;

/// The environment variable that makes this binary the child of one N.
const CHILD: &str = "BLOCKWALK_SCALE_CHILD";

/// Peak resident memory in bytes since the last reset, where the system says.
fn peak_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Resets the peak to the current resident size; false where the kernel does not allow it.
fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// One stage's figures.
struct Stage {
    name: &'static str,
    seconds: f64,
    peak_mib: f64,
}

fn mib(b: Option<u64>) -> f64 {
    b.map_or(f64::NAN, |b| b as f64 / (1024.0 * 1024.0))
}

/// The child: import and extrude the city in `dir`, print one line per stage
/// (`stage seconds peak_mib`) and `triangles N`.
fn child(dir: &Path) {
    let resets = reset_peak();
    let source = CitySource::parse(dir, None, None, &[], 0).expect("a city folder");
    let t = Instant::now();
    let loaded = source
        .load(&BuildOptions::default(), &mut |_| {})
        .expect("the generated city loads");
    let import = Stage {
        name: "import",
        seconds: t.elapsed().as_secs_f64(),
        peak_mib: mib(peak_bytes()),
    };
    let city = loaded.city;
    reset_peak();
    let t = Instant::now();
    let (meshes, errors) = try_extrude_city(&city);
    let extrude = Stage {
        name: "extrude",
        seconds: t.elapsed().as_secs_f64(),
        peak_mib: mib(peak_bytes()),
    };
    assert!(errors.is_empty(), "generated buildings extrude: {errors:?}");
    let triangles: usize = meshes.iter().map(|m| m.triangle_count()).sum();
    for s in [import, extrude] {
        println!("{} {} {}", s.name, s.seconds, s.peak_mib);
    }
    println!("triangles {triangles}");
    println!("resets {resets}");
}

/// Least-squares slope of `ln y` against `ln x`.
fn exponent(xs: &[f64], ys: &[f64]) -> f64 {
    let pts: Vec<(f64, f64)> = xs
        .iter()
        .zip(ys)
        .filter(|(x, y)| **x > 0.0 && **y > 0.0 && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return f64::NAN;
    }
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

fn main() {
    if let Ok(dir) = std::env::var(CHILD) {
        child(Path::new(&dir));
        return;
    }
    // Cargo passes `--bench` (and a filter): nothing to do with them here.
    let ns: Vec<usize> = std::env::var("BLOCKWALK_SCALE_N")
        .ok()
        .map(|s| {
            s.split(',')
                .map(|v| {
                    v.trim()
                        .parse()
                        .expect("BLOCKWALK_SCALE_N: numbers, comma-separated")
                })
                .collect()
        })
        .unwrap_or_else(|| vec![10_000, 20_000, 50_000, 100_000, 200_000, 400_000]);
    let exe = std::env::current_exe().expect("the bench binary");
    println!(
        "{:>9} {:>10} {:>9} {:>10} {:>9} {:>8} {:>10} {:>11}",
        "N", "import s", "MiB", "extrude s", "MiB", "total s", "peak MiB", "triangles"
    );
    let mut rows: Vec<(f64, [f64; 5])> = Vec::new();
    let mut cumulative = false;
    for &n in &ns {
        let dir = tempfile::tempdir().expect("tempdir");
        let city = generate_city(&GenerateParams {
            buildings: n,
            seed: 1,
            ..Default::default()
        })
        .expect("generate");
        write_city(&city, dir.path()).expect("write");
        drop(city);
        let out = Command::new(&exe)
            .env(CHILD, dir.path())
            .output()
            .expect("run the child");
        assert!(
            out.status.success(),
            "N = {n}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        let field = |name: &str, k: usize| -> f64 {
            text.lines()
                .find_map(|l| l.strip_prefix(name).map(|r| r.trim().to_string()))
                .and_then(|r| r.split_whitespace().nth(k).map(|v| v.parse().unwrap()))
                .unwrap_or(f64::NAN)
        };
        let (is, im) = (field("import", 0), field("import", 1));
        let (es, em) = (field("extrude", 0), field("extrude", 1));
        let tri = field("triangles", 0);
        cumulative |= text.contains("resets false");
        let (ts, tm) = (is + es, im.max(em));
        println!(
            "{n:>9} {is:>10.2} {im:>9.0} {es:>10.2} {em:>9.0} {ts:>8.2} {tm:>10.0} {tri:>11.0}"
        );
        rows.push((n as f64, [is, im, es, em, tm]));
    }
    let xs: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let col = |k: usize| -> Vec<f64> { rows.iter().map(|r| r.1[k]).collect() };
    let total: Vec<f64> = rows.iter().map(|r| r.1[0] + r.1[2]).collect();
    println!(
        "fitted exponents (y = a·N^b): import time {:.2}, import peak {:.2}, extrusion time {:.2}, \
         extrusion peak {:.2}, total time {:.2}, peak {:.2}",
        exponent(&xs, &col(0)),
        exponent(&xs, &col(1)),
        exponent(&xs, &col(2)),
        exponent(&xs, &col(3)),
        exponent(&xs, &total),
        exponent(&xs, &col(4)),
    );
    if cumulative {
        println!("(the kernel refused to reset the peak: extrusion peaks include the import's)");
    }
}
