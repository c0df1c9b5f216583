//! Occlusion culling on terrain from adversarial cameras: a generated city on the Nepal DEM
//! (Langtang, 30 m) and a synthetic terrain with a 100 m cliff and a ridge, culled by the
//! occlusion culler with the terrain's min-filtered cells as occluders
//! ([`blockwalk::visibility::occluders::terrain_occluders`]) and without them, each checked
//! against the oracle that draws the full-resolution terrain as an occluder, supersampled 4×4
//! (as `tests/adversarial_cameras.rs`). No block the oracle sees may be culled.
//!
//! Cameras on the DEM: (a) among the ridges around the city, 0.1–3 m above the ground, any yaw,
//! pitch within ±30°; (b) 0.1 m above the steepest points, looking up, down and across the
//! slope; (c) just below ridge crests on lines through the city, looking over them; (d) the
//! adversarial generator's views ([`adversarial_views`]) lifted onto the ground where they fall
//! under it. Near planes cycle through 0.1, 0.5, 2 and 10 m. Cameras where neither culler hid
//! anything are counted apart as vacuous (they are checked all the same), and so are eyes
//! inside a building.
//!
//! The DEM tests need `dem` (`support::skip`); the synthetic cliff runs everywhere.

mod support;

use blockwalk::blocks::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use blockwalk::city::build::ground::GroundOptions;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::{Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Mesh};
use blockwalk::geom::Camera;
use blockwalk::index::Structure;
use blockwalk::route::RouteChoice;
use blockwalk::scene::{CitySource, LoadedCity, Scene, SceneOptions};
use blockwalk::terrain::{BaseRule, Terrain};
use blockwalk::visibility::adversarial::{adversarial_views, AdversarialOptions, BuildingSolids};
use blockwalk::visibility::oracle::visible_blocks_with_terrain;
use blockwalk::visibility::{CullMap, CullerOptions, OcclusionCuller, OcclusionStats, SkipReason};
use geo_types::{LineString, Polygon};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::PathBuf;
use std::sync::Arc;
use support::data::shared_data;
use support::skip::{or_skip, Need};

const NEPAL: &str = "dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif";
/// The oracle's frame (16:9) and its samples per pixel along each axis.
const ORACLE: (u32, u32, u32) = (96, 54, 4);
const NEARS: [f64; 4] = [0.1, 0.5, 2.0, 10.0];

fn dem(test: &str) -> Option<PathBuf> {
    let p = shared_data(NEPAL);
    or_skip(
        Need::Dem,
        test,
        if p.is_file() {
            Ok(p)
        } else {
            Err(format!("../shared/data/{NEPAL} absent"))
        },
    )
}

/// Cameras per family (`$BLOCKWALK_TERRAIN_VIEWS` for more).
fn views_wanted(ci: usize) -> usize {
    std::env::var("BLOCKWALK_TERRAIN_VIEWS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(ci)
}

/// The terrain in the scene's local frame: the bilinear ground under a local point.
struct Ground<'a> {
    terrain: &'a Terrain,
    frame: LocalFrame,
}

impl Ground<'_> {
    fn at(&self, p: DVec2) -> Option<f64> {
        let w = self.frame.to_world(p.extend(0.0));
        self.terrain
            .sample(DVec2::new(w.x, w.y))
            .map(|g| g - self.frame.origin.z)
    }

    /// The grid node `(i, j)` in the local frame.
    fn node(&self, i: usize, j: usize) -> DVec2 {
        let w = self.terrain.node_xy(i, j);
        self.frame.to_local_f64(w.extend(0.0)).truncate()
    }

    /// Local box of the terrain (x0, y0, x1, y1).
    fn extent(&self) -> [f64; 4] {
        let e = self.terrain.extent();
        let lo = self.frame.to_local_f64(DVec3::new(e[0], e[1], 0.0));
        let hi = self.frame.to_local_f64(DVec3::new(e[2], e[3], 0.0));
        [lo.x, lo.y, hi.x, hi.y]
    }
}

/// One camera family's counts.
#[derive(Clone, Debug, Default)]
struct Tally {
    cameras: usize,
    /// Neither culler hid anything, or the eye is inside a building.
    vacuous: usize,
    inside_building: usize,
    /// Blocks the oracle sees, summed.
    visible: usize,
    /// Blocks in the frustum, summed.
    in_frustum: usize,
    /// Blocks the frustum kept that the culler with terrain occluders dropped, summed.
    culled_terrain: usize,
    /// The same without terrain occluders.
    culled_plain: usize,
    /// Cameras where the terrain occluders hid more than the buildings alone.
    terrain_helped: usize,
    /// Cameras not occlusion culled because the near plane dips into the ground.
    near_in_ground: usize,
    /// Seen blocks dropped by the culler with terrain occluders, and without.
    false_terrain: usize,
    false_plain: usize,
    examples: Vec<String>,
}

