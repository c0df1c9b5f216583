//! The terrain's measuring twin: along a route, the level-of-detail cut at each τ against the
//! full-resolution terrain, in the same images and with the same measures as the far field
//! (coverage of ids, colour PSNR: [`crate::blockmap::compare`]), with the cut's cost (tiles,
//! triangles, selection time) and its declared error (the largest projected error of a drawn
//! tile, at most τ by construction).

use std::time::Instant;

use serde::Serialize;

use crate::blockmap::compare::image_psnr_db;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::scene::terrain::SceneTerrain;
use crate::scene::Scene;
use crate::terrain::{LevelStats, NodeId, TreeSummary};
use crate::visibility::oracle::{render_ids_with_terrain, shade_with_terrain};

/// One τ of a terrain sweep, over every frame.
#[derive(Clone, Debug, Serialize)]
pub struct TerrainRow {
    /// The projected error asked for, pixels.
    pub tau_px: f64,
    /// Frames measured.
    pub frames: usize,
    /// Tiles drawn per frame (mean).
    pub tiles_mean: f64,
    /// Triangles drawn per frame (mean), skirts included.
    pub triangles_mean: f64,
    /// Triangles of the full-resolution terrain.
    pub full_triangles: usize,
    /// Selection time per frame, milliseconds (mean and largest).
    pub select_ms_mean: f64,
    /// See `select_ms_mean`.
    pub select_ms_max: f64,
    /// The largest projected error of a drawn tile over the frames, pixels (declared: ≤ τ
    /// except at the finest level, whose error is 0).
    pub declared_px_max: f64,
    /// Pixels whose id (terrain, a block, the sky) differs from the full-resolution frame's, as
    /// a share of all pixels (mean over frames, and the largest).
    pub mismatched_mean: f64,
    /// See `mismatched_mean`.
    pub mismatched_max: f64,
    /// Colour PSNR against the full-resolution frame, dB (mean over the frames that differ, and
    /// the smallest; infinite when identical).
    pub psnr_db_mean: f64,
    /// See `psnr_db_mean`.
    pub psnr_db_min: f64,
    /// Frames identical to the full-resolution frame.
    pub identical_frames: usize,
}

/// A terrain sweep: the tree and one row per τ.
#[derive(Clone, Debug, Serialize)]
pub struct TerrainSweep {
    /// The tree: size, depth, memory, build time.
    pub tree: TreeSummary,
    /// Per level: stride, nodes, the declared bound and the largest measured error.
    pub levels: Vec<LevelStats>,
    /// Image size, pixels.
    pub size: (u32, u32),
    /// One row per τ.
    pub rows: Vec<TerrainRow>,
}

/// The tiles of a cut as one mesh (local frame).
pub fn merged(terrain: &SceneTerrain, cut: &[usize]) -> Mesh {
    let mut m = Mesh::default();
    for &k in cut {
        m.append(&terrain.tiles[k]);
    }
    m
}

/// Measures the cut of `scene`'s terrain at each of `taus` on `cameras` against the
/// full-resolution terrain, drawing `size` images with every block. `None` for a flat scene.
pub fn terrain_sweep(
    scene: &Scene,
    cameras: &[Camera],
    taus: &[f64],
    size: (u32, u32),
) -> Option<TerrainSweep> {
    use rayon::prelude::*;
    let t = scene.terrain_lod.as_ref()?;
    let blocks: Vec<_> = scene.draw_meshes().iter().map(|(b, m)| (*b, m)).collect();
    let full = &t.full;
    // The reference frames: full-resolution terrain.
    let reference: Vec<_> = cameras
        .par_iter()
        .map(|c| {
            (
                shade_with_terrain(&blocks, &[full], c, size.0, size.1),
                render_ids_with_terrain(&blocks, full, c, size.0, size.1),
            )
        })
        .collect();
    let rows = taus
        .iter()
        .map(|&tau| {
            let per: Vec<_> = cameras
                .par_iter()
                .zip(&reference)
                .map(|(c, (ref_img, ref_ids))| {
                    let mut ids = Vec::new();
                    let t0 = Instant::now();
                    t.tree.select(c, &t.frame, size.1, tau, &mut ids);
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    let declared = ids
                        .iter()
                        .map(|&n: &NodeId| t.tree.projected_error_px(n, c, &t.frame, size.1))
                        .fold(0.0f64, f64::max);
                    let cut: Vec<usize> = ids.iter().map(|n| n.0 as usize).collect();
                    let (tris, _) = t.triangles(&cut);
                    let mesh = merged(t, &cut);
                    let img = shade_with_terrain(&blocks, &[&mesh], c, size.0, size.1);
                    let idb = render_ids_with_terrain(&blocks, &mesh, c, size.0, size.1);
                    let n = (size.0 * size.1) as usize;
                    let mism = idb
                        .ids
                        .iter()
                        .zip(&ref_ids.ids)
                        .filter(|(a, b)| a != b)
                        .count();
                    (
                        cut.len(),
                        tris,
                        ms,
                        declared,
                        mism as f64 / n as f64,
                        image_psnr_db(&img, ref_img),
                    )
                })
                .collect();
            let k = per.len().max(1) as f64;
            let finite: Vec<f64> = per.iter().map(|p| p.5).filter(|v| v.is_finite()).collect();
            TerrainRow {
                tau_px: tau,
                frames: per.len(),
                tiles_mean: per.iter().map(|p| p.0 as f64).sum::<f64>() / k,
                triangles_mean: per.iter().map(|p| p.1 as f64).sum::<f64>() / k,
                full_triangles: full.indices.len() / 3,
                select_ms_mean: per.iter().map(|p| p.2).sum::<f64>() / k,
                select_ms_max: per.iter().map(|p| p.2).fold(0.0, f64::max),
                declared_px_max: per.iter().map(|p| p.3).fold(0.0, f64::max),
                mismatched_mean: per.iter().map(|p| p.4).sum::<f64>() / k,
                mismatched_max: per.iter().map(|p| p.4).fold(0.0, f64::max),
                psnr_db_mean: if finite.is_empty() {
                    f64::INFINITY
                } else {
                    finite.iter().sum::<f64>() / finite.len() as f64
                },
                psnr_db_min: per.iter().map(|p| p.5).fold(f64::INFINITY, f64::min),
                identical_frames: per.len() - finite.len(),
            }
        })
        .collect();
    Some(TerrainSweep {
        tree: t.tree.summary(),
        levels: t.tree.levels(),
        size,
        rows,
    })
}

