//! The walk benchmark (seed 003 §5.1, Fig. 4 and Table 1): a camera route through the city,
//! culled by every spatial structure, optionally occlusion-culled, rendered and checked against
//! the visibility oracle; per-frame CSV, a Table-1 style summary, frame-time plots, frames and a
//! self-contained HTML report.
//!
//! Seed 003 measured seconds per rendered frame in OpenGL Performer. Here a frame's time is the
//! culling time plus, when rendering, the render time of the blocks the structure kept (GPU
//! time from timestamp queries when the adapter has them, else wall time). Without rendering the
//! table reports culling time and the triangles each structure sends, which is what drives the
//! render time in the paper.

use crate::blocks::BlockId;
use crate::city::{LocalFrame, Mesh};
use crate::geom::{Aabb3, Camera};
use crate::index::{BlockBounds, CityIndex, CullStats};
use crate::report::plot::{write_plot, PlotError, PlotKind, Series};
use crate::route::CameraRoute;
use geo_types::LineString;
use serde::Serialize;
use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// An occlusion culler for the walk (e.g. occluder shadows and a cull map, seed 004 §3.2).
pub trait OcclusionProvider: Sync {
    /// Short name for reports.
    fn name(&self) -> String;
    /// One frame: builds what the culler needs for `camera` (its time counts as culling time),
    /// then frustum-culls through `index` while dropping what is proven hidden, pushing the blocks
    /// to draw to `out`.
    fn cull(&self, index: &dyn CityIndex, camera: &Camera, out: &mut Vec<BlockId>) -> CullStats;
}

/// The exact set of visible blocks for a camera (the visibility oracle), to count false culls.
pub trait VisibilityOracle: Sync {
    /// Blocks that cover at least one pixel of an image of `width` × `height` pixels.
    fn visible(&self, camera: &Camera, width: u32, height: u32) -> HashSet<BlockId>;
}

/// Draws a frame: returns the render time in seconds, whether it is GPU time, and the image when
/// asked for one.
pub trait FrameRenderer {
    /// What renders, for the report (e.g. `GPU: llvmpipe (Vulkan), timestamps`).
    fn describe(&self) -> String;
    /// Image size.
    fn size(&self) -> (u32, u32);
    /// Draws `visible` for `camera`.
    fn render(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
    ) -> Result<(f64, Option<image::RgbaImage>), String>;
}

/// Everything the walk needs about a city.
pub struct WalkScene {
    /// City name.
    pub name: String,
    /// The local frame (street edges are in world coordinates).
    pub frame: LocalFrame,
    /// Street graph edges, metric world coordinates (may be empty).
    pub street_edges: Vec<LineString<f64>>,
    /// Meshes (local frame) with the block each belongs to; one per block or one per building.
    pub meshes: Vec<(BlockId, Mesh)>,
    /// Per-block bounds (local frame) as the structures index them.
    pub bounds: Vec<BlockBounds>,
    /// The spatial structures to compare, built over `bounds`.
    pub structures: Vec<Box<dyn CityIndex>>,
    /// The occlusion culler, when there is one.
    pub occlusion: Option<Box<dyn OcclusionProvider>>,
    /// The visibility oracle, when there is one.
    pub oracle: Option<Box<dyn VisibilityOracle>>,
    /// A CPU renderer used when no GPU renders (e.g. the oracle's shading).
    pub cpu_renderer: Option<Box<dyn FrameRenderer>>,
}

impl std::fmt::Debug for WalkScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WalkScene")
            .field("name", &self.name)
            .field("blocks", &self.bounds.len())
            .field(
                "structures",
                &self.structures.iter().map(|s| s.name()).collect::<Vec<_>>(),
            )
            .finish()
    }
}

