//! A frame strip of the two far fields beside the meshes: frames along a route drawn three
//! ways (top row meshes only, middle row near meshes + far BlockMaps, bottom row near meshes +
//! far relief impostors) at the same τ, into one PNG, with each hybrid frame's coverage error
//! and PSNR against the mesh frame printed. Draws on the GPU when built with `--features render`
//! and an adapter is found, else with the CPU renderers.
//!
//! ```text
//! cargo run --release --example far_strip --features render -- CITY [STREETS] \
//!     [--route flyover] [--frames 4] [--size 640x360] [--tau 1] [--out strip.png]
//! ```
//! `CITY` is anything `blockwalk walk` takes (a footprint file with optional street lines, a
//! generated city's folder, `synthetic:COLSxROWS`).

use blockwalk::blockmap::SelectOptions;
use blockwalk::index::Structure;
use blockwalk::relief::{ReliefField, ReliefOptions};
use blockwalk::route::RouteChoice;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::visibility::FrameRenderer;
use blockwalk::walk::{image_error, BlockMapsOptions, BuildFar, FarField};
use std::path::{Path, PathBuf};

struct Args {
    city: PathBuf,
    streets: Option<PathBuf>,
    route: String,
    frames: usize,
    size: (u32, u32),
    tau: f64,
    out: PathBuf,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        city: PathBuf::new(),
        streets: None,
        route: "flyover".into(),
        frames: 4,
        size: (640, 360),
        tau: 1.0,
        out: "strip.png".into(),
    };
    let mut pos = Vec::new();
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut val = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match x.as_str() {
            "--route" => a.route = val("--route")?,
            "--frames" => a.frames = val("--frames")?.parse().map_err(|e| format!("{e}"))?,
            "--tau" => a.tau = val("--tau")?.parse().map_err(|e| format!("{e}"))?,
            "--out" => a.out = val("--out")?.into(),
            "--size" => {
                let s = val("--size")?;
                a.size = s
                    .split_once('x')
                    .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
                    .ok_or(format!("--size {s}: expected WIDTHxHEIGHT"))?;
            }
            _ => pos.push(x),
        }
    }
    let mut pos = pos.into_iter();
    a.city = pos.next().ok_or("give a city")?.into();
    a.streets = pos.next().map(Into::into);
    Ok(a)
}

/// The GPU renderer of `scene` with `far` uploaded, when there is one.
#[cfg(feature = "render")]
fn gpu<'a>(
    scene: &'a Scene,
    size: (u32, u32),
    far: &'a dyn FarField,
) -> Option<Box<dyn FrameRenderer + 'a>> {
    blockwalk::render::GpuFrameRenderer::new(scene.draw_meshes(), &scene.ground, size)
        .and_then(|r| r.with_far(far))
        .ok()
        .map(|r| Box::new(r) as Box<dyn FrameRenderer>)
}

#[cfg(not(feature = "render"))]
fn gpu<'a>(
    _: &'a Scene,
    _: (u32, u32),
    _: &'a dyn FarField,
) -> Option<Box<dyn FrameRenderer + 'a>> {
    None
}

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let a = args()?;
    let source = CitySource::parse(&a.city, a.streets.clone(), None, &[], 1)?;
    let scene = Scene::load(
        &source,
        &SceneOptions {
            structures: vec![Structure::Bqr],
            ..SceneOptions::default()
        },
        &mut |_| {},
    )?;
    let (w, h) = a.size;
    let route: RouteChoice = a.route.parse()?;
    let (route, _) =
        blockwalk::walk::job::resolve_route(&route, &scene, f64::from(w) / f64::from(h))?;
    let maps =
        blockwalk::blockmap::MapTree::build(&scene, &BlockMapsOptions::default(), &|_, _| {})?;
    let relief = ReliefField::build(&scene, &ReliefOptions::default(), &|_, _| {})?;
    let fields: [&dyn FarField; 2] = [&maps, &relief];
    let select = SelectOptions {
        tau_px: a.tau,
        ..SelectOptions::default()
    };
    let cameras = route.sample(a.frames.max(1));
    let mut strip = image::RgbaImage::new(w * cameras.len() as u32, h * 3);
    let all: Vec<_> = scene.bounds.iter().map(|b| b.id).collect();
    let mut on = "CPU";
    for (row, field) in fields.iter().enumerate() {
        let renderer = match gpu(&scene, a.size, *field) {
            Some(r) => {
                on = "GPU";
                r
            }
            None => field.cpu_renderer(
                scene.draw_meshes(),
                &scene.ground,
                scene.terrain_draw(),
                a.size,
            ),
        };
        let mut sel = field.selector(&scene.bounds, select)?;
        for (col, cam) in cameras.iter().enumerate() {
            let s = sel.select(cam, h, None);
            let hybrid = renderer
                .draw_with_far(cam, &s.meshes, &s.maps, true)?
                .image
                .ok_or("no image")?;
            let mesh = renderer.draw(cam, &all, true)?.image.ok_or("no image")?;
            let empty = renderer.draw(cam, &[], true)?.image.ok_or("no image")?;
            let e = image_error(&mesh, &hybrid, &empty);
            println!(
                "frame {col} {}: {} far nodes, {} mesh blocks, coverage error {:.4} %, PSNR {:.1} dB",
                field.name(),
                s.maps.len(),
                s.meshes.len(),
                100.0 * e.coverage_error,
                e.psnr_db
            );
            if row == 0 {
                image::imageops::replace(&mut strip, &mesh, i64::from(w) * col as i64, 0);
            }
            image::imageops::replace(
                &mut strip,
                &hybrid,
                i64::from(w) * col as i64,
                i64::from(h) * (row as i64 + 1),
            );
        }
    }
    save(&strip, &a.out)?;
    println!(
        "{}: rows meshes only, meshes + BlockMaps, meshes + relief impostors (τ = {} px, drawn on the {on})",
        a.out.display(),
        a.tau
    );
    Ok(())
}

fn save(
    img: &image::RgbaImage,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    if let Some(d) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d)?;
    }
    img.save(path)?;
    Ok(())
}
