//! Noding street lines into a planar graph (Pina, Serón and Cerezo, §3, first step of "blocks were identified
//! from streets": the streets must meet at shared points before the walk can follow them).
//!
//! Every segment is split at every crossing, at every T-junction and where another line's end
//! comes within the snap tolerance of it (so junctions that miss by a millimetre join); points
//! closer than the tolerance are merged into one node; duplicate and collinear overlapping pieces
//! become one edge; zero-length pieces are dropped. Candidate pairs come from an R-tree of the
//! segments' envelopes (O(n log n) for street networks), the crossing tests use exact orientation
//! and run in parallel; the points found are snapped in the order of a sequential scan, so the
//! graph does not depend on the number of threads. Split points are snapped as they are found
//! and kept once per segment and node, so memory grows with the nodes on each segment, not with
//! the segments crossing it; the pairs themselves are
//! still all tested, so `n` lines through one point (every pair crossing there) cost `n²` tests
//! (10,000 such lines: 16 s, 10 MB in the test profile; `cargo bench -p blockwalk --bench blocks`).
//! That term stays: the `n(n − 1)/2` crossing pairs are the output-sensitive `k` of any pairwise
//! or sweep-line noder (Bentley–Ottmann runs in O((n + k) log n)), and a street junction joins a
//! handful of lines, not thousands.
//!
//! Snapping is repeated until it settles. With a tolerance as large as the features (0.5 m
//! between streets 0.1 m apart), a crossing can snap to a node whose new edges cross again, pass
//! after pass; the crossings left then are split exactly at their computed points, so the graph
//! is planar, and near those points nodes closer than the tolerance can remain.

use crate::geom::predicates::{orient2d, segments_intersect, Orientation, SegmentIntersection};
use crate::geom::segment::point_segment_distance;
use crate::geom::tolerance::STREET_SNAP_M;
use geo_types::{Coord, LineString};
use rayon::prelude::*;
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Default snap tolerance in metres: points closer than this are one node, and a line end this
/// close to another line joins it. The street graph's tolerance,
/// [`crate::geom::tolerance::STREET_SNAP_M`] (5 cm), where its reason is given.
pub const DEFAULT_SNAP_TOLERANCE: f64 = STREET_SNAP_M;

/// Smallest snap tolerance a city's blocks are detected with: 1 mm. A crossing computed in
/// floating point is rounded, and a rounded point can fall an ulp beside another line's end or
/// on the wrong side of a third line, so noding at tolerance 0 cannot promise a planar graph
/// for arbitrary input; a millimetre absorbs that rounding up to the largest coordinate a city
/// accepts ([`crate::geom::tolerance::MAX_WORLD_COORD_M`]), and is below the accuracy of any
/// street centre line. [`node_lines`] itself still takes 0, which is exact for lines that are
/// already noded (no crossing to compute), and is used that way to check a noded graph.
pub const MIN_SNAP_TOLERANCE: f64 = 0.001;

/// Largest snap tolerance accepted, in the lines' units (metres for a city): 5 m. Snapping
/// merges every pair of points closer than the tolerance, so beyond a few metres it closes
/// streets and collapses small blocks (at 1 km a whole district is one node and no block is left).
pub const MAX_SNAP_TOLERANCE: f64 = 5.0;

/// A planar straight-line graph: nodes and undirected edges between distinct nodes, with no two
/// edges crossing or overlapping (up to the snap tolerance).
#[derive(Clone, Debug, Default)]
pub struct PlanarGraph {
    /// Node positions.
    pub nodes: Vec<Coord<f64>>,
    /// Edges as pairs of node indices, `e[0] < e[1]`, sorted, no duplicates.
    pub edges: Vec<[u32; 2]>,
}

impl PlanarGraph {
    /// Degree of every node.
    pub fn degrees(&self) -> Vec<u32> {
        let mut d = vec![0u32; self.nodes.len()];
        for e in &self.edges {
            d[e[0] as usize] += 1;
            d[e[1] as usize] += 1;
        }
        d
    }
    /// Number of nodes of degree one (dead ends, cul-de-sacs, ends at the edge of the data).
    pub fn dangles(&self) -> usize {
        self.degrees().iter().filter(|&&d| d == 1).count()
    }
    /// The edges as two-point line strings.
    pub fn edge_lines(&self) -> Vec<LineString<f64>> {
        self.edges
            .iter()
            .map(|e| LineString(vec![self.nodes[e[0] as usize], self.nodes[e[1] as usize]]))
            .collect()
    }
}

/// Snaps points to nodes: a point joins the nearest node within `tol` of it (ties to the first
/// created; line vertices are created before computed intersections), else it makes a new node.
/// Every node is therefore more than `tol` from every other. Nodes are kept in square cells of
/// side `tol`; a point looks in its cell and the eight around it.
struct Snapper {
    tol: f64,
    cells: HashMap<(i64, i64), Vec<u32>, BuildHasherDefault<CellHasher>>,
    nodes: Vec<Coord<f64>>,
}

