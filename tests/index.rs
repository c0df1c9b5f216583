//! Spatial structures against brute force: no false culls, ever (seed 003 §4).

use blockwalk::blocks::BlockId;
use blockwalk::geom::{Aabb3, Camera, CoherenceState, Frustum};
use blockwalk::index::{
    synthetic::block_grid, BlockBounds, BqrParams, BqrTree, CityIndex, CullQuery, FlatList,
    IndexError, NoStructure, ObjectId, RstarIndex, Structure, VamSplitParams, VamSplitTree,
};
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::collections::HashSet;

fn block(i: usize, min: DVec3, max: DVec3, center: DVec2) -> BlockBounds {
    BlockBounds {
        id: BlockId(i as u32),
        aabb: Aabb3::new(min, max),
        center,
        triangles: 10 + i as u32,
    }
}

/// (x, y, w, d, h, centre jitter) per block.
type Raw = (f64, f64, f64, f64, f64, f64);

fn uniform_city() -> impl Strategy<Value = Vec<BlockBounds>> {
    prop::collection::vec(
        (
            -800.0..800.0f64,
            -800.0..800.0f64,
            2.0..90.0f64,
            2.0..90.0f64,
            0.0..80.0f64,
            -0.4..0.4f64,
        ),
        0..80,
    )
    .prop_map(|raw: Vec<Raw>| to_blocks(&raw))
}

/// Blocks around a few cluster centres; some share exactly the same centre.
fn clustered_city() -> impl Strategy<Value = Vec<BlockBounds>> {
    (
        prop::collection::vec((-600.0..600.0f64, -600.0..600.0f64), 1..4),
        prop::collection::vec(
            (
                0usize..4,
                -30.0..30.0f64,
                -30.0..30.0f64,
                1.0..40.0f64,
                0.0..50.0f64,
                any::<bool>(),
            ),
            1..60,
        ),
    )
        .prop_map(|(centres, raw)| {
            raw.iter()
                .enumerate()
                .map(|(i, &(k, dx, dy, w, h, same))| {
                    let c = DVec2::from(centres[k % centres.len()]);
                    let c = if same { c } else { c + DVec2::new(dx, dy) };
                    let lo = (c - DVec2::splat(w * 0.5)).extend(0.0);
                    let hi = (c + DVec2::splat(w * 0.5)).extend(h);
                    block(i, lo, hi, c)
                })
                .collect()
        })
}

fn to_blocks(raw: &[Raw]) -> Vec<BlockBounds> {
    raw.iter()
        .enumerate()
        .map(|(i, &(x, y, w, d, h, j))| {
            let min = DVec3::new(x, y, 0.0);
            let max = DVec3::new(x + w, y + d, h);
            // The outline centre lies inside the box but not at its centre.
            let c = DVec2::new(x + w * (0.5 + j), y + d * (0.5 - j));
            block(i, min, max, c)
        })
        .collect()
}

fn camera() -> impl Strategy<Value = Camera> {
    (
        0u8..3,
        -900.0..900.0f64,
        -900.0..900.0f64,
        -3.2..3.2f64,
        -1.0..1.0f64,
        20.0..700.0f64,
        prop::sample::select(vec![(0.5, 2000.0), (1e-3, 1e6), (0.1, 300.0)]),
    )
        .prop_map(|(kind, x, y, yaw, p, z, (near, far))| {
            let (z, pitch) = match kind {
                0 => (1.7, p * 0.15),                   // street level
                1 => (z, -0.2 - (p.abs() * 1.3)),       // flying
                _ => (z, -std::f64::consts::FRAC_PI_2), // straight down
            };
            let mut c = Camera::new(DVec3::new(x, y, z), yaw, pitch);
            c.near = near;
            c.far = far;
            c
        })
}

