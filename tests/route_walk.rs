//! The walk on a synthetic scene with real structures (the scene's BqR-tree, flat list and no
//! structure), a real occlusion culler and the CPU oracle: per-frame culling against brute force
//! over every block, zero false culls against the oracle, no vacuous frame, the summary's arithmetic,
//! the CPU fallback said aloud, and the report files.

use blockwalk::blocks::BlockId;
use blockwalk::index::bench::may_be_visible;
use blockwalk::index::{BlockBounds, CullQuery, Structure};
use blockwalk::route::{paper_route, Lens, Obstacles, PaperRouteParams, StreetGraph};
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::visibility::CullerOptions;
use blockwalk::walk::{run_walk, CullMode, Drawing, OcclusionMode, WalkError, WalkParams};
use std::collections::HashSet;
use std::path::Path;

const FRAMES: usize = 24;

fn scene(occlusion: bool) -> Scene {
    let source = CitySource::parse(Path::new("synthetic:4x3"), None, None, &[], 11).unwrap();
    let opts = SceneOptions {
        structures: vec![Structure::None, Structure::Flat, Structure::Bqr],
        occlusion: occlusion.then(CullerOptions::default),
        ..SceneOptions::default()
    };
    Scene::load(&source, &opts, &mut |_| {}).unwrap()
}

