//! The walk benchmark on a small hand-made scene: culling counts against brute force, the
//! summary's arithmetic, the files written.

use blockwalk::blocks::BlockId;
use blockwalk::city::{LocalFrame, Mesh};
use blockwalk::geom::{Aabb3, Frustum};
use blockwalk::index::{BlockBounds, CityIndex, CullStats};
use blockwalk::report::walk::{
    run_walk, OcclusionMode, OcclusionProvider, VisibilityOracle, WalkError, WalkParams, WalkScene,
};
use blockwalk::route::{paper_route, Lens, PaperRouteParams};
use glam::{DVec2, DVec3};
use std::collections::HashSet;

/// Conservative box-vs-frustum test: outside when all corners are behind one plane.
fn outside(f: &Frustum, b: &Aabb3) -> bool {
    f.planes
        .iter()
        .any(|p| b.corners().iter().all(|c| p.distance(*c) < 0.0))
}

/// Tests every block (reference structure for the test).
struct Linear(Vec<BlockBounds>, &'static str);

impl CityIndex for Linear {
    fn name(&self) -> &'static str {
        self.1
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn cull_filtered(
        &self,
        frustum: &Frustum,
        keep: &mut dyn FnMut(&Aabb3) -> bool,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut s = CullStats::default();
        for b in &self.0 {
            s.nodes_visited += 1;
            s.plane_tests += 6;
            if !outside(frustum, &b.aabb) && keep(&b.aabb) {
                out.push(b.id);
                s.blocks_accepted += 1;
                s.triangles_accepted += b.triangles as u64;
            }
        }
        s
    }
}

/// Draws everything.
struct Everything(Vec<BlockBounds>);

impl CityIndex for Everything {
    fn name(&self) -> &'static str {
        "none"
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn cull_filtered(
        &self,
        _: &Frustum,
        _: &mut dyn FnMut(&Aabb3) -> bool,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        out.extend(self.0.iter().map(|b| b.id));
        CullStats {
            nodes_visited: 1,
            ..Default::default()
        }
    }
}

/// Hides every block lower than 10 m (a stand-in occlusion culler).
struct HideLow;
impl OcclusionProvider for HideLow {
    fn name(&self) -> String {
        "hide-low".into()
    }
    fn cull(
        &self,
        index: &dyn CityIndex,
        camera: &blockwalk::geom::Camera,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        index.cull_filtered(&camera.frustum(), &mut |b: &Aabb3| b.max.z >= 10.0, out)
    }
}

/// "Visible" = inside the frustum by the same test (so frustum culling has no false culls, and
/// the hide-low culler has exactly the low blocks in view as false culls).
struct FrustumOracle(Vec<BlockBounds>);
impl VisibilityOracle for FrustumOracle {
    fn visible(&self, c: &blockwalk::geom::Camera, _: u32, _: u32) -> HashSet<BlockId> {
        let f = c.frustum();
        self.0
            .iter()
            .filter(|b| !outside(&f, &b.aabb))
            .map(|b| b.id)
            .collect()
    }
}

/// A 6 × 6 grid of 40 m blocks, heights 5..30 m.
fn scene(occlusion: bool) -> WalkScene {
    let mut bounds = Vec::new();
    for i in 0..36u32 {
        let (x, y) = ((i % 6) as f64 * 50.0 - 150.0, (i / 6) as f64 * 50.0 - 150.0);
        let h = 5.0 + (i * 7 % 26) as f64;
        bounds.push(BlockBounds {
            id: BlockId(i),
            aabb: Aabb3::new(DVec3::new(x, y, 0.0), DVec3::new(x + 40.0, y + 40.0, h)),
            center: DVec2::new(x + 20.0, y + 20.0),
            triangles: 12 + i,
        });
    }
    WalkScene {
        name: "grid".into(),
        frame: LocalFrame {
            origin: DVec3::ZERO,
        },
        street_edges: Vec::new(),
        meshes: bounds.iter().map(|b| (b.id, Mesh::default())).collect(),
        structures: vec![
            Box::new(Everything(bounds.clone())),
            Box::new(Linear(bounds.clone(), "bqr")),
        ],
        occlusion: occlusion.then(|| Box::new(HideLow) as Box<dyn OcclusionProvider>),
        oracle: Some(Box::new(FrustumOracle(bounds.clone()))),
        cpu_renderer: None,
        bounds,
    }
}

fn params(scene: &WalkScene, occlusion: OcclusionMode) -> WalkParams {
    let route = paper_route(
        &scene.city_bounds(),
        None,
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap();
    WalkParams {
        route,
        frames: 40,
        occlusion,
        render: false,
        image_every: 0,
        oracle: true,
        size: (320, 180),
    }
}

#[test]
fn walk_counts_match_brute_force_and_summary_adds_up() {
    let s = scene(false);
    let p = params(&s, OcclusionMode::Auto);
    let mut calls = 0;
    let rep = run_walk(&s, &p, &mut |done, total| {
        calls += 1;
        assert_eq!(total, 40);
        assert_eq!(done, calls);
    })
    .unwrap();
    assert_eq!(calls, 40);
    assert_eq!(rep.rows.len(), 40 * 2);
    assert!(rep.notes.iter().any(|n| n.contains("no occlusion culler")));
    let cams = p.route.sample(40);
    for r in &rep.rows {
        let f = cams[r.frame].frustum();
        let expect: Vec<&BlockBounds> = s.bounds.iter().filter(|b| !outside(&f, &b.aabb)).collect();
        if r.structure == "bqr" {
            assert_eq!(r.blocks, expect.len());
            let tri: u64 = expect.iter().map(|b| b.triangles as u64).sum();
            assert_eq!(r.triangles, tri);
            assert_eq!(r.false_culls, Some(0));
        } else {
            assert_eq!(r.blocks, 36);
            assert_eq!(r.false_culls, Some(0));
        }
        assert_eq!(r.frame_s, r.cull_s);
    }
    // Table 1 arithmetic: means and the ratio against bqr.
    let bqr = rep.summary.iter().find(|r| r.structure == "bqr").unwrap();
    let none = rep.summary.iter().find(|r| r.structure == "none").unwrap();
    assert_eq!(bqr.ratio, 1.0);
    assert!((none.ratio - bqr.seconds_per_frame / none.seconds_per_frame).abs() < 1e-12);
    let mean_tri: f64 = rep
        .rows
        .iter()
        .filter(|r| r.structure == "bqr")
        .map(|r| r.triangles as f64)
        .sum::<f64>()
        / 40.0;
    assert!((bqr.triangles - mean_tri).abs() < 1e-9);
    let all_tri: u32 = s.bounds.iter().map(|b| b.triangles).sum();
    assert_eq!(none.triangles, all_tri as f64);
    // Frustum culling sends fewer triangles on this route than drawing everything.
    assert!(bqr.triangles < none.triangles);
}

#[test]
fn occlusion_mode_and_false_culls() {
    let s = scene(true);
    let rep = run_walk(&s, &params(&s, OcclusionMode::Auto), &mut |_, _| {}).unwrap();
    assert_eq!(rep.modes(), vec!["frustum", "frustum+occlusion"]);
    let cams = params(&s, OcclusionMode::Auto).route.sample(40);
    for r in rep
        .rows
        .iter()
        .filter(|r| r.mode == "frustum+occlusion" && r.structure == "bqr")
    {
        let f = cams[r.frame].frustum();
        let low_in_view = s
            .bounds
            .iter()
            .filter(|b| !outside(&f, &b.aabb) && b.aabb.max.z < 10.0)
            .count();
        assert_eq!(r.false_culls, Some(low_in_view));
    }
    let off = scene(false);
    let e = run_walk(&off, &params(&off, OcclusionMode::On), &mut |_, _| {})
        .err()
        .expect("occlusion asked for without a culler");
    assert!(matches!(e, WalkError::NoOcclusion(_)), "{e:?}");
    assert!(e.to_string().contains("occlusion"), "{e}");
}

#[test]
fn report_files_are_written() {
    let s = scene(true);
    let mut p = params(&s, OcclusionMode::Auto);
    p.render = true; // no GPU in this scene's renderer path without the feature: must say so
    let rep = run_walk(&s, &p, &mut |_, _| {}).unwrap();
    if !cfg!(feature = "render") {
        assert!(rep.renderer.contains("CPU fallback"), "{}", rep.renderer);
    }
    let dir = tempfile::tempdir().unwrap();
    let files = rep.write(dir.path(), None).unwrap();
    for name in [
        "frames.csv",
        "summary.md",
        "report.json",
        "report.html",
        "frame_time_frustum.png",
        "frame_time_frustum.svg",
        "frame_time_frustum_occlusion.png",
        "triangles_frustum.svg",
    ] {
        assert!(
            files.iter().any(|f| f.ends_with(name)),
            "{name} missing from {files:?}"
        );
        assert!(dir.path().join(name).exists(), "{name}");
    }
    let csv = std::fs::read_to_string(dir.path().join("frames.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 40 * 2 * 2);
    let md = std::fs::read_to_string(dir.path().join("summary.md")).unwrap();
    assert!(md.contains("| bqr | frustum |") && md.contains("ratio BqR/structure"));
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    assert!(html.contains("frame_time_frustum.svg") && html.contains("<table>"));
}
