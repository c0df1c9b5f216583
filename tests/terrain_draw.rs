//! Terrain as a drawn, depth-tested, occluding layer, against independent truths: the oracle's
//! ids against an f64 ray cast of the terrain's triangles and the blocks' boxes, the CPU
//! renderer's terrain colour against `appearance`, and (with an adapter) the GPU against the CPU
//! renderer and the oracle, the far field (BlockMaps) behind a ridge included.

mod support;

use blockwalk::blocks::BlockId;
use blockwalk::city::appearance::{self, BuildingStyle};
use blockwalk::city::{Mesh, VertexAppearance};
use blockwalk::geom::Camera;
use blockwalk::visibility::oracle::{self, box_mesh, SKY};
use blockwalk::visibility::{
    CpuFrameRenderer, FixedTerrain, FrameRenderer, HeightGrid, MeshOracle, TerrainDraw,
    VisibilityOracle, TERRAIN_ID,
};
use glam::{DVec3, DVec4, Vec3};

/// A ridge along y at x = 100 m, 30 m high (a Gaussian across x of σ 15 m).
fn ridge(x: f64, _y: f64) -> f64 {
    30.0 * (-(x - 100.0).powi(2) / (2.0 * 15.0f64.powi(2))).exp()
}

/// A round hill at (100, 0), 30 m high, on ground rising gently to the north.
fn hill(x: f64, y: f64) -> f64 {
    30.0 * (-((x - 100.0).powi(2) + y.powi(2)) / (2.0 * 20.0f64.powi(2))).exp() + 0.02 * y
}

/// A cliff: 12 m up over a few metres around x = 60.
fn cliff(x: f64, _y: f64) -> f64 {
    6.0 * (1.0 + ((x - 60.0) / 2.0).tanh())
}

/// A plane rising to the east and the north: z = 0.2 x + 0.1 y + 1.
fn slope(x: f64, y: f64) -> f64 {
    0.2 * x + 0.1 * y + 1.0
}

fn grid(step_m: f64) -> HeightGrid {
    let cells = (300.0 / step_m) as usize;
    HeightGrid {
        origin: [-50.0, -150.0],
        step_m,
        cells: (cells, cells),
    }
}

fn terrain(height: fn(f64, f64) -> f64, step_m: f64) -> FixedTerrain {
    FixedTerrain::from_heights(&grid(step_m), (3, 3), height)
}

/// A block: a box standing on the terrain (its base 1 m below the lowest terrain under its
/// footprint, as a building's foundation), `h` metres above its ground.
fn block_on(height: fn(f64, f64) -> f64, x: f64, y: f64, side: f64, h: f64) -> (Vec3, Vec3) {
    let corners = [(x, y), (x + side, y), (x, y + side), (x + side, y + side)];
    let lo = corners
        .iter()
        .map(|&(a, b)| height(a, b))
        .fold(f64::INFINITY, f64::min);
    let hi = corners
        .iter()
        .map(|&(a, b)| height(a, b))
        .fold(f64::NEG_INFINITY, f64::max);
    (
        DVec3::new(x, y, lo - 1.0).as_vec3(),
        DVec3::new(x + side, y + side, hi + h).as_vec3(),
    )
}

/// Block 1 behind the ridge (x 150..160), block 2 in front of it (x 40..50, off the line of
/// sight to block 1), block 3 beside.
fn blocks(height: fn(f64, f64) -> f64) -> Vec<(BlockId, Mesh, (Vec3, Vec3))> {
    [
        (1, 150.0, -5.0, 10.0, 8.0),
        (2, 40.0, 8.0, 10.0, 8.0),
        (3, 60.0, 40.0, 12.0, 20.0),
    ]
    .into_iter()
    .map(|(id, x, y, s, h)| {
        let (lo, hi) = block_on(height, x, y, s, h);
        (BlockId(id), box_mesh(lo, hi), (lo, hi))
    })
    .collect()
}

fn low_eye() -> Camera {
    Camera::looking_at(DVec3::new(0.0, 0.0, 1.7), DVec3::new(155.0, 0.0, 4.0))
}

fn high_eye() -> Camera {
    Camera::looking_at(DVec3::new(0.0, 0.0, 150.0), DVec3::new(155.0, 0.0, 4.0))
}

