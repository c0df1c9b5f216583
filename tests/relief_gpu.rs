//! The GPU ray caster of relief impostors (`render/relief.wgsl`) against the CPU reference image
//! (`relief::image::cast_image`, the f32 caster the shader mirrors) on the impostors of the
//! bundled Helsinki: node id, depth and colour per pixel, from random views with near planes
//! from 0.1 to 10 m, from far away (small nodes, horizon nodes drawn flat), with the eye inside a
//! node's box, at grazing angles and above columns that stand out of their node's box, and over
//! many nodes at once; a control that must fail (one node's zenithal map shifted by one texel);
//! and the composite with meshes against the CPU hybrid renderer.
//!
//! Needs an adapter (lavapipe in CI). Without one the tests skip loudly, unless the GPU
//! is required (`BLOCKWALK_REQUIRE=gpu`), in which case they fail.
#![cfg(feature = "render")]

mod support;

use blockwalk::blockmap::FrameRays;
use blockwalk::blocks::BlockId;
use blockwalk::geom::Camera;
use blockwalk::relief::cast::{cast_f32, cast_f64, cast_flat, Face, Hit};
use blockwalk::relief::image::{cast_image, frame_nodes, FrameNode, Prepared};
use blockwalk::relief::{
    build_field, CpuReliefRenderer, NodeMaps, ReliefField, ReliefMap, ReliefOptions,
};
use blockwalk::render::{GpuFrameRenderer, NO_MAP};
use blockwalk::scene::Scene;
use blockwalk::visibility::FrameRenderer;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use std::collections::HashSet;
use support::data::helsinki_bqr_occlusion;
use support::gpu::gpu_or_skip;

const W: u32 = 160;
const H: u32 = 120;

/// A margin of the `f64` twin below this (texels, or height units over the node's range) is a
/// tie: the `f32` walks of the GPU and the CPU may part there.
const TIE: f64 = 1e-4;

/// The largest depth difference of a common hit: lavapipe's division is not IEEE-rounded in the
/// last bit, so the hit's parameter (a quotient) and the depth (another) may differ by a few
/// units in the last place; 1e-6 is 17 of them at depth 1.
const DEPTH_TOL: f64 = 1e-6;

/// A depth difference of a wall point from an oblique map's stored depth this near the match
/// tolerance (quantised units) is a tie of the colouring.
const Q_TIE: f64 = 0.5;

