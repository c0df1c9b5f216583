//! Ring utilities shared by the readers: winding, robust point-in-ring, and grouping holes into
//! the outer rings that contain them.

use geo_types::{Coord, LineString, Polygon};

/// Where a point lies with respect to a ring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Location {
    Inside,
    Outside,
    Boundary,
}

/// Twice the signed area of a ring (shoelace); positive when counter-clockwise (y up).
pub(crate) fn signed_area2(ring: &[Coord<f64>]) -> f64 {
    if ring.len() < 3 {
        return 0.0;
    }
    let o = ring[0];
    let mut s = 0.0;
    for w in ring.windows(2) {
        s += (w[0].x - o.x) * (w[1].y - o.y) - (w[1].x - o.x) * (w[0].y - o.y);
    }
    let (a, b) = (ring[ring.len() - 1], ring[0]);
    s += (a.x - o.x) * (b.y - o.y) - (b.x - o.x) * (a.y - o.y);
    s
}

fn orient(a: Coord<f64>, b: Coord<f64>, p: Coord<f64>) -> f64 {
    robust::orient2d(
        robust::Coord { x: a.x, y: a.y },
        robust::Coord { x: b.x, y: b.y },
        robust::Coord { x: p.x, y: p.y },
    )
}

/// Locates `p` against a ring (closed or not) with the winding-number rule; the orientation
/// sign comes from Shewchuk's exact `orient2d`, so the answer is exact for f64 input.
pub(crate) fn locate(p: Coord<f64>, ring: &[Coord<f64>]) -> Location {
    let n = ring.len();
    if n == 0 {
        return Location::Outside;
    }
    let mut winding = 0i32;
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        if a == b {
            continue;
        }
        let o = orient(a, b, p);
        if o == 0.0
            && p.x >= a.x.min(b.x)
            && p.x <= a.x.max(b.x)
            && p.y >= a.y.min(b.y)
            && p.y <= a.y.max(b.y)
        {
            return Location::Boundary;
        }
        if a.y <= p.y {
            if b.y > p.y && o > 0.0 {
                winding += 1;
            }
        } else if b.y <= p.y && o < 0.0 {
            winding -= 1;
        }
    }
    if winding != 0 {
        Location::Inside
    } else {
        Location::Outside
    }
}

/// True when ring `inner` lies inside ring `outer`, judged by its first vertex that is not on
/// `outer`'s boundary (a ring touching its outer ring at vertices is still inside).
pub(crate) fn ring_inside(inner: &[Coord<f64>], outer: &[Coord<f64>]) -> bool {
    for &p in inner {
        match locate(p, outer) {
            Location::Inside => return true,
            Location::Outside => return false,
            Location::Boundary => {}
        }
    }
    // Every vertex lies on the outer boundary: try edge midpoints.
    for w in inner.windows(2) {
        let m = Coord {
            x: 0.5 * (w[0].x + w[1].x),
            y: 0.5 * (w[0].y + w[1].y),
        };
        match locate(m, outer) {
            Location::Inside => return true,
            Location::Outside => return false,
            Location::Boundary => {}
        }
    }
    false
}

/// Polygons assembled from outer rings and holes.
pub(crate) struct Assembled {
    /// One polygon per outer ring (in input order), then one per orphan hole.
    pub polygons: Vec<Polygon<f64>>,
    /// Indices (into the input `holes`) of holes that lie in no outer ring; each became the outer
    /// ring of a polygon of its own.
    pub orphan_holes: Vec<usize>,
}

/// Puts each hole into the smallest outer ring that contains it (ring order is not trusted).
/// Vertex order is kept as read.
pub(crate) fn assemble(outers: Vec<Vec<Coord<f64>>>, holes: Vec<Vec<Coord<f64>>>) -> Assembled {
    let areas: Vec<f64> = outers.iter().map(|r| signed_area2(r).abs()).collect();
    let mut inner_of: Vec<Vec<LineString<f64>>> = vec![Vec::new(); outers.len()];
    let mut orphans = Vec::new();
    let mut orphan_rings = Vec::new();
    for (h, hole) in holes.into_iter().enumerate() {
        let best = outers
            .iter()
            .enumerate()
            .filter(|(_, o)| ring_inside(&hole, o))
            .min_by(|a, b| areas[a.0].total_cmp(&areas[b.0]))
            .map(|(i, _)| i);
        match best {
            Some(i) => inner_of[i].push(LineString::new(hole)),
            None => {
                orphans.push(h);
                orphan_rings.push(hole);
            }
        }
    }
    let mut polygons: Vec<Polygon<f64>> = outers
        .into_iter()
        .zip(inner_of)
        .map(|(o, inner)| Polygon::new(LineString::new(o), inner))
        .collect();
    polygons.extend(
        orphan_rings
            .into_iter()
            .map(|r| Polygon::new(LineString::new(r), vec![])),
    );
    Assembled {
        polygons,
        orphan_holes: orphans,
    }
}

/// The index of the first non-finite coordinate, if any.
pub(crate) fn first_non_finite<'a>(
    coords: impl IntoIterator<Item = &'a Coord<f64>>,
) -> Option<usize> {
    coords
        .into_iter()
        .position(|c| !(c.x.is_finite() && c.y.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(x: f64, y: f64) -> Coord<f64> {
        Coord { x, y }
    }

    #[test]
    fn locate_square() {
        let sq = vec![c(0., 0.), c(0., 10.), c(10., 10.), c(10., 0.), c(0., 0.)];
        assert_eq!(locate(c(5., 5.), &sq), Location::Inside);
        assert_eq!(locate(c(15., 5.), &sq), Location::Outside);
        assert_eq!(locate(c(10., 5.), &sq), Location::Boundary);
        assert_eq!(locate(c(0., 0.), &sq), Location::Boundary);
        assert!(signed_area2(&sq) < 0.0, "clockwise is negative");
    }

    #[test]
    fn holes_go_to_the_containing_outer_whatever_the_order() {
        let big = vec![c(0., 0.), c(0., 10.), c(10., 10.), c(10., 0.), c(0., 0.)];
        let far = vec![c(20., 0.), c(20., 10.), c(30., 10.), c(30., 0.), c(20., 0.)];
        let hole_far = vec![c(22., 2.), c(28., 2.), c(28., 8.), c(22., 8.), c(22., 2.)];
        let hole_big = vec![c(2., 2.), c(8., 2.), c(8., 8.), c(2., 8.), c(2., 2.)];
        let stray = vec![c(50., 50.), c(51., 50.), c(51., 51.), c(50., 50.)];
        let a = assemble(vec![big, far], vec![hole_far, hole_big, stray]);
        assert_eq!(a.polygons.len(), 3);
        assert_eq!(a.polygons[0].interiors().len(), 1);
        assert_eq!(a.polygons[0].interiors()[0].0[0], c(2., 2.));
        assert_eq!(a.polygons[1].interiors()[0].0[0], c(22., 2.));
        assert_eq!(a.orphan_holes, vec![2]);
    }
}