impl Tally {
    fn add(&mut self, o: &Tally) {
        self.cameras += o.cameras;
        self.vacuous += o.vacuous;
        self.inside_building += o.inside_building;
        self.visible += o.visible;
        self.in_frustum += o.in_frustum;
        self.culled_terrain += o.culled_terrain;
        self.culled_plain += o.culled_plain;
        self.terrain_helped += o.terrain_helped;
        self.near_in_ground += o.near_in_ground;
        self.false_terrain += o.false_terrain;
        self.false_plain += o.false_plain;
        self.examples.extend(o.examples.iter().cloned());
    }

    fn print(&self, name: &str) {
        eprintln!(
            "{name:<22} {:>5} cameras, {:>4} vacuous ({} inside a building, {} with the near plane in the ground), seen {:>6}, in frustum {:>6}, culled with terrain occluders {:>6} / without {:>6} ({} cameras where the terrain hid more), false culls {} / {}",
            self.cameras,
            self.vacuous,
            self.inside_building,
            self.near_in_ground,
            self.visible,
            self.in_frustum,
            self.culled_terrain,
            self.culled_plain,
            self.terrain_helped,
            self.false_terrain,
            self.false_plain
        );
    }
}

/// A scene on terrain with the two cullers (with the terrain's occluders: the scene's own;
/// without: the buildings' alone) and what the oracle draws.
struct Checker<'a> {
    scene: &'a Scene,
    plain: OcclusionCuller,
    blocks: Vec<(BlockId, &'a Mesh)>,
    terrain: &'a Mesh,
    solids: BuildingSolids,
}

impl<'a> Checker<'a> {
    fn new(scene: &'a Scene) -> Self {
        let drawn: Vec<bool> = scene
            .building_meshes
            .iter()
            .map(|m| !m.indices.is_empty())
            .collect();
        let opts = *scene.occlusion.as_ref().expect("a culler").options();
        let plain = OcclusionCuller::with_drawn(&scene.city, &scene.layout, &drawn, opts).unwrap();
        Self {
            scene,
            plain,
            blocks: scene
                .block_meshes()
                .iter()
                .map(|(id, m)| (*id, m))
                .collect(),
            terrain: &scene.terrain_lod.as_ref().expect("a terrain").full,
            solids: BuildingSolids::new(&scene.city),
        }
    }

    /// Frustum, then each culler; against the oracle with the full terrain.
    fn check(&self, family: &str, cameras: &[Camera]) -> Tally {
        let with = self.scene.occlusion.as_ref().unwrap();
        let index = self.scene.indexes[0].as_ref();
        let (w, h, ss) = ORACLE;
        let rows: Vec<Tally> = cameras
            .par_iter()
            .enumerate()
            .map_init(
                || (with.new_map(), self.plain.new_map()),
                |(map_t, map_p): &mut (CullMap, CullMap), (k, cam)| {
                    let mut t = Tally {
                        cameras: 1,
                        ..Default::default()
                    };
                    let seen = visible_blocks_with_terrain(
                        &self.blocks,
                        Some(self.terrain),
                        cam,
                        w,
                        h,
                        ss,
                    );
                    let no_map = OcclusionStats {
                        skipped: Some(SkipReason::NoOccluders),
                        ..Default::default()
                    };
                    let mut frustum = Vec::new();
                    with.traverse(index, cam, map_t, no_map, &mut frustum);
                    let run = |c: &OcclusionCuller, map: &mut CullMap| {
                        let st = c.build(cam, map);
                        let mut kept = Vec::new();
                        c.traverse(index, cam, map, st, &mut kept);
                        (kept.into_iter().collect::<BTreeSet<BlockId>>(), st.skipped)
                    };
                    let (kept_t, skip_t) = run(with, map_t);
                    let (kept_p, _) = run(&self.plain, map_p);
                    t.near_in_ground = (skip_t == Some(SkipReason::NearPlaneInGround)) as usize;
                    let frustum: BTreeSet<BlockId> = frustum.into_iter().collect();
                    t.visible = seen.len();
                    t.in_frustum = frustum.len();
                    t.culled_terrain = frustum.difference(&kept_t).count();
                    t.culled_plain = frustum.difference(&kept_p).count();
                    t.terrain_helped = (t.culled_terrain > t.culled_plain) as usize;
                    let inside = self.solids.contains(cam.position);
                    t.inside_building = inside as usize;
                    t.vacuous = (inside || (t.culled_terrain == 0 && t.culled_plain == 0)) as usize;
                    let missed_t: Vec<BlockId> =
                        seen.iter().filter(|b| !kept_t.contains(b)).copied().collect();
                    let missed_p: Vec<BlockId> =
                        seen.iter().filter(|b| !kept_p.contains(b)).copied().collect();
                    t.false_terrain = missed_t.len();
                    t.false_plain = missed_p.len();
                    if !missed_t.is_empty() || !missed_p.is_empty() {
                        t.examples.push(format!(
                            "{family} #{k}: with terrain occluders dropped {missed_t:?}, without {missed_p:?}, inside a building {inside}, {cam:?}"
                        ));
                    }
                    t
                },
            )
            .collect();
        let mut all = Tally::default();
        for r in &rows {
            all.add(r);
        }
        all
    }
}

