//! Relief impostors (Andujar et al.) built on real and generated cities: the nodes hold whole
//! blocks as the selection needs, the zenithal maps hold the buildings where they stand, every
//! node reaches the coverage target or is reported, and a hybrid walk keeps the silhouette
//! bound.

mod support;

use blockwalk::blockmap::{SelectOptions, Source};
use blockwalk::relief::map::{EMPTY, Q_MAX};
use blockwalk::relief::{build_field, ReliefField, ReliefOptions, Stop};
use blockwalk::scene::Scene;
use blockwalk::walk::FarField;
use glam::DVec2;
use std::collections::{BTreeSet, HashMap};
use support::data::helsinki_bqr_occlusion;

fn field(scene: &Scene, opts: &ReliefOptions) -> ReliefField {
    build_field(
        &scene.city,
        &scene.layout,
        &scene.building_meshes,
        opts,
        &|_, _| {},
    )
    .unwrap()
}

/// Every node holds whole blocks (all of each block's buildings), a child's blocks are its
/// parent's, siblings share none, the leaves hold every building of the city once, and the
/// selector accepts the nodes.
#[test]
fn nodes_hold_whole_blocks_and_every_building_once() {
    let scene = helsinki_bqr_occlusion();
    let f = field(
        &scene,
        &ReliefOptions {
            stop: Stop::All,
            ..ReliefOptions::default()
        },
    );
    let block_of: HashMap<u32, u32> = scene
        .layout
        .blocks
        .iter()
        .flat_map(|b| b.buildings.iter().map(move |id| (id.0, b.id.0)))
        .collect();
    let mut per_block: HashMap<u32, BTreeSet<u32>> = HashMap::new();
    for (&b, &k) in &block_of {
        per_block.entry(k).or_default().insert(b);
    }
    let mut in_leaves = vec![0u32; scene.city.buildings.len()];
    for (i, n) in f.nodes.iter().enumerate() {
        let mine: BTreeSet<u32> = n.buildings.iter().copied().collect();
        for k in &n.blocks {
            assert!(
                per_block[&k.0].is_subset(&mine),
                "node {i} cuts block {}",
                k.0
            );
        }
        if let Some(p) = n.parent {
            let theirs: BTreeSet<u32> = f.nodes[p].buildings.iter().copied().collect();
            assert!(mine.is_subset(&theirs), "node {i} outside its parent {p}");
        }
        if f.tree.nodes[n.node].is_leaf() {
            for &b in &n.buildings {
                in_leaves[b as usize] += 1;
            }
        }
    }
    for (b, &c) in in_leaves.iter().enumerate() {
        let expected = u32::from(block_of.contains_key(&(b as u32)));
        assert_eq!(c, expected, "building {b} in {c} leaves");
    }
    let sel = f.selector(&scene.bounds, SelectOptions::default());
    assert!(sel.is_ok(), "{:?}", sel.err());
    // Formula (6) holds exactly on the built tree.
    let (i, t, w) = f.tree.counts();
    assert_eq!(3 * i, t + w - 1);
    assert_eq!(f.formulas.nodes, f.nodes.len());
    // The competitive stop maps a top part of the same tree: every mapped node's parent is
    // mapped, and a node left out has meshes cheaper than its maps would be.
    let c = field(&scene, &ReliefOptions::default());
    assert!(c.nodes.len() < f.nodes.len() && !c.nodes.is_empty());
    let mapped: BTreeSet<usize> = c.nodes.iter().map(|n| n.node).collect();
    for n in &c.nodes {
        let tree_parent = f
            .tree
            .nodes
            .iter()
            .position(|p| p.children.iter().flatten().any(|&k| k as usize == n.node));
        assert_eq!(n.parent.map(|p| c.nodes[p].node), tree_parent);
    }
    let by_tree: HashMap<usize, &blockwalk::relief::NodeMaps> =
        f.nodes.iter().map(|n| (n.node, n)).collect();
    for (i, tn) in c.tree.nodes.iter().enumerate() {
        if mapped.contains(&i) {
            continue;
        }
        let tris: usize = by_tree[&i]
            .buildings
            .iter()
            .map(|&b| scene.building_meshes[b as usize].triangle_count())
            .sum();
        let side = by_tree[&i].m() as usize;
        let parent_mapped = c.tree.nodes.iter().enumerate().any(|(p, pn)| {
            mapped.contains(&p) && pn.children.iter().flatten().any(|&k| k as usize == i)
        });
        if parent_mapped {
            assert!(
                tris * blockwalk::blockmap::tree::MESH_BYTES_PER_TRIANGLE <= side * side * 30,
                "node {i} (depth {}) left out with {tris} triangles",
                tn.depth
            );
        }
    }
    assert!(c.selector(&scene.bounds, SelectOptions::default()).is_ok());
}

