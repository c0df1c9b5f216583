//! Spatial structures: build time and per-frame frustum culling at 1k, 10k, 100k and 1M blocks
//! (seeded jittered block grids, `index::synthetic::block_grid`), for each structure.
//!
//! Every cull here passes no hidden-volume filter, so each structure accepts a subtree found
//! completely inside the frustum without further tests (seed 003 §5): this is the paper's
//! traversal. Occlusion culling is benched beside frustum-only culling in `benches/cullmap.rs`
//! (`frustum_only` against `build_and_cull`) and `benches/route.rs` (the walk, both modes), and
//! `blockwalk cull-bench CITY --occlusion` prints the two side by side per structure.
//!
//! Goals: build ≤ 200 ms for 100k blocks; street-level culling ≤ 100 µs per frame (median) for a
//! 100k-block city with a 2 km far plane. Short runs: `cargo bench --bench index -- --quick`.
//! Set `BLOCKWALK_BENCH_MAX` (e.g. 100000) to skip the larger sizes. The README's table of
//! culling figures comes from `blockwalk cull-bench` (release build), which counts the work
//! (nodes visited, plane tests) as well as the time and checks every result against brute force.

use blockwalk::geom::{Camera, Frustum};
use blockwalk::index::{
    synthetic::block_grid, synthetic::grid_extent_m, BlockBounds, CityIndex, CullQuery, Structure,
};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use std::hint::black_box;
use std::time::Duration;

fn sizes() -> Vec<usize> {
    let max: usize = std::env::var("BLOCKWALK_BENCH_MAX")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000);
    [1_000, 10_000, 100_000, 1_000_000]
        .into_iter()
        .filter(|&n| n <= max)
        .collect()
}

/// Eight street-level views (eye 1.7 m, far 2 km) spread over the city, deterministic.
fn street_views(n: usize) -> Vec<(Frustum, DVec3)> {
    let half = grid_extent_m(n) * 0.4;
    (0..8)
        .map(|k| {
            let a = k as f64 * 0.785;
            let pos = DVec3::new(
                half * (k as f64 * 1.3).cos() * 0.7,
                half * (k as f64 * 0.7).sin() * 0.7,
                1.7,
            );
            let mut c = Camera::new(pos, a, 0.02);
            c.far = 2000.0;
            (c.frustum(), c.position)
        })
        .collect()
}

fn flying_views(n: usize) -> Vec<(Frustum, DVec3)> {
    let half = grid_extent_m(n) * 0.4;
    (0..8)
        .map(|k| {
            let pos = DVec3::new(
                half * (k as f64).cos() * 0.5,
                half * (k as f64).sin() * 0.5,
                300.0,
            );
            let mut c = Camera::new(pos, k as f64 * 0.785, -0.6);
            c.far = 5000.0;
            (c.frustum(), c.position)
        })
        .collect()
}

fn cull_all(
    index: &dyn CityIndex,
    views: &[(Frustum, DVec3)],
    out: &mut Vec<blockwalk::blocks::BlockId>,
) -> u64 {
    let mut n = 0;
    for (f, eye) in views {
        out.clear();
        let q = CullQuery::with_eye(f, *eye);
        n += index.cull(&q, None, out).blocks_accepted;
    }
    n
}

fn bench_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("index_build");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    for n in sizes() {
        let bounds: Vec<BlockBounds> = block_grid(n, 42);
        for s in [Structure::Bqr, Structure::Vamsplit, Structure::Rstar] {
            g.bench_with_input(BenchmarkId::new(s.name(), n), &bounds, |b, bounds| {
                b.iter(|| black_box(s.build(bounds).unwrap().len()))
            });
        }
    }
    g.finish();
}

fn bench_cull(c: &mut Criterion) {
    for (label, views_of) in [
        (
            "cull_street_8_views",
            street_views as fn(usize) -> Vec<(Frustum, DVec3)>,
        ),
        ("cull_flying_8_views", flying_views),
    ] {
        let mut g = c.benchmark_group(label);
        g.sample_size(10)
            .measurement_time(Duration::from_secs(2))
            .warm_up_time(Duration::from_millis(300));
        for n in sizes() {
            let bounds = block_grid(n, 42);
            let views = views_of(n);
            for s in Structure::ALL {
                if s == Structure::None || (s == Structure::Flat && n > 100_000) {
                    continue;
                }
                let index = s.build(&bounds).unwrap();
                let mut out = Vec::new();
                g.bench_with_input(BenchmarkId::new(s.name(), n), &views, |b, views| {
                    b.iter(|| black_box(cull_all(index.as_ref(), views, &mut out)))
                });
            }
        }
        g.finish();
    }
}

criterion_group!(benches, bench_build, bench_cull);
criterion_main!(benches);
