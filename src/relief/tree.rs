//! The relief-impostor tree: an object-space quaternary tree over the city's buildings
//! (Andujar et al., §3 and §4.1).
//!
//! 1. **Merging.** Buildings whose footprints are at most [`TreeParams::gap_m`] apart are one
//!    *group* (transitively: a row of terraced houses is one group). The paper renders the
//!    footprints from above in false colour and merges what the frame buffer cannot separate;
//!    here the test is exact in plan view: the Euclidean distance between the two footprint
//!    polygons (`geo`), for the pairs whose boxes, grown by the gap, meet (an R-tree, `rstar`).
//! 2. **Subdivision.** A node holds groups; its cell is the box of their footprints, so sibling
//!    cells may overlap and no group is ever cut. A node with more than one group is split: each
//!    group goes to the NW, NE, SE or SW child by its barycentre (area-weighted centroid of its
//!    footprints) against the centre of the node's cell (a barycentre exactly on the centre line
//!    goes east, or north). When every barycentre falls in one quadrant (a large L-shaped group
//!    whose barycentre sits off its box, with a small one beside it), the paper's rule would
//!    give the child the parent's own groups and cell for ever; the split is then made about
//!    the median barycentre instead, which separates any two distinct barycentres, and the tree
//!    counts such splits ([`ReliefTree::median_splits`]). A node with one group, or at
//!    [`TreeParams::max_depth`], is a leaf.
//! 3. **Measures.** Per level, the cells' edge `e` (the longer side), and the overlap ratio of
//!    formula (1), `δᵢ = 2 − eᵢ / eᵢ₊₁`, per parent–child pair ([`LevelStats`]); [`Formulas`]
//!    evaluates formulas (3)–(9) with the tree's own `L`, `ω` and `δ` and sets them beside what
//!    was built. Formula (6), `I = (T + W − 1) / 3` for a quaternary tree, holds exactly and is
//!    checked by the tests; (5), (7) and (8) are the paper's estimates and are reported.

use geo::{Centroid, Distance, Euclidean};
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
use serde::Serialize;

use crate::city::{BuildingId, City};
use crate::geom::predicates::polygon_area;
use crate::geom::Rect;

/// Default merge gap: 0.5 m. Walls closer than this are one mass from any distance the far
/// field is drawn at (a texel of the paper's finest maps is 17 cm, two texels about a third of a
/// metre); a passage a person walks through is wider.
pub const DEFAULT_GAP_M: f64 = 0.5;

/// Largest merge gap accepted: 10 m. Beyond it, whole streets close and a district is one group.
pub const MAX_GAP_M: f64 = 10.0;

/// Default depth limit: 16 levels (4¹⁶ cells, far below a centimetre for any city).
pub const DEFAULT_MAX_DEPTH: u32 = 16;

/// Largest depth limit accepted.
pub const MAX_DEPTH: u32 = 32;

/// Why a tree or its formulas cannot be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TreeError {
    /// A parameter is out of its range.
    #[error("{name} = {value} is out of range ({why})")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The range it must be in.
        why: &'static str,
    },
    /// The city has no building with a footprint of positive area.
    #[error("the city has no building to build a relief tree over")]
    Empty,
}

/// How the tree is built, checked where it is made.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TreeParams {
    /// Footprints at most this far apart (metres, plan view) are merged into one group.
    pub gap_m: f64,
    /// Nodes at this depth are leaves whatever they hold (the root is depth 0).
    pub max_depth: u32,
    /// A node whose cell edge is at most this (metres) is a leaf whatever it holds: its maps
    /// already reach the texel size asked for, and splitting it would only add nodes (0: split
    /// down to single groups).
    pub leaf_edge_m: f64,
}

impl TreeParams {
    /// Parameters for a merge gap and a depth limit.
    ///
    /// # Errors
    /// [`TreeError::BadParameter`] for a gap that is not finite or outside 0..=[`MAX_GAP_M`], or
    /// a depth limit outside 1..=[`MAX_DEPTH`].
    pub fn new(gap_m: f64, max_depth: u32) -> Result<Self, TreeError> {
        if !(gap_m.is_finite() && (0.0..=MAX_GAP_M).contains(&gap_m)) {
            return Err(TreeError::BadParameter {
                name: "gap_m",
                value: gap_m,
                why: "0 to 10 m",
            });
        }
        if !(1..=MAX_DEPTH).contains(&max_depth) {
            return Err(TreeError::BadParameter {
                name: "max_depth",
                value: f64::from(max_depth),
                why: "1 to 32",
            });
        }
        Ok(Self {
            gap_m,
            max_depth,
            leaf_edge_m: 0.0,
        })
    }

