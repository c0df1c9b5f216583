//! BlockMaps for the nodes of the block quadtree (Cignoni et al., §4: "reusing the same spatial
//! partitioning"; BLOCKMAPS.md B.2): one map per BqR-tree node, over the node's whole blocks, so
//! no building is ever cut and a node switches between meshes and its map with disjoint block
//! sets. Every map is built from the source prisms, not from its children (Di Benedetto, §4.3.1 builds
//! internal nodes from the children because its data is out of core; ours fits in memory, and
//! this gives each node its own measured bound with no error accumulation). Building inner
//! nodes from their children's maps is the option [`super::children`]
//! (`TreeOptions::parents`).

use super::build::{build_map, BuildOptions, BuildStats, Parents, ResampleStats};
use super::children::{build_from_children, node_square, resample_distances};
use super::error::{measure, ErrorReport};
use super::layout::BlockMap;
use super::source::Source;
use super::BlockMapError;
use crate::blocks::{BlockId, BlockLayout};
use crate::index::BqrTree;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Where the quadtree of maps stops.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stop {
    /// Maps for the first `n` map levels (root = level 0).
    Levels(u32),
    /// Down to nodes of at most `m` blocks (those get the last maps).
    LeafBlocks(usize),
    /// Seed 000 §4: stop where storing the meshes costs less than a map (mesh bytes ≤ map
    /// bytes; a node of one block always stops).
    Competitive,
}

/// Coverage error a checked view should stay under (Andujar et al., §4, Fig. 4: 0.01).
pub const COVERAGE_TARGET: f64 = 0.01;

/// Bytes of a block's meshes per triangle, as the mesh renderer stores them: three unshared
/// vertices of position + normal (24 B each) and three u32 indices.
pub const MESH_BYTES_PER_TRIANGLE: usize = 3 * 24 + 3 * 4;

/// Options of [`build_tree`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TreeOptions {
    /// Per-map construction options.
    pub build: BuildOptions,
    /// Where to stop.
    pub stop: Stop,
    /// How the maps of inner nodes are built: from the polygons, or from their children's maps.
    pub parents: Parents,
}

impl Default for TreeOptions {
    fn default() -> Self {
        Self {
            build: BuildOptions::default(),
            stop: Stop::Competitive,
            parents: Parents::Polygons,
        }
    }
}

/// One node's map.
#[derive(Clone, Debug)]
pub struct NodeMap {
    /// The BqR node (preorder index).
    pub node: usize,
    /// Its linear quadtree key.
    pub key: u64,
    /// Map level (number of mapped ancestors).
    pub level: u32,
    /// Index of the parent map in [`MapTree::maps`].
    pub parent: Option<usize>,
    /// The node's blocks.
    pub blocks: Vec<BlockId>,
    /// Its buildings (indices into `City::buildings`).
    pub buildings: Vec<u32>,
    /// The map; `meta.eps_m` is the declared bound made monotone (≥ every descendant's).
    pub map: BlockMap,
    /// Construction counts.
    pub stats: BuildStats,
    /// Measured error of this map alone.
    pub error: ErrorReport,
}

