//! Occlusion culling from adversarial cameras on the bundled real cities (Bubeneč, Helsinki) and
//! one more (a synthetic grid, or any city given in `$BLOCKWALK_ADVERSARIAL_CITY`):
//! eyes at 0.05–3× `near` from corners and walls, at wall-top height, on wall planes, 1 mm above
//! roofs, looking along walls, straight down and up, `near` ∈ {0.1, 0.5, 2, 10} m
//! ([`blockwalk::visibility::adversarial`]). No block the supersampled oracle sees may be
//! culled, for every structure and cull map resolution.
//!
//! One oracle image per view serves every structure and resolution, and one cull map per view
//! and resolution serves every structure. The oracle is small (the views are what is
//! adversarial) and supersampled 4×4. CI runs `CI_VIEWS` views per city; set
//! `BLOCKWALK_ADVERSARIAL_VIEWS=10000` for the full count. Eyes inside a building (a touching
//! neighbour) are counted apart as vacuous: they are checked too, but not counted as passes.

mod support;
use blockwalk::blocks::{BlockId, BlockOptions};
use blockwalk::city::Mesh;
use blockwalk::index::Structure;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::visibility::adversarial::{adversarial_views, AdversarialOptions, BuildingSolids};
use blockwalk::visibility::oracle::visible_blocks_supersampled;
use blockwalk::visibility::{CullMap, CullerOptions, OcclusionCuller, Resolution};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use support::data::data;

/// Views per city in CI.
const CI_VIEWS: usize = 600;
/// The oracle's frame (16:9) and its samples per pixel along each axis.
const ORACLE: (u32, u32, u32) = (96, 54, 4);
const RESOLUTIONS: [u32; 3] = [64, 256, 1024];
const NEARS: [f64; 4] = [0.1, 0.5, 2.0, 10.0];

fn views_wanted() -> usize {
    std::env::var("BLOCKWALK_ADVERSARIAL_VIEWS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(CI_VIEWS)
}

/// Counts of one structure × resolution × near.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    views: usize,
    vacuous: usize,
    /// Views where the map hid at least one block the frustum kept.
    culled: usize,
    false_culls: usize,
    false_culls_vacuous: usize,
}

type Key = (Structure, u32, u64);

fn run_city(name: &str, footprints: &str, streets: &str, seed: u64) {
    let source = CitySource::parse(&data(footprints), Some(data(streets)), None, &[], 0).unwrap();
    run_source(name, &source, seed);
}

