//! Cull map cost per frame (seed 004 §3.2): occluder selection, shadow drawing, pyramid and the
//! index traversal with cull map tests, on a synthetic street grid of about 80,000 buildings
//! (55 × 55 blocks) from street level, at several resolutions.

use blockwalk::index::{block_bounds, CityIndex, CullQuery, FlatList};
use blockwalk::visibility::synthetic::SyntheticCity;
use blockwalk::visibility::views::{random_views, ViewKind, ViewOptions};
use blockwalk::visibility::{CullerOptions, OccluderShadow, OcclusionCuller, Resolution};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;

fn cullmap(c: &mut Criterion) {
    let s = SyntheticCity::generate(55, 55, 1, DVec2::new(500_000.0, 6_600_000.0));
    let index = FlatList::build(&block_bounds(&s.city, &s.layout)).unwrap();
    let opts = ViewOptions {
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
    // The same views and index with frustum culling alone (no filter: subtrees found
    // completely inside are accepted whole, seed 003 §5), beside the occlusion numbers.
    g.bench_function("frustum_only", |b| {
        let mut k = 0;
        let mut out = Vec::new();
        b.iter(|| {
            out.clear();
            let cam = &views[k % views.len()].camera;
            let f = cam.frustum();
            k += 1;
            index
                .cull(&CullQuery::with_eye(&f, cam.position), None, &mut out)
                .blocks_accepted
        })
    });
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

    // Shadow drawing alone, the span fill against the reference rasterisation (whole map, no
    // window) and with the frustum window, for the first street view's occluders.
    let cam = views[0].camera;
    let mut occ = Vec::new();
    base.select(&cam, &mut occ);
    let shadows: Vec<OccluderShadow> = occ
        .iter()
        .filter_map(|o| OccluderShadow::new(cam.position, o).ok())
        .collect();
    let mut g = c.benchmark_group("cullmap_draw_shadows");
    g.sample_size(10);
    for res in [256u32, 1024] {
        let mut map = base
            .with_resolution(Resolution::Cells(res))
            .unwrap()
            .cull_map_for(&cam);
        map.clear_window();
        g.bench_with_input(BenchmarkId::new("reference", res), &res, |b, _| {
            b.iter(|| {
                map.clear();
                shadows.iter().map(|s| map.draw_reference(s)).sum::<u64>()
            })
        });
        g.bench_with_input(BenchmarkId::new("span_fill", res), &res, |b, _| {
            b.iter(|| {
                map.clear();
                shadows.iter().map(|s| map.draw(s)).sum::<u64>()
            })
        });
        let pts: Vec<DVec2> = cam
            .frustum()
            .corners()
            .map(|c| c.iter().map(|p| p.truncate()).collect())
            .unwrap_or_default();
        map.set_window(&pts, base.options().window_pad);
        g.bench_with_input(BenchmarkId::new("span_fill_window", res), &res, |b, _| {
            b.iter(|| {
                map.clear();
                shadows.iter().map(|s| map.draw(s)).sum::<u64>()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, cullmap);
criterion_main!(benches);
