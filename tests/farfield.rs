//! The quadtree far field per frame: selection properties against brute force (every block
//! drawn exactly once, monotone in τ, hysteresis against flicker, conservative against the
//! oracle), and hybrid walks on Helsinki with the CPU fallback.

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
/// equals τ: without hysteresis the root switches every frame, with the default hysteresis once.
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
    assert_eq!(run(0.25), 0, "with hysteresis the root stays a map");
}