fn run_source(name: &str, source: &CitySource, seed: u64) {
    let opts = SceneOptions {
        blocks: BlockOptions::default(),
        structures: Structure::ALL.to_vec(),
        occlusion: None,
        ..SceneOptions::default()
    };
    let scene = Scene::load(source, &opts, &mut |_| {}).unwrap();
    let refs: Vec<(BlockId, &Mesh)> = scene
        .block_meshes()
        .iter()
        .map(|(id, m)| (*id, m))
        .collect();
    let base = OcclusionCuller::new(&scene.city, &scene.layout, CullerOptions::default()).unwrap();
    let cullers: Vec<OcclusionCuller> = RESOLUTIONS
        .iter()
        .map(|&r| base.with_resolution(Resolution::Cells(r)).unwrap())
        .collect();
    let solids = BuildingSolids::new(&scene.city);
    let n = views_wanted();
    let views = adversarial_views(
        &scene.city,
        &AdversarialOptions {
            views: n,
            seed,
            nears: NEARS.to_vec(),
            ..Default::default()
        },
    );
    assert_eq!(views.len(), n);
    let (w, h, ss) = ORACLE;
    // Per view: (vacuous, per key: (culled something, false culls, first false cull)).
    type Row = (bool, Vec<(Key, bool, usize, Option<BlockId>)>);
    let rows: Vec<Row> = views
        .par_iter()
        .map_init(
            || {
                cullers
                    .iter()
                    .map(|c| c.new_map())
                    .collect::<Vec<CullMap>>()
            },
            |maps, v| {
                let cam = &v.camera;
                let vacuous = solids.contains(cam.position);
                let visible = visible_blocks_supersampled(&refs, cam, w, h, ss);
                let mut out = Vec::new();
                for (c, map) in cullers.iter().zip(maps.iter_mut()) {
                    let st = c.build(cam, map);
                    let res = match c.options().resolution {
                        Resolution::Cells(r) => r,
                        Resolution::CellSize(_) => 0,
                    };
                    for index in &scene.indexes {
                        let mut frustum = Vec::new();
                        c.traverse(
                            index.as_ref(),
                            cam,
                            map,
                            blockwalk::visibility::OcclusionStats {
                                skipped: Some(blockwalk::visibility::SkipReason::NoOccluders),
                                ..Default::default()
                            },
                            &mut frustum,
                        );
                        let mut kept = Vec::new();
                        c.traverse(index.as_ref(), cam, map, st, &mut kept);
                        let kept: BTreeSet<BlockId> = kept.into_iter().collect();
                        let missed: Vec<BlockId> = visible
                            .iter()
                            .filter(|b| !kept.contains(b))
                            .copied()
                            .collect();
                        out.push((
                            (index.structure(), res, cam.near.to_bits()),
                            kept.len() < frustum.len(),
                            missed.len(),
                            missed.first().copied(),
                        ));
                    }
                }
                (vacuous, out)
            },
        )
        .collect();
    let mut tally: BTreeMap<Key, Tally> = BTreeMap::new();
    let mut examples = Vec::new();
    for (v, (vacuous, row)) in views.iter().zip(&rows) {
        for &(key, culled, missed, first) in row {
            let t = tally.entry(key).or_default();
            t.views += 1;
            t.vacuous += *vacuous as usize;
            t.culled += culled as usize;
            if *vacuous {
                t.false_culls_vacuous += missed;
            } else {
                t.false_culls += missed;
            }
            if missed > 0 && examples.len() < 10 {
                examples.push(format!(
                    "{name} {:?} {:?} res {} near {}: {first:?} culled from {:?} ({:?}, {:.3}× near, vacuous {vacuous})",
                    key.0, v.kind, key.1, v.camera.near, v.camera, v.building, v.near_factor
                ));
            }
        }
    }
    eprintln!("{name}: {n} adversarial views, oracle {w}x{h} with {ss}x{ss} samples per pixel");
    eprintln!("structure  res   near  views  vacuous  culling  false_culls (vacuous)");
    let mut total_false = 0;
    let mut total_nonvacuous = 0;
    let mut total_culling = 0;
    for ((s, res, near), t) in &tally {
        eprintln!(
            "{:<9} {:>5} {:>5} {:>6} {:>8} {:>8} {:>6} ({})",
            s.name(),
            res,
            f64::from_bits(*near),
            t.views,
            t.vacuous,
            t.culled,
            t.false_culls,
            t.false_culls_vacuous
        );
        total_false += t.false_culls + t.false_culls_vacuous;
        total_nonvacuous += t.views - t.vacuous;
        total_culling += t.culled;
    }
    for e in &examples {
        eprintln!("{e}");
    }
    assert_eq!(total_false, 0, "false culls: {examples:#?}");
    // Not vacuous: most eyes are outside every building, and the maps do hide blocks.
    let keys = tally.len();
    assert_eq!(keys, Structure::ALL.len() * RESOLUTIONS.len() * NEARS.len());
    let total: usize = tally.values().map(|t| t.views).sum();
    assert_eq!(total, n * Structure::ALL.len() * RESOLUTIONS.len());
    assert!(
        total_nonvacuous * 2 > total,
        "{total_nonvacuous} non-vacuous of {total}"
    );
    assert!(total_culling > 0, "the cull maps never hid anything");
}

#[test]
fn bubenec_adversarial_cameras_never_cull_a_visible_block() {
    run_city(
        "bubenec",
        "bubenec/buildings.shp",
        "bubenec/streets.shp",
        11,
    );
}

#[test]
fn helsinki_adversarial_cameras_never_cull_a_visible_block() {
    run_city(
        "helsinki",
        "helsinki/buildings.shp",
        "helsinki/streets_blockclass.shp",
        12,
    );
}

/// A city none of the above was tuned on: `$BLOCKWALK_ADVERSARIAL_CITY` (any city the command
/// line takes: a footprint file, a generated city's folder, `synthetic:COLSxROWS`) with
/// `$BLOCKWALK_ADVERSARIAL_STREETS` when set, e.g. Astana from `../shared/data/astana`; else a
/// synthetic grid with its own seed.
#[test]
fn another_city_adversarial_cameras_never_cull_a_visible_block() {
    let city = std::env::var_os("BLOCKWALK_ADVERSARIAL_CITY")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("synthetic:7x5"));
    let streets = std::env::var_os("BLOCKWALK_ADVERSARIAL_STREETS").map(PathBuf::from);
    let source = CitySource::parse(&city, streets, None, &[], 29).unwrap();
    run_source(&city.display().to_string(), &source, 13);
}
