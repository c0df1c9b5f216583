//! A walk over a streamed city: per frame the far-field selection over the whole hierarchy,
//! requests by class, the frame drawn from what is resident (stand-ins where the content is
//! not), and the measures.
//!
//! # Requests (Di Benedetto, §4.4)
//! Every frame replaces the queue with three classes, in this order:
//! - **C**, coarser but good enough meanwhile: the ancestors of every missing item the frame
//!   needs (its stand-ins to be, coarsest first), so that one map covering many blocks
//!   replaces their boxes after one small transfer;
//! - **A**, what the frame needs: the maps and block meshes the selection chose (nearest first);
//! - **B**, the neighbourhood ahead: what the selection would need for the cameras of the next
//!   `prefetch` frames of the route (which is known), nearest in time first.
//!
//! # Stand-ins
//! A selected map that is not resident is drawn as its nearest resident ancestor; a block mesh
//! that is not resident, as the deepest resident map holding the block; where no map holding it
//! is resident, as its box (from the hierarchy, always resident) in the stand-in colour. An
//! item covered by a drawn ancestor is not drawn again: every block is drawn once.
//!
//! # Modes
//! [`Mode::Realtime`]: the render thread never waits; it takes what has arrived and draws.
//! [`Mode::Deterministic`]: before drawing, the frame's A items are loaded (the render thread
//! waits for them, and the wait is reported): frames depend on the input alone, for tests and
//! for comparing images.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::time::{Duration, Instant};

use image::RgbaImage;

use crate::blockmap::compare::image_psnr_db;
use crate::blockmap::image::cast_image;
use crate::blockmap::{BlockMap, SelectOptions, Selector};
use crate::blocks::BlockId;
use crate::city::appearance::BuildingStyle;
use crate::city::mesh::VertexAppearance;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::visibility::oracle;

use super::city::{ContentId, StreamCity};
use super::loader::{load, Cache, LoadError, Loader, Priority, Resident};
use super::source::{Link, LinkSpec};
use super::StreamError;

/// The colour boxes standing in for blocks are drawn in (linear RGB).
pub const STANDIN_BOX_COLOR: [f32; 3] = [0.85, 0.1, 0.75];

/// How frames wait for content.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Mode {
    /// Loads complete before the frame that needs them.
    Deterministic,
    /// The render thread never waits.
    Realtime,
}

/// The settings of a streamed walk, checked where they are built.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StreamOptions {
    /// Bytes of decoded content kept resident.
    pub budget_bytes: u64,
    /// Loader threads.
    pub workers: usize,
    /// The link's bandwidth and latency.
    pub link: LinkSpec,
    /// How frames wait for content.
    pub mode: Mode,
    /// Largest projected error of a drawn map, pixels.
    pub tau_px: f64,
    /// Image size.
    pub size: (u32, u32),
    /// Frames of the route ahead whose content is prefetched.
    pub prefetch_frames: usize,
    /// Frames per second the walk is paced at (`None`: as fast as frames are drawn).
    pub fps: Option<f64>,
    /// Draw every frame again from fully resident content and compare.
    pub check: bool,
    /// Keep every `n`th frame's image (stand-ins marked) for a strip.
    pub keep_every: Option<usize>,
    /// Use the far field (BlockMaps); without it every block is a mesh.
    pub far: bool,
    /// List every frame's drawn blocks in [`StreamFrame::blocks`] (for checks).
    pub record_blocks: bool,
    /// Draw every frame again with every block it covers as a mesh (no far field), from content
    /// loaded outside the budget, and compare: the far field's error against its time.
    pub mesh_reference: bool,
    /// Request the needed items before their coarser stand-ins (the thesis' order, class A
    /// first); by default the stand-ins come first.
    pub needed_first: bool,
}

