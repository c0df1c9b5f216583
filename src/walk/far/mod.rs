//! The far field in a walk: per frame, the reference structure's blocks are drawn a second time
//! as a hybrid frame, near meshes plus far nodes chosen by [`crate::blockmap::Selector`]
//! (Cignoni et al., §4–5) through the far-field interface ([`FarField`], [`field`]), and, with a
//! reference, compared with the mesh-only frame of the same camera and culling mode.
//!
//! The image measures work on the frames' own pictures, whatever drew them:
//! - **coverage**: a pixel shows a building when it differs from the same camera's frame drawn
//!   with no block (ground and sky only); the coverage error is the share of pixels whose
//!   coverage differs between the mesh-only and the hybrid frame (the measure of Andujar et
//!   al.);
//! - **colour PSNR** (RGB, dB) of the hybrid frame against the mesh-only frame;
//! - **silhouette distance**: the largest distance, in pixels, of a coverage-mismatched pixel
//!   from a silhouette pixel of the frame that does not cover it (a pixel only the hybrid covers:
//!   the mesh frame's; only the mesh covers: the hybrid frame's), the form of BLOCKMAPS.md D.3-2
//!   that `blockmap::compare` derives (≤ 1 px + τ/cos²θ where the bound holds). This raw figure
//!   knows neither τ nor θ nor the geometry; with the city's buildings ([`FarSetup::source`])
//!   each mismatched pixel is also checked against its own allowed distance, with a second look
//!   at quarter-pixel spacing for sub-pixel features and the maps' declared thin features
//!   counted apart ([`super::bound`]): the ratio, violations, sub-pixel and thin counts;
//! - **popping**: between the hybrid frame and the same camera drawn with the previous frame's
//!   decisions kept ([`crate::blockmap::Selector::select_frozen`]), so that only what the
//!   selection changed differs: pixels whose coverage changes (`popping_px`, the geometric pop)
//!   and pixels whose colour changes at all (`popping_colour_px`; a map's colours differ a little
//!   from the meshes' nearly everywhere, so this counts every pixel of a switched node).

pub mod field;
pub mod relief;
mod summary;

pub use field::{
    BlockMapsOptions, BuildFar, FarBuildSummary, FarField, FarGpu, PixelBound, SilhouetteBound,
};
pub use summary::FarSummary;

use super::CullMode;
pub use crate::blockmap::compare::nearest_in_mask;
use crate::blockmap::compare::silhouette_pixels;
use crate::blockmap::{SelectOptions, SelectStats, Selection};

/// Pixels whose coverage differs between two frames of one camera (`background`: no block).
pub fn coverage_changed(
    a: &image::RgbaImage,
    b: &image::RgbaImage,
    background: &image::RgbaImage,
) -> u64 {
    coverage(a, background)
        .iter()
        .zip(coverage(b, background))
        .filter(|(p, q)| **p != *q)
        .count() as u64
}
use serde::Serialize;

/// Whether a walk draws a far field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FarMode {
    /// Meshes only.
    #[default]
    None,
    /// Near meshes and far BlockMaps.
    Blockmaps,
    /// Near meshes and far relief impostors.
    Relief,
}

crate::choice::choices!(FarMode, "far-field mode",
    None => "none", "Meshes only";
    Blockmaps => "blockmaps", "Near meshes and far BlockMaps";
    Relief => "relief", "Near meshes and far multi-level relief impostors";
);

/// The far field of a walk and how the walk uses it.
#[derive(Clone, Copy)]
pub struct FarSetup<'a> {
    /// The representation (its node indices are what the renderer was built with).
    pub field: &'a dyn FarField,
    /// τ and hysteresis.
    pub select: SelectOptions,
    /// Compare every hybrid frame with the mesh-only frame (draws 3–4 frames per camera).
    pub reference: bool,
    /// Leave the far field out when the scene does not need it: when no node qualifies on any
    /// frame of the route, or when, over the first [`FarSetup::probe_frames`] frames timed on
    /// the GPU, hybrid frames draw no faster than mesh-only ones.
    pub leave_out: bool,
    /// Frames measured before the timing decision.
    pub probe_frames: usize,
    /// The city's buildings as exact prisms (`blockmap::Source::new` over the scene's city,
    /// layout and building meshes), to check the silhouette bound of each referenced frame with
    /// the exact geometry ([`super::bound`]); without it the bound's figures are none and the
    /// walk says so.
    pub source: Option<&'a crate::blockmap::Source<'a>>,
}

impl std::fmt::Debug for FarSetup<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FarSetup")
            .field("field", &self.field.name())
            .field("nodes", &self.field.len())
            .field("select", &self.select)
            .field("reference", &self.reference)
            .field("leave_out", &self.leave_out)
            .field("probe_frames", &self.probe_frames)
            .field("source", &self.source.is_some())
            .finish()
    }
}