fn with_near(mut cam: Camera, near: f64) -> Camera {
    cam.near = near;
    cam.far = cam.far.max(near * 100.0);
    cam
}

/// (a) Eyes 0.1–3 m above random points of the terrain within `reach` metres of the city's
/// box, any yaw, pitch within ±30°.
fn among_ridges(g: &Ground<'_>, city: [f64; 4], reach: f64, n: usize, seed: u64) -> Vec<Camera> {
    let e = g.extent();
    let lo = DVec2::new((city[0] - reach).max(e[0]), (city[1] - reach).max(e[1]));
    let hi = DVec2::new((city[2] + reach).min(e[2]), (city[3] + reach).min(e[3]));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = DVec2::new(rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
        let Some(z) = g.at(p) else { continue };
        let up = rng.random_range(0.1..=3.0);
        let cam = Camera::new(
            p.extend(z + up),
            rng.random_range(-PI..PI),
            rng.random_range(-30f64..=30.0).to_radians(),
        );
        out.push(with_near(cam, NEARS[out.len() % NEARS.len()]));
    }
    out
}

/// (b) 0.1 m above the steepest grid nodes within the box `area` (the `n / 4` steepest, at
/// least `gap` metres apart), looking up the slope (pitched along it), down it, and across
/// both ways.
fn on_slopes(g: &Ground<'_>, area: [f64; 4], gap: f64, n: usize, seed: u64) -> Vec<Camera> {
    let t = g.terrain;
    let mut nodes: Vec<(f64, DVec2, DVec2)> = Vec::new();
    for j in 1..t.ny() - 1 {
        for i in 1..t.nx() - 1 {
            let p = g.node(i, j);
            if p.x < area[0] || p.y < area[1] || p.x > area[2] || p.y > area[3] {
                continue;
            }
            let grad = t.gradient_at_node(i, j);
            if grad.is_finite() && grad.length() > 0.0 {
                nodes.push((grad.length(), p, grad));
            }
        }
    }
    nodes.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut picked: Vec<(f64, DVec2, DVec2)> = Vec::new();
    for nd in nodes {
        if picked.len() * 4 >= n {
            break;
        }
        if picked.iter().all(|q| (q.1 - nd.1).length() >= gap) {
            picked.push(nd);
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    for (s, p, grad) in picked {
        let up = grad / s;
        let slope = s.atan();
        // A little off the node, so the eye is not always over a grid vertex.
        let q = p + DVec2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
        let Some(z) = g.at(q) else { continue };
        let eye = q.extend(z + 0.1);
        for (dir, pitch) in [
            (up, slope),
            (-up, -slope),
            (up.perp(), 0.0),
            (-up.perp(), 0.0),
        ] {
            let yaw = dir.y.atan2(dir.x) + rng.random_range(-0.1..0.1);
            let pitch = (pitch + rng.random_range(-0.05..0.05)).clamp(-FRAC_PI_2, FRAC_PI_2);
            let cam = Camera::new(eye, yaw, pitch);
            out.push(with_near(cam, NEARS[out.len() % NEARS.len()]));
        }
    }
    out
}

/// (c) On `lines` lines through `centre`, the ridge crests (local maxima of the ground along
/// the line, at least 2 m above the ground 60 m either side); for each, eyes just below the
/// crest on both sides (0.5–15 m back along the line, 0.1–1 m above the ground, below the
/// crest), looking over it (pitched at the crest's top, ± a few degrees).
fn behind_ridges(
    g: &Ground<'_>,
    centre: DVec2,
    lines: usize,
    half_len: f64,
    n: usize,
    seed: u64,
) -> Vec<Camera> {
    let step = g.terrain.spacing().min_element() * 0.25;
    let mut crests: Vec<(DVec2, DVec2, f64)> = Vec::new();
    for l in 0..lines {
        let a = PI * l as f64 / lines as f64;
        let d = DVec2::from_angle(a);
        let k = (half_len / step) as i64;
        let prof: Vec<Option<f64>> = (-k..=k)
            .map(|s| g.at(centre + d * (s as f64 * step)))
            .collect();
        let w = (60.0 / step) as usize;
        for s in w..prof.len().saturating_sub(w) {
            let Some(h) = prof[s] else { continue };
            let near_max = prof[s - 3..=s + 3]
                .iter()
                .all(|v| v.is_some_and(|v| v <= h));
            let drop = |o: usize| prof[o].is_some_and(|v| h - v >= 2.0);
            if near_max && drop(s - w) && drop(s + w) {
                let p = centre + d * ((s as i64 - k) as f64 * step);
                crests.push((p, d, h));
            }
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    if crests.is_empty() {
        return out;
    }
    let mut tries = 0;
    while out.len() < n && tries < n * 20 {
        tries += 1;
        let (c, d, h) = crests[rng.random_range(0..crests.len())];
        let side = if rng.random_bool(0.5) { d } else { -d };
        let back = rng.random_range(0.5..15.0);
        let p = c - side * back;
        let Some(z) = g.at(p) else { continue };
        let eye_z = z + rng.random_range(0.1..=1.0);
        if eye_z >= h {
            continue;
        }
        let pitch = (h - eye_z).atan2(back) + rng.random_range(-3f64..3.0).to_radians();
        let yaw = side.y.atan2(side.x) + rng.random_range(-0.3..0.3);
        let cam = Camera::new(p.extend(eye_z), yaw, pitch);
        out.push(with_near(cam, NEARS[out.len() % NEARS.len()]));
    }
    out
}

/// (d) The adversarial generator's views, with eyes that fall under the ground (it places them
/// from z = 0) lifted onto it: the same fraction of the way from the ground to the roof.
fn adversarial_on_ground(scene: &Scene, g: &Ground<'_>, n: usize, seed: u64) -> Vec<Camera> {
    adversarial_views(
        &scene.city,
        &AdversarialOptions {
            views: n,
            seed,
            nears: NEARS.to_vec(),
            ..Default::default()
        },
    )
    .into_iter()
    .filter_map(|v| {
        let mut cam = v.camera;
        let ground = g.at(cam.position.truncate())?;
        if cam.position.z < ground + 0.05 {
            let top = scene.city.buildings[v.building.0 as usize].top_z();
            let frac = (cam.position.z / top.max(1e-9)).clamp(0.0, 2.5);
            cam.position.z = ground + 0.05 + frac * (top - ground).max(0.5);
        }
        Some(cam)
    })
    .collect()
}

/// The box of the city's blocks, local frame (x0, y0, x1, y1).
fn city_box(scene: &Scene) -> [f64; 4] {
    let b = scene.city_bounds();
    [b.min.x, b.min.y, b.max.x, b.max.y]
}

fn nepal_scene(path: &std::path::Path, occlusion: bool) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    let city = generate_city(&GenerateParams {
        buildings: 300,
        seed: 23,
        epsg: 32645,
        centre: Some((333_000.0, 3_110_000.0)),
        ..Default::default()
    })
    .unwrap();
    write_city(&city, &dir.path().join("city")).unwrap();
    let source = CitySource::parse(&dir.path().join("city"), None, None, &[], 0)
        .unwrap()
        .with_ground(Some(GroundOptions::new(path)));
    let opts = SceneOptions {
        structures: vec![Structure::Bqr],
        occlusion: occlusion.then(CullerOptions::default),
        terrain_occludes: true,
        ..SceneOptions::default()
    };
    let scene = Scene::load(&source, &opts, &mut |_| {}).unwrap();
    (dir, scene)
}

fn report_and_assert(city: &str, families: &[(&str, Tally)]) {
    let mut total = Tally::default();
    for (name, t) in families {
        t.print(&format!("{city} {name}"));
        total.add(t);
    }
    total.print(&format!("{city} all"));
    for e in total.examples.iter().take(12) {
        eprintln!("  {e}");
    }
    assert_eq!(
        total.false_terrain + total.false_plain,
        0,
        "false culls: {:#?}",
        &total.examples[..total.examples.len().min(12)]
    );
    assert!(
        total.culled_terrain > 0,
        "the culler with terrain occluders never hid a block: the check is vacuous"
    );
    assert!(
        total.vacuous < total.cameras,
        "{} vacuous of {}",
        total.vacuous,
        total.cameras
    );
}

#[test]
fn nepal_terrain_adversarial_cameras_never_cull_a_visible_block() {
    let test = "nepal_terrain_adversarial_cameras_never_cull_a_visible_block";
    let Some(path) = dem(test) else { return };
    let (_dir, scene) = nepal_scene(&path, true);
    let t = scene.city.terrain.clone().unwrap();
    let g = Ground {
        terrain: &t,
        frame: scene.city.frame,
    };
    let checker = Checker::new(&scene);
    let cb = city_box(&scene);
    let centre = DVec2::new(0.5 * (cb[0] + cb[2]), 0.5 * (cb[1] + cb[3]));
    let n = views_wanted(160);
    let around = [cb[0] - 600.0, cb[1] - 600.0, cb[2] + 600.0, cb[3] + 600.0];
    let families = [
        (
            "among ridges",
            checker.check("among ridges", &among_ridges(&g, cb, 600.0, n, 1)),
        ),
        (
            "on slopes",
            checker.check("on slopes", &on_slopes(&g, around, 60.0, n, 2)),
        ),
        (
            "behind ridges",
            checker.check(
                "behind ridges",
                &behind_ridges(&g, centre, 12, 1500.0, n, 3),
            ),
        ),
        (
            "adversarial",
            checker.check("adversarial", &adversarial_on_ground(&scene, &g, n, 4)),
        ),
    ];
    report_and_assert("nepal", &families);
}

/// Per-frame occlusion time (cull map of 256² cells: select, draw and traverse) on the street
/// route, with the terrain's occluders and without. Debug builds are slow; the numbers are for
/// comparing the two.
#[test]
fn nepal_street_route_occlusion_time_with_and_without_terrain_occluders() {
    let test = "nepal_street_route_occlusion_time_with_and_without_terrain_occluders";
    let Some(path) = dem(test) else { return };
    let (_dir, scene) = nepal_scene(&path, true);
    let checker = Checker::new(&scene);
    let (route, _) =
        blockwalk::walk::job::resolve_route(&RouteChoice::Street, &scene, 1.0).unwrap();
    let cams = route.sample(views_wanted(200));
    let index = scene.indexes[0].as_ref();
    let with = scene.occlusion.as_ref().unwrap();
    let time = |c: &OcclusionCuller| {
        let mut ms = Vec::with_capacity(cams.len());
        let (mut culled, mut in_ground) = (0usize, 0usize);
        let (mut out, mut frustum) = (Vec::new(), Vec::new());
        let map = c.new_map();
        for cam in &cams {
            out.clear();
            let st = c.cull(index, cam, &mut out);
            ms.push(st.build_ms + st.test_ms);
            frustum.clear();
            let no_map = OcclusionStats {
                skipped: Some(SkipReason::NoOccluders),
                ..Default::default()
            };
            c.traverse(index, cam, &map, no_map, &mut frustum);
            culled += frustum.len() - out.len();
            in_ground += (st.skipped == Some(SkipReason::NearPlaneInGround)) as usize;
        }
        let mean = ms.iter().sum::<f64>() / ms.len().max(1) as f64;
        let max = ms.iter().copied().fold(0.0, f64::max);
        (mean, max, culled, in_ground)
    };
    // Once each to warm up, then measured.
    time(with);
    time(&checker.plain);
    let (mt, xt, ct, gt) = time(with);
    let (mp, xp, cp, _) = time(&checker.plain);
    let terrain_groups = with.blocks().len() - checker.plain.blocks().len();
    eprintln!(
        "nepal street route, {} frames, cull map 256², {} terrain occluder groups: with terrain occluders mean {mt:.3} ms, max {xt:.3} ms ({ct} blocks culled); without mean {mp:.3} ms, max {xp:.3} ms ({cp} blocks culled); {gt} frames with the near plane in the ground",
        cams.len(),
        terrain_groups
    );
    assert!(mt.is_finite() && mp.is_finite());
}

// ---------------------------------------------------------------------------------------------
// A stiff synthetic case: a 100 m cliff and a ridge.

/// Grid spacing of the synthetic terrain, metres (two cells make one 25 m occluder cell).
const SP: f64 = 12.5;

/// West to east: a valley floor at 100 m up to x = 200, a 100 m cliff (one cell wide, 200 to
/// 212.5), a plateau at 200 m, a ridge rising to 250 m at x = 400 (flanks 100 m wide), the
/// plateau again at 200 m behind it, and a gentle twist of the ground across y so that the
/// triangulated ground differs from the bilinear one.
fn cliff_height(x: f64, y: f64) -> f64 {
    let base = if x <= 200.0 { 100.0 } else { 200.0 };
    let ridge = (50.0 * (1.0 - (x - 400.0).abs() / 100.0)).max(0.0);
    let wobble = 3.0 * ((x / 37.0).sin() * (y / 29.0).cos());
    base + ridge + wobble
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon<f64> {
    Polygon::new(
        LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]),
        vec![],
    )
}

fn cliff_scene() -> Scene {
    let (nx, ny) = (65usize, 41usize);
    let mut heights = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            heights.push(cliff_height(i as f64 * SP, j as f64 * SP));
        }
    }
    let terrain =
        Terrain::from_heights("cliff", nx, ny, DVec2::ZERO, DVec2::splat(SP), heights).unwrap();
    // Buildings at the foot of the cliff (x 90 … 195), on the plateau before the ridge, and
    // behind the ridge (x 470 … 600), rows along y.
    let mut footprints = Vec::new();
    for (x0, x1, h) in [
        (90.0, 110.0, 12.0),
        (130.0, 150.0, 20.0),
        (170.0, 195.0, 9.0),
        (260.0, 280.0, 15.0),
        (470.0, 490.0, 10.0),
        (520.0, 545.0, 25.0),
        (570.0, 600.0, 8.0),
    ] {
        for k in 0..6 {
            let y0 = 40.0 + k as f64 * 70.0;
            footprints.push((rect(x0, y0, x1, y0 + 30.0), h));
        }
    }
    let buildings: Vec<Building> = footprints
        .into_iter()
        .enumerate()
        .map(|(i, (footprint, h))| {
            let base_m = terrain
                .ground_under(&footprint, BaseRule::Min)
                .unwrap()
                .base_m;
            Building {
                id: BuildingId(i as u32),
                source_id: format!("cliff:{i}"),
                footprint,
                height_m: h,
                min_height_m: 0.0,
                base_m,
                height_source: HeightSource::Height,
                attributes: Default::default(),
            }
        })
        .collect();
    scene_of("cliff", buildings, terrain)
}

