//! Building the relief impostors of a city (Andujar et al., §3, §4): the map size from
//! formula (9), the tree over whole blocks with leaves where the maps reach the texel size, and
//! per node its zenithal map, its façade vote, its oblique maps and its measured coverage
//! error. Nodes are built in parallel and independently (each from the meshes it holds).

use super::error::measure_node;
use super::map::{MapFrame, MapKind, ReliefMap};
use super::node::{NodeError, NodeMaps};
use super::surfels::{oblique_frame, surfels, vote};
use super::tree::{largest_block_m, Formulas, ReliefTree, TreeError, TreeParams};
use crate::blockmap::tree::MESH_BYTES_PER_TRIANGLE;
use crate::blockmap::{BlockMapError, Source};
use crate::blocks::{BlockId, BlockLayout};
use crate::city::{City, Mesh};
use crate::geom::Aabb3;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Default texel size asked for, metres (`ts` of formula (9)): the deepest maps sample the
/// blocks at this size or finer. The paper's 17 cm serves photographed façades; blockwalk's
/// façades are flat colours and windows, and at 2 m (M = 64 for blocks up to 256 m) the far
/// field of a city holds about as many bytes as its BlockMaps at K = 64.
pub const DEFAULT_TEXEL_M: f64 = 2.0;

/// Default coverage target of the oblique maps (the paper's 95 %).
pub const DEFAULT_COVERAGE: f64 = 0.95;

/// Default and largest number of oblique maps per node (the paper's nodes have at most 16).
pub const DEFAULT_MAX_OBLIQUES: usize = 16;

/// Largest oblique count accepted.
pub const MAX_OBLIQUES: usize = 64;

/// Default cap on the map side formula (9) gives (the side of the largest block over twice the
/// texel size can be large for a city with one huge block).
pub const DEFAULT_MAX_MAP_SIZE: u32 = 128;

/// Smallest and largest map side accepted.
pub const MAP_SIZE_RANGE: (u32, u32) = (4, 4096);

/// Why relief impostors cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ReliefError {
    /// A parameter is out of range.
    #[error("relief impostors: {name} = {value} is out of range ({why})")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        why: &'static str,
    },
    /// The tree cannot be built.
    #[error("relief impostors: {0}")]
    Tree(#[from] TreeError),
    /// The buildings cannot be read.
    #[error("relief impostors: {0}")]
    Source(#[from] BlockMapError),
}

/// How the impostors are built, checked where they are made ([`ReliefOptions::validate`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ReliefOptions {
    /// The tree's merge gap and depth limit.
    pub tree: TreeParams,
    /// Texel size asked for, metres (`ts`).
    pub texel_m: f64,
    /// The map side `M`; `None`: formula (9), capped at `max_map_size`.
    pub map_size: Option<u32>,
    /// Cap on the side formula (9) gives.
    pub max_map_size: u32,
    /// Share of the seeable façade area the oblique maps must see, in (0, 1].
    pub coverage_target: f64,
    /// Most oblique maps per node.
    pub max_obliques: usize,
    /// Which nodes get maps.
    pub stop: Stop,
    /// Horizon nodes: a node whose height projects to fewer pixels than this is drawn as a flat
    /// quad at mid height with its zenithal colours (the paper's §5.2 uses 2). 0, the default,
    /// draws every node by the walk: a flat quad seen at a grazing angle projects to less than a
    /// pixel and can fall between pixel centres, losing walls up to its height from the frame,
    /// which breaks the silhouette bound (measured in `docs/relief.md`).
    pub flat_px: f64,
    /// Frames over which a node's colours move from its previous three obliques to a new
    /// choice (§5.2: both sets are used for a few frames with varying weights, against the pop
    /// of a switch); 0 switches at once.
    pub blend_frames: u32,
}

/// Default frames of a switch of oblique maps (the paper's "a few frames").
pub const DEFAULT_BLEND_FRAMES: u32 = 4;

/// Most blend frames accepted.
pub const MAX_BLEND_FRAMES: u32 = 60;

/// Which nodes of the tree get maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stop {
    /// Every node (the paper's tree).
    All,
    /// From the root down, while a node's meshes take more bytes than its zenithal map and
    /// core set would: below that, meshes are cheaper to hold and to draw (the rule Cignoni et
    /// al. give BlockMaps, §4). A node that stops leaves its blocks to the meshes.
    #[default]
    Competitive,
}

