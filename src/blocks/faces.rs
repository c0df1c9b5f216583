//! Faces of a planar graph by the counter-clockwise walk (Pina, Serón and Cerezo, §3: "if the final point of a
//! street coincided with the initial point of several streets, the selection of the suitable street
//! was performed in a counter-clockwise manner").
//!
//! Around every node the outgoing half-edges are sorted by angle exactly (half-plane, then the
//! robust orientation of the two directions). Arriving at a node along `u → v`, the walk leaves
//! along the half-edge that comes just before `v → u` in counter-clockwise order, i.e. it always
//! turns as far left as possible, so every bounded face is traced counter-clockwise with its
//! interior on the left; the outer boundary of each connected piece is traced clockwise (negative
//! area) and is dropped, or becomes a hole of the face around it.
//!
//! Deviation from the paper's recursive search: edges with the same face on both sides (dangling
//! streets, cul-de-sacs, a street linking an island to the rest) do not bound any block; they are
//! taken out before the final walk (a first walk finds them), which is the same as removing the
//! zero-area spikes from the face rings, and keeps every ring simple.

use super::noding::PlanarGraph;
use crate::geom::predicates::{orient2d_det, point_in_ring, ring_signed_area, Location};
use geo_types::{Coord, LineString, Polygon};
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree};
use std::cmp::Ordering;

/// A face of the planar graph.
#[derive(Clone, Debug)]
pub struct Face {
    /// Boundary as node indices, counter-clockwise for a bounded face, not closed.
    pub ring: Vec<u32>,
    /// Signed area of `ring` (positive: a bounded face).
    pub ring_area: f64,
    /// Outer boundaries of islands inside this face (clockwise node rings): its holes.
    pub holes: Vec<usize>,
    /// For an outer (negative) face: the bounded face that contains it, if any.
    pub container: Option<usize>,
}

/// All faces of a planar graph, with the half-edge structure that produced them.
#[derive(Clone, Debug)]
pub struct FaceSet {
    /// The graph (node positions; edges as given).
    pub nodes: Vec<Coord<f64>>,
    /// Edges that bound faces (the graph minus edges with one face on both sides).
    pub core_edges: Vec<[u32; 2]>,
    /// Faces: bounded ones (positive `ring_area`) and each piece's outer boundary.
    pub faces: Vec<Face>,
    /// Face on the left of half-edge `2e` (`core_edges[e][0] → [1]`) and `2e + 1` (reverse).
    pub left: Vec<usize>,
}

fn half_plane(d_y_pos: bool, d_y_zero: bool, d_x_pos: bool) -> u8 {
    if d_y_pos || (d_y_zero && d_x_pos) {
        0
    } else {
        1
    }
}

/// Exact counter-clockwise angular order of the directions `o → a` and `o → b`, starting at +x.
fn angle_cmp(o: Coord<f64>, a: Coord<f64>, b: Coord<f64>) -> Ordering {
    let ha = half_plane(a.y > o.y, a.y == o.y, a.x > o.x);
    let hb = half_plane(b.y > o.y, b.y == o.y, b.x > o.x);
    ha.cmp(&hb).then_with(|| {
        let s = orient2d_det(o, a, b);
        if s > 0.0 {
            Ordering::Less
        } else if s < 0.0 {
            Ordering::Greater
        } else {
            // Same direction (only after an incomplete noding): nearer first, deterministic.
            let da = (a.x - o.x).abs() + (a.y - o.y).abs();
            let db = (b.x - o.x).abs() + (b.y - o.y).abs();
            da.total_cmp(&db)
        }
    })
}

/// Traces all face cycles; returns (face of every half-edge, rings as node lists).
fn walk(nodes: &[Coord<f64>], edges: &[[u32; 2]]) -> (Vec<usize>, Vec<Vec<u32>>) {
    let n = nodes.len();
    let mut out: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (e, &[a, b]) in edges.iter().enumerate() {
        out[a as usize].push(2 * e as u32);
        out[b as usize].push(2 * e as u32 + 1);
    }
    let head = |h: u32| -> u32 {
        let e = edges[(h / 2) as usize];
        if h & 1 == 0 {
            e[1]
        } else {
            e[0]
        }
    };
    let tail = |h: u32| -> u32 { head(h ^ 1) };
    let mut pos = vec![0u32; edges.len() * 2];
    for (v, list) in out.iter_mut().enumerate() {
        let o = nodes[v];
        list.sort_by(|&x, &y| angle_cmp(o, nodes[head(x) as usize], nodes[head(y) as usize]));
        for (k, &h) in list.iter().enumerate() {
            pos[h as usize] = k as u32;
        }
    }
    let next = |h: u32| -> u32 {
        let t = h ^ 1;
        let v = tail(t) as usize;
        let list = &out[v];
        let k = pos[t as usize] as usize;
        list[(k + list.len() - 1) % list.len()]
    };
    let mut face = vec![usize::MAX; edges.len() * 2];
    let mut rings = Vec::new();
    for start in 0..(edges.len() * 2) as u32 {
        if face[start as usize] != usize::MAX {
            continue;
        }
        let id = rings.len();
        let mut ring = Vec::new();
        let mut h = start;
        loop {
            face[h as usize] = id;
            ring.push(tail(h));
            h = next(h);
            if h == start {
                break;
            }
        }
        rings.push(ring);
    }
    (face, rings)
}

fn ring_coords(nodes: &[Coord<f64>], ring: &[u32]) -> Vec<Coord<f64>> {
    ring.iter().map(|&i| nodes[i as usize]).collect()
}