impl WalkScene {
    /// A scene from a city, its blocks, one mesh per building (`building_meshes[i]` is building
    /// `i`'s, as `city::extrude::extrude_city` returns) and the blocks' bounds; no structures,
    /// culler or oracle yet. Buildings in no block are left out of the meshes (none are, when the
    /// layout assigns every building).
    pub fn from_city(
        city: &crate::city::City,
        layout: &crate::blocks::BlockLayout,
        building_meshes: Vec<Mesh>,
        bounds: Vec<BlockBounds>,
    ) -> Self {
        let mut block_of: Vec<Option<BlockId>> = vec![None; building_meshes.len()];
        for b in &layout.blocks {
            for bid in &b.buildings {
                if let Some(slot) = block_of.get_mut(bid.0 as usize) {
                    *slot = Some(b.id);
                }
            }
        }
        let meshes = building_meshes
            .into_iter()
            .zip(block_of)
            .filter_map(|(m, b)| b.map(|b| (b, m)))
            .collect();
        Self {
            name: city.name.clone(),
            frame: city.frame,
            street_edges: layout.street_edges.clone(),
            meshes,
            bounds,
            structures: Vec::new(),
            occlusion: None,
            oracle: None,
            cpu_renderer: None,
        }
    }

    /// Box of all block bounds (local frame).
    pub fn city_bounds(&self) -> Aabb3 {
        self.bounds
            .iter()
            .fold(Aabb3::EMPTY, |b, bb| b.union(bb.aabb))
    }
}

/// Whether occlusion culling runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OcclusionMode {
    /// Frustum culling only.
    Off,
    /// Frustum and occlusion culling (fails without an occlusion culler).
    On,
    /// Both modes, side by side, when an occlusion culler is there; frustum only otherwise.
    #[default]
    Auto,
}

/// Walk settings.
#[derive(Clone, Debug)]
pub struct WalkParams {
    /// The route.
    pub route: CameraRoute,
    /// Frames sampled along it.
    pub frames: usize,
    /// Occlusion culling.
    pub occlusion: OcclusionMode,
    /// Render every frame (GPU with feature `render` and an adapter, else the CPU renderer).
    pub render: bool,
    /// Keep an image every this many frames (0: none). Images need `render`.
    pub image_every: usize,
    /// Count false culls against the oracle.
    pub oracle: bool,
    /// Image size for rendering and the oracle.
    pub size: (u32, u32),
}

/// One frame of one structure in one culling mode.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRow {
    /// Frame number along the route.
    pub frame: usize,
    /// Structure name.
    pub structure: String,
    /// `frustum` or `frustum+occlusion`.
    pub mode: String,
    /// Culling time, seconds.
    pub cull_s: f64,
    /// Render time, seconds (GPU when measured), when rendering.
    pub render_s: Option<f64>,
    /// Culling + rendering, seconds.
    pub frame_s: f64,
    /// Work counters of the cull.
    pub stats: CullStats,
    /// Blocks kept.
    pub blocks: usize,
    /// Triangles of the kept blocks.
    pub triangles: u64,
    /// Oracle-visible blocks the structure dropped (should be 0), when checked.
    pub false_culls: Option<usize>,
}

/// Averages over the route for one structure and mode (seed 003 Table 1).
#[derive(Clone, Debug, Serialize)]
pub struct SummaryRow {
    /// Structure name.
    pub structure: String,
    /// Culling mode.
    pub mode: String,
    /// Mean seconds per frame.
    pub seconds_per_frame: f64,
    /// Mean culling seconds per frame.
    pub cull_s: f64,
    /// Mean render seconds per frame, when rendering.
    pub render_s: Option<f64>,
    /// BqR-tree seconds per frame / this structure's (1 for the BqR-tree; the reference is the
    /// first structure when there is no `bqr`).
    pub ratio: f64,
    /// Mean triangles drawn per frame.
    pub triangles: f64,
    /// Mean blocks drawn per frame.
    pub blocks: f64,
    /// Mean nodes visited per frame.
    pub nodes_visited: f64,
    /// Total false culls over the route, when checked.
    pub false_culls: Option<usize>,
}

/// The walk's results.
#[derive(Debug)]
pub struct WalkReport {
    /// City name.
    pub city: String,
    /// Route name.
    pub route: String,
    /// The cameras, one per frame.
    pub cameras: Vec<Camera>,
    /// Per-frame rows (frame-major, then structure, then mode).
    pub rows: Vec<FrameRow>,
    /// Table 1.
    pub summary: Vec<SummaryRow>,
    /// What rendered, or why nothing did.
    pub renderer: String,
    /// Kept images: frame number and picture (of the reference structure in the last mode).
    pub images: Vec<(usize, image::RgbaImage)>,
    /// Notes for the reader (fallbacks, skipped checks).
    pub notes: Vec<String>,
    /// Wall time of the whole walk, seconds.
    pub total_s: f64,
}

