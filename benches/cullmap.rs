//! Cull map cost per frame (seed 004 §3.2): occluder selection, shadow drawing, pyramid and the
//! index traversal with cull map tests, on a synthetic street grid of about 80,000 buildings
//! (55 × 55 blocks) from street level, at several resolutions.

use blockwalk::index::{block_bounds, CityIndex, CullQuery, FlatList};
use blockwalk::visibility::synthetic::SyntheticCity;
use blockwalk::visibility::views::{random_views, ViewKind, ViewOptions};
use blockwalk::visibility::{CullerOptions, OccluderShadow, OcclusionCuller, Resolution};
use criterion::{criterion_group, BenchmarkId, Criterion};
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

/// The street-level frames (eye at most 2 m up) of the paper route (300 frames, 1280×720, as
/// `blockwalk walk --route paper` samples it) over the city directory in `BLOCKWALK_CULLMAP_CITY`
/// (e.g. `blockwalk generate --buildings 80000 --seed 1 -o city80k/`), and its scene (BqR-tree
/// and the occlusion culler at its defaults).
fn paper_route_street_frames() -> Option<(blockwalk::scene::Scene, Vec<blockwalk::geom::Camera>)> {
    use blockwalk::index::Structure;
    use blockwalk::route::{RouteChoice, RouteContext};
    use blockwalk::scene::{CitySource, Scene, SceneOptions};
    let dir = std::env::var_os("BLOCKWALK_CULLMAP_CITY")?;
    let source = CitySource::parse(std::path::Path::new(&dir), None, None, &[], 1).ok()?;
    let opts = SceneOptions {
        structures: vec![Structure::Bqr],
        occlusion: Some(CullerOptions::default()),
        ..SceneOptions::default()
    };
    let scene = Scene::load(&source, &opts, &mut |_| {}).ok()?;
    let ctx = RouteContext {
        city: &scene.name,
        bounds: scene.city_bounds(),
        street_edges: &scene.layout.street_edges,
        buildings: &scene.city.buildings,
        frame: &scene.city.frame,
        aspect: 1280.0 / 720.0,
        terrain: None,
    };
    let (route, _) = RouteChoice::Paper.resolve(&ctx).ok()?;
    let cams: Vec<_> = route
        .sample(300)
        .into_iter()
        .filter(|c| c.position.z <= 2.0)
        .collect();
    Some((scene, cams))
}

/// Cull map build and build + traversal on the paper route's street frames (see
/// [`paper_route_street_frames`]); nothing without `BLOCKWALK_CULLMAP_CITY`.
fn paper_route(c: &mut Criterion) {
    let Some((scene, cams)) = paper_route_street_frames() else {
        eprintln!("cullmap_paper_route: set BLOCKWALK_CULLMAP_CITY to a generated city directory");
        return;
    };
    let culler = scene.occlusion.as_ref().expect("asked for");
    let index = scene.indexes[0].as_ref();
    let mut g = c.benchmark_group("cullmap_paper_route_street");
    g.sample_size(20);
    let mut map = culler.new_map();
    g.bench_function("build_256", |b| {
        let mut k = 0;
        b.iter(|| {
            let st = culler.build(&cams[k % cams.len()], &mut map);
            k += 1;
            st.cells_covered
        })
    });
    g.bench_function("build_and_cull_256", |b| {
        let mut k = 0;
        let mut out = Vec::new();
        b.iter(|| {
            out.clear();
            let st = culler.cull(index, &cams[k % cams.len()], &mut out);
            k += 1;
            st.blocks_out
        })
    });
    g.finish();
}

/// `BLOCKWALK_CULLMAP_PASSES=N`: instead of criterion, N passes of build + traversal over the
/// paper route's street frames, for instruction counts (`valgrind --tool=callgrind
/// --toggle-collect='*OcclusionCuller*build*'`), with the mean per frame of the culler's own
/// timers and counters.
fn passes(n: usize) {
    let Some((scene, cams)) = paper_route_street_frames() else {
        eprintln!("set BLOCKWALK_CULLMAP_CITY to a generated city directory");
        std::process::exit(2);
    };
    let culler = scene.occlusion.as_ref().expect("asked for");
    let index = scene.indexes[0].as_ref();
    let mut out = Vec::new();
    let (mut build, mut test, mut used, mut cells, mut blocks) = (0.0, 0.0, 0u64, 0u64, 0u64);
    let mut skipped = 0u64;
    let cpu0 = thread_cpu_ns();
    for _ in 0..n {
        for cam in &cams {
            out.clear();
            let st = culler.cull(index, cam, &mut out);
            build += st.build_ms;
            test += st.test_ms;
            used += st.occluders_used;
            skipped += st.occluders_covered;
            cells += st.cells_covered;
            blocks += st.blocks_out;
        }
    }
    let cpu = thread_cpu_ns()
        .zip(cpu0)
        .map(|(b, a)| (b - a) as f64 * 1e-6);
    let f = (n * cams.len()) as f64;
    println!(
        "{} street frames x {n}: build {:.3} ms, traversal {:.3} ms (wall), build + traversal \
         {:.3} ms on the CPU; occluders drawn {:.1}, skipped {:.1}, cells {:.0}, blocks out {:.1} \
         per frame",
        cams.len(),
        build / f,
        test / f,
        cpu.map_or(f64::NAN, |c| c / f),
        used as f64 / f,
        skipped as f64 / f,
        cells as f64 / f,
        blocks as f64 / f
    );
}

/// Nanoseconds this thread has run on a CPU (`/proc/thread-self/schedstat`, Linux), which a
/// loaded machine's waiting does not inflate.
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

criterion_group!(benches, cullmap, paper_route);

fn main() {
    if let Some(n) = std::env::var("BLOCKWALK_CULLMAP_PASSES")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        passes(n);
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