#[test]
fn a_ridge_hides_a_block_behind_it_until_the_eye_rises_over_it() {
    let t = terrain(ridge, 5.0);
    let bs = blocks(ridge);
    let meshes: Vec<(BlockId, Mesh)> = bs.iter().map(|(b, m, _)| (*b, m.clone())).collect();
    let (w, h) = (160, 90);
    for samples in [1, 3] {
        let bare = MeshOracle::supersampled(&meshes, samples);
        let over = bare.with_terrain(t.full());
        // Without terrain the block behind the ridge is seen from the street.
        assert!(bare.visible(&low_eye(), w, h).contains(&BlockId(1)));
        let low = over.visible(&low_eye(), w, h);
        assert!(
            !low.contains(&BlockId(1)),
            "hidden behind the ridge: {low:?}"
        );
        assert!(low.contains(&BlockId(2)), "in front of the ridge: {low:?}");
        let high = over.visible(&high_eye(), w, h);
        assert!(high.contains(&BlockId(1)), "seen over the ridge: {high:?}");
        assert!(!low.contains(&BlockId(TERRAIN_ID)) && !high.contains(&BlockId(TERRAIN_ID)));
        assert!(over.describe(w, h).contains("terrain"));
    }
}

#[test]
fn the_terrain_id_fills_the_buffer_but_is_never_reported_visible() {
    let t = terrain(hill, 10.0);
    let bs = blocks(hill);
    let refs: Vec<(BlockId, &Mesh)> = bs.iter().map(|(b, m, _)| (*b, m)).collect();
    let buf = oracle::render_ids_with_terrain(&refs, t.full(), &low_eye(), 96, 54);
    let terrain_px = buf.ids.iter().filter(|&&i| i == TERRAIN_ID).count();
    assert!(terrain_px > 96 * 10, "{terrain_px} terrain pixels");
    let vis = buf.visible();
    assert!(!vis.contains(&BlockId(TERRAIN_ID)));
    assert!(vis.contains(&BlockId(2)));
    // The terrain alone: nothing visible although half the image is terrain.
    let alone = oracle::render_ids_with_terrain(&[], t.full(), &low_eye(), 96, 54);
    assert!(alone.ids.contains(&TERRAIN_ID) && alone.visible().is_empty());
    assert!(
        oracle::visible_blocks_with_terrain(&[], Some(t.full()), &high_eye(), 96, 54, 2).is_empty()
    );
}

/// What the f64 ray through a pixel centre meets first: the terrain, a block, or nothing.
fn ray_cast(
    cam: &Camera,
    terrain: &Mesh,
    boxes: &[(BlockId, (Vec3, Vec3))],
    (w, h): (u32, u32),
    (x, y): (u32, u32),
) -> u32 {
    let inv = cam.clip_from_world().inverse();
    let ndc_x = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
    let ndc_y = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
    let un = |z: f64| {
        let p = inv * DVec4::new(ndc_x, ndc_y, z, 1.0);
        p.truncate() / p.w
    };
    let (o, b) = (un(0.0), un(1.0));
    let d = b - o;
    let mut best: Option<(f64, u32)> = None;
    let mut take = |t: f64, id: u32| {
        if (0.0..=1.0).contains(&t) && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, id));
        }
    };
    // Möller–Trumbore against every terrain triangle (the f32 vertices, in f64).
    for tri in terrain.indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|i| terrain.positions[tri[i] as usize].as_dvec3());
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let q = d.cross(e2);
        let det = e1.dot(q);
        if det.abs() < 1e-300 {
            continue;
        }
        let s = o - p[0];
        let u = s.dot(q) / det;
        let r = s.cross(e1);
        let v = d.dot(r) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            continue;
        }
        take(e2.dot(r) / det, TERRAIN_ID);
    }
    // Slabs against every box.
    for (id, (lo, hi)) in boxes {
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let (mut ta, mut tb) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        if t0 <= t1 {
            take(t0, id.0);
        }
    }
    best.map_or(SKY, |b| b.1)
}

