//! Draws one frame of the bundled Helsinki data with the procedural appearance (facades with
//! windows, roofs by building type, streets and blocks on the ground), with the CPU fallback
//! renderer and, when built with `--features render` and an adapter is found, with the GPU.
//!
//! ```text
//! cargo run --example appearance_frame --features render -- [OUT_DIR] [WIDTHxHEIGHT]
//! ```
//! Writes `OUT_DIR/helsinki_cpu.png` and `OUT_DIR/helsinki_gpu.png` (default `out/`, 1280x720).

use blockwalk::blocks::{detect, BlockId, BlockKind, BlockOptions};
use blockwalk::city::appearance::ground_mesh;
use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::Mesh;
use blockwalk::geom::Camera;
use blockwalk::importers::{read_layer, Theme};
use blockwalk::visibility::oracle;
use glam::DVec3;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "out".into()));
    let size = args.next().unwrap_or_else(|| "1280x720".into());
    let (w, h) = size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .ok_or_else(|| format!("size {size}: expected WIDTHxHEIGHT"))?;
    std::fs::create_dir_all(&out)?;
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/helsinki");
    let fp = read_layer(&data.join("buildings.shp"), &Theme::Any)?;
    let st = read_layer(&data.join("streets_blockclass.shp"), &Theme::Any)?;
    let city = build_city(&fp, Some(&st), None, &BuildOptions::default())?;
    let layout = detect(&city, &BlockOptions::default())?;
    let meshes = extrude_city(&city);
    let mut block_of = vec![BlockId(0); city.buildings.len()];
    for b in &layout.blocks {
        for id in &b.buildings {
            block_of[id.0 as usize] = b.id;
        }
    }
    let blocks: Vec<(BlockId, &Mesh)> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| (block_of[i], m))
        .collect();
    let block_ground: Vec<_> = layout
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Block)
        .map(|b| b.polygon.clone())
        .collect();
    let ground = ground_mesh(&city.frame, &city.streets, &block_ground);
    // Over the centre, 120 m up, looking north-east and down.
    let mut cam = Camera::looking_at(DVec3::new(-260.0, -300.0, 120.0), DVec3::new(0.0, 0.0, 0.0));
    cam.aspect = w as f64 / h as f64;
    let t = std::time::Instant::now();
    let img = oracle::shade_with_ground(&blocks, &ground, &cam, w, h);
    let path = out.join("helsinki_cpu.png");
    img.save(&path)?;
    println!(
        "{}: {} buildings, {} blocks, {} streets; CPU frame in {:.2} s",
        path.display(),
        city.buildings.len(),
        layout.blocks.len(),
        city.streets.len(),
        t.elapsed().as_secs_f64()
    );
    #[cfg(feature = "render")]
    {
        use blockwalk::render::{Gpu, MeshRenderer, RenderOptions};
        match Gpu::new_headless() {
            Ok(gpu) => {
                let r = MeshRenderer::with_ground(
                    &gpu,
                    &blocks,
                    &ground,
                    RenderOptions {
                        width: w,
                        height: h,
                    },
                )?;
                let all: Vec<BlockId> = layout.blocks.iter().map(|b| b.id).collect();
                let frame = r.draw(&gpu, &cam, &all)?;
                let path = out.join("helsinki_gpu.png");
                frame.save_png(&path)?;
                let differ = frame
                    .rgba
                    .chunks_exact(4)
                    .zip(img.as_raw().chunks_exact(4))
                    .filter(|(g, c)| (0..3).any(|k| g[k].abs_diff(c[k]) > 1))
                    .count();
                println!(
                    "{}: on {}; {differ} pixels ({:.3} %) differ from the CPU frame by more \
                     than 1/255",
                    path.display(),
                    gpu.adapter_name(),
                    100.0 * differ as f64 / (w as f64 * h as f64)
                );
            }
            Err(e) => println!("no GPU frame: {e}"),
        }
    }
    Ok(())
}