    /// These parameters with nodes of edge at most `edge_m` made leaves.
    ///
    /// # Errors
    /// [`TreeError::BadParameter`] for an edge that is not finite and ≥ 0.
    pub fn with_leaf_edge(self, edge_m: f64) -> Result<Self, TreeError> {
        if !(edge_m.is_finite() && edge_m >= 0.0) {
            return Err(TreeError::BadParameter {
                name: "leaf_edge_m",
                value: edge_m,
                why: "a finite length >= 0",
            });
        }
        Ok(Self {
            leaf_edge_m: edge_m,
            ..self
        })
    }
}

impl Default for TreeParams {
    fn default() -> Self {
        Self {
            gap_m: DEFAULT_GAP_M,
            max_depth: DEFAULT_MAX_DEPTH,
            leaf_edge_m: 0.0,
        }
    }
}

/// Buildings merged because their footprints are within the gap of one another.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Group {
    /// The buildings, in increasing id.
    pub buildings: Vec<BuildingId>,
    /// The box of their footprints.
    pub bounds: Rect,
    /// The area-weighted centroid of their footprints (the centre of their boxes' union when
    /// the footprints have no area).
    pub barycentre: [f64; 2],
    /// The sum of their footprint areas, m².
    pub area_m2: f64,
}

/// One node of the tree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReliefNode {
    /// The node's cell: the box of its groups' footprints.
    pub bounds: Rect,
    /// Depth below the root (the root is 0).
    pub depth: u32,
    /// Its groups (indices into [`ReliefTree::groups`]), in increasing index.
    pub groups: Vec<u32>,
    /// The NW, NE, SE and SW children (indices into [`ReliefTree::nodes`]); `None` for a
    /// quadrant that no group went to, and all `None` for a leaf.
    pub children: [Option<u32>; 4],
    /// The point the groups were classified about: the cell's centre, or, for a median split,
    /// the point just above the median barycentre; `None` for a leaf.
    pub split_at: Option<[f64; 2]>,
}

impl ReliefNode {
    /// The cell's edge: its longer side (the paper's cells are square-based).
    pub fn edge(&self) -> f64 {
        let b = &self.bounds;
        (b.max[0] - b.min[0]).max(b.max[1] - b.min[1])
    }

    /// True when the node has no child.
    pub fn is_leaf(&self) -> bool {
        self.children.iter().all(Option::is_none)
    }
}

/// The built tree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReliefTree {
    /// How it was built.
    pub params: TreeParams,
    /// The building groups.
    pub groups: Vec<Group>,
    /// The nodes; the root is the first, and every child comes after its parent.
    pub nodes: Vec<ReliefNode>,
    /// Splits made about the median barycentre because the paper's rule separated nothing.
    pub median_splits: usize,
}

/// What one level of the tree holds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelStats {
    /// Depth.
    pub depth: u32,
    /// Nodes at this depth.
    pub nodes: usize,
    /// Of them, leaves.
    pub leaves: usize,
    /// Mean cell edge, m.
    pub mean_edge_m: f64,
    /// Mean overlap ratio δ of formula (1) over the pairs (parent at the level above, child
    /// here); `None` at the root.
    pub mean_delta: Option<f64>,
    /// Smallest and largest δ of those pairs.
    pub delta_range: Option<[f64; 2]>,
}

/// Quadrant of `p` about `c`: 0 NW, 1 NE, 2 SE, 3 SW (on the centre line: east, north).
pub fn quadrant(p: [f64; 2], c: [f64; 2]) -> usize {
    match (p[0] >= c[0], p[1] >= c[1]) {
        (false, true) => 0,
        (true, true) => 1,
        (true, false) => 2,
        (false, false) => 3,
    }
}

fn footprint_box(p: &geo_types::Polygon<f64>) -> Option<Rect> {
    p.exterior()
        .0
        .iter()
        .map(|c| Rect::point([c.x, c.y]))
        .reduce(Rect::union)
}