#[test]
fn oracle_ids_over_terrain_match_brute_force_ray_casting() {
    let (w, h) = (64u32, 36u32);
    let cams = [
        low_eye(),
        high_eye(),
        Camera::looking_at(
            DVec3::new(-40.0, -120.0, 40.0),
            DVec3::new(100.0, 0.0, 10.0),
        ),
        Camera::looking_at(DVec3::new(20.0, 10.0, 14.0), DVec3::new(150.0, 30.0, 0.0)),
    ];
    for (name, height) in [
        ("ridge", ridge as fn(f64, f64) -> f64),
        ("hill", hill),
        ("cliff", cliff),
    ] {
        let t = terrain(height, 10.0);
        let bs = blocks(height);
        let refs: Vec<(BlockId, &Mesh)> = bs.iter().map(|(b, m, _)| (*b, m)).collect();
        let boxes: Vec<(BlockId, (Vec3, Vec3))> = bs.iter().map(|(b, _, x)| (*b, *x)).collect();
        let mut total = [0usize; 3];
        for cam in &cams {
            let buf = oracle::render_ids_with_terrain(&refs, t.full(), cam, w, h);
            let mut differ = 0;
            for y in 0..h {
                for x in 0..w {
                    let truth = ray_cast(cam, t.full(), &boxes, (w, h), (x, y));
                    let got = buf.ids[(y * w + x) as usize];
                    differ += (got != truth) as usize;
                    total[1] += (truth == TERRAIN_ID) as usize;
                    total[2] += (truth != TERRAIN_ID && truth != SKY) as usize;
                }
            }
            total[0] += differ;
            // Rasterisation and ray casting (both f64 over the same f32 vertices) may only
            // disagree where a pixel centre lies within rounding of an edge or of a depth tie.
            assert!(differ <= 2, "{name}: {differ} of {} pixels differ", w * h);
        }
        eprintln!(
            "{name}: {} pixels differ; the ray casts saw {} terrain and {} block pixels",
            total[0], total[1], total[2]
        );
        assert!(total[1] > 1000 && total[2] > 100, "{total:?}");
    }
}

/// A ground layer (a street strip at z = 0 across the view) in a colour of its own.
fn street() -> Mesh {
    let c = appearance::unit_rgb([200, 40, 40]);
    Mesh {
        positions: vec![
            Vec3::new(-50.0, -4.0, 0.0),
            Vec3::new(250.0, -4.0, 0.0),
            Vec3::new(250.0, 4.0, 0.0),
            Vec3::new(-50.0, 4.0, 0.0),
        ],
        normals: vec![Vec3::Z; 4],
        indices: vec![0, 1, 2, 0, 2, 3],
        appearance: vec![VertexAppearance { u_m: 0.0, style: 0 }; 4],
        styles: vec![BuildingStyle::flat(c, c)],
    }
}

fn terrain_rgb(n: Vec3) -> [u8; 3] {
    appearance::to_rgb8(appearance::shade(
        appearance::unit_rgb(appearance::TERRAIN),
        n.normalize_or_zero(),
    ))
}

