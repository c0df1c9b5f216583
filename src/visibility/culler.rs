//! Per-frame occlusion culling: select occluders near the viewer, draw their shadows into the
//! cull map, and test the index's nodes against it while frustum culling (Willmott et al., §3.2.5–3.2.8).
//!
//! Conservative for the drawn frame, whatever the camera: Willmott et al. assumes each occluder's whole
//! wall is drawn, exactly where the f64 footprint puts it. Here
//! - walls nearer the eye than [`near_plane_reach`] are cut off the occluders (the frame clips
//!   them at the near plane, and what lies behind a clipped corner shows);
//! - every shadow allows the drawn wall to lie within a [`Slack`] of its occluder: the f32
//!   rounding of the mesh at its distance from the local origin, plus the tolerance of merged
//!   facade runs ([`super::occluders::merge_runs`]);
//! - every box under test is grown by the f32 rounding of its own coordinates
//!   ([`CullMap::box_hidden`]);
//! - buildings whose extrusion fails give no occluders;
//! - on terrain, no frame is culled whose near plane dips into the ground
//!   ([`SkipReason::NearPlaneInGround`], see [`OcclusionCuller::near_plane_above_ground`]).
//!
//! `tests/adversarial_cameras.rs` checks this on the bundled cities from adversarial eyes.

use super::cullmap::{CullMap, Resolution};
use super::occluders::{extract, extract_drawn, BlockOccluders, OccluderOptions};
use super::shadow::{Occluder, OccluderShadow, Slack};
use super::VisibilityError;
use crate::blocks::{BlockId, BlockLayout};
use crate::city::{City, LocalFrame};
use crate::geom::segment::point_rect_distance;
use crate::geom::{Aabb3, Camera};
use crate::index::{CityIndex, CullQuery, CullStats};
use crate::terrain::Terrain;
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Parameters of the occlusion culler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CullerOptions {
    /// Cull map resolution.
    pub resolution: Resolution,
    /// Only blocks within this plan-view distance of the viewer give occluders (the seed's
    /// "local model"), metres.
    pub local_radius: f64,
    /// At most this many building occluders per frame, the largest by
    /// `length × height / distance²` (height above the city's lowest ground), and as many
    /// terrain occluders, chosen apart.
    pub max_occluders: usize,
    /// Skip occlusion culling when the eye is higher than this many times the tallest candidate
    /// occluder (the shadows would be small and drawing them cannot pay).
    pub skip_height_factor: f64,
    /// How occluders are extracted.
    pub occluders: OccluderOptions,
    /// Shadows are drawn only into cells within this many metres of the frustum's plan-view
    /// footprint (boxes reaching further out are never hidden). The default, 60 m, keeps blocks
    /// that straddle the frustum's sides hideable: on the synthetic city it gives back the
    /// effectiveness of drawing the whole map within 0.3 %.
    pub window_pad: f64,
}

impl Default for CullerOptions {
    fn default() -> Self {
        Self {
            resolution: Resolution::Cells(256),
            local_radius: 300.0,
            max_occluders: 256,
            skip_height_factor: 3.0,
            occluders: OccluderOptions::default(),
            window_pad: 60.0,
        }
    }
}

/// Why a frame was not occlusion culled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SkipReason {
    /// No occluder faces the viewer within the local radius.
    NoOccluders,
    /// The eye is far above the roofs nearby.
    TooHigh,
    /// The eye is below the ground.
    BelowGround,
    /// On terrain: part of the near plane lies in the ground, so rays run under the terrain
    /// from the near plane on and see what the ground would hide (buried walls, the terrain's
    /// underside): no shadow that leans on the ground holds (see
    /// [`OcclusionCuller::near_plane_above_ground`]).
    NearPlaneInGround,
}

