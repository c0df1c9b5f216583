//! The quadtree far field per frame: selection properties against brute force (every block
//! drawn exactly once, monotone in τ, hysteresis against flicker, conservative against the
//! oracle), and hybrid walks on Helsinki with the CPU fallback.

mod support;
use blockwalk::blockmap::{skeleton_tree, MapTree, SelectOptions, Selection, Selector, Stop};
use blockwalk::blocks::BlockId;
use blockwalk::geom::{Camera, Containment};
use blockwalk::index::synthetic::{block_grid, grid_extent_m};
use blockwalk::index::{BlockBounds, BqrParams, BqrTree};
use glam::DVec3;
use proptest::prelude::*;
use std::collections::{HashMap, HashSet};

fn skeleton(bounds: &[BlockBounds], stop: Stop) -> MapTree {
    let tree = BqrTree::build(bounds, &BqrParams::default()).unwrap();
    let maps = skeleton_tree(&tree, 32, stop).unwrap();
    maps.check_invariants();
    maps
}

/// How often each block is drawn: once per mesh entry, once per drawn map holding it.
fn draw_counts(maps: &MapTree, sel: &Selection) -> HashMap<BlockId, usize> {
    let mut n: HashMap<BlockId, usize> = HashMap::new();
    for b in &sel.meshes {
        *n.entry(*b).or_default() += 1;
    }
    for &m in &sel.maps {
        for b in &maps.maps[m].blocks {
            *n.entry(*b).or_default() += 1;
        }
    }
    n
}

fn camera(eye: DVec3, yaw: f64, pitch: f64) -> Camera {
    let mut c = Camera::new(eye, yaw, pitch);
    c.far = 20_000.0;
    c
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Every block is drawn at most once, and every block the brute-force frustum test keeps is
    /// drawn (as a mesh or inside a drawn map); every mesh block passes that test.
    #[test]
    fn every_block_exactly_once(
        n in 30usize..300,
        seed in 0u64..1000,
        x in -1.5f64..1.5, y in -1.5f64..1.5, z in 1.7f64..3000.0,
        yaw in 0.0f64..std::f64::consts::TAU, pitch in -1.5f64..0.3,
        tau in 0.25f64..32.0,
        leaf_blocks in 1usize..6,
    ) {
        let bounds = block_grid(n, seed);
        let maps = skeleton(&bounds, Stop::LeafBlocks(leaf_blocks));
        prop_assert!(!maps.maps.is_empty());
        let ext = grid_extent_m(n);
        let cam = camera(DVec3::new(x * ext, y * ext, z), yaw, pitch);
        let mut s = Selector::new(&maps, &bounds, SelectOptions { tau_px: tau, hysteresis: 0.25 }).unwrap();
        let sel = s.select(&cam, 720, None);
        let counts = draw_counts(&maps, &sel);
        let frustum = cam.frustum();
        for b in &bounds {
            let seen = frustum.test_aabb_sphere(&b.aabb, &b.sphere) != Containment::Outside;
            let c = counts.get(&b.id).copied().unwrap_or(0);
            prop_assert!(c <= 1, "block {} drawn {c} times", b.id.0);
            if seen {
                prop_assert_eq!(c, 1, "block {} in view but not drawn", b.id.0);
            }
        }
        for m in &sel.meshes {
            let b = &bounds[m.0 as usize];
            prop_assert!(frustum.test_aabb_sphere(&b.aabb, &b.sphere) != Containment::Outside);
        }
        // Every drawn map meets the rule (no hysteresis in a first frame).
        for &m in &sel.maps {
            prop_assert!(s.error_px(m, &cam, 720) <= tau);
        }
        prop_assert_eq!(sel.stats.maps as usize, sel.maps.len());
        prop_assert_eq!(sel.stats.mesh_blocks as usize, sel.meshes.len());
    }

    /// A larger τ never draws more meshes: the mesh set at τ₂ > τ₁ is a subset of the one at τ₁.
    #[test]
    fn larger_tau_never_draws_more_meshes(
        n in 30usize..300,
        seed in 0u64..1000,
        x in -1.0f64..1.0, y in -1.0f64..1.0, z in 1.7f64..1500.0,
        yaw in 0.0f64..std::f64::consts::TAU, pitch in -1.5f64..0.3,
        tau in 0.25f64..16.0, factor in 1.0f64..8.0,
    ) {
        let bounds = block_grid(n, seed);
        let maps = skeleton(&bounds, Stop::LeafBlocks(2));
        let ext = grid_extent_m(n);
        let cam = camera(DVec3::new(x * ext, y * ext, z), yaw, pitch);
        let meshes = |t: f64| -> HashSet<BlockId> {
            let mut s = Selector::new(&maps, &bounds, SelectOptions { tau_px: t, hysteresis: 0.25 }).unwrap();
            s.select(&cam, 720, None).meshes.into_iter().collect()
        };
        let (a, b) = (meshes(tau), meshes(tau * factor));
        prop_assert!(b.is_subset(&a), "τ {} → {} meshes, τ {} → {}", tau, a.len(), tau * factor, b.len());
    }
}