crate::choice::choices!(Stop, "relief impostors' stop",
    All => "all", "Maps for every node of the tree (the paper's)";
    Competitive => "competitive", "Maps down to where a node's meshes take fewer bytes than its maps";
);

impl Default for ReliefOptions {
    fn default() -> Self {
        Self {
            tree: TreeParams::default(),
            texel_m: DEFAULT_TEXEL_M,
            map_size: None,
            max_map_size: DEFAULT_MAX_MAP_SIZE,
            coverage_target: DEFAULT_COVERAGE,
            max_obliques: DEFAULT_MAX_OBLIQUES,
            stop: Stop::default(),
            flat_px: 0.0,
            blend_frames: DEFAULT_BLEND_FRAMES,
        }
    }
}

fn bad(name: &'static str, value: f64, why: &'static str) -> ReliefError {
    ReliefError::BadParameter { name, value, why }
}

impl ReliefOptions {
    /// Checks every setting.
    ///
    /// # Errors
    /// [`ReliefError::BadParameter`] naming the setting: a texel size that is not finite and
    /// positive, a map side that is not a power of two in [`MAP_SIZE_RANGE`], a coverage target
    /// outside (0, 1], an oblique count above [`MAX_OBLIQUES`]; the tree's own checks.
    pub fn validate(&self) -> Result<(), ReliefError> {
        TreeParams::new(self.tree.gap_m, self.tree.max_depth)?;
        if !(self.texel_m.is_finite() && self.texel_m > 0.0) {
            return Err(bad("texel_m", self.texel_m, "a finite length > 0"));
        }
        for (name, m) in [
            ("map_size", self.map_size.unwrap_or(self.max_map_size)),
            ("max_map_size", self.max_map_size),
        ] {
            if !m.is_power_of_two() || !(MAP_SIZE_RANGE.0..=MAP_SIZE_RANGE.1).contains(&m) {
                return Err(bad(name, f64::from(m), "a power of two from 4 to 4096"));
            }
        }
        if !(self.coverage_target > 0.0 && self.coverage_target <= 1.0) {
            return Err(bad(
                "coverage_target",
                self.coverage_target,
                "a share in (0, 1]",
            ));
        }
        if !(self.flat_px.is_finite() && self.flat_px >= 0.0) {
            return Err(bad(
                "flat_px",
                self.flat_px,
                "a finite number of pixels >= 0",
            ));
        }
        if self.blend_frames > MAX_BLEND_FRAMES {
            return Err(bad(
                "blend_frames",
                f64::from(self.blend_frames),
                "at most 60 frames",
            ));
        }
        if self.max_obliques > MAX_OBLIQUES {
            return Err(bad("max_obliques", self.max_obliques as f64, "at most 64"));
        }
        Ok(())
    }
}

/// A node whose oblique maps did not reach the coverage target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BelowTarget {
    /// The node (index into [`ReliefField::nodes`]).
    pub node: usize,
    /// Its depth.
    pub depth: u32,
    /// The coverage its maps reached.
    pub coverage: f64,
    /// Maps it has.
    pub obliques: usize,
}

/// What was built, for reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReliefSummary {
    /// Nodes with maps.
    pub nodes: usize,
    /// Nodes of the tree (with maps or left to the meshes by the stop).
    pub tree_nodes: usize,
    /// The map side `M` (the largest; smaller nodes may have smaller maps, see
    /// [`node_map_size`]).
    pub map_size: u32,
    /// Whether `M` came from formula (9) (else given), and whether it was capped.
    pub map_size_from_formula: bool,
    /// True when formula (9) asked for more than the cap.
    pub map_size_capped: bool,
    /// Oblique maps per node: mean and largest.
    pub obliques_mean: f64,
    /// Largest.
    pub obliques_max: usize,
    /// Coverage reached: mean over nodes with walls and smallest.
    pub coverage_mean: f64,
    /// Smallest.
    pub coverage_min: f64,
    /// Share of the wall area seen from no direction (against a neighbour), over all nodes.
    pub unseeable_share: f64,
    /// Nodes below the coverage target, with their coverage (every one of them).
    pub below_target: Vec<BelowTarget>,
    /// Bytes of every map and pyramid.
    pub bytes: u64,
    /// Bytes per node (mean).
    pub bytes_per_node: f64,
    /// Bytes per km² of the root cell.
    pub bytes_per_km2: f64,
    /// Coverage error of the nodes (the paper's measure, see [`super::error`]): largest, 95th
    /// percentile and mean of the nodes' largest.
    pub coverage_error_max: f64,
    /// 95th percentile.
    pub coverage_error_p95: f64,
    /// Mean.
    pub coverage_error_mean: f64,
    /// Largest share of a node's covered pixels with a colour off by more than the tolerance
    /// (see [`super::error`]).
    pub colour_mismatch_max: f64,
    /// Smallest colour PSNR of a node's covered pixels, dB.
    pub psnr_min_db: f64,
    /// Texel range of the deepest mapped nodes (no mapped child), metres (smallest, largest).
    pub leaf_texel_m: [f64; 2],
    /// Largest declared error, metres.
    pub max_error_m: f64,
    /// Seconds to build.
    pub build_s: f64,
}

