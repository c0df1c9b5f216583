//! The kept buildings of a block drawn in few calls ([`Batching::Runs`]) against independent
//! truths:
//!
//! - the layout: every block's buildings are contiguous in [`DrawUnits::building_meshes`], in
//!   the blocks' order, so a block with every building kept is one call;
//! - the count: the calls the renderer issues equal [`DrawUnits::draw_calls`] and a brute-force
//!   count of the maximal runs of kept buildings in that order;
//! - the image: on Helsinki views along the paper route (frustum, and frustum + occlusion, then
//!   the per-building test), the frame drawn with merged calls equals, pixel for pixel, the
//!   frame drawn with one call per building, lit and in the id pass; the id pass still names
//!   the building at each pixel.
//!
//! The GPU tests need an adapter (lavapipe will do) and skip loudly without one, unless the
//! GPU is required (`BLOCKWALK_REQUIRE=gpu`).
#![cfg(feature = "render")]

mod support;

use blockwalk::blocks::BlockId;
use blockwalk::city::{BuildingId, Mesh};
use blockwalk::geom::Camera;
use blockwalk::index::{CullQuery, Structure};
use blockwalk::render::{Batching, MeshRenderer, RenderOptions, Shading};
use blockwalk::route::{paper_route, Lens, Obstacles, PaperRouteParams, StreetGraph};
use blockwalk::scene::{BuildingsMode, DrawOrder, DrawUnits, Scene};
use std::collections::HashSet;

use support::gpu::gpu_or_skip;

/// Helsinki (bundled) with the BqR-tree, the occlusion culler and building units.
fn helsinki() -> Scene {
    let mut scene = support::data::helsinki_bqr_occlusion();
    scene
        .build_units(&Default::default(), BuildingsMode::On)
        .unwrap();
    scene
}

