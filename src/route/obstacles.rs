//! The buildings a generated route must keep its eye away from: footprint prisms in the local
//! frame, found near a point through an R-tree of their plan boxes (`rstar`).

use crate::city::{Building, LocalFrame};
use crate::geom::predicates::ring_signed_area;
use crate::geom::{Aabb3, Frustum};
use geo::{Area, Centroid, Distance, Euclidean};
use geo_types::{Line, Point, Polygon};
use glam::{DVec2, DVec3};
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, AABB};

/// How far a generated route keeps its eye from every building, metres: twice the default near
/// plane (0.5 m), so that no wall is ever clipped open in front of the eye.
pub const EYE_CLEARANCE_M: f64 = 1.0;

/// One building prism, local frame.
#[derive(Clone, Debug)]
struct Prism {
    footprint: Polygon<f64>,
    lo: f64,
    hi: f64,
}

/// A convex corner of a building's footprint (local frame), walked counter-clockwise around the
/// building: the wall arriving at it, then the wall leaving it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootprintCorner {
    /// The corner.
    pub at: DVec2,
    /// Unit direction of the wall arriving at the corner.
    pub incoming: DVec2,
    /// Unit direction of the wall leaving the corner.
    pub outgoing: DVec2,
    /// Length of the arriving wall, metres.
    pub incoming_len: f64,
    /// Length of the leaving wall, metres.
    pub outgoing_len: f64,
    /// How far the outline turns left at the corner, radians (in `(0, π)`).
    pub turn: f64,
}

impl FootprintCorner {
    /// Outward unit normal of the arriving wall (right of its direction).
    pub fn incoming_normal(&self) -> DVec2 {
        DVec2::new(self.incoming.y, -self.incoming.x)
    }

    /// Outward unit normal of the leaving wall.
    pub fn outgoing_normal(&self) -> DVec2 {
        DVec2::new(self.outgoing.y, -self.outgoing.x)
    }
}

/// The buildings of a city as prisms in its local frame, with a spatial index.
#[derive(Clone, Debug, Default)]
pub struct Obstacles {
    prisms: Vec<Prism>,
    tree: RTree<GeomWithData<Rectangle<[f64; 2]>, u32>>,
    max_height: f64,
}

impl Obstacles {
    /// No building: every point is clear.
    pub fn none() -> Self {
        Self::default()
    }

    /// The footprints of `buildings` (metric world coordinates) moved into `frame`, each from its
    /// `min_height_m` to its `height_m` above its own ground (on terrain, routes are made as over
    /// a flat city and lifted afterwards: [`super::RouteGround`]). Footprints with a non-finite vertex or height are left
    /// out (they are not drawn either).
    pub fn from_buildings(buildings: &[Building], frame: &LocalFrame) -> Self {
        let mut prisms = Vec::with_capacity(buildings.len());
        let mut rects = Vec::with_capacity(buildings.len());
        let mut max_height = 0.0f64;
        for b in buildings {
            // Heights above each building's own ground: routes are made as over a flat city
            // and lifted onto the terrain afterwards (`RouteGround`).
            let (lo, hi) = (
                b.min_height_m.min(b.height_m),
                b.height_m.max(b.min_height_m),
            );
            let footprint = frame.to_local_polygon(&b.footprint);
            let mut min = DVec2::splat(f64::INFINITY);
            let mut max = DVec2::splat(f64::NEG_INFINITY);
            for c in footprint.exterior().coords() {
                min = min.min(DVec2::new(c.x, c.y));
                max = max.max(DVec2::new(c.x, c.y));
            }
            if !(min.is_finite() && max.is_finite() && lo.is_finite() && hi.is_finite()) {
                continue;
            }
            max_height = max_height.max(hi);
            rects.push(GeomWithData::new(
                Rectangle::from_corners([min.x, min.y], [max.x, max.y]),
                prisms.len() as u32,
            ));
            prisms.push(Prism { footprint, lo, hi });
        }
        Self {
            prisms,
            tree: RTree::bulk_load(rects),
            max_height,
        }
    }

    /// Number of buildings.
    pub fn len(&self) -> usize {
        self.prisms.len()
    }

    /// True when there is no building.
    pub fn is_empty(&self) -> bool {
        self.prisms.is_empty()
    }

    /// The highest roof, metres above the ground (0 without buildings).
    pub fn max_height(&self) -> f64 {
        self.max_height
    }