/// The buildings of `city` merged into groups: footprints at most `gap` apart (plan view,
/// exact) are in one group, transitively, and, with `block_of` (each building's block, indexed
/// like `city.buildings`), so are the buildings of one block, so that no group cuts a block.
/// Buildings without a footprint point are left out.
pub fn merge(city: &City, gap: f64, block_of: Option<&[u32]>) -> Vec<Group> {
    let items: Vec<(usize, Rect)> = city
        .buildings
        .iter()
        .enumerate()
        .filter_map(|(i, b)| footprint_box(&b.footprint).map(|r| (i, r)))
        .collect();
    type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;
    let tree: RTree<Env> = RTree::bulk_load(
        items
            .iter()
            .enumerate()
            .map(|(k, (_, r))| GeomWithData::new(Rectangle::from_corners(r.min, r.max), k))
            .collect(),
    );
    let mut parent: Vec<usize> = (0..items.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for (k, (i, r)) in items.iter().enumerate() {
        let env = AABB::from_corners(
            [r.min[0] - gap, r.min[1] - gap],
            [r.max[0] + gap, r.max[1] + gap],
        );
        for cand in tree.locate_in_envelope_intersecting(&env) {
            let m = cand.data;
            if m <= k {
                continue;
            }
            let (rk, rm) = (find(&mut parent, k), find(&mut parent, m));
            if rk == rm {
                continue;
            }
            let j = items[m].0;
            let d = Euclidean.distance(&city.buildings[*i].footprint, &city.buildings[j].footprint);
            if d <= gap {
                parent[rk.max(rm)] = rk.min(rm);
            }
        }
    }
    if let Some(block_of) = block_of {
        let mut first_of_block: std::collections::HashMap<u32, usize> = Default::default();
        for (k, (i, _)) in items.iter().enumerate() {
            let Some(&b) = block_of.get(*i) else { continue };
            match first_of_block.get(&b) {
                None => {
                    first_of_block.insert(b, k);
                }
                Some(&f) => {
                    let (rk, rf) = (find(&mut parent, k), find(&mut parent, f));
                    if rk != rf {
                        parent[rk.max(rf)] = rk.min(rf);
                    }
                }
            }
        }
    }
    // Groups in order of their first building.
    let mut index_of_root: Vec<Option<usize>> = vec![None; items.len()];
    let mut groups: Vec<Group> = Vec::new();
    let mut weighted: Vec<[f64; 3]> = Vec::new();
    for (k, (i, r)) in items.iter().enumerate() {
        let root = find(&mut parent, k);
        let g = *index_of_root[root].get_or_insert_with(|| {
            groups.push(Group {
                buildings: Vec::new(),
                bounds: *r,
                barycentre: [0.0; 2],
                area_m2: 0.0,
            });
            weighted.push([0.0; 3]);
            groups.len() - 1
        });
        let fp = &city.buildings[*i].footprint;
        let a = polygon_area(fp);
        let c = fp.centroid().map_or(r.centre(), |c| [c.x(), c.y()]);
        let group = &mut groups[g];
        group.buildings.push(BuildingId(*i as u32));
        group.bounds = group.bounds.union(*r);
        group.area_m2 += a;
        weighted[g][0] += a * c[0];
        weighted[g][1] += a * c[1];
        weighted[g][2] += a;
    }
    for (g, w) in groups.iter_mut().zip(&weighted) {
        g.barycentre = if w[2] > 0.0 {
            [w[0] / w[2], w[1] / w[2]]
        } else {
            g.bounds.centre()
        };
    }
    groups
}

impl ReliefTree {
    /// Merges the city's buildings and builds the tree over the groups (see the module doc).
    ///
    /// # Errors
    /// [`TreeError::Empty`] for a city without buildings.
    pub fn build(city: &City, params: TreeParams) -> Result<Self, TreeError> {
        Self::build_with_blocks(city, params, None)
    }

    /// [`ReliefTree::build`], with the buildings of one block (`block_of`, each building's block
    /// indexed like `city.buildings`) always in one group: the far field's nodes then hold whole
    /// blocks, as the near field draws them.
    ///
    /// # Errors
    /// [`TreeError::Empty`] for a city without buildings.
    pub fn build_with_blocks(
        city: &City,
        params: TreeParams,
        block_of: Option<&[u32]>,
    ) -> Result<Self, TreeError> {
        Self::from_groups(merge(city, params.gap_m, block_of), params)
    }

    /// The tree over building groups already merged ([`merge`]) with `params`.
    ///
    /// # Errors
    /// [`TreeError::Empty`] without a group.
    pub fn from_groups(groups: Vec<Group>, params: TreeParams) -> Result<Self, TreeError> {
        if groups.is_empty() {
            return Err(TreeError::Empty);
        }
        let bounds_of = |ids: &[u32]| -> Rect {
            ids.iter()
                .map(|&g| groups[g as usize].bounds)
                .reduce(Rect::union)
                .expect("a node holds a group")
        };
        let all: Vec<u32> = (0..groups.len() as u32).collect();
        let mut nodes = vec![ReliefNode {
            bounds: bounds_of(&all),
            depth: 0,
            groups: all,
            children: [None; 4],
            split_at: None,
        }];
        let mut median_splits = 0;
        let mut next = 0;
        while next < nodes.len() {
            let n = next;
            next += 1;
            if nodes[n].groups.len() <= 1
                || nodes[n].depth >= params.max_depth
                || nodes[n].edge() <= params.leaf_edge_m
            {
                continue;
            }
            let bary = |g: u32| groups[g as usize].barycentre;
            let split = |centre: [f64; 2]| -> [Vec<u32>; 4] {
                let mut q: [Vec<u32>; 4] = Default::default();
                for &g in &nodes[n].groups {
                    q[quadrant(bary(g), centre)].push(g);
                }
                q
            };
            let mut at = nodes[n].bounds.centre();
            let mut quads = split(at);
            if quads.iter().filter(|q| !q.is_empty()).count() < 2 {
                // The lower median of the barycentres, per axis.
                let median = |axis: usize| {
                    let mut v: Vec<f64> = nodes[n].groups.iter().map(|&g| bary(g)[axis]).collect();
                    v.sort_by(f64::total_cmp);
                    v[(v.len() - 1) / 2]
                };
                // About the number just above the lower median, every barycentre at or below
                // it goes west (south), every one above it east (north): two distinct
                // barycentres differ on some axis, and are then apart.
                at = [next_up(median(0)), next_up(median(1))];
                quads = split(at);
                if quads.iter().filter(|q| !q.is_empty()).count() < 2 {
                    continue;
                }
                median_splits += 1;
            }
            nodes[n].split_at = Some(at);
            let depth = nodes[n].depth + 1;
            for (k, q) in quads.into_iter().enumerate() {
                if q.is_empty() {
                    continue;
                }
                let id = nodes.len() as u32;
                nodes.push(ReliefNode {
                    bounds: bounds_of(&q),
                    depth,
                    groups: q,
                    children: [None; 4],
                    split_at: None,
                });
                nodes[n].children[k] = Some(id);
            }
        }
        Ok(Self {
            params,
            groups,
            nodes,
            median_splits,
        })
    }

    /// The depth of the deepest node.
    pub fn depth(&self) -> u32 {
        self.nodes.iter().map(|n| n.depth).max().unwrap_or(0)
    }

    /// Interior nodes, leaves, and empty child slots of interior nodes: the `I`, `T` and `W`
    /// of formula (6) (the tree creates no empty node, so every node is non-empty).
    pub fn counts(&self) -> (usize, usize, usize) {
        let interior = self.nodes.iter().filter(|n| !n.is_leaf()).count();
        let leaves = self.nodes.len() - interior;
        let empty = self
            .nodes
            .iter()
            .filter(|n| !n.is_leaf())
            .map(|n| n.children.iter().filter(|c| c.is_none()).count())
            .sum();
        (interior, leaves, empty)
    }

    /// Every parent–child pair's overlap ratio δ = 2 − e_parent / e_child (formula (1)), with
    /// the child's depth; pairs whose child cell has no extent are left out.
    pub fn deltas(&self) -> Vec<(u32, f64)> {
        let mut out = Vec::new();
        for p in &self.nodes {
            for c in p.children.iter().flatten() {
                let c = &self.nodes[*c as usize];
                if c.edge() > 0.0 {
                    out.push((c.depth, 2.0 - p.edge() / c.edge()));
                }
            }
        }
        out
    }

    /// Per level: nodes, leaves, mean edge, and the overlap ratio δ of its parent–child pairs.
    pub fn levels(&self) -> Vec<LevelStats> {
        let deltas = self.deltas();
        (0..=self.depth())
            .map(|d| {
                let at: Vec<&ReliefNode> = self.nodes.iter().filter(|n| n.depth == d).collect();
                let ds: Vec<f64> = deltas
                    .iter()
                    .filter(|(k, _)| *k == d)
                    .map(|&(_, v)| v)
                    .collect();
                LevelStats {
                    depth: d,
                    nodes: at.len(),
                    leaves: at.iter().filter(|n| n.is_leaf()).count(),
                    mean_edge_m: at.iter().map(|n| n.edge()).sum::<f64>() / at.len() as f64,
                    mean_delta: (!ds.is_empty()).then(|| ds.iter().sum::<f64>() / ds.len() as f64),
                    delta_range: (!ds.is_empty()).then(|| {
                        [
                            ds.iter().copied().fold(f64::INFINITY, f64::min),
                            ds.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                        ]
                    }),
                }
            })
            .collect()
    }
}

/// The next `f64` above `x` (finite `x`).
fn next_up(x: f64) -> f64 {
    if x == 0.0 {
        f64::from_bits(1)
    } else if x > 0.0 {
        f64::from_bits(x.to_bits() + 1)
    } else {
        f64::from_bits(x.to_bits() - 1)
    }
}

/// Formulas (3)–(9) of the paper with the tree's own `L`, `ω` and `δ`, beside what was built.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Formulas {
    /// `L`: the root cell's edge, m.
    pub universe_m: f64,
    /// `ω`: the footprints' area over `L²`.
    pub coverage: f64,
    /// `δ`: the overlap ratio of formula (2) over every parent–child pair, `2 − g` with `g` the
    /// geometric mean of their edge ratios.
    pub delta: f64,
    /// `ts`: the texel size asked for, m.
    pub texel_m: f64,
    /// `b`: the largest block's size, m.
    pub largest_block_m: f64,
    /// `M` from formula (9): the smallest power of two with `M ≥ b / (2 ts)`.
    pub map_size: u32,
    /// Per level: (depth, the texel `2 ē_d / M` of the level's mean edge, formula (3)'s
    /// `t_d = 2L / (M (2 − δ)^d)`, formula (4)'s worst oblique texel `2 t_d`).
    pub texel_by_level: Vec<(u32, f64, f64, f64)>,
    /// Formula (5): the depth at which `t_d` reaches `ts`; `None` when `δ ≥ 1`.
    pub predicted_depth: Option<f64>,
    /// The first level whose measured texel is at most `ts`, if any.
    pub texel_depth: Option<u32>,
    /// The tree's depth `d`.
    pub built_depth: u32,
    /// Formula (6): `I` and `(T + W − 1) / 3`.
    pub interior: (usize, f64),
    /// The tree's non-empty nodes `N = I + T`.
    pub nodes: usize,
    /// Formula (7) with the built depth: `4^d ω + (4^d − 1) / 3`.
    pub node_bound: f64,
    /// Formula (8), two levels simulated by wavelets: `4^(d−2) ω + (4^(d−2) − 1) / 3`.
    pub node_bound_two_virtual_levels: f64,
}