impl<'a> FarSetup<'a> {
    /// τ = 1 px, default hysteresis, no reference, leave-out on, 8 probe frames, no geometry.
    pub fn new(field: &'a dyn FarField) -> Self {
        Self {
            field,
            select: SelectOptions::default(),
            reference: false,
            leave_out: true,
            probe_frames: 8,
            source: None,
        }
    }
}

/// One hybrid frame.
#[derive(Clone, Debug, Serialize)]
pub struct FarRecord {
    /// Frame number along the route.
    pub frame: usize,
    /// The culling mode (the cull map prunes nodes in `frustum+occlusion`).
    pub mode: CullMode,
    /// Selection time (with the cull map's construction in occlusion mode), seconds.
    pub select_s: f64,
    /// Drawing time of the hybrid frame, seconds.
    pub render_s: Option<f64>,
    /// Selection + drawing, seconds.
    pub frame_s: f64,
    /// The mesh-only frame of the same camera and mode (reference structure), seconds.
    pub mesh_frame_s: f64,
    /// Seconds per pass of the hybrid draw, when the renderer measures them.
    pub passes: Vec<(String, f64)>,
    /// Blocks drawn as meshes.
    pub mesh_blocks: usize,
    /// Their triangles.
    pub mesh_triangles: u64,
    /// Maps drawn.
    pub far_nodes: usize,
    /// Blocks inside the drawn maps.
    pub far_blocks: u64,
    /// Pixels the maps covered, when the renderer counts them.
    pub far_pixels: Option<u64>,
    /// Selection counters.
    pub stats: SelectStats,
    /// Image measures, with a reference.
    pub image: Option<ImageError>,
    /// True when `render_s` comes from GPU timestamps.
    pub gpu_time: bool,
}

/// The hybrid frame against the mesh-only frame (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ImageError {
    /// Share of pixels whose coverage differs.
    pub coverage_error: f64,
    /// Colour PSNR, dB (infinite when identical).
    pub psnr_db: f64,
    /// Largest distance of a coverage-mismatched pixel from a mesh silhouette, pixels (0 when
    /// nothing mismatches): the raw, image-only figure.
    pub silhouette_px: f64,
    /// Largest distance over allowed distance `1 + τ/cos²θ` of a mismatched pixel after the
    /// second look with the exact geometry ([`super::bound`]; ≤ 1 where the bound holds); none
    /// when the frame was measured without the geometry.
    pub silhouette_ratio_max: Option<f64>,
    /// Mismatched pixels beyond the bound after the second look (violations); none without the
    /// geometry.
    pub beyond_bound: Option<u64>,
    /// Pixels beyond the bound at pixel spacing that the second look settled (sub-pixel
    /// features); none without the geometry.
    pub beyond_bound_subpixel: Option<u64>,
    /// Pixels beyond the bound that show a building a drawn map declares thin or dropped, within
    /// the bound of the mesh frame's silhouette; none without the geometry.
    pub beyond_bound_thin: Option<u64>,
    /// The pixel `(x, y)` of [`ImageError::silhouette_ratio_max`].
    pub worst_bound_px: Option<[u32; 2]>,
    /// Pixels whose coverage changed only because the selection changed.
    pub popping_px: u64,
    /// Pixels whose colour changed only because the selection changed.
    pub popping_colour_px: u64,
}

/// Whether the far field ran, and why not.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FarDecision {
    /// The representation ("BlockMaps", "relief impostors").
    pub representation: String,
    /// True when hybrid frames were drawn (for the whole route unless `left_out_after`).
    pub used: bool,
    /// Why it was left out, in words.
    pub reason: Option<String>,
    /// The frame after which it was left out (after the timing probe).
    pub left_out_after: Option<usize>,
}

/// Whether occlusion culling paid for itself on the route (reference structure).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OcclusionDecision {
    /// Mean seconds per frame with frustum culling only.
    pub frustum_s: f64,
    /// Mean seconds per frame with frustum and occlusion culling.
    pub occlusion_s: f64,
    /// Mean blocks per frame the occlusion test dropped.
    pub blocks_dropped: f64,
    /// True when occlusion culling made frames faster on this route.
    pub saves: bool,
    /// The decision in words.
    pub note: String,
}

/// Pixels of `img` that show something other than `background` (the same camera with no block).
pub fn coverage(img: &image::RgbaImage, background: &image::RgbaImage) -> Vec<bool> {
    img.pixels()
        .zip(background.pixels())
        .map(|(a, b)| a.0[..3] != b.0[..3])
        .collect()
}

