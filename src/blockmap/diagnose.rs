//! Where a hybrid frame's coverage error comes from: every pixel whose coverage
//! differs between the hybrid frame (near meshes + far maps, drawn as [`super::CpuHybridRenderer`]
//! draws them) and the mesh-only frame of the same camera, classified by cause.
//!
//! Per mismatched pixel:
//! - **side**: `extra` (the hybrid shows a building, the meshes do not) or `missing` (the
//!   reverse), and which node drew or should have drawn it (a map or a near mesh);
//! - **cause**, from the exact (f64) geometry:
//!   - an extra map pixel: the f64 twin's hit point `P` against the map's buildings: `P.xy`
//!     outside every footprint in a texel that is *partly* covered and stores a half-plane
//!     (`edge-excess`: the one half-plane cannot follow the footprint there, e.g. a convex
//!     corner, plus offset rounding), partly covered without a half-plane (`whole-partial`: a
//!     texel kept whole, a corner or a gap narrower than a texel between two footprints), not
//!     covered at all (`empty-filled`), or `P.xy` inside a footprint with `P.z` above the roof
//!     (`height`, the 8-bit quantisation), else `on-solid` (ties);
//!   - a missing pixel of a building a map holds: the mesh's exact hit point `Q` in the map's
//!     texel: `empty-texel` (the texel has no column: a building or part narrower than a
//!     texel), `edge-cut` (outside the stored half-plane), `roof-low` (above the column's
//!     height), else `caster`;
//! - **building size**: pixels of the building in the mesh frame (for an extra pixel the
//!   building of the nearest mesh pixel);
//! - **silhouette distance**: to the nearest silhouette pixel of the frame that does not cover
//!   the pixel (the form `walk::far` measures), and whether it exceeds `1 + τ/cos²θ`;
//! - **seam**: the 3×3 neighbourhood shows two sources (two maps, or a map and a near mesh);
//! - **near**: the hit lies within 1 % of the near plane; **background**: ground or sky.

use super::cast::{cast_f64, CastOptions, Face, Hit};
use super::error::{horizontal_distance, in_polygon};
use super::image::{cast_image, twin_ray};
use super::layout::BlockMap;
use super::select::Selection;
use super::source::{Source, SourceBuilding};
use super::tree::MapTree;
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::clip::clip_to_box;
use crate::geom::predicates::shoelace;
use crate::geom::Camera;
use crate::visibility::oracle::{render_ids, shade_with_ground_depth, SKY};
use glam::{DVec2, DVec3, DVec4};
use serde::Serialize;
use std::collections::BTreeMap;

/// One class of mismatched pixels.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ClassFigures {
    /// Pixels.
    pub pixels: usize,
    /// Share of all mismatched pixels.
    pub share: f64,
    /// Of those, pixels beyond `1 + τ/cos²θ` of the silhouette they are measured against.
    pub beyond_bound: usize,
    /// Largest silhouette distance, pixels.
    pub silhouette_px_max: f64,
    /// Mean silhouette distance, pixels.
    pub silhouette_px_mean: f64,
    /// Pixels at a seam (two sources in the 3×3 neighbourhood).
    pub seam: usize,
    /// Pixels whose building covers fewer than 4 pixels in the mesh frame.
    pub building_under_4px: usize,
    /// Pixels whose building covers 4–15 pixels.
    pub building_4_to_16px: usize,
    /// Pixels whose building covers 16 pixels or more.
    pub building_16px_up: usize,
    /// Pixels in front of the ground (else the sky).
    pub over_ground: usize,
    /// Pixels whose hit lies within 1 % of the near plane.
    pub near_plane: usize,
    /// Mean horizontal distance of the hit (extra) or mesh point (missing) to the nearest
    /// footprint edge, texels of the map (maps only).
    pub edge_distance_texels_mean: f64,
}

/// One mismatched pixel, in detail (the worst ones are kept).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PixelDetail {
    /// Pixel.
    pub px: [u32; 2],
    /// Class key (`side/node/cause`).
    pub class: String,
    /// Distance to the silhouette it is measured against, pixels.
    pub silhouette_px: f64,
    /// Its allowed distance `1 + τ/cos²θ`.
    pub allowed_px: f64,
    /// The building (index into `City::buildings`), when known.
    pub building: Option<u32>,
    /// Its pixels in the mesh frame.
    pub building_px: usize,
    /// The map (index into `MapTree::maps`) that drew it or holds its building.
    pub map: Option<usize>,
    /// The texel of that map.
    pub texel: Option<[u32; 2]>,
    /// Hit (extra) or mesh point (missing), local frame.
    pub point: Option<[f64; 3]>,
    /// Distance from the eye, metres.
    pub distance_m: Option<f64>,
}

