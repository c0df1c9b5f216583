//! Far-field GPU figures (a plain main that prints them; no timing assertions): the BlockMap ray
//! caster of `render/blockmap.wgsl` on Helsinki's maps at K = 64 (BLOCKMAPS.md goal 4: one
//! full-screen K = 64 map at 1280×1024 in ≤ 1 ms, seed 000 §5's "more than 1 kHz"), and N maps
//! at once (every map of a quadtree level) from a fly-over, beside the mesh pass of all blocks
//! from the same camera.
//!
//! `cargo bench --features render --bench farfield` (or the built bench binary). GPU time from
//! timestamp queries when the adapter has them, else wall time (said in the output). Environment:
//! `BLOCKWALK_FARFIELD_SIZE=WxH` (default 1280x1024), `BLOCKWALK_FARFIELD_FRAMES=N` (default 20;
//! the median is printed), `BLOCKWALK_FARFIELD_CITY=DIR` (default the bundled Helsinki).

use blockwalk::blockmap::cast::TexRay;
use blockwalk::blockmap::image::twin_ray;
use blockwalk::blockmap::{BlockMap, BuildOptions, CityMapsOptions, Stop, TreeOptions};
use blockwalk::blocks::BlockId;
use blockwalk::geom::Camera;
use blockwalk::render::GpuFrameRenderer;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use glam::DVec3;
use std::path::PathBuf;

/// Whether a texture-space ray meets the box `[0, K]² × [0, 1]` at `t ≥ 0`.
fn meets_box(ray: &TexRay<f64>, k: f64) -> bool {
    let hi = [k, k, 1.0];
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for ((&o, &d), &hi) in ray.o.iter().zip(&ray.d).zip(&hi) {
        if d == 0.0 {
            if o < 0.0 || o > hi {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((0.0 - o) / d, (hi - o) / d);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    t0 < t1
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let size = std::env::var("BLOCKWALK_FARFIELD_SIZE")
        .ok()
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((1280u32, 1024u32));
    let frames: usize = std::env::var("BLOCKWALK_FARFIELD_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20)
        .max(1);
    let dir = std::env::var_os("BLOCKWALK_FARFIELD_CITY")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/helsinki"));
    let src = CitySource::parse(&dir, None, None, &[], 7).expect("city source");
    let scene = Scene::load(
        &src,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .expect("scene");
    let maps = scene
        .blockmaps(
            &CityMapsOptions {
                tree: TreeOptions {
                    build: BuildOptions::default(),
                    stop: Stop::Levels(4),
                    ..TreeOptions::default()
                },
                checks: 0,
                check_size: (16, 9),
            },
            &|_, _| {},
        )
        .expect("maps");
    let nodes = &maps.maps.maps;
    let refs: Vec<&BlockMap> = nodes.iter().map(|m| &m.map).collect();
    let r = match GpuFrameRenderer::new(scene.block_meshes(), &scene.ground, size) {
        Ok(r) => r.with_far_field(&refs).expect("far field"),
        Err(e) => {
            println!("farfield: no GPU ({e}); nothing to measure");
            return;
        }
    };
    let all_blocks: Vec<BlockId> = scene.block_meshes().iter().map(|(b, _)| *b).collect();
    let triangles: u64 = scene.triangles_by_block().iter().sum();
    println!(
        "farfield: {} ({} blocks, {triangles} triangles), {} maps at K = {} (levels 0..=3), {}x{}, {}, median of {frames} frames",
        scene.name,
        all_blocks.len(),
        nodes.len(),
        nodes[0].map.k(),
        size.0,
        size.1,
        blockwalk::visibility::FrameRenderer::describe(&r),
    );
    let aspect = size.0 as f64 / size.1 as f64;
    let root = nodes[0].map.aabb();
    let (c, side) = (root.center(), root.extent().x.max(root.extent().y));
    let mut cams: Vec<(String, Camera, Vec<usize>)> = Vec::new();
    // One map filling the screen: the root's box seen from above its roofs, 55° down.
    let mut full = Camera::looking_at(
        DVec3::new(c.x, c.y - 0.12 * side, root.max.z + 0.16 * side),
        DVec3::new(c.x, c.y, 0.0),
    );
    full.near = 1.0;
    full.far = 4.0 * side;
    cams.push(("one K=64 map, full screen".into(), full, vec![0]));
    // N maps: every map of a level, from a fly-over that sees the whole city.
    let mut fly = Camera::looking_at(
        c + DVec3::new(-0.45 * side, -0.55 * side, 0.55 * side),
        DVec3::new(c.x, c.y, 0.0),
    );
    fly.near = 5.0;
    fly.far = 5.0 * side;
    for level in 0..=3 {
        let far: Vec<usize> = (0..nodes.len())
            .filter(|&i| nodes[i].level == level)
            .collect();
        if !far.is_empty() {
            cams.push((format!("fly-over, level {level}"), fly, far));
        }
    }
    for (what, mut cam, far) in cams {
        cam.aspect = aspect;
        // Far field alone (no meshes; the mesh pass still clears and draws the ground plane).
        let mut far_s = Vec::new();
        let mut mesh_only_s = Vec::new();
        let mut pixels = 0;
        let mut draws = 0;
        for f in 0..=frames {
            let h = r.draw_hybrid(&cam, &[], &far, false).expect("far frame");
            let m = r
                .draw_hybrid(&cam, &all_blocks, &[], false)
                .expect("mesh frame");
            if f > 0 {
                // The first frame warms up (pipeline and shader compilation, uploads).
                far_s.push(h.passes[1].1);
                mesh_only_s.push(m.passes[0].1);
            }
            pixels = h.far_pixels;
            draws = h.far_draws;
        }
        let (fs, ms) = (median(far_s), median(mesh_only_s));
        // Pixels whose ray meets a drawn map's box: the fragments the far pass shades.
        let boxed = (0..size.1)
            .flat_map(|y| (0..size.0).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                far.iter().any(|&m| {
                    let ray = twin_ray(refs[m], &cam, size.0, size.1, x, y);
                    meets_box(&ray, refs[m].k() as f64)
                })
            })
            .count();
        println!(
            "  {what}: {} maps in {draws} draw calls, boxes cover {:.1} % of the image, {pixels} map pixels ({:.1} %): far pass {:.3} ms; all {} blocks as meshes {:.3} ms; far / meshes = {:.3}",
            far.len(),
            100.0 * boxed as f64 / (size.0 as f64 * size.1 as f64),
            100.0 * pixels as f64 / (size.0 as f64 * size.1 as f64),
            fs * 1e3,
            all_blocks.len(),
            ms * 1e3,
            fs / ms
        );
    }
}