/// Pixels whose RGB differs.
pub fn changed_pixels(a: &image::RgbaImage, b: &image::RgbaImage) -> u64 {
    a.pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0[..3] != q.0[..3])
        .count() as u64
}

/// Coverage error, PSNR and silhouette distance of `hybrid` against `mesh`, both of the same
/// camera, `background` the frame with no block (popping is filled in by the walk). Without the
/// geometry: the bound's fields are none ([`image_error_with_bound`] fills them).
pub fn image_error(
    mesh: &image::RgbaImage,
    hybrid: &image::RgbaImage,
    background: &image::RgbaImage,
) -> ImageError {
    image_error_with_bound(mesh, hybrid, background, None)
}

/// [`image_error`], and with `bound` (the frame's exact geometry, selection, camera and τ) the
/// bound `1 + τ/cos²θ` checked per mismatched pixel with the second look of [`super::bound`].
pub fn image_error_with_bound(
    mesh: &image::RgbaImage,
    hybrid: &image::RgbaImage,
    background: &image::RgbaImage,
    bound: Option<&dyn PixelBound>,
) -> ImageError {
    let (w, h) = (mesh.width() as usize, mesh.height() as usize);
    let mc = coverage(mesh, background);
    let hc = coverage(hybrid, background);
    let mask = |cov: &[bool]| {
        let mut m = vec![false; w * h];
        for (x, y) in silhouette_pixels(cov, w, h) {
            m[y as usize * w + x as usize] = true;
        }
        m
    };
    let (mesh_sil, hybrid_sil) = (mask(&mc), mask(&hc));
    let mut mismatched = 0usize;
    let mut worst: f64 = 0.0;
    let mut listed: Vec<(u32, u32, bool, f64)> = Vec::new();
    for k in 0..w * h {
        if mc[k] != hc[k] {
            mismatched += 1;
            let (x, y) = ((k % w) as i64, (k / w) as i64);
            // As `blockmap::compare` derives the bound: a pixel only the hybrid covers lies
            // near a silhouette of the mesh frame, one only the mesh covers near a silhouette
            // of the hybrid frame. No silhouette at all: the frame's diagonal.
            let sil = if hc[k] { &mesh_sil } else { &hybrid_sil };
            let d =
                nearest_in_mask(sil, w, h, x, y).unwrap_or_else(|| ((w * w + h * h) as f64).sqrt());
            worst = worst.max(d);
            if bound.is_some() {
                listed.push((x as u32, y as u32, hc[k], d));
            }
        }
    }
    let figures = bound.map(|b| b.check(w as u32, h as u32, &listed, &mesh_sil));
    ImageError {
        coverage_error: mismatched as f64 / (w * h).max(1) as f64,
        psnr_db: crate::blockmap::compare::image_psnr_db(mesh, hybrid),
        silhouette_px: worst,
        silhouette_ratio_max: figures.map(|f| f.ratio_max),
        beyond_bound: figures.map(|f| f.beyond_bound),
        beyond_bound_subpixel: figures.map(|f| f.beyond_bound_subpixel),
        beyond_bound_thin: figures.map(|f| f.beyond_bound_thin),
        worst_bound_px: figures.map(|f| f.worst_px),
        popping_px: 0,
        popping_colour_px: 0,
    }
}