/// The classification of one frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameDiagnosis {
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// τ the bound is measured with, pixels.
    pub tau_px: f64,
    /// Maps drawn.
    pub maps: usize,
    /// Blocks drawn as meshes.
    pub mesh_blocks: usize,
    /// Pixels the mesh frame covers.
    pub mesh_pixels: usize,
    /// Pixels the hybrid frame covers.
    pub hybrid_pixels: usize,
    /// Pixels whose coverage differs.
    pub mismatched: usize,
    /// `mismatched / (width·height)`.
    pub coverage_error: f64,
    /// Mismatched pixels beyond the bound.
    pub beyond_bound: usize,
    /// Largest silhouette distance of a mismatched pixel.
    pub silhouette_px_max: f64,
    /// Pixels whose coverage differs without the ground but agrees with it (the ground's depth
    /// test hid the difference).
    pub hidden_by_ground: usize,
    /// Pixels that are silhouettes of the mesh frame (covered with an uncovered 4-neighbour or
    /// the reverse): the band a shift of a pixel can touch.
    pub mesh_silhouette_pixels: usize,
    /// Mesh-frame buildings by pixel count: fewer than 4, 4–15, 16 or more.
    pub buildings_by_px: [usize; 3],
    /// Per class (`side/node/cause`).
    pub classes: BTreeMap<String, ClassFigures>,
    /// The mismatched pixels farthest from their silhouette (at most 20), worst first.
    pub worst: Vec<PixelDetail>,
}

/// What a frame is made of: the buildings and their meshes, the maps, the selection.
#[derive(Clone, Copy)]
pub struct FrameInput<'a> {
    /// Buildings (f64) and one mesh per building.
    pub source: &'a Source<'a>,
    /// The ground layers, when the frames are drawn with them (the walk's frames): coverage is
    /// then, as in `walk::far`, a pixel that differs from the frame without buildings, and the
    /// ground's depth test can hide a building's lower walls in one frame and not in the other.
    pub ground: Option<&'a Mesh>,
    /// The maps.
    pub tree: &'a MapTree,
    /// What the frame draws: maps and near blocks.
    pub selection: &'a Selection,
    /// The camera.
    pub camera: &'a Camera,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// τ, pixels (the bound `1 + τ/cos²θ`).
    pub tau_px: f64,
}

/// Buildings per texel of a map (by footprint box), for the footprint tests.
struct TexelBuckets {
    k: usize,
    cells: Vec<Vec<u32>>,
}

impl TexelBuckets {
    fn new(map: &BlockMap, source: &Source, buildings: &[u32]) -> Self {
        let k = map.k() as usize;
        let s = map.texel_m();
        let (mx, my) = (map.meta.min[0], map.meta.min[1]);
        let mut cells = vec![Vec::new(); k * k];
        for &b in buildings {
            let Some(sb) = source.buildings.get(b as usize).and_then(|x| x.as_ref()) else {
                continue;
            };
            let c = |v: f64, m: f64| (((v - m) / s).floor().max(0.0) as usize).min(k - 1);
            for j in c(sb.min.y, my)..=c(sb.max.y, my) {
                for i in c(sb.min.x, mx)..=c(sb.max.x, mx) {
                    cells[j * k + i].push(b);
                }
            }
        }
        Self { k, cells }
    }