impl Formulas {
    /// The formulas for `tree`, a texel size `texel_m` and the largest block's size
    /// `largest_block_m` (both metres).
    ///
    /// # Errors
    /// [`TreeError::BadParameter`] for a texel size or block size that is not finite and
    /// positive.
    pub fn new(tree: &ReliefTree, texel_m: f64, largest_block_m: f64) -> Result<Self, TreeError> {
        for (name, value) in [("texel_m", texel_m), ("largest_block_m", largest_block_m)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(TreeError::BadParameter {
                    name,
                    value,
                    why: "a finite length > 0",
                });
            }
        }
        let l = tree.nodes[0].edge();
        let area: f64 = tree.groups.iter().map(|g| g.area_m2).sum();
        let coverage = if l > 0.0 { area / (l * l) } else { 0.0 };
        // δ from the geometric mean of the pairs' edge ratios e_parent / e_child = 2 − δᵢ, so
        // that (2 − δ)^d is the mean shrinking over d levels that formula (2) chains (the
        // arithmetic mean of δᵢ is swamped by the few leaves much smaller than their parents).
        let deltas = tree.deltas();
        let delta = if deltas.is_empty() {
            0.0
        } else {
            let log_mean =
                deltas.iter().map(|d| (2.0 - d.1).ln()).sum::<f64>() / deltas.len() as f64;
            2.0 - log_mean.exp()
        };
        let need = largest_block_m / (2.0 * texel_m);
        let map_size = (need.ceil().max(1.0) as u64)
            .checked_next_power_of_two()
            .and_then(|m| u32::try_from(m).ok())
            .unwrap_or(u32::MAX);
        let m = f64::from(map_size);
        let levels = tree.levels();
        let texel_by_level = levels
            .iter()
            .map(|s| {
                let t = 2.0 * l / (m * (2.0 - delta).powi(s.depth as i32));
                (s.depth, 2.0 * s.mean_edge_m / m, t, 2.0 * t)
            })
            .collect::<Vec<_>>();
        let predicted_depth =
            (delta < 1.0).then(|| (2.0 * l / (m * texel_m)).ln() / (2.0 - delta).ln());
        let texel_depth = texel_by_level.iter().find(|t| t.1 <= texel_m).map(|t| t.0);
        let (i, t, w) = tree.counts();
        let d = tree.depth();
        let bound = |d: i32| {
            let p = 4f64.powi(d.max(0));
            p * coverage + (p - 1.0) / 3.0
        };
        Ok(Self {
            universe_m: l,
            coverage,
            delta,
            texel_m,
            largest_block_m,
            map_size,
            texel_by_level,
            predicted_depth,
            texel_depth,
            built_depth: d,
            interior: (i, (t + w) as f64 / 3.0 - 1.0 / 3.0),
            nodes: i + t,
            node_bound: bound(d as i32),
            node_bound_two_virtual_levels: bound(d as i32 - 2),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrants_and_their_ties() {
        let c = [0.0, 0.0];
        assert_eq!(quadrant([-1.0, 1.0], c), 0);
        assert_eq!(quadrant([1.0, 1.0], c), 1);
        assert_eq!(quadrant([1.0, -1.0], c), 2);
        assert_eq!(quadrant([-1.0, -1.0], c), 3);
        assert_eq!(
            quadrant([0.0, 0.0], c),
            1,
            "on both centre lines: north-east"
        );
        assert_eq!(quadrant([0.0, -1.0], c), 2);
    }

    #[test]
    fn parameters_are_checked_where_they_are_made() {
        assert!(TreeParams::new(0.5, 16).is_ok());
        for (g, d) in [(-1.0, 4), (f64::NAN, 4), (11.0, 4), (0.5, 0), (0.5, 33)] {
            assert!(TreeParams::new(g, d).is_err(), "{g} {d}");
        }
    }

    #[test]
    fn next_up_is_the_next_number() {
        for x in [-3.5, -0.0, 0.0, 1.0, 5.4e6] {
            let y = next_up(x);
            // Nothing lies between: the midpoint rounds to one of them.
            let mid = x / 2.0 + y / 2.0;
            assert!(y > x && (mid == x || mid == y), "{x} {y}");
        }
    }
}

/// Everything `blockwalk relief-tree` reports: the tree's size, its levels and the formulas.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TreeReport {
    /// How the tree was built.
    pub params: TreeParams,
    /// Buildings in the city.
    pub buildings: usize,
    /// Groups after merging.
    pub groups: usize,
    /// Nodes, and the deepest level.
    pub nodes: usize,
    /// The deepest level.
    pub depth: u32,
    /// Splits made about the median barycentre.
    pub median_splits: usize,
    /// Per level.
    pub levels: Vec<LevelStats>,
    /// Formulas (3)–(9).
    pub formulas: Formulas,
}

/// The largest block's size `b` of formula (9): the longer side of the largest box of the
/// layout's blocks (outskirts groups left out); the largest of `groups` when there is no block.
pub fn largest_block_m(layout: &crate::blocks::BlockLayout, groups: &[Group]) -> f64 {
    let side = |r: Rect| (r.max[0] - r.min[0]).max(r.max[1] - r.min[1]);
    let blocks = layout
        .blocks
        .iter()
        .filter(|b| b.kind == crate::blocks::BlockKind::Block)
        .filter_map(|b| footprint_box(&b.polygon))
        .map(side)
        .fold(0.0, f64::max);
    if blocks > 0.0 {
        blocks
    } else {
        groups.iter().map(|g| side(g.bounds)).fold(0.0, f64::max)
    }
}

impl TreeReport {
    /// The tree of `city` with `params`, and its formulas for the texel size `texel_m` and the
    /// largest block of `layout`.
    ///
    /// # Errors
    /// [`TreeError`] for an empty city or a texel size that is not finite and positive.
    pub fn new(
        city: &City,
        layout: &crate::blocks::BlockLayout,
        params: TreeParams,
        texel_m: f64,
    ) -> Result<Self, TreeError> {
        let tree = ReliefTree::build(city, params)?;
        let b = largest_block_m(layout, &tree.groups).max(texel_m);
        let formulas = Formulas::new(&tree, texel_m, b)?;
        Ok(Self {
            params,
            buildings: city.buildings.len(),
            groups: tree.groups.len(),
            nodes: tree.nodes.len(),
            depth: tree.depth(),
            median_splits: tree.median_splits,
            levels: tree.levels(),
            formulas,
        })
    }
}