/// Helsinki (bundled) and its relief impostors for every node of the tree at 1 m a texel (M
/// from formula (9), at most 128), horizon nodes drawn flat below the paper's 2 pixels: every
/// path of the shader has pixels.
fn helsinki() -> (Scene, ReliefField) {
    let scene = helsinki_bqr_occlusion();
    let field = build_field(
        &scene.city,
        &scene.layout,
        &scene.building_meshes,
        &ReliefOptions {
            stop: blockwalk::relief::Stop::All,
            texel_m: 1.0,
            flat_px: blockwalk::relief::image::PAPER_FLAT_PX,
            // Each view compared on its own: no blend carried from one view to the next (the
            // blends have their own test).
            blend_frames: 0,
            ..ReliefOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();
    (scene, field)
}

/// A camera at `eye` looking at `target` with the near plane at `near` metres.
fn cam(eye: DVec3, target: DVec3, near: f64) -> Camera {
    let mut c = Camera::looking_at(eye, target);
    c.aspect = W as f64 / H as f64;
    c.near = near;
    c.far = 20_000.0;
    c
}

/// A near plane from 0.1 to 10 m, log-uniform.
fn near(rng: &mut impl Rng) -> f64 {
    10f64.powf(rng.random_range(-1.0..1.0))
}

/// The views of the comparison: `(what, camera, nodes drawn)`.
fn views(field: &ReliefField) -> Vec<(String, Camera, Vec<usize>)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
    let mut out = Vec::new();
    let n = field.nodes.len();
    // Random orbits around nodes of every depth.
    let step = (n / 24).max(1);
    for i in (0..n).step_by(step) {
        let b = field.nodes[i].aabb;
        let (c, diag) = (b.center(), b.extent().length());
        let az = rng.random_range(0.0..std::f64::consts::TAU);
        let el = rng.random_range(5f64..75.0).to_radians();
        let dist = diag * rng.random_range(0.4..1.4);
        let dir = DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        let nr = near(&mut rng);
        out.push((
            format!("node {i} random, near {nr:.2}"),
            cam(c + dir * dist, c, nr),
            vec![i],
        ));
    }
    // The eye inside a node's box, low and high, looking across it; and grazing above the roofs.
    for i in [0, n / 3, n / 2, n - 1] {
        let b = field.nodes[i].aabb;
        let (c, e) = (b.center(), b.extent());
        for (k, h) in [0.3, 0.9].into_iter().enumerate() {
            let eye = DVec3::new(c.x + 0.13 * e.x, c.y - 0.07 * e.y, b.min.z + h * e.z);
            let yaw = rng.random_range(0.0..std::f64::consts::TAU);
            let target = eye + DVec3::new(yaw.cos(), yaw.sin(), -0.3 * k as f64);
            let nr = 0.1 + 0.4 * k as f64;
            out.push((
                format!("node {i} eye inside at {h}, near {nr}"),
                cam(eye, target, nr),
                vec![i],
            ));
        }
        let eye = DVec3::new(b.min.x - 5.0, b.min.y - 5.0, b.max.z + 0.5);
        let target = DVec3::new(b.max.x, b.max.y, b.max.z - 0.02 * e.length());
        out.push((format!("node {i} grazing"), cam(eye, target, 0.1), vec![i]));
    }
    // Above a column that stands out of its node's box (a texel at the box's edge is covered
    // when most of it is), outside the box, looking down and outwards.
    for (i, node) in field.nodes.iter().enumerate() {
        if let Some((by, top, dir)) = sticking_out(node).filter(|s| s.0 > 0.2) {
            let eye = top + dir * 2.0 * by + DVec3::new(0.0, 0.0, 15.0);
            out.push((
                format!("node {i} column {by:.2} m out of the box"),
                cam(eye, top + dir * 3.0 * by, 0.5),
                vec![i],
            ));
        }
    }
    // Many nodes at once: every node of a depth (and the leaves), from high and low, near and
    // far; far away the nodes are a few pixels and the low ones horizon nodes (flat quads).
    let root = field.nodes[0].aabb;
    let (c, diag) = (root.center(), root.extent().length());
    let leaves: Vec<usize> = (0..n)
        .filter(|&i| field.tree.nodes[field.nodes[i].node].is_leaf())
        .collect();
    let sets = [1, 2].map(|d| {
        let at: Vec<usize> = (0..n).filter(|&i| field.nodes[i].depth == d).collect();
        (format!("depth {d}"), at)
    });
    for (set, at) in sets.into_iter().chain([("leaves".to_string(), leaves)]) {
        if at.is_empty() {
            continue;
        }
        for (what, dir, dist, nr) in [
            ("high oblique", DVec3::new(-0.6, -0.8, 0.7), 0.8, 5.0),
            ("low inside the city", DVec3::new(0.3, -0.2, 0.03), 0.3, 0.1),
            ("half-way, low", DVec3::new(-0.8, 0.5, 0.12), 1.5, 2.0),
            ("far away", DVec3::new(0.9, 0.4, 0.5), 2.5, 10.0),
            ("very far away", DVec3::new(-0.5, 0.8, 0.8), 4.0, 10.0),
        ] {
            let eye = c + dir.normalize() * dist * diag;
            out.push((
                format!("{set}: {} nodes, {what}", at.len()),
                cam(eye, c, nr),
                at.clone(),
            ));
        }
    }
    out
}

/// The column of `node` that stands farthest out of its box: by how much (metres), the centre
/// of its top (local frame) and the outward normal of the box side it passes.
fn sticking_out(node: &NodeMaps) -> Option<(f64, DVec3, DVec3)> {
    let (o, s) = node.tex_to_local();
    let (b, m) = (node.aabb, node.m());
    let mut worst: Option<(f64, DVec3, DVec3)> = None;
    for j in 0..m {
        for i in 0..m {
            let q = node.zenithal.at(i, j);
            if q == 0 {
                continue;
            }
            let lo = o + DVec3::new(f64::from(i), f64::from(j), 0.0) * s;
            let hi = o + DVec3::new(f64::from(i + 1), f64::from(j + 1), 0.0) * s;
            let top = (lo + hi) * 0.5 + DVec3::new(0.0, 0.0, f64::from(q) / 65535.0 * s.z);
            for (by, dir) in [
                (b.min.x - lo.x, DVec3::NEG_X),
                (b.min.y - lo.y, DVec3::NEG_Y),
                (hi.x - b.max.x, DVec3::X),
                (hi.y - b.max.y, DVec3::Y),
            ] {
                if by > worst.map_or(0.0, |w| w.0) {
                    worst = Some((by, top, dir));
                }
            }
        }
    }
    worst
}

/// Per-pixel agreement of the GPU image with the CPU reference.
#[derive(Debug, Default, Clone)]
struct Agreement {
    pixels: u64,
    hits_cpu: u64,
    hits_gpu: u64,
    /// Node-id differences (a hit on one side only, or another node) not explained by a tie.
    mask: u64,
    /// Node-id differences at pixels the f64 twin names as ties.
    tie: u64,
    /// Hits the GPU draws and the reference leaves out: the walk's own hit, at the GPU's depth,
    /// at a pixel outside the rectangle the reference casts a node in.
    outside: u64,
    /// Hits the CPU has that lost on the GPU to the ground already in the depth buffer (not
    /// the caster).
    ground: u64,
    /// Common hits on a wall (coloured from the obliques).
    walls: u64,
    /// Common hits on a horizon node's flat quad.
    flat: u64,
    /// Horizon nodes drawn.
    flat_nodes: u64,
    /// Common hits whose depths differ.
    depth: u64,
    /// Largest depth difference of a common hit.
    depth_max: f64,
    /// Common hits whose colours differ, not explained by a tie of the colouring.
    color: u64,
    /// Common hits whose colours differ where the reference's colouring is a tie (a projected
    /// texel coordinate within [`TIE`] of a texel line, or a depth difference within [`Q_TIE`]
    /// of the match tolerance).
    color_tie: u64,
    /// Largest channel difference of a common hit.
    color_max: u8,
}

impl Agreement {
    /// The GPU image equals the reference: every node id but at ties and where the reference
    /// does not cast, every colour but at ties of the colouring, every depth within
    /// [`DEPTH_TOL`].
    fn equal(&self) -> bool {
        self.mask == 0 && self.color == 0 && self.depth_max <= DEPTH_TOL
    }

    fn add(&mut self, a: &Agreement) {
        self.pixels += a.pixels;
        self.hits_cpu += a.hits_cpu;
        self.hits_gpu += a.hits_gpu;
        self.mask += a.mask;
        self.tie += a.tie;
        self.outside += a.outside;
        self.ground += a.ground;
        self.walls += a.walls;
        self.flat += a.flat;
        self.flat_nodes += a.flat_nodes;
        self.depth += a.depth;
        self.depth_max = self.depth_max.max(a.depth_max);
        self.color += a.color;
        self.color_tie += a.color_tie;
        self.color_max = self.color_max.max(a.color_max);
    }
}

/// Draws `far` from `camera` on the GPU (the far pass alone over the ground) and on the CPU
/// (`cpu_field`, the reference) and compares them pixel by pixel.
fn compare(
    gpu: &GpuFrameRenderer,
    cpu_field: &ReliefField,
    prepared: &Prepared<'_>,
    camera: &Camera,
    far: &[usize],
) -> Agreement {
    let frame = gpu.draw_hybrid(camera, &[], far, true).unwrap();
    let depth = frame.depth.as_ref().unwrap();
    let nodes = frame_nodes(prepared.infos(), far, camera, H);
    let cpu = cast_image(cpu_field, prepared, &nodes, camera, W, H);
    let mut a = Agreement {
        pixels: u64::from(W * H),
        flat_nodes: nodes.iter().filter(|f| f.flat).count() as u64,
        ..Agreement::default()
    };
    let debug = std::env::var_os("BLOCKWALK_DEBUG_MISMATCH").is_some();
    for (k, (&g, &c)) in frame.map_ids.iter().zip(&cpu.node).enumerate() {
        let (x, y) = (k as u32 % W, k as u32 / W);
        a.hits_cpu += u64::from(c != NO_MAP);
        a.hits_gpu += u64::from(g != NO_MAP);
        if g == NO_MAP && c != NO_MAP && depth[k] <= cpu.depth[k] {
            a.ground += 1;
            continue;
        }
        if g != c && c == NO_MAP {
            // The walk's own hit where the reference does not cast: outside the rectangle it
            // casts a node's pixels in (its box's, a pixel or two wider), which a column standing
            // out of the box may leave.
            let f = nodes.iter().find(|f| f.node as u32 == g).expect("drawn");
            let n = &cpu_field.nodes[f.node];
            let fr = FrameRays::new(camera, W, H);
            let ray = f.xform.ray(fr.view_dir(x, y), fr.near);
            let levels = prepared.levels(f.node);
            let cast = if f.flat {
                cast_flat(levels, n.m(), &ray)
            } else {
                cast_f32(levels, n.m(), &ray)
            };
            if cast.hit.is_some_and(|h| fr.depth(h.t as f32) == depth[k]) {
                a.outside += 1;
                continue;
            }
        }
        if g != c {
            // A tie of the f64 twin of any node drawn at this pixel explains it.
            let tie = nodes.iter().any(|f| {
                let n = &cpu_field.nodes[f.node];
                let r = n.twin_ray(camera, W, H, x, y);
                let levels = prepared.levels(f.node);
                let cast = if f.flat {
                    cast_flat(levels, n.m(), &r)
                } else {
                    cast_f64(levels, n.m(), &r)
                };
                cast.is_tie(TIE)
            });
            if tie {
                a.tie += 1;
            } else {
                a.mask += 1;
                if debug {
                    eprintln!(
                        "  ({x}, {y}) gpu node {g} cpu node {c}, depth gpu {} cpu {}, cpu {:?}",
                        depth[k], cpu.depth[k], cpu.hit[k]
                    );
                }
            }
            continue;
        }
        if g == NO_MAP {
            continue;
        }
        if let Some(h) = cpu.hit[k] {
            a.walls += u64::from(matches!(h.face, Face::WallX | Face::WallY));
            a.flat += u64::from(h.face == Face::Flat);
        }
        let dd = (f64::from(depth[k]) - f64::from(cpu.depth[k])).abs();
        a.depth_max = a.depth_max.max(dd);
        a.depth += u64::from(dd > 0.0);
        if debug && dd > DEPTH_TOL {
            eprintln!(
                "  ({x}, {y}) depth gpu {:e} cpu {:e}, {:?}",
                depth[k], cpu.depth[k], cpu.hit[k]
            );
        }
        let dc = (0..4)
            .map(|ch| frame.rgba[4 * k + ch].abs_diff(cpu.color[k][ch]))
            .max()
            .unwrap_or(0);
        a.color_max = a.color_max.max(dc);
        if dc > 0 {
            let f = nodes.iter().find(|f| f.node as u32 == g).expect("drawn");
            let (tm, qm) = shade_margin(&cpu_field.nodes[f.node], f, camera, x, y, cpu.hit[k]);
            if tm < TIE || qm < Q_TIE {
                a.color_tie += 1;
            } else {
                a.color += 1;
            }
            if debug {
                eprintln!(
                    "  ({x}, {y}) node {g} colour gpu {:?} cpu {:?}, {:?}, margins: texel {tm:e}, \
                     depth {qm:e}",
                    &frame.rgba[4 * k..4 * k + 4],
                    cpu.color[k],
                    cpu.hit[k]
                );
            }
        }
    }
    a
}

/// How near the reference's colouring of the hit `hit` of pixel `(x, y)` on node `f` came to
/// another decision: the smallest distance, over the chosen obliques and evaluated in `f64` on
/// the reference's own `f32` ray and hit, of a projected texel coordinate to a texel line
/// (texels) and of a depth difference to the match tolerance (quantised units). Infinite for a
/// hit that is not on a wall.
fn shade_margin(
    n: &NodeMaps,
    f: &FrameNode,
    camera: &Camera,
    x: u32,
    y: u32,
    hit: Option<Hit>,
) -> (f64, f64) {
    let mut out = (f64::INFINITY, f64::INFINITY);
    let Some(h) = hit.filter(|h| matches!(h.face, Face::WallX | Face::WallY)) else {
        return out;
    };
    let fr = FrameRays::new(camera, W, H);
    let ray = f.xform.ray(fr.view_dir(x, y), fr.near);
    let t = h.t as f32;
    let p = [0, 1, 2].map(|a| f64::from(ray.o[a] + ray.d[a] * t));
    let xf = n.oblique_xforms();
    let m = f64::from(n.m());
    for k in f.chosen.iter().flatten() {
        let (ob, x) = (&n.obliques[*k as usize], &xf[*k as usize]);
        let val = |r: &[f32; 4]| {
            f64::from(r[0]) * p[0]
                + f64::from(r[1]) * p[1]
                + f64::from(r[2]) * p[2]
                + f64::from(r[3])
        };
        let (a, b, dq) = (val(&x.rows[0]), val(&x.rows[1]), val(&x.rows[2]));
        let frac = |v: f64| (v - v.round()).abs();
        out.0 = out.0.min(frac(a)).min(frac(b));
        if a >= 0.0 && b >= 0.0 && a < m && b < m {
            let q = ob.at(a.floor() as u32, b.floor() as u32);
            if q != 0 {
                out.1 = out
                    .1
                    .min(((f64::from(q) - dq).abs() - f64::from(x.tol_q)).abs());
            }
        }
    }
    out
}

/// The renderer of `scene`'s meshes and ground with `field` uploaded through the far-field
/// interface, as the walk makes it.
fn gpu_renderer(
    gpu: blockwalk::render::Gpu,
    scene: &Scene,
    field: &ReliefField,
) -> GpuFrameRenderer {
    GpuFrameRenderer::with_gpu(gpu, scene.draw_meshes(), &scene.ground, (W, H))
        .unwrap()
        .with_far(field)
        .unwrap()
}

#[test]
fn gpu_relief_caster_equals_the_cpu_reference() {
    let Some(gpu) = gpu_or_skip("gpu_relief_caster_equals_the_cpu_reference") else {
        return;
    };
    let t0 = std::time::Instant::now();
    let (scene, field) = helsinki();
    eprintln!(
        "{} nodes, M = {}, {} oblique maps, built in {:.1} s",
        field.nodes.len(),
        field.m,
        field.nodes.iter().map(|n| n.obliques.len()).sum::<usize>(),
        t0.elapsed().as_secs_f64()
    );
    let r = gpu_renderer(gpu, &scene, &field);
    let relief = r.relief().expect("the relief pass");
    assert_eq!(relief.nodes(), field.nodes.len());
    let described = r.describe();
    eprintln!("{described}");
    assert!(described.contains("relief-impostor nodes"), "{described}");
    let prepared = Prepared::new(&field);
    let mut total = Agreement::default();
    let all = views(&field);
    for (what, camera, far) in &all {
        let a = compare(&r, &field, &prepared, camera, far);
        eprintln!("{what}: {a:?}");
        assert!(a.hits_cpu > 0, "{what}: the view shows no node");
        assert!(a.equal(), "{what}: {a:?}");
        total.add(&a);
    }
    let share = |v: u64| 100.0 * v as f64 / total.pixels as f64;
    eprintln!(
        "{} views: {total:?}; node ids equal on {:.5} % of the pixels (ties {:.5} %, lost to \
         the ground {:.5} %, outside the reference's rectangles {:.5} %)",
        all.len(),
        100.0 - share(total.mask + total.tie + total.ground + total.outside),
        share(total.tie),
        share(total.ground),
        share(total.outside)
    );
    // The views exercise walls (oblique colours), flat quads and horizon nodes.
    assert!(total.walls > 1000, "{total:?}");
    assert!(total.flat_nodes > 0 && total.flat > 0, "{total:?}");
    assert!(total.hits_cpu > 100_000, "{total:?}");
    // Measured on lavapipe over 88 views (1 689 600 pixels, 456 964 hits of the reference): no
    // node id differs but at 15 hits level with or behind the ground already in the depth
    // buffer, and at 316 pixels (0.019 %) where the GPU draws the walk's own hit and the
    // reference does not cast (a column standing out of its node's box, outside the pixel
    // rectangle of the box the reference casts in); no tie; the depth differs on 0.7 % of the
    // common hits, by at most 7.9e-7 (lavapipe's division is not IEEE-rounded in the last
    // bit, and the hit's parameter with it); one colour differs, at a point 9e-6 texels from
    // an oblique texel line.
    assert_eq!(total.mask, 0, "{total:?}");
    assert!(
        total.tie * 1000 <= total.pixels,
        "ties above 0.1 %: {total:?}"
    );
    assert!(total.ground * 1000 <= total.pixels, "{total:?}");
    assert!(total.outside * 1000 <= total.pixels, "{total:?}");
    assert!(total.depth_max <= DEPTH_TOL, "{total:?}");
    assert_eq!(total.color, 0, "{total:?}");
    assert!(
        total.color_tie * 10_000 <= total.hits_cpu,
        "colour ties above 0.01 % of the hits: {total:?}"
    );
}

/// `map` moved one texel east (depth and colour; the west column left empty).
fn shifted(map: &ReliefMap) -> ReliefMap {
    let mut s = map.clone();
    let m = map.m() as usize;
    for j in 0..m {
        for i in 0..m {
            let k = j * m + i;
            let (q, c) = if i == 0 {
                (0, [0; 4])
            } else {
                (map.depth[k - 1], map.color[k - 1])
            };
            s.depth[k] = q;
            s.color[k] = c;
        }
    }
    s
}

#[test]
fn a_node_shifted_by_one_texel_fails_the_comparison() {
    let Some(gpu) = gpu_or_skip("a_node_shifted_by_one_texel_fails_the_comparison") else {
        return;
    };
    let (scene, field) = helsinki();
    let all = views(&field);
    // The node of the first view, shifted on the GPU only.
    let (_, _, first) = &all[0];
    let node = first[0];
    let mut moved = field.clone();
    let n = &mut moved.nodes[node];
    n.zenithal = shifted(&n.zenithal);
    n.upper = n.zenithal.pyramid().into_iter().skip(1).collect();
    let r = gpu_renderer(gpu, &scene, &moved);
    let prepared = Prepared::new(&field);
    let (mut seen, mut failed, mut mask) = (0, 0, 0);
    for (what, camera, far) in all.iter().filter(|v| v.2.contains(&node)) {
        let a = compare(&r, &field, &prepared, camera, far);
        eprintln!("shifted node {node}, {what}: {a:?}");
        if a.hits_cpu == 0 {
            continue;
        }
        seen += 1;
        // The shift shows in the node ids (the columns moved), the colours or the depths.
        if !a.equal() {
            failed += 1;
        }
        mask += a.mask;
    }
    eprintln!("shifted node {node}: {failed} of {seen} views fail, {mask} node ids differ");
    assert!(seen >= 2, "node {node} is drawn in {seen} views");
    assert_eq!(failed, seen);
    assert!(mask > 1000, "{mask}");
}

#[test]
fn meshes_and_relief_composite_by_depth() {
    let Some(gpu) = gpu_or_skip("meshes_and_relief_composite_by_depth") else {
        return;
    };
    let (scene, field) = helsinki();
    let r = gpu_renderer(gpu, &scene, &field);
    let cpu = CpuReliefRenderer::new(scene.draw_meshes(), &scene.ground, &field, (W, H));
    // The depth-1 node with the most buildings as impostors, every block outside it as meshes.
    let node = (0..field.nodes.len())
        .filter(|&i| field.nodes[i].depth == 1)
        .max_by_key(|&i| field.nodes[i].buildings.len())
        .expect("a node of depth 1");
    let far = vec![node];
    let inside: HashSet<BlockId> = field.nodes[node].blocks.iter().copied().collect();
    let visible: Vec<BlockId> = scene
        .layout
        .blocks
        .iter()
        .map(|b| b.id)
        .filter(|b| !inside.contains(b))
        .collect();
    let b = field.nodes[node].aabb;
    let (c, half) = (b.center(), 0.5 * b.extent().length());
    let (mut gpu_px, mut cpu_px, mut hidden) = (0u64, 0u64, 0u64);
    // From the streets around the node, 20 m up, looking at its centre over the meshes.
    for v in 0..4 {
        let az = std::f64::consts::FRAC_PI_2 * f64::from(v) + 0.4;
        let eye = DVec3::new(
            c.x + (half + 150.0) * az.cos(),
            c.y + (half + 150.0) * az.sin(),
            b.min.z + 20.0,
        );
        let camera = cam(eye, c, 1.0);
        let g = r.draw_with_far(&camera, &visible, &far, false).unwrap();
        let alone = r.draw_with_far(&camera, &[], &far, false).unwrap();
        let names: Vec<&str> = g.passes.iter().map(|p| p.0).collect();
        assert_eq!(names, ["meshes", "far"]);
        let cf = cpu.draw_with_far(&camera, &visible, &far, false).unwrap();
        let (gp, cp, ap) = (
            g.far_pixels.unwrap(),
            cf.far_pixels.unwrap(),
            alone.far_pixels.unwrap(),
        );
        eprintln!("view {v}: far pixels GPU {gp} (alone {ap}), CPU {cp}");
        assert!(gp <= ap);
        hidden += ap - gp;
        gpu_px += gp;
        cpu_px += cp;
    }
    // The meshes hide part of the impostors.
    assert!(hidden * 10 > gpu_px, "{hidden} of {gpu_px}");
    // The far pixels agree but for the edges where the two rasterisers of the meshes part.
    assert!(cpu_px > 1000, "{cpu_px}");
    assert!(
        gpu_px.abs_diff(cpu_px) * 100 <= cpu_px,
        "GPU {gpu_px} vs CPU {cpu_px}"
    );
    // An index the renderer does not hold is an error, not a panic.
    let camera = cam(c + DVec3::new(0.0, -1.0, 1.0) * half, c, 1.0);
    let bad = field.nodes.len() + 3;
    let err = r
        .draw_with_far(&camera, &[], &[bad], false)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("far-field map {bad} does not exist")),
        "{err}"
    );
}

