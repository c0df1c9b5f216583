//! Exact 2D predicates for the block stage: orientation and the odd-crossing point-in-ring test
//! (seed 003 §3, "the ray method"), built on the `robust` crate's adaptive-precision orient2d.

use geo_types::{Coord, LineString, Polygon};

/// Sign of the orientation of `c` relative to the directed line `a → b`, computed exactly:
/// `> 0` left (counter-clockwise), `< 0` right, `0` collinear.
#[inline]
pub fn orient(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>) -> f64 {
    robust::orient2d(
        robust::Coord { x: a.x, y: a.y },
        robust::Coord { x: b.x, y: b.y },
        robust::Coord { x: c.x, y: c.y },
    )
}

/// Where a point lies relative to a ring or polygon.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// Strictly inside.
    Inside,
    /// Exactly on an edge or vertex.
    Boundary,
    /// Strictly outside.
    Outside,
}

/// Odd-crossing test of `p` against a closed ring (seed 003 §3: a ray is cast from the point and
/// the ring's crossings are counted).
///
/// The ray goes towards +x. An edge counts when it straddles the ray's line under the half-open
/// rule (one end strictly above, the other on or below), and the side test uses the exact
/// orientation, so the degenerate cases the paper works around (the ray through a vertex or along
/// an edge) are decided exactly, without retrying another point. A point exactly on the ring is
/// reported as [`Location::Boundary`].
pub fn locate_in_ring(p: Coord<f64>, ring: &[Coord<f64>]) -> Location {
    let n = ring.len();
    if n < 3 {
        return Location::Outside;
    }
    let mut inside = false;
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        if a == b {
            continue;
        }
        let up_a = a.y > p.y;
        let up_b = b.y > p.y;
        let o = orient(a, b, p);
        if o == 0.0
            && p.x >= a.x.min(b.x)
            && p.x <= a.x.max(b.x)
            && p.y >= a.y.min(b.y)
            && p.y <= a.y.max(b.y)
        {
            return Location::Boundary;
        }
        if up_a != up_b {
            // Upward edge (b above): p left of a→b means the crossing is to the right of p.
            if (up_b && o > 0.0) || (up_a && o < 0.0) {
                inside = !inside;
            }
        }
    }
    if inside {
        Location::Inside
    } else {
        Location::Outside
    }
}

/// Coordinates of a closed `LineString` without the repeated closing point.
pub fn open_ring(ls: &LineString<f64>) -> &[Coord<f64>] {
    let c = &ls.0;
    if c.len() >= 2 && c[0] == c[c.len() - 1] {
        &c[..c.len() - 1]
    } else {
        c
    }
}

/// Odd-crossing test against a polygon with holes.
pub fn locate_in_polygon(p: Coord<f64>, poly: &Polygon<f64>) -> Location {
    match locate_in_ring(p, open_ring(poly.exterior())) {
        Location::Inside => {}
        other => return other,
    }
    for h in poly.interiors() {
        match locate_in_ring(p, open_ring(h)) {
            Location::Outside => {}
            Location::Inside => return Location::Outside,
            Location::Boundary => return Location::Boundary,
        }
    }
    Location::Inside
}

/// Signed area of an open ring (shoelace, relative to the first vertex for precision far from
/// the origin): positive when counter-clockwise.
pub fn signed_ring_area(ring: &[Coord<f64>]) -> f64 {
    if ring.len() < 3 {
        return 0.0;
    }
    let o = ring[0];
    let mut s = 0.0;
    for i in 1..ring.len() - 1 {
        let a = ring[i] - o;
        let b = ring[i + 1] - o;
        s += a.x * b.y - a.y * b.x;
    }
    0.5 * s
}

/// Net area of a polygon (exterior minus holes), whatever the rings' orientation.
pub fn polygon_area(poly: &Polygon<f64>) -> f64 {
    let mut a = signed_ring_area(open_ring(poly.exterior())).abs();
    for h in poly.interiors() {
        a -= signed_ring_area(open_ring(h)).abs();
    }
    a
}