/// A zenithal texel whose 4 × 4 samples all fall inside one building's footprint holds that
/// building's height (within a quantum), and a texel no footprint comes within a texel of is
/// empty: checked against the footprints themselves, by brute force.
#[test]
fn zenithal_maps_hold_the_buildings_where_they_stand() {
    let scene = helsinki_bqr_occlusion();
    let f = field(
        &scene,
        &ReliefOptions {
            stop: Stop::All,
            ..ReliefOptions::default()
        },
    );
    let source = Source::new(&scene.city, &scene.layout, &scene.building_meshes).unwrap();
    let inside = |p: DVec2, rings: &[Vec<DVec2>]| {
        let mut c = false;
        for r in rings {
            for e in 0..r.len() {
                let (u, v) = (r[e], r[(e + 1) % r.len()]);
                if (u.y > p.y) != (v.y > p.y) && p.x < u.x + (p.y - u.y) / (v.y - u.y) * (v.x - u.x)
                {
                    c = !c;
                }
            }
        }
        c
    };
    let (mut full, mut empty) = (0, 0);
    for n in f.nodes.iter().filter(|n| n.depth >= 2) {
        let fr = &n.zenithal.frame;
        let t = fr.texel_m();
        let near: Vec<&blockwalk::blockmap::SourceBuilding> = n
            .buildings
            .iter()
            .filter_map(|&b| source.buildings[b as usize].as_ref())
            .collect();
        for j in 0..fr.m {
            for i in 0..fr.m {
                let q = n.zenithal.at(i, j);
                let c = fr.from_map(f64::from(i) + 0.5, f64::from(j) + 0.5, 0.0);
                let c = DVec2::new(c.x, c.y);
                let close: Vec<_> = near
                    .iter()
                    .filter(|b| {
                        c.x >= b.min.x - 1.5 * t
                            && c.x <= b.max.x + 1.5 * t
                            && c.y >= b.min.y - 1.5 * t
                            && c.y <= b.max.y + 1.5 * t
                    })
                    .collect();
                if close.is_empty() {
                    assert_eq!(
                        q, EMPTY,
                        "node {} texel {i},{j} far from any building",
                        n.node
                    );
                    empty += 1;
                    continue;
                }
                let samples: Vec<DVec2> = (0..16)
                    .map(|s| {
                        let p = fr.from_map(
                            f64::from(i) + (f64::from(s % 4) + 0.5) / 4.0,
                            f64::from(j) + (f64::from(s / 4) + 0.5) / 4.0,
                            0.0,
                        );
                        DVec2::new(p.x, p.y)
                    })
                    .collect();
                for b in &close {
                    if samples.iter().all(|&p| inside(p, &b.rings)) {
                        let z = n.z_range[0]
                            + f64::from(q) / f64::from(Q_MAX) * (n.z_range[1] - n.z_range[0]);
                        // The highest building of the texel wins; this one lies under it.
                        assert!(
                            z >= b.z1 - (n.z_range[1] - n.z_range[0]) / 65535.0 - 1e-6,
                            "node {} texel {i},{j}: {z} below building {} at {}",
                            n.node,
                            b.id.0,
                            b.z1
                        );
                        full += 1;
                    }
                }
            }
        }
    }
    assert!(
        full > 10_000 && empty > 10_000,
        "{full} full, {empty} empty texels checked"
    );
}

