//! Polygon repair and extrusion against the vertex count: time per call for
//! one n-vertex ring (n = 1k … 100k), for a ring whose every tenth vertex carries a spike, and for
//! m footprints of 2,000 vertices each, with the exponent k of a least-squares fit t ∝ n^k.
//!
//! A plain timing loop (`harness = false`), not criterion: one call at 100k vertices took 86 s
//! before the change, too long for criterion's sampling. Each point is the median of a few runs.
//!
//! ```text
//! cargo bench --bench repair                      # every size
//! REPAIR_BENCH_MAX_N=20000 cargo bench --bench repair   # stop at 20k vertices (and 1,000 footprints)
//! ```

use std::hint::black_box;
use std::time::Instant;

use blockwalk::city::extrude::try_extrude_building;
use blockwalk::city::{Building, BuildingId, HeightSource, LocalFrame};
use blockwalk::geom::repair::repair_polygon;
use geo_types::{Coord, LineString, Polygon};
use glam::DVec3;
use rand::{Rng, SeedableRng};

/// A star-shaped (hence simple) ring of `n` vertices around `(cx, cy)`: strictly increasing
/// angles, a wavy radius of about 100 m with a little noise. With `spikes`, every tenth vertex is
/// followed by a zero-width spike (out 2 m along the edge and back), which repair removes.
fn ring(n: usize, seed: u64, cx: f64, cy: f64, spikes: bool) -> Vec<Coord<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut pts = Vec::with_capacity(n + n / 5 + 1);
    for i in 0..n {
        let a = std::f64::consts::TAU * (i as f64 + rng.random_range(0.1..0.9)) / n as f64;
        let r = 100.0 + 5.0 * (7.0 * a).sin() + rng.random_range(0.0..1.0);
        let p = Coord {
            x: cx + r * a.cos(),
            y: cy + r * a.sin(),
        };
        if spikes && i % 10 == 9 {
            let q: Coord<f64> = *pts.last().expect("i > 0");
            let (dx, dy) = (p.x - q.x, p.y - q.y);
            let l = (dx * dx + dy * dy).sqrt();
            pts.push(p);
            pts.push(Coord {
                x: p.x + 2.0 * dx / l,
                y: p.y + 2.0 * dy / l,
            });
        }
        pts.push(p);
    }
    pts.push(pts[0]);
    pts
}

fn building(p: Polygon<f64>) -> Building {
    Building {
        id: BuildingId(0),
        source_id: "bench:0".into(),
        footprint: p,
        height_m: 20.0,
        min_height_m: 0.0,
        base_m: 0.0,
        height_source: HeightSource::Height,
        attributes: Default::default(),
    }
}

/// Median seconds of `runs` calls of `f`.
fn time(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Least-squares slope of log t against log n.
fn exponent(points: &[(usize, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|p| (p.0 as f64).ln()).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.1.max(1e-9).ln()).collect();
    let k = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / k, ys.iter().sum::<f64>() / k);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn report(title: &str, unit: &str, points: &[(usize, f64)]) {
    println!("\n{title}");
    println!("| {unit} | seconds |");
    println!("|---:|---:|");
    for (n, t) in points {
        println!("| {n} | {t:.4} |");
    }
    if points.len() >= 2 {
        println!("fitted exponent: {:.2}", exponent(points));
    }
}

fn main() {
    let max_n: usize = std::env::var("REPAIR_BENCH_MAX_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    let sizes: Vec<usize> = [1_000, 2_000, 5_000, 10_000, 20_000, 50_000, 100_000]
        .into_iter()
        .filter(|&n| n <= max_n)
        .collect();
    let runs = |n: usize| if n <= 10_000 { 5 } else { 3 };
    let off = 5.0e5;
    let frame = LocalFrame {
        origin: DVec3::new(off, off, 0.0),
    };

    let mut rep = Vec::new();
    let mut ext = Vec::new();
    let mut spiky = Vec::new();
    for &n in &sizes {
        let p = Polygon::new(LineString::from(ring(n, n as u64, off, off, false)), vec![]);
        rep.push((
            n,
            time(runs(n), || {
                black_box(repair_polygon(black_box(&p)).expect("valid ring"));
            }),
        ));
        let b = building(repair_polygon(&p).expect("valid ring").polygons[0].clone());
        ext.push((
            n,
            time(runs(n), || {
                black_box(try_extrude_building(black_box(&b), &frame).expect("extrudes"));
            }),
        ));
        let s = Polygon::new(LineString::from(ring(n, n as u64, off, off, true)), vec![]);
        spiky.push((
            n,
            time(runs(n), || {
                black_box(repair_polygon(black_box(&s)).expect("repairable ring"));
            }),
        ));
        eprintln!("n = {n} done");
    }
    report("repair_polygon, one simple ring", "vertices", &rep);
    report("try_extrude_building, one ring", "vertices", &ext);
    report(
        "repair_polygon, one ring with a spike every 10 vertices",
        "vertices",
        &spiky,
    );

    // Many footprints of 2,000 vertices each, side by side: repair then extrude, as import does.
    let counts: Vec<usize> = [250, 500, 1_000, 2_000, 5_000]
        .into_iter()
        .filter(|&m| m * 20 <= max_n)
        .collect();
    let mut many = Vec::new();
    for &m in &counts {
        let polys: Vec<Polygon<f64>> = (0..m)
            .map(|k| {
                let (cx, cy) = (
                    off + 250.0 * (k % 100) as f64,
                    off + 250.0 * (k / 100) as f64,
                );
                Polygon::new(
                    LineString::from(ring(2_000, k as u64, cx, cy, false)),
                    vec![],
                )
            })
            .collect();
        many.push((
            m,
            time(1, || {
                for p in &polys {
                    let r = repair_polygon(p).expect("valid ring");
                    let b = building(r.polygons[0].clone());
                    black_box(try_extrude_building(&b, &frame).expect("extrudes"));
                }
            }),
        ));
        eprintln!("m = {m} done");
    }
    report(
        "repair + extrude, m footprints of 2,000 vertices (one thread)",
        "footprints",
        &many,
    );
}
