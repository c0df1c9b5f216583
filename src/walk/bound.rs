//! The screen-space bound of a hybrid frame, checked with the exact geometry: no
//! mismatched pixel may lie farther than 1 px + τ/cos²θ from a mesh silhouette, on every frame of
//! every route.
//!
//! [`super::far::image_error`] measures, from the two pictures alone, how far each
//! coverage-mismatched pixel lies from a silhouette of the frame that does not cover it (the raw
//! distance). This module decides, per such pixel, whether the bound holds, the way
//! `blockmap::compare` decides it for one map (its module doc derives the bound):
//!
//! 1. the pixel's allowed distance is `r = 1 + τ/cos²θ`, θ the angle of its centre off the
//!    optical axis (`1/cos²θ = 1 + nx² + ny²` with `nx`, `ny` the centre's view-plane
//!    coordinates at unit depth, from the camera's fov and aspect);
//! 2. a pixel whose raw distance is at most `r` holds the bound (ratio `raw/r`);
//! 3. a pixel beyond `r` gets a **second look at quarter-pixel spacing** within `r` (the lattice
//!    of `blockmap::compare`), since a feature smaller than a pixel can fall between one image's
//!    pixel centres and be caught by the other's; the nearest lattice point that settles it
//!    gives its distance:
//!    - a pixel only the hybrid frame covers: a ray through a lattice point that meets an exact
//!      building prism of the frame (the drawn maps' buildings and the near meshes' buildings)
//!      shows the mesh frame's geometry within that distance. Else, when a map drew the pixel
//!      and the f64 twin of its hit lies within the map's ε of a prism of the original solid,
//!      the original point projects within `e_px·e/ε` of the pixel (`e` the hit's distance,
//!      `e_px` the map's projected ε): sub-pixel as `blockmap::compare` argues. (Deviation,
//!      stricter than `compare`: a hit whose nearest original surface is the ground, not a
//!      prism, is not accepted, since the mesh frame covers nothing there. The ground is the
//!      plane z = 0, or the terrain when the buildings stand on one, `Source::terrain`: a hit
//!      within its distance of a terrain triangle is the terrain's, which both frames draw.)
//!    - a pixel only the mesh frame covers: a ray through a lattice point that meets the hybrid
//!      frame's geometry (a drawn map, by the f32 caster the GPU runs; a near mesh's building,
//!      by its exact prism). Else, when the building the pixel shows is one a drawn map declares
//!      (a thin feature of its measured error, `ErrorReport::thin`, or a building no texel
//!      holds, `BuildStats::dropped_buildings`) and the pixel lies within `r` of the mesh
//!      frame's silhouette, the map's declared error explains it: counted apart as *thin*.
//!
//!    Pixels settled by the lattice or the twin are counted as *sub-pixel*; the rest are
//!    violations (ratio `raw/r` > 1).
//!
//! τ is the selection's threshold, as the bound is stated; a map the hysteresis keeps
//! (`e ≤ τ·(1 + h)`) may project its ε up to `τ·(1 + h)`, and its pixels are judged with τ all
//! the same (the stricter reading).
//!
//! The exact prisms ignore the ground layers' depth test (the frames draw the ground, and a
//! depth test against it may hide a wall's lowest centimetres in one frame and not the other):
//! such a pixel is geometry at distance 0 and is counted as sub-pixel, not hidden.
//!
//! Candidates per lattice point come from a coarse screen grid: every building's box (and every
//! drawn map's box) is projected once per frame, and only for frames with pixels beyond `r`.

use crate::blockmap::cast::{cast_f32, cast_f64, CastOptions};
use crate::blockmap::compare::{image_ray_with, lattice_within};
use crate::blockmap::diagnose::ray_prism;
use crate::blockmap::error::{BuildingGrid, Scratch};
use crate::blockmap::image::{twin_ray, FrameRays, MapXform};
use crate::blockmap::{MapTree, Selection, Source};
use crate::geom::Aabb3;
use crate::geom::Camera;
use glam::{DMat4, DVec2, DVec3, DVec4};
use rayon::prelude::*;
use serde::Serialize;

/// What the second look needs of a far field's nodes ("maps" below): their boxes, buildings,
/// declared buildings and error, the GPU's `f32` cast through any image point and its `f64`
/// twin through a pixel centre. BlockMaps ([`MapTree`]) and relief impostors implement it.
pub trait BoundMaps: Sync {
    /// Nodes.
    fn count(&self) -> usize;
    /// Node `m`'s own box (local frame).
    fn aabb(&self, m: usize) -> Aabb3;
    /// Its buildings (indices into `City::buildings`).
    fn buildings(&self, m: usize) -> &[u32];
    /// The buildings it declares it draws unfaithfully (thin or dropped), sorted.
    fn declared(&self, m: usize) -> Vec<u32>;
    /// Its declared world-space error, metres.
    fn eps_m(&self, m: usize) -> f64;
    /// Its casts from `camera` in a `w × h` frame, as the frame draws it.
    fn frame_caster<'s>(
        &'s self,
        m: usize,
        camera: &Camera,
        w: u32,
        h: u32,
    ) -> Box<dyn FrameCaster + 's>;
    /// The buildings of node `m` bucketed over its square, for the twin's surface distance.
    fn building_grid<'s>(&self, m: usize, source: &'s Source<'s>) -> BuildingGrid<'s>;
}