/// `n` cameras along the paper route (seed 003 §5), as the walk samples them.
fn paper_cameras(scene: &Scene, n: usize) -> Vec<Camera> {
    let graph = StreetGraph::from_world_lines(&scene.layout.street_edges, &scene.city.frame);
    let obstacles = Obstacles::from_buildings(&scene.city.buildings, &scene.city.frame);
    paper_route(
        &scene.city_bounds(),
        Some(&graph),
        &obstacles,
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap()
    .sample(n)
}

/// The buildings the walk keeps from `cam`: blocks through the BqR-tree (and the cull map when
/// `occlusion`), then each building of the surviving blocks; and the blocks kept.
fn kept_buildings(scene: &Scene, cam: &Camera, occlusion: bool) -> (Vec<BlockId>, Vec<BuildingId>) {
    let units = scene.units.as_ref().unwrap();
    let index = scene.index(Structure::Bqr).unwrap();
    let frustum = cam.frustum();
    let mut blocks = Vec::new();
    let mut kept = Vec::new();
    if occlusion {
        let culler = scene.occlusion.as_ref().unwrap();
        let mut map = culler.new_map();
        let st = culler.build(cam, &mut map);
        let usable = st.skipped.is_none() && st.cells_covered > 0;
        culler.traverse(index, cam, &map, st, &mut blocks);
        units
            .buildings
            .refine(&frustum, usable.then_some(&map), &blocks, &mut kept);
    } else {
        index.cull(
            &CullQuery::with_eye(&frustum, cam.position),
            None,
            &mut blocks,
        );
        units.buildings.refine(&frustum, None, &blocks, &mut kept);
    }
    (blocks, kept)
}

/// Brute force: walk the building units in their stored order and count the maximal runs of
/// kept ones (every building unit has triangles: asserted).
fn brute_runs(units: &DrawUnits, kept: &HashSet<BlockId>) -> usize {
    let mut runs = 0;
    let mut prev = false;
    for (id, m) in units.building_meshes() {
        assert!(
            m.triangle_count() > 0,
            "building unit {id:?} without triangles"
        );
        let now = kept.contains(id);
        if now && !prev {
            runs += 1;
        }
        prev = now;
    }
    runs
}

/// A deterministic generator for the random subsets (SplitMix64).
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[test]
fn buildings_are_laid_out_block_by_block_and_runs_are_counted_exactly() {
    let scene = helsinki();
    let units = scene.units.as_ref().unwrap();
    // Each block's buildings are one contiguous stretch, in the layout's block order and the
    // block's own order.
    let expected: Vec<BlockId> = scene
        .layout
        .blocks
        .iter()
        .flat_map(|b| units.buildings.of(b.id).iter())
        .map(|bb| units.building_id(bb.id))
        .collect();
    let stored: Vec<BlockId> = units.building_meshes().iter().map(|(id, _)| *id).collect();
    assert_eq!(stored, expected);
    // A block with every building kept is one call; all the buildings of k blocks at most k.
    let mut whole_blocks = 0;
    for b in &scene.layout.blocks {
        let ids: Vec<BlockId> = units
            .buildings
            .of(b.id)
            .iter()
            .map(|bb| units.building_id(bb.id))
            .collect();
        if !ids.is_empty() {
            assert_eq!(units.draw_calls(&ids), 1, "block {:?}", b.id);
            whole_blocks += 1;
        }
    }
    assert!(whole_blocks > 50, "{whole_blocks} blocks with buildings");
    // Random subsets (each building kept with probability 1/8 … 7/8), repeats and unknown ids:
    // the count equals brute force, and DrawOrder over the same meshes agrees.
    let order = DrawOrder::new(&units.meshes);
    let mut rng = 7u64;
    for case in 0..300 {
        let p = 1 + (case % 7) as u64;
        let mut ids: Vec<BlockId> = stored
            .iter()
            .copied()
            .filter(|_| splitmix(&mut rng) % 8 < p)
            .collect();
        if case % 3 == 0 {
            ids.extend(ids.clone().iter().take(5));
            ids.push(BlockId(u32::MAX - 1));
        }
        // Any order: the calls do not depend on it.
        ids.sort_by_cached_key(|_| splitmix(&mut rng));
        let set: HashSet<BlockId> = ids.iter().copied().collect();
        let want = brute_runs(units, &set);
        assert_eq!(units.draw_calls(&ids), want, "case {case}");
        assert_eq!(order.calls(&ids), want, "case {case}");
        assert!(want <= set.len());
    }
    // Blocks: neighbouring block ids are neighbours in the buffer.
    let blocks: Vec<BlockId> = scene.block_meshes().iter().map(|(b, _)| *b).collect();
    let nonempty = scene
        .block_meshes()
        .iter()
        .filter(|(_, m)| m.triangle_count() > 0)
        .count();
    assert_eq!(units.draw_calls(&blocks), usize::from(nonempty > 0));
}

#[test]
fn merged_calls_draw_the_same_frames_as_one_call_per_building() {
    let Some(gpu) = gpu_or_skip("merged_calls_draw_the_same_frames_as_one_call_per_building")
    else {
        return;
    };
    let scene = helsinki();
    let units = scene.units.as_ref().unwrap();
    let refs: Vec<(BlockId, &Mesh)> = units.meshes.iter().map(|(b, m)| (*b, m)).collect();
    let (w, h) = (320u32, 180u32);
    let mut r = MeshRenderer::with_ground(
        &gpu,
        &refs,
        &scene.ground,
        RenderOptions {
            width: w,
            height: h,
        },
    )
    .unwrap();
    assert_eq!(r.batching(), Batching::Runs);
    let cams = paper_cameras(&scene, 12);
    let (mut units_drawn, mut calls, mut kept_blocks, mut frames) = (0u64, 0u64, 0u64, 0);
    for (f, cam) in cams.iter().enumerate() {
        for occlusion in [false, true] {
            let (blocks, kept) = kept_buildings(&scene, cam, occlusion);
            if kept.is_empty() {
                continue;
            }
            let ids: Vec<BlockId> = kept.iter().map(|&b| units.building_id(b)).collect();
            let set: HashSet<BlockId> = ids.iter().copied().collect();
            let tri: u64 = ids.iter().map(|&u| units.unit_triangles(u)).sum();
            for shading in [Shading::Lit, Shading::Ids] {
                r = r.with_batching(Batching::Runs);
                let merged = r.draw_shaded(&gpu, cam, &ids, shading).unwrap();
                r = r.with_batching(Batching::PerUnit);
                let single = r.draw_shaded(&gpu, cam, &ids, shading).unwrap();
                let what = format!("frame {f}, occlusion {occlusion}, {shading:?}");
                // Same units and triangles, counted exactly.
                assert_eq!(merged.timings.blocks as usize, set.len(), "{what}");
                assert_eq!(single.timings.blocks, merged.timings.blocks, "{what}");
                assert_eq!(merged.timings.triangles, tri, "{what}");
                assert_eq!(single.timings.triangles, tri, "{what}");
                // Calls: one per building, against one per run of neighbours.
                assert_eq!(single.timings.draws as usize, set.len(), "{what}");
                assert_eq!(
                    merged.timings.draws as usize,
                    brute_runs(units, &set),
                    "{what}"
                );
                assert_eq!(
                    merged.timings.draws as usize,
                    units.draw_calls(&ids),
                    "{what}"
                );
                // The image, pixel for pixel.
                let differ = merged
                    .rgba
                    .chunks_exact(4)
                    .zip(single.rgba.chunks_exact(4))
                    .filter(|(a, b)| a != b)
                    .count();
                assert_eq!(differ, 0, "{what}: {differ} pixels differ");
                if shading == Shading::Ids {
                    // The id pass names buildings, and only kept ones.
                    let seen: HashSet<BlockId> = merged.block_ids().into_iter().flatten().collect();
                    assert!(!seen.is_empty(), "{what}: nothing drawn");
                    assert!(seen.is_subset(&set), "{what}: an id not drawn");
                } else {
                    units_drawn += set.len() as u64;
                    calls += merged.timings.draws as u64;
                    kept_blocks += blocks.len() as u64;
                    frames += 1;
                }
            }
        }
    }
    assert!(frames >= 12, "{frames} frames with buildings in view");
    eprintln!(
        "Helsinki paper route, {frames} frames: {:.1} buildings in {:.1} calls per frame ({:.1} blocks kept)",
        units_drawn as f64 / frames as f64,
        calls as f64 / frames as f64,
        kept_blocks as f64 / frames as f64
    );
    // Merging does merge: fewer calls than buildings.
    assert!(
        calls < units_drawn,
        "{calls} calls for {units_drawn} buildings"
    );
}