/// A camera that moves back and forth across the distance where the root map's projected error
/// equals τ: without hysteresis the root switches every frame, with the default hysteresis once
/// (to meshes, where it stays: the far position's error lies between τ/1.25 and τ). With or
/// without, no drawn map ever has an error above τ.
#[test]
fn hysteresis_stops_flicker_on_an_oscillating_camera() {
    let bounds = block_grid(100, 3);
    let maps = skeleton(&bounds, Stop::LeafBlocks(2));
    let root = maps.maps.iter().position(|m| m.parent.is_none()).unwrap();
    let opts = SelectOptions {
        tau_px: 1.0,
        hysteresis: 0.25,
    };
    let probe = Selector::new(&maps, &bounds, opts).unwrap();
    // Looking down at the city centre from height z: find z where the root's error is τ.
    let c = probe.cull_box(root).center();
    let at = |z: f64| {
        let mut cam = Camera::looking_at(DVec3::new(c.x, c.y - 1.0, z), c);
        cam.far = 1e6;
        cam
    };
    let (mut lo, mut hi) = (100.0, 1e6);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if probe.error_px(root, &at(mid), 720) > 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // e ∝ 1/d: ±8 % around the switch distance keeps e within (τ/1.09, τ·1.09).
    let near = at(hi / 1.08);
    let far = at(hi * 1.08);
    assert!(probe.error_px(root, &near, 720) > 1.0);
    assert!(probe.error_px(root, &near, 720) < 1.25);
    assert!(probe.error_px(root, &far, 720) <= 1.0);
    let run = |h: f64| -> usize {
        let mut s = Selector::new(
            &maps,
            &bounds,
            SelectOptions {
                tau_px: 1.0,
                hysteresis: h,
            },
        )
        .unwrap();
        let mut last: Option<bool> = None;
        let mut switches = 0;
        for f in 0..40 {
            let cam = if f % 2 == 0 { &far } else { &near };
            let sel = s.select(cam, 720, None);
            for &m in &sel.maps {
                let e = s.error_px(m, cam, 720);
                assert!(e <= 1.0, "h {h}, frame {f}: map {m} drawn at {e} px > τ");
            }
            let root_drawn = sel.maps.contains(&root);
            if last.is_some_and(|l| l != root_drawn) {
                switches += 1;
            }
            last = Some(root_drawn);
        }
        switches
    };
    assert_eq!(
        run(0.0),
        39,
        "without hysteresis the root flips every frame"
    );
    assert_eq!(
        run(0.25),
        1,
        "with hysteresis the root switches to meshes once and stays"
    );
}

mod helsinki {
    use blockwalk::blockmap::{CityMapsOptions, MapTree, SelectOptions, Selector};
    use blockwalk::route::RouteChoice;
    use blockwalk::scene::Scene;
    use blockwalk::visibility::{MeshOracle, VisibilityOracle};
    use blockwalk::walk::job::resolve_route;
    use blockwalk::walk::{run_walk_with_far, Drawing, FarSetup, OcclusionMode, WalkParams};
    use std::collections::HashSet;

    fn scene() -> Scene {
        crate::support::data::helsinki_bqr_occlusion()
    }

    fn maps(scene: &Scene) -> MapTree {
        let opts = CityMapsOptions {
            checks: 0,
            ..CityMapsOptions::default()
        };
        let m = scene.blockmaps(&opts, &|_, _| {}).unwrap().maps;
        assert!(
            m.invariant_violations().is_empty(),
            "{:?}",
            m.invariant_violations()
        );
        m
    }

