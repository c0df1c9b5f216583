//! Culling checked over whole routes: every frame of every route is drawn by the supersampled
//! oracle, then culled through every structure with the cull map at several resolutions
//! (Willmott et al., §3.2) and with the per-building test inside the surviving blocks (§3.2.8).
//! A block (or a building) that the oracle sees and the culler dropped is a false cull; there
//! must be none.
//!
//! The oracle draws the buildings' meshes (the ones the blocks' meshes are merged from) with
//! building ids, once per frame; a block is seen when one of its buildings is. Before drawing,
//! buildings whose box lies wholly beyond one plane of the camera's clip space are left out
//! (they give no pixel); that test uses the camera's own matrix, not the culler's frustum.
//!
//! Frames are vacuous, counted apart, when the eye is inside a building's closed solid
//! ([`BuildingSolids::contains`]: from inside a closed prism nothing else can be seen), when no
//! building's box reaches into the view volume, or when the oracle sees nothing. They are
//! culled and checked all the same, and their false culls are counted apart too.

use super::adversarial::BuildingSolids;
use super::buildings::{BlockBuildings, BuildingBox};
use super::culler::{CullerOptions, OcclusionCuller, OcclusionStats, SkipReason};
use super::cullmap::{CullMap, Resolution, MAX_CELLS_PER_SIDE};
use super::oracle::visible_blocks_supersampled;
use super::VisibilityError;
use crate::blocks::{BlockId, BlockLayout};
use crate::city::{BuildingId, City, Mesh};
use crate::geom::{Aabb3, Camera};
use crate::index::{CityIndex, Structure};
use glam::{DMat4, DVec4};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeSet;
use std::sync::Mutex;
use std::time::Instant;

/// Most pixels along an oracle image's side, samples included.
pub const MAX_ORACLE_SIDE: u32 = 8192;

/// A deliberately broken culler, for the control that shows the check catches false culls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sabotage {
    /// After each cull, drop the lowest-numbered block the oracle sees from what the culler
    /// kept (with its buildings).
    DropVisibleBlock,
}

/// How [`prove_routes`] checks.
#[derive(Clone, Debug, PartialEq)]
pub struct ProofOptions {
    /// The oracle's image, pixels (width, height).
    pub oracle_size: (u32, u32),
    /// Oracle samples per pixel along each axis.
    pub samples: u32,
    /// Cull map cells along the longer side, one culler each.
    pub resolutions: Vec<u32>,
    /// Culler parameters (the resolution is replaced by each of `resolutions`).
    pub culler: CullerOptions,
    /// How many false culls to describe, at most.
    pub max_examples: usize,
    /// A broken culler for the control; `None` checks the real one.
    pub sabotage: Option<Sabotage>,
}

impl Default for ProofOptions {
    /// The adversarial test's oracle (96×54, 4×4 samples) and cull maps (64, 256, 1024 cells).
    fn default() -> Self {
        Self {
            oracle_size: (96, 54),
            samples: 4,
            resolutions: vec![64, 256, 1024],
            culler: CullerOptions::default(),
            max_examples: 20,
            sabotage: None,
        }
    }
}

impl ProofOptions {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`VisibilityError::BadParameter`] for an empty oracle image, no samples or an image
    /// over [`MAX_ORACLE_SIDE`]; [`VisibilityError::NoResolutions`]; a resolution out of
    /// `1..=MAX_CELLS_PER_SIDE` as [`VisibilityError::BadResolution`].
    pub fn check(&self) -> Result<(), VisibilityError> {
        let (w, h) = self.oracle_size;
        for (name, v) in [("oracle width", w), ("oracle height", h)] {
            if v == 0 || v.saturating_mul(self.samples.max(1)) > MAX_ORACLE_SIDE {
                return Err(VisibilityError::BadParameter {
                    name,
                    value: f64::from(v),
                    expected: "at least 1, and at most 8192 with the samples",
                });
            }
        }
        if self.samples == 0 {
            return Err(VisibilityError::BadParameter {
                name: "oracle samples",
                value: 0.0,
                expected: "at least 1 per pixel along each axis",
            });
        }
        if self.resolutions.is_empty() {
            return Err(VisibilityError::NoResolutions);
        }
        if let Some(&r) = self
            .resolutions
            .iter()
            .find(|&&r| r == 0 || r as usize > MAX_CELLS_PER_SIDE)
        {
            return Err(VisibilityError::BadResolution {
                resolution: Resolution::Cells(r),
                max: MAX_CELLS_PER_SIDE,
            });
        }
        Ok(())
    }
}