/// Eyes 0.1 m above the ground: at the cliff's top edge looking down over it and along it, at
/// its foot looking up the face, on the ridge's flanks looking over the crest from both sides,
/// on the crest itself, and among the buildings behind the ridge looking back at it.
fn cliff_cameras(g: &Ground<'_>, n: usize) -> Vec<Camera> {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let mut out = Vec::new();
    let y_range = 20.0..480.0;
    while out.len() < n {
        let y = rng.random_range(y_range.clone());
        let kind = out.len() % 6;
        let (x, yaw, pitch): (f64, f64, f64) = match kind {
            // Top of the cliff, looking west over the edge (down to level).
            0 => (
                rng.random_range(212.5..230.0),
                PI,
                rng.random_range(-45f64..5.0).to_radians(),
            ),
            // Foot of the cliff, looking east up the face.
            1 => (
                rng.random_range(190.0..200.0),
                0.0,
                rng.random_range(0f64..80.0).to_radians(),
            ),
            // West flank of the ridge, just below the crest, looking east over it.
            2 => (
                rng.random_range(370.0..399.0),
                0.0,
                rng.random_range(0f64..30.0).to_radians(),
            ),
            // East flank, looking west over the crest towards the cliff.
            3 => (
                rng.random_range(401.0..430.0),
                PI,
                rng.random_range(0f64..30.0).to_radians(),
            ),
            // On the crest, looking either way down.
            4 => (
                rng.random_range(399.0..401.0),
                if rng.random_bool(0.5) { 0.0 } else { PI },
                rng.random_range(-30f64..0.0).to_radians(),
            ),
            // Among the buildings behind the ridge, looking back at it, or at the foot looking
            // along the cliff.
            _ => {
                if rng.random_bool(0.5) {
                    (
                        rng.random_range(495.0..515.0),
                        PI,
                        rng.random_range(-5f64..25.0).to_radians(),
                    )
                } else {
                    (
                        rng.random_range(196.0..200.0),
                        if rng.random_bool(0.5) {
                            FRAC_PI_2
                        } else {
                            -FRAC_PI_2
                        },
                        rng.random_range(-10f64..10.0).to_radians(),
                    )
                }
            }
        };
        let p = DVec2::new(x, y);
        let Some(z) = g.at(p) else { continue };
        let yaw = yaw + rng.random_range(-0.4..0.4);
        let cam = Camera::new(p.extend(z + 0.1), yaw, pitch);
        out.push(with_near(cam, NEARS[(out.len() / 6) % NEARS.len()]));
    }
    out
}