impl StreamOptions {
    /// Checks the values.
    ///
    /// # Errors
    /// A budget of 0, no workers, τ not a finite number > 0, an empty image, `fps` not > 0.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        budget_bytes: u64,
        workers: usize,
        link: LinkSpec,
        mode: Mode,
        tau_px: f64,
        size: (u32, u32),
        prefetch_frames: usize,
        fps: Option<f64>,
    ) -> Result<Self, StreamError> {
        let bad = |s: String| Err(StreamError::Bad(s));
        if budget_bytes == 0 {
            return bad("budget 0: expected some bytes (e.g. 768MiB)".into());
        }
        if workers == 0 || workers > 256 {
            return bad(format!("{workers} loader threads: expected 1 to 256"));
        }
        if !(tau_px.is_finite() && tau_px > 0.0) {
            return bad(format!("tau {tau_px}: expected a number of pixels > 0"));
        }
        if size.0 == 0 || size.1 == 0 {
            return bad(format!(
                "image {}x{}: expected at least 1x1",
                size.0, size.1
            ));
        }
        if let Some(f) = fps {
            if !(f.is_finite() && f > 0.0) {
                return bad(format!("{f} frames per second: expected a number > 0"));
            }
        }
        Ok(Self {
            budget_bytes,
            workers,
            link,
            mode,
            tau_px,
            size,
            prefetch_frames,
            fps,
            check: false,
            keep_every: None,
            far: true,
            record_blocks: false,
            mesh_reference: false,
            needed_first: false,
        })
    }
}

/// One frame of a streamed walk.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct StreamFrame {
    /// Frame number.
    pub frame: usize,
    /// Seconds since the walk started, when the frame was drawn.
    pub at_s: f64,
    /// Items the selection chose (maps and block meshes).
    pub needed: usize,
    /// Of these, resident when the frame started (cache hits).
    pub hits: usize,
    /// Maps drawn.
    pub maps: usize,
    /// Block meshes drawn.
    pub meshes: usize,
    /// Maps drawn in place of finer content (stand-ins).
    pub standin_maps: usize,
    /// Blocks drawn as boxes (no map holding them resident).
    pub standin_boxes: usize,
    /// Selected items not drawn as themselves (replaced by a stand-in, or covered by one).
    pub replaced: usize,
    /// Requests queued after the frame: needed now, their coarser stand-ins, the route ahead
    /// (each item once).
    pub queued: [usize; 3],
    /// Loads received during the frame.
    pub loaded: usize,
    /// Bytes of those loads.
    pub bytes_loaded: u64,
    /// Bytes resident after the frame.
    pub resident_bytes: u64,
    /// Seconds the render thread waited for loads (0 in real-time mode).
    pub wait_s: f64,
    /// Seconds spent handing requests over and taking results (the queue's lock and channel).
    pub handoff_s: f64,
    /// Seconds selecting.
    pub select_s: f64,
    /// Seconds selecting for the route ahead (the prefetch).
    pub prefetch_s: f64,
    /// Seconds drawing.
    pub draw_s: f64,
    /// Pixels differing from the fully resident frame (with `check`).
    pub differing_pixels: Option<u64>,
    /// PSNR against the fully resident frame, dB (infinite when equal; with `check`).
    pub psnr_db: Option<f64>,
    /// With `mesh_reference`: pixels differing from the frame drawn with meshes only.
    pub mesh_differing_pixels: Option<u64>,
    /// With `mesh_reference`: PSNR against the mesh-only frame, dB.
    pub mesh_psnr_db: Option<f64>,
    /// With `mesh_reference`: seconds drawing the mesh-only frame (content resident).
    pub mesh_draw_s: Option<f64>,
    /// With `record_blocks`: every block drawn (as a mesh, inside a drawn map, or as a box),
    /// once per time it is drawn.
    #[serde(skip)]
    pub blocks: Vec<BlockId>,
}

impl StreamFrame {
    /// Drawn as the selection asked: no stand-in.
    pub fn converged(&self) -> bool {
        self.replaced == 0
    }
}

/// A content item refused or missing during the walk.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Refusal {
    /// Frame it was reported in.
    pub frame: usize,
    /// What happened, naming the file.
    pub error: LoadError,
}