/// What went wrong in the walk.
#[derive(Debug, thiserror::Error)]
pub enum WalkError {
    /// The scene has no structure to walk with.
    #[error("{0}: no spatial structure to compare")]
    NoStructures(String),
    /// Occlusion was asked for but there is no culler.
    #[error("{0}: occlusion culling asked for, but no occlusion culler is available")]
    NoOcclusion(String),
    /// Writing an output failed.
    #[error("{file}: {message}")]
    Write {
        /// The file.
        file: PathBuf,
        /// What failed.
        message: String,
    },
    /// A plot failed.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

const FRUSTUM: &str = "frustum";
const OCCLUSION: &str = "frustum+occlusion";

/// Runs the walk: for every frame, every structure and every culling mode, culls, optionally
/// renders and checks against the oracle. `progress(done, total)` is called after every frame.
///
/// Without the `render` feature or an adapter, `params.render` falls back to the scene's CPU
/// renderer, and the report says so.
pub fn run_walk(
    scene: &WalkScene,
    params: &WalkParams,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<WalkReport, WalkError> {
    let started = Instant::now();
    if scene.structures.is_empty() {
        return Err(WalkError::NoStructures(scene.name.clone()));
    }
    let mut notes = Vec::new();
    let modes: Vec<&str> = match (params.occlusion, scene.occlusion.is_some()) {
        (OcclusionMode::Off, _) => vec![FRUSTUM],
        (OcclusionMode::On, true) => vec![OCCLUSION],
        (OcclusionMode::On, false) => return Err(WalkError::NoOcclusion(scene.name.clone())),
        (OcclusionMode::Auto, true) => vec![FRUSTUM, OCCLUSION],
        (OcclusionMode::Auto, false) => {
            notes.push("no occlusion culler available: frustum culling only".into());
            vec![FRUSTUM]
        }
    };
    let cameras = params.route.sample(params.frames);
    let triangles: Vec<u64> = {
        let n = scene
            .bounds
            .iter()
            .map(|b| b.id.0 as usize + 1)
            .max()
            .unwrap_or(0);
        let mut t = vec![0u64; n];
        for b in &scene.bounds {
            t[b.id.0 as usize] = b.triangles as u64;
        }
        t
    };

    let mut gpu_renderer: Option<Box<dyn FrameRenderer>> = None;
    // A GPU renderer when there is one; the scene's CPU renderer otherwise.
    let mut renderer_desc = "none (rendering not asked for)".to_string();
    if params.render {
        match gpu_frame_renderer(scene, params.size) {
            Ok(r) => {
                renderer_desc = r.describe();
                gpu_renderer = Some(r);
            }
            Err(why) => {
                let fallback = scene
                    .cpu_renderer
                    .as_ref()
                    .map(|r| r.describe())
                    .unwrap_or_else(|| {
                        "CPU z-buffer shading (visibility::oracle::shade), wall time".into()
                    });
                renderer_desc = format!("CPU fallback ({why}): {fallback}");
                notes.push(format!(
                    "GPU rendering unavailable ({why}); render times are CPU times and not comparable with GPU numbers"
                ));
            }
        }
    }
    // The reference structure for ratios and images: bqr when present.
    let reference = scene
        .structures
        .iter()
        .position(|s| s.name() == "bqr")
        .unwrap_or(0);

    let mesh_refs: Vec<(BlockId, &Mesh)> = scene.meshes.iter().map(|(b, m)| (*b, m)).collect();
    let oracle_shader = OracleShader {
        meshes: &mesh_refs,
        size: params.size,
    };
    let mut rows = Vec::with_capacity(cameras.len() * scene.structures.len() * modes.len());
    let mut images = Vec::new();
    let mut visible: Vec<BlockId> = Vec::new();
    let mut oracle_note = false;
    for (f, cam) in cameras.iter().enumerate() {
        let frustum = cam.frustum();
        let truth = if params.oracle {
            Some(match &scene.oracle {
                Some(o) => o.visible(cam, params.size.0, params.size.1),
                None => {
                    if !oracle_note {
                        notes.push(format!(
                            "false culls counted against the CPU z-buffer oracle at {}x{}",
                            params.size.0, params.size.1
                        ));
                        oracle_note = true;
                    }
                    crate::visibility::oracle::visible_blocks(
                        &mesh_refs,
                        cam,
                        params.size.0,
                        params.size.1,
                    )
                    .into_iter()
                    .collect()
                }
            })
        } else {
            None
        };
        for (si, s) in scene.structures.iter().enumerate() {
            for &mode in &modes {
                visible.clear();
                let t0 = Instant::now();
                let stats = if mode == OCCLUSION {
                    let occ = scene.occlusion.as_ref().expect("checked above");
                    occ.cull(&**s, cam, &mut visible)
                } else {
                    s.cull(&frustum, &mut visible)
                };
                let cull_s = t0.elapsed().as_secs_f64();
                let tri: u64 = visible
                    .iter()
                    .map(|b| triangles.get(b.0 as usize).copied().unwrap_or(0))
                    .sum();
                let want_image = params.image_every > 0
                    && f % params.image_every == 0
                    && si == reference
                    && mode == *modes.last().unwrap();
                let mut render_s = None;
                if params.render {
                    let r: &dyn FrameRenderer = if let Some(g) = gpu_renderer.as_deref() {
                        g
                    } else if let Some(c) = scene.cpu_renderer.as_deref() {
                        c
                    } else {
                        &oracle_shader
                    };
                    {
                        match r.render(cam, &visible, want_image) {
                            Ok((secs, img)) => {
                                render_s = Some(secs);
                                if let Some(img) = img {
                                    images.push((f, img));
                                }
                            }
                            Err(e) => notes.push(format!("frame {f}: render failed: {e}")),
                        }
                    }
                }
                let false_culls = truth.as_ref().map(|t| {
                    let kept: HashSet<BlockId> = visible.iter().copied().collect();
                    t.iter().filter(|b| !kept.contains(b)).count()
                });
                rows.push(FrameRow {
                    frame: f,
                    structure: s.name().to_string(),
                    mode: mode.to_string(),
                    cull_s,
                    render_s,
                    frame_s: cull_s + render_s.unwrap_or(0.0),
                    stats,
                    blocks: visible.len(),
                    triangles: tri,
                    false_culls,
                });
            }
        }
        progress(f + 1, cameras.len());
    }
    let summary = summarise(&rows, &scene.structures[reference].name().to_string());
    Ok(WalkReport {
        city: scene.name.clone(),
        route: params.route.name.clone(),
        cameras,
        rows,
        summary,
        renderer: renderer_desc,
        images,
        notes,
        total_s: started.elapsed().as_secs_f64(),
    })
}

/// The CPU fallback: the visibility oracle's shaded z-buffer image of the listed blocks.
struct OracleShader<'a> {
    meshes: &'a [(BlockId, &'a Mesh)],
    size: (u32, u32),
}