    fn route(scene: &Scene, choice: RouteChoice, aspect: f64) -> blockwalk::route::CameraRoute {
        resolve_route(&choice, scene, aspect).unwrap().0
    }

    /// One walk over Helsinki's bundled data (building the maps is the slow part): a short
    /// hybrid orbit with the CPU fallback (JSON keys, coverage error ≤ 1 % at τ = 1), the
    /// selection with the occlusion culler's cull map against the oracle, and the leave-out
    /// decision on a street-level walk.
    #[test]
    fn hybrid_walks_on_helsinki() {
        let scene = scene();
        let maps = maps(&scene);
        assert!(maps.maps.len() > 3, "{} maps", maps.maps.len());
        let size = (160u32, 90u32);

        // Conservative against the oracle: every block the oracle sees is drawn, as a mesh or
        // inside a drawn map, with the cull map pruning nodes.
        let culler = scene.occlusion.as_ref().unwrap();
        let oracle = MeshOracle::new(scene.block_meshes());
        let mut sel = Selector::new(&maps, &scene.bounds, SelectOptions::default()).unwrap();
        let mut checked = 0;
        let mut hidden = 0;
        for choice in [RouteChoice::Paper, RouteChoice::Orbit, RouteChoice::Street] {
            let r = route(&scene, choice, size.0 as f64 / size.1 as f64);
            for cam in r.sample(24) {
                let cmap = culler.cull_map_for(&cam);
                let s = sel.select(&cam, size.1, Some(&cmap));
                hidden += s.stats.nodes_hidden;
                let mut drawn: HashSet<_> = s.meshes.iter().copied().collect();
                for &m in &s.maps {
                    drawn.extend(maps.maps[m].blocks.iter().copied());
                }
                for b in oracle.visible(&cam, size.0, size.1) {
                    assert!(drawn.contains(&b), "block {} seen but not drawn", b.0);
                    checked += 1;
                }
            }
        }
        assert!(checked > 100, "{checked} visible blocks checked");
        eprintln!("cull map hid {hidden} map nodes");

        // A short hybrid orbit, CPU fallback, with the reference.
        let params = WalkParams {
            route: route(&scene, RouteChoice::Orbit, size.0 as f64 / size.1 as f64),
            frames: 6,
            occlusion: OcclusionMode::Auto,
            image_every: 0,
            oracle: false,
            size,
        };
        // With the buildings as exact prisms (the scene's own meshes), so that the bound is
        // checked per pixel.
        let source =
            blockwalk::blockmap::Source::new(&scene.city, &scene.layout, &scene.building_meshes)
                .unwrap();
        let far = FarSetup {
            reference: true,
            source: Some(&source),
            ..FarSetup::new(&maps)
        };
        let rec = run_walk_with_far(
            &scene,
            &params,
            Drawing::CpuFallback {
                reason: "test".into(),
            },
            Some(far),
            &mut |_, _| {},
        )
        .unwrap();
        let j = blockwalk::report::walk::json(&rec);
        eprintln!("{}", serde_json::to_string_pretty(&j["far"]).unwrap());
        for key in [
            "coverage_error_max",
            "psnr_min",
            "silhouette_px_max",
            "far_nodes",
            "frame_time_ratio_vs_mesh",
            "popping_px_max",
        ] {
            assert!(j.get(key).is_some(), "JSON lacks {key}");
        }
        // The bound, judged with the geometry on every referenced frame.
        assert!(j["silhouette_ratio_max"].is_number(), "{}", j["far"]);
        for key in [
            "silhouette_bound_violations",
            "silhouette_subpixel",
            "silhouette_thin",
        ] {
            assert!(j[key].is_u64(), "{key}: {}", j["far"]);
        }
        // And it holds: no mismatched pixel beyond its allowed distance.
        assert_eq!(
            rec.far_summary().unwrap().silhouette_bound_violations,
            Some(0),
            "{}",
            j["far"]
        );
        assert!(rec
            .far
            .iter()
            .all(|r| r.image.is_some_and(|i| i.silhouette_ratio_max.is_some())));
        // The check measured something: the bound is checked at every coverage-mismatched
        // pixel, and there were some (a zero would hold on frames that differ nowhere).
        let frame_px = (size.0 * size.1) as f64;
        let checked: f64 = rec
            .far
            .iter()
            .filter_map(|r| r.image.map(|i| (i.coverage_error * frame_px).round()))
            .sum();
        eprintln!("bound checked at {checked} mismatched pixels (both culling modes)");
        assert!(
            checked > 0.0,
            "no mismatched pixel was checked: {}",
            j["far"]
        );
        // No violation on any frame of either mode (the summary sums the last mode's).
        assert!(
            rec.far
                .iter()
                .all(|r| r.image.is_some_and(|i| i.beyond_bound == Some(0))),
            "{}",
            j["far"]
        );
        assert_eq!(j["far_used"], true);
        assert!(j["far_nodes"].as_f64().unwrap() > 0.0, "no far node drawn");
        assert!(j["frame_time_ratio_vs_mesh"].as_f64().unwrap() > 0.0);
        let cov = j["coverage_error_max"].as_f64().unwrap();
        assert!(cov <= 0.01, "coverage error {cov}");
        assert!(j["occlusion_decision"].is_object());
        assert_eq!(rec.far.len(), 6 * 2, "a hybrid frame per frame and mode");

        // Street level at a large image: nothing qualifies at τ = 1, the walk says so.
        let params = WalkParams {
            route: route(&scene, RouteChoice::Street, 16.0 / 9.0),
            frames: 12,
            occlusion: OcclusionMode::Off,
            image_every: 0,
            oracle: false,
            size: (1920, 1080),
        };
        let far = FarSetup {
            select: SelectOptions {
                tau_px: 0.25,
                ..SelectOptions::default()
            },
            ..FarSetup::new(&maps)
        };
        let rec =
            run_walk_with_far(&scene, &params, Drawing::Off, Some(far), &mut |_, _| {}).unwrap();
        let d = rec.far_decision.clone().unwrap();
        assert!(!d.used, "{d:?}");
        assert!(d
            .reason
            .as_deref()
            .unwrap()
            .contains("qualifies on any frame"));
        assert!(rec.far.is_empty());
        assert!(rec.notes.iter().any(|n| n.contains("far field left out")));
    }
}