fn structures(bounds: &[BlockBounds]) -> Vec<Box<dyn CityIndex>> {
    let bqr = BqrTree::build(bounds, &BqrParams::default()).unwrap();
    bqr.check_invariants();
    let vam = VamSplitTree::build(bounds, &VamSplitParams { node_capacity: 4 }).unwrap();
    vam.check_invariants();
    let vam8 = VamSplitTree::build(bounds, &VamSplitParams::default()).unwrap();
    vam8.check_invariants();
    let flat = FlatList::build(bounds).unwrap();
    flat.check_invariants();
    let none = NoStructure::build(bounds).unwrap();
    none.check_invariants();
    let rs = RstarIndex::build(bounds).unwrap();
    rs.check_invariants();
    vec![
        Box::new(bqr),
        Box::new(vam),
        Box::new(vam8),
        Box::new(flat),
        Box::new(none),
        Box::new(rs),
    ]
}

fn visible(bounds: &[BlockBounds], f: &Frustum) -> Vec<BlockId> {
    bounds
        .iter()
        .filter(|b| f.intersects_aabb_exact(&b.aabb))
        .map(|b| b.id)
        .collect()
}

fn check_no_false_culls(bounds: &[BlockBounds], cams: &[Camera]) -> Result<(), TestCaseError> {
    let idx = structures(bounds);
    for cam in cams {
        let f = cam.frustum();
        let truth = visible(bounds, &f);
        for s in &idx {
            // Mode 0: no filter (the "completely inside → accept the subtree" shortcut);
            // mode 1: a filter that keeps everything (every surviving volume asked);
            // mode 2: no filter with an explicit eye.
            for mode in 0..3 {
                let mut out = Vec::new();
                let stats = match mode {
                    0 => s.cull(&CullQuery::new(&f), None, &mut out),
                    1 => s.cull(&CullQuery::new(&f), Some(&mut |_: &Aabb3| true), &mut out),
                    _ => s.cull(&CullQuery::with_eye(&f, cam.position), None, &mut out),
                };
                let got: HashSet<BlockId> = out.iter().copied().collect();
                prop_assert_eq!(
                    got.len(),
                    out.len(),
                    "{} reports a block twice",
                    s.structure()
                );
                prop_assert_eq!(stats.blocks_accepted as usize, out.len());
                for id in &truth {
                    prop_assert!(
                        got.contains(id),
                        "{} (mode {}) culls visible block {:?}, camera {:?}",
                        s.structure(),
                        mode,
                        id,
                        cam
                    );
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn no_false_culls_uniform(bounds in uniform_city(), cams in prop::collection::vec(camera(), 1..6)) {
        check_no_false_culls(&bounds, &cams)?;
    }

    #[test]
    fn no_false_culls_clustered(bounds in clustered_city(), cams in prop::collection::vec(camera(), 1..6)) {
        check_no_false_culls(&bounds, &cams)?;
    }

    /// `keep` drops a node with its subtree: with a predicate that holds for a node's box only
    /// if it can hold for some block inside, the result is exactly the visible blocks it keeps
    /// (up to the structure's own false accepts) and none it refuses.
    #[test]
    fn keep_drops_subtrees(bounds in uniform_city(), cam in camera(), cut in -800.0..800.0f64) {
        let f = cam.frustum();
        let truth = visible(&bounds, &f);
        for s in structures(&bounds) {
            let mut asked = 0usize;
            let mut out = Vec::new();
            s.cull(
                &CullQuery::with_eye(&f, cam.position),
                Some(&mut |b: &Aabb3| { asked += 1; b.min.x < cut }),
                &mut out,
            );
            let got: HashSet<BlockId> = out.iter().copied().collect();
            for b in &bounds {
                if got.contains(&b.id) {
                    prop_assert!(b.aabb.min.x < cut, "{} kept a refused block", s.structure());
                }
            }
            for id in &truth {
                if bounds[id.0 as usize].aabb.min.x < cut {
                    prop_assert!(got.contains(id), "{} dropped a kept visible block", s.structure());
                }
            }
            if !out.is_empty() {
                prop_assert!(asked >= out.len(), "{}: keep not asked per block", s.structure());
            }
        }
    }

    /// Temporal coherence changes the order of plane tests, never the result.
    #[test]
    fn coherent_cull_matches_plain(bounds in uniform_city(), cams in prop::collection::vec(camera(), 1..8)) {
        let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
        let mut state = CoherenceState::default();
        for cam in &cams {
            let f = cam.frustum();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            tree.cull(&CullQuery::new(&f), None, &mut a);
            tree.cull_coherent(&f, &mut state, &mut b);
            let sa: HashSet<_> = a.into_iter().collect();
            let sb: HashSet<_> = b.into_iter().collect();
            let truth = visible(&bounds, &f);
            for id in &truth {
                prop_assert!(sb.contains(id));
            }
            prop_assert_eq!(sa, sb);
        }
    }

    /// Mobile objects: after random inserts, moves and removals, culling reports every object
    /// whose box intersects the frustum, and blocks as before.
    #[test]
    fn mobile_objects_against_brute_force(
        bounds in uniform_city(),
        ops in prop::collection::vec((0u8..3, 0u32..24, -900.0..900.0f64, -900.0..900.0f64, 0.5..6.0f64), 1..80),
        cams in prop::collection::vec(camera(), 1..4),
        refit in any::<bool>(),
    ) {
        let mut tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
        let mut truth: std::collections::HashMap<u32, Aabb3> = Default::default();
        for &(op, id, x, y, s) in &ops {
            let b = Aabb3::new(DVec3::new(x, y, 0.0), DVec3::new(x + s, y + s * 0.5, s));
            match op {
                0 => {
                    let r = tree.insert_object(ObjectId(id), b);
                    prop_assert_eq!(r.is_ok(), !truth.contains_key(&id));
                    truth.entry(id).or_insert(b);
                }
                1 => {
                    let r = tree.move_object(ObjectId(id), b);
                    prop_assert_eq!(r.is_ok(), truth.contains_key(&id));
                    if let Some(v) = truth.get_mut(&id) { *v = b; }
                }
                _ => {
                    let r = tree.remove_object(ObjectId(id));
                    prop_assert_eq!(r.is_ok(), truth.remove(&id).is_some());
                }
            }
        }
        if refit {
            tree.refit();
        }
        tree.check_invariants();
        prop_assert_eq!(tree.object_count(), truth.len());
        for cam in &cams {
            let f = cam.frustum();
            let (mut blocks, mut objs) = (Vec::new(), Vec::new());
            tree.cull_with_objects(&CullQuery::with_eye(&f, cam.position), None, &mut blocks, &mut objs, None);
            let got: HashSet<ObjectId> = objs.iter().copied().collect();
            prop_assert_eq!(got.len(), objs.len(), "object reported twice");
            for (id, b) in &truth {
                if f.intersects_aabb_exact(b) {
                    prop_assert!(got.contains(&ObjectId(*id)), "object {} culled", id);
                }
            }
            for o in &objs {
                prop_assert!(truth.contains_key(&o.0), "removed object {:?} reported", o);
            }
            let bset: HashSet<BlockId> = blocks.into_iter().collect();
            for id in visible(&bounds, &f) {
                prop_assert!(bset.contains(&id));
            }
        }
    }
}

#[test]
fn bqr_paper_shape_one_block_per_leaf_and_keys() {
    let bounds = block_grid(1000, 3);
    let t = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    t.check_invariants();
    assert_eq!(t.leaf_count(), 1000, "distinct centres: one block per leaf");
    let keys: HashSet<u64> = t.node_keys().map(|(k, _, _)| k).collect();
    assert_eq!(keys.len(), t.node_count(), "keys are unique");
    // Adaptive: no more than 4 children each, so at least leaves/3 inner nodes... and empty
    // quadrants get no node: every inner node has a child.
    assert!(t.node_count() < 3 * 1000);
}

#[test]
fn bqr_same_centre_blocks_share_a_leaf_at_the_depth_limit() {
    let c = DVec2::new(10.0, 10.0);
    let mut bounds: Vec<BlockBounds> = (0..5)
        .map(|i| {
            let w = 5.0 + i as f64;
            block(
                i,
                (c - DVec2::splat(w)).extend(0.0),
                (c + DVec2::splat(w)).extend(10.0),
                c,
            )
        })
        .collect();
    bounds.push(block(
        5,
        DVec3::new(100.0, 100.0, 0.0),
        DVec3::new(120.0, 120.0, 5.0),
        DVec2::new(110.0, 110.0),
    ));
    let t = BqrTree::build(&bounds, &BqrParams { max_depth: 6 }).unwrap();
    t.check_invariants();
    assert_eq!(t.leaf_count(), 2);
    assert_eq!(t.depth(), 6);
}

#[test]
fn bad_params_and_blocks_are_errors() {
    let mut bounds = block_grid(10, 1);
    let e = VamSplitTree::build(&bounds, &VamSplitParams { node_capacity: 1 }).unwrap_err();
    assert!(
        matches!(&e, IndexError::BadParam { name: "node_capacity", value, .. } if value == "1"),
        "{e:?}"
    );
    for depth in [0, 31] {
        let e = BqrTree::build(&bounds, &BqrParams { max_depth: depth }).unwrap_err();
        assert!(
            matches!(&e, IndexError::BadParam { name: "max_depth", value, .. } if *value == depth.to_string()),
            "{e:?}"
        );
    }
    bounds[3].aabb.max.x = f64::NAN;
    let bad_block = |e: &IndexError| matches!(e, IndexError::BadBlock { index: 3, .. });
    let e = BqrTree::build(&bounds, &BqrParams::default()).unwrap_err();
    assert!(bad_block(&e), "{e:?}");
    assert!(e.to_string().contains("block 3"), "{e}");
    for s in Structure::ALL {
        let e = s
            .build(&bounds)
            .err()
            .unwrap_or_else(|| panic!("{s} accepted a NaN box"));
        assert!(
            matches!(e, IndexError::BadBlock { structure, index: 3, .. } if structure == s),
            "{s}: {e}"
        );
    }
}

#[test]
fn empty_city_culls_nothing() {
    let f = Camera::new(DVec3::ZERO, 0.0, 0.0).frustum();
    for s in structures(&[]) {
        let mut out = Vec::new();
        s.cull(&CullQuery::new(&f), None, &mut out);
        assert!(out.is_empty());
    }
}

#[test]
fn vamsplit_fills_subtrees_to_capacity() {
    let bounds = block_grid(1000, 5);
    let t = VamSplitTree::build(&bounds, &VamSplitParams { node_capacity: 10 }).unwrap();
    t.check_invariants();
    // 1000 = 10³ blocks: a perfectly filled tree of height 2 with 100 full leaves.
    assert_eq!(t.height(), 2);
    assert_eq!(t.leaf_count(), 100);
    assert_eq!(t.node_count(), 111);
}

#[test]
fn hierarchies_visit_fewer_volumes_than_the_flat_list_at_street_level() {
    let bounds = block_grid(10_000, 11);
    let cam = {
        let mut c = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.3, 0.0);
        c.far = 2000.0;
        c
    };
    let f = cam.frustum();
    let idx = structures(&bounds);
    let mut checked = 0;
    for s in &idx {
        let mut out = Vec::new();
        let visits = s.cull(&CullQuery::new(&f), None, &mut out).nodes_visited;
        match s.structure() {
            Structure::Flat => assert_eq!(visits, 10_000),
            Structure::Bqr | Structure::Vamsplit => {
                assert!(visits < 5_000, "{}: {visits} visits", s.structure());
                checked += 1;
            }
            _ => {}
        }
    }
    // One BqR-tree and two VAMSplit trees (capacities 4 and 8), each checked on its own.
    assert_eq!(checked, 3);
}
