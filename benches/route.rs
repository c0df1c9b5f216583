//! Route benchmarks: sampling the paper's route (seed 003 §5) and extracting its frusta; the
//! walk (culling + bookkeeping, no rendering) of 300 frames through every structure.

use blockwalk::geom::Aabb3;
use blockwalk::route::{paper_route, Lens, Obstacles, PaperRouteParams, StreetGraph};
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
                &Obstacles::none(),
                &PaperRouteParams::default(),
                Lens::default(),
            )
            .unwrap()
        })
    });
    let r = paper_route(
        &bounds,
        Some(&g),
        &Obstacles::none(),
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

/// The walk without rendering: 300 frames of the paper route, five structures, the per-frame
/// bookkeeping, on a synthetic street grid of 50 × 50 blocks (2,500 blocks, about the block count
/// of a generated city of 80,000 buildings); frustum culling alone (no hidden-volume filter, so
/// the structures accept subtrees found completely inside, seed 003 §5) and frustum + occlusion
/// culling (cull map, seed 004 §3.2), side by side.
fn walk_300_frames(c: &mut Criterion) {
    use blockwalk::index::Structure;
    use blockwalk::scene::{CitySource, Scene, SceneOptions};
    use blockwalk::visibility::CullerOptions;
    use blockwalk::walk::{run_walk, Drawing, OcclusionMode, WalkParams};
    let source =
        CitySource::parse(std::path::Path::new("synthetic:50x50"), None, None, &[], 1).unwrap();
    let opts = SceneOptions {
        structures: Structure::ALL.to_vec(),
        occlusion: Some(CullerOptions::default()),
        ..SceneOptions::default()
    };
    let scene = Scene::load(&source, &opts, &mut |_| {}).unwrap();
    let graph = StreetGraph::from_world_lines(&scene.layout.street_edges, &scene.city.frame);
    let obstacles = Obstacles::from_buildings(&scene.city.buildings, &scene.city.frame);
    let route = paper_route(
        &scene.city_bounds(),
        Some(&graph).filter(|g| !g.is_empty()),
        &obstacles,
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap();
    let mut g = c.benchmark_group("walk_paper_route_300_frames_5_structures_2500_blocks");
    g.sample_size(10);
    for (label, occlusion) in [
        ("frustum_only", OcclusionMode::Off),
        ("frustum_and_occlusion", OcclusionMode::On),
    ] {
        let params = WalkParams {
            route: route.clone(),
            frames: 300,
            occlusion,
            image_every: 0,
            oracle: false,
            size: (1280, 720),
        };
        g.bench_function(label, |b| {
            b.iter(|| run_walk(&scene, &params, Drawing::Off, &mut |_, _| {}).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, route_sampling, walk_300_frames);
criterion_main!(benches);