/// One node's casts in one frame.
pub trait FrameCaster: Sync + Send {
    /// Depth written by the GPU's `f32` cast through the image point `(px, py)` (pixels from
    /// the top-left corner), when it hits.
    fn hit_depth(&self, px: f64, py: f64) -> Option<f32>;
    /// The `f64` twin's hit point (local frame) through the centre of pixel `(x, y)`.
    fn twin_point(&self, x: u32, y: u32) -> Option<DVec3>;
}

/// A BlockMap's casts in one frame.
struct MapCaster<'s> {
    map: &'s crate::blockmap::BlockMap,
    xform: MapXform,
    rays: FrameRays,
    camera: Camera,
    w: u32,
    h: u32,
}

impl FrameCaster for MapCaster<'_> {
    fn hit_depth(&self, px: f64, py: f64) -> Option<f32> {
        let fr = &self.rays;
        let v = [px as f32 * fr.sx + fr.cx, py as f32 * fr.sy + fr.cy];
        let c = cast_f32(
            self.map,
            &self.xform.ray(v, fr.near),
            &CastOptions::default(),
        );
        c.hit.t().map(|t| fr.depth(t as f32))
    }
    fn twin_point(&self, x: u32, y: u32) -> Option<DVec3> {
        let ray = twin_ray(self.map, &self.camera, self.w, self.h, x, y);
        cast_f64(self.map, &ray, &CastOptions::default())
            .hit
            .t()
            .map(|t| self.map.local_point(&ray, t))
    }
}

impl BoundMaps for MapTree {
    fn count(&self) -> usize {
        self.maps.len()
    }
    fn aabb(&self, m: usize) -> Aabb3 {
        self.maps[m].map.aabb()
    }
    fn buildings(&self, m: usize) -> &[u32] {
        &self.maps[m].buildings
    }
    fn declared(&self, m: usize) -> Vec<u32> {
        self.maps[m].declared_buildings()
    }
    fn eps_m(&self, m: usize) -> f64 {
        self.maps[m].map.meta.eps_m
    }
    fn frame_caster<'s>(
        &'s self,
        m: usize,
        camera: &Camera,
        w: u32,
        h: u32,
    ) -> Box<dyn FrameCaster + 's> {
        let map = &self.maps[m].map;
        Box::new(MapCaster {
            map,
            xform: MapXform::new(map, camera),
            rays: FrameRays::new(camera, w, h),
            camera: *camera,
            w,
            h,
        })
    }
    fn building_grid<'s>(&self, m: usize, source: &'s Source<'s>) -> BuildingGrid<'s> {
        let nm = &self.maps[m];
        BuildingGrid::new(&nm.map, source, &nm.buildings)
    }
}

/// The geometry a walk checks its hybrid frames with: the buildings (f64 prisms, local frame),
/// their blocks, and per map the buildings it declares (thin or dropped).
pub struct BoundGeometry<'a> {
    source: &'a Source<'a>,
    tree: &'a dyn BoundMaps,
    by_block: Vec<Vec<u32>>,
    declared: Vec<Vec<u32>>,
    /// The ground when it is a terrain (`Source::terrain`); `None`: the plane z = 0.
    terrain: Option<TerrainSurface>,
}

impl<'a> BoundGeometry<'a> {
    /// The geometry of `source` (the city's buildings, `blockmap::Source::new`) for the maps of
    /// `tree` (built from the same city).
    pub fn new(source: &'a Source<'a>, tree: &'a dyn BoundMaps) -> Self {
        let mut by_block: Vec<Vec<u32>> = Vec::new();
        for (i, b) in source.buildings.iter().enumerate() {
            if let Some(b) = b {
                let k = b.block.0 as usize;
                if by_block.len() <= k {
                    by_block.resize(k + 1, Vec::new());
                }
                by_block[k].push(i as u32);
            }
        }
        let declared = (0..tree.count()).map(|m| tree.declared(m)).collect();
        Self {
            source,
            tree,
            by_block,
            declared,
            terrain: source.terrain.map(TerrainSurface::new),
        }
    }

    /// Whether the ground lies within `e` of `point`: the plane z = 0 (`point.z ≤ e`), or with
    /// a terrain, some terrain triangle within `e` (exact f64 point–triangle distance).
    fn ground_within(&self, point: DVec3, e: f64) -> bool {
        match &self.terrain {
            None => point.z <= e,
            Some(t) => t.within(point, e),
        }
    }

    /// The buildings map `m` declares: its thin features and the buildings no texel holds
    /// (sorted).
    pub fn declared(&self, m: usize) -> &[u32] {
        self.declared.get(m).map_or(&[], |v| v.as_slice())
    }