/// The figures of a streamed walk.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StreamSummary {
    /// The settings.
    pub options: StreamOptions,
    /// Frames drawn.
    pub frames: usize,
    /// Seconds from opening the city to the first frame drawn (startup included).
    pub first_frame_s: f64,
    /// Frames drawn with a stand-in.
    pub frames_with_standins: usize,
    /// The first frame drawn with no stand-in, and the seconds to it since the walk started.
    pub first_converged: Option<(usize, f64)>,
    /// Episodes of stand-ins (a frame with stand-ins after one without, or the first frame):
    /// count, and the longest and mean length in frames until converged again.
    pub episodes: usize,
    /// Longest episode, frames.
    pub episode_max_frames: usize,
    /// Mean episode, frames.
    pub episode_mean_frames: f64,
    /// Episodes still open at the end.
    pub unfinished_episodes: usize,
    /// Items loaded and their bytes.
    pub loads: usize,
    /// Bytes loaded.
    pub bytes_loaded: u64,
    /// Needed items resident when asked for / all asked for.
    pub hit_rate: f64,
    /// Items evicted.
    pub evictions: u64,
    /// Items not kept because a frame's own content filled the budget.
    pub over_budget: u64,
    /// The most bytes resident at the end of a frame.
    pub resident_max_bytes: u64,
    /// Seconds the render thread waited for loads: total and the largest per frame.
    pub wait_total_s: f64,
    /// Largest per-frame wait.
    pub wait_max_s: f64,
    /// Largest per-frame hand-over time (queue locks).
    pub handoff_max_s: f64,
    /// Mean seconds per frame drawing.
    pub draw_mean_s: f64,
    /// Content refused or missing, naming the files.
    pub refusals: Vec<Refusal>,
    /// With `check`: the largest share of differing pixels and the lowest PSNR over frames
    /// with stand-ins, and the frames that differ although converged (expected 0).
    pub differing_max: Option<f64>,
    /// Lowest PSNR, dB.
    pub psnr_min_db: Option<f64>,
    /// Converged frames that differ from the fully resident frame.
    pub converged_but_different: Option<usize>,
    /// Peak resident memory of the process (`VmHWM`), where the system tells.
    pub peak_rss_bytes: Option<u64>,
}

/// A streamed walk's result.
#[derive(Debug)]
pub struct StreamRun {
    /// Per frame.
    pub frames: Vec<StreamFrame>,
    /// The figures.
    pub summary: StreamSummary,
    /// Kept images (frame, image with stand-ins marked).
    pub kept: Vec<(usize, RgbaImage)>,
}

/// A block's box as a mesh in the stand-in colour.
fn box_standin(b: &crate::index::BlockBounds) -> Mesh {
    let mut m = oracle::box_mesh(b.aabb.min.as_vec3(), b.aabb.max.as_vec3());
    m.styles = vec![BuildingStyle::flat(STANDIN_BOX_COLOR, STANDIN_BOX_COLOR)];
    m.appearance = vec![VertexAppearance { u_m: 0.0, style: 0 }; m.positions.len()];
    m
}

/// What one frame draws.
#[derive(Default)]
struct Drawn {
    meshes: Vec<(BlockId, Arc<Resident>)>,
    boxes: Vec<(BlockId, Mesh)>,
    maps: Vec<Arc<Resident>>,
    standin: Vec<bool>,
}

/// Draws meshes, boxes and maps composited by depth (the CPU hybrid frame, as
/// [`crate::visibility::CpuFrameRenderer::draw_composited`] composites: a map pixel wins where
/// it is nearer than the mesh pass); with `mark`, also the same image with the stand-in maps'
/// pixels tinted, from the same passes.
fn draw(
    d: &Drawn,
    camera: &Camera,
    size: (u32, u32),
    mark: bool,
) -> (RgbaImage, Option<RgbaImage>) {
    let mut list: Vec<(BlockId, &Mesh)> = Vec::with_capacity(d.meshes.len() + d.boxes.len());
    for (b, r) in &d.meshes {
        if let Resident::Mesh(m) = &**r {
            list.push((*b, m));
        }
    }
    list.extend(d.boxes.iter().map(|(b, m)| (*b, m)));
    let (mut img, depth) =
        oracle::shade_with_ground_depth(&list, &Mesh::default(), camera, size.0, size.1);
    let maps: Vec<&BlockMap> = d
        .maps
        .iter()
        .filter_map(|r| match &**r {
            Resident::Map(m) => Some(m),
            Resident::Mesh(_) => None,
        })
        .collect();
    let mut marked = (mark && d.standin.iter().any(|&s| s)).then(|| img.clone());
    if !maps.is_empty() {
        let all: Vec<usize> = (0..maps.len()).collect();
        let mi = cast_image(&maps, &all, camera, size.0, size.1);
        for (i, px) in img.pixels_mut().enumerate() {
            if mi.hit[i] && mi.depth[i] < depth[i] {
                let c = mi.color[i];
                *px = image::Rgba(c);
                if let Some(m) = marked.as_mut() {
                    let mut t = c;
                    if d.standin[mi.map[i] as usize] {
                        for (k, tint) in [255u8, 40, 200].iter().enumerate() {
                            t[k] = ((t[k] as u16 + *tint as u16) / 2) as u8;
                        }
                    }
                    m.as_mut()[4 * i..4 * i + 4].copy_from_slice(&t);
                }
            }
        }
    }
    let marked = if mark {
        Some(marked.unwrap_or_else(|| img.clone()))
    } else {
        None
    };
    (img, marked)
}