/// Computes the faces of a planar graph (see the module docs).
pub fn faces(graph: &PlanarGraph) -> FaceSet {
    let nodes = &graph.nodes;
    // First walk: find edges with the same face on both sides.
    let (face0, _) = walk(nodes, &graph.edges);
    let core_edges: Vec<[u32; 2]> = graph
        .edges
        .iter()
        .enumerate()
        .filter(|(e, _)| face0[2 * e] != face0[2 * e + 1])
        .map(|(_, &e)| e)
        .collect();
    let (left, rings) = walk(nodes, &core_edges);
    let mut faces: Vec<Face> = rings
        .into_iter()
        .map(|ring| {
            let ring_area = ring_signed_area(&ring_coords(nodes, &ring));
            Face {
                ring,
                ring_area,
                holes: Vec::new(),
                container: None,
            }
        })
        .collect();
    // Islands: each outer (non-positive) face goes into the smallest bounded face containing it.
    type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;
    let bbox = |ring: &[u32]| {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for &i in ring {
            let c = nodes[i as usize];
            lo = [lo[0].min(c.x), lo[1].min(c.y)];
            hi = [hi[0].max(c.x), hi[1].max(c.y)];
        }
        (lo, hi)
    };
    let bounded: Vec<Env> = faces
        .iter()
        .enumerate()
        .filter(|(_, f)| f.ring_area > 0.0)
        .map(|(i, f)| {
            let (lo, hi) = bbox(&f.ring);
            GeomWithData::new(Rectangle::from_corners(lo, hi), i)
        })
        .collect();
    let has_outer = faces.iter().filter(|f| f.ring_area <= 0.0).count();
    if has_outer > 1 {
        let tree = RTree::bulk_load(bounded);
        // Node sets of faces, to skip faces of the same connected piece.
        let comp = components(nodes.len(), &core_edges);
        for i in 0..faces.len() {
            if faces[i].ring_area > 0.0 {
                continue;
            }
            let p = nodes[faces[i].ring[0] as usize];
            let my = comp[faces[i].ring[0] as usize];
            let mut best: Option<(f64, usize)> = None;
            for cand in tree.locate_all_at_point(&[p.x, p.y]) {
                let j = cand.data;
                if comp[faces[j].ring[0] as usize] == my {
                    continue;
                }
                let f = &faces[j];
                if best.is_some_and(|(a, _)| a <= f.ring_area) {
                    continue;
                }
                if point_in_ring(p, &ring_coords(nodes, &f.ring)) == Location::Inside {
                    best = Some((f.ring_area, j));
                }
            }
            if let Some((_, j)) = best {
                faces[i].container = Some(j);
                faces[j].holes.push(i);
            }
        }
    }
    FaceSet {
        nodes: nodes.clone(),
        core_edges,
        faces,
        left,
    }
}

fn components(n: usize, edges: &[[u32; 2]]) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for &[a, b] in edges {
        let ra = find(&mut parent, a);
        let rb = find(&mut parent, b);
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    (0..n as u32).map(|x| find(&mut parent, x)).collect()
}

impl FaceSet {
    /// Indices of the bounded faces (the blocks), in walk order.
    pub fn bounded(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.faces.len()).filter(|&i| self.faces[i].ring_area > 0.0)
    }

    /// The bounded face a half-edge's left side belongs to after resolving islands (`None`: the
    /// unbounded face).
    pub fn resolved_left(&self, h: usize) -> Option<usize> {
        let f = self.left[h];
        if self.faces[f].ring_area > 0.0 {
            Some(f)
        } else {
            self.faces[f].container
        }
    }

    /// Polygon of a bounded face: exterior counter-clockwise, holes clockwise, rings closed.
    pub fn polygon(&self, i: usize) -> Polygon<f64> {
        let close = |ring: &[u32]| {
            let mut c = ring_coords(&self.nodes, ring);
            c.push(c[0]);
            LineString(c)
        };
        let f = &self.faces[i];
        Polygon::new(
            close(&f.ring),
            f.holes
                .iter()
                .map(|&h| close(&self.faces[h].ring))
                .collect(),
        )
    }

    /// Net area of a bounded face (ring minus holes).
    pub fn area(&self, i: usize) -> f64 {
        let f = &self.faces[i];
        f.ring_area
            + f.holes
                .iter()
                .map(|&h| self.faces[h].ring_area)
                .sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::noding::{node_lines, DEFAULT_SNAP_TOLERANCE};
    use geo_types::line_string;

    #[test]
    fn grid_with_dangle_and_island() {
        let lines = vec![
            line_string![(x: 0., y: 0.), (x: 20., y: 0.), (x: 20., y: 10.), (x: 0., y: 10.), (x: 0., y: 0.)],
            line_string![(x: 10., y: 0.), (x: 10., y: 10.)],
            // cul-de-sac into the left block
            line_string![(x: 0., y: 5.), (x: 4., y: 5.)],
            // island loop inside the right block
            line_string![(x: 13., y: 3.), (x: 17., y: 3.), (x: 17., y: 7.), (x: 13., y: 7.), (x: 13., y: 3.)],
        ];
        let g = node_lines(&lines, DEFAULT_SNAP_TOLERANCE);
        assert_eq!(g.dangles(), 1);
        let fs = faces(&g);
        let mut areas: Vec<f64> = fs.bounded().map(|i| fs.area(i)).collect();
        areas.sort_by(f64::total_cmp);
        assert_eq!(areas, vec![16.0, 84.0, 100.0]);
        // The left block's ring has no spike.
        for i in fs.bounded() {
            let r = &fs.faces[i].ring;
            let mut s = r.clone();
            s.sort();
            s.dedup();
            assert_eq!(s.len(), r.len());
        }
    }
}