/// A small multiplicative hasher for integer cell keys (the default SipHash costs more than the
/// distance tests it guards, and the keys are not chosen by an adversary of the table).
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        // The splitmix64 finaliser, so that the low bits (the table's bucket) depend on every
        // bit of the keys (exact-coordinate keys often end in zero bits).
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

impl Snapper {
    fn new(tol: f64) -> Self {
        Self {
            tol,
            cells: HashMap::default(),
            nodes: Vec::new(),
        }
    }
    fn key(&self, c: Coord<f64>) -> (i64, i64) {
        if self.tol > 0.0 {
            (
                (c.x / self.tol).floor() as i64,
                (c.y / self.tol).floor() as i64,
            )
        } else {
            (c.x.to_bits() as i64, c.y.to_bits() as i64)
        }
    }
    fn node(&mut self, c: Coord<f64>) -> u32 {
        let (kx, ky) = self.key(c);
        let r = if self.tol > 0.0 { 1 } else { 0 };
        let mut best: Option<(f64, u32)> = None;
        for dx in -r..=r {
            for dy in -r..=r {
                // Keys saturate for coordinates beyond ±2⁶³ tolerances: no cell past them.
                let (Some(cx), Some(cy)) = (kx.checked_add(dx), ky.checked_add(dy)) else {
                    continue;
                };
                if let Some(list) = self.cells.get(&(cx, cy)) {
                    for &id in list {
                        let n = self.nodes[id as usize];
                        let d = (n.x - c.x).hypot(n.y - c.y);
                        if d <= self.tol && best.is_none_or(|(bd, bid)| (d, id) < (bd, bid)) {
                            best = Some((d, id));
                        }
                    }
                }
            }
        }
        if let Some((_, id)) = best {
            return id;
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(c);
        self.cells.entry((kx, ky)).or_default().push(id);
        id
    }
    /// [`Snapper::node`] for `c` when `hint` is a node that `c` certainly snaps to, without the
    /// lookup: `c` within `0.49·tol` of `hint` (every other node is more than `tol` from `hint`,
    /// so more than `0.51·tol` from `c`), or, with `tol = 0`, `c` bitwise equal to `hint`.
    fn node_near(&mut self, c: Coord<f64>, hint: Option<u32>) -> u32 {
        if let Some(h) = hint {
            let n = self.nodes[h as usize];
            let same = if self.tol > 0.0 {
                (n.x - c.x).hypot(n.y - c.y) <= 0.49 * self.tol
            } else {
                n.x.to_bits() == c.x.to_bits() && n.y.to_bits() == c.y.to_bits()
            };
            if same {
                return h;
            }
        }
        self.node(c)
    }
}

/// A point where a segment is to be split: the segment, the point's parameter along it, the
/// point.
struct Split {
    seg: u32,
    t: f64,
    p: Coord<f64>,
}

type SegEnv = GeomWithData<Rectangle<[f64; 2]>, usize>;

/// The split points that segment `i` and the later segments near it give, appended to `out` in
/// the order of the candidates from `tree`: proper crossings, and ends on or within `tol` of
/// the other segment (T-junctions, overlaps, near misses).
fn splits_of(
    segs: &[[Coord<f64>; 2]],
    tree: &RTree<SegEnv>,
    i: usize,
    tol: f64,
    out: &mut Vec<Split>,
) {
    let mut record = |seg: usize, t: f64, p: Coord<f64>| {
        out.push(Split {
            seg: seg as u32,
            t,
            p,
        })
    };
    let s = &segs[i];
    let env = AABB::from_corners(
        [s[0].x.min(s[1].x) - tol, s[0].y.min(s[1].y) - tol],
        [s[0].x.max(s[1].x) + tol, s[0].y.max(s[1].y) + tol],
    );
    for cand in tree.locate_in_envelope_intersecting(&env) {
        let j = cand.data;
        if j <= i {
            continue;
        }
        let [a, b] = *s;
        let [c, d] = segs[j];
        // Segments sharing an end (pieces of one line, edges at a node) cannot cross
        // properly, and the shared end lies on both: only the other two ends need a look.
        let shared = [a == c || a == d, b == c || b == d];
        if shared[0] || shared[1] {
            let (pi, pj) = if shared[0] {
                (b, if a == c { d } else { c })
            } else {
                (a, if b == c { d } else { c })
            };
            for (p, target, other) in [(pj, i, [a, b]), (pi, j, [c, d])] {
                let (dist, t) = point_segment_distance(p, other[0], other[1]);
                if (dist <= tol || orient2d(other[0], other[1], p) == Orientation::Collinear)
                    && t > 0.0
                    && t < 1.0
                {
                    record(target, t, p);
                }
            }
            continue;
        }
        if segments_intersect(a, b, c, d) == SegmentIntersection::Proper {
            // Proper crossing: the point, computed relative to `a` for precision, with the
            // three vectors scaled by one power of two (exactly) so that the products
            // neither underflow nor overflow (their ratio `t` is unchanged).
            let (r, q, w) = (b - a, d - c, c - a);
            let m = [r.x, r.y, q.x, q.y, w.x, w.y]
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let k = 2f64.powi(-(m.log2().floor() as i32));
            let (rs, qs, ws) = (r * k, q * k, w * k);
            let den = rs.x * qs.y - rs.y * qs.x;
            let t = ((ws.x * qs.y - ws.y * qs.x) / den).clamp(0.0, 1.0);
            let t = if t.is_finite() { t } else { 0.5 };
            let p = Coord {
                x: a.x + t * r.x,
                y: a.y + t * r.y,
            };
            let (_, u) = point_segment_distance(p, c, d);
            record(i, t, p);
            record(j, u, p);
        }
        // Ends touching or near the other segment (T-junctions, overlaps, near misses).
        // An exactly collinear end counts as distance 0 whatever the rounding of the distance.
        for (p, target, other) in [
            (c, i, [a, b]),
            (d, i, [a, b]),
            (a, j, [c, d]),
            (b, j, [c, d]),
        ] {
            let (dist, t) = point_segment_distance(p, other[0], other[1]);
            if (dist <= tol || orient2d(other[0], other[1], p) == Orientation::Collinear)
                && t > 0.0
                && t < 1.0
            {
                record(target, t, p);
            }
        }
    }
}

/// One noding pass over segments; returns the graph and whether any segment was split at a point
/// that is not one of its own end nodes.
fn node_once(segs: &[[Coord<f64>; 2]], tol: f64) -> (PlanarGraph, bool) {
    // Split nodes per segment: (parameter, node). A point is snapped to its node as it is found,
    // and a node equal to the one last recorded on the same segment is not recorded again: when
    // many segments cross one segment at one point (lines through a common centre) the segment
    // keeps one entry, not one per crossing segment.
    let mut splits: Vec<Vec<(f64, u32)>> = vec![Vec::new(); segs.len()];
    let mut changed = false;
    // The pairs are tested in parallel, each segment's split points listed in the order the
    // sequential scan would find them (segments in order, candidates in the tree's order); the
    // points are then snapped one after the other in that order, so the nodes (and their
    // numbering) are those of a sequential pass.
    // Line vertices become nodes first (meanwhile: the tree and the tests need no node), so a
    // computed point near a vertex joins the vertex.
    let ((mut snap, ends), found) = rayon::join(
        || {
            let mut snap = Snapper::new(tol);
            let ends: Vec<[u32; 2]> = segs
                .iter()
                .map(|s| [snap.node(s[0]), snap.node(s[1])])
                .collect();
            (snap, ends)
        },
        || {
            let envs: Vec<SegEnv> = segs
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let lo = [s[0].x.min(s[1].x) - tol, s[0].y.min(s[1].y) - tol];
                    let hi = [s[0].x.max(s[1].x) + tol, s[0].y.max(s[1].y) + tol];
                    GeomWithData::new(Rectangle::from_corners(lo, hi), i)
                })
                .collect();
            let tree = RTree::bulk_load(envs);
            (0..segs.len())
                .into_par_iter()
                .with_min_len(1024)
                .fold(Vec::new, |mut out, i| {
                    splits_of(segs, &tree, i, tol, &mut out);
                    out
                })
                .reduce(Vec::new, |mut a: Vec<Split>, mut b| {
                    a.append(&mut b);
                    a
                })
        },
    );
    for Split { seg, t, p } in found {
        let seg = seg as usize;
        let n = snap.node_near(p, splits[seg].last().map(|&(_, n)| n));
        if n != ends[seg][0] && n != ends[seg][1] {
            changed = true;
        }
        let list = &mut splits[seg];
        if list.last().is_none_or(|&(_, last)| last != n) {
            list.push((t, n));
        }
    }
    let mut edges: Vec<[u32; 2]> = Vec::with_capacity(segs.len());
    for (i, sp) in splits.iter_mut().enumerate() {
        // Sorted once per segment, by parameter then node, so equal parameters order the same
        // way on every run.
        sp.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut prev = ends[i][0];
        for &(_, n) in sp.iter() {
            if n != prev {
                edges.push([prev.min(n), prev.max(n)]);
                prev = n;
            }
        }
        let last = ends[i][1];
        if last != prev {
            edges.push([prev.min(last), prev.max(last)]);
        }
    }
    edges.sort_unstable();
    edges.dedup();
    (
        PlanarGraph {
            nodes: snap.nodes,
            edges,
        },
        changed,
    )
}

