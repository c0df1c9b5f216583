//! The coverage error of a node's maps (Andujar et al., §5.3, Fig. 4): the node's meshes are
//! drawn orthographically from a test view, the node's impostor is cast through the same pixels
//! (the `f32` caster and colouring the GPU runs, with the three obliques the core-set heuristic
//! picks for that view), and the **coverage error** is the share of the pixels covered by one
//! image and not the other, over the pixels either covers: the paper's pairwise comparison,
//! restricted to the node's own pixels (over the whole image, a node that covers little of its
//! box would look better than it is). The image is `M × M`, so a texel projects
//! to about a pixel, as at the distance a node is first drawn at with τ = 1.
//!
//! Colour is measured apart: the PSNR of the covered pixels, and the share of them off by more
//! than [`COLOUR_TOLERANCE`] in some channel. blockwalk's façades carry procedural windows a
//! storey high and a bay wide, finer than the texels of all but the deepest nodes; any
//! resampling of them (a map texel against a pixel centre elsewhere on the same wall) differs
//! on a share of wall pixels that falls as the maps get finer (on one generated block: about
//! 30 % of wall pixels at M = 64, 11 % at 256, 2.5 % at 1024), so the colour share measures
//! aliasing rather than a wrong surface. The paper's façades are photographs with the same
//! property.
//!
//! Test views: four azimuths between the vote's bins (22.5° + k·90°) at elevations 15° (far
//! nodes seen from the street) and 45°; [`NodeError`] keeps the largest and the mean.

use super::cast::cast_f32;
use super::map::MapFrame;
use super::node::{choose_obliques, shade, NodeError, NodeMaps};
use crate::city::Mesh;
use crate::visibility::oracle::{shade_ids_clip, SKY};
use glam::DVec3;

/// Largest per-channel difference (of 255) of a pixel that counts as reproduced.
pub const COLOUR_TOLERANCE: u8 = 24;

/// The test views' directions (into the scene).
pub fn test_views() -> Vec<DVec3> {
    let mut v = Vec::new();
    for elev in [15.0f64, 45.0] {
        for k in 0..4 {
            let az = (22.5 + 90.0 * k as f64).to_radians();
            let e = elev.to_radians();
            v.push(-DVec3::new(e.cos() * az.cos(), e.cos() * az.sin(), e.sin()));
        }
    }
    v
}

/// What one view measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewError {
    /// Coverage error: pixels covered by one image only, over the pixels either covers.
    pub coverage: f64,
    /// Pixels covered by both whose colour is off by more than [`COLOUR_TOLERANCE`], over the
    /// meshes' covered pixels.
    pub colour: f64,
    /// PSNR of the pixels covered by both, dB (infinite when identical).
    pub psnr_db: f64,
    /// Pixels the meshes cover.
    pub covered: u64,
}

/// The errors of one view (see the module doc).
pub fn view_error(node: &NodeMaps, meshes: &[(u32, &Mesh)], dir: DVec3) -> ViewError {
    let m = node.m();
    let frame = MapFrame::fitting(dir, node.aabb.min, node.aabb.max, m);
    let (ids, colors) = shade_ids_clip(meshes, &frame.clip_from_local(), m, m);
    let levels = node.levels();
    let xf = node.oblique_xforms();
    let chosen = choose_obliques(
        node.obliques.iter().map(|o| o.frame.dir),
        node.obliques.len(),
        frame.dir,
    );
    let (mut covered, mut mismatched, mut off, mut both) = (0u64, 0u64, 0u64, 0u64);
    let mut se = 0.0f64;
    for j in 0..m {
        for i in 0..m {
            let k = (j * m + i) as usize;
            let origin = frame.from_map(f64::from(i) + 0.5, f64::from(j) + 0.5, 0.0);
            let ray = node.tex_ray(origin, frame.dir).to_f32();
            let cast = cast_f32(&levels, m, &ray);
            let mesh = ids.ids[k] != SKY;
            covered += u64::from(mesh);
            match (mesh, cast.hit) {
                (false, None) => {}
                (true, Some(h)) => {
                    both += 1;
                    let c = shade(node, &xf, &chosen, &ray, &h);
                    if (0..3).any(|ch| c[ch].abs_diff(colors[k][ch]) > COLOUR_TOLERANCE) {
                        off += 1;
                    }
                    se += (0..3)
                        .map(|ch| (f64::from(c[ch]) - f64::from(colors[k][ch])).powi(2))
                        .sum::<f64>();
                }
                _ => mismatched += 1,
            }
        }
    }
    let n = covered.max(1) as f64;
    ViewError {
        // The pixels either covers: the mismatched ones and those both cover.
        coverage: mismatched as f64 / (mismatched + both).max(1) as f64,
        colour: off as f64 / n,
        psnr_db: crate::blockmap::compare::psnr_db(se, 3 * both as usize),
        covered,
    }
}

/// The node's errors over [`test_views`].
pub fn measure_node(node: &NodeMaps, meshes: &[(u32, &Mesh)]) -> NodeError {
    let errs: Vec<ViewError> = test_views()
        .iter()
        .map(|&d| view_error(node, meshes, d))
        .collect();
    let k = errs.len().max(1) as f64;
    NodeError {
        coverage_error_max: errs.iter().map(|e| e.coverage).fold(0.0, f64::max),
        coverage_error_mean: errs.iter().map(|e| e.coverage).sum::<f64>() / k,
        colour_mismatch_max: errs.iter().map(|e| e.colour).fold(0.0, f64::max),
        psnr_min_db: errs.iter().map(|e| e.psnr_db).fold(f64::INFINITY, f64::min),
        views: errs.len(),
    }
}