/// The relief impostors of a city: the tree and every node's maps.
#[derive(Clone, Debug)]
pub struct ReliefField {
    /// How they were built.
    pub options: ReliefOptions,
    /// The tree (over building groups that hold whole blocks).
    pub tree: ReliefTree,
    /// Formulas (3)–(9) beside the tree.
    pub formulas: Formulas,
    /// The map side `M` of formula (9) (capped), the largest of the nodes' (see
    /// [`node_map_size`]).
    pub m: u32,
    /// Every node's maps, in the tree's order (parents first; index = tree node).
    pub nodes: Vec<NodeMaps>,
    /// The summary.
    pub summary: ReliefSummary,
}

/// The map side for `opts` over a city whose largest block is `b` metres: given, or the
/// smallest power of two with `M ≥ b / (2 ts)` (formula (9)), capped; and whether it was
/// capped.
pub fn map_size(opts: &ReliefOptions, b: f64) -> (u32, bool) {
    if let Some(m) = opts.map_size {
        return (m, false);
    }
    let need = (b / (2.0 * opts.texel_m)).ceil().max(1.0);
    let m = if need >= f64::from(u32::MAX) {
        u32::MAX
    } else {
        (need as u32).next_power_of_two()
    };
    let m = m.max(MAP_SIZE_RANGE.0);
    (m.min(opts.max_map_size), m > opts.max_map_size)
}

/// The side of a node's maps: the smallest power of two (at least [`MAP_SIZE_RANGE`]'s lower
/// end) that samples a cell of `edge` metres at `texel_m` or finer, and at most the tree's `m`.
/// The paper gives every node `M × M` maps; a node already at the texel size with fewer
/// texels keeps the texel size asked for and not `M`'s finer one, which saves memory on the
/// small blocks of a city with one large one, and shows the same thing at the distance it is
/// drawn from.
pub fn node_map_size(edge: f64, texel_m: f64, m: u32) -> u32 {
    let need = (edge / texel_m).ceil().max(1.0);
    let side = if need >= f64::from(m) {
        m
    } else {
        (need as u32).next_power_of_two()
    };
    side.clamp(MAP_SIZE_RANGE.0.min(m), m)
}