#[test]
fn cpu_frames_draw_the_terrain_lit_instead_of_the_flat_ground() {
    let t = terrain(slope, 10.0);
    let bs = blocks(slope);
    let meshes: Vec<(BlockId, Mesh)> = bs.iter().map(|(b, m, _)| (*b, m.clone())).collect();
    let (w, h) = (128u32, 72u32);
    let cam = Camera::looking_at(
        DVec3::new(-30.0, -10.0, 20.0),
        DVec3::new(120.0, 10.0, 10.0),
    );
    let ground = street();
    let all: Vec<BlockId> = meshes.iter().map(|m| m.0).collect();
    let with = CpuFrameRenderer::new(&meshes, (w, h))
        .with_ground(&ground)
        .with_terrain(&t);
    assert!(with.describe().contains("terrain"));
    let img = with.draw(&cam, &all, true).unwrap().image.unwrap();
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
    let ids = oracle::render_ids_with_terrain(&refs, t.full(), &cam, w, h);
    // The plane's normal: every terrain pixel has exactly the lit terrain colour.
    let n = DVec3::new(-0.2, -0.1, 1.0).normalize().as_vec3();
    let want = terrain_rgb(n);
    let lit = |c: [u8; 3]| appearance::to_rgb8(appearance::shade(appearance::unit_rgb(c), Vec3::Z));
    let (street_rgb, plane_rgb) = (lit([200, 40, 40]), lit(appearance::GROUND));
    let (mut terrain_px, mut sky_px) = (0, 0);
    for (k, px) in img.pixels().enumerate() {
        let rgb = [px[0], px[1], px[2]];
        match ids.ids[k] {
            TERRAIN_ID => {
                terrain_px += 1;
                assert_eq!(rgb, want, "pixel {k}");
            }
            SKY => {
                sky_px += 1;
                assert_eq!(rgb, appearance::SKY, "pixel {k}");
            }
            _ => {}
        }
        // Neither the ground plane nor the street layer is drawn.
        assert!(rgb != street_rgb && rgb != plane_rgb, "pixel {k}: {rgb:?}");
    }
    assert!(terrain_px > 1000 && sky_px > 100, "{terrain_px} {sky_px}");
    // Without terrain the street and the ground plane show.
    let without = CpuFrameRenderer::new(&meshes, (w, h)).with_ground(&ground);
    let flat = without.draw(&cam, &all, true).unwrap().image.unwrap();
    assert!(flat.pixels().any(|p| [p[0], p[1], p[2]] == street_rgb));
    assert!(flat.pixels().any(|p| [p[0], p[1], p[2]] == plane_rgb));
}

#[test]
fn cpu_frames_hide_buildings_behind_the_ridge_under_terrain_colour() {
    let t = terrain(ridge, 5.0);
    let bs = blocks(ridge);
    let meshes: Vec<(BlockId, Mesh)> = bs.iter().map(|(b, m, _)| (*b, m.clone())).collect();
    let (w, h) = (160u32, 90u32);
    let cam = low_eye();
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
    // Where block 1 is seen without terrain, the frame with terrain shows terrain (its colours
    // are those of the terrain's normals, lit) and the id buffer says terrain.
    let bare = oracle::render_ids(&refs, &cam, w, h);
    let ids = oracle::render_ids_with_terrain(&refs, t.full(), &cam, w, h);
    let img = CpuFrameRenderer::new(&meshes, (w, h))
        .with_terrain(&t)
        .draw(&cam, &[BlockId(1), BlockId(2), BlockId(3)], true)
        .unwrap()
        .image
        .unwrap();
    let lit: std::collections::HashSet<[u8; 3]> =
        t.full().normals.iter().map(|&n| terrain_rgb(n)).collect();
    let mut behind = 0;
    for k in 0..(w * h) as usize {
        if bare.ids[k] == 1 {
            behind += 1;
            assert_eq!(ids.ids[k], TERRAIN_ID);
            let p = img.get_pixel(k as u32 % w, k as u32 / w);
            assert!(lit.contains(&[p[0], p[1], p[2]]), "pixel {k}: {p:?}");
        }
    }
    assert!(
        behind > 20,
        "block 1 covers {behind} pixels without terrain"
    );
}

#[cfg(feature = "render")]
mod gpu {
    use super::*;
    use blockwalk::blockmap::{build_map, BuildOptions, Source};
    use blockwalk::city::extrude::extrude_city;
    use blockwalk::render::{Gpu, GpuFrameRenderer, RenderError, Shading, NO_MAP};
    use blockwalk::visibility::synthetic::SyntheticCity;
    use glam::DVec2;
    use std::sync::Arc;

    use crate::support::gpu::gpu_or_skip;

    /// GPU ids against the oracle: (pixels that differ, of which depth ties between the terrain
    /// and a block, pixels).
    fn compare_ids(
        gpu_ids: &[Option<BlockId>],
        refs: &[(BlockId, &Mesh)],
        full: &Mesh,
        cam: &Camera,
        (w, h): (u32, u32),
    ) -> (usize, usize) {
        let cpu = oracle::render_ids_with_terrain(refs, full, cam, w, h);
        let blocks = oracle::render_ids(refs, cam, w, h);
        let ground = oracle::render_ids_with_terrain(&[], full, cam, w, h);
        let (mut differ, mut ties) = (0, 0);
        for (k, got) in gpu_ids.iter().enumerate() {
            let want = (cpu.ids[k] != SKY).then_some(BlockId(cpu.ids[k]));
            if *got != want {
                differ += 1;
                let (a, b) = (blocks.depth[k], ground.depth[k]);
                if blocks.ids[k] != SKY && ground.ids[k] != SKY && (a - b).abs() <= 1e-6 {
                    ties += 1;
                }
            }
        }
        (differ, ties)
    }