/// Pixels whose colour differs, and the colour PSNR ([`image_psnr_db`]).
fn psnr_and_diff(a: &RgbaImage, b: &RgbaImage) -> (u64, f64) {
    let diff = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0[..3] != q.0[..3])
        .count() as u64;
    (diff, image_psnr_db(a, b))
}

/// The walk's state between frames.
struct Walker<'a> {
    city: &'a StreamCity,
    selector: Selector,
    cache: Cache,
    failed: HashMap<ContentId, LoadError>,
    refusals: Vec<Refusal>,
    /// The fully resident twin's content (with `check`).
    reference: Option<Cache>,
    parent: Vec<Option<usize>>,
}

impl Walker<'_> {
    fn resident_ancestor(&mut self, mut node: Option<usize>, frame: u64) -> Option<usize> {
        while let Some(n) = node {
            if self.cache.contains(self.city.node_content[n]) {
                self.cache.get(self.city.node_content[n], frame);
                return Some(n);
            }
            node = self.parent[n];
        }
        None
    }

    fn receive(&mut self, l: super::loader::Loaded, frame: usize, f: &mut StreamFrame) {
        f.loaded += 1;
        f.bytes_loaded += l.bytes;
        match l.result {
            Ok(r) => {
                self.cache.insert(l.id, r, frame as u64);
            }
            Err(e) => {
                self.refusals.push(Refusal {
                    frame,
                    error: e.clone(),
                });
                self.failed.insert(l.id, e);
            }
        }
    }

    /// The selection's items for `camera`: (maps as nodes, meshes as block slots with content).
    fn wanted(&self, sel: &crate::blockmap::Selection) -> (Vec<usize>, Vec<usize>) {
        let maps = sel.maps.clone();
        let meshes = sel
            .meshes
            .iter()
            .filter_map(|b| self.city.slot.get(b).copied())
            .filter(|&s| self.city.block_content[s].is_some())
            .collect();
        (maps, meshes)
    }
}

/// A streamed walk frame by frame: what [`play`] runs over a route and the viewer runs
/// live.
pub struct Streamer<'a> {
    city: &'a StreamCity,
    opts: StreamOptions,
    w: Walker<'a>,
    loader: Loader,
    t_walk: Instant,
    frames: Vec<StreamFrame>,
    first_frame_s: Option<f64>,
}

impl std::fmt::Debug for Streamer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Streamer")
            .field("frames", &self.frames.len())
            .field("resident_bytes", &self.w.cache.used())
            .finish()
    }
}

impl<'a> Streamer<'a> {
    /// Starts the loader over `city` with `opts`.
    ///
    /// # Errors
    /// [`StreamError::Bad`] for a far-field hierarchy the selector refuses.
    pub fn new(city: &'a StreamCity, opts: &StreamOptions) -> Result<Self, StreamError> {
        let nodes = if opts.far {
            city.nodes.clone()
        } else {
            Vec::new()
        };
        let selector = Selector::from_nodes(
            &nodes,
            &city.bounds,
            SelectOptions::new(opts.tau_px, SelectOptions::default().hysteresis)
                .map_err(|e| StreamError::Bad(e.to_string()))?,
        )
        .map_err(|e| StreamError::Bad(format!("the far-field hierarchy: {e}")))?;
        let link = Arc::new(Link::new(opts.link));
        let loader = Loader::start(
            city.contents.clone(),
            city.source.clone(),
            link,
            opts.workers,
        );
        let w = Walker {
            city,
            selector,
            cache: Cache::new(opts.budget_bytes),
            failed: HashMap::new(),
            refusals: Vec::new(),
            reference: (opts.check || opts.mesh_reference).then(|| Cache::new(opts.budget_bytes)),
            parent: city.nodes.iter().map(|n| n.parent).collect(),
        };
        Ok(Self {
            city,
            opts: opts.clone(),
            w,
            loader,
            t_walk: Instant::now(),
            frames: Vec::new(),
            first_frame_s: None,
        })
    }