fn params(scene: &Scene, occlusion: OcclusionMode) -> WalkParams {
    let graph = StreetGraph::from_world_lines(&scene.layout.street_edges, &scene.city.frame);
    let obstacles = Obstacles::from_buildings(&scene.city.buildings, &scene.city.frame);
    let route = paper_route(
        &scene.city_bounds(),
        Some(&graph),
        &obstacles,
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap();
    WalkParams {
        route,
        frames: FRAMES,
        occlusion,
        image_every: 0,
        oracle: true,
        size: (160, 90),
    }
}

#[test]
fn culling_matches_brute_force_and_the_summary_adds_up() {
    let s = scene(false);
    let p = params(&s, OcclusionMode::Auto);
    let mut calls = 0;
    let rec = run_walk(&s, &p, Drawing::Off, &mut |done, total| {
        calls += 1;
        assert_eq!(total, FRAMES);
        assert_eq!(done, calls);
    })
    .unwrap();
    assert_eq!(calls, FRAMES);
    assert_eq!(rec.frames.len(), FRAMES * 3, "3 structures, 1 mode");
    assert!(rec.notes.iter().any(|n| n.contains("no occlusion culler")));
    let cams = p.route.sample(FRAMES);
    let by_id: std::collections::HashMap<BlockId, &BlockBounds> =
        s.bounds.iter().map(|b| (b.id, b)).collect();
    // The structures are the real ones: a BqR-tree has nodes, a flat list has none.
    let bqr = s.index(Structure::Bqr).expect("bqr built");
    assert!(bqr.node_count() > s.bounds.len(), "{}", bqr.node_count());
    assert_eq!(s.index(Structure::Flat).unwrap().node_count(), 0);
    let mut vacuous = 0;
    for r in &rec.frames {
        let cam = &cams[r.frame];
        let f = cam.frustum();
        // Independent truth: brute force over every block (exact box test, and the block's
        // sphere outside no plane), no structure involved.
        let truth: HashSet<BlockId> = s
            .bounds
            .iter()
            .filter(|b| may_be_visible(&f, b))
            .map(|b| b.id)
            .collect();
        if r.structure == Structure::Bqr {
            vacuous += usize::from(truth.is_empty());
        }
        // What the structure returns for this frame: a superset of the truth, and exactly what
        // the walk recorded (count and triangles).
        let mut out = Vec::new();
        s.index(r.structure)
            .unwrap()
            .cull(&CullQuery::with_eye(&f, cam.position), None, &mut out);
        let got: HashSet<BlockId> = out.iter().copied().collect();
        assert!(
            truth.is_subset(&got),
            "{} frame {}: drops {:?}",
            r.structure,
            r.frame,
            truth.difference(&got).collect::<Vec<_>>()
        );
        assert_eq!(r.blocks, got.len(), "{} frame {}", r.structure, r.frame);
        let tri: u64 = got.iter().map(|b| u64::from(by_id[b].triangles)).sum();
        assert_eq!(r.triangles, tri, "{} frame {}", r.structure, r.frame);
        if r.structure == Structure::None {
            assert_eq!(r.blocks, s.bounds.len());
        }
        assert_eq!(r.false_culls, Some(0), "{r:?}");
        assert_eq!(r.frame_s, r.cull_s, "nothing drawn");
        assert_eq!(r.render_s, None);
    }
    // The generated route keeps the city in view: no frame is vacuous.
    assert_eq!(
        vacuous, 0,
        "{vacuous} frames see no block: the route misses the city"
    );
    // Table 1 arithmetic: means and the ratio against bqr.
    let row = |st| {
        rec.summary
            .iter()
            .find(|r| r.structure == st)
            .unwrap_or_else(|| panic!("no {st} row"))
    };
    let (bqr, none) = (row(Structure::Bqr), row(Structure::None));
    assert_eq!(bqr.ratio, 1.0);
    assert!((none.ratio - bqr.seconds_per_frame / none.seconds_per_frame).abs() < 1e-12);
    let mean_tri = rec
        .frames
        .iter()
        .filter(|r| r.structure == Structure::Bqr)
        .map(|r| r.triangles as f64)
        .sum::<f64>()
        / FRAMES as f64;
    assert!((bqr.triangles - mean_tri).abs() < 1e-9);
    let all_tri: u64 = s.bounds.iter().map(|b| u64::from(b.triangles)).sum();
    assert_eq!(none.triangles, all_tri as f64);
    assert!(
        bqr.triangles < none.triangles,
        "frustum culling saves nothing?"
    );
    // Triangles of a record are those of the blocks it kept.
    for r in rec.frames.iter().filter(|r| r.structure == Structure::None) {
        let t: u64 = by_id.values().map(|b| u64::from(b.triangles)).sum();
        assert_eq!(r.triangles, t);
    }
}

#[test]
fn occlusion_runs_beside_frustum_culling_without_false_culls() {
    let s = scene(true);
    let rec = run_walk(
        &s,
        &params(&s, OcclusionMode::Auto),
        Drawing::Off,
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(
        rec.modes(),
        vec![CullMode::Frustum, CullMode::FrustumOcclusion]
    );
    assert_eq!(rec.false_culls(), Some(0));
    for st in [Structure::Flat, Structure::Bqr] {
        let mean = |m| {
            rec.summary
                .iter()
                .find(|r| r.structure == st && r.mode == m)
                .unwrap()
                .blocks
        };
        assert!(
            mean(CullMode::FrustumOcclusion) <= mean(CullMode::Frustum),
            "{st}: occlusion added blocks"
        );
    }
    let off = scene(false);
    let e = run_walk(
        &off,
        &params(&off, OcclusionMode::On),
        Drawing::Off,
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(e, WalkError::NoOcclusion(ref c) if c == &off.name),
        "{e}"
    );
    let mut p = params(&off, OcclusionMode::Off);
    p.frames = 0;
    let e = run_walk(&off, &p, Drawing::Off, &mut |_, _| {}).unwrap_err();
    assert!(matches!(e, WalkError::NoFrames(_)), "{e}");
}

#[test]
fn the_cpu_fallback_draws_and_says_so() {
    let s = scene(false);
    let mut p = params(&s, OcclusionMode::Off);
    p.frames = 4;
    p.image_every = 2;
    let rec = run_walk(
        &s,
        &p,
        Drawing::CpuFallback {
            reason: "no adapter in this test".into(),
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert!(
        rec.renderer
            .starts_with("CPU fallback (no adapter in this test)"),
        "{}",
        rec.renderer
    );
    assert!(rec
        .notes
        .iter()
        .any(|n| n.contains("not comparable with GPU")));
    assert!(rec.frames.iter().all(|r| r.render_s.is_some()));
    // Images of the reference structure (bqr) at frames 0 and 2, at the walk's size.
    let kept: Vec<usize> = rec.images.iter().map(|(f, _)| *f).collect();
    assert_eq!(kept, vec![0, 2]);
    assert!(rec.images.iter().all(|(_, i)| i.dimensions() == (160, 90)));
    let dir = tempfile::tempdir().unwrap();
    let files = blockwalk::report::walk::write(&rec, dir.path(), None).unwrap();
    assert!(files.iter().any(|f| f.ends_with("frames/frame_0002.png")));
    let csv = std::fs::read_to_string(dir.path().join("frames.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4 * 3);
}