/// Switches of oblique maps blended over frames: the GPU and the CPU renderers keep their own
/// state and draw a moving camera's frames with the same blends, pixel for pixel on the
/// impostors' walls; the sequence has blends (counted by a third copy of the state).
#[test]
fn blended_switches_are_drawn_alike() {
    let Some(gpu) = gpu_or_skip("blended_switches_are_drawn_alike") else {
        return;
    };
    let (scene, mut field) = helsinki();
    field.options.blend_frames = 4;
    let r = gpu_renderer(gpu, &scene, &field);
    let cpu = CpuReliefRenderer::new(scene.draw_meshes(), &scene.ground, &field, (W, H));
    let prepared = Prepared::new(&field);
    let mut sets = blockwalk::relief::image::MapSets::new(4);
    let node = (0..field.nodes.len())
        .filter(|&i| field.nodes[i].depth == 1 && field.nodes[i].obliques.len() >= 4)
        .max_by_key(|&i| field.nodes[i].buildings.len())
        .expect("a node of depth 1 with four obliques");
    let far = vec![node];
    let b = field.nodes[node].aabb;
    let (c, half) = (b.center(), 0.5 * b.extent().length());
    let (mut blended, mut compared, mut differ) = (0, 0u64, 0u64);
    // Round the node in 24 steps, 60 m up: its best-aligned oblique changes on the way.
    for step in 0..24 {
        let az = std::f64::consts::TAU * f64::from(step) / 24.0;
        let eye = DVec3::new(
            c.x + (half + 200.0) * az.cos(),
            c.y + (half + 200.0) * az.sin(),
            b.max.z + 60.0,
        );
        let camera = cam(eye, c, 1.0);
        let mut nodes = frame_nodes(prepared.infos(), &far, &camera, H);
        sets.apply(&mut nodes, &camera);
        blended += nodes.iter().filter(|f| f.previous.is_some()).count();
        let g = r.draw_hybrid(&camera, &[], &far, false).unwrap();
        let c = cast_image(&field, &prepared, &nodes, &camera, W, H);
        // And the CPU renderer, which keeps its own state, draws the same blends.
        let cf = cpu.draw_with_far(&camera, &[], &far, true).unwrap();
        let ci = cf.image.unwrap();
        for k in 0..(W * H) as usize {
            if g.map_ids[k] != node as u32 || c.node[k] != node as u32 {
                continue;
            }
            compared += 1;
            let gp = &g.rgba[4 * k..4 * k + 3];
            let cp = &c.color[k][..3];
            let rp = &ci.as_raw()[4 * k..4 * k + 3];
            differ += u64::from(gp != cp || rp != cp);
        }
    }
    eprintln!("24 frames: {blended} blended node-frames, {differ} of {compared} pixels differ");
    assert!(
        blended >= 2,
        "the route switched no oblique set ({blended})"
    );
    // The mesh pass's ground differs at a few edge pixels between the two rasterisers; the
    // impostors' pixels, blended or not, are the same.
    assert!(differ * 1000 <= compared, "{differ} of {compared}");
}