/// Builds the relief impostors of `city` (its blocks `layout`, one mesh per building in
/// `building_meshes`, local frame). `progress(done, total)` hears the nodes as they finish.
///
/// # Errors
/// [`ReliefError`]: a bad option, an empty city, meshes that do not match the buildings.
pub fn build_field(
    city: &City,
    layout: &BlockLayout,
    building_meshes: &[Mesh],
    opts: &ReliefOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ReliefField, ReliefError> {
    opts.validate()?;
    let t0 = Instant::now();
    let source = Source::new(city, layout, building_meshes)?;
    let mut block_of = vec![u32::MAX; city.buildings.len()];
    for b in &layout.blocks {
        for id in &b.buildings {
            if let Some(s) = block_of.get_mut(id.0 as usize) {
                *s = b.id.0;
            }
        }
    }
    // The groups, the largest block, then M, then the tree with leaves at M·ts.
    let groups = super::tree::merge(city, opts.tree.gap_m, Some(&block_of));
    let b = largest_block_m(layout, &groups).max(opts.texel_m);
    let (m, capped) = map_size(opts, b);
    let params = opts.tree.with_leaf_edge(f64::from(m) * opts.texel_m)?;
    let tree = ReliefTree::from_groups(groups, params)?;
    let formulas = Formulas::new(&tree, opts.texel_m, b)?;
    let origin = city.frame.origin;
    let buildings_of = |n: &super::tree::ReliefNode| -> Vec<u32> {
        let mut v: Vec<u32> = n
            .groups
            .iter()
            .flat_map(|&g| tree.groups[g as usize].buildings.iter().map(|b| b.0))
            .collect();
        v.sort_unstable();
        v
    };
    // Which tree nodes get maps, parents first, with their parent's slot among them.
    let mut chosen: Vec<(usize, Option<usize>)> = Vec::new();
    let mut stack = vec![(0usize, None::<usize>)];
    while let Some((i, parent)) = stack.pop() {
        let n = &tree.nodes[i];
        if opts.stop == Stop::Competitive {
            let tris: u64 = buildings_of(n)
                .iter()
                .filter_map(|&b| building_meshes.get(b as usize))
                .map(|mesh| mesh.triangle_count() as u64)
                .sum();
            let side = u64::from(node_map_size(n.edge(), opts.texel_m, m));
            let maps = side * side * 6 * (1 + super::node::CORE_SET as u64);
            if tris * MESH_BYTES_PER_TRIANGLE as u64 <= maps {
                continue;
            }
        }
        let slot = chosen.len();
        chosen.push((i, parent));
        for c in n.children.iter().rev().flatten() {
            stack.push((*c as usize, Some(slot)));
        }
    }
    let done = AtomicUsize::new(0);
    let total = chosen.len();
    let nodes: Vec<NodeMaps> = chosen
        .par_iter()
        .map(|&(i, parent)| {
            let n = &tree.nodes[i];
            let out = build_node(
                &source,
                building_meshes,
                &block_of,
                i,
                n.depth,
                parent,
                buildings_of(n),
                [n.bounds.min[0] - origin.x, n.bounds.min[1] - origin.y],
                [n.bounds.max[0] - origin.x, n.bounds.max[1] - origin.y],
                node_map_size(n.edge(), opts.texel_m, m),
                opts,
            );
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            out
        })
        .collect();
    let summary = summarise(&nodes, &tree, m, opts, capped, t0.elapsed().as_secs_f64());
    Ok(ReliefField {
        options: *opts,
        tree,
        formulas,
        m,
        nodes,
        summary,
    })
}

/// One node: zenithal map, vote, obliques, declared buildings, measured error.
#[allow(clippy::too_many_arguments)]
fn build_node(
    source: &Source,
    building_meshes: &[Mesh],
    block_of: &[u32],
    index: usize,
    depth: u32,
    parent: Option<usize>,
    buildings: Vec<u32>,
    min: [f64; 2],
    max: [f64; 2],
    m: u32,
    opts: &ReliefOptions,
) -> NodeMaps {
    let started = Instant::now();
    let mut z = [f64::INFINITY, f64::NEG_INFINITY];
    for &b in &buildings {
        if let Some(Some(sb)) = source.buildings.get(b as usize) {
            z = [z[0].min(sb.z0), z[1].max(sb.z1)];
        }
    }
    if !(z[0].is_finite() && z[1].is_finite()) || z[0] > z[1] {
        z = [0.0, 1.0];
    }
    if z[1] - z[0] < 1e-3 {
        z[1] = z[0] + 1e-3;
    }
    let aabb = Aabb3::new(
        DVec3::new(min[0], min[1], z[0]),
        DVec3::new(max[0], max[1], z[1]),
    );
    let meshes: Vec<(u32, &Mesh)> = buildings
        .iter()
        .filter_map(|&b| building_meshes.get(b as usize).map(|mesh| (b, mesh)))
        .collect();
    let zf = MapFrame::zenithal(aabb.min, aabb.max, m);
    let (zenithal, texels_of, lost) = ReliefMap::capture_zenithal(zf, &meshes, z);
    let texel = zf.texel_m();
    // Buildings no texel shows (narrower than half a texel: at the distance the node is drawn
    // at, a fraction of a pixel), buildings with a part the map loses (a wing narrower than half
    // a texel, a texel or more from every column), and buildings narrower than a texel (twice
    // the area over the perimeter, the width of a long thin footprint): declared, not drawn
    // faithfully.
    let mut declared: Vec<u32> = buildings
        .iter()
        .copied()
        .filter(|b| {
            if !texels_of.contains_key(b) || lost.binary_search(b).is_ok() {
                return true;
            }
            let Some(Some(sb)) = source.buildings.get(*b as usize) else {
                return false;
            };
            let (mut area, mut perim) = (0.0, 0.0);
            for (k, r) in sb.rings.iter().enumerate() {
                let a: f64 = (0..r.len())
                    .map(|i| r[i].perp_dot(r[(i + 1) % r.len()]))
                    .sum::<f64>()
                    * 0.5;
                area += if k == 0 { a.abs() } else { -a.abs() };
                perim += (0..r.len())
                    .map(|i| (r[(i + 1) % r.len()] - r[i]).length())
                    .sum::<f64>();
            }
            perim > 0.0 && 2.0 * area / perim < texel
        })
        .collect();
    declared.sort_unstable();
    // The box grows to hold every covered texel's whole column: a texel at the footprints'
    // edge is covered when most of it is, and its column stands up to a texel beyond them. The
    // selection culls, and both renderers draw, with this box.
    let aabb = column_box(&zenithal, aabb);
    let pyramid = zenithal.pyramid();
    let upper: Vec<Vec<u16>> = pyramid.into_iter().skip(1).collect();
    let surf = surfels(source, &buildings, texel);
    let v = vote(&surf, &zenithal, z, opts.coverage_target, opts.max_obliques);
    let obliques: Vec<ReliefMap> = v
        .chosen
        .iter()
        .map(|c| {
            ReliefMap::capture(
                MapKind::Oblique,
                oblique_frame(c, aabb.min, aabb.max, m),
                &meshes,
                z,
            )
        })
        .collect();
    let range = z[1] - z[0];
    let eps = texel.max(0.5 * texel * std::f64::consts::SQRT_2 + range / 65535.0);
    let mut blocks: Vec<BlockId> = buildings
        .iter()
        .filter_map(|&b| block_of.get(b as usize).copied())
        .filter(|&b| b != u32::MAX)
        .map(BlockId)
        .collect();
    blocks.sort_unstable();
    blocks.dedup();
    let mut node = NodeMaps {
        node: index,
        depth,
        parent,
        blocks,
        buildings,
        aabb,
        z_range: z,
        zenithal,
        upper,
        obliques,
        vote: v,
        texel_m: texel,
        eps_m: eps,
        declared,
        error: NodeError::default(),
        flat_px: opts.flat_px,
        build_s: 0.0,
    };
    node.error = measure_node(&node, &meshes);
    node.build_s = started.elapsed().as_secs_f64();
    node
}

/// `aabb` grown to hold the whole column of every covered texel of the zenithal map `zen`.
fn column_box(zen: &ReliefMap, aabb: Aabb3) -> Aabb3 {
    let m = zen.frame.m;
    let (mut lo, mut hi) = ([u32::MAX; 2], [0u32; 2]);
    for (k, &q) in zen.depth.iter().enumerate() {
        if q != super::map::EMPTY {
            let (i, j) = (k as u32 % m, k as u32 / m);
            lo = [lo[0].min(i), lo[1].min(j)];
            hi = [hi[0].max(i + 1), hi[1].max(j + 1)];
        }
    }
    if lo[0] > hi[0] {
        return aabb;
    }
    let f = &zen.frame;
    let (a, b) = (
        f.from_map(f64::from(lo[0]), f64::from(lo[1]), 0.0),
        f.from_map(f64::from(hi[0]), f64::from(hi[1]), 0.0),
    );
    Aabb3::new(
        DVec3::new(a.x.min(aabb.min.x), a.y.min(aabb.min.y), aabb.min.z),
        DVec3::new(b.x.max(aabb.max.x), b.y.max(aabb.max.y), aabb.max.z),
    )
}

/// One level of the built tree, as the paper's Table 1 lists its levels.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelReport {
    /// Depth.
    pub depth: u32,
    /// Nodes with maps.
    pub nodes: usize,
    /// Mean zenithal texel, metres.
    pub texel_m: f64,
    /// Mean oblique maps per node.
    pub obliques_mean: f64,
    /// Mean coverage reached (nodes with walls).
    pub coverage_mean: f64,
    /// Largest coverage error of a node.
    pub coverage_error_max: f64,
    /// Bytes of the level's maps.
    pub bytes: u64,
    /// Mean seconds per node to build its maps (the paper's "map acquisition").
    pub seconds_per_node: f64,
}