    /// Whether a drawn map of `sel` declares building `b`.
    fn declared_by(&self, sel: &Selection, b: u32) -> bool {
        sel.maps
            .iter()
            .any(|&m| self.declared(m).binary_search(&b).is_ok())
    }
}

/// What the second look found in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct BoundFigures {
    /// Largest distance over allowed distance of a mismatched pixel after the second look (≤ 1
    /// where the bound holds on the whole frame).
    pub ratio_max: f64,
    /// The pixel `(x, y)` of [`BoundFigures::ratio_max`].
    pub worst_px: [u32; 2],
    /// Mismatched pixels beyond the bound after the second look: violations.
    pub beyond_bound: u64,
    /// Pixels beyond the bound at pixel spacing that the second look settled (quarter-pixel
    /// lattice, or a map's hit within ε of a prism).
    pub beyond_bound_subpixel: u64,
    /// Pixels beyond the bound that show a building a drawn map declares (thin or dropped),
    /// within the bound of the mesh frame's silhouette.
    pub beyond_bound_thin: u64,
}

/// A mismatched pixel beyond its allowed distance at pixel spacing.
#[derive(Clone, Copy, Debug)]
struct Beyond {
    x: u32,
    y: u32,
    /// Only the hybrid frame covers it.
    extra: bool,
    raw: f64,
    r: f64,
}

/// How a pixel beyond `r` was settled.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Verdict {
    /// Sub-pixel, at this distance.
    Subpixel(f64),
    /// A map's hit to check against the original surface: map, world point.
    Twin(usize, DVec3),
    /// Thin, at this distance from the mesh silhouette.
    Thin(f64),
    /// Not settled.
    Violation,
}

/// One candidate in the screen grid: a building prism (of a near mesh or not) or a drawn map,
/// with its projected box in pixels.
#[derive(Clone, Copy, Debug)]
struct Item {
    kind: Kind,
    lo: [f64; 2],
    hi: [f64; 2],
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Building { b: u32, near: bool },
    Map(usize),
}

/// A box on the screen.
#[derive(Clone, Copy, Debug)]
enum Projected {
    /// Off the screen (or beyond the far plane).
    Off,
    /// Crossing the near plane: a candidate everywhere.
    Everywhere,
    /// Its corners' image box, pixels (min, max).
    Box([f64; 2], [f64; 2]),
}

/// Cell side of the screen grid, pixels.
const CELL: f64 = 4.0;

/// Projected boxes bucketed over the screen.
struct ScreenGrid {
    cols: usize,
    rows: usize,
    cells: Vec<Vec<u32>>,
    /// Items whose box crosses the near plane or covers much of the screen.
    everywhere: Vec<u32>,
    items: Vec<Item>,
}

impl ScreenGrid {
    /// Items whose box holds the image point `(px, py)`.
    fn at(&self, px: f64, py: f64) -> impl Iterator<Item = &Item> {
        let (i, j) = ((px / CELL).floor(), (py / CELL).floor());
        let cell: &[u32] =
            if i >= 0.0 && j >= 0.0 && (i as usize) < self.cols && (j as usize) < self.rows {
                &self.cells[j as usize * self.cols + i as usize]
            } else {
                &[]
            };
        cell.iter()
            .chain(self.everywhere.iter())
            .map(|&n| &self.items[n as usize])
            .filter(move |it| px >= it.lo[0] && px <= it.hi[0] && py >= it.lo[1] && py <= it.hi[1])
    }
}

/// The second look of one hybrid frame (see the module doc).
pub struct FrameBound<'g, 'a> {
    geometry: &'g BoundGeometry<'a>,
    selection: &'g Selection,
    camera: &'g Camera,
    tau_px: f64,
}

impl<'g, 'a> FrameBound<'g, 'a> {
    /// The frame of `camera` drawing `selection` (maps of the geometry's tree, near blocks), at
    /// threshold τ = `tau_px`.
    pub fn new(
        geometry: &'g BoundGeometry<'a>,
        selection: &'g Selection,
        camera: &'g Camera,
        tau_px: f64,
    ) -> Self {
        Self {
            geometry,
            selection,
            camera,
            tau_px,
        }
    }

    /// The allowed distance `1 + τ/cos²θ` of pixel `(x, y)` of a `w × h` image.
    pub fn allowed_px(&self, x: u32, y: u32, w: u32, h: u32) -> f64 {
        let fy = (0.5 * self.camera.fov_y).tan();
        let fx = fy * self.camera.aspect;
        let nx = ((x as f64 + 0.5) / w as f64 * 2.0 - 1.0) * fx;
        let ny = (1.0 - (y as f64 + 0.5) / h as f64 * 2.0) * fy;
        1.0 + self.tau_px * (1.0 + nx * nx + ny * ny)
    }

