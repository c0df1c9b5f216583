//! Terrain level-of-detail tree: build time on a Nepal-sized grid (1451 × 878 at 30 m, synthetic
//! hills, and the Nepal DEM itself when the GeoTIFF reader reads it), and the per-frame cut for
//! street-level and fly-over cameras.

use blockwalk::geom::{Camera, LocalFrame};
use blockwalk::importers::dem::read_dem;
use blockwalk::terrain::{GridSpec, Synthetic, Terrain, TerrainTree, TreeOptions};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

const NEPAL: &str = "../shared/data/dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif";

fn synthetic_nepal() -> Terrain {
    Terrain::synthetic(
        GridSpec::new(1451, 878, 30.0, DVec2::new(328_290.0, 3_097_260.0)),
        Synthetic::Smooth {
            seed: 1,
            relief_m: 5300.0,
        },
    )
}

fn nepal() -> Option<Terrain> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(NEPAL);
    match read_dem(&path) {
        Ok(dem) => {
            let m = dem.crs.metric_transform([350_000.0, 3_110_000.0]);
            Some(Terrain::from_dem(&dem, &m, None).expect("the Nepal DEM"))
        }
        Err(e) => {
            eprintln!("SKIP the Nepal DEM: {e}");
            None
        }
    }
}

/// Cameras over the terrain: street level (1.7 m over the ground, looking about horizontally,
/// far 5 km) or flying (300 m to 3 km over it, looking down, far 60 km).
fn cameras(t: &Terrain, frame: &LocalFrame, street: bool, n: usize) -> Vec<Camera> {
    let mut rng = ChaCha8Rng::seed_from_u64(if street { 1 } else { 2 });
    let e = t.extent();
    let mut out = Vec::new();
    while out.len() < n {
        let p = DVec2::new(rng.random_range(e[0]..e[2]), rng.random_range(e[1]..e[3]));
        let Some(g) = t.sample(p) else { continue };
        let (dz, pitch) = if street {
            (1.7, rng.random_range(-0.2..0.1))
        } else {
            (
                rng.random_range(300.0..3000.0),
                rng.random_range(-1.2..-0.3),
            )
        };
        let mut c = Camera::new(
            frame.to_local_f64(DVec3::new(p.x, p.y, g + dz)),
            rng.random_range(0.0..std::f64::consts::TAU),
            pitch,
        );
        if !street {
            c.far = 60_000.0;
        }
        out.push(c);
    }
    out
}

fn terrain(c: &mut Criterion) {
    let mut grids = vec![("synthetic_1451x878", synthetic_nepal())];
    if let Some(t) = nepal() {
        grids.push(("nepal_1451x878", t));
    }
    let mut g = c.benchmark_group("terrain_tree_build");
    g.sample_size(10);
    for (name, t) in &grids {
        g.bench_with_input(BenchmarkId::from_parameter(name), t, |b, t| {
            b.iter(|| TerrainTree::build(t.clone(), &TreeOptions::default()).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("terrain_select_frame");
    for (name, t) in grids {
        let tree = TerrainTree::build(t, &TreeOptions::default()).unwrap();
        let s = tree.summary();
        eprintln!(
            "{name}: tree {} B / grid {} B = {:.3}; levels {}",
            s.heap_bytes,
            s.terrain_heap_bytes,
            s.heap_bytes as f64 / s.terrain_heap_bytes as f64,
            serde_json::to_string(&s.levels).unwrap()
        );
        let c0 = tree.terrain().extent();
        let frame = LocalFrame {
            origin: DVec3::new(0.5 * (c0[0] + c0[2]), 0.5 * (c0[1] + c0[3]), 0.0),
        };
        for street in [true, false] {
            let cams = cameras(tree.terrain(), &frame, street, 64);
            let mut out = Vec::new();
            let mut drawn = 0;
            for cam in &cams {
                tree.select(cam, &frame, 1080, 1.0, &mut out);
                drawn += out.len();
            }
            let kind = if street { "street" } else { "flyover" };
            eprintln!(
                "{name} {kind}: {:.1} nodes drawn per frame at τ = 1 px",
                drawn as f64 / cams.len() as f64
            );
            g.bench_function(BenchmarkId::new(kind, name), |b| {
                let mut k = 0;
                b.iter(|| {
                    tree.select(&cams[k % cams.len()], &frame, 1080, 1.0, &mut out);
                    k += 1;
                    out.len()
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, terrain);
criterion_main!(benches);