    #[test]
    fn gpu_terrain_frames_equal_the_cpu_reference() {
        let Some(gpu) = gpu_or_skip("gpu_terrain_frames_equal_the_cpu_reference") else {
            return;
        };
        let (w, h) = (320u32, 180u32);
        let cams = [
            low_eye(),
            high_eye(),
            Camera::looking_at(
                DVec3::new(-40.0, -120.0, 40.0),
                DVec3::new(100.0, 0.0, 10.0),
            ),
        ];
        let mut gpu = Some(gpu);
        for (name, height) in [
            ("ridge", ridge as fn(f64, f64) -> f64),
            ("hill", hill),
            ("cliff", cliff),
        ] {
            let t = Arc::new(terrain(height, 5.0));
            let bs = blocks(height);
            let meshes: Vec<(BlockId, Mesh)> = bs.iter().map(|(b, m, _)| (*b, m.clone())).collect();
            let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
            let all: Vec<BlockId> = meshes.iter().map(|m| m.0).collect();
            // The first renderer takes the test's device, the others a device of their own.
            let device = gpu.take().map_or_else(Gpu::new_headless, Ok).unwrap();
            let r = GpuFrameRenderer::with_gpu(device, &meshes, &street(), (w, h))
                .unwrap()
                .with_terrain(t.clone())
                .unwrap();
            let streets = street();
            let cpu_r = CpuFrameRenderer::new(&meshes, (w, h))
                .with_ground(&streets)
                .with_terrain(t.as_ref());
            for cam in &cams {
                let ids = r.draw_shaded(cam, &all, Shading::Ids).unwrap().block_ids();
                assert!(ids.contains(&Some(BlockId(TERRAIN_ID))));
                let (differ, ties) = compare_ids(&ids, &refs, t.full(), cam, (w, h));
                let lit = r.draw(cam, &all, true).unwrap().image.unwrap();
                let cpu = cpu_r.draw(cam, &all, true).unwrap().image.unwrap();
                let colours = lit
                    .pixels()
                    .zip(cpu.pixels())
                    .filter(|(g, c)| (0..3).any(|k| g[k].abs_diff(c[k]) > 1))
                    .count();
                let n = (w * h) as f64;
                eprintln!(
                    "{name}: ids differ at {differ} px ({:.3} %), {ties} of them depth ties; \
                     colours differ by > 1/255 at {colours} px ({:.3} %)",
                    differ as f64 / n * 100.0,
                    colours as f64 / n * 100.0
                );
                // As the box tests: only pixels within rounding of an edge may differ.
                assert!(
                    (differ - ties) as f64 <= 0.005 * n,
                    "{name}: {differ} ids differ"
                );
                assert!(
                    colours as f64 <= 0.01 * n,
                    "{name}: {colours} colours differ"
                );
            }
        }
        // With a terrain, no block may take the terrain's id.
        let taken = vec![(BlockId(TERRAIN_ID), box_mesh(Vec3::ZERO, Vec3::ONE))];
        let r = GpuFrameRenderer::with_gpu(Gpu::new_headless().unwrap(), &taken, &street(), (w, h))
            .unwrap();
        let e = r.with_terrain(Arc::new(terrain(ridge, 50.0))).unwrap_err();
        assert!(
            matches!(e, RenderError::BlockIdTooLarge { id: TERRAIN_ID, .. }),
            "{e:?}"
        );
    }

