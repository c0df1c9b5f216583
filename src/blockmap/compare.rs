//! A ray-cast image of one map against the oracle's image of the same buildings' meshes
//! (BLOCKMAPS.md D.3), from views where the projected error is at most one pixel.
//!
//! - **Coverage error** (Andujar et al.'s measure): the share of pixels where one image shows a
//!   building and the other does not.
//! - **The screen-space bound**: every mismatched pixel must lie within `1 px + e_px/cos²θ` of a
//!   silhouette pixel of the image that does not cover it (`θ` the pixel's angle off the
//!   optical axis, BLOCKMAPS.md A.4-12; `e_px` Cignoni et al., §3.3 with the distance to the nearest
//!   point of the map's bounding sphere). Derivation, with `r = e_px/cos²θ` the largest image
//!   shift of a world displacement of ε seen from at least the sphere's distance:
//!   - the map covers pixel `p` and the mesh does not: the map's hit `P` lies within ε of the
//!     original surface (the 3D point error below checks it); where that nearest point `O` is on
//!     a prism, the mesh covers `O`'s image point, which lies within `r` of `p`, so the mesh
//!     image changes from uncovered to covered within `r` of `p`: a *mesh* silhouette;
//!   - the mesh covers `p` and the map does not: the mesh's hit `Q` lies within ε of the map's
//!     surface; where that nearest point `M` is on a map prism, the *map* image changes from
//!     uncovered to covered within `r`: a *map* silhouette. (A first version measured only mesh
//!     silhouettes and so flagged, on Helsinki, a roof point 0.15 m inside a texel whose centre
//!     falls in a courtyard: the map shows the courtyard one texel wider, its silhouette is next
//!     to the pixel, the mesh's lies 3 px away.)
//!   - where the nearest point is on the ground instead (a feature lower than ε, or thinner
//!     than a texel and dropped), the feature is within its own projected size of its own
//!     silhouette, and it is reported as a thin feature by `error`.
//!
//!   The `1 px` is the sampling: silhouettes are found between pixel centres.
//! - **3D point error**: the f64 twin's hit point of every covered pixel lies within the map's
//!   declared ε of the original surface.
//! - **Colour PSNR** (RGB, dB) of the two lit images, both shaded by [`super::colors`].

use super::cast::{cast_f32, cast_f64, surface, CastOptions, Hit};
use super::colors;
use super::error::BuildingGrid;
use super::layout::BlockMap;
use super::source::Source;
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::oracle::{render_ids, SKY};
use glam::{DVec2, DVec3, DVec4};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// The figures of one view.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ViewCompare {
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Projected ε at the image centre, pixels.
    pub eps_px: f64,
    /// Pixels covered by the mesh image.
    pub mesh_pixels: usize,
    /// Pixels covered by the ray-cast image.
    pub map_pixels: usize,
    /// Pixels whose coverage differs.
    pub mismatched: usize,
    /// `mismatched / (width·height)` (Andujar et al.'s coverage error).
    pub coverage_error: f64,
    /// `mismatched / |mesh ∪ map pixels|`: the same count against the pixels either image
    /// covers, a stricter figure when the map is small on screen.
    pub coverage_error_of_union: f64,
    /// Mismatched pixels farther than `1 + e_px/cos²θ` from the silhouette they are measured
    /// against (see [`ViewCompare::worst_mismatch_ratio`]), not counting
    /// [`ViewCompare::beyond_bound_thin`].
    pub beyond_bound: usize,
    /// Mismatched pixels beyond the bound that show a building the map reports (a thin
    /// feature: narrower than a texel, or raised; or a building no texel holds) and lie within
    /// the bound of that building's own mesh silhouette: the error the map declares for them
    /// (module doc, last case), counted apart and never hidden.
    pub beyond_bound_thin: usize,
    /// Mismatched pixels beyond the bound at pixel spacing but within it at quarter-pixel
    /// spacing (a feature smaller than a pixel that one image's pixel centres missed), or map
    /// pixels whose hit point lies within ε of the original surface (the mesh's exact image
    /// then covers a point within `e_px` of the pixel: a building narrower than a quarter
    /// pixel, which a map with footprint edges draws and the mesh's samples miss): not
    /// violations, counted apart.
    pub beyond_bound_subpixel: usize,
    /// Largest distance of a mismatched pixel to the nearest silhouette pixel of the image that
    /// does not cover it (the mesh image's where only the map covers it, the map image's where
    /// only the mesh covers it), in units of
    /// its allowed distance `1 + e_px/cos²θ` (≤ 1 when the bound holds).
    pub worst_mismatch_ratio: f64,
    /// The pixel `(x, y)` of [`ViewCompare::worst_mismatch_ratio`].
    pub worst_mismatch_px: [u32; 2],
    /// Hit points farther than ε from the original surface (f64 twin).
    pub point_violations: usize,
    /// Largest hit-point distance to the original surface, metres.
    pub point_error_max_m: f64,
    /// Colour PSNR, dB (infinite when identical).
    pub psnr_db: f64,
    /// Mean grid cells visited per ray (f32 cast).
    pub mean_steps: f64,
}