/// What [`terrain_job`] measures.
#[derive(Clone, Debug)]
pub struct TerrainJob {
    /// The route the frames are sampled on.
    pub route: crate::route::RouteChoice,
    /// Frames along it (at least 1).
    pub frames: usize,
    /// The projected errors to cut at, pixels (each > 0).
    pub taus: Vec<f64>,
    /// Image size, pixels.
    pub size: (u32, u32),
    /// Where to write a frame strip (full-resolution terrain, the cut at `strip_tau`, and the
    /// pixels whose id differs in red), with how many frames.
    pub strip: Option<(std::path::PathBuf, usize)>,
    /// The τ of the strip's middle row.
    pub strip_tau: f64,
}

impl TerrainJob {
    /// Checks the numbers.
    ///
    /// # Errors
    /// [`super::job::JobError::Parameter`] naming the parameter.
    pub fn validate(&self) -> Result<(), super::job::JobError> {
        let bad = |m: String| Err(super::job::JobError::Parameter(m));
        if self.frames == 0 {
            return bad("frames: need at least 1".into());
        }
        if self.taus.is_empty() || self.taus.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
            return bad(format!("tau {:?}: need finite values > 0", self.taus));
        }
        if !(self.strip_tau.is_finite() && self.strip_tau > 0.0) {
            return bad(format!(
                "strip tau {}: need a finite value > 0",
                self.strip_tau
            ));
        }
        if matches!(self.strip, Some((_, 0))) {
            return bad("strip frames: need at least 1".into());
        }
        Ok(())
    }
}

/// The terrain sweep of [`TerrainJob`] over `scene` (`None` for a flat scene), writing the
/// strip when asked.
///
/// # Errors
/// Parameters, the route, or the strip's file.
pub fn terrain_job(
    scene: &Scene,
    job: &TerrainJob,
) -> Result<Option<TerrainSweep>, super::job::JobError> {
    job.validate()?;
    let Some(t) = scene.terrain_lod.as_ref() else {
        return Ok(None);
    };
    let aspect = job.size.0 as f64 / job.size.1 as f64;
    let (route, _) = super::job::resolve_route(&job.route, scene, aspect)?;
    let cameras = route.sample(job.frames);
    let sweep = terrain_sweep(scene, &cameras, &job.taus, job.size);
    if let Some((path, n)) = &job.strip {
        let picks: Vec<Camera> = route.sample(*n);
        let img = strip(scene, t, &picks, job.strip_tau, job.size);
        crate::output::write_png(path, &img).map_err(|e| {
            super::job::JobError::Parameter(format!("writing {}: {e}", path.display()))
        })?;
    }
    Ok(sweep)
}

/// Rows of `cameras`' frames: the full-resolution terrain, the cut at `tau`, and the cut's frame
/// with the pixels whose id differs from the full frame's in red.
pub fn strip(
    scene: &Scene,
    t: &SceneTerrain,
    cameras: &[Camera],
    tau: f64,
    size: (u32, u32),
) -> image::RgbaImage {
    use rayon::prelude::*;
    let blocks: Vec<_> = scene.draw_meshes().iter().map(|(b, m)| (*b, m)).collect();
    let (w, h) = size;
    let cols: Vec<[image::RgbaImage; 3]> = cameras
        .par_iter()
        .map(|c| {
            let full = shade_with_terrain(&blocks, &[&t.full], c, w, h);
            let full_ids = render_ids_with_terrain(&blocks, &t.full, c, w, h);
            let mut ids = Vec::new();
            t.tree.select(c, &t.frame, h, tau, &mut ids);
            let cut: Vec<usize> = ids.iter().map(|n| n.0 as usize).collect();
            let mesh = merged(t, &cut);
            let lod = shade_with_terrain(&blocks, &[&mesh], c, w, h);
            let lod_ids = render_ids_with_terrain(&blocks, &mesh, c, w, h);
            let mut diff = lod.clone();
            for (k, p) in diff.pixels_mut().enumerate() {
                if lod_ids.ids[k] != full_ids.ids[k] {
                    *p = image::Rgba([230, 20, 20, 255]);
                }
            }
            [full, lod, diff]
        })
        .collect();
    let gap = 4;
    let n = cols.len() as u32;
    let mut out = image::RgbaImage::from_pixel(
        n * w + n.saturating_sub(1) * gap,
        3 * h + 2 * gap,
        image::Rgba([255, 255, 255, 255]),
    );
    for (i, c) in cols.iter().enumerate() {
        for (r, img) in c.iter().enumerate() {
            image::imageops::replace(
                &mut out,
                img,
                (i as u32 * (w + gap)) as i64,
                (r as u32 * (h + gap)) as i64,
            );
        }
    }
    out
}