/// What one frame of occlusion culling did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OcclusionStats {
    /// Set when the cull map was not used this frame.
    pub skipped: Option<SkipReason>,
    /// Facing occluders within the local radius.
    pub occluder_candidates: u64,
    /// Occluders whose shadows were drawn.
    pub occluders_used: u64,
    /// Occluders not drawn because their wall stood in shadows drawn before (nearer walls hid
    /// it, see [`CullMap::segment_hidden`]).
    pub occluders_covered: u64,
    /// Shadows that covered at least one cell.
    pub shadows_drawn: u64,
    /// Cells written (summed over shadows).
    pub cells_covered: u64,
    /// Volumes (nodes and blocks) the index asked about.
    pub volumes_tested: u64,
    /// Volumes proven hidden (dropped with their subtrees).
    pub volumes_hidden: u64,
    /// Blocks pushed to the output.
    pub blocks_out: u64,
    /// Milliseconds to select occluders and draw the cull map (with its pyramid).
    pub build_ms: f64,
    /// Milliseconds of the index traversal with the cull map tests.
    pub test_ms: f64,
    /// The index's own counters.
    pub cull: CullStats,
}

/// Occlusion culling with occluder shadows and a cull map (Willmott et al., §3.2).
#[derive(Debug)]
pub struct OcclusionCuller {
    blocks: Vec<BlockOccluders>,
    opts: CullerOptions,
    min: DVec2,
    max: DVec2,
    map: Mutex<CullMap>,
    /// The city's terrain, when it stands on one: where the near plane must clear the ground.
    ground: Option<NearGround>,
    /// The height occluders are scored from ([`Self::select`]): 0 for a flat city, the lowest
    /// ground under the city's blocks on terrain.
    floor: f64,
}

/// The terrain under a culler's cameras ([`OcclusionCuller::near_plane_above_ground`]).
#[derive(Clone, Debug)]
struct NearGround {
    terrain: Arc<Terrain>,
    frame: LocalFrame,
}

impl OcclusionCuller {
    /// Extracts every block's occluders and allocates the cull map over the city's plan-view
    /// bounds (buildings and block outlines, local frame).
    ///
    /// Every building is extruded to learn which ones are drawn; a caller that has extruded
    /// them already passes the answer to [`Self::with_drawn`].
    pub fn new(
        city: &City,
        layout: &BlockLayout,
        opts: CullerOptions,
    ) -> Result<Self, VisibilityError> {
        let blocks = extract(city, layout, &opts.occluders);
        Self::from_occluders(city, layout, blocks, opts)
    }

    /// As [`Self::new`], with `drawn[i]` saying whether building `i` has a mesh (see
    /// [`extract_drawn`]): no building is extruded again.
    pub fn with_drawn(
        city: &City,
        layout: &BlockLayout,
        drawn: &[bool],
        opts: CullerOptions,
    ) -> Result<Self, VisibilityError> {
        let blocks = extract_drawn(city, layout, &opts.occluders, drawn);
        Self::from_occluders(city, layout, blocks, opts)
    }

    /// As [`Self::with_drawn`], with `extra` occluders beside the blocks' (the terrain's,
    /// [`super::occluders::terrain_occluders`]); the cull map still covers the city's blocks.
    ///
    /// # Errors
    /// As [`Self::with_drawn`].
    pub fn with_drawn_and(
        city: &City,
        layout: &BlockLayout,
        drawn: &[bool],
        extra: Vec<BlockOccluders>,
        opts: CullerOptions,
    ) -> Result<Self, VisibilityError> {
        let blocks = extract_drawn(city, layout, &opts.occluders, drawn);
        let mut c = Self::from_occluders(city, layout, blocks, opts)?;
        c.blocks.extend(extra);
        Ok(c)
    }

    /// The culler over extracted occluders; the cull map covers the city's plan-view bounds.
    fn from_occluders(
        city: &City,
        layout: &BlockLayout,
        blocks: Vec<BlockOccluders>,
        opts: CullerOptions,
    ) -> Result<Self, VisibilityError> {
        let mut bounds = Aabb3::EMPTY;
        for b in &blocks {
            bounds = bounds.union(b.aabb);
        }
        for block in &layout.blocks {
            for c in block.polygon.exterior().coords() {
                bounds = bounds.including(city.frame.to_local_f64(DVec3::new(c.x, c.y, 0.0)));
            }
        }
        if bounds.is_empty() {
            bounds = Aabb3::new(DVec3::ZERO, DVec3::ZERO);
        }
        let mut c = Self::from_blocks(
            blocks,
            bounds.min.truncate() - 1.0,
            bounds.max.truncate() + 1.0,
            opts,
        )?;
        c.ground = city.terrain.clone().map(|terrain| NearGround {
            terrain,
            frame: city.frame,
        });
        if c.ground.is_some() && bounds.min.z.is_finite() {
            c.floor = bounds.min.z;
        }
        Ok(c)
    }