    /// Checks the bound over the mismatched pixels of a `w × h` frame: `mismatched` lists
    /// `(x, y, extra, raw)` (`extra`: only the hybrid frame covers it; `raw`: its distance to the
    /// silhouette of the frame that does not cover it), `mesh_sil` marks the mesh frame's
    /// silhouette pixels (row-major).
    pub fn check(
        &self,
        w: u32,
        h: u32,
        mismatched: &[(u32, u32, bool, f64)],
        mesh_sil: &[bool],
    ) -> BoundFigures {
        let mut out = BoundFigures::default();
        let worst = |ratio: f64, x: u32, y: u32, out: &mut BoundFigures| {
            if ratio > out.ratio_max {
                out.ratio_max = ratio;
                out.worst_px = [x, y];
            }
        };
        let mut beyond = Vec::new();
        for &(x, y, extra, raw) in mismatched {
            let r = self.allowed_px(x, y, w, h);
            if raw <= r {
                worst(raw / r, x, y, &mut out);
            } else {
                beyond.push(Beyond {
                    x,
                    y,
                    extra,
                    raw,
                    r,
                });
            }
        }
        if beyond.is_empty() {
            return out;
        }
        let look = Look::new(self, w, h, &beyond);
        let verdicts: Vec<Verdict> = beyond
            .par_iter()
            .map(|p| look.verdict(p, mesh_sil))
            .collect();
        // The twins: the original surface near each map hit, one building grid per map.
        let mut twin_maps: Vec<usize> = verdicts
            .iter()
            .filter_map(|v| match v {
                Verdict::Twin(m, _) => Some(*m),
                _ => None,
            })
            .collect();
        twin_maps.sort_unstable();
        twin_maps.dedup();
        let tree = self.geometry.tree;
        let grids: Vec<(usize, BuildingGrid)> = twin_maps
            .par_iter()
            .map(|&m| (m, tree.building_grid(m, self.geometry.source)))
            .collect();
        let settled: Vec<Verdict> = beyond
            .par_iter()
            .zip(verdicts.par_iter())
            .map_init(Scratch::default, |scratch, (p, v)| match *v {
                Verdict::Twin(m, point) => {
                    let grid = &grids[grids.partition_point(|g| g.0 < m)].1;
                    look.twin(m, point, grid, scratch)
                        .map(Verdict::Subpixel)
                        .unwrap_or_else(|| look.thin_or_violation(p, mesh_sil))
                }
                v => v,
            })
            .collect();
        for (p, v) in beyond.iter().zip(settled) {
            match v {
                Verdict::Subpixel(d) => {
                    out.beyond_bound_subpixel += 1;
                    worst(d / p.r, p.x, p.y, &mut out);
                }
                Verdict::Thin(d) => {
                    out.beyond_bound_thin += 1;
                    worst(d / p.r, p.x, p.y, &mut out);
                }
                Verdict::Violation | Verdict::Twin(..) => {
                    out.beyond_bound += 1;
                    worst(p.raw / p.r, p.x, p.y, &mut out);
                }
            }
        }
        out
    }
}

/// The per-frame state of the second look: rays, the screen grid, the lattice.
struct Look<'f, 'g, 'a> {
    frame: &'f FrameBound<'g, 'a>,
    w: u32,
    h: u32,
    inv: DMat4,
    forward: DVec3,
    /// Per map of the tree, its casts when the frame draws it.
    xforms: Vec<Option<Box<dyn FrameCaster + 'g>>>,
    grid: ScreenGrid,
    /// Quarter-pixel lattice offsets `(dx, dy, d)` within the largest `r`, nearest first.
    lattice: Vec<(f64, f64, f64)>,
}

impl<'f, 'g, 'a> Look<'f, 'g, 'a> {
    fn new(frame: &'f FrameBound<'g, 'a>, w: u32, h: u32, beyond: &[Beyond]) -> Self {
        let cam = frame.camera;
        let r_max = beyond.iter().map(|p| p.r).fold(1.0, f64::max);
        let mut lattice: Vec<(f64, f64, f64)> = lattice_within(r_max).collect();
        lattice.sort_by(|a, b| {
            a.2.total_cmp(&b.2)
                .then(a.1.total_cmp(&b.1))
                .then(a.0.total_cmp(&b.0))
        });
        let maps = frame.geometry.tree;
        let mut xforms: Vec<Option<Box<dyn FrameCaster + 'g>>> =
            (0..maps.count()).map(|_| None).collect();
        for &m in &frame.selection.maps {
            if m < maps.count() {
                xforms[m] = Some(maps.frame_caster(m, cam, w, h));
            }
        }
        let mut look = Self {
            frame,
            w,
            h,
            inv: cam.clip_from_world().inverse(),
            forward: cam.forward(),
            xforms,
            grid: ScreenGrid {
                cols: 0,
                rows: 0,
                cells: Vec::new(),
                everywhere: Vec::new(),
                items: Vec::new(),
            },
            lattice,
        };
        look.grid = look.screen_grid(r_max);
        look
    }

