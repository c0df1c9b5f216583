//! Cull map cost per frame (seed 004 §3.2): occluder selection, shadow drawing, pyramid and the
//! index traversal with cull map tests, on a synthetic street grid of about 80,000 buildings
//! (55 × 55 blocks) from street level, at several resolutions.

use blockwalk::visibility::bench::{
    block_bounds, random_views, BenchOptions, ListIndex, SyntheticCity, ViewKind,
};
use blockwalk::visibility::{CullerOptions, OcclusionCuller, Resolution};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;

fn cullmap(c: &mut Criterion) {
    let s = SyntheticCity::generate(55, 55, 1, DVec2::new(500_000.0, 6_600_000.0));
    let refs = s.mesh_refs();
    let index = ListIndex::new(block_bounds(&s.city, &s.layout, &refs));
    let opts = BenchOptions {
        views: 32,
        street_fraction: 1.0,
        ..Default::default()
    };
    let views: Vec<_> = random_views(&s.city, &s.layout, &opts)
        .into_iter()
        .filter(|v| v.kind == ViewKind::Street)
        .collect();
    let base = OcclusionCuller::new(&s.city, &s.layout, CullerOptions::default()).unwrap();
    let mut g = c.benchmark_group("cullmap_street_frame");
    g.sample_size(20);
    for res in [64u32, 256, 1024] {
        let culler = base.with_resolution(Resolution::Cells(res)).unwrap();
        g.bench_with_input(BenchmarkId::new("build_and_cull", res), &res, |b, _| {
            let mut k = 0;
            let mut out = Vec::new();
            b.iter(|| {
                out.clear();
                let st = culler.cull(&index, &views[k % views.len()].camera, &mut out);
                k += 1;
                st.blocks_out
            })
        });
        g.bench_with_input(BenchmarkId::new("build_only", res), &res, |b, _| {
            let mut map = culler.cull_map_for(&views[0].camera);
            let mut k = 0;
            b.iter(|| {
                let st = culler.build(&views[k % views.len()].camera, &mut map);
                k += 1;
                st.cells_covered
            })
        });
    }
    g.finish();
}

criterion_group!(benches, cullmap);
criterion_main!(benches);