    /// Each building's plan centroid (local frame) and footprint area, square metres, in the
    /// order they were given (footprints left out by [`Obstacles::from_buildings`] excepted).
    /// A degenerate footprint (no area) gives the centre of its box and area 0.
    pub fn plan_centroids(&self) -> Vec<(DVec2, f64)> {
        self.plan_boxes()
            .map(|(prism, min, max)| {
                let area = prism.footprint.unsigned_area();
                let c = prism
                    .footprint
                    .centroid()
                    .map(|p| DVec2::new(p.x(), p.y()))
                    .filter(|c| c.is_finite() && area > 0.0)
                    .unwrap_or(0.5 * (min + max));
                (c, if area.is_finite() { area } else { 0.0 })
            })
            .collect()
    }

    /// Each building's box (footprint box × its heights), local frame, in the order of
    /// [`Obstacles::plan_centroids`].
    pub fn boxes(&self) -> Vec<Aabb3> {
        self.plan_boxes()
            .map(|(p, min, max)| Aabb3::new(min.extend(p.lo), max.extend(p.hi)))
            .collect()
    }

    /// The prisms with their plan boxes, in input order.
    fn plan_boxes(&self) -> impl Iterator<Item = (&Prism, DVec2, DVec2)> {
        self.prisms.iter().map(|p| {
            let mut min = DVec2::splat(f64::INFINITY);
            let mut max = DVec2::splat(f64::NEG_INFINITY);
            for c in p.footprint.exterior().coords() {
                min = min.min(DVec2::new(c.x, c.y));
                max = max.max(DVec2::new(c.x, c.y));
            }
            (p, min, max)
        })
    }

    /// Distance from `p` to the nearest building (0 inside one), looking no farther than
    /// `reach`: returns `reach` or more when no building is within it.
    pub fn distance(&self, p: DVec3, reach: f64) -> f64 {
        self.distance_to(p.truncate(), p.truncate(), p.z, reach)
    }

    /// Distance from the horizontal segment `a`–`b` at height `z` to the nearest building,
    /// looking no farther than `reach` (as [`Obstacles::distance`]).
    pub fn segment_distance(&self, a: DVec2, b: DVec2, z: f64, reach: f64) -> f64 {
        self.distance_to(a, b, z, reach)
    }

    fn distance_to(&self, a: DVec2, b: DVec2, z: f64, reach: f64) -> f64 {
        let lo = a.min(b) - DVec2::splat(reach);
        let hi = a.max(b) + DVec2::splat(reach);
        let env = AABB::from_corners([lo.x, lo.y], [hi.x, hi.y]);
        let mut best = reach;
        for r in self.tree.locate_in_envelope_intersecting(&env) {
            let prism = &self.prisms[r.data as usize];
            let dv = (prism.lo - z).max(z - prism.hi).max(0.0);
            if dv >= best {
                continue;
            }
            let dh = if a == b {
                Euclidean.distance(&Point::new(a.x, a.y), &prism.footprint)
            } else {
                Euclidean.distance(&Line::new((a.x, a.y), (b.x, b.y)), &prism.footprint)
            };
            best = best.min((dh * dh + dv * dv).sqrt());
        }
        best
    }

    /// True when some building's box (footprint box × its heights) meets `frustum` (exact test),
    /// among the buildings whose plan box lies within `reach` of `eye`: a cheap "is the city in
    /// view" for choosing a heading.
    pub fn any_in_view(&self, frustum: &Frustum, eye: DVec2, reach: f64) -> bool {
        let env = AABB::from_corners(
            [eye.x - reach, eye.y - reach],
            [eye.x + reach, eye.y + reach],
        );
        self.tree.locate_in_envelope_intersecting(&env).any(|r| {
            let prism = &self.prisms[r.data as usize];
            let [x0, y0] = r.geom().lower();
            let [x1, y1] = r.geom().upper();
            let b = Aabb3::new(DVec3::new(x0, y0, prism.lo), DVec3::new(x1, y1, prism.hi));
            frustum.intersects_aabb_exact(&b)
        })
    }