    /// Buildings whose box meets texel `(i, j)` or its 8 neighbours.
    fn around(&self, i: i64, j: i64) -> Vec<u32> {
        let mut out = Vec::new();
        for dj in -1..=1 {
            for di in -1..=1 {
                let (a, b) = (i + di, j + dj);
                if a >= 0 && b >= 0 && (a as usize) < self.k && (b as usize) < self.k {
                    out.extend_from_slice(&self.cells[b as usize * self.k + a as usize]);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// Share of texel `(i, j)` of `map` that footprints of `bs` cover (overlaps counted once
/// only approximately: capped at 1).
fn texel_cover(map: &BlockMap, i: u32, j: u32, bs: &[&SourceBuilding]) -> f64 {
    let s = map.texel_m();
    let lo = DVec2::new(
        map.meta.min[0] + i as f64 * s,
        map.meta.min[1] + j as f64 * s,
    );
    let hi = lo + DVec2::splat(s);
    let mut a = 0.0;
    for b in bs {
        let mut area = shoelace(&clip_to_box(&b.rings[0], lo, hi)).abs();
        for hole in &b.rings[1..] {
            area -= shoelace(&clip_to_box(hole, lo, hi)).abs();
        }
        a += area.max(0.0);
    }
    (a / (s * s)).min(1.0)
}

/// Exact first intersection (ray parameter, `d` unit) of a ray with a building's prism.
pub fn ray_prism(b: &SourceBuilding, o: DVec3, d: DVec3) -> Option<f64> {
    let mut best = f64::INFINITY;
    for z in [b.z1, b.z0] {
        if d.z != 0.0 {
            let t = (z - o.z) / d.z;
            if t > 0.0 && t < best && in_polygon(b, (o + d * t).truncate()) {
                best = t;
            }
        }
    }
    let (o2, d2) = (o.truncate(), d.truncate());
    for ring in &b.rings {
        let n = ring.len();
        for e in 0..n {
            let (a, c) = (ring[e], ring[(e + 1) % n]);
            let ac = c - a;
            let den = d2.perp_dot(ac);
            if den == 0.0 {
                continue;
            }
            let w = a - o2;
            let t = w.perp_dot(ac) / den;
            let u = w.perp_dot(d2) / den;
            if t > 0.0 && t < best && (-1e-12..=1.0 + 1e-12).contains(&u) {
                let z = o.z + d.z * t;
                if z >= b.z0 - 1e-9 && z <= b.z1 + 1e-9 {
                    best = t;
                }
            }
        }
    }
    best.is_finite().then_some(best)
}

/// Classifies every coverage-mismatched pixel of the hybrid frame of `input` (see the module
/// doc).
pub fn diagnose_frame(input: &FrameInput) -> FrameDiagnosis {
    let FrameInput {
        source,
        ground,
        tree,
        selection,
        camera,
        width,
        height,
        tau_px,
    } = *input;
    let (w, h) = (width as usize, height as usize);
    let all: Vec<(BlockId, &Mesh)> = source
        .buildings
        .iter()
        .enumerate()
        .filter(|(_, b)| b.is_some())
        .map(|(i, _)| (BlockId(i as u32), &source.meshes[i]))
        .collect();
    let near_blocks: std::collections::HashSet<BlockId> =
        selection.meshes.iter().copied().collect();
    let near: Vec<(BlockId, &Mesh)> = all
        .iter()
        .filter(|(b, _)| {
            source.buildings[b.0 as usize]
                .as_ref()
                .is_some_and(|sb| near_blocks.contains(&sb.block))
        })
        .copied()
        .collect();
    let mesh = render_ids(&all, camera, width, height);
    let near_ids = render_ids(&near, camera, width, height);
    let map_refs: Vec<&BlockMap> = tree.maps.iter().map(|m| &m.map).collect();
    let far = cast_image(&map_refs, &selection.maps, camera, width, height);
    // The building → drawing map of this frame.
    let mut owner: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    for &m in &selection.maps {
        for &b in &tree.maps[m].buildings {
            owner.insert(b, m);
        }
    }
    // Hybrid per pixel: source 0 = nothing, 1 + m = map m, MESH = a near mesh.
    const MESH: u32 = u32::MAX;
    let src: Vec<u32> = (0..w * h)
        .map(|k| {
            if far.hit[k] && far.depth[k] < near_ids.depth[k] {
                far.map[k] + 1
            } else if near_ids.ids[k] != SKY {
                MESH
            } else {
                0
            }
        })
        .collect();
    let mut mesh_cov: Vec<bool> = mesh.ids.iter().map(|&i| i != SKY).collect();
    let mut hyb_cov: Vec<bool> = src.iter().map(|&s| s != 0).collect();
    // With the ground: the frames as the walk draws and measures them (the CPU hybrid
    // renderer's composite), and which pixels the ground's depth test decided.
    let mut ground_decided = vec![false; w * h];
    let mut hidden_by_ground = 0usize;
    if let Some(g) = ground {
        let none: Vec<(BlockId, &Mesh)> = Vec::new();
        let (bg, _) = shade_with_ground_depth(&none, g, camera, width, height);
        let (mimg, _) = shade_with_ground_depth(&all, g, camera, width, height);
        let (mut himg, hdepth) = shade_with_ground_depth(&near, g, camera, width, height);
        for (k, px) in himg.pixels_mut().enumerate() {
            if far.hit[k] && far.depth[k] < hdepth[k] {
                *px = image::Rgba(far.color[k]);
            }
        }
        let cov = |img: &image::RgbaImage| -> Vec<bool> {
            img.pixels()
                .zip(bg.pixels())
                .map(|(a, b)| a.0[..3] != b.0[..3])
                .collect()
        };
        let (mc, hc) = (cov(&mimg), cov(&himg));
        for k in 0..w * h {
            let id_mis = mesh_cov[k] != hyb_cov[k];
            let sh_mis = mc[k] != hc[k];
            if sh_mis && !id_mis {
                ground_decided[k] = true;
            }
            if id_mis && !sh_mis {
                hidden_by_ground += 1;
            }
        }
        mesh_cov = mc;
        hyb_cov = hc;
    }
    let mask = |cov: &[bool]| {
        let mut m = vec![false; w * h];
        for (x, y) in super::compare::silhouette_pixels(cov, w, h) {
            m[y as usize * w + x as usize] = true;
        }
        m
    };
    let (mesh_sil, hyb_sil) = (mask(&mesh_cov), mask(&hyb_cov));
    let mut bpx: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    for &id in &mesh.ids {
        if id != SKY {
            *bpx.entry(id).or_default() += 1;
        }
    }
    let mut out = FrameDiagnosis {
        width,
        height,
        tau_px,
        maps: selection.maps.len(),
        mesh_blocks: selection.meshes.len(),
        mesh_pixels: mesh_cov.iter().filter(|&&c| c).count(),
        hybrid_pixels: hyb_cov.iter().filter(|&&c| c).count(),
        mesh_silhouette_pixels: mesh_sil.iter().filter(|&&c| c).count(),
        ..FrameDiagnosis::default()
    };
    for &n in bpx.values() {
        out.buildings_by_px[if n < 4 {
            0
        } else if n < 16 {
            1
        } else {
            2
        }] += 1;
    }
    let buckets: std::collections::HashMap<usize, TexelBuckets> = selection
        .maps
        .iter()
        .map(|&m| {
            (
                m,
                TexelBuckets::new(&tree.maps[m].map, source, &tree.maps[m].buildings),
            )
        })
        .collect();
    let fy = (0.5 * camera.fov_y).tan();
    let fx = fy * camera.aspect;
    let mut sums: BTreeMap<String, (f64, f64, usize)> = BTreeMap::new();
    let mut details: Vec<PixelDetail> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if mesh_cov[k] == hyb_cov[k] {
                continue;
            }
            out.mismatched += 1;
            let extra = hyb_cov[k];
            let (o, d) = super::compare::pixel_ray(camera, x as u32, y as u32, width, height);
            let sil = if extra { &mesh_sil } else { &hyb_sil };
            let dist = super::compare::nearest_in_mask(sil, w, h, x as i64, y as i64)
                .unwrap_or(((w * w + h * h) as f64).sqrt());
            let nx = ((x as f64 + 0.5) / w as f64 * 2.0 - 1.0) * fx;
            let ny = (1.0 - (y as f64 + 0.5) / h as f64 * 2.0) * fy;
            let allowed = 1.0 + tau_px * (1.0 + nx * nx + ny * ny);
            let seam = {
                let mut first: Option<u32> = None;
                let mut two = false;
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (a, b) = (x as i64 + dx, y as i64 + dy);
                        if a < 0 || b < 0 || a >= w as i64 || b >= h as i64 {
                            continue;
                        }
                        let s = src[b as usize * w + a as usize];
                        if s == 0 {
                            continue;
                        }
                        match first {
                            None => first = Some(s),
                            Some(f) if f != s => two = true,
                            _ => {}
                        }
                    }
                }
                two
            };
            // Node, cause, building, texel, point.
            let mut building: Option<u32> = if mesh.ids[k] != SKY {
                Some(mesh.ids[k])
            } else {
                None
            };
            let mut map_i: Option<usize> = None;
            let mut texel: Option<[u32; 2]> = None;
            let mut point: Option<DVec3> = None;
            let mut edge_dist: Option<f64> = None;
            let class = if ground_decided[k] {
                // Both frames agree without the ground: its depth test decided this pixel.
                format!(
                    "{}/ground-depth/{}",
                    if extra { "extra" } else { "missing" },
                    match src[k] {
                        0 => "none",
                        MESH => "mesh",
                        _ => "map",
                    }
                )
            } else if extra && src[k] == 0 || !extra && mesh.ids[k] == SKY {
                // The two coverages disagree in kind (a depth test against the ground turned
                // an extra pixel into a missing one or the reverse).
                "mixed/ground-depth/-".to_string()
            } else if extra {
                if src[k] == MESH {
                    "extra/mesh/-".to_string()
                } else {
                    let m = (src[k] - 1) as usize;
                    map_i = Some(m);
                    let map = &tree.maps[m].map;
                    let ray = twin_ray(map, camera, width, height, x as u32, y as u32);
                    let c = cast_f64(map, &ray, &CastOptions::default());
                    let cause = match c.hit {
                        Hit::Miss => "twin-miss".to_string(),
                        Hit::Roof { i, j, t } | Hit::Wall { i, j, t, .. } => {
                            texel = Some([i, j]);
                            let s = map.texel_m();
                            let p = map.local_point(&ray, t);
                            point = Some(p);
                            let ids = buckets[&m].around(i as i64, j as i64);
                            let bs: Vec<&SourceBuilding> = ids
                                .iter()
                                .filter_map(|&b| source.buildings[b as usize].as_ref())
                                .collect();
                            let hd = bs
                                .iter()
                                .map(|b| (horizontal_distance(b, p.truncate()), b))
                                .fold((f64::INFINITY, None), |a, (dd, b)| {
                                    if dd < a.0 {
                                        (dd, Some(*b))
                                    } else {
                                        a
                                    }
                                });
                            edge_dist = Some(hd.0 / s);
                            building = hd.1.map(|b| b.id.0);
                            let face = match c.hit {
                                Hit::Roof { .. } => "roof",
                                Hit::Wall {
                                    face: Face::Edge | Face::Edge2,
                                    ..
                                } => "edgewall",
                                _ => "wall",
                            };
                            let tol = 1e-6 * s.max(1.0);
                            if hd.0 > tol {
                                let cover = texel_cover(map, i, j, &bs);
                                let [e1, e2] = map.edges(i, j);
                                let kind = if cover <= 1e-9 {
                                    "empty-filled"
                                } else if e2.is_some() {
                                    "edge2-excess"
                                } else if e1.is_some() {
                                    "edge-excess"
                                } else if cover >= 1.0 - 1e-9 {
                                    "full-outside"
                                } else {
                                    "whole-partial"
                                };
                                format!("{kind}/{face}")
                            } else {
                                let b = hd.1.expect("a footprint holds the point");
                                if p.z > b.z1 + 1e-6 * (1.0 + b.z1) {
                                    format!("height/{face}")
                                } else {
                                    format!("on-solid/{face}")
                                }
                            }
                        }
                    };
                    format!("extra/map/{cause}")
                }
            } else {
                let b = mesh.ids[k];
                let sb = source.buildings[b as usize].as_ref();
                let q = sb.and_then(|sb| ray_prism(sb, o, d)).map(|t| o + d * t);
                let q = q.unwrap_or_else(|| {
                    let inv = camera.clip_from_world().inverse();
                    let nxx = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
                    let nyy = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
                    let v = inv * DVec4::new(nxx, nyy, mesh.depth[k] as f64, 1.0);
                    v.truncate() / v.w
                });
                point = Some(q);
                match owner.get(&b) {
                    None => {
                        if near_blocks.contains(&sb.map_or(BlockId(u32::MAX), |s| s.block)) {
                            "missing/mesh/-".to_string()
                        } else {
                            "missing/none/-".to_string()
                        }
                    }
                    Some(&m) => {
                        map_i = Some(m);
                        let nm = &tree.maps[m];
                        let map = &nm.map;
                        let s = map.texel_m();
                        let fi = (q.x - map.meta.min[0]) / s;
                        let fj = (q.y - map.meta.min[1]) / s;
                        let kk = map.k() as f64;
                        let (i, j) = (
                            fi.floor().clamp(0.0, kk - 1.0) as u32,
                            fj.floor().clamp(0.0, kk - 1.0) as u32,
                        );
                        texel = Some([i, j]);
                        if let Some(sb) = sb {
                            edge_dist = Some({
                                // Distance to the footprint's boundary from inside.
                                let mut best = f64::INFINITY;
                                for ring in &sb.rings {
                                    let n = ring.len();
                                    for e in 0..n {
                                        let (a, c) = (ring[e], ring[(e + 1) % n]);
                                        let ac = c - a;
                                        let l2 = ac.length_squared();
                                        let t = if l2 > 0.0 {
                                            ((q.truncate() - a).dot(ac) / l2).clamp(0.0, 1.0)
                                        } else {
                                            0.0
                                        };
                                        best = best.min((a + ac * t - q.truncate()).length());
                                    }
                                }
                                best / s
                            });
                        }
                        let dropped = nm.stats.dropped_buildings.iter().any(|id| id.0 == b);
                        let code = map.height_code(i, j);
                        let cause = if code == 0 {
                            if dropped {
                                "building-dropped"
                            } else {
                                "empty-texel"
                            }
                        } else if map.edges(i, j).iter().flatten().any(|e| {
                            let qx = (fi - i as f64 - 0.5) as f32;
                            let qy = (fj - j as f64 - 0.5) as f32;
                            e.n[0] * qx + e.n[1] * qy > e.o + 1e-4
                        }) {
                            "edge-cut"
                        } else if q.z > map.code_height_m(code) + 1e-6 * (1.0 + q.z.abs()) {
                            "roof-low"
                        } else {
                            "caster"
                        };
                        format!("missing/map/{cause}")
                    }
                }
            };
            let bp = building
                .and_then(|b| bpx.get(&b).copied())
                .unwrap_or_else(|| {
                    // The building of the nearest mesh pixel.
                    nearest_building(&mesh.ids, w, h, x, y)
                        .and_then(|b| bpx.get(&b).copied())
                        .unwrap_or(0)
                });
            let e = out.classes.entry(class.clone()).or_default();
            e.pixels += 1;
            let beyond = dist > allowed;
            if beyond {
                e.beyond_bound += 1;
                out.beyond_bound += 1;
            }
            e.silhouette_px_max = e.silhouette_px_max.max(dist);
            out.silhouette_px_max = out.silhouette_px_max.max(dist);
            if seam {
                e.seam += 1;
            }
            match bp {
                0..=3 => e.building_under_4px += 1,
                4..=15 => e.building_4_to_16px += 1,
                _ => e.building_16px_up += 1,
            }
            if d.z < 0.0 {
                e.over_ground += 1;
            }
            let dist_m = point.map(|p| (p - o).length());
            if let Some(dm) = dist_m {
                if dm * camera.forward().dot(d) < camera.near * 1.01 {
                    e.near_plane += 1;
                }
            }
            let s = sums.entry(class.clone()).or_default();
            s.0 += dist;
            if let Some(ed) = edge_dist {
                s.1 += ed;
                s.2 += 1;
            }
            details.push(PixelDetail {
                px: [x as u32, y as u32],
                class,
                silhouette_px: dist,
                allowed_px: allowed,
                building,
                building_px: bp,
                map: map_i,
                texel,
                point: point.map(|p| p.to_array()),
                distance_m: dist_m,
            });
        }
    }
    let n = out.mismatched.max(1) as f64;
    for (key, c) in out.classes.iter_mut() {
        let s = sums[key];
        c.share = c.pixels as f64 / n;
        c.silhouette_px_mean = s.0 / c.pixels.max(1) as f64;
        c.edge_distance_texels_mean = if s.2 > 0 { s.1 / s.2 as f64 } else { 0.0 };
    }
    out.coverage_error = out.mismatched as f64 / (w * h).max(1) as f64;
    out.hidden_by_ground = hidden_by_ground;
    details.sort_by(|a, b| {
        (b.silhouette_px / b.allowed_px)
            .total_cmp(&(a.silhouette_px / a.allowed_px))
            .then(a.px.cmp(&b.px))
    });
    details.truncate(20);
    out.worst = details;
    out
}

/// The building of the nearest covered pixel of `ids` (ring search up to 8 px).
fn nearest_building(ids: &[u32], w: usize, h: usize, x: usize, y: usize) -> Option<u32> {
    for r in 1..=8i64 {
        let mut best: Option<(i64, u32)> = None;
        for dy in -r..=r {
            for dx in -r..=r {
                if dx.abs() != r && dy.abs() != r {
                    continue;
                }
                let (a, b) = (x as i64 + dx, y as i64 + dy);
                if a < 0 || b < 0 || a >= w as i64 || b >= h as i64 {
                    continue;
                }
                let id = ids[b as usize * w + a as usize];
                let d2 = dx * dx + dy * dy;
                if id != SKY && best.is_none_or(|bb| d2 < bb.0) {
                    best = Some((d2, id));
                }
            }
        }
        if let Some(b) = best {
            return Some(b.1);
        }
    }
    None
}

impl FrameDiagnosis {
    /// The class table as Markdown (share of the mismatched pixels per class).
    pub fn table(&self) -> String {
        let mut s = format!(
            "{}x{}, τ = {} px, {} maps, {} mesh blocks: {} mismatched pixels ({:.3} % of the frame), \
             {} beyond the bound, silhouette px max {:.1}; mesh silhouette pixels {} ({:.2} %); \
             buildings on screen by pixels <4 / 4–15 / ≥16: {:?}; mismatched without the ground \
             but not with it: {}\n\n",
            self.width,
            self.height,
            self.tau_px,
            self.maps,
            self.mesh_blocks,
            self.mismatched,
            100.0 * self.coverage_error,
            self.beyond_bound,
            self.silhouette_px_max,
            self.mesh_silhouette_pixels,
            100.0 * self.mesh_silhouette_pixels as f64 / (self.width * self.height).max(1) as f64,
            self.buildings_by_px,
            self.hidden_by_ground,
        );
        s.push_str("| class | pixels | share | beyond bound | sil px mean / max | seam | bldg <4 / 4–15 / ≥16 px | edge dist (texels) |\n|---|---|---|---|---|---|---|---|\n");
        let mut rows: Vec<(&String, &ClassFigures)> = self.classes.iter().collect();
        rows.sort_by(|a, b| b.1.pixels.cmp(&a.1.pixels).then(a.0.cmp(b.0)));
        for (k, c) in rows {
            s.push_str(&format!(
                "| {k} | {} | {:.1} % | {} | {:.2} / {:.1} | {} | {} / {} / {} | {:.2} |\n",
                c.pixels,
                100.0 * c.share,
                c.beyond_bound,
                c.silhouette_px_mean,
                c.silhouette_px_max,
                c.seam,
                c.building_under_4px,
                c.building_4_to_16px,
                c.building_16px_up,
                c.edge_distance_texels_mean
            ));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, a: f64, z1: f64) -> SourceBuilding {
        SourceBuilding {
            id: crate::city::BuildingId(0),
            source_id: "0".into(),
            block: BlockId(0),
            rings: vec![vec![
                DVec2::new(x0, y0),
                DVec2::new(x0 + a, y0),
                DVec2::new(x0 + a, y0 + a),
                DVec2::new(x0, y0 + a),
            ]],
            ground: 0.0,
            z0: 0.0,
            z1,
            min: DVec2::new(x0, y0),
            max: DVec2::new(x0 + a, y0 + a),
            bridge: false,
            style: Default::default(),
            ring_u: vec![vec![0.0; 4]],
        }
    }

    #[test]
    fn ray_prism_meets_roof_and_wall() {
        let b = square(0.0, 0.0, 10.0, 20.0);
        // Straight down onto the roof.
        let t = ray_prism(&b, DVec3::new(5.0, 5.0, 50.0), DVec3::NEG_Z).unwrap();
        assert!((t - 30.0).abs() < 1e-12);
        // Horizontally into the west wall.
        let t = ray_prism(&b, DVec3::new(-5.0, 5.0, 10.0), DVec3::X).unwrap();
        assert!((t - 5.0).abs() < 1e-12);
        // Over the roof: nothing.
        assert_eq!(ray_prism(&b, DVec3::new(-5.0, 5.0, 21.0), DVec3::X), None);
    }
}