/// A random view of `map` at a distance where its projected ε is `eps_px_target` pixels or
/// less: looking at the box centre from azimuth `az` and elevation `el` (radians).
pub fn view_at(map: &BlockMap, az: f64, el: f64, height_px: u32, eps_px_target: f64) -> Camera {
    let b = map.aabb();
    let c = b.center();
    let r = b.extent().length() * 0.5;
    let mut cam = Camera::new(DVec3::ZERO, 0.0, 0.0);
    let eps = map.meta.eps_m;
    // e_px = ε·H / (2·d·tan(fov/2)) with d the distance to the sphere's nearest point (Cignoni et al.
    // §3.3): choose d for the target, then stand at d + r from the centre.
    let d = eps * height_px as f64 / (2.0 * (0.5 * cam.fov_y).tan() * eps_px_target);
    let dist = d + r;
    let dir = DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
    let eye = c + dir * dist;
    cam = Camera::looking_at(eye, c);
    cam.near = (d * 0.5).max(0.5);
    cam.far = dist + 2.0 * r + 10.0;
    cam
}

/// Seeded random views of `map` ([`view_at`]), elevations 10°–70°.
pub fn random_views(map: &BlockMap, n: usize, seed: u64, height_px: u32) -> Vec<Camera> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let az = rng.random_range(0.0..std::f64::consts::TAU);
            let el = rng.random_range(10f64..70.0).to_radians();
            view_at(map, az, el, height_px, 1.0)
        })
        .collect()
}

/// World ray through the centre of pixel `(x, y)` (row 0 at the top).
pub fn pixel_ray(cam: &Camera, x: u32, y: u32, w: u32, h: u32) -> (DVec3, DVec3) {
    image_ray(cam, x as f64 + 0.5, y as f64 + 0.5, w, h)
}

/// World ray through the image point `(px, py)` in pixel units (the centre of pixel `(x, y)`
/// is `(x + ½, y + ½)`, row 0 at the top).
pub fn image_ray(cam: &Camera, px: f64, py: f64, w: u32, h: u32) -> (DVec3, DVec3) {
    image_ray_with(cam, &cam.clip_from_world().inverse(), px, py, w, h)
}

/// [`image_ray`] with the inverse of `cam.clip_from_world()` computed once by the caller
/// (`inv`), for many rays of one camera.
pub(crate) fn image_ray_with(
    cam: &Camera,
    inv: &glam::DMat4,
    px: f64,
    py: f64,
    w: u32,
    h: u32,
) -> (DVec3, DVec3) {
    let nx = px / w as f64 * 2.0 - 1.0;
    let ny = 1.0 - py / h as f64 * 2.0;
    let p = |z: f64| {
        let q = inv * DVec4::new(nx, ny, z, 1.0);
        q.truncate() / q.w
    };
    let a = p(0.0);
    let b = p(1.0);
    (cam.position, (b - a).normalize())
}

/// Compares the ray-cast image of `map` with the oracle's image of its buildings' meshes from
/// `cam` (see the module doc).
pub fn compare_view(
    map: &BlockMap,
    source: &Source,
    buildings: &[u32],
    cam: &Camera,
    width: u32,
    height: u32,
) -> ViewCompare {
    compare_view_with_thin(map, source, buildings, &[], cam, width, height)
}