/// A city as the proof sees it.
#[derive(Clone, Copy)]
pub struct ProofScene<'a> {
    /// City name, for reports.
    pub name: &'a str,
    /// The city.
    pub city: &'a City,
    /// Its blocks.
    pub layout: &'a BlockLayout,
    /// One mesh per building (local frame, by building id; empty where extrusion failed): what
    /// the blocks' meshes are merged from.
    pub building_meshes: &'a [Mesh],
    /// The structures to cull through (block structures only).
    pub indexes: &'a [&'a dyn CityIndex],
}

/// One route's frames.
#[derive(Clone, Debug)]
pub struct ProofRoute {
    /// Route name.
    pub name: String,
    /// Its cameras (local frame).
    pub cameras: Vec<Camera>,
}

/// Why frames were vacuous.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct VacuousFrames {
    /// The eye inside a building.
    pub inside_building: u64,
    /// No building's box reaches into the view volume.
    pub empty_view: u64,
    /// Something in view, but the oracle sees no building.
    pub nothing_seen: u64,
}

impl VacuousFrames {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.inside_building + self.empty_view + self.nothing_seen
    }
}

/// One structure at one cull map resolution over one route.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProofTally {
    /// The structure.
    pub structure: Structure,
    /// Cull map cells along the longer side.
    pub resolution: u32,
    /// Frames culled.
    pub frames: u64,
    /// Blocks the oracle sees that the culler dropped, on checked frames (must be 0).
    pub false_block_culls: u64,
    /// Buildings the oracle sees that the per-building test dropped, on checked frames (must
    /// be 0).
    pub false_building_culls: u64,
    /// False culls (blocks and buildings) on vacuous frames (must be 0 too).
    pub false_culls_vacuous: u64,
    /// Blocks in the frustum (the flat list's exact test), summed over frames: the same for
    /// every structure.
    pub blocks_in_frustum: u64,
    /// Of those, blocks this structure with the cull map did not keep.
    pub blocks_culled: u64,
    /// Buildings of those blocks that the per-building frustum test keeps, summed over frames.
    pub buildings_in_frustum: u64,
    /// Of those, buildings not kept with occlusion on (block and per-building tests).
    pub buildings_culled: u64,
    /// Frames where the cull map was used.
    pub frames_occlusion: u64,
}

impl ProofTally {
    /// Share of the blocks in the frustum that the cull map removed.
    pub fn block_culled_share(&self) -> f64 {
        ratio(self.blocks_culled, self.blocks_in_frustum)
    }

    /// Share of the buildings in the frustum removed with occlusion on.
    pub fn building_culled_share(&self) -> f64 {
        ratio(self.buildings_culled, self.buildings_in_frustum)
    }

    /// All false culls.
    pub fn false_culls(&self) -> u64 {
        self.false_block_culls + self.false_building_culls + self.false_culls_vacuous
    }
}

fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// What was checked on one route.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RouteProof {
    /// Route name.
    pub route: String,
    /// Frames.
    pub frames: u64,
    /// Vacuous frames, by reason.
    pub vacuous: VacuousFrames,
    /// Frames checked that are not vacuous (`frames - vacuous`).
    pub checked: u64,
    /// Blocks the oracle sees, summed over frames.
    pub visible_blocks: u64,
    /// Buildings the oracle sees, summed over frames.
    pub visible_buildings: u64,
    /// One entry per structure × resolution.
    pub tallies: Vec<ProofTally>,
}

impl RouteProof {
    /// All false culls on this route.
    pub fn false_culls(&self) -> u64 {
        self.tallies.iter().map(ProofTally::false_culls).sum()
    }
}

