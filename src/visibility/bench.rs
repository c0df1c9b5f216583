//! Occlusion culling against the oracle over random views: false culls, effectiveness, time
//! (seed 004 §3.2.9 measures the same trade-off between cull map resolution and cost).

use super::culler::{aabb_may_intersect, CullerOptions, OcclusionCuller};
use super::cullmap::Resolution;
use super::oracle::render_ids;
use super::VisibilityError;
use crate::blocks::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use crate::city::{Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Mesh};
use crate::geom::{Aabb3, Camera, Frustum};
use crate::index::{BlockBounds, CityIndex, CullStats};
use geo_types::{coord, LineString, Polygon};
use glam::{DVec2, DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeSet;

/// Where a view is taken from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewKind {
    /// Eye at pedestrian height in a street, looking roughly level.
    Street,
    /// Eye above the roofs, looking down at an angle.
    Flying,
}

/// One view of a benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct View {
    /// Street or flying.
    pub kind: ViewKind,
    /// The camera (local frame).
    pub camera: Camera,
}

/// Parameters of [`run_occlusion_bench`].
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Cull map cells along the longer side, one run each.
    pub resolutions: Vec<u32>,
    /// Number of random views.
    pub views: usize,
    /// Fraction of street-level views (the rest fly).
    pub street_fraction: f64,
    /// Seed of the view generator.
    pub seed: u64,
    /// Oracle image size (pixels).
    pub oracle_size: (u32, u32),
    /// Eye height of street views, metres.
    pub eye_height: f64,
    /// Range of eye heights of flying views, metres.
    pub flying_heights: (f64, f64),
    /// Culler parameters (its resolution is replaced by each of `resolutions`).
    pub culler: CullerOptions,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            resolutions: vec![64, 128, 256, 512, 1024],
            views: 100,
            street_fraction: 0.7,
            seed: 1,
            oracle_size: (640, 360),
            eye_height: 1.7,
            flying_heights: (30.0, 200.0),
            culler: CullerOptions::default(),
        }
    }
}

/// A block the cull map removed although the oracle sees it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FalseCull {
    /// Index of the view.
    pub view: usize,
    /// Cull map cells along the longer side.
    pub resolution: u32,
    /// The block.
    pub block: BlockId,
}

/// Results for one cull map resolution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResolutionReport {
    /// Cells along the longer side.
    pub resolution: u32,
    /// Grid size.
    pub cells: (usize, usize),
    /// Cell side, metres.
    pub cell_m: f64,
    /// Median milliseconds per frame (select + draw + pyramid + index traversal).
    pub median_ms: f64,
    /// Median milliseconds to build the cull map.
    pub median_build_ms: f64,
    /// Median milliseconds of the index traversal with cull map tests.
    pub median_test_ms: f64,
    /// Mean occluders drawn per frame.
    pub mean_occluders: f64,
    /// Mean blocks removed by the cull map per frame.
    pub mean_culled: f64,
    /// Blocks removed that the oracle sees (must be 0).
    pub false_culls: u64,
    /// Blocks removed / blocks in the frustum the oracle proves hidden, over all views.
    pub effectiveness: f64,
    /// Effectiveness over street views only.
    pub effectiveness_street: f64,
    /// Effectiveness over flying views only.
    pub effectiveness_flying: f64,
    /// Frames where occlusion culling was skipped.
    pub skipped: u64,
}

/// What [`run_occlusion_bench`] measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OcclusionBenchReport {
    /// Views used.
    pub views: usize,
    /// Street-level views among them.
    pub street_views: usize,
    /// Blocks in the scene.
    pub blocks: usize,
    /// Mean blocks in the frustum per view.
    pub mean_in_frustum: f64,
    /// Mean blocks the oracle sees per view.
    pub mean_visible: f64,
    /// Oracle image size.
    pub oracle_size: (u32, u32),
    /// One entry per resolution.
    pub resolutions: Vec<ResolutionReport>,
    /// The first false culls found (at most 20).
    pub false_cull_examples: Vec<FalseCull>,
}