impl FrameRenderer for OracleShader<'_> {
    fn describe(&self) -> String {
        format!(
            "CPU z-buffer shading (visibility::oracle::shade), wall time, {}x{}",
            self.size.0, self.size.1
        )
    }
    fn size(&self) -> (u32, u32) {
        self.size
    }
    fn render(
        &self,
        camera: &Camera,
        visible: &[BlockId],
        want_image: bool,
    ) -> Result<(f64, Option<image::RgbaImage>), String> {
        let t0 = Instant::now();
        let keep: HashSet<BlockId> = visible.iter().copied().collect();
        let list: Vec<(BlockId, &Mesh)> = self
            .meshes
            .iter()
            .filter(|(b, _)| keep.contains(b))
            .copied()
            .collect();
        let img = crate::visibility::oracle::shade(&list, camera, self.size.0, self.size.1);
        Ok((t0.elapsed().as_secs_f64(), want_image.then_some(img)))
    }
}

/// The occluder-shadow culler (seed 004 §3.2) as the walk's occlusion culler.
impl OcclusionProvider for crate::visibility::OcclusionCuller {
    fn name(&self) -> String {
        "occluder shadows + cull map (seed 004 §3.2)".into()
    }
    fn cull(&self, index: &dyn CityIndex, camera: &Camera, out: &mut Vec<BlockId>) -> CullStats {
        crate::visibility::OcclusionCuller::cull(self, index, camera, out).cull
    }
}