impl ReliefField {
    /// Per level of the tree.
    pub fn levels(&self) -> Vec<LevelReport> {
        let depth = self.nodes.iter().map(|n| n.depth).max().unwrap_or(0);
        (0..=depth)
            .map(|d| {
                let at: Vec<&NodeMaps> = self.nodes.iter().filter(|n| n.depth == d).collect();
                let k = at.len().max(1) as f64;
                let walls: Vec<&&NodeMaps> =
                    at.iter().filter(|n| n.vote.seeable_m2 > 0.0).collect();
                LevelReport {
                    depth: d,
                    nodes: at.len(),
                    texel_m: at.iter().map(|n| n.texel_m).sum::<f64>() / k,
                    obliques_mean: at.iter().map(|n| n.obliques.len() as f64).sum::<f64>() / k,
                    coverage_mean: if walls.is_empty() {
                        1.0
                    } else {
                        walls.iter().map(|n| n.vote.coverage).sum::<f64>() / walls.len() as f64
                    },
                    coverage_error_max: at
                        .iter()
                        .map(|n| n.error.coverage_error_max)
                        .fold(0.0, f64::max),
                    bytes: at.iter().map(|n| n.bytes()).sum(),
                    seconds_per_node: at.iter().map(|n| n.build_s).sum::<f64>() / k,
                }
            })
            .collect()
    }