/// A plain list of block boxes implementing [`CityIndex`]: every block tested on its own, nearest
/// first. The reference the tree structures are compared with, and a stand-in when none is built.
#[derive(Clone, Debug)]
pub struct ListIndex {
    blocks: Vec<BlockBounds>,
    viewer: Option<DVec3>,
}

impl ListIndex {
    /// An index over `blocks`.
    pub fn new(blocks: Vec<BlockBounds>) -> Self {
        Self {
            blocks,
            viewer: None,
        }
    }
    /// Orders the output front to back from `eye` (plan-view distance to each box).
    pub fn with_viewer(mut self, eye: DVec3) -> Self {
        self.viewer = Some(eye);
        self
    }
    /// The boxes.
    pub fn bounds(&self) -> &[BlockBounds] {
        &self.blocks
    }
}

impl CityIndex for ListIndex {
    fn name(&self) -> &'static str {
        "list"
    }

    fn len(&self) -> usize {
        self.blocks.len()
    }

    fn cull_filtered(
        &self,
        frustum: &Frustum,
        keep: &mut dyn FnMut(&Aabb3) -> bool,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut st = CullStats::default();
        let mut order: Vec<(f64, usize)> = self
            .blocks
            .iter()
            .enumerate()
            .map(|(k, b)| {
                let d = self.viewer.map_or(0.0, |e| {
                    let e2 = e.truncate();
                    (e2.clamp(b.aabb.min.truncate(), b.aabb.max.truncate()) - e2).length()
                });
                (d, k)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (_, k) in order {
            let b = &self.blocks[k];
            st.nodes_visited += 1;
            st.plane_tests += 6;
            if b.aabb.is_empty() || !aabb_may_intersect(frustum, &b.aabb) || !keep(&b.aabb) {
                continue;
            }
            st.blocks_accepted += 1;
            st.triangles_accepted += b.triangles as u64;
            out.push(b.id);
        }
        st
    }
}

/// Box of each block's buildings (footprints × [0, max height], local frame), as an index wants.
pub fn block_bounds(
    city: &City,
    layout: &BlockLayout,
    meshes: &[(BlockId, &Mesh)],
) -> Vec<BlockBounds> {
    let occ = super::occluders::extract(city, layout, &Default::default());
    occ.into_iter()
        .map(|b| {
            let mut aabb = b.aabb;
            let mut triangles = 0u32;
            for (id, m) in meshes.iter().filter(|(id, _)| *id == b.block) {
                let _ = id;
                triangles += m.triangle_count() as u32;
                for p in &m.positions {
                    aabb = aabb.including(p.as_dvec3());
                }
            }
            let center = if aabb.is_empty() {
                DVec2::ZERO
            } else {
                aabb.center().truncate()
            };
            BlockBounds {
                id: b.block,
                aabb,
                center,
                triangles,
            }
        })
        .collect()
}

/// True when `p` is inside or on the ring (the exact odd-crossing test of `geom::predicates`).
fn point_in_ring(p: DVec2, ring: &[DVec2]) -> bool {
    use crate::geom::predicates::{self, Location};
    let r: Vec<geo_types::Coord<f64>> = ring
        .iter()
        .map(|c| geo_types::Coord { x: c.x, y: c.y })
        .collect();
    predicates::point_in_ring(geo_types::Coord { x: p.x, y: p.y }, &r) != Location::Outside
}

/// Random views over the city (deterministic for a seed): street views at `eye_height` on the
/// street edges (or anywhere outside every footprint when there are none), flying views above.
pub fn random_views(city: &City, layout: &BlockLayout, opts: &BenchOptions) -> Vec<View> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let rings: Vec<(Aabb3, Vec<DVec2>)> = city
        .buildings
        .iter()
        .map(|b| {
            let r: Vec<DVec2> = b
                .footprint
                .exterior()
                .coords()
                .map(|c| {
                    city.frame
                        .to_local_f64(DVec3::new(c.x, c.y, 0.0))
                        .truncate()
                })
                .collect();
            (Aabb3::from_points(r.iter().map(|p| p.extend(0.0))), r)
        })
        .collect();
    let mut bounds = Aabb3::EMPTY;
    for (b, _) in &rings {
        bounds = bounds.union(*b);
    }
    if bounds.is_empty() {
        return Vec::new();
    }
    let edges: Vec<Vec<DVec2>> = layout
        .street_edges
        .iter()
        .map(|l| {
            l.coords()
                .map(|c| {
                    city.frame
                        .to_local_f64(DVec3::new(c.x, c.y, 0.0))
                        .truncate()
                })
                .collect::<Vec<_>>()
        })
        .filter(|l: &Vec<DVec2>| l.len() >= 2)
        .collect();
    let inside_any = |p: DVec2| {
        rings.iter().any(|(b, r)| {
            p.x >= b.min.x
                && p.x <= b.max.x
                && p.y >= b.min.y
                && p.y <= b.max.y
                && point_in_ring(p, r)
        })
    };
    let (lo, hi) = (bounds.min.truncate(), bounds.max.truncate());
    let mut views = Vec::with_capacity(opts.views);
    for _ in 0..opts.views {
        let street = rng.random_bool(opts.street_fraction.clamp(0.0, 1.0));
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        if street {
            let mut p = lo;
            for _ in 0..100 {
                p = if edges.is_empty() {
                    DVec2::new(rng.random_range(lo.x..=hi.x), rng.random_range(lo.y..=hi.y))
                } else {
                    let e = &edges[rng.random_range(0..edges.len())];
                    let k = rng.random_range(0..e.len() - 1);
                    e[k].lerp(e[k + 1], rng.random_range(0.0..=1.0))
                };
                if !inside_any(p) {
                    break;
                }
            }
            let pitch = rng.random_range(-0.15..0.25);
            views.push(View {
                kind: ViewKind::Street,
                camera: Camera::new(p.extend(opts.eye_height), yaw, pitch),
            });
        } else {
            let p = DVec2::new(rng.random_range(lo.x..=hi.x), rng.random_range(lo.y..=hi.y));
            let (h0, h1) = opts.flying_heights;
            let z = if h1 > h0 {
                rng.random_range(h0..h1)
            } else {
                h0
            };
            let pitch = rng.random_range(-0.9..-0.1);
            views.push(View {
                kind: ViewKind::Flying,
                camera: Camera::new(p.extend(z), yaw, pitch),
            });
        }
    }
    views
}

