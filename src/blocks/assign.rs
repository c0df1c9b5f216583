//! Assigning buildings to blocks (seed 003 §3, fourth step): one point of each footprint is tested
//! against the blocks' bounding boxes (an R-tree), then by the odd-crossing ray test.
//!
//! The point is a guaranteed interior point of the footprint (a scanline midpoint, see
//! [`interior_point`]), not a vertex: a footprint touching a street line would otherwise have its
//! vertex on the block boundary. When the point lands exactly on a block boundary the next
//! scanline's point is taken, as the paper retries "another point of the polygon".
//! Buildings in no block are grouped into outskirts by proximity.

use crate::geom::hull::convex_hull_polygon;
use crate::geom::predicates::{interior_point, point_in_polygon, Location};
use geo::{Distance, Euclidean};
use geo_types::{Coord, Polygon};
use rayon::prelude::*;
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};

/// Default distance (m) within which outskirts buildings join one group.
pub const DEFAULT_OUTSKIRTS_LINK: f64 = 30.0;

pub(super) type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;

/// Plan-view box of a polygon's exterior grown by `grow`; `None` for an empty exterior.
fn envelope(p: &Polygon<f64>, grow: f64) -> Option<([f64; 2], [f64; 2])> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for c in &p.exterior().0 {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    (lo[0] <= hi[0]).then_some(([lo[0] - grow, lo[1] - grow], [hi[0] + grow, hi[1] + grow]))
}

/// An R-tree of the polygons' exterior boxes grown by `grow`, each tagged with its index.
pub(super) fn tree_of(polys: &[Polygon<f64>], grow: f64) -> RTree<Env> {
    RTree::bulk_load(
        polys
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                envelope(p, grow)
                    .map(|(lo, hi)| GeomWithData::new(Rectangle::from_corners(lo, hi), i))
            })
            .collect(),
    )
}

/// The block (index into `blocks`) containing `p` strictly, `Err(())` when `p` is exactly on a
/// block boundary, `Ok(None)` when in none. Blocks are disjoint; if rounding ever made two contain
/// the point, the smaller is taken so the answer is still unique.
fn block_at(
    p: Coord<f64>,
    blocks: &[Polygon<f64>],
    areas: &[f64],
    tree: &RTree<Env>,
) -> Result<Option<usize>, ()> {
    let mut found: Option<usize> = None;
    for cand in tree.locate_all_at_point(&[p.x, p.y]) {
        let j = cand.data;
        match point_in_polygon(p, &blocks[j]) {
            Location::OnBoundary => return Err(()),
            Location::Inside => {
                if found.is_none_or(|f| (areas[j], j) < (areas[f], f)) {
                    found = Some(j);
                }
            }
            Location::Outside => {}
        }
    }
    Ok(found)
}

/// Assigns every footprint to at most one block: `result[i]` is the block of `buildings[i]`.
pub fn assign(buildings: &[Polygon<f64>], blocks: &[Polygon<f64>]) -> Vec<Option<usize>> {
    let tree = tree_of(blocks, 0.0);
    let areas: Vec<f64> = blocks
        .iter()
        .map(crate::geom::predicates::polygon_area)
        .collect();
    buildings
        .par_iter()
        .map(|b| {
            let n = b.exterior().0.len().clamp(1, 16);
            let mut last = None;
            for k in 0..n {
                let Some(p) = interior_point(b, k) else { break };
                if point_in_polygon(p, b) != Location::Inside && k + 1 < n {
                    continue;
                }
                match block_at(p, blocks, &areas, &tree) {
                    Ok(r) => return r,
                    Err(()) => last = Some(p),
                }
            }
            // Every point tried was on a block boundary: use the first vertex not on one.
            let _ = last;
            b.exterior()
                .0
                .iter()
                .find_map(|&c| block_at(c, blocks, &areas, &tree).ok())
                .flatten()
        })
        .collect()
}

/// Groups the given buildings (indices into `buildings`) into outskirts: buildings within `link`
/// of each other (footprint to footprint) are in one group. Returns the groups, each with the
/// convex hull of its footprints, in order of their first building.
pub fn outskirts_groups(
    buildings: &[Polygon<f64>],
    which: &[usize],
    link: f64,
) -> Vec<(Polygon<f64>, Vec<usize>)> {
    let polys: Vec<Polygon<f64>> = which.iter().map(|&i| buildings[i].clone()).collect();
    let tree = tree_of(&polys, 0.5 * link);
    let mut parent: Vec<usize> = (0..polys.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for (i, p) in polys.iter().enumerate() {
        let Some((lo, hi)) = envelope(p, 0.5 * link) else {
            continue;
        };
        for cand in tree.locate_in_envelope_intersecting(&AABB::from_corners(lo, hi)) {
            let j = cand.data;
            if j <= i || find(&mut parent, i) == find(&mut parent, j) {
                continue;
            }
            if Euclidean.distance(p, &polys[j]) <= link {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                parent[ri.max(rj)] = ri.min(rj);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; polys.len()];
    for (i, &b) in which.iter().enumerate() {
        let r = find(&mut parent, i);
        if slot[r] == usize::MAX {
            slot[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[r]].push(b);
    }
    groups
        .into_iter()
        .map(|g| {
            let pts = g
                .iter()
                .flat_map(|&i| buildings[i].exterior().0.iter().copied());
            (convex_hull_polygon(pts), g)
        })
        .collect()
}