#[test]
fn cliff_and_ridge_cameras_never_cull_a_visible_block() {
    let scene = cliff_scene();
    let t = scene.city.terrain.clone().unwrap();
    let g = Ground {
        terrain: &t,
        frame: scene.city.frame,
    };
    let checker = Checker::new(&scene);
    let cams = cliff_cameras(&g, views_wanted(240));
    let area = [0.0, 0.0, 800.0, 500.0];
    let families = [
        ("cliff and ridge", checker.check("cliff and ridge", &cams)),
        (
            "on slopes",
            checker.check(
                "on slopes",
                &on_slopes(&g, area, 25.0, views_wanted(120), 5),
            ),
        ),
        (
            "behind ridges",
            checker.check(
                "behind ridges",
                &behind_ridges(&g, DVec2::new(400.0, 250.0), 8, 390.0, views_wanted(120), 6),
            ),
        ),
    ];
    report_and_assert("cliff", &families);
}

/// An eye 0.1 m above the foot of the cliff, looking south along it with a near plane of 2 m:
/// the near plane cuts into the cliff face, so the rays beyond it run under the plateau and the
/// ridge and see the buried uphill walls of the buildings behind the ridge. The shadows of the
/// terrain's cells (and of the buildings' walls, below their bases) would hide those blocks:
/// the culler must not use the cull map for such a frame
/// ([`SkipReason::NearPlaneInGround`]). With a near plane of 5 cm nothing is seen through the
/// ground and the map is used.
#[test]
fn a_near_plane_inside_the_cliff_sees_buried_walls_and_culls_nothing() {
    let scene = cliff_scene();
    let checker = Checker::new(&scene);
    let with = scene.occlusion.as_ref().unwrap();
    let index = scene.indexes[0].as_ref();
    let (w, h, ss) = ORACLE;
    let eye = DVec3::new(198.9156985881022, 361.00608493262035, 97.78686306182092);
    let mut cam = Camera::new(eye, -1.496494175691347, 0.023808533206463246);
    cam.near = 2.0;
    let seen = visible_blocks_with_terrain(&checker.blocks, Some(checker.terrain), &cam, w, h, ss);
    // Behind the ridge, 270 m east, seen through the ground.
    assert!(seen.contains(&BlockId(24)), "{seen:?}");
    assert!(!with.near_plane_above_ground(&cam));
    for c in [with, &checker.plain] {
        let mut kept = Vec::new();
        let st = c.cull(index, &cam, &mut kept);
        assert_eq!(st.skipped, Some(SkipReason::NearPlaneInGround));
        assert!(seen.iter().all(|b| kept.contains(b)), "{seen:?} {kept:?}");
    }
    cam.near = 0.05;
    assert!(with.near_plane_above_ground(&cam));
    let seen = visible_blocks_with_terrain(&checker.blocks, Some(checker.terrain), &cam, w, h, ss);
    assert!(!seen.contains(&BlockId(24)), "{seen:?}");
    let mut kept = Vec::new();
    let st = with.cull(index, &cam, &mut kept);
    assert_eq!(st.skipped, None);
    assert!(seen.iter().all(|b| kept.contains(b)), "{seen:?} {kept:?}");
    assert!(
        !kept.contains(&BlockId(24)),
        "the ground hides it: {kept:?}"
    );
}