/// [`compare_view`] knowing the buildings the map reports (`thin`, indices into
/// `City::buildings`: [`super::ErrorReport::thin`] and [`super::BuildStats::dropped_buildings`]):
/// a pixel only the mesh
/// covers, showing one of them, beyond the bound of the map's silhouettes but within it of the
/// mesh's, is counted in [`ViewCompare::beyond_bound_thin`] instead of
/// [`ViewCompare::beyond_bound`].
pub fn compare_view_with_thin(
    map: &BlockMap,
    source: &Source,
    buildings: &[u32],
    thin: &[u32],
    cam: &Camera,
    width: u32,
    height: u32,
) -> ViewCompare {
    let (w, h) = (width as usize, height as usize);
    let pairs: Vec<(BlockId, &Mesh)> = buildings
        .iter()
        .map(|&b| (BlockId(b), &source.meshes[b as usize]))
        .collect();
    let ids = render_ids(&pairs, cam, width, height);
    let inv = cam.clip_from_world().inverse();
    let grid = BuildingGrid::new(map, source, buildings);
    let mut scratch = super::error::Scratch::default();
    let eps = map.meta.eps_m;
    let sphere_c = map.aabb().center();
    let sphere_r = map.aabb().extent().length() * 0.5;
    let d = ((cam.position - sphere_c).length() - sphere_r).max(cam.near);
    let f = height as f64 / (2.0 * (0.5 * cam.fov_y).tan());
    let eps_px = eps * f / d;
    let mut out = ViewCompare {
        width,
        height,
        eps_px,
        ..ViewCompare::default()
    };
    let mut mesh_cov = vec![false; w * h];
    let mut map_cov = vec![false; w * h];
    // Per pixel, the f64 hit point's distance to the original surface (∞ without a hit).
    let mut hit_err = vec![f64::INFINITY; w * h];
    let mut se = 0f64;
    let mut steps = 0u64;
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            // Mesh pixel: lit colour from the building and the surface at the unprojected depth.
            let mut mesh_rgb = [0u8; 3];
            if ids.ids[k] != SKY {
                mesh_cov[k] = true;
                out.mesh_pixels += 1;
                let b = ids.ids[k] as usize;
                let nx = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
                let ny = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
                let q = inv * DVec4::new(nx, ny, ids.depth[k] as f64, 1.0);
                let p = q.truncate() / q.w;
                if let Some(sb) = source.buildings[b].as_ref() {
                    let tol = 0.02 * (1.0 + sb.z1);
                    let (base, n) = if (p.z - sb.z1).abs() < tol {
                        (colors::roof_rgb(&sb.style), glam::Vec3::Z)
                    } else if sb.z0 > 0.0 && (p.z - sb.z0).abs() < tol {
                        (colors::underside_rgb(), glam::Vec3::NEG_Z)
                    } else {
                        let (n, u) = super::build::nearest_facade(sb, p.truncate())
                            .unwrap_or((DVec2::X, 0.0));
                        (
                            colors::facade_rgb(&sb.style, u, p.z as f32),
                            n.extend(0.0).as_vec3(),
                        )
                    };
                    mesh_rgb = colors::lit(colors::to_bytes(base), n);
                }
            }
            // Map pixel: the GPU's f32 cast for coverage and colour, the f64 twin for the point.
            let (o, dir) = pixel_ray(cam, x as u32, y as u32, width, height);
            let ray = map.tex_ray(o, dir);
            let c32 = cast_f32(map, &ray.to_f32(), &CastOptions::default());
            steps += c32.steps as u64;
            let mut map_rgb = [0u8; 3];
            if c32.hit != Hit::Miss {
                map_cov[k] = true;
                out.map_pixels += 1;
                if let Some(s) = surface(map, &ray, &c32.hit) {
                    map_rgb = colors::lit(s.color, s.normal);
                }
            }
            let c64 = cast_f64(map, &ray, &CastOptions::default());
            if let Some(t) = c64.hit.t() {
                let p = o + dir * t;
                let e = grid.surface_distance(p, &mut scratch);
                hit_err[k] = e;
                out.point_error_max_m = out.point_error_max_m.max(e);
                if e > eps * (1.0 + 1e-9) + 1e-6 {
                    out.point_violations += 1;
                }
            }
            for ch in 0..3 {
                let dv = mesh_rgb[ch] as f64 - map_rgb[ch] as f64;
                se += dv * dv;
            }
        }
    }
    out.mean_steps = steps as f64 / (w * h) as f64;
    out.psnr_db = psnr_db(se, 3 * w * h);
    // Silhouette pixels of each image: covered with an uncovered 4-neighbour, or the reverse.
    // Which one a mismatched pixel is measured against (see the module doc): a pixel the map
    // covers and the mesh does not must lie near a silhouette of the mesh image, a pixel the
    // mesh covers and the map does not near one of the map image.
    let (mesh_sil, map_sil) = (
        silhouette_pixels(&mesh_cov, w, h),
        silhouette_pixels(&map_cov, w, h),
    );
    let fy = (0.5 * cam.fov_y).tan();
    let fx = fy * cam.aspect;
    let mut fine_ids: Option<crate::visibility::oracle::IdBuffer> = None;
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if mesh_cov[k] == map_cov[k] {
                continue;
            }
            out.mismatched += 1;
            let nx = ((x as f64 + 0.5) / w as f64 * 2.0 - 1.0) * fx;
            let ny = (1.0 - (y as f64 + 0.5) / h as f64 * 2.0) * fy;
            let cos2 = 1.0 / (1.0 + nx * nx + ny * ny);
            let r = 1.0 + eps_px / cos2;
            let r2 = r * r;
            // The map shows a building the mesh does not: a mesh silhouette is near; the
            // mesh shows one the map does not: a map silhouette is near.
            let sil = if map_cov[k] { &mesh_sil } else { &map_sil };
            let nearest = nearest_distance(sil, x as i64, y as i64);
            let nearest2 = nearest * nearest;
            // A feature smaller than a pixel can fall between the pixel centres of one image
            // and be caught by a centre in the other: the bound is about the images, not their
            // samples, so a pixel beyond it gets a second look at quarter-pixel spacing for
            // coverage of the other image within `r`.
            let mut ratio = nearest / r;
            if nearest2 > r2 {
                let found = if map_cov[k] {
                    let fine = fine_ids
                        .get_or_insert_with(|| render_ids(&pairs, cam, width * SUB, height * SUB));
                    mesh_covered_within(fine, x, y, r).or_else(|| {
                        // The hit point is within ε of the original surface: the original
                        // point projects within e_px·(e/ε) of this pixel (ε projects to at
                        // most e_px at the map's nearest distance).
                        let e = hit_err[k];
                        (e <= eps * (1.0 + 1e-9) + 1e-6).then(|| eps_px * e / eps.max(1e-12))
                    })
                } else {
                    map_covered_within(map, cam, width, height, x, y, r)
                };
                if let Some(dist) = found {
                    out.beyond_bound_subpixel += 1;
                    ratio = dist / r;
                }
            }
            if ratio > out.worst_mismatch_ratio {
                out.worst_mismatch_ratio = ratio;
                out.worst_mismatch_px = [x as u32, y as u32];
            }
            if ratio > 1.0 {
                let own = !map_cov[k] && thin.contains(&ids.ids[k]) && {
                    nearest_distance(&mesh_sil, x as i64, y as i64) <= r
                };
                if own {
                    out.beyond_bound_thin += 1;
                } else {
                    out.beyond_bound += 1;
                }
            }
        }
    }
    out.coverage_error = out.mismatched as f64 / (w * h) as f64;
    let union = mesh_cov
        .iter()
        .zip(&map_cov)
        .filter(|(a, b)| **a || **b)
        .count();
    out.coverage_error_of_union = out.mismatched as f64 / union.max(1) as f64;
    out
}