/// Broken hierarchies are named, not drawn: a child ε above its parent's, a child block missing
/// from its parent, two siblings sharing a block.
#[test]
fn broken_trees_are_refused_with_the_node() {
    use blockwalk::blockmap::{SelectError, TreeViolation};
    let bounds = block_grid(64, 9);
    let good = skeleton(&bounds, Stop::LeafBlocks(2));
    assert!(good.invariant_violations().is_empty());
    // A grandchild of the root, so that its parent does not hold every block.
    let child = good
        .maps
        .iter()
        .position(|m| m.parent.is_some_and(|p| good.maps[p].parent.is_some()))
        .unwrap();
    let parent = good.maps[child].parent.unwrap();

    let mut t = good.clone();
    t.maps[child].map.meta.eps_m = t.maps[parent].map.meta.eps_m * 2.0;
    let v = t.invariant_violations();
    assert!(
        matches!(v[0], TreeViolation::EpsGrowsDownward { parent: p, child: c, .. }
            if p == good.maps[parent].key && c == good.maps[child].key),
        "{v:?}"
    );

    // A block of the parent's sibling subtree moved into the child: not in the parent.
    let mut t = good.clone();
    let stranger = bounds
        .iter()
        .map(|b| b.id)
        .find(|b| !t.maps[parent].blocks.contains(b))
        .unwrap();
    t.maps[child].blocks.push(stranger);
    assert!(t.invariant_violations().iter().any(
        |e| matches!(e, TreeViolation::NotInParent { what: "block", id, .. } if *id == stranger.0)
    ));
    assert!(matches!(
        Selector::new(&t, &bounds, SelectOptions::default()),
        Err(SelectError::NotInParent { block, .. }) | Err(SelectError::Shared { block, .. })
            if block == stranger.0
    ));

    // Two siblings holding one block.
    let kids: Vec<usize> = (0..good.maps.len())
        .filter(|&i| good.maps[i].parent == Some(parent))
        .collect();
    if kids.len() >= 2 {
        let mut t = good.clone();
        let b = t.maps[kids[0]].blocks[0];
        t.maps[kids[1]].blocks.push(b);
        assert!(t
            .invariant_violations()
            .iter()
            .any(|e| matches!(e, TreeViolation::SharedBlock { block, .. } if *block == b.0)));
        assert!(matches!(
            Selector::new(&t, &bounds, SelectOptions::default()),
            Err(SelectError::Shared { block, .. }) if block == b.0
        ));
    }
}
