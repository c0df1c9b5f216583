//! Route benchmarks: sampling the paper's route (seed 003 §5) and extracting its frusta.

use blockwalk::geom::Aabb3;
use blockwalk::route::{paper_route, Lens, PaperRouteParams, StreetGraph};
use criterion::{criterion_group, criterion_main, Criterion};
use geo_types::LineString;
use glam::DVec3;
use std::hint::black_box;

/// A 40 × 40 street grid, 60 m apart (the size of the generated 80k-building city's network).
fn grid() -> (Vec<LineString<f64>>, blockwalk::city::LocalFrame) {
    let n = 40;
    let mut lines = Vec::new();
    for i in 0..=n {
        let v = 60.0 * i as f64;
        lines.push(LineString::from(
            (0..=n).map(|j| (v, 60.0 * j as f64)).collect::<Vec<_>>(),
        ));
        lines.push(LineString::from(
            (0..=n).map(|j| (60.0 * j as f64, v)).collect::<Vec<_>>(),
        ));
    }
    let frame = blockwalk::city::LocalFrame {
        origin: DVec3::new(1200.0, 1200.0, 0.0),
    };
    (lines, frame)
}

fn route_sampling(c: &mut Criterion) {
    let (lines, frame) = grid();
    let bounds = Aabb3::new(
        DVec3::new(-1200.0, -1200.0, 0.0),
        DVec3::new(1200.0, 1200.0, 60.0),
    );
    c.bench_function("street graph 40x40 build", |b| {
        b.iter(|| StreetGraph::from_world_lines(black_box(&lines), &frame))
    });
    let g = StreetGraph::from_world_lines(&lines, &frame);
    c.bench_function("paper route build (Dijkstra)", |b| {
        b.iter(|| {
            paper_route(
                black_box(&bounds),
                Some(&g),
                &PaperRouteParams::default(),
                Lens::default(),
            )
            .unwrap()
        })
    });
    let r = paper_route(
        &bounds,
        Some(&g),
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap();
    c.bench_function("paper route sample 300 frames + frusta", |b| {
        b.iter(|| {
            let cams = r.sample(300);
            cams.iter().map(|c| c.frustum()).collect::<Vec<_>>()
        })
    });
}

criterion_group!(benches, route_sampling);
criterion_main!(benches);