/// Colour PSNR in dB of a summed squared error `se` over `samples` 8-bit samples (infinite when
/// identical).
pub fn psnr_db(se: f64, samples: usize) -> f64 {
    let mse = se / samples.max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// Colour PSNR in dB between two images of the same size, over their RGB samples (alpha
/// ignored; infinite when identical).
pub fn image_psnr_db(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let se: f64 = a
        .pixels()
        .zip(b.pixels())
        .map(|(p, q)| {
            (0..3)
                .map(|k| (p.0[k] as f64 - q.0[k] as f64).powi(2))
                .sum::<f64>()
        })
        .sum();
    psnr_db(se, 3 * a.width() as usize * a.height() as usize)
}

/// Silhouette pixels `(x, y)` of a coverage mask `w × h` (row-major): covered with an uncovered
/// 4-neighbour, or the reverse.
pub fn silhouette_pixels(cov: &[bool], w: usize, h: usize) -> Vec<(i64, i64)> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let c = cov[y * w + x];
            [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                .iter()
                .any(|(dx, dy)| {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    nx >= 0
                        && ny >= 0
                        && (nx as usize) < w
                        && (ny as usize) < h
                        && cov[ny as usize * w + nx as usize] != c
                })
        })
        .map(|(x, y)| (x as i64, y as i64))
        .collect()
}