/// What a false cull dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Dropped {
    /// A block (the structure's cull with the cull map).
    Block(BlockId),
    /// A building (the per-building test).
    Building(BuildingId),
}

/// One false cull, with what it takes to find it again.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FalseCullExample {
    /// City name.
    pub city: String,
    /// Route name.
    pub route: String,
    /// Frame index along the route.
    pub frame: usize,
    /// The structure.
    pub structure: Structure,
    /// Cull map cells along the longer side.
    pub resolution: u32,
    /// What was dropped.
    pub dropped: Dropped,
    /// Whether the frame was vacuous.
    pub vacuous: bool,
    /// The camera (local frame).
    pub camera: Camera,
}

/// What [`prove_routes`] found on one city.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CityProof {
    /// City name.
    pub city: String,
    /// Buildings drawn by the oracle (those in a block, with a mesh).
    pub buildings: usize,
    /// Blocks.
    pub blocks: usize,
    /// The oracle's image and samples per pixel along each axis.
    pub oracle: (u32, u32, u32),
    /// One entry per route.
    pub routes: Vec<RouteProof>,
    /// The first false culls (at most [`ProofOptions::max_examples`]).
    pub false_cull_examples: Vec<FalseCullExample>,
    /// Seconds the check took.
    pub seconds: f64,
}

impl CityProof {
    /// Frames over every route.
    pub fn frames(&self) -> u64 {
        self.routes.iter().map(|r| r.frames).sum()
    }

    /// All false culls.
    pub fn false_culls(&self) -> u64 {
        self.routes.iter().map(RouteProof::false_culls).sum()
    }
}

/// True when the box's eight corners all lie beyond one plane of the clip volume
/// (`-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`): nothing inside it can be drawn.
fn beyond_clip_plane(clip: &DMat4, b: &Aabb3) -> bool {
    let mut out = [true; 6];
    for i in 0..8 {
        let p = glam::DVec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        let c: DVec4 = *clip * p.extend(1.0);
        let tests = [
            c.x < -c.w,
            c.x > c.w,
            c.y < -c.w,
            c.y > c.w,
            c.z < 0.0,
            c.z > c.w,
        ];
        for (o, t) in out.iter_mut().zip(tests) {
            *o &= t;
        }
        if !out.iter().any(|&o| o) {
            return false;
        }
    }
    out.iter().any(|&o| o)
}

/// One frame through one structure at one resolution: the false culls (and the first of
/// each), what of the frustum's blocks and buildings it culled, whether the map was used.
#[derive(Clone, Copy, Debug, Default)]
struct Cell {
    missed_blocks: u32,
    missed_buildings: u32,
    first_block: Option<BlockId>,
    first_building: Option<BuildingId>,
    culled: u32,
    buildings_culled: u32,
    used: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Vacuous {
    Inside,
    EmptyView,
    NothingSeen,
}

struct FrameRow {
    vacuous: Option<Vacuous>,
    in_frustum: u32,
    in_frustum_buildings: u32,
    visible_blocks: u32,
    visible_buildings: u32,
    /// Index `r * n_indexes + i`: resolution `r`, structure `i`.
    cells: Vec<Cell>,
}

/// Cull maps taken from a shared pool and given back when dropped (rayon makes one set per
/// piece of work it splits off; the pool keeps their number at the number of threads).
struct Pooled<'a> {
    maps: Vec<CullMap>,
    pool: &'a Mutex<Vec<Vec<CullMap>>>,
}

impl Drop for Pooled<'_> {
    fn drop(&mut self) {
        let maps = std::mem::take(&mut self.maps);
        if let Ok(mut p) = self.pool.lock() {
            p.push(maps);
        }
    }
}

/// Frames checked between two calls of the progress callback.
const CHUNK: usize = 64;