    /// The convex corners of the footprints' outer rings whose vertex lies within `reach` of
    /// `p` (plan, local frame), where the outline turns by at least `min_turn` radians, nearest
    /// first (ties in input order). Zero-length walls are skipped.
    pub fn convex_corners_near(&self, p: DVec2, reach: f64, min_turn: f64) -> Vec<FootprintCorner> {
        let env = AABB::from_corners([p.x - reach, p.y - reach], [p.x + reach, p.y + reach]);
        let mut out: Vec<(f64, FootprintCorner)> = Vec::new();
        let mut hits: Vec<u32> = self
            .tree
            .locate_in_envelope_intersecting(&env)
            .map(|r| r.data)
            .collect();
        hits.sort_unstable();
        for i in hits {
            let prism = &self.prisms[i as usize];
            let mut ring: Vec<DVec2> = prism
                .footprint
                .exterior()
                .coords()
                .map(|c| DVec2::new(c.x, c.y))
                .collect();
            ring.dedup_by(|a, b| a.distance(*b) < 1e-9);
            while ring.len() > 1 && ring[0].distance(ring[ring.len() - 1]) < 1e-9 {
                ring.pop();
            }
            if ring.len() < 3 {
                continue;
            }
            if ring_signed_area(&ring) < 0.0 {
                ring.reverse();
            }
            let n = ring.len();
            for k in 0..n {
                let (prev, at, next) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
                let d = at.distance(p);
                if d > reach {
                    continue;
                }
                let (li, lo) = (prev.distance(at), at.distance(next));
                let (ei, eo) = ((at - prev) / li, (next - at) / lo);
                // Counter-clockwise ring: a convex corner turns left.
                let turn = ei.perp_dot(eo).atan2(ei.dot(eo));
                if turn >= min_turn && turn < std::f64::consts::PI {
                    out.push((
                        d,
                        FootprintCorner {
                            at,
                            incoming: ei,
                            outgoing: eo,
                            incoming_len: li,
                            outgoing_len: lo,
                            turn,
                        },
                    ));
                }
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.into_iter().map(|(_, c)| c).collect()
    }

    /// True when `p` is at least `clearance` from every building.
    pub fn is_clear(&self, p: DVec3, clearance: f64) -> bool {
        self.distance(p, clearance) >= clearance
    }

    /// True when every point of the straight segment `a`–`b` (any slope) is at least `clearance`
    /// from every building. Horizontal segments are tested exactly; sloped ones at steps of a
    /// quarter of the clearance, each step needing the clearance plus half a step, which covers
    /// the points between steps.
    pub fn segment_is_clear(&self, a: DVec3, b: DVec3, clearance: f64) -> bool {
        if a.z == b.z {
            return self.segment_distance(a.truncate(), b.truncate(), a.z, clearance) >= clearance;
        }
        let step = 0.25 * clearance.max(1e-3);
        let n = (a.distance(b) / step).ceil().max(1.0) as usize;
        let need = clearance + 0.5 * step;
        (0..=n).all(|i| self.distance(a.lerp(b, i as f64 / n as f64), need) >= need)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::model::{BuildingId, HeightSource};
    use geo_types::polygon;

    fn one_building() -> Obstacles {
        let b = Building {
            id: BuildingId(0),
            source_id: "t:0".into(),
            footprint: polygon![(x: 10., y: 10.), (x: 20., y: 10.), (x: 20., y: 20.), (x: 10., y: 20.)],
            height_m: 12.0,
            min_height_m: 0.0,
            base_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        };
        let frame = LocalFrame {
            origin: DVec3::new(10.0, 10.0, 0.0),
        };
        Obstacles::from_buildings(&[b], &frame)
    }

    #[test]
    fn distances_to_a_prism() {
        let o = one_building();
        assert_eq!(o.len(), 1);
        assert_eq!(o.max_height(), 12.0);
        // Local frame: the building covers 0..10 × 0..10, 0..12 m.
        assert_eq!(o.distance(DVec3::new(5.0, 5.0, 1.7), 50.0), 0.0);
        assert!((o.distance(DVec3::new(13.0, 5.0, 1.7), 50.0) - 3.0).abs() < 1e-12);
        assert!((o.distance(DVec3::new(5.0, 5.0, 16.0), 50.0) - 4.0).abs() < 1e-12);
        assert!((o.distance(DVec3::new(13.0, 14.0, 12.0), 50.0) - 5.0).abs() < 1e-12);
        assert_eq!(o.distance(DVec3::new(100.0, 5.0, 1.7), 50.0), 50.0);
        assert!(!o.is_clear(DVec3::new(10.5, 5.0, 1.7), 1.0));
        assert!(o.is_clear(DVec3::new(11.0, 5.0, 1.7), 1.0));
        // A street past the wall at 2 m is clear, one through the building is not; a descent
        // over the roof is clear until it comes down beside the wall too close.
        let (a, b) = (DVec2::new(-5.0, 12.0), DVec2::new(15.0, 12.0));
        assert!(o.segment_distance(a, b, 1.7, 5.0) >= 2.0 - 1e-12);
        assert_eq!(o.segment_distance(a, DVec2::new(15.0, 5.0), 1.7, 5.0), 0.0);
        let top = DVec3::new(5.0, 5.0, 40.0);
        assert!(o.segment_is_clear(top, DVec3::new(5.0, 5.0, 14.0), 1.0));
        assert!(!o.segment_is_clear(top, DVec3::new(10.5, 5.0, 1.7), 1.0));
        assert!(Obstacles::none().is_clear(DVec3::ZERO, 1.0));
    }
}