    /// Projects every candidate's box once and buckets it (see [`ScreenGrid`]).
    fn screen_grid(&self, r_max: f64) -> ScreenGrid {
        let g = self.frame.geometry;
        let sel = self.frame.selection;
        let cam = self.frame.camera;
        let cfw = cam.clip_from_world();
        let (w, h) = (self.w as f64, self.h as f64);
        let margin = r_max + 1.0;
        let mut kinds: Vec<(Kind, DVec3, DVec3)> = Vec::new();
        let tree = g.tree;
        for &m in &sel.maps {
            if m >= tree.count() {
                continue;
            }
            let b = tree.aabb(m);
            kinds.push((Kind::Map(m), b.min, b.max));
            for &bi in tree.buildings(m) {
                if let Some(Some(sb)) = g.source.buildings.get(bi as usize) {
                    kinds.push((
                        Kind::Building { b: bi, near: false },
                        sb.min.extend(sb.z0),
                        sb.max.extend(sb.z1),
                    ));
                }
            }
        }
        for blk in &sel.meshes {
            for &bi in g.by_block.get(blk.0 as usize).map_or(&[][..], |v| v) {
                if let Some(Some(sb)) = g.source.buildings.get(bi as usize) {
                    kinds.push((
                        Kind::Building { b: bi, near: true },
                        sb.min.extend(sb.z0),
                        sb.max.extend(sb.z1),
                    ));
                }
            }
        }
        let project = |lo: DVec3, hi: DVec3| -> Projected {
            let mut a = [f64::INFINITY; 2];
            let mut b = [f64::NEG_INFINITY; 2];
            let mut beyond_far = true;
            for c in 0..8 {
                let p = DVec3::new(
                    if c & 1 == 0 { lo.x } else { hi.x },
                    if c & 2 == 0 { lo.y } else { hi.y },
                    if c & 4 == 0 { lo.z } else { hi.z },
                );
                let q = cfw * DVec4::new(p.x, p.y, p.z, 1.0);
                if q.w < cam.near {
                    return Projected::Everywhere;
                }
                if q.w <= cam.far {
                    beyond_far = false;
                }
                let px = (q.x / q.w + 1.0) * 0.5 * w;
                let py = (1.0 - q.y / q.w) * 0.5 * h;
                a = [a[0].min(px), a[1].min(py)];
                b = [b[0].max(px), b[1].max(py)];
            }
            if beyond_far
                || b[0] < -margin
                || b[1] < -margin
                || a[0] > w + margin
                || a[1] > h + margin
            {
                return Projected::Off;
            }
            Projected::Box(a, b)
        };
        let cols = (w / CELL).ceil() as usize;
        let rows = (h / CELL).ceil() as usize;
        let mut grid = ScreenGrid {
            cols,
            rows,
            cells: vec![Vec::new(); cols * rows],
            everywhere: Vec::new(),
            items: Vec::new(),
        };
        let projected: Vec<Projected> = kinds
            .par_iter()
            .map(|(_, lo, hi)| project(*lo, *hi))
            .collect();
        // A pixel's worth of slack around each box: the box corners are exact, the rays are not.
        let slack = 0.01;
        for ((kind, _, _), p) in kinds.iter().zip(projected) {
            let n = grid.items.len() as u32;
            match p {
                Projected::Off => continue,
                Projected::Everywhere => {
                    grid.items.push(Item {
                        kind: *kind,
                        lo: [f64::NEG_INFINITY; 2],
                        hi: [f64::INFINITY; 2],
                    });
                    grid.everywhere.push(n);
                }
                Projected::Box(a, b) => {
                    let lo = [a[0] - slack, a[1] - slack];
                    let hi = [b[0] + slack, b[1] + slack];
                    grid.items.push(Item {
                        kind: *kind,
                        lo,
                        hi,
                    });
                    let c = |v: f64, n: usize| ((v / CELL).floor().max(0.0) as usize).min(n - 1);
                    let (i0, i1) = (c(lo[0], cols), c(hi[0], cols));
                    let (j0, j1) = (c(lo[1], rows), c(hi[1], rows));
                    if (i1 - i0 + 1) * (j1 - j0 + 1) * 4 > cols * rows {
                        grid.everywhere.push(n);
                        continue;
                    }
                    for j in j0..=j1 {
                        for i in i0..=i1 {
                            grid.cells[j * cols + i].push(n);
                        }
                    }
                }
            }
        }
        grid
    }

    /// The nearest exact prism hit through image point `(px, py)` among the buildings `want`
    /// accepts, between the near and far planes: (building, distance along the ray).
    fn prism_hit(&self, px: f64, py: f64, want: impl Fn(bool) -> bool) -> Option<(u32, f64)> {
        let cam = self.frame.camera;
        let (o, d) = image_ray_with(cam, &self.inv, px, py, self.w, self.h);
        let depth_per_t = d.dot(self.forward);
        let src = &self.frame.geometry.source.buildings;
        let mut best: Option<(u32, f64)> = None;
        for it in self.grid.at(px, py) {
            let Kind::Building { b, near } = it.kind else {
                continue;
            };
            if !want(near) {
                continue;
            }
            let Some(Some(sb)) = src.get(b as usize) else {
                continue;
            };
            if let Some(t) = ray_prism(sb, o, d) {
                let depth = t * depth_per_t;
                if depth >= cam.near && depth <= cam.far && best.is_none_or(|(_, bt)| t < bt) {
                    best = Some((b, t));
                }
            }
        }
        best
    }