impl NodeMap {
    /// The buildings this map declares it does not draw faithfully: its thin features and the
    /// buildings no texel holds (indices into `City::buildings`, sorted, without repeats).
    pub fn declared_buildings(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .error
            .thin
            .iter()
            .map(|t| t.building)
            .chain(self.stats.dropped_buildings.iter().map(|b| b.0))
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// All maps of a city.
#[derive(Clone, Debug, Default)]
pub struct MapTree {
    /// Maps, parents before children (preorder).
    pub maps: Vec<NodeMap>,
}

/// The nodes that get a map, parents first: `(node, level, parent slot)`.
pub fn select_nodes(tree: &BqrTree, k: u32, stop: Stop) -> Vec<(usize, u32, Option<usize>)> {
    let map_bytes = (super::layout::image_width(k) * k * 4) as usize;
    let blocks = tree.blocks();
    let mut out = Vec::new();
    if tree.nodes_len() == 0 {
        return out;
    }
    // (node, level, parent slot)
    let mut stack = vec![(0usize, 0u32, None::<usize>)];
    while let Some((n, level, parent)) = stack.pop() {
        let Some(v) = tree.node(n) else { continue };
        let kids: Vec<usize> = v.children.iter().flatten().copied().collect();
        // A chain node whose single child holds the same blocks: map the child instead.
        if kids.len() == 1 {
            if let Some(c) = tree.node(kids[0]) {
                if c.blocks == v.blocks {
                    stack.push((kids[0], level, parent));
                    continue;
                }
            }
        }
        let nblocks = v.blocks.len();
        let tris: usize = blocks[v.blocks.clone()]
            .iter()
            .map(|b| b.triangles as usize)
            .sum();
        let make = match stop {
            Stop::Levels(l) => level < l,
            Stop::LeafBlocks(_) => true,
            Stop::Competitive => nblocks > 1 && tris * MESH_BYTES_PER_TRIANGLE > map_bytes,
        };
        if !make || tris == 0 {
            continue;
        }
        let slot = out.len();
        out.push((n, level, parent));
        let deeper = match stop {
            Stop::Levels(l) => level + 1 < l,
            Stop::LeafBlocks(m) => nblocks > m,
            Stop::Competitive => true,
        };
        if deeper {
            for c in kids.into_iter().rev() {
                stack.push((c, level + 1, Some(slot)));
            }
        }
    }
    out
}

/// Builds and measures the maps of every selected node in parallel (deterministic: each map
/// depends only on its node), then makes ε monotone: a parent's declared ε ≥ its children's
/// (BLOCKMAPS.md B.3). `progress(done, total)` is called as maps finish.
///
/// # Errors
/// The first construction error, naming the node.
pub fn build_tree(
    source: &Source,
    layout: &BlockLayout,
    tree: &BqrTree,
    opts: &TreeOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<MapTree, BlockMapError> {
    if opts.parents == Parents::Children {
        return build_tree_from_children(source, layout, tree, opts, progress);
    }
    let sel = select_nodes(tree, opts.build.k, opts.stop);
    let total = sel.len();
    let done = AtomicUsize::new(0);
    let built: Result<Vec<NodeMap>, BlockMapError> = sel
        .par_iter()
        .map(|&(n, level, parent)| {
            let v = tree.node(n).expect("selected nodes exist");
            let blocks: Vec<BlockId> = tree.blocks()[v.blocks.clone()]
                .iter()
                .map(|b| b.id)
                .collect();
            let buildings = source.buildings_of(layout, &blocks);
            let (map, buildings, stats, error) =
                polygon_map(source, &buildings, &opts.build, v.key)?;
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(d, total);
            Ok(NodeMap {
                node: n,
                key: v.key,
                level,
                parent,
                blocks,
                buildings,
                map,
                stats,
                error,
            })
        })
        .collect();
    let mut maps = built?;
    monotone_eps(&mut maps);
    Ok(MapTree { maps })
}

/// Raises every parent's declared ε to at least its children's (children come after parents:
/// one backward sweep).
fn monotone_eps(maps: &mut [NodeMap]) {
    for i in (0..maps.len()).rev() {
        if let Some(p) = maps[i].parent {
            let e = maps[i].map.meta.eps_m;
            let pe = &mut maps[p].map.meta.eps_m;
            *pe = pe.max(e);
        }
    }
}

/// A node's map from the polygons, measured, its ε and key in the map's meta.
fn polygon_map(
    source: &Source,
    buildings: &[u32],
    opts: &BuildOptions,
    key: u64,
) -> Result<(BlockMap, Vec<u32>, BuildStats, ErrorReport), BlockMapError> {
    let (mut map, kept, stats) =
        build_map(source, buildings, opts).map_err(|e| BlockMapError::Node {
            key,
            what: e.to_string(),
        })?;
    let error = measure(&map, source, &kept);
    map.meta.eps_measured_m = error.measured_m;
    map.meta.eps_m = error.declared_m;
    map.meta.node_key = key;
    Ok((map, kept, stats, error))
}

/// [`build_tree`] with every map that has mapped children built from them
/// ([`build_from_children`]); maps without are built from the polygons. Bottom-up, one level
/// at a time, the maps of a level in parallel (deterministic: each map depends only on its
/// node and its children's maps).
///
/// # Errors
/// The first construction error, naming the node.
fn build_tree_from_children(
    source: &Source,
    layout: &BlockLayout,
    tree: &BqrTree,
    opts: &TreeOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<MapTree, BlockMapError> {
    let sel = select_nodes(tree, opts.build.k, opts.stop);
    let total = sel.len();
    let done = AtomicUsize::new(0);
    let mut kids: Vec<Vec<usize>> = vec![Vec::new(); total];
    for (slot, &(_, _, parent)) in sel.iter().enumerate() {
        if let Some(p) = parent {
            kids[p].push(slot);
        }
    }
    let max_level = sel.iter().map(|s| s.1).max().unwrap_or(0);
    let mut built: Vec<Option<NodeMap>> = (0..total).map(|_| None).collect();
    for level in (0..=max_level).rev() {
        let slots: Vec<usize> = (0..total).filter(|&q| sel[q].1 == level).collect();
        let maps: Result<Vec<(usize, NodeMap)>, BlockMapError> = slots
            .par_iter()
            .map(|&slot| {
                let (n, level, parent) = sel[slot];
                let v = tree.node(n).expect("selected nodes exist");
                let blocks: Vec<BlockId> = tree.blocks()[v.blocks.clone()]
                    .iter()
                    .map(|b| b.id)
                    .collect();
                let buildings = source.buildings_of(layout, &blocks);
                let node = if kids[slot].is_empty() {
                    let (map, buildings, stats, error) =
                        polygon_map(source, &buildings, &opts.build, v.key)?;
                    NodeMap {
                        node: n,
                        key: v.key,
                        level,
                        parent,
                        blocks,
                        buildings,
                        map,
                        stats,
                        error,
                    }
                } else {
                    let mapped: Vec<&NodeMap> = kids[slot]
                        .iter()
                        .map(|&q| built[q].as_ref().expect("children are built first"))
                        .collect();
                    parent_from_children(
                        source, layout, tree, opts, n, level, parent, blocks, buildings, &mapped,
                    )?
                };
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(d, total);
                Ok((slot, node))
            })
            .collect();
        for (slot, m) in maps? {
            built[slot] = Some(m);
        }
    }
    let mut maps: Vec<NodeMap> = built
        .into_iter()
        .map(|m| m.expect("every selected node is built"))
        .collect();
    monotone_eps(&mut maps);
    Ok(MapTree { maps })
}

/// One parent from its mapped children and, for the blocks no mapped child holds, maps built
/// from the polygons per BqR kid (and one for blocks of the node in no kid).
#[allow(clippy::too_many_arguments)]
fn parent_from_children(
    source: &Source,
    layout: &BlockLayout,
    tree: &BqrTree,
    opts: &TreeOptions,
    n: usize,
    level: u32,
    parent: Option<usize>,
    blocks: Vec<BlockId>,
    buildings: Vec<u32>,
    mapped: &[&NodeMap],
) -> Result<NodeMap, BlockMapError> {
    let v = tree.node(n).expect("selected nodes exist");
    let held: std::collections::HashSet<BlockId> = mapped
        .iter()
        .flat_map(|m| m.blocks.iter().copied())
        .collect();
    // Blocks no mapped child holds, grouped by the BqR kid they are in.
    let mut groups: Vec<Vec<BlockId>> = Vec::new();
    let mut grouped: std::collections::HashSet<BlockId> = Default::default();
    for c in v.children.iter().flatten() {
        let Some(cv) = tree.node(*c) else { continue };
        let g: Vec<BlockId> = tree.blocks()[cv.blocks.clone()]
            .iter()
            .map(|b| b.id)
            .filter(|b| !held.contains(b))
            .collect();
        grouped.extend(g.iter().copied());
        if !g.is_empty() {
            groups.push(g);
        }
    }
    let rest: Vec<BlockId> = blocks
        .iter()
        .copied()
        .filter(|b| !held.contains(b) && !grouped.contains(b))
        .collect();
    if !rest.is_empty() {
        groups.push(rest);
    }
    let mut temp: Vec<(BlockMap, BuildStats)> = Vec::new();
    for g in &groups {
        let bs = source.buildings_of(layout, g);
        if bs.is_empty() {
            continue;
        }
        let (map, _, stats, _) = polygon_map(source, &bs, &opts.build, v.key)?;
        temp.push((map, stats));
    }
    let children: Vec<&BlockMap> = mapped
        .iter()
        .map(|m| &m.map)
        .chain(temp.iter().map(|t| &t.0))
        .collect();
    let Some((min, side, zmax)) = node_square(source, &buildings) else {
        return Err(BlockMapError::Node {
            key: v.key,
            what: "no building to map".into(),
        });
    };
    let (mut map, mut stats) = build_from_children(&children, min, side, zmax, &opts.build)
        .map_err(|e| BlockMapError::Node {
            key: v.key,
            what: e.to_string(),
        })?;
    stats.buildings = buildings.len();
    let mut dropped: Vec<crate::city::BuildingId> = mapped
        .iter()
        .flat_map(|m| m.stats.dropped_buildings.iter().copied())
        .chain(
            temp.iter()
                .flat_map(|t| t.1.dropped_buildings.iter().copied()),
        )
        .collect();
    dropped.sort_unstable_by_key(|b| b.0);
    dropped.dedup();
    stats.dropped_buildings = dropped;
    let child_eps = children.iter().map(|c| c.meta.eps_m).fold(0.0, f64::max);
    let (to, from) = resample_distances(&map, &children);
    let derived = map.half_voxel_diagonal().max(child_eps + to.max(from));
    let error = measure(&map, source, &buildings);
    map.meta.eps_measured_m = error.measured_m;
    map.meta.eps_m = derived.max(error.measured_m);
    map.meta.node_key = v.key;
    stats.from_children = Some(ResampleStats {
        children: children.len(),
        from_polygons: temp.len(),
        child_eps_max_m: child_eps,
        to_children_m: to,
        from_children_m: from,
        derived_eps_m: derived,
        measured_over_derived: error.measured_m > derived,
    });
    Ok(NodeMap {
        node: n,
        key: v.key,
        level,
        parent,
        blocks,
        buildings,
        map,
        stats,
        error,
    })
}

/// The hierarchy [`build_tree`] would build over `tree`, with empty maps whose declared ε is half
/// their voxel diagonal (Cignoni et al., §3.3) made monotone upward: what selection sees of a map tree
/// (boxes, ε, blocks), built in milliseconds. For selection tests and for timing selection
/// apart from construction; nothing here is drawable.
///
/// # Errors
/// [`BlockMapError::BadParameter`] when `k` is not 32, 64 or 128.
pub fn skeleton_tree(tree: &BqrTree, k: u32, stop: Stop) -> Result<MapTree, BlockMapError> {
    let sel = select_nodes(tree, k, stop);
    let mut maps = Vec::with_capacity(sel.len());
    for (n, level, parent) in sel {
        let v = tree.node(n).expect("selected nodes exist");
        let b = v.aabb;
        let side = (b.max.x - b.min.x).max(b.max.y - b.min.y).max(1e-3);
        let zmin = if b.min.z.is_finite() { b.min.z } else { 0.0 };
        let zmax = b.max.z.max(zmin + 1.0);
        let mut map = BlockMap::empty(k, glam::DVec3::new(b.min.x, b.min.y, zmin), side, zmax)?;
        map.meta.eps_m = map.half_voxel_diagonal();
        map.meta.node_key = v.key;
        let blocks: Vec<BlockId> = tree.blocks()[v.blocks.clone()]
            .iter()
            .map(|b| b.id)
            .collect();
        maps.push(NodeMap {
            node: n,
            key: v.key,
            level,
            parent,
            blocks,
            buildings: Vec::new(),
            map,
            stats: BuildStats::default(),
            error: ErrorReport::default(),
        });
    }
    for i in (0..maps.len()).rev() {
        if let Some(p) = maps[i].parent {
            let e = maps[i].map.meta.eps_m;
            let pe = &mut maps[p].map.meta.eps_m;
            *pe = pe.max(e);
        }
    }
    Ok(MapTree { maps })
}

/// A broken invariant of the map hierarchy (BLOCKMAPS.md B.3, D.2), naming the nodes.
#[derive(Clone, Debug, PartialEq, Serialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TreeViolation {
    /// A parent's declared ε is below a child's (ε must not grow downward).
    #[error("ε of node {parent} ({parent_eps_m} m) < ε of its child {child} ({child_eps_m} m)")]
    EpsGrowsDownward {
        /// Parent key.
        parent: u64,
        /// Child key.
        child: u64,
        /// Parent ε, metres.
        parent_eps_m: f64,
        /// Child ε, metres.
        child_eps_m: f64,
    },
    /// A child's block (or building) is not in its parent.
    #[error("{what} {id} of node {child} is not in its parent {parent}")]
    NotInParent {
        /// Parent key.
        parent: u64,
        /// Child key.
        child: u64,
        /// `block` or `building`.
        what: &'static str,
        /// Its id.
        id: u32,
    },
    /// Two children of one parent hold the same block.
    #[error("block {block} is in both children {a} and {b} of one parent")]
    SharedBlock {
        /// One child key.
        a: u64,
        /// The other.
        b: u64,
        /// The block.
        block: u32,
    },
    /// A child's content (its box's top, or a non-empty texel) lies outside its parent's box.
    #[error("node {child} reaches outside its parent {parent}'s box: {what}")]
    OutsideParent {
        /// Parent key.
        parent: u64,
        /// Child key.
        child: u64,
        /// Which part.
        what: String,
    },
    /// A parent slot that does not precede its child.
    #[error("map {index} names parent slot {parent}, which does not come before it")]
    BadParent {
        /// The map's slot.
        index: usize,
        /// The parent slot.
        parent: usize,
    },
}

impl MapTree {
    /// The hierarchy's broken invariants (BLOCKMAPS.md B.3), none when it is sound: every
    /// parent precedes its children; a parent's ε ≥ its children's; a child's blocks and
    /// buildings are its parent's, and siblings share no block; a child's box is no higher than
    /// its parent's and every non-empty texel of the child lies inside the parent's box (up to
    /// one texel of either map). A child's square may stick out of its parent's over streets:
    /// its content may not.
    pub fn invariant_violations(&self) -> Vec<TreeViolation> {
        let mut out = Vec::new();
        let mut siblings: std::collections::HashMap<(usize, BlockId), u64> =
            std::collections::HashMap::new();
        for (i, m) in self.maps.iter().enumerate() {
            let Some(p) = m.parent else { continue };
            if p >= i {
                out.push(TreeViolation::BadParent {
                    index: i,
                    parent: p,
                });
                continue;
            }
            let pm = &self.maps[p];
            if pm.map.meta.eps_m < m.map.meta.eps_m {
                out.push(TreeViolation::EpsGrowsDownward {
                    parent: pm.key,
                    child: m.key,
                    parent_eps_m: pm.map.meta.eps_m,
                    child_eps_m: m.map.meta.eps_m,
                });
            }
            let pb: std::collections::HashSet<BlockId> = pm.blocks.iter().copied().collect();
            for b in &m.blocks {
                if !pb.contains(b) {
                    out.push(TreeViolation::NotInParent {
                        parent: pm.key,
                        child: m.key,
                        what: "block",
                        id: b.0,
                    });
                }
                if let Some(&other) = siblings.get(&(p, *b)) {
                    out.push(TreeViolation::SharedBlock {
                        a: other,
                        b: m.key,
                        block: b.0,
                    });
                } else {
                    siblings.insert((p, *b), m.key);
                }
            }
            let pbuild: std::collections::HashSet<u32> = pm.buildings.iter().copied().collect();
            for &bi in &m.buildings {
                if !pbuild.contains(&bi) {
                    out.push(TreeViolation::NotInParent {
                        parent: pm.key,
                        child: m.key,
                        what: "building",
                        id: bi,
                    });
                }
            }
            let (a, b) = (pm.map.aabb(), m.map.aabb());
            let slack = 1e-6 * (1.0 + a.extent().max_element());
            if a.max.z + slack < b.max.z {
                out.push(TreeViolation::OutsideParent {
                    parent: pm.key,
                    child: m.key,
                    what: format!("top {} m above the parent's {} m", b.max.z, a.max.z),
                });
            }
            if let Some(c) = occupied_box(&m.map) {
                let pad = pm.map.texel_m() + m.map.texel_m() + slack;
                if c.min.x < a.min.x - pad
                    || c.min.y < a.min.y - pad
                    || c.max.x > a.max.x + pad
                    || c.max.y > a.max.y + pad
                {
                    out.push(TreeViolation::OutsideParent {
                        parent: pm.key,
                        child: m.key,
                        what: format!(
                            "non-empty texels over x {:.2}..{:.2}, y {:.2}..{:.2} m; parent box x {:.2}..{:.2}, y {:.2}..{:.2} m",
                            c.min.x, c.max.x, c.min.y, c.max.y, a.min.x, a.max.x, a.min.y, a.max.y
                        ),
                    });
                }
            }
        }
        out
    }

    /// Checks the hierarchy's invariants ([`MapTree::invariant_violations`]).
    ///
    /// # Panics
    /// On a broken invariant, listing them all.
    pub fn check_invariants(&self) {
        let v = self.invariant_violations();
        assert!(
            v.is_empty(),
            "map tree invariants broken:\n{}",
            v.iter()
                .map(|e| e.to_string())
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
}

/// The plan-view box of a map's non-empty texels (height code > 0), none when all are empty.
fn occupied_box(map: &BlockMap) -> Option<crate::geom::Aabb3> {
    let k = map.k();
    let s = map.texel_m();
    let (mut i0, mut i1, mut j0, mut j1) = (u32::MAX, 0u32, u32::MAX, 0u32);
    for j in 0..k {
        for i in 0..k {
            if map.height_code(i, j) > 0 {
                i0 = i0.min(i);
                i1 = i1.max(i);
                j0 = j0.min(j);
                j1 = j1.max(j);
            }
        }
    }
    if i0 == u32::MAX {
        return None;
    }
    let m = map.meta.min;
    Some(crate::geom::Aabb3::new(
        glam::DVec3::new(m[0] + i0 as f64 * s, m[1] + j0 as f64 * s, m[2]),
        glam::DVec3::new(
            m[0] + (i1 + 1) as f64 * s,
            m[1] + (j1 + 1) as f64 * s,
            map.meta.zmax,
        ),
    ))
}

/// Options of [`build_city_maps`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CityMapsOptions {
    /// Which maps and how they are built.
    pub tree: TreeOptions,
    /// Maps to check against the oracle's mesh image (one seeded random view each, projected
    /// error 1 px), spread evenly over the list.
    pub checks: usize,
    /// Size of the check images.
    pub check_size: (u32, u32),
}

impl Default for CityMapsOptions {
    fn default() -> Self {
        Self {
            tree: TreeOptions::default(),
            checks: 8,
            check_size: (160, 90),
        }
    }
}

/// The maps of a city and their figures: what `blockwalk blockmaps` prints.
#[derive(Clone, Debug)]
pub struct CityMaps {
    /// City name.
    pub city: String,
    /// The maps.
    pub maps: MapTree,
    /// Seconds spent building and measuring the maps (not loading, extruding or checking).
    pub build_s: f64,
    /// Area of the blocks' box, km².
    pub area_km2: f64,
    /// The image checks: node key and figures.
    pub checks: Vec<(u64, super::compare::ViewCompare)>,
}

/// Builds the BlockMaps of a city in one call: the per-building prisms, the block quadtree over
/// `bounds`, every selected node's map ([`build_tree`], parallel), the hierarchy's invariants,
/// and `opts.checks` ray-cast images against the oracle's mesh images.
///
/// # Errors
/// [`BlockMapError::BadParameter`] when the quadtree cannot be built or the options are out of
/// range; the first map that fails, naming its node.
pub fn build_city_maps(
    city: &crate::city::City,
    layout: &BlockLayout,
    bounds: &[crate::index::BlockBounds],
    opts: &CityMapsOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<CityMaps, BlockMapError> {
    let meshes = crate::city::extrude::extrude_city(city);
    build_city_maps_from(city, layout, bounds, &meshes, opts, progress)
}

/// [`build_city_maps`] from the buildings' meshes already extruded (`meshes[i]`: building `i`'s
/// mesh, as `city::extrude::extrude_city` returns them).
///
/// # Errors
/// As [`build_city_maps`].
pub fn build_city_maps_from(
    city: &crate::city::City,
    layout: &BlockLayout,
    bounds: &[crate::index::BlockBounds],
    meshes: &[crate::city::Mesh],
    opts: &CityMapsOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<CityMaps, BlockMapError> {
    let tree = BqrTree::build(bounds, &crate::index::BqrParams::default()).map_err(|e| {
        BlockMapError::BadParameter(format!("the block quadtree of {}: {e}", city.name))
    })?;
    let source = Source::new(city, layout, meshes)?;
    let t0 = std::time::Instant::now();
    let maps = build_tree(&source, layout, &tree, &opts.tree, progress)?;
    let build_s = t0.elapsed().as_secs_f64();
    if let Some(v) = maps.invariant_violations().first() {
        return Err(BlockMapError::BadParameter(format!(
            "the map tree of {} breaks an invariant: {v}",
            city.name
        )));
    }
    let mut checks = Vec::new();
    if opts.checks > 0 && !maps.maps.is_empty() {
        let n = opts.checks.min(maps.maps.len());
        let (w, h) = opts.check_size;
        let picked: Vec<&NodeMap> = (0..n)
            .map(|q| &maps.maps[q * maps.maps.len() / n])
            .collect();
        checks = picked
            .par_iter()
            .map(|m| {
                let cam = super::compare::random_views(&m.map, 1, m.key, h)[0];
                let thin = m.declared_buildings();
                (
                    m.key,
                    super::compare::compare_view_with_thin(
                        &m.map,
                        &source,
                        &m.buildings,
                        &thin,
                        &cam,
                        w,
                        h,
                    ),
                )
            })
            .collect();
    }
    let b = bounds
        .iter()
        .fold(crate::geom::Aabb3::EMPTY, |a, b| a.union(b.aabb));
    let e = b.extent();
    Ok(CityMaps {
        city: city.name.clone(),
        maps,
        build_s,
        area_km2: (e.x * e.y / 1e6).max(1e-9),
        checks,
    })
}

/// True for the entries a folder of BlockMaps holds (`blockmaps.json`, `node_*.png`,
/// `node_*.json`).
pub fn is_maps_entry(name: &std::ffi::OsStr) -> bool {
    let n = name.to_string_lossy();
    n == "blockmaps.json"
        || (n.starts_with("node_") && (n.ends_with(".png") || n.ends_with(".json")))
}

impl CityMaps {
    /// Pixels beyond the screen-space bound plus hit points beyond ε, over all checks.
    pub fn bound_violations(&self) -> usize {
        self.checks
            .iter()
            .map(|(_, c)| c.point_violations + c.beyond_bound)
            .sum()
    }

    /// Writes the folder `dir`: the summary as `blockmaps.json` ([`Self::summary`]) and, with
    /// `maps`, every map as `node_KEY.png` + `.json`; returns the summary's path. The folder is
    /// written under a temporary name beside `dir` and swapped in when complete, so a previous
    /// set of maps there is replaced whole (never mixed with maps of another run); a folder
    /// holding anything else is refused.
    ///
    /// # Errors
    /// [`BlockMapError::Io`] naming the file or folder.
    pub fn write(
        &self,
        dir: &std::path::Path,
        maps: bool,
    ) -> Result<std::path::PathBuf, BlockMapError> {
        let out = |e: crate::output::OutputError| BlockMapError::Io {
            path: e.path().to_path_buf(),
            what: e.to_string(),
        };
        let staged = crate::output::StagedDir::create(
            dir,
            "set of BlockMaps (blockmaps.json, node_*.png, node_*.json)",
            is_maps_entry,
        )
        .map_err(out)?;
        if maps {
            for m in &self.maps.maps {
                m.map.write(staged.path(), &format!("node_{:x}", m.key))?;
            }
        }
        let path = dir.join("blockmaps.json");
        let text =
            serde_json::to_string_pretty(&self.summary()).map_err(|e| BlockMapError::Io {
                path: path.clone(),
                what: e.to_string(),
            })?;
        std::fs::write(staged.path().join("blockmaps.json"), text).map_err(|e| {
            BlockMapError::Io {
                path: path.clone(),
                what: e.to_string(),
            }
        })?;
        staged.commit().map_err(out)?;
        Ok(path)
    }

    /// The figures as one JSON object: `maps`, `bytes`, `build_s`, `eps_declared_max`,
    /// `eps_measured_max`, `bound_violations`, `thin_features`, per-level rows, the thin
    /// features by building, the checks, and the AO summary when AO was computed.
    pub fn summary(&self) -> serde_json::Value {
        let maps = &self.maps;
        let k = maps.maps.first().map(|m| m.map.k()).unwrap_or(0);
        let bytes: usize = maps.maps.iter().map(|m| m.map.bytes()).sum();
        let mut levels: Vec<serde_json::Value> = Vec::new();
        let max_level = maps.maps.iter().map(|m| m.level).max().unwrap_or(0);
        for l in 0..=max_level {
            let at: Vec<&NodeMap> = maps.maps.iter().filter(|m| m.level == l).collect();
            if at.is_empty() {
                continue;
            }
            let f = |g: &dyn Fn(&NodeMap) -> f64| at.iter().map(|m| g(m)).fold(0.0, f64::max);
            levels.push(serde_json::json!({
                "level": l,
                "maps": at.len(),
                "texel_m_max": f(&|m| m.map.texel_m()),
                "eps_declared_max_m": f(&|m| m.map.meta.eps_m),
                "eps_measured_max_m": f(&|m| m.error.measured_m),
                "half_voxel_diagonal_max_m": f(&|m| m.error.half_voxel_diagonal_m),
                "exposed_texels": at.iter().map(|m| m.stats.exposed_texels).sum::<usize>(),
                "shared_columns": at.iter().map(|m| m.stats.shared_columns).sum::<usize>(),
                "slices_max": at.iter().map(|m| m.stats.slices).max().unwrap_or(1),
                "thin_features": at.iter().map(|m| m.error.thin.len()).sum::<usize>(),
            }));
        }
        let thin: Vec<serde_json::Value> = maps
            .maps
            .iter()
            .flat_map(|m| {
                m.error.thin.iter().map(move |t| {
                    serde_json::json!({"node": m.key, "level": m.level, "kind": t.kind,
                        "building": t.building, "source_id": t.source_id, "error_m": t.error_m, "at": t.at})
                })
            })
            .collect();
        let mut thin_by_kind: std::collections::BTreeMap<String, usize> = Default::default();
        for t in &thin {
            *thin_by_kind
                .entry(t["kind"].as_str().unwrap_or("").to_string())
                .or_default() += 1;
        }
        let fmax = |g: &dyn Fn(&NodeMap) -> f64| maps.maps.iter().map(g).fold(0.0, f64::max);
        let cov_max = self
            .checks
            .iter()
            .map(|(_, c)| c.coverage_error)
            .fold(0.0, f64::max);
        let mut covs: Vec<f64> = self.checks.iter().map(|(_, c)| c.coverage_error).collect();
        covs.sort_by(f64::total_cmp);
        let cov_mean = covs.iter().sum::<f64>() / covs.len().max(1) as f64;
        // Nearest-rank 95th percentile.
        let cov_p95 = if covs.is_empty() {
            0.0
        } else {
            covs[((0.95 * covs.len() as f64).ceil() as usize).clamp(1, covs.len()) - 1]
        };
        let over_target = covs.iter().filter(|c| **c > COVERAGE_TARGET).count();
        let psnr_min = self
            .checks
            .iter()
            .map(|(_, c)| c.psnr_db)
            .fold(f64::INFINITY, f64::min);
        let ao: Vec<&super::ao::AoStats> = maps
            .maps
            .iter()
            .filter_map(|m| m.stats.ao.as_ref())
            .collect();
        let ao = if ao.is_empty() {
            serde_json::Value::Null
        } else {
            let n = ao.len() as f64;
            serde_json::json!({
                "roof_mean": ao.iter().map(|a| a.roof_mean).sum::<f64>() / n,
                "ground_mean": ao.iter().map(|a| a.ground_mean).sum::<f64>() / n,
                "wall_mean": ao.iter().map(|a| a.wall_mean).sum::<f64>() / n,
                "occluded_share": ao.iter().map(|a| a.occluded_share).sum::<f64>() / n,
            })
        };
        serde_json::json!({
            "city": self.city,
            "k": k,
            "maps": maps.maps.len(),
            "bytes": bytes,
            "bytes_per_map": maps.maps.first().map(|m| m.map.bytes()).unwrap_or(0),
            "area_km2": self.area_km2,
            "mib_per_km2": bytes as f64 / 1048576.0 / self.area_km2,
            "build_s": self.build_s,
            "parents_from_children": maps.maps.iter().filter(|m| m.stats.from_children.is_some()).count(),
            "eps_derived_max": maps.maps.iter().filter_map(|m| m.stats.from_children.as_ref()).map(|r| r.derived_eps_m).fold(0.0, f64::max),
            "measured_over_derived": maps.maps.iter().filter_map(|m| m.stats.from_children.as_ref()).filter(|r| r.measured_over_derived).count(),
            "eps_declared_max": fmax(&|m| m.map.meta.eps_m),
            "eps_measured_max": fmax(&|m| m.error.measured_m),
            "bound_violations": self.bound_violations(),
            "thin_features": thin.len(),
            "thin_by_kind": thin_by_kind,
            "thin": thin,
            "raised_parts": maps.maps.iter().map(|m| m.error.raised_parts).sum::<usize>(),
            "bridges": maps.maps.iter().map(|m| m.error.bridges).sum::<usize>(),
            "dropped_buildings": maps.maps.iter().map(|m| m.stats.dropped_buildings.len()).sum::<usize>(),
            "dropped": maps.maps.iter().flat_map(|m| m.stats.dropped_buildings.iter().map(move |b| serde_json::json!({"node": m.key, "level": m.level, "building": b.0}))).collect::<Vec<_>>(),
            "levels": levels,
            "checks": self.checks.iter().map(|(k, c)| serde_json::json!({"node": k, "view": c})).collect::<Vec<_>>(),
            "coverage_error_max": cov_max,
            "coverage_error_mean": cov_mean,
            "coverage_error_p95": cov_p95,
            "coverage_over_target": over_target,
            "coverage_target": COVERAGE_TARGET,
            "bound_subpixel_pixels": self.checks.iter().map(|(_, c)| c.beyond_bound_subpixel).sum::<usize>(),
            "bound_thin_pixels": self.checks.iter().map(|(_, c)| c.beyond_bound_thin).sum::<usize>(),
            "psnr_min_db": if psnr_min.is_finite() { serde_json::json!(psnr_min) } else { serde_json::Value::Null },
            "ao": ao,
        })
    }
}