    #[test]
    fn far_maps_behind_a_ridge_are_hidden_where_the_terrain_is_in_front() {
        let Some(gpu) =
            gpu_or_skip("far_maps_behind_a_ridge_are_hidden_where_the_terrain_is_in_front")
        else {
            return;
        };
        let sc = SyntheticCity::generate(3, 3, 11, DVec2::new(5.0e5, 6.0e6));
        let building_meshes = extrude_city(&sc.city);
        let source = Source::new(&sc.city, &sc.layout, &building_meshes).unwrap();
        let ids: Vec<BlockId> = sc.layout.blocks.iter().map(|b| b.id).collect();
        let all = source.buildings_of(&sc.layout, &ids);
        let (map, _, _) = build_map(&source, &all, &BuildOptions::default()).unwrap();
        let b = map.aabb();
        let (lo, hi) = (b.min, b.max);
        let top = hi.z;
        // A ridge along y 60 m west of the city, 0.6 of its tallest building high; the terrain
        // stops 20 m short of the city, so all of it lies in front of the map from the west.
        let x_r = lo.x - 60.0;
        let grid = HeightGrid {
            origin: [lo.x - 250.0, lo.y - 150.0],
            step_m: 5.0,
            cells: (46, ((hi.y - lo.y + 300.0) / 5.0) as usize),
        };
        let ridge_h = 0.6 * top;
        let t = Arc::new(FixedTerrain::from_heights(&grid, (2, 2), move |x, _| {
            ridge_h * (-(x - x_r).powi(2) / (2.0 * 15.0f64.powi(2))).exp()
        }));
        let c = b.center();
        let cam = Camera::looking_at(DVec3::new(lo.x - 220.0, c.y, 0.45 * top), c);
        let (w, h) = (320u32, 180u32);
        let meshes: Vec<(BlockId, Mesh)> = Vec::new();
        let ground = Mesh::default();
        let maps = [&map];
        let bare =
            GpuFrameRenderer::with_gpu(Gpu::new_headless().unwrap(), &meshes, &ground, (w, h))
                .unwrap()
                .with_far_field(&maps)
                .unwrap();
        let over = GpuFrameRenderer::with_gpu(gpu, &meshes, &ground, (w, h))
            .unwrap()
            .with_far_field(&maps)
            .unwrap()
            .with_terrain(t.clone())
            .unwrap();
        let alone = bare.draw_hybrid(&cam, &[], &[0], false).unwrap();
        let frame = over.draw_hybrid(&cam, &[], &[0], false).unwrap();
        let terrain_ids = oracle::render_ids_with_terrain(&[], t.full(), &cam, w, h);
        let is_terrain = |x: i64, y: i64| {
            x >= 0
                && y >= 0
                && x < w as i64
                && y < h as i64
                && terrain_ids.ids[(y as u32 * w + x as u32) as usize] == TERRAIN_ID
        };
        let (mut hidden, mut shown_over_terrain) = (0, 0);
        for k in 0..(w * h) as usize {
            let (x, y) = ((k as u32 % w) as i64, (k as u32 / w) as i64);
            let inner = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)]
                .iter()
                .all(|(dx, dy)| is_terrain(x + dx, y + dy));
            if inner && alone.map_ids[k] != NO_MAP {
                hidden += 1;
                shown_over_terrain += (frame.map_ids[k] != NO_MAP) as usize;
            }
        }
        eprintln!(
            "far field behind the ridge: {} map pixels alone, {} over terrain; {hidden} inside \
             the ridge hidden, {shown_over_terrain} shown through it",
            alone.far_pixels, frame.far_pixels
        );
        assert!(hidden > 100, "the ridge covers {hidden} map pixels");
        assert_eq!(shown_over_terrain, 0, "map pixels drawn through the ridge");
        assert!(frame.far_pixels > 0, "the map shows above the ridge");
        assert!(frame.far_pixels < alone.far_pixels);
        // The CPU reference composites the same way: far pixels within 1 %.
        let cpu = blockwalk::blockmap::CpuHybridRenderer::new(&meshes, &ground, vec![&map], (w, h))
            .with_terrain(t.as_ref());
        let cpu_far = cpu
            .draw_with_far(&cam, &[], &[0], false)
            .unwrap()
            .far_pixels
            .unwrap();
        eprintln!(
            "far pixels over terrain: GPU {}, CPU {cpu_far}",
            frame.far_pixels
        );
        assert!(
            frame.far_pixels.abs_diff(cpu_far) * 100 <= cpu_far.max(1),
            "{} vs {cpu_far}",
            frame.far_pixels
        );
    }
}