/// Distance in pixels from `(x, y)` to the nearest of `sil` (infinite when `sil` is empty).
pub fn nearest_distance(sil: &[(i64, i64)], x: i64, y: i64) -> f64 {
    sil.iter()
        .map(|&(sx, sy)| {
            let (dx, dy) = ((sx - x) as f64, (sy - y) as f64);
            dx * dx + dy * dy
        })
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

/// Distance from `(x, y)` to the nearest set pixel of `mask` (`w × h`), searching square rings
/// of growing radius (the first hit at ring `r` bounds the answer by `r·√2`, so rings up to
/// that bound are searched too); none when the mask is empty. The same distance as
/// [`nearest_distance`] over the mask's pixels, in time proportional to the answer's square
/// instead of the silhouette's length.
pub fn nearest_in_mask(mask: &[bool], w: usize, h: usize, x: i64, y: i64) -> Option<f64> {
    let (wi, hi) = (w as i64, h as i64);
    let rmax = wi.max(hi);
    let mut best2: Option<i64> = None;
    for r in 0..=rmax {
        if let Some(b) = best2 {
            if r * r > b {
                break;
            }
        }
        let mut visit = |px: i64, py: i64| {
            if px >= 0 && py >= 0 && px < wi && py < hi && mask[(py * wi + px) as usize] {
                let d2 = (px - x) * (px - x) + (py - y) * (py - y);
                if best2.is_none_or(|b| d2 < b) {
                    best2 = Some(d2);
                }
            }
        };
        if r == 0 {
            visit(x, y);
            continue;
        }
        for d in -r..=r {
            visit(x + d, y - r);
            visit(x + d, y + r);
        }
        for d in -r + 1..r {
            visit(x - r, y + d);
            visit(x + r, y + d);
        }
    }
    best2.map(|b| (b as f64).sqrt())
}

/// Sub-samples per pixel side of the second look at pixels beyond the bound.
pub(crate) const SUB: u32 = 4;

/// Offsets (in pixels) of the quarter-pixel lattice within `r` of a pixel centre, with their
/// distance.
pub(crate) fn lattice_within(r: f64) -> impl Iterator<Item = (f64, f64, f64)> {
    let n = (r * SUB as f64).ceil() as i64;
    (-n..=n).flat_map(move |j| {
        (-n..=n).filter_map(move |i| {
            let (dx, dy) = (i as f64 / SUB as f64, j as f64 / SUB as f64);
            let d = (dx * dx + dy * dy).sqrt();
            (d <= r).then_some((dx, dy, d))
        })
    })
}

/// Distance to the nearest point of the quarter-pixel lattice within `r` of pixel `(x, y)`'s
/// centre that the map covers (its f32 cast hits), if any.
fn map_covered_within(
    map: &BlockMap,
    cam: &Camera,
    width: u32,
    height: u32,
    x: usize,
    y: usize,
    r: f64,
) -> Option<f64> {
    lattice_within(r)
        .filter(|&(dx, dy, _)| {
            let (o, dir) = image_ray(cam, x as f64 + 0.5 + dx, y as f64 + 0.5 + dy, width, height);
            cast_f32(map, &map.tex_ray(o, dir).to_f32(), &CastOptions::default()).hit != Hit::Miss
        })
        .map(|(_, _, d)| d)
        .fold(None, |a: Option<f64>, d| Some(a.map_or(d, |a| a.min(d))))
}

/// Distance to the nearest sub-pixel centre within `r` of pixel `(x, y)`'s centre that the
/// mesh image at [`SUB`]× resolution (`fine`) covers, if any.
fn mesh_covered_within(
    fine: &crate::visibility::oracle::IdBuffer,
    x: usize,
    y: usize,
    r: f64,
) -> Option<f64> {
    let (fw, fh) = (fine.width as usize, fine.height as usize);
    let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
    let lo = |c: f64| (((c - r) * SUB as f64).floor().max(0.0)) as usize;
    let hi = |c: f64, n: usize| ((((c + r) * SUB as f64).ceil()) as usize).min(n);
    let mut best: Option<f64> = None;
    for fy in lo(cy)..hi(cy, fh) {
        for fx in lo(cx)..hi(cx, fw) {
            if fine.ids[fy * fw + fx] == SKY {
                continue;
            }
            let (px, py) = (
                (fx as f64 + 0.5) / SUB as f64,
                (fy as f64 + 0.5) / SUB as f64,
            );
            let d = ((px - cx).powi(2) + (py - cy).powi(2)).sqrt();
            if d <= r {
                best = Some(best.map_or(d, |b: f64| b.min(d)));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One 10 m texel, 10 m tall, at the centre of a K = 32 map of 320 m.
    fn one_texel_map() -> BlockMap {
        let mut m = BlockMap::empty(32, DVec3::new(0.0, 0.0, 0.0), 320.0, 10.0).unwrap();
        m.texel_mut(16, 16)[0] = 255;
        m
    }

    fn hits(map: &BlockMap, cam: &Camera, w: u32, h: u32) -> usize {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let (o, d) = pixel_ray(cam, x, y, w, h);
                cast_f32(map, &map.tex_ray(o, d).to_f32(), &CastOptions::default()).hit != Hit::Miss
            })
            .count()
    }

    #[test]
    fn a_prism_between_pixel_centres_is_found_at_quarter_pixels() {
        let map = one_texel_map();
        let (w, h) = (64u32, 36u32);
        // Straight down from 600 m a pixel is 19.2 m and the texel 0.52 px wide (two quarter-
        // pixel steps); shift the eye until no pixel centre meets it, so only the second look
        // can.
        let mut tried = 0;
        let mut checked = 0;
        for q in 0..40 {
            tried += 1;
            let off = q as f64 * 1.7;
            let c = DVec3::new(165.0 + off, 165.0 + 0.6 * off, 0.0);
            let mut cam = Camera::looking_at(c + DVec3::new(0.0, 0.0, 600.0), c);
            cam.near = 10.0;
            cam.far = 1000.0;
            if hits(&map, &cam, w, h) > 0 {
                continue;
            }
            checked += 1;
            // The pixel whose centre is nearest the texel's image.
            let clip = cam.clip_from_world() * DVec3::new(165.0, 165.0, 10.0).extend(1.0);
            let ndc = clip.truncate() / clip.w;
            let px = (ndc.x + 1.0) * 0.5 * w as f64;
            let py = (1.0 - ndc.y) * 0.5 * h as f64;
            let (x, y) = (px.floor() as usize, py.floor() as usize);
            let found = map_covered_within(&map, &cam, w, h, x, y, 1.0);
            let d =
                found.expect("a texel 0.52 px wide lies within one pixel of the nearest centre");
            assert!(d <= 1.0, "{d}");
            // Far from it, nothing is found: the search is local.
            assert_eq!(
                map_covered_within(&map, &cam, w, h, (x + 10) % w as usize, y, 1.0),
                None
            );
        }
        assert!(
            checked > 0,
            "no eye of {tried} put the texel between pixel centres"
        );
    }

    #[test]
    fn the_fine_mesh_image_is_searched_within_the_radius() {
        let (w, h) = (8usize, 6usize);
        let (fw, fh) = (w * SUB as usize, h * SUB as usize);
        let mut fine = crate::visibility::oracle::IdBuffer {
            width: fw as u32,
            height: fh as u32,
            ids: vec![SKY; fw * fh],
            depth: vec![1.0; fw * fh],
        };
        assert_eq!(mesh_covered_within(&fine, 3, 2, 2.0), None);
        // Sub-pixel (17, 9): centre (4.375, 2.375) px, 0.875 px right of pixel (3, 2)'s
        // centre (3.5, 2.5) and 0.125 px up.
        fine.ids[9 * fw + 17] = 7;
        let d = mesh_covered_within(&fine, 3, 2, 2.0).unwrap();
        assert!(
            (d - (0.875f64.powi(2) + 0.125f64.powi(2)).sqrt()).abs() < 1e-12,
            "{d}"
        );
        assert_eq!(mesh_covered_within(&fine, 3, 2, 0.5), None);
        assert_eq!(mesh_covered_within(&fine, 0, 5, 2.0), None);
    }

    #[test]
    fn the_quarter_pixel_lattice_is_the_disc() {
        let pts: Vec<_> = lattice_within(1.0).collect();
        assert!(pts.iter().all(|p| p.2 <= 1.0));
        assert!(pts.contains(&(0.0, 0.0, 0.0)));
        // Integer points (i, j) with i² + j² ≤ 16, counted by hand: 49.
        assert_eq!(pts.len(), 49);
    }
}