    /// The nearest drawn map the GPU's f32 cast hits through image point `(px, py)` (as
    /// `blockmap::cast_image` chooses it: least depth, below 1): (map, depth).
    fn map_hit(&self, px: f64, py: f64) -> Option<(usize, f32)> {
        let mut best: Option<(usize, f32)> = None;
        for it in self.grid.at(px, py) {
            let Kind::Map(m) = it.kind else { continue };
            let Some(x) = self.xforms.get(m).and_then(|x| x.as_ref()) else {
                continue;
            };
            if let Some(depth) = x.hit_depth(px, py) {
                if depth < 1.0 && best.is_none_or(|(_, bd)| depth < bd) {
                    best = Some((m, depth));
                }
            }
        }
        best
    }

    /// The lattice points within `r` of pixel `(x, y)`'s centre inside the image, nearest
    /// first: `(px, py, d)`.
    fn points(&self, x: u32, y: u32, r: f64) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
        let (w, h) = (self.w as f64, self.h as f64);
        self.lattice
            .iter()
            .take_while(move |p| p.2 <= r)
            .map(move |&(dx, dy, d)| (cx + dx, cy + dy, d))
            .filter(move |&(px, py, _)| px >= 0.0 && py >= 0.0 && px <= w && py <= h)
    }

    /// The first verdict on a pixel beyond `r` (the twin is settled by the caller).
    fn verdict(&self, p: &Beyond, mesh_sil: &[bool]) -> Verdict {
        if p.extra {
            // The mesh frame's geometry within r?
            if let Some((_, _, d)) = self
                .points(p.x, p.y, p.r)
                .find(|&(px, py, _)| self.prism_hit(px, py, |_| true).is_some())
            {
                return Verdict::Subpixel(d);
            }
            // The map that drew the pixel, and its f64 twin's hit.
            let (cx, cy) = (p.x as f64 + 0.5, p.y as f64 + 0.5);
            if let Some((m, _)) = self.map_hit(cx, cy) {
                let twin = self.xforms[m].as_ref().and_then(|x| x.twin_point(p.x, p.y));
                if let Some(point) = twin {
                    return Verdict::Twin(m, point);
                }
            }
            Verdict::Violation
        } else {
            // The hybrid frame's geometry within r?
            let found = self.points(p.x, p.y, p.r).find(|&(px, py, _)| {
                self.prism_hit(px, py, |near| near).is_some() || self.map_hit(px, py).is_some()
            });
            match found {
                Some((_, _, d)) => Verdict::Subpixel(d),
                None => self.thin_or_violation(p, mesh_sil),
            }
        }
    }

    /// A pixel only the mesh frame covers, showing a building a drawn map declares, within `r`
    /// of the mesh frame's silhouette: thin; else a violation. (An extra pixel is never thin.)
    fn thin_or_violation(&self, p: &Beyond, mesh_sil: &[bool]) -> Verdict {
        if p.extra {
            return Verdict::Violation;
        }
        // The building the pixel shows: the nearest prism at the nearest lattice point that
        // meets one.
        let shown = self
            .points(p.x, p.y, p.r)
            .find_map(|(px, py, _)| self.prism_hit(px, py, |_| true));
        let Some((b, _)) = shown else {
            return Verdict::Violation;
        };
        if !self.frame.geometry.declared_by(self.frame.selection, b) {
            return Verdict::Violation;
        }
        let d = crate::blockmap::compare::nearest_in_mask(
            mesh_sil,
            self.w as usize,
            self.h as usize,
            p.x as i64,
            p.y as i64,
        );
        match d {
            Some(d) if d <= p.r => Verdict::Thin(d),
            _ => Verdict::Violation,
        }
    }

    /// The twin test of `blockmap::compare`: the hit `point` of map `m` lies within its ε of a
    /// prism of the original solid (not the ground); then the original point projects within
    /// `e_px·e/ε` of the pixel.
    fn twin(
        &self,
        m: usize,
        point: DVec3,
        grid: &BuildingGrid,
        scratch: &mut Scratch,
    ) -> Option<f64> {
        let eps = self.frame.geometry.tree.eps_m(m);
        let e = grid.surface_distance(point, scratch);
        // The ground (z = 0, or the terrain) is nearer than (or as near as) every prism: the
        // hit is explained by the ground, which both frames draw alike, not by a building.
        let on_ground = self.frame.geometry.ground_within(point, e);
        if on_ground || e > eps * (1.0 + 1e-9) + 1e-6 {
            return None;
        }
        let cam = self.frame.camera;
        let b = self.frame.geometry.tree.aabb(m);
        let d = ((cam.position - b.center()).length() - 0.5 * b.extent().length()).max(cam.near);
        let f = self.h as f64 / (2.0 * (0.5 * cam.fov_y).tan());
        let e_px = eps * f / d;
        Some(e_px * e / eps.max(1e-12))
    }
}