    /// Draws the next frames at `width × height` pixels.
    pub fn set_size(&mut self, width: u32, height: u32) {
        if width > 0 && height > 0 {
            self.opts.size = (width, height);
        }
    }

    /// Seconds since the streamer started.
    pub fn elapsed_s(&self) -> f64 {
        self.t_walk.elapsed().as_secs_f64()
    }

    /// The frames drawn so far.
    pub fn frames(&self) -> &[StreamFrame] {
        &self.frames
    }

    /// Draws the next frame from `camera`, prefetching for the cameras `ahead` (the route's
    /// next ones; empty when unknown). Returns the image and, with `keep`, the image with
    /// stand-in maps marked.
    pub fn frame(
        &mut self,
        camera: &Camera,
        ahead: &[Camera],
        keep: bool,
    ) -> (RgbaImage, Option<RgbaImage>) {
        let Self {
            city,
            opts,
            w,
            loader,
            t_walk,
            frames,
            first_frame_s,
        } = self;
        let city: &StreamCity = city;
        let opts: &StreamOptions = opts;
        let i = frames.len();
        let height = opts.size.1;
        let fi = i as u64;
        let mut f = StreamFrame {
            frame: i,
            ..Default::default()
        };
        // What has arrived.
        let th = Instant::now();
        while let Some(l) = loader.try_take() {
            w.receive(l, i, &mut f);
        }
        f.handoff_s += th.elapsed().as_secs_f64();
        let ts = Instant::now();
        let sel = w.selector.select(camera, height, None);
        let (maps, meshes) = w.wanted(&sel);
        f.select_s = ts.elapsed().as_secs_f64();
        let content_of_map = |n: usize| city.node_content[n];
        let content_of_block = |s: usize| city.block_content[s].expect("filtered");
        let needed: Vec<ContentId> = maps
            .iter()
            .map(|&n| content_of_map(n))
            .chain(meshes.iter().map(|&s| content_of_block(s)))
            .collect();
        f.needed = needed.len();
        f.hits = needed.iter().filter(|&&c| w.cache.contains(c)).count();
        // Marked as used now: nothing arriving during this frame evicts them.
        for &c in &needed {
            w.cache.get(c, fi);
        }
        let missing = |w: &Walker<'_>| -> Vec<ContentId> {
            needed
                .iter()
                .copied()
                .filter(|c| !w.cache.contains(*c) && !w.failed.contains_key(c))
                .collect()
        };
        // Class A first: the frame's own missing items, nearest first (the selection's order).
        let a: Vec<ContentId> = missing(w);
        if opts.mode == Mode::Deterministic && !a.is_empty() {
            let tw = Instant::now();
            let reqs: Vec<(Priority, ContentId)> = a
                .iter()
                .enumerate()
                .map(|(k, &c)| ((0, k as u32), c))
                .collect();
            loader.request(&reqs);
            let mut left: HashSet<ContentId> = a.iter().copied().collect();
            while !left.is_empty() {
                let Some(l) = loader.take(Duration::from_secs(2)) else {
                    // Nothing for a while: ask again for what is still missing (a load lost
                    // between two frames' requests is fetched again, never waited for forever).
                    let again: Vec<(Priority, ContentId)> = left
                        .iter()
                        .enumerate()
                        .map(|(k, &c)| ((0, k as u32), c))
                        .collect();
                    loader.request(&again);
                    continue;
                };
                left.remove(&l.id);
                // The frame's own content is marked as used now, so it is not evicted by the
                // rest of the frame's arrivals.
                let id = l.id;
                w.receive(l, i, &mut f);
                w.cache.get(id, fi);
            }
            f.wait_s = tw.elapsed().as_secs_f64();
        }
        // Resolve what is drawn.
        let mut drawn = Drawn::default();
        let mut standin_nodes: Vec<usize> = Vec::new();
        let mut map_nodes: Vec<usize> = Vec::new();
        let mut mesh_slots: Vec<usize> = Vec::new();
        let mut box_slots: Vec<usize> = Vec::new();
        for &n in &maps {
            if w.cache.get(content_of_map(n), fi).is_some() {
                map_nodes.push(n);
            } else if let Some(a) = w.resident_ancestor(w.parent[n], fi) {
                standin_nodes.push(a);
            } else {
                for b in &city.nodes[n].blocks {
                    if let Some(&s) = city.slot.get(b) {
                        box_slots.push(s);
                    }
                }
            }
        }
        for &s in &meshes {
            if w.cache.get(content_of_block(s), fi).is_some() {
                mesh_slots.push(s);
            } else if let Some(a) = w.resident_ancestor(city.block_leaf[s], fi) {
                standin_nodes.push(a);
            } else {
                box_slots.push(s);
            }
        }
        standin_nodes.sort_unstable();
        standin_nodes.dedup();
        let standin_set: HashSet<usize> = standin_nodes.iter().copied().collect();
        let covered_by = |mut node: Option<usize>, parent: &[Option<usize>]| -> bool {
            while let Some(n) = node {
                if standin_set.contains(&n) {
                    return true;
                }
                node = parent[n];
            }
            false
        };
        map_nodes.retain(|&n| !covered_by(w.parent[n], &w.parent));
        let standin_kept: Vec<usize> = standin_nodes
            .iter()
            .copied()
            .filter(|&n| !covered_by(w.parent[n], &w.parent))
            .collect();
        mesh_slots.retain(|&s| !covered_by(city.block_leaf[s], &w.parent));
        box_slots.sort_unstable();
        box_slots.dedup();
        box_slots.retain(|&s| !covered_by(city.block_leaf[s], &w.parent));
        f.replaced = f.needed - map_nodes.len() - mesh_slots.len();
        for &n in &map_nodes {
            drawn
                .maps
                .push(w.cache.get(content_of_map(n), fi).expect("resident"));
            drawn.standin.push(false);
        }
        for &n in &standin_kept {
            drawn
                .maps
                .push(w.cache.get(content_of_map(n), fi).expect("resident"));
            drawn.standin.push(true);
        }
        for &s in &mesh_slots {
            drawn.meshes.push((
                city.bounds[s].id,
                w.cache.get(content_of_block(s), fi).expect("resident"),
            ));
        }
        for &s in &box_slots {
            drawn
                .boxes
                .push((city.bounds[s].id, box_standin(&city.bounds[s])));
        }
        if opts.record_blocks {
            for &n in map_nodes.iter().chain(&standin_kept) {
                f.blocks.extend(city.nodes[n].blocks.iter().copied());
            }
            f.blocks.extend(
                mesh_slots
                    .iter()
                    .chain(&box_slots)
                    .map(|&s| city.bounds[s].id),
            );
        }
        f.maps = drawn.maps.len();
        f.meshes = drawn.meshes.len();
        f.standin_maps = standin_kept.len();
        f.standin_boxes = box_slots.len();
        // Requests: the frame's missing items, their coarser stand-ins, the route ahead.
        let mut reqs: Vec<(Priority, ContentId)> = Vec::new();
        let a = missing(w);
        let (needed_class, standin_class) = if opts.needed_first { (0, 1) } else { (1, 0) };
        for (k, &c) in a.iter().enumerate() {
            reqs.push(((needed_class, k as u32), c));
        }
        let mut c_items: Vec<(u32, ContentId)> = Vec::new();
        let ancestors_of = |start: Option<usize>, out: &mut Vec<(u32, ContentId)>| {
            let mut chain = Vec::new();
            let mut node = start;
            while let Some(n) = node {
                chain.push(n);
                node = w.parent[n];
            }
            for (depth_from_top, n) in chain.iter().rev().enumerate() {
                let c = city.node_content[*n];
                if !w.cache.contains(c) && !w.failed.contains_key(&c) {
                    out.push((depth_from_top as u32, c));
                }
            }
        };
        for &n in &maps {
            if !w.cache.contains(content_of_map(n)) {
                ancestors_of(w.parent[n], &mut c_items);
            }
        }
        for &s in &meshes {
            if !w.cache.contains(content_of_block(s)) {
                ancestors_of(city.block_leaf[s], &mut c_items);
            }
        }
        c_items.sort();
        c_items.dedup_by_key(|x| x.1);
        for (k, &(_, c)) in c_items.iter().enumerate() {
            reqs.push(((standin_class, k as u32), c));
        }
        let tp = Instant::now();
        let mut queued: HashSet<ContentId> = reqs.iter().map(|r| r.1).collect();
        let mut b_count = 0u32;
        for ahead in ahead.iter().take(opts.prefetch_frames) {
            let s = w.selector.select_frozen(ahead, height, None);
            let (pm, pb) = w.wanted(&s);
            for c in pm
                .iter()
                .map(|&n| content_of_map(n))
                .chain(pb.iter().map(|&s| content_of_block(s)))
            {
                if !w.cache.contains(c) && !w.failed.contains_key(&c) && queued.insert(c) {
                    reqs.push(((2, b_count), c));
                    b_count += 1;
                }
            }
        }
        f.prefetch_s = tp.elapsed().as_secs_f64();
        f.queued = [a.len(), c_items.len(), b_count as usize];
        let th = Instant::now();
        loader.request(&reqs);
        f.handoff_s += th.elapsed().as_secs_f64();
        let td = Instant::now();
        // Every frame is drawn (the CPU hybrid frame); kept ones also with stand-ins marked.
        let (img, marked) = draw(&drawn, camera, opts.size, keep);
        f.draw_s = td.elapsed().as_secs_f64();
        if first_frame_s.is_none() {
            *first_frame_s = Some(city.startup.seconds + t_walk.elapsed().as_secs_f64());
        }
        f.resident_bytes = w.cache.used();
        f.at_s = t_walk.elapsed().as_secs_f64();
        // The fully resident twin, drawn from content loaded here, outside the budget.
        if let Some(reference) = w.reference.as_mut() {
            let mut full = Drawn::default();
            let get = |c: ContentId, reference: &mut Cache| -> Option<Arc<Resident>> {
                if let Some(r) = reference.get(c, fi) {
                    return Some(r);
                }
                match load(&city.source, None, &city.contents[c as usize]).1 {
                    Ok(r) => {
                        reference.insert(c, r, fi);
                        reference.get(c, fi)
                    }
                    Err(_) => None,
                }
            };
            if opts.mesh_reference {
                let mut all = Drawn::default();
                let mut complete = true;
                let slots = maps
                    .iter()
                    .flat_map(|&n| city.nodes[n].blocks.iter().filter_map(|b| city.slot.get(b)))
                    .copied()
                    .chain(meshes.iter().copied());
                for s in slots {
                    let Some(c) = city.block_content[s] else {
                        continue;
                    };
                    match get(c, reference) {
                        Some(r) => all.meshes.push((city.bounds[s].id, r)),
                        None => complete = false,
                    }
                }
                if complete {
                    let t = Instant::now();
                    let truth = draw(&all, camera, opts.size, false).0;
                    f.mesh_draw_s = Some(t.elapsed().as_secs_f64());
                    let (d, p) = psnr_and_diff(&img, &truth);
                    f.mesh_differing_pixels = Some(d);
                    f.mesh_psnr_db = Some(p);
                }
            }
            let mut complete = opts.check;
            for &n in maps.iter().filter(|_| opts.check) {
                match get(content_of_map(n), reference) {
                    Some(r) => {
                        full.maps.push(r);
                        full.standin.push(false);
                    }
                    None => complete = false,
                }
            }
            for &s in meshes.iter().filter(|_| opts.check) {
                match get(content_of_block(s), reference) {
                    Some(r) => full.meshes.push((city.bounds[s].id, r)),
                    None => complete = false,
                }
            }
            if complete {
                let truth = draw(&full, camera, opts.size, false).0;
                let (d, p) = psnr_and_diff(&img, &truth);
                f.differing_pixels = Some(d);
                f.psnr_db = Some(p);
            }
        }
        frames.push(f);
        (img, marked)
    }

    /// The figures of the frames drawn.
    pub fn summary(&self) -> StreamSummary {
        summarise(
            &self.frames,
            &self.opts,
            self.first_frame_s.unwrap_or(self.city.startup.seconds),
            &self.w,
        )
    }

    /// The frames and the figures.
    pub fn finish(self) -> (Vec<StreamFrame>, StreamSummary) {
        let s = self.summary();
        (self.frames, s)
    }
}