/// A GPU renderer over the scene's meshes, or why there is none.
#[cfg(feature = "render")]
fn gpu_frame_renderer(
    scene: &WalkScene,
    size: (u32, u32),
) -> Result<Box<dyn FrameRenderer>, String> {
    use crate::render::{Gpu, MeshRenderer, RenderOptions};
    let gpu = Gpu::new_headless().map_err(|e| e.to_string())?;
    let meshes: Vec<(BlockId, &Mesh)> = scene.meshes.iter().map(|(b, m)| (*b, m)).collect();
    let renderer = MeshRenderer::with_options(
        &gpu,
        &meshes,
        RenderOptions {
            width: size.0,
            height: size.1,
        },
    )
    .map_err(|e| e.to_string())?;
    struct GpuFrames {
        gpu: Gpu,
        renderer: MeshRenderer,
    }
    impl FrameRenderer for GpuFrames {
        fn describe(&self) -> String {
            format!(
                "GPU: {}{}, {}x{}",
                self.gpu.adapter_name(),
                if self.gpu.timestamps {
                    ", GPU timestamps"
                } else {
                    ", wall time (no timestamp queries)"
                },
                self.renderer.options().width,
                self.renderer.options().height
            )
        }
        fn size(&self) -> (u32, u32) {
            let o = self.renderer.options();
            (o.width, o.height)
        }
        fn render(
            &self,
            camera: &Camera,
            visible: &[BlockId],
            want_image: bool,
        ) -> Result<(f64, Option<image::RgbaImage>), String> {
            let frame = self
                .renderer
                .draw(&self.gpu, camera, visible)
                .map_err(|e| e.to_string())?;
            let img = if want_image { frame.to_image() } else { None };
            Ok((frame.timings.best_s(), img))
        }
    }
    Ok(Box::new(GpuFrames { gpu, renderer }))
}