/// A terrain's triangles (f64, local frame) binned by plan-view box on a uniform grid, for the
/// distance from a point.
struct TerrainSurface {
    tris: Vec<[DVec3; 3]>,
    min: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Triangles (indices into `tris`) whose plan-view box meets each cell, row-major.
    cells: Vec<Vec<u32>>,
}

impl TerrainSurface {
    fn new(mesh: &crate::city::Mesh) -> Self {
        let tris: Vec<[DVec3; 3]> = mesh
            .indices
            .chunks_exact(3)
            .filter_map(|t| {
                let p = |i: usize| mesh.positions.get(t[i] as usize).map(|v| v.as_dvec3());
                Some([p(0)?, p(1)?, p(2)?])
            })
            .collect();
        let (mut min, mut max) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in tris.iter().flatten() {
            min = min.min(p.truncate());
            max = max.max(p.truncate());
        }
        if tris.is_empty() {
            (min, max) = (DVec2::ZERO, DVec2::ONE);
        }
        let size = (max - min).max(DVec2::splat(1e-9));
        // About two triangles per cell.
        let cell = (size.x * size.y / (tris.len().max(1) as f64 / 2.0))
            .sqrt()
            .max(1e-6);
        let nx = ((size.x / cell).ceil() as usize).clamp(1, 4096);
        let ny = ((size.y / cell).ceil() as usize).clamp(1, 4096);
        let mut s = Self {
            tris: Vec::new(),
            min,
            cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
        };
        for (i, t) in tris.iter().enumerate() {
            let lo = t[0].truncate().min(t[1].truncate()).min(t[2].truncate());
            let hi = t[0].truncate().max(t[1].truncate()).max(t[2].truncate());
            let ((x0, y0), (x1, y1)) = (s.cell_of(lo), s.cell_of(hi));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    s.cells[y * nx + x].push(i as u32);
                }
            }
        }
        s.tris = tris;
        s
    }

    fn cell_of(&self, p: DVec2) -> (usize, usize) {
        let q = (p - self.min) / self.cell;
        let c = |v: f64, n: usize| (v.floor().max(0.0) as usize).min(n - 1);
        (c(q.x, self.nx), c(q.y, self.ny))
    }

    /// Whether a triangle lies within `e` of `p`.
    fn within(&self, p: DVec3, e: f64) -> bool {
        let r = DVec2::splat(e.max(0.0));
        let (lo, hi) = (p.truncate() - r, p.truncate() + r);
        if hi.x < self.min.x || hi.y < self.min.y {
            return false;
        }
        let ((x0, y0), (x1, y1)) = (self.cell_of(lo), self.cell_of(hi));
        (y0..=y1).any(|y| {
            (x0..=x1).any(|x| {
                self.cells[y * self.nx + x]
                    .iter()
                    .any(|&i| closest_on_triangle(p, &self.tris[i as usize]).distance(p) <= e)
            })
        })
    }
}