/// A building standing across a row of saddle cells (10 m cells, nodes alternately 0 and 8 m
/// on two rows): the lowest point of the bilinear surface under it is 3.6 m, but the drawn
/// terrain splits each cell along its south-west–north-east diagonal, and along the diagonals of
/// these saddles it lies at 0: a V valley passes under the building. With the base on the
/// bilinear surface alone, an eye 1 m up looking along the valley sees a low block behind the
/// building through the 3.6 m gap, which the wall's shadow (a facade solid down to the ground)
/// hides: a false cull. The base is the lowest point of both surfaces
/// ([`BaseRule::Min`]), so the building reaches the drawn ground, the gap is closed, and the
/// culler is right again.
#[test]
fn a_wall_over_a_dip_of_the_drawn_ground_reaches_down_to_it() {
    let (nx, ny, sp) = (20usize, 20usize, 10.0);
    let mut heights = vec![0.0; nx * ny];
    for i in 0..nx {
        heights[8 * nx + i] = if i % 2 == 1 { 8.0 } else { 0.0 };
        heights[9 * nx + i] = if i % 2 == 0 { 8.0 } else { 0.0 };
    }
    let terrain =
        Terrain::from_heights("saddles", nx, ny, DVec2::ZERO, DVec2::splat(sp), heights).unwrap();
    let wall = rect(40.0, 84.5, 100.0, 85.5);
    let target = rect(93.0, 113.0, 97.0, 117.0);
    // The bilinear surface under the wall's footprint never goes below 3.6 m; the drawn one
    // goes down to 0 on the diagonals; the base takes the lower.
    let mut bilinear_min = f64::INFINITY;
    for k in 0..=600 {
        for y in [84.5, 85.0, 85.5] {
            bilinear_min = bilinear_min.min(
                terrain
                    .sample(DVec2::new(40.0 + 0.1 * k as f64, y))
                    .unwrap(),
            );
        }
    }
    assert!((bilinear_min - 3.6).abs() < 1e-9, "{bilinear_min}");
    assert!(terrain.sample_drawn(DVec2::new(64.5, 84.5)).unwrap().abs() < 1e-9);
    let base = terrain.ground_under(&wall, BaseRule::Min).unwrap().base_m;
    assert!(base.abs() < 1e-9, "{base}");
    let mut cam = Camera::new(
        DVec3::new(40.0, 60.0, 1.0),
        std::f64::consts::FRAC_PI_4,
        0.0,
    );
    cam.near = 0.1;
    let (w, h, ss) = ORACLE;
    let check = |scene: &Scene| {
        let checker = Checker::new(scene);
        let seen =
            visible_blocks_with_terrain(&checker.blocks, Some(checker.terrain), &cam, w, h, ss);
        let index = scene.indexes[0].as_ref();
        let mut missed = 0;
        for c in [scene.occlusion.as_ref().unwrap(), &checker.plain] {
            let mut kept = Vec::new();
            let st = c.cull(index, &cam, &mut kept);
            assert_eq!(st.skipped, None);
            missed += seen.iter().filter(|b| !kept.contains(b)).count();
        }
        (seen, missed)
    };
    // The base on the bilinear surface: the gap shows the block behind, and the shadow hid it.
    let floating = scene_on(
        terrain.clone(),
        vec![(wall.clone(), 10.0), (target.clone(), 2.0)],
        Some(3.6),
    );
    let (seen, missed) = check(&floating);
    assert!(seen.contains(&BlockId(1)), "{seen:?}");
    assert_eq!(
        missed, 2,
        "both cullers hide the block seen through the gap"
    );
    // The base on both surfaces: nothing is seen under the wall, nothing seen is culled.
    let scene = scene_on(terrain, vec![(wall, 10.0), (target, 2.0)], None);
    assert_eq!(scene.city.buildings[0].base_m, base);
    let (seen, missed) = check(&scene);
    assert!(!seen.contains(&BlockId(1)), "{seen:?}");
    assert_eq!(missed, 0);
}