/// Without the `render` feature there is no GPU renderer.
#[cfg(not(feature = "render"))]
fn gpu_frame_renderer(
    _scene: &WalkScene,
    _size: (u32, u32),
) -> Result<Box<dyn FrameRenderer>, String> {
    Err("built without the `render` feature".into())
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

/// Table 1: averages per structure and mode, ratio against `reference` in the same mode.
fn summarise(rows: &[FrameRow], reference: &str) -> Vec<SummaryRow> {
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in rows {
        let k = (r.structure.clone(), r.mode.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    let mut out: Vec<SummaryRow> = keys
        .iter()
        .map(|(s, m)| {
            let sel = || rows.iter().filter(|r| &r.structure == s && &r.mode == m);
            let rendered = sel().all(|r| r.render_s.is_some()) && sel().next().is_some();
            SummaryRow {
                structure: s.clone(),
                mode: m.clone(),
                seconds_per_frame: mean(sel().map(|r| r.frame_s)),
                cull_s: mean(sel().map(|r| r.cull_s)),
                render_s: rendered.then(|| mean(sel().map(|r| r.render_s.unwrap_or(0.0)))),
                ratio: 0.0,
                triangles: mean(sel().map(|r| r.triangles as f64)),
                blocks: mean(sel().map(|r| r.blocks as f64)),
                nodes_visited: mean(sel().map(|r| r.stats.nodes_visited as f64)),
                false_culls: sel()
                    .map(|r| r.false_culls)
                    .try_fold(0usize, |a, x| x.map(|x| a + x)),
            }
        })
        .collect();
    let refs: Vec<(String, f64)> = out
        .iter()
        .filter(|r| r.structure == reference)
        .map(|r| (r.mode.clone(), r.seconds_per_frame))
        .collect();
    for r in &mut out {
        if let Some((_, t)) = refs.iter().find(|(m, _)| *m == r.mode) {
            r.ratio = if r.seconds_per_frame > 0.0 {
                t / r.seconds_per_frame
            } else {
                f64::NAN
            };
        }
    }
    out
}

impl WalkReport {
    /// The structure names in order of first appearance.
    pub fn structures(&self) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for r in &self.rows {
            if !v.contains(&r.structure) {
                v.push(r.structure.clone());
            }
        }
        v
    }

    /// The culling modes in order of first appearance.
    pub fn modes(&self) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for r in &self.rows {
            if !v.contains(&r.mode) {
                v.push(r.mode.clone());
            }
        }
        v
    }

    /// Per-frame rows as CSV.
    pub fn frames_csv(&self) -> String {
        let mut s = String::from(
            "frame,structure,mode,cull_s,render_s,frame_s,nodes_visited,plane_tests,blocks,triangles,false_culls,x,y,z,yaw_deg,pitch_deg\n",
        );
        for r in &self.rows {
            let c = &self.cameras[r.frame];
            let _ = writeln!(
                s,
                "{},{},{},{:.9},{},{:.9},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3}",
                r.frame,
                r.structure,
                r.mode,
                r.cull_s,
                r.render_s.map(|v| format!("{v:.9}")).unwrap_or_default(),
                r.frame_s,
                r.stats.nodes_visited,
                r.stats.plane_tests,
                r.blocks,
                r.triangles,
                r.false_culls.map(|v| v.to_string()).unwrap_or_default(),
                c.position.x,
                c.position.y,
                c.position.z,
                c.yaw.to_degrees(),
                c.pitch.to_degrees(),
            );
        }
        s
    }

    /// The summary as a Markdown table (seed 003 Table 1, plus culling and triangle columns).
    pub fn summary_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "| structure | culling | seconds/frame | ratio BqR/structure | cull s/frame | render s/frame | triangles/frame | blocks/frame | nodes/frame | false culls |"
        );
        let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        for r in &self.summary {
            let _ = writeln!(
                s,
                "| {} | {} | {:.6} | {:.3} | {:.6} | {} | {:.0} | {:.1} | {:.1} | {} |",
                r.structure,
                r.mode,
                r.seconds_per_frame,
                r.ratio,
                r.cull_s,
                r.render_s.map(|v| format!("{v:.6}")).unwrap_or("–".into()),
                r.triangles,
                r.blocks,
                r.nodes_visited,
                r.false_culls.map(|v| v.to_string()).unwrap_or("–".into()),
            );
        }
        s
    }

    /// One series per structure of `value` along the route, for `mode`.
    fn series(&self, mode: &str, value: impl Fn(&FrameRow) -> f64) -> Vec<Series> {
        self.structures()
            .into_iter()
            .map(|st| Series {
                points: self
                    .rows
                    .iter()
                    .filter(|r| r.structure == st && r.mode == mode)
                    .map(|r| (r.frame as f64, value(r)))
                    .collect(),
                name: st,
            })
            .collect()
    }

    /// Writes `frames.csv`, `summary.md`, `report.json`, the plots (`frame_time_<mode>.png/.svg`,
    /// `triangles_<mode>.png/.svg`), the kept frames (`frames/frame_NNNN.png`, or under
    /// `frames_dir`) and `report.html`, which links them all. Returns the files written.
    pub fn write(&self, dir: &Path, frames_dir: Option<&Path>) -> Result<Vec<PathBuf>, WalkError> {
        let werr = |file: &Path, e: std::io::Error| WalkError::Write {
            file: file.to_path_buf(),
            message: e.to_string(),
        };
        std::fs::create_dir_all(dir).map_err(|e| werr(dir, e))?;
        let mut written = Vec::new();
        let mut put = |name: &str, text: String| -> Result<PathBuf, WalkError> {
            let p = dir.join(name);
            std::fs::write(&p, text).map_err(|e| werr(&p, e))?;
            written.push(p.clone());
            Ok(p)
        };
        put("frames.csv", self.frames_csv())?;
        put("summary.md", self.summary_markdown())?;
        put(
            "report.json",
            serde_json::to_string_pretty(&self.json()).unwrap_or_default(),
        )?;
        let mut plots = Vec::new();
        for mode in self.modes() {
            let tag = mode.replace('+', "_");
            let ft = self.series(&mode, |r| r.frame_s);
            let tri = self.series(&mode, |r| r.triangles as f64);
            for ext in ["png", "svg"] {
                let p = dir.join(format!("frame_time_{tag}.{ext}"));
                write_plot(
                    &p,
                    &format!("Time per frame along the {} route ({mode})", self.route),
                    "frame",
                    "seconds",
                    &ft,
                    PlotKind::Lines,
                )?;
                written.push(p.clone());
                let q = dir.join(format!("triangles_{tag}.{ext}"));
                write_plot(
                    &q,
                    &format!("Triangles drawn along the {} route ({mode})", self.route),
                    "frame",
                    "triangles",
                    &tri,
                    PlotKind::Lines,
                )?;
                written.push(q.clone());
            }
            plots.push((mode.clone(), tag));
        }
        let fdir = frames_dir
            .map(Path::to_path_buf)
            .unwrap_or_else(|| dir.join("frames"));
        let mut frame_files = Vec::new();
        if !self.images.is_empty() {
            std::fs::create_dir_all(&fdir).map_err(|e| werr(&fdir, e))?;
            for (f, img) in &self.images {
                let p = fdir.join(format!("frame_{f:04}.png"));
                img.save(&p).map_err(|e| WalkError::Write {
                    file: p.clone(),
                    message: e.to_string(),
                })?;
                frame_files.push((*f, p.clone()));
                written.push(p);
            }
        }
        let html = self.html(dir, &plots, &frame_files);
        let p = dir.join("report.html");
        std::fs::write(&p, html).map_err(|e| werr(&p, e))?;
        written.push(p);
        Ok(written)
    }

    /// One JSON object: settings, summary, notes (the per-frame rows are in the CSV).
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "city": self.city,
            "route": self.route,
            "frames": self.cameras.len(),
            "renderer": self.renderer,
            "summary": self.summary,
            "notes": self.notes,
            "total_s": self.total_s,
        })
    }

    fn html(&self, dir: &Path, plots: &[(String, String)], frames: &[(usize, PathBuf)]) -> String {
        let esc = |s: &str| {
            s.replace('&', "&amp;")
                .replace('<', "&lt;")
                .replace('>', "&gt;")
        };
        let rel = |p: &Path| {
            p.strip_prefix(dir)
                .map(|r| r.to_string_lossy().into_owned())
                .unwrap_or_else(|_| p.to_string_lossy().into_owned())
        };
        let mut h = String::new();
        let _ = write!(
            h,
            "<!doctype html><html><head><meta charset=\"utf-8\"><title>blockwalk walk: {city}</title>\
             <style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}\
             table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
             td:first-child,td:nth-child(2){{text-align:left}}img{{max-width:100%}}</style></head><body>\
             <h1>Walk through {city}</h1><p>Route <b>{route}</b>, {n} frames; renderer: {r}; total {t:.2} s.</p>",
            city = esc(&self.city),
            route = esc(&self.route),
            n = self.cameras.len(),
            r = esc(&self.renderer),
            t = self.total_s
        );
        h.push_str("<h2>Average per frame (seed 003 Table 1)</h2><table><tr><th>structure</th><th>culling</th><th>seconds/frame</th><th>ratio BqR/structure</th><th>cull s</th><th>render s</th><th>triangles</th><th>blocks</th><th>nodes</th><th>false culls</th></tr>");
        for r in &self.summary {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{:.6}</td><td>{:.3}</td><td>{:.6}</td><td>{}</td><td>{:.0}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td></tr>",
                esc(&r.structure),
                esc(&r.mode),
                r.seconds_per_frame,
                r.ratio,
                r.cull_s,
                r.render_s.map(|v| format!("{v:.6}")).unwrap_or("–".into()),
                r.triangles,
                r.blocks,
                r.nodes_visited,
                r.false_culls.map(|v| v.to_string()).unwrap_or("–".into())
            );
        }
        h.push_str("</table>");
        if !self.notes.is_empty() {
            h.push_str("<h2>Notes</h2><ul>");
            for n in &self.notes {
                let _ = write!(h, "<li>{}</li>", esc(n));
            }
            h.push_str("</ul>");
        }
        for (mode, tag) in plots {
            let _ = write!(
                h,
                "<h2>Along the route ({m}; seed 003 Fig. 4)</h2><p><img src=\"frame_time_{t}.svg\" alt=\"frame time\"></p><p><img src=\"triangles_{t}.svg\" alt=\"triangles\"></p>",
                m = esc(mode),
                t = tag
            );
        }
        if !frames.is_empty() {
            h.push_str("<h2>Frames</h2>");
            for (f, p) in frames {
                let _ = write!(
                    h,
                    "<figure style=\"display:inline-block;width:48%\"><img src=\"{}\" alt=\"frame {f}\"><figcaption>frame {f}</figcaption></figure>",
                    esc(&rel(p))
                );
            }
        }
        h.push_str("<p>Per-frame data: <a href=\"frames.csv\">frames.csv</a>; summary: <a href=\"summary.md\">summary.md</a>; <a href=\"report.json\">report.json</a>.</p></body></html>\n");
        h
    }
}
