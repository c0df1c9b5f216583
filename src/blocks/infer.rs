//! Blocks without a street layer (Pina, Serón and Cerezo, §3: "streets are usually identified in cadastral maps,
//! otherwise it is necessary to perform the identification").
//!
//! - From parcels: a block is a connected union of parcels that share boundary. The parcels'
//!   rings are noded together, the faces that lie inside some parcel are kept, and every edge with
//!   kept faces on both sides is dropped ([`dissolve`]).
//! - From footprints alone: a Delaunay triangulation of the footprints' vertices, with footprint
//!   edges first densified to at most half the street width so that long walls get short links;
//!   triangles with every side at most [`DEFAULT_STREET_WIDTH`] are "inside a block", longer links
//!   cross a street. Kept triangles and footprints are dissolved into blocks.
//! - Streets in both cases are the space between blocks; their centre lines are approximated by
//!   the chordal axis of that space ([`gap_centrelines`]): in a Delaunay triangulation of the
//!   blocks' boundary points, the midpoints of the links that join two different blocks.

use super::assign::{tree_of, Env};
use super::faces::faces;
use super::noding::{node_lines, PlanarGraph};
use crate::geom::predicates::{point_in_polygon, robust_interior_point, Location};
use geo_types::{Coord, LineString, Polygon};
use rayon::prelude::*;
use rstar::RTree;
use spade::{DelaunayTriangulation, HasPosition, Point2, PositionInTriangulation, Triangulation};

/// Default street width threshold (m) for blocks from footprints: two buildings closer than this
/// (wall to wall) are in one block. 20 m is a narrow street with its pavements; courtyards wider
/// than this split a block, streets narrower than this are missed.
pub const DEFAULT_STREET_WIDTH: f64 = 20.0;

/// Regions of the plane bounded by `lines` for which `inside` holds at an interior point, merged
/// across the lines between two inside regions. Lines are noded with snap tolerance `tol`.
pub fn dissolve(
    lines: &[LineString<f64>],
    tol: f64,
    inside: impl Fn(Coord<f64>) -> bool + Sync,
) -> Vec<Polygon<f64>> {
    let graph = node_lines(lines, tol);
    let label = |fs: &super::faces::FaceSet| -> Vec<bool> {
        (0..fs.faces.len())
            .into_par_iter()
            .map(|i| {
                fs.faces[i].ring_area > 0.0
                    && robust_interior_point(&fs.polygon(i)).is_some_and(&inside)
            })
            .collect()
    };
    let fs = faces(&graph);
    let lab = label(&fs);
    let side = |h: usize| fs.resolved_left(h).is_some_and(|f| lab[f]);
    let kept: Vec<[u32; 2]> = fs
        .core_edges
        .iter()
        .enumerate()
        .filter(|&(e, _)| side(2 * e) != side(2 * e + 1))
        .map(|(_, &e)| e)
        .collect();
    let merged = PlanarGraph {
        nodes: graph.nodes,
        edges: kept,
    };
    let fs2 = faces(&merged);
    let lab2 = label(&fs2);
    fs2.bounded()
        .filter(|&i| lab2[i])
        .map(|i| fs2.polygon(i))
        .collect()
}

fn inside_any(tree: &RTree<Env>, polys: &[Polygon<f64>], p: Coord<f64>) -> bool {
    tree.locate_all_at_point(&[p.x, p.y])
        .any(|c| point_in_polygon(p, &polys[c.data]) == Location::Inside)
}

fn rings(polys: &[Polygon<f64>]) -> Vec<LineString<f64>> {
    polys
        .iter()
        .flat_map(|p| std::iter::once(p.exterior()).chain(p.interiors()).cloned())
        .collect()
}

/// Blocks from parcels: connected unions of parcels sharing boundary (see the module docs).
pub fn blocks_from_parcels(parcels: &[Polygon<f64>], tol: f64) -> Vec<Polygon<f64>> {
    let tree = tree_of(parcels, 0.0);
    dissolve(&rings(parcels), tol, |p| inside_any(&tree, parcels, p))
}

#[derive(Clone, Copy, Debug)]
struct Tagged {
    p: Point2<f64>,
    tag: u32,
}

impl HasPosition for Tagged {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.p
    }
}