/// Plays `cameras` over `city` (see the module doc).
///
/// # Errors
/// [`StreamError::Bad`] for a far-field hierarchy the selector refuses.
pub fn play(
    city: &StreamCity,
    cameras: &[Camera],
    opts: &StreamOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<StreamRun, StreamError> {
    let mut s = Streamer::new(city, opts)?;
    let mut kept = Vec::new();
    for (i, camera) in cameras.iter().enumerate() {
        let keep = opts.keep_every.is_some_and(|n| n > 0 && i % n == 0);
        let (_, marked) = s.frame(camera, &cameras[i + 1..], keep);
        if let Some(m) = marked {
            kept.push((i, m));
        }
        progress(i + 1, cameras.len());
        if let (Some(fps), Mode::Realtime) = (opts.fps, opts.mode) {
            let due = Duration::from_secs_f64((i + 1) as f64 / fps);
            let now = Duration::from_secs_f64(s.elapsed_s());
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }
    let (frames, summary) = s.finish();
    Ok(StreamRun {
        frames,
        summary,
        kept,
    })
}

fn summarise(
    frames: &[StreamFrame],
    opts: &StreamOptions,
    first_frame_s: f64,
    w: &Walker<'_>,
) -> StreamSummary {
    let mut episodes = Vec::new();
    let mut open: Option<usize> = None;
    for f in frames {
        match (f.converged(), open) {
            (false, None) => open = Some(f.frame),
            (true, Some(s)) => {
                episodes.push(f.frame - s);
                open = None;
            }
            _ => {}
        }
    }
    let needed: usize = frames.iter().map(|f| f.needed).sum();
    let hits: usize = frames.iter().map(|f| f.hits).sum();
    let checked: Vec<&StreamFrame> = frames
        .iter()
        .filter(|f| f.differing_pixels.is_some())
        .collect();
    let px = (opts.size.0 as f64 * opts.size.1 as f64).max(1.0);
    StreamSummary {
        options: opts.clone(),
        frames: frames.len(),
        first_frame_s,
        frames_with_standins: frames.iter().filter(|f| !f.converged()).count(),
        first_converged: frames
            .iter()
            .find(|f| f.converged())
            .map(|f| (f.frame, f.at_s)),
        episodes: episodes.len() + usize::from(open.is_some()),
        episode_max_frames: episodes.iter().copied().max().unwrap_or(0),
        episode_mean_frames: if episodes.is_empty() {
            0.0
        } else {
            episodes.iter().sum::<usize>() as f64 / episodes.len() as f64
        },
        unfinished_episodes: usize::from(open.is_some()),
        loads: frames.iter().map(|f| f.loaded).sum(),
        bytes_loaded: frames.iter().map(|f| f.bytes_loaded).sum(),
        hit_rate: if needed == 0 {
            1.0
        } else {
            hits as f64 / needed as f64
        },
        evictions: w.cache.evictions,
        over_budget: w.cache.over_budget,
        resident_max_bytes: frames.iter().map(|f| f.resident_bytes).max().unwrap_or(0),
        wait_total_s: frames.iter().map(|f| f.wait_s).sum(),
        wait_max_s: frames.iter().map(|f| f.wait_s).fold(0.0, f64::max),
        handoff_max_s: frames.iter().map(|f| f.handoff_s).fold(0.0, f64::max),
        draw_mean_s: frames.iter().map(|f| f.draw_s).sum::<f64>() / frames.len().max(1) as f64,
        refusals: w.refusals.clone(),
        differing_max: (!checked.is_empty()).then(|| {
            checked
                .iter()
                .filter_map(|f| f.differing_pixels)
                .max()
                .unwrap_or(0) as f64
                / px
        }),
        psnr_min_db: checked
            .iter()
            .filter_map(|f| f.psnr_db)
            .filter(|p| p.is_finite())
            .reduce(f64::min),
        converged_but_different: (!checked.is_empty()).then(|| {
            checked
                .iter()
                .filter(|f| f.converged() && f.differing_pixels != Some(0))
                .count()
        }),
        peak_rss_bytes: crate::process::peak_rss_bytes(),
    }
}
