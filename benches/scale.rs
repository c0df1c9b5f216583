//! Time and peak memory of import, extrusion and block detection against the number of
//! buildings, with the fitted exponents.
//!
//! For each N a generated city (seed 1) is written to a folder, then a child process (this
//! bench binary run again) imports it as `blockwalk import` does (the footprint and street
//! layers, not the folder's parcels, read and built into a `City`; of the footprints' columns
//! only those the buildings are made from), extrudes every building,
//! drops the meshes and detects the blocks (street noding and faces, then the assignment of the
//! buildings to them, timed apart). The child reports wall seconds, CPU seconds (user + system,
//! all threads, from `/proc/self/stat`) and peak resident memory per stage: the peak is `VmHWM`
//! from `/proc/self/status`, reset between stages by writing `5` to `/proc/self/clear_refs`
//! where the kernel allows it (else the peaks are cumulative and the table says so). One
//! process per N keeps one N's peak out of the next one's.
//!
//! `cargo bench --bench scale` runs N = 10k, 50k, 100k, 200k, 400k; `BLOCKWALK_SCALE_1M=1` adds
//! 1,000,000 (about 20 s to generate, 10 s to run idle, 4.4 GiB peak), and `BLOCKWALK_SCALE_N=10000,100000` runs the
//! sizes given. `BLOCKWALK_SCALE_DIR=DIR` keeps the generated cities in `DIR/cityN` and reuses
//! them on the next run (for profiling one stage: `BLOCKWALK_SCALE_CHILD=DIR/cityN` runs the
//! child alone, e.g. under `valgrind --tool=callgrind`). The exponent `b` of `y = a·N^b` is
//! fitted by least squares on the logarithms; 1 is linear.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use blockwalk::blocks::{detect_geometry, BlockOptions, BlockSource};
use blockwalk::city::build::{footprint_columns, BuildOptions};
use blockwalk::city::extrude::try_extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::scene::CitySource;

/// The environment variable that makes this binary the child of one N.
const CHILD: &str = "BLOCKWALK_SCALE_CHILD";