/// A point strictly inside a polygon (not the centroid, which can fall outside a concave or
/// holed footprint), or `None` for a degenerate polygon.
///
/// A horizontal scanline is placed halfway between two consecutive distinct vertex heights, so it
/// passes through no vertex; its crossings with every ring are sorted and the midpoint of the widest
/// inside interval is returned. `attempt` picks other scanlines (0 = the one nearest the middle,
/// then alternating outwards), for the rare case where rounding puts the point on the boundary.
pub fn interior_point(poly: &Polygon<f64>, attempt: usize) -> Option<Coord<f64>> {
    let mut ys: Vec<f64> = std::iter::once(poly.exterior())
        .chain(poly.interiors())
        .flat_map(|r| r.0.iter().map(|c| c.y))
        .collect();
    ys.sort_by(f64::total_cmp);
    ys.dedup();
    if ys.len() < 2 {
        return None;
    }
    let gaps = ys.len() - 1;
    // Order the gaps from the middle outwards; prefer wide gaps near the middle.
    let mid = gaps / 2;
    let mut order: Vec<usize> = (0..gaps).collect();
    order.sort_by_key(|&g| (g as isize - mid as isize).unsigned_abs());
    let g = *order.get(attempt % gaps.max(1))?;
    let y = 0.5 * (ys[g] + ys[g + 1]);
    let mut xs = Vec::new();
    for r in std::iter::once(poly.exterior()).chain(poly.interiors()) {
        let ring = open_ring(r);
        let n = ring.len();
        for i in 0..n {
            let a = ring[i];
            let b = ring[(i + 1) % n];
            if (a.y > y) != (b.y > y) {
                let t = (y - a.y) / (b.y - a.y);
                xs.push(a.x + t * (b.x - a.x));
            }
        }
    }
    xs.sort_by(f64::total_cmp);
    let mut best: Option<(f64, f64)> = None;
    for pair in xs.chunks_exact(2) {
        let w = pair[1] - pair[0];
        if w > 0.0 && best.is_none_or(|(bw, _)| w > bw) {
            best = Some((w, 0.5 * (pair[0] + pair[1])));
        }
    }
    best.map(|(_, x)| Coord { x, y })
}

/// A point strictly inside `poly` by the exact test, trying several scanlines.
pub fn robust_interior_point(poly: &Polygon<f64>) -> Option<Coord<f64>> {
    let n = poly.exterior().0.len() + poly.interiors().iter().map(|h| h.0.len()).sum::<usize>();
    let tries = n.clamp(1, 16);
    let mut fallback = None;
    for k in 0..tries {
        if let Some(p) = interior_point(poly, k) {
            if locate_in_polygon(p, poly) == Location::Inside {
                return Some(p);
            }
            fallback.get_or_insert(p);
        }
    }
    fallback
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::polygon;

    #[test]
    fn ring_degenerate_cases_are_exact() {
        let sq = [
            Coord { x: 0.0, y: 0.0 },
            Coord { x: 2.0, y: 0.0 },
            Coord { x: 2.0, y: 2.0 },
            Coord { x: 0.0, y: 2.0 },
        ];
        assert_eq!(
            locate_in_ring(Coord { x: 1.0, y: 1.0 }, &sq),
            Location::Inside
        );
        // Ray through vertex (2,2)'s height and along the top edge.
        assert_eq!(
            locate_in_ring(Coord { x: 1.0, y: 2.0 }, &sq),
            Location::Boundary
        );
        assert_eq!(
            locate_in_ring(Coord { x: -1.0, y: 2.0 }, &sq),
            Location::Outside
        );
        assert_eq!(
            locate_in_ring(Coord { x: -1.0, y: 0.0 }, &sq),
            Location::Outside
        );
        assert_eq!(
            locate_in_ring(Coord { x: 2.0, y: 1.0 }, &sq),
            Location::Boundary
        );
        assert_eq!(
            locate_in_ring(Coord { x: 3.0, y: 1.0 }, &sq),
            Location::Outside
        );
        // Diamond: the ray passes exactly through the left and right vertices.
        let d = [
            Coord { x: 0.0, y: -1.0 },
            Coord { x: 1.0, y: 0.0 },
            Coord { x: 0.0, y: 1.0 },
            Coord { x: -1.0, y: 0.0 },
        ];
        assert_eq!(
            locate_in_ring(Coord { x: 0.0, y: 0.0 }, &d),
            Location::Inside
        );
        assert_eq!(
            locate_in_ring(Coord { x: -2.0, y: 0.0 }, &d),
            Location::Outside
        );
    }

    #[test]
    fn interior_point_of_concave_and_holed() {
        // U shape: centroid of the bbox is in the notch.
        let u = polygon![(x: 0., y: 0.), (x: 3., y: 0.), (x: 3., y: 3.), (x: 2., y: 3.),
            (x: 2., y: 1.), (x: 1., y: 1.), (x: 1., y: 3.), (x: 0., y: 3.)];
        let p = robust_interior_point(&u).unwrap();
        assert_eq!(locate_in_polygon(p, &u), Location::Inside);
        let holed = polygon!(
            exterior: [(x: 0., y: 0.), (x: 4., y: 0.), (x: 4., y: 4.), (x: 0., y: 4.)],
            interiors: [[(x: 1., y: 1.), (x: 1., y: 3.), (x: 3., y: 3.), (x: 3., y: 1.)]],
        );
        let p = robust_interior_point(&holed).unwrap();
        assert_eq!(locate_in_polygon(p, &holed), Location::Inside);
        assert!((polygon_area(&holed) - 12.0).abs() < 1e-12);
    }
}
