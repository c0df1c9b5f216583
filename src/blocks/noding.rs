//! Noding street lines into a planar graph (Pina, Serón and Cerezo, §3, first step of "blocks were identified
//! from streets": the streets must meet at shared points before the walk can follow them).
//!
//! Every segment is split at every crossing, at every T-junction and where another line's end
//! comes within the snap tolerance of it (so junctions that miss by a millimetre join); points
//! closer than the tolerance are merged into one node; duplicate and collinear overlapping pieces
//! become one edge; zero-length pieces are dropped. Candidate pairs come from an R-tree of the
//! segments' envelopes (O(n log n) for street networks), the crossing tests use exact orientation.

use crate::geom::predicates::{orient2d, segments_intersect, Orientation, SegmentIntersection};
use crate::geom::segment::point_segment_distance;
use crate::geom::tolerance::STREET_SNAP_M;
use geo_types::{Coord, LineString};
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
use std::collections::HashMap;

/// Default snap tolerance in metres: points closer than this are one node, and a line end this
/// close to another line joins it. The street graph's tolerance,
/// [`crate::geom::tolerance::STREET_SNAP_M`] (5 cm), where its reason is given.
pub const DEFAULT_SNAP_TOLERANCE: f64 = STREET_SNAP_M;

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

/// Snaps points to nodes: a point joins the first node created within `tol` of it (first by
/// insertion order: line vertices before computed intersections), else it makes a new node.
struct Snapper {
    tol: f64,
    cells: HashMap<(i64, i64), Vec<u32>>,
    nodes: Vec<Coord<f64>>,
}

impl Snapper {
    fn new(tol: f64) -> Self {
        Self {
            tol,
            cells: HashMap::new(),
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
}

/// One noding pass over segments; returns the graph and whether any segment was split at a point
/// that is not one of its own end nodes.
fn node_once(segs: &[[Coord<f64>; 2]], tol: f64) -> (PlanarGraph, bool) {
    type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;
    let envs: Vec<Env> = segs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let lo = [s[0].x.min(s[1].x) - tol, s[0].y.min(s[1].y) - tol];
            let hi = [s[0].x.max(s[1].x) + tol, s[0].y.max(s[1].y) + tol];
            GeomWithData::new(Rectangle::from_corners(lo, hi), i)
        })
        .collect();
    let tree = RTree::bulk_load(envs);
    // Split points per segment: (parameter, point).
    let mut splits: Vec<Vec<(f64, Coord<f64>)>> = vec![Vec::new(); segs.len()];
    for (i, s) in segs.iter().enumerate() {
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
            if segments_intersect(a, b, c, d) == SegmentIntersection::Proper {
                // Proper crossing: the point, computed relative to `a` for precision.
                let r = b - a;
                let q = d - c;
                let den = r.x * q.y - r.y * q.x;
                let w = c - a;
                let t = ((w.x * q.y - w.y * q.x) / den).clamp(0.0, 1.0);
                let p = Coord {
                    x: a.x + t * r.x,
                    y: a.y + t * r.y,
                };
                let (_, u) = point_segment_distance(p, c, d);
                splits[i].push((t, p));
                splits[j].push((u, p));
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
                    splits[target].push((t, p));
                }
            }
        }
    }
    let mut snap = Snapper::new(tol);
    let ends: Vec<[u32; 2]> = segs
        .iter()
        .map(|s| [snap.node(s[0]), snap.node(s[1])])
        .collect();
    let mut changed = false;
    let mut edges: Vec<[u32; 2]> = Vec::with_capacity(segs.len());
    for (i, sp) in splits.iter_mut().enumerate() {
        sp.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut prev = ends[i][0];
        for &(_, p) in sp.iter() {
            let n = snap.node(p);
            if n != ends[i][0] && n != ends[i][1] {
                changed = true;
            }
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
/// the lines' units ([`DEFAULT_SNAP_TOLERANCE`] metres by default; 0 nodes exactly).
///
/// Passes repeat (at most four) while a pass still splits something, since snapping moves points
/// by up to `tol` and may create a new crossing; the result is then exact: its edges meet only at
/// nodes. Unused nodes are removed. Non-finite coordinates must be filtered by the caller.
pub fn node_lines(lines: &[LineString<f64>], tol: f64) -> PlanarGraph {
    let mut segs: Vec<[Coord<f64>; 2]> = lines
        .iter()
        .flat_map(|l| l.0.windows(2).map(|w| [w[0], w[1]]))
        .filter(|s| s[0] != s[1])
        .collect();
    let mut graph = PlanarGraph::default();
    for _ in 0..4 {
        let (g, changed) = node_once(&segs, tol);
        graph = g;
        if !changed {
            break;
        }
        segs = graph
            .edges
            .iter()
            .map(|e| [graph.nodes[e[0] as usize], graph.nodes[e[1] as usize]])
            .collect();
    }
    compact(graph)
}

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