    /// A culler over given per-block occluders and cull map bounds (local frame).
    pub fn from_blocks(
        blocks: Vec<BlockOccluders>,
        min: DVec2,
        max: DVec2,
        opts: CullerOptions,
    ) -> Result<Self, VisibilityError> {
        for (name, value) in [
            ("local_radius", opts.local_radius),
            ("skip_height_factor", opts.skip_height_factor),
        ] {
            // NaN fails this test too.
            if value.is_nan() || value <= 0.0 {
                return Err(VisibilityError::BadParameter {
                    name,
                    value,
                    expected: "> 0",
                });
            }
        }
        let map = CullMap::new(min, max, opts.resolution)?;
        Ok(Self {
            blocks,
            opts,
            min,
            max,
            map: Mutex::new(map),
            ground: None,
            floor: 0.0,
        })
    }

    /// How far the drawn walls may lie from occluder `o`: the f32 rounding of the meshes
    /// ([`Slack::f32_mesh`]) plus the distance a merged run may keep from the walls it stands
    /// for ([`super::occluders::merge_runs`]).
    pub fn slack(&self, o: &Occluder) -> Slack {
        let mut s = Slack::f32_mesh(o);
        s.plan += self.opts.occluders.collinear_offset.max(0.0);
        s
    }

    /// The options.
    pub fn options(&self) -> &CullerOptions {
        &self.opts
    }

    /// Per-block occluders.
    pub fn blocks(&self) -> &[BlockOccluders] {
        &self.blocks
    }

    /// A copy of this culler at another resolution (occluders are reused).
    pub fn with_resolution(&self, resolution: Resolution) -> Result<Self, VisibilityError> {
        let mut c = Self::from_blocks(
            self.blocks.clone(),
            self.min,
            self.max,
            CullerOptions {
                resolution,
                ..self.opts
            },
        )?;
        c.ground = self.ground.clone();
        c.floor = self.floor;
        Ok(c)
    }

