//! Block detection on a generated city (`city::generate`, 80,000 buildings): the street graph,
//! its faces and the assignment of every building, end to end, plus the noding and the footprint
//! inference alone.

use blockwalk::blocks::noding::{node_lines, DEFAULT_SNAP_TOLERANCE};
use blockwalk::blocks::{detect_geometry, BlockOptions, BlockSource};
use blockwalk::city::generate::{generate_city, GenerateParams};
use criterion::{criterion_group, criterion_main, Criterion};
use geo_types::{LineString, Polygon};
use std::hint::black_box;

fn city(n: usize) -> (Vec<LineString<f64>>, Vec<Polygon<f64>>) {
    let g = generate_city(&GenerateParams {
        buildings: n,
        seed: 7,
        ..GenerateParams::default()
    })
    .expect("generated city");
    (
        g.streets.into_iter().map(|s| s.line).collect(),
        g.buildings.into_iter().map(|b| b.footprint).collect(),
    )
}

fn bench(c: &mut Criterion) {
    let (lines, footprints) = city(80_000);
    let opts = BlockOptions::default();
    let l = detect_geometry(BlockSource::Streets, &lines, &[], &footprints, &opts).unwrap();
    eprintln!(
        "generated city: {} buildings, {} street lines, {} blocks and outskirts, {} street edges",
        footprints.len(),
        lines.len(),
        l.blocks.len(),
        l.street_edges.len()
    );
    let mut g = c.benchmark_group("blocks");
    g.sample_size(10);
    // Lines through one point: every pair crosses there, the worst case for the split lists.
    let star: Vec<LineString<f64>> = (0..10_000)
        .map(|k| {
            let a = std::f64::consts::PI * (k as f64 + 0.5) / 10_000.0;
            LineString::from(vec![
                (-1000.0 * a.cos(), -1000.0 * a.sin()),
                (1000.0 * a.cos(), 1000.0 * a.sin()),
            ])
        })
        .collect();
    g.bench_function("noding_10k_lines_through_one_point", |b| {
        b.iter(|| node_lines(black_box(&star), DEFAULT_SNAP_TOLERANCE))
    });
    g.bench_function("streets_80k_buildings", |b| {
        b.iter(|| {
            detect_geometry(
                BlockSource::Streets,
                black_box(&lines),
                &[],
                &footprints,
                &opts,
            )
            .unwrap()
        })
    });
    g.bench_function("noding_only", |b| {
        b.iter(|| node_lines(black_box(&lines), DEFAULT_SNAP_TOLERANCE))
    });
    let (_, small) = city(5_000);
    g.bench_function("footprints_5k_buildings", |b| {
        b.iter(|| {
            detect_geometry(BlockSource::Footprints, &[], &[], black_box(&small), &opts).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