/// A scene to benchmark: the city, its blocks, one mesh per block (local frame) and an index.
#[derive(Clone, Copy)]
pub struct BenchScene<'a> {
    /// The city.
    pub city: &'a City,
    /// Its blocks.
    pub layout: &'a BlockLayout,
    /// Geometry per block, local frame (what the oracle draws).
    pub meshes: &'a [(BlockId, &'a Mesh)],
    /// The structure frustum culling runs on.
    pub index: &'a dyn CityIndex,
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Runs the occlusion culler at every resolution over random views and compares each frame with
/// the oracle: false culls (the oracle sees a removed block; must be 0), effectiveness (removed /
/// in the frustum but hidden in the oracle) and time. `progress(done, total)` is called per view.
pub fn run_occlusion_bench(
    scene: &BenchScene<'_>,
    opts: &BenchOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<OcclusionBenchReport, VisibilityError> {
    let views = random_views(scene.city, scene.layout, opts);
    run_on_views(scene, opts, &views, progress)
}

/// As [`run_occlusion_bench`] on given views.
pub fn run_on_views(
    scene: &BenchScene<'_>,
    opts: &BenchOptions,
    views: &[View],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<OcclusionBenchReport, VisibilityError> {
    if opts.resolutions.is_empty() {
        return Err(VisibilityError::NoResolutions);
    }
    let base = OcclusionCuller::new(scene.city, scene.layout, opts.culler)?;
    let cullers: Vec<OcclusionCuller> = opts
        .resolutions
        .iter()
        .map(|&r| base.with_resolution(Resolution::Cells(r)))
        .collect::<Result<_, _>>()?;
    struct Acc {
        ms: Vec<f64>,
        build: Vec<f64>,
        test: Vec<f64>,
        occ: u64,
        culled: u64,
        culled_hidden: [u64; 2],
        hidden: [u64; 2],
        false_culls: u64,
        skipped: u64,
    }
    let mut acc: Vec<Acc> = cullers
        .iter()
        .map(|_| Acc {
            ms: vec![],
            build: vec![],
            test: vec![],
            occ: 0,
            culled: 0,
            culled_hidden: [0; 2],
            hidden: [0; 2],
            false_culls: 0,
            skipped: 0,
        })
        .collect();
    let mut examples = Vec::new();
    let (mut in_frustum_sum, mut visible_sum) = (0u64, 0u64);
    for (vi, view) in views.iter().enumerate() {
        progress(vi, views.len());
        let cam = &view.camera;
        let kind = (view.kind == ViewKind::Flying) as usize;
        let mut frustum_out = Vec::new();
        scene.index.cull(&cam.frustum(), &mut frustum_out);
        let in_frustum: BTreeSet<BlockId> = frustum_out.into_iter().collect();
        let visible =
            render_ids(scene.meshes, cam, opts.oracle_size.0, opts.oracle_size.1).visible();
        in_frustum_sum += in_frustum.len() as u64;
        visible_sum += visible.len() as u64;
        let hidden: BTreeSet<BlockId> = in_frustum.difference(&visible).copied().collect();
        for (c, a) in cullers.iter().zip(acc.iter_mut()) {
            let mut out = Vec::new();
            let st = c.cull(scene.index, cam, &mut out);
            let kept: BTreeSet<BlockId> = out.into_iter().collect();
            let culled: Vec<BlockId> = in_frustum.difference(&kept).copied().collect();
            a.ms.push(st.build_ms + st.test_ms);
            a.build.push(st.build_ms);
            a.test.push(st.test_ms);
            a.occ += st.occluders_used;
            a.culled += culled.len() as u64;
            a.hidden[kind] += hidden.len() as u64;
            a.skipped += st.skipped.is_some() as u64;
            for b in culled {
                if visible.contains(&b) {
                    a.false_culls += 1;
                    if examples.len() < 20 {
                        examples.push(FalseCull {
                            view: vi,
                            resolution: match c.options().resolution {
                                Resolution::Cells(n) => n,
                                Resolution::CellSize(_) => 0,
                            },
                            block: b,
                        });
                    }
                } else {
                    a.culled_hidden[kind] += 1;
                }
            }
        }
    }
    progress(views.len(), views.len());
    let n = views.len().max(1) as f64;
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let resolutions = cullers
        .iter()
        .zip(acc.iter_mut())
        .zip(&opts.resolutions)
        .map(|((c, a), &r)| {
            let g = *c
                .cull_map_for(&Camera::new(DVec3::new(0.0, 0.0, -1.0), 0.0, 0.0))
                .grid();
            ResolutionReport {
                resolution: r,
                cells: (g.nx, g.ny),
                cell_m: g.cell,
                median_ms: median(&mut a.ms),
                median_build_ms: median(&mut a.build),
                median_test_ms: median(&mut a.test),
                mean_occluders: a.occ as f64 / n,
                mean_culled: a.culled as f64 / n,
                false_culls: a.false_culls,
                effectiveness: ratio(
                    a.culled_hidden[0] + a.culled_hidden[1],
                    a.hidden[0] + a.hidden[1],
                ),
                effectiveness_street: ratio(a.culled_hidden[0], a.hidden[0]),
                effectiveness_flying: ratio(a.culled_hidden[1], a.hidden[1]),
                skipped: a.skipped,
            }
        })
        .collect();
    Ok(OcclusionBenchReport {
        views: views.len(),
        street_views: views.iter().filter(|v| v.kind == ViewKind::Street).count(),
        blocks: scene.layout.blocks.len(),
        mean_in_frustum: in_frustum_sum as f64 / n,
        mean_visible: visible_sum as f64 / n,
        oracle_size: opts.oracle_size,
        resolutions,
        false_cull_examples: examples,
    })
}

/// A synthetic city for tests and benches: a grid of rectangular blocks separated by streets,
/// each lined with touching box buildings of random heights, an L-shaped building at one corner,
/// some gaps between buildings, and some raised buildings (`min_height_m > 0`, passages). Every
/// footprint is a union of axis-aligned boxes, so [`SyntheticCity::meshes`] holds the exact
/// geometry. World coordinates are offset by `origin` to exercise the local frame.
#[derive(Clone, Debug)]
pub struct SyntheticCity {
    /// The city (metric world coordinates).
    pub city: City,
    /// Its blocks and street edges.
    pub layout: BlockLayout,
    /// One mesh per block (local frame).
    pub meshes: Vec<(BlockId, Mesh)>,
}

impl SyntheticCity {
    /// A `cols × rows` grid of blocks from `seed`.
    pub fn generate(cols: usize, rows: usize, seed: u64, origin: DVec2) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let frame = LocalFrame {
            origin: origin.extend(0.0),
        };
        let mut buildings: Vec<Building> = Vec::new();
        let mut blocks: Vec<Block> = Vec::new();
        let mut meshes: Vec<(BlockId, Mesh)> = Vec::new();
        let street = 16.0;
        let xs: Vec<f64> = std::iter::once(0.0)
            .chain((0..cols).scan(0.0, |x, _| {
                *x += rng.random_range(50.0..110.0) + street;
                Some(*x)
            }))
            .collect();
        let ys: Vec<f64> = std::iter::once(0.0)
            .chain((0..rows).scan(0.0, |y, _| {
                *y += rng.random_range(50.0..110.0) + street;
                Some(*y)
            }))
            .collect();
        let mut street_edges = Vec::new();
        let (w, h) = (*xs.last().unwrap_or(&0.0), *ys.last().unwrap_or(&0.0));
        let wl = |x: f64, y: f64| coord! { x: x + origin.x, y: y + origin.y };
        for &x in &xs {
            street_edges.push(LineString(vec![
                wl(x - street / 2.0, -street / 2.0),
                wl(x - street / 2.0, h - street / 2.0),
            ]));
        }
        for &y in &ys {
            street_edges.push(LineString(vec![
                wl(-street / 2.0, y - street / 2.0),
                wl(w - street / 2.0, y - street / 2.0),
            ]));
        }
        for j in 0..rows {
            for i in 0..cols {
                let (x0, x1) = (xs[i], xs[i + 1] - street);
                let (y0, y1) = (ys[j], ys[j + 1] - street);
                let id = BlockId(blocks.len() as u32);
                let mut mesh = Mesh::default();
                let mut ids = Vec::new();
                let depth = rng
                    .random_range(9.0..15.0f64)
                    .min((x1 - x0) / 3.0)
                    .min((y1 - y0) / 3.0);
                // Boxes as (min, max, min_height, height); each entry one building made of boxes.
                let mut parts: Vec<Vec<(DVec2, DVec2)>> = Vec::new();
                // L at the south-west corner.
                let (la, lb) = (
                    rng.random_range(15.0..30.0f64).min(x1 - x0 - depth),
                    rng.random_range(15.0..30.0f64).min(y1 - y0 - depth),
                );
                parts.push(vec![
                    (DVec2::new(x0, y0), DVec2::new(x0 + la, y0 + depth)),
                    (DVec2::new(x0, y0 + depth), DVec2::new(x0 + depth, y0 + lb)),
                ]);
                let row = |a: f64,
                           b: f64,
                           horizontal: bool,
                           fixed0: f64,
                           fixed1: f64,
                           rng: &mut ChaCha8Rng,
                           parts: &mut Vec<Vec<(DVec2, DVec2)>>| {
                    let mut s = a;
                    while s < b - 4.0 {
                        let mut e = (s + rng.random_range(8.0..25.0)).min(b);
                        if b - e < 6.0 {
                            e = b;
                        }
                        let r = if horizontal {
                            (DVec2::new(s, fixed0), DVec2::new(e, fixed1))
                        } else {
                            (DVec2::new(fixed0, s), DVec2::new(fixed1, e))
                        };
                        parts.push(vec![r]);
                        s = e + if rng.random_bool(0.1) { 2.0 } else { 0.0 };
                    }
                };
                row(x0 + la, x1, true, y0, y0 + depth, &mut rng, &mut parts); // south
                row(x0, x1, true, y1 - depth, y1, &mut rng, &mut parts); // north
                row(
                    y0 + depth,
                    y1 - depth,
                    false,
                    x1 - depth,
                    x1,
                    &mut rng,
                    &mut parts,
                ); // east
                row(
                    y0 + lb,
                    y1 - depth,
                    false,
                    x0,
                    x0 + depth,
                    &mut rng,
                    &mut parts,
                ); // west
                for boxes in parts {
                    let height = rng.random_range(6.0..40.0f64).round();
                    let min_height = if boxes.len() == 1 && rng.random_bool(0.05) {
                        4.0
                    } else {
                        0.0
                    };
                    let ring: Vec<DVec2> = if boxes.len() == 1 {
                        let (a, b) = boxes[0];
                        vec![a, DVec2::new(b.x, a.y), b, DVec2::new(a.x, b.y), a]
                    } else {
                        let (a, b) = boxes[0];
                        let (_, d) = boxes[1];
                        vec![
                            a,
                            DVec2::new(b.x, a.y),
                            DVec2::new(b.x, b.y),
                            DVec2::new(d.x, b.y),
                            d,
                            DVec2::new(a.x, d.y),
                            a,
                        ]
                    };
                    let bid = BuildingId(buildings.len() as u32);
                    ids.push(bid);
                    buildings.push(Building {
                        id: bid,
                        source_id: format!("synthetic:{}", bid.0),
                        footprint: Polygon::new(
                            LineString(ring.iter().map(|p| wl(p.x, p.y)).collect()),
                            vec![],
                        ),
                        height_m: height,
                        min_height_m: min_height,
                        height_source: HeightSource::Height,
                        attributes: Default::default(),
                    });
                    for (a, b) in boxes {
                        let m = super::oracle::box_mesh(
                            Vec3::new(a.x as f32, a.y as f32, min_height as f32),
                            Vec3::new(b.x as f32, b.y as f32, height as f32),
                        );
                        let base = mesh.positions.len() as u32;
                        mesh.positions.extend_from_slice(&m.positions);
                        mesh.normals.extend_from_slice(&m.normals);
                        mesh.indices.extend(m.indices.iter().map(|k| k + base));
                    }
                }
                blocks.push(Block {
                    id,
                    kind: BlockKind::Block,
                    polygon: Polygon::new(
                        LineString(vec![
                            wl(x0, y0),
                            wl(x1, y0),
                            wl(x1, y1),
                            wl(x0, y1),
                            wl(x0, y0),
                        ]),
                        vec![],
                    ),
                    buildings: ids,
                });
                meshes.push((id, mesh));
            }
        }
        let city = City {
            name: format!("synthetic {cols}x{rows} seed {seed}"),
            transform: blockwalk_importers::Crs::Unknown.metric_transform([origin.x, origin.y]),
            frame,
            buildings,
            streets: Vec::new(),
            parcels: Vec::new(),
            report: CityReport::default(),
        };
        Self {
            city,
            layout: BlockLayout {
                blocks,
                source: BlockSource::Streets,
                street_edges,
                dangles: 0,
            },
            meshes,
        }
    }

    /// The meshes as the oracle takes them.
    pub fn mesh_refs(&self) -> Vec<(BlockId, &Mesh)> {
        self.meshes.iter().map(|(id, m)| (*id, m)).collect()
    }
}