/// Every node with walls either reaches the coverage target or is listed with the coverage it
/// reached; with one oblique map allowed, many nodes fall short and every one is listed.
#[test]
fn nodes_below_the_coverage_target_are_reported() {
    let scene = helsinki_bqr_occlusion();
    for (max, expect_short) in [(16, false), (1, true)] {
        let opts = ReliefOptions {
            max_obliques: max,
            ..ReliefOptions::default()
        };
        let f = field(&scene, &opts);
        let listed: BTreeSet<usize> = f.summary.below_target.iter().map(|b| b.node).collect();
        for (i, n) in f.nodes.iter().enumerate() {
            let short = n.vote.seeable_m2 > 0.0 && n.vote.coverage < opts.coverage_target;
            assert_eq!(
                short,
                listed.contains(&i),
                "node {i}: {:?}",
                n.vote.coverage
            );
            assert!(n.obliques.len() <= max);
        }
        for b in &f.summary.below_target {
            assert!((f.nodes[b.node].vote.coverage - b.coverage).abs() < 1e-12);
        }
        assert_eq!(!listed.is_empty(), expect_short, "max {max}: {listed:?}");
    }
}

/// The pop of a switch of oblique maps, measured with and without the blend: along the orbit of
/// Helsinki, each frame's impostor pixels are cast twice at the same camera and selection, with
/// this frame's map sets and with the last frame's, and the colour changes between the two are
/// what the switches and blend steps of this frame changed. Without a blend a switch changes a
/// wall's colours at once; blended over 4 frames, each frame moves them a fifth of the way.
#[test]
fn blending_spreads_the_pop_of_a_switch_over_frames() {
    use blockwalk::relief::image::{cast_image, frame_nodes, MapSets, Prepared};
    let scene = helsinki_bqr_occlusion();
    let f = field(
        &scene,
        &ReliefOptions {
            stop: Stop::All,
            texel_m: 1.0,
            ..ReliefOptions::default()
        },
    );
    let prepared = Prepared::new(&f);
    let (w, h) = (160u32, 120u32);
    let (route, _) = blockwalk::walk::job::resolve_route(
        &blockwalk::route::RouteChoice::Orbit,
        &scene,
        f64::from(w) / f64::from(h),
    )
    .unwrap();
    let cameras = route.sample(120);
    let mut out = Vec::new();
    for frames in [0u32, 4] {
        let mut sel = f
            .selector(&scene.bounds, SelectOptions::new(2.0, 0.25).unwrap())
            .unwrap();
        let mut sets = MapSets::new(frames);
        let (mut changed, mut max_step, mut sum) = (0u64, 0u8, 0u64);
        for cam in &cameras {
            let s = sel.select(cam, h, None);
            let base = frame_nodes(prepared.infos(), &s.maps, cam, h);
            let mut last = base.clone();
            sets.peek(&mut last);
            let mut now = base;
            sets.apply(&mut now, cam);
            let a = cast_image(&f, &prepared, &last, cam, w, h);
            let b = cast_image(&f, &prepared, &now, cam, w, h);
            for k in 0..(w * h) as usize {
                if a.hit[k].is_none() || a.node[k] != b.node[k] {
                    continue;
                }
                let d = (0..3)
                    .map(|c| a.color[k][c].abs_diff(b.color[k][c]))
                    .max()
                    .unwrap();
                if d > 0 {
                    changed += 1;
                    sum += u64::from(d);
                    max_step = max_step.max(d);
                }
            }
        }
        eprintln!(
            "blend over {frames} frames: {changed} pixel changes from switches over {} frames, largest {max_step}, mean {:.1} (of 255)",
            cameras.len(),
            sum as f64 / changed.max(1) as f64
        );
        out.push((changed, max_step, sum));
    }
    let (none, blend) = (out[0], out[1]);
    assert!(
        none.0 > 100,
        "the orbit switched no wall's colours: {none:?}"
    );
    // Blended, the same changes come in five smaller steps: more pixels change, each by less.
    assert!(blend.0 > none.0, "{none:?} {blend:?}");
    assert!(
        u32::from(blend.1) * 10 <= u32::from(none.1) * 3 + 10,
        "largest step {} blended against {} at once",
        blend.1,
        none.1
    );
}
