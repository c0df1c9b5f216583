//! Spatial structures against brute force: no false culls, ever (seed 003 §4).

use blockwalk::blocks::BlockId;
use blockwalk::geom::BoundingSphere;
use blockwalk::geom::{Aabb3, Camera, CoherenceState, Frustum};
use blockwalk::index::{
    enclosing_sphere, synthetic::block_grid, BlockBounds, BqrParams, BqrTree, CityIndex, CullQuery,
    FlatList, IndexError, NoStructure, ObjectId, RstarIndex, Structure, VamSplitParams,
    VamSplitTree,
};
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::collections::HashSet;

fn block(i: usize, min: DVec3, max: DVec3, center: DVec2) -> BlockBounds {
    BlockBounds::from_box(
        BlockId(i as u32),
        Aabb3::new(min, max),
        center,
        10 + i as u32,
    )
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

/// The plain cull runs on the traversal layout (chains collapsed, leaf buckets); with a filter
/// that keeps everything it runs on the build tree, volume by volume. Both accept a block
/// exactly when its own leaf volume (box ∩ sphere) is not outside the frustum.
fn layout_matches_build_tree(bounds: &[BlockBounds], cams: &[Camera]) -> Result<(), TestCaseError> {
    let tree = BqrTree::build(bounds, &BqrParams::default()).unwrap();
    tree.check_invariants();
    for cam in cams {
        let f = cam.frustum();
        let q = CullQuery::with_eye(&f, cam.position);
        let (mut fast, mut slow) = (Vec::new(), Vec::new());
        let a = tree.cull(&q, None, &mut fast);
        let b = tree.cull(&q, Some(&mut |_: &Aabb3| true), &mut slow);
        let sa: HashSet<BlockId> = fast.iter().copied().collect();
        let sb: HashSet<BlockId> = slow.iter().copied().collect();
        prop_assert_eq!(sa.len(), fast.len(), "a block reported twice");
        prop_assert_eq!(&sa, &sb);
        prop_assert_eq!(a.blocks_accepted, b.blocks_accepted);
        prop_assert_eq!(a.triangles_accepted, b.triangles_accepted);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn bqr_layout_accepts_what_the_build_tree_accepts_uniform(
        bounds in uniform_city(), cams in prop::collection::vec(camera(), 1..6),
    ) {
        layout_matches_build_tree(&bounds, &cams)?;
    }

    #[test]
    fn bqr_layout_accepts_what_the_build_tree_accepts_clustered(
        bounds in clustered_city(), cams in prop::collection::vec(camera(), 1..6),
    ) {
        layout_matches_build_tree(&bounds, &cams)?;
    }
}

#[test]
fn bqr_layout_on_a_grid_and_with_mobile_objects() {
    let bounds = block_grid(5000, 9);
    let mut t = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    t.check_invariants();
    let laid = t.traversal_nodes();
    // Buckets of a few blocks and collapsed chains: far fewer nodes to visit than built.
    assert!(
        laid > 0 && laid * 4 < t.nodes_len(),
        "{laid} of {}",
        t.nodes_len()
    );
    let cam = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.4, 0.0);
    let f = cam.frustum();
    let q = CullQuery::with_eye(&f, cam.position);
    let mut before = Vec::new();
    let s0 = t.cull(&q, None, &mut before);
    assert!(s0.blocks_accepted > 0);
    // An object present: the build tree serves (the layout has no objects); the volumes only
    // grew, so every block accepted before still is.
    let obj = Aabb3::new(DVec3::new(1.0, 1.0, 0.0), DVec3::new(3.0, 2.0, 1.5));
    t.insert_object(ObjectId(7), obj).unwrap();
    assert_eq!(t.traversal_nodes(), 0);
    t.check_invariants();
    let mut with = Vec::new();
    t.cull(&q, None, &mut with);
    let sb: HashSet<BlockId> = before.iter().copied().collect();
    let sw: HashSet<BlockId> = with.iter().copied().collect();
    assert!(sb.is_subset(&sw));
    // Removed and refitted: laid out again, as built.
    t.remove_object(ObjectId(7)).unwrap();
    t.refit();
    t.check_invariants();
    assert_eq!(t.traversal_nodes(), laid);
    let mut after = Vec::new();
    let s1 = t.cull(&q, None, &mut after);
    assert_eq!(after, before);
    assert_eq!(s1, s0);
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

/// A block of 1–4 buildings, each an axis-aligned prism `(dx, dy, w, d, floor, height)` placed in
/// a 100 m cell at `(x, y)`: L-shapes, a tower on a low block, empty corners.
type RawBuilding = (f64, f64, f64, f64, f64, f64);

fn building_city() -> impl Strategy<Value = Vec<Vec<Aabb3>>> {
    prop::collection::vec(
        (
            -800.0..800.0f64,
            -800.0..800.0f64,
            prop::collection::vec(
                (
                    0.0..80.0f64,
                    0.0..80.0f64,
                    2.0..40.0f64,
                    2.0..40.0f64,
                    prop::sample::select(vec![0.0, 0.0, 5.0]),
                    3.0..150.0f64,
                ),
                1..5,
            ),
        ),
        0..60,
    )
    .prop_map(|blocks: Vec<(f64, f64, Vec<RawBuilding>)>| {
        blocks
            .into_iter()
            .map(|(x, y, bs)| {
                bs.into_iter()
                    .map(|(dx, dy, w, d, lo, h)| {
                        Aabb3::new(
                            DVec3::new(x + dx, y + dy, lo),
                            DVec3::new(x + dx + w, y + dy + d, lo + h),
                        )
                    })
                    .collect()
            })
            .collect()
    })
}

/// Bounds as `block_bounds` makes them: the union box and the smallest sphere around every
/// building's vertices.
fn building_bounds(city: &[Vec<Aabb3>]) -> Vec<BlockBounds> {
    city.iter()
        .enumerate()
        .map(|(i, bs)| {
            let aabb = bs.iter().fold(Aabb3::EMPTY, |a, b| a.union(*b));
            let corners: Vec<DVec3> = bs.iter().flat_map(|b| b.corners()).collect();
            BlockBounds {
                id: BlockId(i as u32),
                aabb,
                sphere: enclosing_sphere(&corners).unwrap(),
                center: aabb.center().truncate(),
                triangles: 12 * bs.len() as u32,
            }
        })
        .collect()
}

/// Blocks whose geometry (some building) meets the frustum: exact box–frustum tests per building.
fn geometry_visible(city: &[Vec<Aabb3>], f: &Frustum) -> Vec<BlockId> {
    city.iter()
        .enumerate()
        .filter(|(_, bs)| bs.iter().any(|b| f.intersects_aabb_exact(b)))
        .map(|(i, _)| BlockId(i as u32))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// The sphere holds every vertex exactly (no tolerance) and is never larger than the sphere
    /// around the box of the same points (that one holds them all, so the smallest is smaller).
    #[test]
    fn enclosing_sphere_holds_every_vertex(
        pts in prop::collection::vec((-500.0..500.0f64, -500.0..500.0f64, 0.0..200.0f64), 1..80),
        offset in prop::sample::select(vec![0.0, 5e3, 3e4, 6e6]),
    ) {
        let pts: Vec<DVec3> = pts.into_iter().map(|(x, y, z)| DVec3::new(x + offset, y, z)).collect();
        let s = enclosing_sphere(&pts).unwrap();
        for p in &pts {
            prop_assert!(s.contains_point(*p), "{p} outside {s:?}");
        }
        let around_box = BoundingSphere::from_aabb(&Aabb3::from_points(pts.iter().copied()));
        prop_assert!(
            s.radius <= around_box.radius * (1.0 + 1e-9) + 1e-6,
            "{} > box sphere {}", s.radius, around_box.radius
        );
        // Some point is on the sphere (it is not loose all round).
        let far = pts.iter().map(|p| p.distance(s.center)).fold(0.0, f64::max);
        prop_assert!(s.radius - far < 1e-6 * (1.0 + far));
    }

    /// With the blocks' own tight spheres, culling keeps every block whose geometry is in view,
    /// and the BqR-tree's result is the same as with box-only leaves or a subset of it.
    #[test]
    fn tight_leaf_spheres_never_lose_a_visible_block(
        city in building_city(),
        cams in prop::collection::vec(camera(), 1..6),
    ) {
        let bounds = building_bounds(&city);
        for b in &bounds {
            prop_assert!(b.sphere.radius <= BoundingSphere::from_aabb(&b.aabb).radius * (1.0 + 1e-9) + 1e-6);
        }
        let boxed: Vec<BlockBounds> = bounds
            .iter()
            .map(|b| BlockBounds::from_box(b.id, b.aabb, b.center, b.triangles))
            .collect();
        let tight = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
        tight.check_invariants();
        let loose = BqrTree::build(&boxed, &BqrParams::default()).unwrap();
        let others = structures(&bounds);
        let mut state = CoherenceState::default();
        for cam in &cams {
            let f = cam.frustum();
            let truth = geometry_visible(&city, &f);
            let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
            tight.cull(&CullQuery::new(&f), None, &mut a);
            loose.cull(&CullQuery::new(&f), None, &mut b);
            tight.cull_coherent(&f, &mut state, &mut c);
            let (a, b, c): (HashSet<_>, HashSet<_>, HashSet<_>) =
                (a.into_iter().collect(), b.into_iter().collect(), c.into_iter().collect());
            for id in &truth {
                prop_assert!(a.contains(id), "tight BqR culls visible block {id:?}, camera {cam:?}");
            }
            prop_assert!(a.is_subset(&b), "tight leaves accept a block box leaves do not");
            prop_assert_eq!(&a, &c);
            for s in &others {
                let mut out = Vec::new();
                s.cull(&CullQuery::with_eye(&f, cam.position), Some(&mut |_: &Aabb3| true), &mut out);
                let got: HashSet<BlockId> = out.into_iter().collect();
                for id in &truth {
                    prop_assert!(got.contains(id), "{} culls visible block {id:?}", s.structure());
                }
            }
        }
    }
}

/// Blocks of a low slab with a tall tower in the middle: the box's sphere is larger than the
/// geometry's (70.54 m against 77.78 m), and over many views the tight leaves accept strictly fewer blocks, losing none.
#[test]
fn tight_leaf_spheres_accept_strictly_fewer_blocks_on_towers() {
    let mut city = Vec::new();
    for gx in 0..20 {
        for gy in 0..20 {
            let (x, y) = (gx as f64 * 100.0 - 1000.0, gy as f64 * 100.0 - 1000.0);
            city.push(vec![
                Aabb3::new(DVec3::new(x, y, 0.0), DVec3::new(x + 70.0, y + 70.0, 8.0)),
                Aabb3::new(
                    DVec3::new(x + 27.5, y + 27.5, 0.0),
                    DVec3::new(x + 42.5, y + 42.5, 120.0),
                ),
            ]);
        }
    }
    let bounds = building_bounds(&city);
    let boxed: Vec<BlockBounds> = bounds
        .iter()
        .map(|b| BlockBounds::from_box(b.id, b.aabb, b.center, b.triangles))
        .collect();
    let tight = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    let loose = BqrTree::build(&boxed, &BqrParams::default()).unwrap();
    // Views at tower height with a short far plane, where a box's empty upper corners (above
    // the slab, beside the tower) are what a frustum meets.
    let cams: Vec<Camera> = (0..400)
        .map(|k| {
            let t = k as f64;
            let eye = DVec3::new(
                900.0 * (t * 0.37).sin(),
                900.0 * (t * 0.53).cos(),
                20.0 + 130.0 * (0.5 + 0.5 * (t * 0.71).sin()),
            );
            let mut c = Camera::new(eye, t * 0.9, 0.3 * (t * 1.3).sin());
            c.far = 250.0;
            c
        })
        .collect();
    let (mut n_tight, mut n_loose) = (0usize, 0usize);
    for cam in &cams {
        let f = cam.frustum();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        tight.cull(&CullQuery::new(&f), None, &mut a);
        loose.cull(&CullQuery::new(&f), None, &mut b);
        let got: HashSet<BlockId> = a.iter().copied().collect();
        for id in geometry_visible(&city, &f) {
            assert!(got.contains(&id), "lost {id:?} at {cam:?}");
        }
        n_tight += a.len();
        n_loose += b.len();
    }
    assert!(n_tight < n_loose, "tight {n_tight} vs box leaves {n_loose}");
}