/// The point of triangle `t` closest to `p` (Ericson, *Real-Time Collision Detection*, §5.1.5).
fn closest_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The terrain's distance test against brute force over every triangle (the closest point
    /// checked against dense samples of each triangle), and z = 0 without terrain.
    #[test]
    fn the_ground_is_the_terrain_when_there_is_one() {
        use crate::visibility::terrain::{height_mesh, HeightGrid};
        let grid = HeightGrid {
            origin: [-20.0, -10.0],
            step_m: 4.0,
            cells: (10, 6),
        };
        let mesh = height_mesh(&grid, |x, y| 5.0 + 0.3 * x + 2.0 * (0.2 * y).sin());
        let surf = TerrainSurface::new(&mesh);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for _ in 0..300 {
            let p = DVec3::new(
                rng.random_range(-30.0..30.0),
                rng.random_range(-20.0..20.0),
                rng.random_range(-10.0..20.0),
            );
            let exact = surf
                .tris
                .iter()
                .map(|t| closest_on_triangle(p, t).distance(p))
                .fold(f64::INFINITY, f64::min);
            // The closest point is no farther than any sampled point of any triangle.
            for t in &surf.tris {
                for (u, v) in [(0.2, 0.3), (0.5, 0.5), (0.0, 1.0), (0.1, 0.1)] {
                    let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v * (1.0 - u);
                    assert!(exact <= q.distance(p) + 1e-9);
                }
            }
            for e in [exact * 0.999, exact * 1.001 + 1e-9] {
                assert_eq!(surf.within(p, e), exact <= e, "{p:?} {e} {exact}");
            }
        }
    }

    /// The bound's geometry takes its ground from the source: z = 0 without terrain, the
    /// terrain's surface with one.
    #[test]
    fn the_bound_geometry_takes_its_ground_from_the_source() {
        use crate::visibility::terrain::{height_mesh, HeightGrid};
        let sc = SyntheticCity::generate(1, 1, 5, DVec2::new(5.0e5, 6.0e6));
        let meshes = crate::city::extrude::extrude_city(&sc.city);
        let tree = MapTree::default();
        let grid = HeightGrid {
            origin: [-500.0, -500.0],
            step_m: 100.0,
            cells: (10, 10),
        };
        let plateau = height_mesh(&grid, |_, _| 50.0);
        let flat = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
        let raised = Source::new(&sc.city, &sc.layout, &meshes)
            .unwrap()
            .with_terrain(&plateau);
        let (g0, g1) = (
            BoundGeometry::new(&flat, &tree),
            BoundGeometry::new(&raised, &tree),
        );
        let above = DVec3::new(3.0, 4.0, 50.5);
        assert!(!g0.ground_within(above, 1.0) && g1.ground_within(above, 1.0));
        let low = DVec3::new(3.0, 4.0, 0.5);
        assert!(g0.ground_within(low, 1.0) && !g1.ground_within(low, 1.0));
    }

    use crate::blocks::BlockId;
    use crate::visibility::synthetic::SyntheticCity;
    use glam::DVec2;
    use rand::{Rng, SeedableRng};

    /// The screen grid hands every prism a ray meets to the search: the nearest hit through
    /// random image points equals the brute force over every building, from random eyes.
    #[test]
    fn the_screen_grid_misses_no_prism() {
        let sc = SyntheticCity::generate(3, 3, 5, DVec2::new(5.0e5, 6.0e6));
        let meshes = crate::city::extrude::extrude_city(&sc.city);
        let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
        let tree = MapTree::default();
        let geom = BoundGeometry::new(&source, &tree);
        let sel = Selection {
            maps: Vec::new(),
            meshes: (0..sc.layout.blocks.len() as u32).map(BlockId).collect(),
            stats: Default::default(),
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (w, h) = (96u32, 54u32);
        let mut hits = 0;
        for _ in 0..12 {
            let eye = DVec3::new(
                rng.random_range(-60.0..300.0),
                rng.random_range(-60.0..300.0),
                rng.random_range(2.0..200.0),
            );
            let target = DVec3::new(
                rng.random_range(0.0..250.0),
                rng.random_range(0.0..250.0),
                0.0,
            );
            let mut cam = Camera::looking_at(eye, target);
            cam.near = 1.0;
            let fb = FrameBound::new(&geom, &sel, &cam, 1.0);
            let beyond = [Beyond {
                x: 0,
                y: 0,
                extra: true,
                raw: 9.0,
                r: 2.0,
            }];
            let look = Look::new(&fb, w, h, &beyond);
            for _ in 0..300 {
                let (px, py) = (
                    rng.random_range(0.0..w as f64),
                    rng.random_range(0.0..h as f64),
                );
                let fast = look.prism_hit(px, py, |_| true);
                let (o, d) = image_ray_with(&cam, &look.inv, px, py, w, h);
                let brute = source
                    .buildings
                    .iter()
                    .enumerate()
                    .filter_map(|(i, b)| {
                        let t = ray_prism(b.as_ref()?, o, d)?;
                        let depth = t * d.dot(cam.forward());
                        (depth >= cam.near && depth <= cam.far).then_some((i as u32, t))
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                assert_eq!(fast, brute, "eye {eye}, point ({px}, {py})");
                hits += usize::from(brute.is_some());
            }
        }
        assert!(hits > 300, "{hits} rays met a prism");
    }

    #[test]
    fn the_allowed_distance_grows_off_axis() {
        let source_city = SyntheticCity::generate(1, 1, 1, DVec2::ZERO);
        let meshes = crate::city::extrude::extrude_city(&source_city.city);
        let source = Source::new(&source_city.city, &source_city.layout, &meshes).unwrap();
        let tree = MapTree::default();
        let geom = BoundGeometry::new(&source, &tree);
        let sel = Selection {
            maps: Vec::new(),
            meshes: Vec::new(),
            stats: Default::default(),
        };
        let cam = Camera::new(DVec3::ZERO, 0.0, 0.0);
        let fb = FrameBound::new(&geom, &sel, &cam, 2.0);
        // At the centre of an even image, half a pixel off the axis: nearly 1 + τ.
        let c = fb.allowed_px(80, 45, 160, 90);
        assert!((c - 3.0).abs() < 1e-3, "{c}");
        // At the corner: 1/cos²θ = 1 + tan²(fx) + tan²(fy) at the pixel centre.
        let fy = (0.5 * cam.fov_y).tan();
        let fx = fy * cam.aspect;
        let (nx, ny) = (
            (0.5 / 160.0 * 2.0 - 1.0) * fx,
            (1.0 - 0.5 / 90.0 * 2.0) * fy,
        );
        let corner = fb.allowed_px(0, 0, 160, 90);
        assert!(
            (corner - (1.0 + 2.0 * (1.0 + nx * nx + ny * ny))).abs() < 1e-12,
            "{corner}"
        );
        assert!(corner > c + 2.0);
    }
}