/// User + system CPU seconds of this process (all threads) so far, where the system says.
fn cpu_seconds() -> f64 {
    // Fields 14 and 15 of /proc/self/stat (after the parenthesised command name), in clock
    // ticks; Linux reports them at 100 ticks a second (USER_HZ).
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    let Some(rest) = s.rfind(')').map(|i| &s[i + 2..]) else {
        return f64::NAN;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok());
    // `rest` starts at field 3 (state): utime is field 14, stime 15.
    match (tick(11), tick(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// Resets the peak to the current resident size; false where the kernel does not allow it.
fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Times one stage: wall and CPU seconds and the peak, printed as `name wall cpu peak_mib`.
fn stage<T>(name: &str, f: impl FnOnce() -> T) -> T {
    reset_peak();
    let (t, c) = (Instant::now(), cpu_seconds());
    let out = f();
    println!(
        "{name} {} {} {}",
        t.elapsed().as_secs_f64(),
        cpu_seconds() - c,
        mib(blockwalk::process::peak_rss_bytes())
    );
    out
}

fn mib(b: Option<u64>) -> f64 {
    b.map_or(f64::NAN, |b| b as f64 / (1024.0 * 1024.0))
}

/// The child: import and extrude the city in `dir`, then detect its blocks; one line per stage
/// (`stage wall_s cpu_s peak_mib`), then `triangles N`, `blocks N` and `resets B`.
fn child(dir: &Path) {
    let resets = reset_peak();
    let source = CitySource::parse(dir, None, None, &[], 0)
        .and_then(|s| s.without_folder_parcels())
        .expect("a city folder");
    let city = stage("import", || {
        let opts = BuildOptions::default();
        source
            .load_with_columns(&opts, &footprint_columns(&opts.heights), &mut |_| {})
            .expect("the generated city loads")
            .city
    });
    let (meshes, errors) = stage("extrude", || try_extrude_city(&city));
    assert!(errors.is_empty(), "generated buildings extrude: {errors:?}");
    let triangles: usize = meshes.iter().map(|m| m.triangle_count()).sum();
    drop(meshes);
    // Blocks, as `blocks::detect` does them, with the two steps timed apart.
    let opts = BlockOptions::default();
    let lines: Vec<_> = city.streets.iter().map(|s| s.line.clone()).collect();
    let footprints: Vec<_> = city.buildings.iter().map(|b| b.footprint.clone()).collect();
    let polys = stage("noding", || {
        let graph = blockwalk::blocks::noding::node_lines(&lines, opts.snap_tolerance);
        let fs = blockwalk::blocks::faces::faces(&graph);
        fs.bounded().map(|i| fs.polygon(i)).collect::<Vec<_>>()
    });
    let assigned = stage("assign", || {
        blockwalk::blocks::assign::assign(&footprints, &polys)
    });
    let layout = stage("blocks", || {
        detect_geometry(BlockSource::Streets, &lines, &[], &footprints, &opts)
            .expect("generated blocks")
    });
    let in_blocks = assigned.iter().filter(|a| a.is_some()).count();
    println!("triangles {triangles}");
    println!("nblocks {} {in_blocks}", layout.blocks.len());
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

/// The generated city of `n` buildings in `keep/cityN` (written unless already there), or in a
/// temporary folder.
fn city_folder(n: usize, keep: Option<&Path>) -> (PathBuf, Option<tempfile::TempDir>) {
    let (dir, tmp) = match keep {
        Some(k) => (k.join(format!("city{n}")), None),
        None => {
            let t = tempfile::tempdir().expect("tempdir");
            (t.path().to_path_buf(), Some(t))
        }
    };
    if !dir.join("buildings.shp").is_file() {
        let city = generate_city(&GenerateParams {
            buildings: n,
            seed: 1,
            ..Default::default()
        })
        .expect("generate");
        write_city(&city, &dir).expect("write");
    }
    (dir, tmp)
}

/// The stages a child reports, in order.
const STAGES: [&str; 5] = ["import", "extrude", "noding", "assign", "blocks"];

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
        .unwrap_or_else(|| {
            let mut v = vec![10_000, 50_000, 100_000, 200_000, 400_000];
            if std::env::var_os("BLOCKWALK_SCALE_1M").is_some() {
                v.push(1_000_000);
            }
            v
        });
    let keep = std::env::var_os("BLOCKWALK_SCALE_DIR").map(PathBuf::from);
    let exe = std::env::current_exe().expect("the bench binary");
    println!("wall s / CPU s (user + system) / peak MiB per stage; blocks = noding + faces + assignment + outskirts");
    println!(
        "{:>8} | {:>21} | {:>21} | {:>8} {:>10} | {:>21} | {:>14} {:>7} | {:>10}",
        "N",
        "import s / cpu / MiB",
        "extrude s / cpu / MiB",
        "total s",
        "peak MiB",
        "blocks s / cpu / MiB",
        "noding/assign",
        "blocks",
        "triangles"
    );
    // Per N: [wall, cpu, peak] per stage.
    let mut rows: Vec<(f64, Vec<[f64; 3]>)> = Vec::new();
    let mut cumulative = false;
    for &n in &ns {
        let (dir, _tmp) = city_folder(n, keep.as_deref());
        let out = Command::new(&exe)
            .env(CHILD, &dir)
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
                .find_map(|l| l.strip_prefix(&format!("{name} ")).map(str::to_string))
                .and_then(|r| r.split_whitespace().nth(k).map(|v| v.parse().unwrap()))
                .unwrap_or(f64::NAN)
        };
        let s: Vec<[f64; 3]> = STAGES
            .iter()
            .map(|st| [field(st, 0), field(st, 1), field(st, 2)])
            .collect();
        let tri = field("triangles", 0);
        let nblocks = field("nblocks", 0);
        cumulative |= text.contains("resets false");
        let (ts, tm) = (s[0][0] + s[1][0], s[0][2].max(s[1][2]));
        println!(
            "{n:>8} | {:>6.2} {:>6.2} {:>7.0} | {:>6.2} {:>6.2} {:>7.0} | {ts:>8.2} {tm:>10.0} | \
             {:>6.2} {:>6.2} {:>7.0} | {:>6.3} {:>7.3} {nblocks:>7.0} | {tri:>10.0}",
            s[0][0],
            s[0][1],
            s[0][2],
            s[1][0],
            s[1][1],
            s[1][2],
            s[4][0],
            s[4][1],
            s[4][2],
            s[2][0],
            s[3][0]
        );
        rows.push((n as f64, s));
    }
    let xs: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let col = |st: usize, k: usize| -> Vec<f64> { rows.iter().map(|r| r.1[st][k]).collect() };
    let sum = |k: usize| -> Vec<f64> { rows.iter().map(|r| r.1[0][k] + r.1[1][k]).collect() };
    let peak: Vec<f64> = rows.iter().map(|r| r.1[0][2].max(r.1[1][2])).collect();
    println!("fitted exponents (y = a·N^b):");
    for (i, name) in STAGES.iter().enumerate() {
        println!(
            "  {name:<8} wall {:.2}, CPU {:.2}, peak {:.2}",
            exponent(&xs, &col(i, 0)),
            exponent(&xs, &col(i, 1)),
            exponent(&xs, &col(i, 2)),
        );
    }
    println!(
        "  import + extrusion: wall {:.2}, CPU {:.2}, peak {:.2}",
        exponent(&xs, &sum(0)),
        exponent(&xs, &sum(1)),
        exponent(&xs, &peak),
    );
    if cumulative {
        println!(
            "(the kernel refused to reset the peak: later stages' peaks include earlier ones)"
        );
    }
}