/// A scene of `buildings` (footprint, height) on `terrain` (local frame at the origin), each
/// on the ground by [`BaseRule::Min`] (or the first at `first_base`), one block each.
fn scene_on(
    terrain: Terrain,
    footprints: Vec<(Polygon<f64>, f64)>,
    first_base: Option<f64>,
) -> Scene {
    let buildings: Vec<Building> = footprints
        .into_iter()
        .enumerate()
        .map(|(i, (footprint, h))| Building {
            id: BuildingId(i as u32),
            source_id: format!("t:{i}"),
            base_m: match (i, first_base) {
                (0, Some(b)) => b,
                _ => {
                    terrain
                        .ground_under(&footprint, BaseRule::Min)
                        .unwrap()
                        .base_m
                }
            },
            footprint,
            height_m: h,
            min_height_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        })
        .collect();
    scene_of("terrain test", buildings, terrain)
}

/// A scene of `buildings` on `terrain`, one block per building, with the BqR-tree and the
/// occlusion culler using the terrain as an occluder.
fn scene_of(name: &str, buildings: Vec<Building>, terrain: Terrain) -> Scene {
    let layout = BlockLayout {
        blocks: buildings
            .iter()
            .map(|b| Block {
                id: BlockId(b.id.0),
                kind: BlockKind::Block,
                polygon: b.footprint.clone(),
                buildings: vec![b.id],
            })
            .collect(),
        source: BlockSource::Streets,
        street_edges: Vec::new(),
        dangles: 0,
    };
    let city = City {
        name: name.into(),
        transform: blockwalk::importers::Crs::Unknown.metric_transform([0.0, 0.0]),
        frame: LocalFrame {
            origin: DVec3::ZERO,
        },
        buildings,
        streets: Vec::new(),
        parcels: Vec::new(),
        report: CityReport::default(),
        terrain: Some(Arc::new(terrain)),
    };
    let opts = SceneOptions {
        structures: vec![Structure::Bqr],
        occlusion: Some(CullerOptions::default()),
        terrain_occludes: true,
        ..SceneOptions::default()
    };
    Scene::from_loaded(
        LoadedCity {
            city,
            layout: Some(layout),
            meshes: None,
        },
        &opts,
        &mut |_| {},
    )
    .unwrap()
}