/// Points of every ring, with edges longer than `step` subdivided, tagged with the polygon index.
fn densified_points(polys: &[Polygon<f64>], step: f64) -> Vec<Tagged> {
    let mut out = Vec::new();
    for (i, p) in polys.iter().enumerate() {
        for r in std::iter::once(p.exterior()).chain(p.interiors()) {
            for w in r.0.windows(2) {
                let (a, b) = (w[0], w[1]);
                let len = (b.x - a.x).hypot(b.y - a.y);
                let n = if step > 0.0 && len.is_finite() {
                    ((len / step).ceil() as usize).clamp(1, 10_000)
                } else {
                    1
                };
                for k in 0..n {
                    let t = k as f64 / n as f64;
                    out.push(Tagged {
                        p: Point2::new(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)),
                        tag: i as u32,
                    });
                }
            }
        }
    }
    out.retain(|t| t.p.x.is_finite() && t.p.y.is_finite());
    out
}

/// Blocks from footprints alone (see the module docs); `street_width` in metres.
pub fn blocks_from_footprints(
    footprints: &[Polygon<f64>],
    street_width: f64,
    tol: f64,
) -> Vec<Polygon<f64>> {
    let pts = densified_points(footprints, 0.5 * street_width);
    let Ok(tri) = DelaunayTriangulation::<Tagged>::bulk_load(pts) else {
        return Vec::new();
    };
    let mut kept = vec![false; tri.num_all_faces()];
    for f in tri.inner_faces() {
        let ok = f
            .adjacent_edges()
            .iter()
            .all(|e| e.length_2() <= street_width * street_width);
        kept[f.fix().index()] = ok;
    }
    let mut lines = rings(footprints);
    for e in tri.undirected_edges() {
        let [d0, d1] = [e.as_directed(), e.as_directed().rev()];
        let k0 = d0.face().as_inner().is_some_and(|f| kept[f.fix().index()]);
        let k1 = d1.face().as_inner().is_some_and(|f| kept[f.fix().index()]);
        if k0 != k1 {
            let [a, b] = e.positions();
            lines.push(LineString(vec![
                Coord { x: a.x, y: a.y },
                Coord { x: b.x, y: b.y },
            ]));
        }
    }
    let tree = tree_of(footprints, 0.0);
    let in_kept = |p: Coord<f64>| match tri.locate(Point2::new(p.x, p.y)) {
        PositionInTriangulation::OnFace(f) => kept[f.index()],
        PositionInTriangulation::OnEdge(e) => {
            let d = tri.directed_edge(e);
            [d, d.rev()]
                .iter()
                .any(|d| d.face().as_inner().is_some_and(|f| kept[f.fix().index()]))
        }
        _ => false,
    };
    dissolve(&lines, tol, |p| {
        in_kept(p) || inside_any(&tree, footprints, p)
    })
}

/// Approximate street centre lines between blocks: the chordal axis of the gaps (see the module
/// docs). Links longer than `max_gap` are ignored (open land, not a street).
pub fn gap_centrelines(blocks: &[Polygon<f64>], step: f64, max_gap: f64) -> Vec<LineString<f64>> {
    let pts = densified_points(blocks, step);
    let Ok(tri) = DelaunayTriangulation::<Tagged>::bulk_load(pts) else {
        return Vec::new();
    };
    let tree = tree_of(blocks, 0.0);
    let mid = |a: Point2<f64>, b: Point2<f64>| Coord {
        x: 0.5 * (a.x + b.x),
        y: 0.5 * (a.y + b.y),
    };
    let mut out = Vec::new();
    for f in tri.inner_faces() {
        let v = f.vertices();
        let tags = [v[0].data().tag, v[1].data().tag, v[2].data().tag];
        if tags[0] == tags[1] && tags[1] == tags[2] {
            continue;
        }
        if f.adjacent_edges()
            .iter()
            .any(|e| e.length_2() > max_gap * max_gap)
        {
            continue;
        }
        let c = f.center();
        if inside_any(&tree, blocks, Coord { x: c.x, y: c.y }) {
            continue;
        }
        let mut mids = Vec::new();
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            if a.data().tag != b.data().tag {
                mids.push(mid(a.position(), b.position()));
            }
        }
        match mids.len() {
            2 => out.push(LineString(vec![mids[0], mids[1]])),
            3 => {
                for m in mids {
                    out.push(LineString(vec![m, Coord { x: c.x, y: c.y }]));
                }
            }
            _ => {}
        }
    }
    out
}