/// Nodes line strings into a planar graph (see the module docs). `tol` is the snap tolerance in
/// the lines' units ([`DEFAULT_SNAP_TOLERANCE`] metres by default; 0 merges only equal points,
/// which is exact for lines already noded, see [`MIN_SNAP_TOLERANCE`]).
///
/// Passes repeat (at most [`SNAP_PASSES`]) while a pass still splits something, since snapping
/// moves points by up to `tol` and may create a new crossing. Where snapping does not settle (a
/// tolerance as large as the features, so that a crossing snaps to a node whose new edges cross
/// again, pass after pass), passes at tolerance 0 follow (at most [`SNAP_PASSES`] more), which
/// split the crossings that remain at their computed points. Unused nodes are removed.
/// Non-finite coordinates must be filtered by the caller.
pub fn node_lines<'a>(
    lines: impl IntoIterator<Item = &'a LineString<f64>>,
    tol: f64,
) -> PlanarGraph {
    let mut segs: Vec<[Coord<f64>; 2]> = lines
        .into_iter()
        .flat_map(|l| l.0.windows(2).map(|w| [w[0], w[1]]))
        .filter(|s| s[0] != s[1])
        .collect();
    let edges_of = |g: &PlanarGraph| -> Vec<[Coord<f64>; 2]> {
        g.edges
            .iter()
            .map(|e| [g.nodes[e[0] as usize], g.nodes[e[1] as usize]])
            .collect()
    };
    // Snapping passes, until one splits nothing or gives back the graph it was given.
    let mut graph: Option<PlanarGraph> = None;
    let mut unsettled = true;
    for _ in 0..SNAP_PASSES {
        let (g, changed) = node_once(&segs, tol);
        let cycle = graph
            .as_ref()
            .is_some_and(|p| p.nodes == g.nodes && p.edges == g.edges);
        segs = edges_of(&g);
        graph = Some(g);
        if !changed {
            unsettled = false;
            break;
        }
        if cycle {
            break;
        }
    }
    let mut graph = graph.unwrap_or_default();
    if unsettled && tol > 0.0 {
        for _ in 0..SNAP_PASSES {
            let (g, changed) = node_once(&segs, 0.0);
            segs = edges_of(&g);
            graph = g;
            if !changed {
                break;
            }
        }
    }
    compact(graph)
}

