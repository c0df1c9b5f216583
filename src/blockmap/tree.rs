//! BlockMaps for the nodes of the block quadtree (seed 000 §4: "reusing the same spatial
//! partitioning"; BLOCKMAPS.md B.2): one map per BqR-tree node, over the node's whole blocks, so
//! no building is ever cut and a node switches between meshes and its map with disjoint block
//! sets. Every map is built from the source prisms, not from its children (seed 002 §4.3.1 builds
//! internal nodes from the children because its data is out of core; ours fits in memory, and
//! this gives each node its own measured bound with no error accumulation).

use super::build::{build_map, BuildOptions, BuildStats, Source};
use super::error::{measure, ErrorReport};
use super::layout::BlockMap;
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
}

impl Default for TreeOptions {
    fn default() -> Self {
        Self {
            build: BuildOptions::default(),
            stop: Stop::Competitive,
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

/// All maps of a city.
#[derive(Clone, Debug, Default)]
pub struct MapTree {
    /// Maps, parents before children (preorder).
    pub maps: Vec<NodeMap>,
}

/// The nodes that get a map, parents first: `(node, level, parent slot)`.
pub fn select_nodes(tree: &BqrTree, k: u32, stop: Stop) -> Vec<(usize, u32, Option<usize>)> {
    let map_bytes = ((2 * k + super::layout::WALL_COLUMNS) * k * 4) as usize;
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
            let (mut map, buildings, stats) =
                build_map(source, &buildings, &opts.build).map_err(|e| BlockMapError::Node {
                    key: v.key,
                    what: e.to_string(),
                })?;
            let error = measure(&map, source, &buildings);
            map.meta.eps_measured_m = error.measured_m;
            map.meta.eps_m = error.declared_m;
            map.meta.node_key = v.key;
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
    // Monotone ε, children after parents: sweep backwards.
    for i in (0..maps.len()).rev() {
        if let Some(p) = maps[i].parent {
            let e = maps[i].map.meta.eps_m;
            let pe = &mut maps[p].map.meta.eps_m;
            *pe = pe.max(e);
        }
    }
    Ok(MapTree { maps })
}

impl MapTree {
    /// Checks the hierarchy's invariants (BLOCKMAPS.md B.3): a parent's box holds its
    /// children's footprints, its ε is ≥ theirs, and its blocks include theirs.
    ///
    /// # Panics
    /// On a broken invariant, with the node keys.
    pub fn check_invariants(&self) {
        for m in &self.maps {
            let Some(p) = m.parent else { continue };
            let pm = &self.maps[p];
            assert!(
                pm.map.meta.eps_m >= m.map.meta.eps_m,
                "ε of node {} < child {}",
                pm.key,
                m.key
            );
            let (a, b) = (pm.map.aabb(), m.map.aabb());
            let slack = 1e-6 * (1.0 + a.extent().max_element());
            // The child's square may stick out of the parent's over streets; its buildings may not.
            for &bi in &m.buildings {
                assert!(
                    pm.buildings.contains(&bi),
                    "building {bi} of node {} missing from parent {}",
                    m.key,
                    pm.key
                );
            }
            assert!(
                a.max.z + slack >= b.max.z,
                "parent {} lower than child {}",
                pm.key,
                m.key
            );
        }
    }
}