    /// Everything `blockwalk relief` reports.
    pub fn report(&self) -> ReliefReport {
        ReliefReport {
            options: self.options,
            summary: self.summary.clone(),
            levels: self.levels(),
            tree_levels: self.tree.levels(),
            formulas: self.formulas.clone(),
            groups: self.tree.groups.len(),
            median_splits: self.tree.median_splits,
        }
    }
}

/// The build's report: the summary, per level, the tree's levels (δ) and the formulas.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReliefReport {
    /// How it was built.
    pub options: ReliefOptions,
    /// What was built.
    pub summary: ReliefSummary,
    /// Per level.
    pub levels: Vec<LevelReport>,
    /// The tree's levels: cells' edges and the overlap ratio δ.
    pub tree_levels: Vec<super::tree::LevelStats>,
    /// Formulas (3)–(9) beside the tree.
    pub formulas: Formulas,
    /// Building groups (whole blocks, and footprints within the gap).
    pub groups: usize,
    /// Splits about the median barycentre.
    pub median_splits: usize,
}

fn summarise(
    nodes: &[NodeMaps],
    tree: &ReliefTree,
    m: u32,
    opts: &ReliefOptions,
    capped: bool,
    build_s: f64,
) -> ReliefSummary {
    let n = nodes.len().max(1) as f64;
    let with_walls: Vec<&NodeMaps> = nodes.iter().filter(|x| x.vote.seeable_m2 > 0.0).collect();
    let bytes: u64 = nodes.iter().map(|x| x.bytes()).sum();
    let root = tree.nodes.first().map_or(0.0, |r| r.edge());
    let km2 = (root * root / 1e6).max(1e-12);
    let mut errs: Vec<f64> = nodes.iter().map(|x| x.error.coverage_error_max).collect();
    errs.sort_by(f64::total_cmp);
    let p95 = errs
        .get(((errs.len() as f64 * 0.95).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    let wall: f64 = nodes.iter().map(|x| x.vote.wall_m2).sum();
    let seeable: f64 = nodes.iter().map(|x| x.vote.seeable_m2).sum();
    // The deepest mapped nodes: no mapped child.
    let mut has_child = vec![false; nodes.len()];
    for x in nodes {
        if let Some(p) = x.parent {
            has_child[p] = true;
        }
    }
    let leaves: Vec<f64> = nodes
        .iter()
        .zip(&has_child)
        .filter(|(_, &c)| !c)
        .map(|(x, _)| x.texel_m)
        .collect();
    ReliefSummary {
        nodes: nodes.len(),
        tree_nodes: tree.nodes.len(),
        map_size: m,
        map_size_from_formula: opts.map_size.is_none(),
        map_size_capped: capped,
        obliques_mean: nodes.iter().map(|x| x.obliques.len() as f64).sum::<f64>() / n,
        obliques_max: nodes.iter().map(|x| x.obliques.len()).max().unwrap_or(0),
        coverage_mean: if with_walls.is_empty() {
            1.0
        } else {
            with_walls.iter().map(|x| x.vote.coverage).sum::<f64>() / with_walls.len() as f64
        },
        coverage_min: with_walls
            .iter()
            .map(|x| x.vote.coverage)
            .fold(1.0, f64::min),
        unseeable_share: if wall > 0.0 {
            1.0 - seeable / wall
        } else {
            0.0
        },
        below_target: nodes
            .iter()
            .enumerate()
            .filter(|(_, x)| x.vote.seeable_m2 > 0.0 && x.vote.coverage < opts.coverage_target)
            .map(|(i, x)| BelowTarget {
                node: i,
                depth: x.depth,
                coverage: x.vote.coverage,
                obliques: x.obliques.len(),
            })
            .collect(),
        bytes,
        bytes_per_node: bytes as f64 / n,
        bytes_per_km2: bytes as f64 / km2,
        coverage_error_max: errs.last().copied().unwrap_or(0.0),
        coverage_error_p95: p95,
        coverage_error_mean: errs.iter().sum::<f64>() / n,
        colour_mismatch_max: nodes
            .iter()
            .map(|x| x.error.colour_mismatch_max)
            .fold(0.0, f64::max),
        psnr_min_db: nodes
            .iter()
            .map(|x| x.error.psnr_min_db)
            .fold(f64::INFINITY, f64::min),
        leaf_texel_m: [
            leaves.iter().copied().fold(f64::INFINITY, f64::min),
            leaves.iter().copied().fold(0.0, f64::max),
        ],
        max_error_m: nodes.iter().map(|x| x.eps_m).fold(0.0, f64::max),
        build_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_options_are_refused_by_name() {
        assert!(ReliefOptions::default().validate().is_ok());
        let cases: [(ReliefOptions, &str); 10] = [
            (
                ReliefOptions {
                    blend_frames: 61,
                    ..Default::default()
                },
                "blend_frames",
            ),
            (
                ReliefOptions {
                    flat_px: -1.0,
                    ..Default::default()
                },
                "flat_px",
            ),
            (
                ReliefOptions {
                    max_obliques: 65,
                    ..Default::default()
                },
                "max_obliques",
            ),
            (
                ReliefOptions {
                    texel_m: 0.0,
                    ..Default::default()
                },
                "texel_m",
            ),
            (
                ReliefOptions {
                    texel_m: f64::NAN,
                    ..Default::default()
                },
                "texel_m",
            ),
            (
                ReliefOptions {
                    map_size: Some(100),
                    ..Default::default()
                },
                "map_size",
            ),
            (
                ReliefOptions {
                    map_size: Some(8192),
                    ..Default::default()
                },
                "map_size",
            ),
            (
                ReliefOptions {
                    coverage_target: 0.0,
                    ..Default::default()
                },
                "coverage_target",
            ),
            (
                ReliefOptions {
                    coverage_target: 1.01,
                    ..Default::default()
                },
                "coverage_target",
            ),
            (
                ReliefOptions {
                    tree: TreeParams {
                        gap_m: -1.0,
                        ..TreeParams::default()
                    },
                    ..Default::default()
                },
                "gap_m",
            ),
        ];
        for (o, name) in cases {
            let e = o.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }

    #[test]
    fn small_nodes_get_maps_just_fine_enough() {
        // 100 m at 1 m a texel: 128 texels, capped at M.
        assert_eq!(node_map_size(100.0, 1.0, 128), 128);
        assert_eq!(node_map_size(100.0, 1.0, 64), 64);
        // 20 m: 32 texels reach 1 m (0.63 m); 5 m: the smallest side, 4.
        assert_eq!(node_map_size(20.0, 1.0, 128), 32);
        assert_eq!(node_map_size(5.0, 1.0, 128), 8);
        assert_eq!(node_map_size(0.5, 1.0, 128), 4);
        // Never above M, never a side that is not a power of two.
        for e in [1.0, 7.0, 33.3, 1e4] {
            let m = node_map_size(e, 0.5, 64);
            assert!(m.is_power_of_two() && m <= 64 && m as f64 * 0.5 >= e.min(32.0));
        }
    }

    #[test]
    fn formula_nine_picks_the_smallest_power_of_two() {
        let o = ReliefOptions {
            texel_m: 0.17,
            max_map_size: 4096,
            ..Default::default()
        };
        // The paper's b = 85 m, ts = 17 cm: M ≥ 250, so 256.
        assert_eq!(map_size(&o, 85.0), (256, false));
        let o = ReliefOptions {
            texel_m: 0.17,
            ..Default::default()
        };
        assert_eq!(map_size(&o, 85.0), (128, true), "capped at 128");
        let o = ReliefOptions {
            map_size: Some(32),
            ..Default::default()
        };
        assert_eq!(map_size(&o, 85.0), (32, false));
    }
}