/// Most noding passes at the snap tolerance, and then at tolerance 0 (see [`node_lines`]).
pub const SNAP_PASSES: usize = 8;

/// Removes nodes no edge uses, renumbering in order of first use.
fn compact(g: PlanarGraph) -> PlanarGraph {
    let mut map = vec![u32::MAX; g.nodes.len()];
    let mut nodes = Vec::new();
    let mut edges = Vec::with_capacity(g.edges.len());
    for e in &g.edges {
        let mut ne = [0u32; 2];
        for k in 0..2 {
            let n = e[k] as usize;
            if map[n] == u32::MAX {
                map[n] = nodes.len() as u32;
                nodes.push(g.nodes[n]);
            }
            ne[k] = map[n];
        }
        edges.push([ne[0].min(ne[1]), ne[0].max(ne[1])]);
    }
    edges.sort_unstable();
    edges.dedup();
    PlanarGraph { nodes, edges }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::line_string;

    #[test]
    fn crossing_splits_both() {
        let g = node_lines(
            &[
                line_string![(x: 0., y: 0.), (x: 2., y: 2.)],
                line_string![(x: 0., y: 2.), (x: 2., y: 0.)],
            ],
            DEFAULT_SNAP_TOLERANCE,
        );
        assert_eq!(g.nodes.len(), 5);
        assert_eq!(g.edges.len(), 4);
        assert_eq!(g.dangles(), 4);
    }

    #[test]
    fn collinear_overlap_merges() {
        let g = node_lines(
            &[
                line_string![(x: 0., y: 0.), (x: 10., y: 0.)],
                line_string![(x: 5., y: 0.), (x: 15., y: 0.)],
                line_string![(x: 10., y: 0.), (x: 0., y: 0.)],
            ],
            DEFAULT_SNAP_TOLERANCE,
        );
        assert_eq!(g.nodes.len(), 4);
        assert_eq!(g.edges.len(), 3);
    }

    #[test]
    fn t_junction_missing_by_a_millimetre_joins() {
        let g = node_lines(
            &[
                line_string![(x: 0., y: 0.), (x: 10., y: 0.)],
                line_string![(x: 5., y: 0.001), (x: 5., y: 10.)],
            ],
            DEFAULT_SNAP_TOLERANCE,
        );
        assert_eq!(g.edges.len(), 3);
        assert_eq!(g.nodes.len(), 4);
    }
}