    /// Whether the whole near plane of `camera` lies above the ground: always for a city
    /// without terrain (its ground is z = 0, under every eye the culler accepts).
    ///
    /// On terrain the shadows lean on the ground. A terrain occluder stands for the solid
    /// ground under the drawn surface ([`super::occluders::terrain_occluders`]); a facade edge
    /// for a wall from its building's base up, and below the base for the ground, which the
    /// base never rises above. A ray from the eye that crosses such a wall below the drawn
    /// surface is under the ground there, so it crossed the drawn surface before, and that
    /// crossing hides what lies behind — provided the crossing is drawn, that is, lies beyond
    /// the near plane. It does when the ray's point on the near plane is above the ground.
    /// When part of the near plane is in the ground (an eye a few centimetres above a slope
    /// with a near plane of metres, looking into it), the frame clips the surface there and
    /// the rays run under the terrain from the near plane on: they see the buried walls of
    /// buildings up the slope and the terrain's underside, through everything the shadows
    /// would hide. Such frames are not occlusion culled
    /// ([`SkipReason::NearPlaneInGround`]).
    ///
    /// The test is exact up to rounding, against the drawn full-resolution surface
    /// ([`Terrain::sample_drawn`], the oracle's): the near plane is the rectangle of centre
    /// `eye + near·forward` and half-extents `near·tan(fov_y/2)` and that times the aspect.
    /// Its height over the plan view and the surface's are both linear between the crossings
    /// of its plan view with the grid's lines and diagonals, so the lowest clearance is at its
    /// edges (checked by [`Terrain::drawn_clearance`]) or over a grid node inside it (checked
    /// there). Every clearance must exceed the f32 rounding of the drawn mesh (vertical, and
    /// the horizontal rounding times the slope). A node with no height under the rectangle (a
    /// hole in the drawn terrain) fails the test, and so does a non-finite camera. (Holes
    /// farther along the rays are not looked at: a ray that enters the ground through one is
    /// not stopped by a surface.)
    pub fn near_plane_above_ground(&self, camera: &Camera) -> bool {
        let Some(g) = &self.ground else {
            return true;
        };
        let f = camera.forward();
        let u = camera.up();
        let s = f.cross(u);
        let hh = camera.near * (0.5 * camera.fov_y).tan().abs();
        let hw = hh * camera.aspect.abs();
        let c = camera.position + f * camera.near;
        // In order around the rectangle.
        let corners = [
            c + s * hw + u * hh,
            c + s * hw - u * hh,
            c - s * hw - u * hh,
            c - s * hw + u * hh,
        ];
        if !corners.iter().all(|p| p.is_finite()) {
            return false;
        }
        let t = &g.terrain;
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &corners {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        // The drawn mesh's rounding: f32 local coordinates (plan, and height).
        let m = lo.truncate().abs().max(hi.truncate().abs()).max_element();
        let plan_tol = f32::EPSILON as f64 * m + 1e-6;
        let z_tol = |z: f64| f32::EPSILON as f64 * z.abs() + 1e-6;
        let world: Vec<DVec3> = corners.iter().map(|p| g.frame.to_world(*p)).collect();
        for k in 0..4 {
            let (a, b) = (world[k], world[(k + 1) % 4]);
            match t.drawn_clearance(a, b, plan_tol) {
                Some(cl) if cl > z_tol(a.z - g.frame.origin.z) + z_tol(b.z - g.frame.origin.z) => {}
                _ => return false,
            }
        }
        // Grid nodes under the rectangle (its plan view has an inside when it is not
        // vertical).
        if f.z == 0.0 {
            return true;
        }
        let (wlo, whi) = (g.frame.to_world(lo), g.frame.to_world(hi));
        let (ulo, uhi) = (t.grid_uv(wlo.truncate()), t.grid_uv(whi.truncate()));
        let (mx, my) = ((t.nx() - 1) as f64, (t.ny() - 1) as f64);
        if uhi.x < 0.0 || uhi.y < 0.0 || ulo.x > mx || ulo.y > my {
            return true;
        }
        let plan: Vec<DVec2> = corners.iter().map(|p| p.truncate()).collect();
        let inside = |q: DVec2| {
            let sides: Vec<f64> = (0..4)
                .map(|k| (plan[(k + 1) % 4] - plan[k]).perp_dot(q - plan[k]))
                .collect();
            sides.iter().all(|&v| v >= 0.0) || sides.iter().all(|&v| v <= 0.0)
        };
        for j in ulo.y.ceil().max(0.0) as usize..=uhi.y.floor().min(my) as usize {
            for i in ulo.x.ceil().max(0.0) as usize..=uhi.x.floor().min(mx) as usize {
                let q = g.frame.to_local_f64(t.node_xy(i, j).extend(0.0)).truncate();
                if !inside(q) {
                    continue;
                }
                let Some(h) = t.height(i, j) else {
                    return false;
                };
                let h = h - g.frame.origin.z;
                // The near plane, f · (p − c) = 0, over q.
                let z = c.z - (f.x * (q.x - c.x) + f.y * (q.y - c.y)) / f.z;
                // NaN (a broken camera) is not clear either.
                let clear = z - h > 2.0 * z_tol(h);
                if !clear {
                    return false;
                }
            }
        }
        true
    }

    /// The occluders chosen for `camera` (Willmott et al., §3.2.5): facade edges facing the viewer, of
    /// blocks within the local radius whose box meets the frustum, the `max_occluders` largest,
    /// nearest first.
    ///
    /// Each edge is cut to its parts at least [`near_plane_reach`] (plus the f32 rounding of the
    /// mesh, [`Slack::f32_mesh`]) from the eye in plan view: the renderer and the oracle clip
    /// everything nearer than the near plane, so a wall there hides nothing, and a shadow that
    /// assumed it did would hide what the frame shows through the clipped corner of a building
    /// (Willmott et al., §3.2.2 assumes the whole wall is drawn). A sub-segment of a solid wall is still
    /// a solid wall, so the cut edges' shadows stay conservative.
    pub fn select(&self, camera: &Camera, out: &mut Vec<Occluder>) -> (u64, Option<SkipReason>) {
        out.clear();
        let v = camera.position;
        if v.z < 0.0 {
            return (0, Some(SkipReason::BelowGround));
        }
        if !self.near_plane_above_ground(camera) {
            return (0, Some(SkipReason::NearPlaneInGround));
        }
        let v2 = v.truncate();
        let frustum = camera.frustum();
        let r = self.opts.local_radius;
        let reach = near_plane_reach(camera);
        let mut scored: Vec<(f64, Occluder)> = Vec::new();
        // The terrain's cells compete among themselves, with a budget of their own, so that
        // long terrain walls never crowd the buildings' walls out.
        let mut terrain_scored: Vec<(f64, Occluder)> = Vec::new();
        let mut tallest: f64 = 0.0;
        for b in &self.blocks {
            let into = if b.block == super::occluders::TERRAIN_OCCLUDER_BLOCK {
                &mut terrain_scored
            } else {
                &mut scored
            };
            let d = point_rect_distance(v2, b.aabb.min.truncate(), b.aabb.max.truncate());
            if b.aabb.is_empty() || d > r || !frustum.intersects_aabb(&b.aabb) {
                continue;
            }
            for o in &b.occluders {
                if !o.faces(v2) {
                    continue;
                }
                let dist = o.distance_to(v2);
                if dist > r {
                    continue;
                }
                tallest = tallest.max(o.height);
                // The drawn frame has no wall nearer than the near plane: keep only the parts of
                // the edge at least its reach (plus the mesh's rounding) away.
                let keep = reach + self.slack(o).plan;
                for piece in outside_disk(o, v2, keep).into_iter().flatten() {
                    let dist = piece.distance_to(v2);
                    // Walls are scored by their height above the city's lowest ground (on
                    // terrain, world heights would make every wall look alike).
                    let score = piece.length() * (piece.height - self.floor).max(0.0)
                        / (dist * dist).max(1.0);
                    into.push((score, piece));
                }
            }
        }
        let candidates = (scored.len() + terrain_scored.len()) as u64;
        if scored.is_empty() && terrain_scored.is_empty() {
            return (0, Some(SkipReason::NoOccluders));
        }
        // Heights above the floor (0 for a flat city), so that the rule means the same on
        // terrain.
        if v.z - self.floor > self.opts.skip_height_factor * (tallest - self.floor) {
            return (candidates, Some(SkipReason::TooHigh));
        }
        for list in [&mut scored, &mut terrain_scored] {
            let n = self.opts.max_occluders.min(list.len());
            if n < list.len() {
                list.select_nth_unstable_by(n, |a, b| b.0.total_cmp(&a.0));
                list.truncate(n);
            }
        }
        scored.extend(terrain_scored);
        // Nearest first, so that [`Self::build`] can skip walls that nearer ones hide; ties by
        // score, for a deterministic order.
        let mut keyed: Vec<(f64, f64, Occluder)> = scored
            .into_iter()
            .map(|(score, o)| (o.distance_to(v2), score, o))
            .collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
        out.extend(keyed.into_iter().map(|(_, _, o)| o));
        (candidates, None)
    }

    /// Selects occluders and draws their shadows into `map` (cleared first), then builds its
    /// pyramid. Returns the stats so far.
    pub fn build(&self, camera: &Camera, map: &mut CullMap) -> OcclusionStats {
        let t0 = Instant::now();
        map.clear();
        // Shadows are drawn only over the frustum's plan-view footprint (its eight corners'
        // hull); without corners (a degenerate frustum) the whole map is used.
        match camera.frustum().corners() {
            Some(c) => {
                let pts: Vec<DVec2> = c.iter().map(|p| p.truncate()).collect();
                map.set_window(&pts, self.opts.window_pad);
            }
            None => map.clear_window(),
        }
        let mut occ = Vec::new();
        let (candidates, skipped) = self.select(camera, &mut occ);
        let mut st = OcclusionStats {
            skipped,
            occluder_candidates: candidates,
            ..Default::default()
        };
        if skipped.is_none() {
            for o in &occ {
                // Drawn nearest first, a wall standing inside the shadows drawn so far adds
                // nothing they do not hide already (see [`CullMap::segment_hidden`]).
                if map.segment_hidden(o.a, o.b, o.height) {
                    st.occluders_covered += 1;
                    continue;
                }
                if let Ok(s) = OccluderShadow::with_slack(camera.position, o, self.slack(o)) {
                    st.occluders_used += 1;
                    let c = map.draw(&s);
                    st.cells_covered += c;
                    st.shadows_drawn += (c > 0) as u64;
                }
            }
        }
        map.build_pyramid();
        st.build_ms = t0.elapsed().as_secs_f64() * 1e3;
        st
    }

    /// The cull map this culler builds for `camera` (a fresh copy, for inspection and tests).
    pub fn cull_map_for(&self, camera: &Camera) -> CullMap {
        let mut map = self.map.lock().unwrap_or_else(|e| e.into_inner()).clone();
        self.build(camera, &mut map);
        map
    }

    /// One frame: frustum culling through `index` with every surviving node and block tested
    /// against the cull map, front to back; pushes the blocks to draw to `out`.
    pub fn cull(
        &self,
        index: &dyn CityIndex,
        camera: &Camera,
        out: &mut Vec<BlockId>,
    ) -> OcclusionStats {
        let mut map = self.map.lock().unwrap_or_else(|e| e.into_inner());
        let st = self.build(camera, &mut map);
        self.traverse(index, camera, &map, st, out)
    }

    /// A fresh cull map of this culler's grid, for callers that cull from several threads
    /// ([`OcclusionCuller::build`] into it, then [`OcclusionCuller::traverse`] with it).
    pub fn new_map(&self) -> CullMap {
        let mut map = self.map.lock().unwrap_or_else(|e| e.into_inner()).clone();
        map.clear();
        map
    }

    /// The traversal half of [`OcclusionCuller::cull`]: frustum culling through `index` with
    /// every surviving node and block tested against `map`, which [`OcclusionCuller::build`]
    /// drew for `camera` and which gave `st`. One map serves any number of indexes.
    pub fn traverse(
        &self,
        index: &dyn CityIndex,
        camera: &Camera,
        map: &CullMap,
        mut st: OcclusionStats,
        out: &mut Vec<BlockId>,
    ) -> OcclusionStats {
        let t1 = Instant::now();
        let frustum = camera.frustum();
        let n0 = out.len();
        let (mut tested, mut hidden) = (0u64, 0u64);
        let use_map = st.skipped.is_none() && st.cells_covered > 0;
        let query = CullQuery::with_eye(&frustum, camera.position);
        let mut filter = |b: &Aabb3| {
            tested += 1;
            let h = map.box_hidden(b);
            hidden += h as u64;
            !h
        };
        // Without a usable map there is nothing to filter: no callback, so structures keep
        // their "node completely inside → accept the subtree" shortcut (Pina, Serón and Cerezo, §5).
        let hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool> =
            if use_map { Some(&mut filter) } else { None };
        st.cull = index.cull(&query, hidden_filter, out);
        st.volumes_tested = tested;
        st.volumes_hidden = hidden;
        st.blocks_out = (out.len() - n0) as u64;
        st.test_ms = t1.elapsed().as_secs_f64() * 1e3;
        st
    }
}

/// The near plane's reach: the largest distance from the eye of a point of the view frustum
/// that the near plane clips.
///
/// In view space a ray through the image at `(tx, ty)` (the tangents of its angles from the
/// view axis, `|tx| ≤ tan(fov_x / 2) = aspect · tan(fov_y / 2)`, `|ty| ≤ tan(fov_y / 2)`) meets
/// the depth `z` at distance `z · sqrt(1 + tx² + ty²)`. The near plane clips depths below `near`,
/// so on every ray through the image the clipped points lie within `near · sqrt(1 + Tx² + Ty²)`
/// of the eye, the distance to the near plane's corners (the simpler `near / (cos hx · cos hy)`
/// is the same bound for small angles and larger than it otherwise). Conversely any point of
/// the frustum at least this far from the eye has depth ≥ `near` and is drawn. Plan-view
/// distance is at most the 3D distance, so a wall whose plan distance from the eye is at least
/// the reach is drawn wherever it lies in the frustum.
pub fn near_plane_reach(camera: &Camera) -> f64 {
    let ty = (0.5 * camera.fov_y).tan().abs();
    let tx = ty * camera.aspect.abs();
    let r = camera.near * (1.0 + tx * tx + ty * ty).sqrt();
    // One part in a million for the rounding of the projection; NaN (a broken camera) keeps
    // nothing.
    if r.is_finite() {
        r * (1.0 + 1e-6)
    } else {
        f64::INFINITY
    }
}

/// The parts of `o` at least `r` from `c` in plan view: none, one or two pieces (`o` itself
/// when it stays clear of the disc).
pub fn outside_disk(o: &Occluder, c: DVec2, r: f64) -> [Option<Occluder>; 2] {
    let d = o.b - o.a;
    let dd = d.dot(d);
    if r.is_nan() || r <= 0.0 || dd == 0.0 {
        return [(r <= 0.0).then_some(*o), None];
    }
    if r.is_infinite() {
        return [None, None];
    }
    // |a + t d − c|² = r²  ⇔  dd t² + 2 (f·d) t + (f·f − r²) = 0, f = a − c.
    let f = o.a - c;
    let (bq, cq) = (f.dot(d), f.dot(f) - r * r);
    let disc = bq * bq - dd * cq;
    if disc <= 0.0 {
        return [Some(*o), None];
    }
    let sq = disc.sqrt();
    let (t0, t1) = ((-bq - sq) / dd, (-bq + sq) / dd);
    let piece = |s: f64, e: f64| {
        (e > s).then(|| Occluder {
            a: o.a + d * s,
            b: o.a + d * e,
            height: o.height,
        })
    };
    [piece(0.0, t0.min(1.0)), piece(t1.max(0.0), 1.0)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every point the near plane clips from a ray through the image lies within the reach, and
    /// the near plane's corners are at the reach (within its rounding allowance).
    #[test]
    fn near_plane_reach_bounds_the_clipped_points() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for _ in 0..200 {
            let mut cam = Camera::new(
                DVec3::new(rng.random_range(-50.0..50.0), 3.0, 1.7),
                rng.random_range(-3.0..3.0),
                rng.random_range(-1.5..1.5),
            );
            cam.near = rng.random_range(0.05..20.0);
            cam.fov_y = rng.random_range(0.2..2.5);
            cam.aspect = rng.random_range(0.5..3.0);
            let reach = near_plane_reach(&cam);
            let inv = cam.clip_from_world().inverse();
            let mut far_corner: f64 = 0.0;
            for k in 0..50 {
                // NDC x, y in [-1, 1], depth 0 (the near plane) and a bit beyond.
                let (x, y) = if k < 4 {
                    ([-1.0, 1.0][k % 2], [-1.0, 1.0][k / 2])
                } else {
                    (rng.random_range(-1.0..=1.0), rng.random_range(-1.0..=1.0))
                };
                let p = inv * glam::DVec4::new(x, y, 0.0, 1.0);
                let d = (p.truncate() / p.w - cam.position).length();
                assert!(d <= reach, "{d} > {reach}");
                if k < 4 {
                    far_corner = far_corner.max(d);
                }
            }
            assert!(far_corner > reach * (1.0 - 2e-6), "{far_corner} vs {reach}");
        }
    }

    #[test]
    fn outside_disk_keeps_exactly_the_far_parts() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut cut = 0;
        for _ in 0..500 {
            let o = Occluder {
                a: DVec2::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0)),
                b: DVec2::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0)),
                height: 5.0,
            };
            let c = DVec2::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0));
            let r = rng.random_range(0.0..8.0);
            let pieces: Vec<Occluder> = outside_disk(&o, c, r).into_iter().flatten().collect();
            cut += (pieces.len() != 1 || pieces[0] != o) as usize;
            for p in &pieces {
                assert_eq!(p.height, o.height);
                // Same direction (facing is kept).
                assert!((p.b - p.a).dot(o.b - o.a) > 0.0);
                for k in 0..=20 {
                    let q = p.a.lerp(p.b, k as f64 / 20.0);
                    assert!(
                        (q - c).length() >= r * (1.0 - 1e-9),
                        "{q} within {r} of {c}"
                    );
                }
            }
            // Points of the edge far from the disc are kept.
            for k in 0..=50 {
                let q = o.a.lerp(o.b, k as f64 / 50.0);
                if (q - c).length() > r * (1.0 + 1e-6) + 1e-9 {
                    assert!(
                        pieces.iter().any(|p| p.distance_to(q) < 1e-9),
                        "{q} lost from {o:?}"
                    );
                }
            }
        }
        assert!(cut > 50, "{cut}");
        let o = Occluder {
            a: DVec2::ZERO,
            b: DVec2::X,
            height: 1.0,
        };
        assert_eq!(outside_disk(&o, DVec2::ZERO, f64::INFINITY), [None, None]);
        assert_eq!(outside_disk(&o, DVec2::ZERO, f64::NAN), [None, None]);
        assert_eq!(outside_disk(&o, DVec2::ZERO, 0.0), [Some(o), None]);
    }
}