/// True when two selections draw the same maps and meshes.
pub fn same_selection(a: &Selection, b: &Selection) -> bool {
    let mut am = a.maps.clone();
    let mut bm = b.maps.clone();
    am.sort_unstable();
    bm.sort_unstable();
    let mut ab = a.meshes.clone();
    let mut bb = b.meshes.clone();
    ab.sort_unstable();
    bb.sort_unstable();
    am == bm && ab == bb
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blockmap::compare::nearest_distance;
    use image::{Rgba, RgbaImage};

    /// A 20×10 frame on a grey background with a red square `[x0, x0 + 4) × [2, 6)`.
    fn frame(x0: u32, colour: [u8; 3]) -> RgbaImage {
        let mut img = RgbaImage::from_pixel(20, 10, Rgba([90, 90, 90, 255]));
        for y in 2..6 {
            for x in x0..x0 + 4 {
                img.put_pixel(x, y, Rgba([colour[0], colour[1], colour[2], 255]));
            }
        }
        img
    }

    #[test]
    fn ring_search_equals_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for _ in 0..200 {
            let (w, h) = (rng.random_range(1..30usize), rng.random_range(1..30usize));
            let fill = rng.random_range(0.0..0.2);
            let mask: Vec<bool> = (0..w * h).map(|_| rng.random_bool(fill)).collect();
            let list: Vec<(i64, i64)> = (0..w * h)
                .filter(|&k| mask[k])
                .map(|k| ((k % w) as i64, (k / w) as i64))
                .collect();
            let (x, y) = (rng.random_range(0..w) as i64, rng.random_range(0..h) as i64);
            let fast = nearest_in_mask(&mask, w, h, x, y);
            if list.is_empty() {
                assert_eq!(fast, None);
            } else {
                assert_eq!(fast, Some(nearest_distance(&list, x, y)));
            }
        }
    }

    #[test]
    fn identical_frames_have_no_error() {
        let bg = RgbaImage::from_pixel(20, 10, Rgba([90, 90, 90, 255]));
        let e = image_error(&frame(5, [200, 0, 0]), &frame(5, [200, 0, 0]), &bg);
        assert_eq!(e.coverage_error, 0.0);
        assert!(e.psnr_db.is_infinite());
        assert_eq!(e.silhouette_px, 0.0);
    }

    #[test]
    fn a_shifted_square_mismatches_next_to_the_silhouette() {
        let bg = RgbaImage::from_pixel(20, 10, Rgba([90, 90, 90, 255]));
        // Shifted by 3 px: columns 5–7 only in the mesh, 9–11 only in the hybrid (8 in both).
        let e = image_error(&frame(5, [200, 0, 0]), &frame(8, [200, 0, 0]), &bg);
        assert!((e.coverage_error - 24.0 / 200.0).abs() < 1e-12, "{e:?}");
        // Column 11 is 2 px from the mesh silhouette (column 9, just right of the square);
        // column 5 lies on it.
        assert!((e.silhouette_px - 2.0).abs() < 1e-12, "{e:?}");
        assert!(e.psnr_db.is_finite());
        // A colour change alone is no coverage error, but lowers the PSNR.
        let c = image_error(&frame(5, [200, 0, 0]), &frame(5, [190, 0, 0]), &bg);
        assert_eq!(c.coverage_error, 0.0);
        assert!(c.psnr_db < 60.0 && c.psnr_db > 20.0, "{c:?}");
        assert_eq!(
            changed_pixels(&frame(5, [200, 0, 0]), &frame(5, [190, 0, 0])),
            16
        );
        // Without the geometry the bound is not judged.
        assert_eq!(e.silhouette_ratio_max, None);
        assert_eq!(e.beyond_bound, None);
    }

    fn record(frame: usize, image: Option<ImageError>) -> FarRecord {
        FarRecord {
            frame,
            mode: CullMode::Frustum,
            select_s: 0.001,
            render_s: Some(0.01),
            frame_s: 0.011,
            mesh_frame_s: 0.02,
            passes: Vec::new(),
            mesh_blocks: 1,
            mesh_triangles: 12,
            far_nodes: 1,
            far_blocks: 1,
            far_pixels: None,
            stats: SelectStats::default(),
            image,
            gpu_time: false,
        }
    }

    #[test]
    fn far_summary_sums_the_bound_and_is_none_without_the_geometry() {
        let checked = |ratio: f64, v: u64, s: u64, t: u64| ImageError {
            silhouette_px: 3.0 * ratio,
            silhouette_ratio_max: Some(ratio),
            beyond_bound: Some(v),
            beyond_bound_subpixel: Some(s),
            beyond_bound_thin: Some(t),
            worst_bound_px: Some([0, 0]),
            ..ImageError::default()
        };
        let d = FarDecision {
            representation: "BlockMaps".into(),
            used: true,
            reason: None,
            left_out_after: None,
        };
        let o = SelectOptions::default();
        let recs = vec![
            record(0, Some(checked(0.5, 0, 3, 1))),
            record(1, Some(checked(1.7, 2, 5, 0))),
        ];
        let j = FarSummary::new(&recs, &d, &o);
        assert_eq!(j.silhouette_ratio_max, Some(1.7));
        assert_eq!(j.silhouette_bound_violations, Some(2));
        assert_eq!(j.silhouette_subpixel, Some(8));
        assert_eq!(j.silhouette_thin, Some(1));
        assert_eq!(j.silhouette_px_max, Some(3.0 * 1.7));
        // Serialised, the fields keep the report's keys.
        let v = serde_json::to_value(&j).unwrap();
        assert_eq!(v["silhouette_bound_violations"], serde_json::json!(2));
        // One frame measured without the geometry: the bound's figures are null, the raw one is
        // kept.
        let mut recs = recs;
        recs.push(record(2, Some(ImageError::default())));
        let j = FarSummary::new(&recs, &d, &o);
        assert_eq!(j.silhouette_ratio_max, None);
        assert_eq!(j.silhouette_bound_violations, None);
        assert_eq!(j.silhouette_subpixel, None);
        assert_eq!(j.silhouette_thin, None);
        assert!(j.silhouette_px_max.is_some());
    }
}