/// Checks every frame of `routes` on `scene` (see the module doc). `progress(done, total)` is
/// called as frames are done.
///
/// # Errors
/// Bad options ([`ProofOptions::check`]) or a culler that cannot be built.
pub fn prove_routes(
    scene: &ProofScene<'_>,
    routes: &[ProofRoute],
    opts: &ProofOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<CityProof, VisibilityError> {
    opts.check()?;
    let t0 = Instant::now();
    let city = scene.city;
    let drawn: Vec<bool> = (0..city.buildings.len())
        .map(|i| {
            scene
                .building_meshes
                .get(i)
                .is_some_and(|m| !m.indices.is_empty())
        })
        .collect();
    let base = OcclusionCuller::with_drawn(city, scene.layout, &drawn, opts.culler)?;
    let cullers: Vec<OcclusionCuller> = opts
        .resolutions
        .iter()
        .map(|&r| base.with_resolution(Resolution::Cells(r)))
        .collect::<Result<_, _>>()?;
    let solids = BuildingSolids::new(city);
    // The buildings the blocks' meshes hold: block of each, box of each.
    let mut block_of: Vec<Option<BlockId>> = vec![None; scene.building_meshes.len()];
    let mut boxes: Vec<Option<BuildingBox>> = vec![None; scene.building_meshes.len()];
    let per_block = scene.layout.blocks.iter().map(|b| {
        let v: Vec<BuildingBox> = b
            .buildings
            .iter()
            .filter_map(|id| {
                let i = id.0 as usize;
                let bb = BuildingBox::from_mesh(*id, scene.building_meshes.get(i)?)?;
                block_of[i] = Some(b.id);
                boxes[i] = Some(bb);
                Some(bb)
            })
            .collect();
        (b.id, v)
    });
    let per_block: Vec<(BlockId, Vec<BuildingBox>)> = per_block.collect();
    let buildings = BlockBuildings::new(per_block);
    let drawable: Vec<(BlockId, &Mesh, Aabb3)> = boxes
        .iter()
        .flatten()
        .map(|b| {
            (
                BlockId(b.id.0),
                &scene.building_meshes[b.id.0 as usize],
                b.aabb,
            )
        })
        .collect();
    let (w, h) = opts.oracle_size;
    let ss = opts.samples;
    let n_idx = scene.indexes.len();
    let pool: Mutex<Vec<Vec<CullMap>>> = Mutex::new(Vec::new());
    let total: usize = routes.iter().map(|r| r.cameras.len()).sum();
    let mut done = 0usize;
    let mut examples = Vec::new();
    let mut route_reports = Vec::with_capacity(routes.len());
    let frame_check = |maps: &mut Pooled<'_>, cam: &Camera| -> FrameRow {
        let clip = cam.clip_from_world();
        let in_view: Vec<(BlockId, &Mesh)> = drawable
            .iter()
            .filter(|(_, _, b)| !beyond_clip_plane(&clip, b))
            .map(|(id, m, _)| (*id, *m))
            .collect();
        let seen: BTreeSet<BuildingId> = visible_blocks_supersampled(&in_view, cam, w, h, ss)
            .into_iter()
            .map(|b| BuildingId(b.0))
            .collect();
        let seen_blocks: BTreeSet<BlockId> = seen
            .iter()
            .filter_map(|b| block_of.get(b.0 as usize).copied().flatten())
            .collect();
        let vacuous = if solids.contains(cam.position) {
            Some(Vacuous::Inside)
        } else if in_view.is_empty() {
            Some(Vacuous::EmptyView)
        } else if seen.is_empty() {
            Some(Vacuous::NothingSeen)
        } else {
            None
        };
        let frustum = cam.frustum();
        // What the frustum holds: the flat list's exact test of every block (or the first
        // structure's, without a flat list), and the buildings of those blocks that the
        // per-building frustum test keeps; the shares culled are of these, for every structure.
        let no_map = OcclusionStats {
            skipped: Some(SkipReason::NoOccluders),
            ..Default::default()
        };
        let reference = scene
            .indexes
            .iter()
            .find(|i| i.structure() == Structure::Flat)
            .or(scene.indexes.first());
        let mut in_frustum = Vec::new();
        if let Some(index) = reference {
            cullers[0].traverse(*index, cam, &maps.maps[0], no_map, &mut in_frustum);
        }
        let mut in_frustum_b = Vec::new();
        buildings.refine(&frustum, None, &in_frustum, &mut in_frustum_b);
        let mut cells = Vec::with_capacity(cullers.len() * n_idx);
        for (c, map) in cullers.iter().zip(maps.maps.iter_mut()) {
            let st = c.build(cam, map);
            let used = st.skipped.is_none() && st.cells_covered > 0;
            for index in scene.indexes {
                let mut kept = Vec::new();
                c.traverse(*index, cam, map, st, &mut kept);
                if opts.sabotage == Some(Sabotage::DropVisibleBlock) {
                    if let Some(&b) = seen_blocks.iter().find(|b| kept.contains(b)) {
                        kept.retain(|k| *k != b);
                    }
                }
                let kept_set: BTreeSet<BlockId> = kept.iter().copied().collect();
                let missed: Vec<BlockId> = seen_blocks
                    .iter()
                    .filter(|b| !kept_set.contains(b))
                    .copied()
                    .collect();
                let mut kept_b = Vec::new();
                buildings.refine(&frustum, used.then_some(&*map), &kept, &mut kept_b);
                let kept_b: BTreeSet<BuildingId> = kept_b.into_iter().collect();
                let missed_b: Vec<BuildingId> = seen
                    .iter()
                    .filter(|b| !kept_b.contains(b))
                    .copied()
                    .collect();
                cells.push(Cell {
                    missed_blocks: missed.len() as u32,
                    missed_buildings: missed_b.len() as u32,
                    first_block: missed.first().copied(),
                    first_building: missed_b.first().copied(),
                    culled: in_frustum.iter().filter(|b| !kept_set.contains(b)).count() as u32,
                    buildings_culled: in_frustum_b.iter().filter(|b| !kept_b.contains(b)).count()
                        as u32,
                    used,
                });
            }
        }
        FrameRow {
            vacuous,
            in_frustum: in_frustum.len() as u32,
            in_frustum_buildings: in_frustum_b.len() as u32,
            visible_blocks: seen_blocks.len() as u32,
            visible_buildings: seen.len() as u32,
            cells,
        }
    };
    for route in routes {
        let mut tallies: Vec<ProofTally> = opts
            .resolutions
            .iter()
            .flat_map(|&r| {
                scene.indexes.iter().map(move |ix| ProofTally {
                    structure: ix.structure(),
                    resolution: r,
                    frames: 0,
                    false_block_culls: 0,
                    false_building_culls: 0,
                    false_culls_vacuous: 0,
                    blocks_in_frustum: 0,
                    blocks_culled: 0,
                    buildings_in_frustum: 0,
                    buildings_culled: 0,
                    frames_occlusion: 0,
                })
            })
            .collect();
        let mut vac = VacuousFrames::default();
        let (mut vis_b, mut vis_bb) = (0u64, 0u64);
        for (ci, chunk) in route.cameras.chunks(CHUNK).enumerate() {
            progress(done, total);
            let rows: Vec<FrameRow> = chunk
                .par_iter()
                .map_init(
                    || Pooled {
                        maps: pool
                            .lock()
                            .ok()
                            .and_then(|mut p| p.pop())
                            .unwrap_or_else(|| cullers.iter().map(|c| c.new_map()).collect()),
                        pool: &pool,
                    },
                    |maps, cam| frame_check(maps, cam),
                )
                .collect();
            for (k, row) in rows.iter().enumerate() {
                let frame = ci * CHUNK + k;
                match row.vacuous {
                    Some(Vacuous::Inside) => vac.inside_building += 1,
                    Some(Vacuous::EmptyView) => vac.empty_view += 1,
                    Some(Vacuous::NothingSeen) => vac.nothing_seen += 1,
                    None => {}
                }
                vis_b += u64::from(row.visible_blocks);
                vis_bb += u64::from(row.visible_buildings);
                for (t, c) in tallies.iter_mut().zip(&row.cells) {
                    t.frames += 1;
                    let missed = u64::from(c.missed_blocks) + u64::from(c.missed_buildings);
                    if row.vacuous.is_some() {
                        t.false_culls_vacuous += missed;
                    } else {
                        t.false_block_culls += u64::from(c.missed_blocks);
                        t.false_building_culls += u64::from(c.missed_buildings);
                    }
                    t.blocks_in_frustum += u64::from(row.in_frustum);
                    t.blocks_culled += u64::from(c.culled);
                    t.buildings_in_frustum += u64::from(row.in_frustum_buildings);
                    t.buildings_culled += u64::from(c.buildings_culled);
                    t.frames_occlusion += u64::from(c.used);
                    let dropped = c
                        .first_block
                        .map(Dropped::Block)
                        .or(c.first_building.map(Dropped::Building));
                    if let Some(dropped) = dropped {
                        if examples.len() < opts.max_examples {
                            examples.push(FalseCullExample {
                                city: scene.name.to_string(),
                                route: route.name.clone(),
                                frame,
                                structure: t.structure,
                                resolution: t.resolution,
                                dropped,
                                vacuous: row.vacuous.is_some(),
                                camera: route.cameras[frame],
                            });
                        }
                    }
                }
            }
            done += chunk.len();
        }
        let frames = route.cameras.len() as u64;
        route_reports.push(RouteProof {
            route: route.name.clone(),
            frames,
            vacuous: vac,
            checked: frames - vac.total(),
            visible_blocks: vis_b,
            visible_buildings: vis_bb,
            tallies,
        });
    }
    progress(total, total);
    Ok(CityProof {
        city: scene.name.to_string(),
        buildings: drawable.len(),
        blocks: scene.layout.blocks.len(),
        oracle: (w, h, ss),
        routes: route_reports,
        false_cull_examples: examples,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn boxes_beyond_a_clip_plane_are_the_ones_the_oracle_cannot_see() {
        let cam = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.0, 0.0);
        let clip = cam.clip_from_world();
        let unit = |x: f64, y: f64, z: f64| {
            Aabb3::new(DVec3::new(x, y, z), DVec3::new(x + 1.0, y + 1.0, z + 1.0))
        };
        // Ahead, behind, far to the side, beyond the far plane, and one around the eye.
        assert!(!beyond_clip_plane(&clip, &unit(10.0, -0.5, 1.0)));
        assert!(beyond_clip_plane(&clip, &unit(-10.0, -0.5, 1.0)));
        assert!(beyond_clip_plane(&clip, &unit(10.0, 100.0, 1.0)));
        assert!(beyond_clip_plane(&clip, &unit(cam.far + 10.0, -0.5, 1.0)));
        assert!(!beyond_clip_plane(&clip, &unit(-0.5, -0.5, 1.2)));
        // Against the oracle itself: a box it is told to skip draws no pixel.
        let mut rng = 1u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut skipped, mut drawn) = (0, 0);
        for _ in 0..400 {
            let p = DVec3::new(
                next() * 200.0 - 100.0,
                next() * 200.0 - 100.0,
                next() * 20.0,
            );
            let m = super::super::oracle::box_mesh(
                p.as_vec3(),
                (p + DVec3::new(3.0, 3.0, 3.0)).as_vec3(),
            );
            let seen =
                !visible_blocks_supersampled(&[(BlockId(0), &m)], &cam, 48, 27, 2).is_empty();
            let b = Aabb3::new(p, p + DVec3::splat(3.0));
            if beyond_clip_plane(&clip, &b) {
                skipped += 1;
                assert!(!seen, "skipped a box the oracle sees at {p}");
            } else {
                drawn += seen as usize;
            }
        }
        assert!(
            skipped > 50 && drawn > 20,
            "{skipped} skipped, {drawn} drawn"
        );
    }

    #[test]
    fn options_are_checked() {
        assert!(ProofOptions::default().check().is_ok());
        let bad = |f: &dyn Fn(&mut ProofOptions)| {
            let mut o = ProofOptions::default();
            f(&mut o);
            o.check().unwrap_err().to_string()
        };
        assert!(bad(&|o| o.oracle_size = (0, 54)).contains("oracle width"));
        assert!(bad(&|o| o.samples = 0).contains("samples"));
        assert!(bad(&|o| o.oracle_size = (4000, 54)).contains("8192"));
        assert!(bad(&|o| o.resolutions.clear()).contains("no cull map resolution"));
        assert!(bad(&|o| o.resolutions = vec![64, 0]).contains("out of range"));
    }
}
