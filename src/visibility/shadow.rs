//! The occluder shadow of one facade edge (Willmott et al., §3.2.2, after Wonka & Schmalstieg 1999).
//!
//! A facade edge `(a, b)` at height `h` stands for a wall that is solid from the ground up to `h`
//! along the whole segment. Seen from a viewpoint `v`, a point `p` is hidden by that wall exactly
//! when the segment `v p` crosses the wall rectangle. In plan view this means `p` lies beyond the
//! edge's line (on the side away from `v`) and inside the wedge between the rays `v→a` and `v→b`;
//! in height it means `p.z` is at most the height of the plane through `v`, `a_h` and `b_h` above
//! `p` (and at least a value that is never above ground for a viewer at or above ground).
//!
//! The seed extends the side rays to a large parameter `t` and draws a triangle or quad. Here the
//! region is kept as an intersection of three half-planes (edge line, two rays) plus a fourth that
//! drops the part where the shadow plane is under the ground. Nothing is ever extended to
//! infinity: the cull map intersects each half-plane with its own rows, in f64, and clamps the
//! result to the map rectangle.

use crate::geom::predicates::{orient2d, Orientation};
use crate::geom::segment::point_segment_distance;
use glam::{DVec2, DVec3};

/// A facade top edge that occludes: the wall below `a`–`b` is solid from the ground to `height`.
/// Local frame, metres. For a counter-clockwise exterior ring the outward side is on the right of
/// `a → b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Occluder {
    /// First end point (x, y).
    pub a: DVec2,
    /// Second end point (x, y).
    pub b: DVec2,
    /// Height of the solid wall's top above the ground, metres (> 0).
    pub height: f64,
}

impl Occluder {
    /// Length of the edge in plan view.
    pub fn length(&self) -> f64 {
        (self.b - self.a).length()
    }

    /// True when `p` lies strictly on the outward side (right of `a → b`), decided exactly.
    pub fn faces(&self, p: DVec2) -> bool {
        orient2d(self.a, self.b, p) == Orientation::Clockwise
    }

    /// Plan-view distance from `p` to the segment.
    pub fn distance_to(&self, p: DVec2) -> f64 {
        point_segment_distance(p, self.a, self.b).0
    }
}

/// A closed half-plane `n · p + c ≥ 0` in plan view, `n` unit length (so values are distances).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfPlane {
    /// Unit normal pointing into the half-plane.
    pub n: DVec2,
    /// Offset.
    pub c: f64,
}

impl HalfPlane {
    /// The half-plane bounded by the line through `p` and `q` that holds `inside`; `None` when the
    /// line is degenerate.
    fn through(p: DVec2, q: DVec2, inside: DVec2) -> Option<Self> {
        let d = q - p;
        let len = d.length();
        if len <= 0.0 || !len.is_finite() {
            return None;
        }
        let mut n = DVec2::new(-d.y, d.x) / len;
        if n.dot(inside - p) < 0.0 {
            n = -n;
        }
        Some(Self { n, c: -n.dot(p) })
    }

    /// Signed distance of `p` (positive inside).
    pub fn eval(&self, p: DVec2) -> f64 {
        self.n.dot(p) + self.c
    }
}

/// The height field `z = z0 + zx·x + zy·y` of a shadow plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowPlane {
    /// Height at the local origin.
    pub z0: f64,
    /// Slope along x.
    pub zx: f64,
    /// Slope along y.
    pub zy: f64,
}

impl ShadowPlane {
    /// Height above `(x, y)`.
    pub fn at(&self, p: DVec2) -> f64 {
        self.z0 + self.zx * p.x + self.zy * p.y
    }
}

/// The occluder shadow of one edge (Willmott et al., §3.2.2, figure 8): the plan-view region where
/// anything below [`OccluderShadow::plane`] is hidden behind the wall.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OccluderShadow {
    /// The region: the intersection of these half-planes (edge line, ray `v→a`, ray `v→b`, plane
    /// above ground). All four are closed; the cull map shrinks them by a small margin.
    pub region: [HalfPlane; 4],
    /// Height below which points of the region are hidden.
    pub plane: ShadowPlane,
}

/// How far the drawn wall may lie from its [`Occluder`]: see [`OccluderShadow::with_slack`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Slack {
    /// Largest plan-view distance between an end of the drawn edge and the occluder's, metres.
    pub plan: f64,
    /// Largest amount by which the drawn top may lie below `height`, metres.
    pub height: f64,
}

impl Slack {
    /// The slack of a mesh whose vertices are the occluder's local-frame coordinates rounded to
    /// f32 (as the extruded meshes are): each coordinate moves by at most half an ulp, at most
    /// `2^-24 |x|`; over the two plan coordinates at most `√2 · 2^-24 · max(|x|, |y|)`, which
    /// `f32::EPSILON · max(|x|, |y|)` (= `2^-23 · …`) bounds. A micrometre is added for the f64
    /// rounding of the world → local subtraction (about `1e-16 ×` world coordinates of a few
    /// thousand km).
    pub fn f32_mesh(occ: &Occluder) -> Self {
        let m = occ.a.abs().max_element().max(occ.b.abs().max_element());
        Self {
            plan: f32::EPSILON as f64 * m + 1e-6,
            height: f32::EPSILON as f64 * occ.height.abs() + 1e-6,
        }
    }
}

/// Why an edge casts no shadow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoShadow {
    /// The viewer is below the ground (z < 0): the wall's hidden volume is not described by the
    /// plane.
    ViewerBelowGround,
    /// The edge has no length or no height.
    DegenerateEdge,
    /// The viewer lies on the edge's line (or sees it end-on within rounding): the wedge is empty.
    ViewerOnLine,
    /// Something was not finite.
    NotFinite,
}

impl OccluderShadow {
    /// Builds the shadow of `occ` seen from `viewer` (Willmott et al., §3.2.2). The edge may face the
    /// viewer or not: a solid wall hides what is behind it either way.
    ///
    /// Cases: viewer below the edge top (the plane rises behind the wall), at its height (the
    /// plane is horizontal at `height`), above it (the plane descends behind the wall and the
    /// fourth half-plane cuts the region where it reaches the ground), on the edge's line or
    /// seeing it end-on within f64 rounding (no shadow).
    pub fn new(viewer: DVec3, occ: &Occluder) -> Result<Self, NoShadow> {
        Self::with_slack(viewer, occ, Slack::default())
    }

    /// As [`OccluderShadow::new`] for a wall that is drawn only to within `slack` of `occ`: each
    /// end of the drawn edge lies within `slack.plan` metres of `a` and `b` (plan view), its top
    /// within `slack.height` of `height` (e.g. the f32 rounding of the drawn mesh, see
    /// [`Slack::f32_mesh`]). The region is the part of the exact shadow that every such wall
    /// casts:
    ///
    /// - the side rays are the tangents from the viewer to the discs of radius `slack.plan`
    ///   around `a` and `b`, on the inner side (every admissible end lies outside the wedge);
    /// - the edge line is moved `slack.plan` away from the viewer (every admissible edge, inside
    ///   the wedge, lies in the slab of that width around the exact line, so a point beyond the
    ///   slab and in the wedge is beyond the drawn edge);
    /// - the plane passes through the viewer and the edge line moved `slack.plan` towards the
    ///   viewer when the viewer is at or above the lowered top (a ray descending over the wall
    ///   must pass under the top at the nearest admissible edge), away from it when below (an
    ///   ascending ray at the farthest one), at the height `height - slack.height`.
    ///
    /// With zero slack this is exactly [`OccluderShadow::new`]. No shadow when the narrowed wedge
    /// is empty or the lowered top is not above the ground.
    pub fn with_slack(viewer: DVec3, occ: &Occluder, slack: Slack) -> Result<Self, NoShadow> {
        if !(viewer.is_finite()
            && occ.a.is_finite()
            && occ.b.is_finite()
            && occ.height.is_finite()
            && slack.plan.is_finite()
            && slack.height.is_finite())
        {
            return Err(NoShadow::NotFinite);
        }
        if viewer.z < 0.0 {
            return Err(NoShadow::ViewerBelowGround);
        }
        let (d, dz) = (slack.plan.max(0.0), slack.height.max(0.0));
        let len = occ.length();
        let height = occ.height - dz;
        if len.is_nan() || len <= 0.0 || occ.height <= 0.0 || height <= 0.0 {
            return Err(NoShadow::DegenerateEdge);
        }
        let v = viewer.truncate();
        let da = occ.a - v;
        let db = occ.b - v;
        let cross = da.perp_dot(db);
        // End-on within rounding: the wedge is too thin to cover any cell, and the plane's slope
        // would be ill-conditioned.
        if cross.abs() <= 1e-9 * da.length() * db.length() || cross == 0.0 {
            return Err(NoShadow::ViewerOnLine);
        }
        let mid = (occ.a + occ.b) * 0.5;
        // Beyond the edge line: the side away from the viewer. `far` is any point on that side.
        let edge_dir = occ.b - occ.a;
        let mut away = DVec2::new(-edge_dir.y, edge_dir.x);
        if away.dot(v - occ.a) > 0.0 {
            away = -away;
        }
        let away_unit = away / len;
        let far_point = mid + away;
        let (ray_a, ray_b) = if d == 0.0 {
            (
                HalfPlane::through(v, occ.a, occ.b).ok_or(NoShadow::ViewerOnLine)?,
                HalfPlane::through(v, occ.b, occ.a).ok_or(NoShadow::ViewerOnLine)?,
            )
        } else {
            // Tangent rays: each side turned inwards by asin(d / distance to the end).
            let (la, lb) = (da.length(), db.length());
            if la <= d || lb <= d {
                return Err(NoShadow::ViewerOnLine);
            }
            let (pa, pb) = ((d / la).asin(), (d / lb).asin());
            let wedge = cross.abs().atan2(da.dot(db));
            if wedge <= pa + pb {
                return Err(NoShadow::ViewerOnLine);
            }
            let s = cross.signum();
            let ua = DVec2::from_angle(s * pa).rotate(da / la);
            let ub = DVec2::from_angle(-s * pb).rotate(db / lb);
            let inside = v + (ua + ub);
            (
                HalfPlane::through(v, v + ua, inside).ok_or(NoShadow::ViewerOnLine)?,
                HalfPlane::through(v, v + ub, inside).ok_or(NoShadow::ViewerOnLine)?,
            )
        };
        let shift = away_unit * d;
        let beyond = HalfPlane::through(occ.a + shift, occ.b + shift, far_point + shift)
            .ok_or(NoShadow::DegenerateEdge)?;
        // Plane through V, A_h, B_h (the edge moved by ±d, see above): normal
        // n = (A_h − V) × (B_h − V); n.z is the plan cross product, ≠ 0 since V is off the line.
        let to_line = if viewer.z >= height { -shift } else { shift };
        let (pa, pb) = (occ.a + to_line - v, occ.b + to_line - v);
        let dzv = height - viewer.z;
        let ea = DVec3::new(pa.x, pa.y, dzv);
        let eb = DVec3::new(pb.x, pb.y, dzv);
        let n = ea.cross(eb);
        if n.z == 0.0 {
            return Err(NoShadow::ViewerOnLine);
        }
        let zx = -n.x / n.z;
        let zy = -n.y / n.z;
        let z0 = viewer.z - zx * v.x - zy * v.y;
        let plane = ShadowPlane { z0, zx, zy };
        if !(z0.is_finite() && zx.is_finite() && zy.is_finite()) {
            return Err(NoShadow::NotFinite);
        }
        // Where the plane is at or above the ground. When it is horizontal (viewer at the edge's
        // height) or rises behind the wall this half-plane holds the whole region; it is built
        // through a point of the wall line so it is never degenerate.
        let g = DVec2::new(zx, zy);
        let gl = g.length();
        let above_ground = if gl > 0.0 {
            // z0 + g·p ≥ 0  ⇔  (g/|g|)·p + z0/|g| ≥ 0
            HalfPlane {
                n: g / gl,
                c: z0 / gl,
            }
        } else {
            // Horizontal plane at the edge height (> 0): everything is above ground.
            HalfPlane {
                n: DVec2::X,
                c: f64::INFINITY,
            }
        };
        Ok(Self {
            region: [beyond, ray_a, ray_b, above_ground],
            plane,
        })
    }

    /// True when `p` lies in the closed region (no margin).
    pub fn contains(&self, p: DVec2) -> bool {
        self.region.iter().all(|h| h.eval(p) >= 0.0)
    }

    /// The interval of x on the horizontal line `y` where every half-plane holds with `margin`
    /// to spare, intersected with `[x_lo, x_hi]`; `None` when empty. Exact up to one rounding per
    /// half-plane; no infinities leave this function.
    pub fn row_interval(&self, y: f64, margin: f64, x_lo: f64, x_hi: f64) -> Option<(f64, f64)> {
        self.row_bounds(margin).interval(y, x_lo, x_hi)
    }

    /// The bounds of [`OccluderShadow::row_interval`] as linear functions of `y`, set up once
    /// per shadow so that each row costs a multiply-add per half-plane and no division.
    pub fn row_bounds(&self, margin: f64) -> RowBounds {
        let mut rb = RowBounds {
            bounds: [Bound::None; 4],
            empty: false,
        };
        for (k, h) in self.region.iter().enumerate() {
            // n.x·x + (n.y·y + c − margin) ≥ 0
            let c = h.c - margin;
            rb.bounds[k] = if c.is_infinite() {
                if c < 0.0 {
                    rb.empty = true;
                }
                Bound::None
            } else if h.n.x == 0.0 {
                Bound::Y { ny: h.n.y, c }
            } else {
                // x ≥ or ≤ −c/n.x − (n.y/n.x)·y; within a few roundings of `-t / n.x`, far
                // below the margin.
                let (a, b) = (-c / h.n.x, -h.n.y / h.n.x);
                if !(a.is_finite() && b.is_finite()) {
                    rb.empty = true;
                }
                if h.n.x > 0.0 {
                    Bound::Lower { a, b }
                } else {
                    Bound::Upper { a, b }
                }
            };
        }
        rb
    }
}

/// One half-plane of [`RowBounds`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Bound {
    /// No constraint.
    None,
    /// `x ≥ a + b·y`.
    Lower { a: f64, b: f64 },
    /// `x ≤ a + b·y`.
    Upper { a: f64, b: f64 },
    /// `ny·y + c ≥ 0` (a horizontal boundary).
    Y { ny: f64, c: f64 },
}

/// A shadow's region shrunk by a margin, as per-row x-bounds (see
/// [`OccluderShadow::row_bounds`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowBounds {
    bounds: [Bound; 4],
    /// Nothing is inside (a half-plane empty everywhere, or a bound not finite).
    empty: bool,
}

impl RowBounds {
    /// The x-interval of the shrunk region on the line `y`, within `[x_lo, x_hi]`; `None` when
    /// empty.
    #[inline]
    pub fn interval(&self, y: f64, x_lo: f64, x_hi: f64) -> Option<(f64, f64)> {
        if self.empty {
            return None;
        }
        let (mut lo, mut hi) = (x_lo, x_hi);
        for b in &self.bounds {
            match *b {
                Bound::None => {}
                Bound::Lower { a, b } => lo = lo.max(a + b * y),
                Bound::Upper { a, b } => hi = hi.min(a + b * y),
                Bound::Y { ny, c } => {
                    let t = ny * y + c;
                    if t.is_nan() || t < 0.0 {
                        return None;
                    }
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall() -> Occluder {
        Occluder {
            a: DVec2::new(10.0, -5.0),
            b: DVec2::new(10.0, 5.0),
            height: 10.0,
        }
    }

    #[test]
    fn below_edge_plane_rises_behind_the_wall() {
        let s = OccluderShadow::new(DVec3::new(0.0, 0.0, 2.0), &wall()).unwrap();
        // On the wall line the plane is at the wall's top.
        assert!((s.plane.at(DVec2::new(10.0, 0.0)) - 10.0).abs() < 1e-9);
        // Twice as far: 2 + 2·8 = 18.
        assert!((s.plane.at(DVec2::new(20.0, 0.0)) - 18.0).abs() < 1e-9);
        assert!(s.contains(DVec2::new(20.0, 0.0)));
        assert!(!s.contains(DVec2::new(5.0, 0.0)), "in front of the wall");
        assert!(!s.contains(DVec2::new(0.0, 0.0)), "the viewer");
        assert!(!s.contains(DVec2::new(20.0, 11.0)), "outside the wedge");
        assert!(s.contains(DVec2::new(20.0, 9.9)));
    }

    #[test]
    fn at_edge_height_plane_is_horizontal() {
        let s = OccluderShadow::new(DVec3::new(0.0, 0.0, 10.0), &wall()).unwrap();
        assert_eq!(s.plane.zx, 0.0);
        assert_eq!(s.plane.zy, 0.0);
        assert!((s.plane.z0 - 10.0).abs() < 1e-12);
        assert!(s.contains(DVec2::new(1e6, 0.0)));
        assert!(s.row_interval(0.0, 1e-6, -1e3, 1e3).unwrap().1 == 1e3);
    }

    #[test]
    fn above_edge_plane_descends_and_ends_at_ground() {
        let s = OccluderShadow::new(DVec3::new(0.0, 0.0, 20.0), &wall()).unwrap();
        // Plane: 20 − 10·(d/10) → zero at x = 20.
        assert!((s.plane.at(DVec2::new(15.0, 0.0)) - 5.0).abs() < 1e-9);
        assert!(s.contains(DVec2::new(19.0, 0.0)));
        assert!(!s.contains(DVec2::new(21.0, 0.0)), "plane under ground");
        let (lo, hi) = s.row_interval(0.0, 0.0, -100.0, 100.0).unwrap();
        assert!((lo - 10.0).abs() < 1e-9 && (hi - 20.0).abs() < 1e-9);
    }

    #[test]
    fn viewer_on_line_gives_no_shadow() {
        for v in [
            DVec3::new(10.0, -20.0, 2.0),
            DVec3::new(10.0, 0.0, 2.0),
            DVec3::new(10.0, 1e7, 50.0),
        ] {
            assert_eq!(
                OccluderShadow::new(v, &wall()),
                Err(NoShadow::ViewerOnLine),
                "{v}"
            );
        }
    }

    #[test]
    fn viewer_below_ground_and_degenerate_edges() {
        assert_eq!(
            OccluderShadow::new(DVec3::new(0.0, 0.0, -1.0), &wall()),
            Err(NoShadow::ViewerBelowGround)
        );
        let mut w = wall();
        w.b = w.a;
        assert_eq!(
            OccluderShadow::new(DVec3::new(0.0, 0.0, 1.0), &w),
            Err(NoShadow::DegenerateEdge)
        );
        let mut w = wall();
        w.height = 0.0;
        assert_eq!(
            OccluderShadow::new(DVec3::new(0.0, 0.0, 1.0), &w),
            Err(NoShadow::DegenerateEdge)
        );
        let mut w = wall();
        w.height = f64::NAN;
        assert_eq!(
            OccluderShadow::new(DVec3::new(0.0, 0.0, 1.0), &w),
            Err(NoShadow::NotFinite)
        );
    }

    #[test]
    fn nearly_end_on_edge_is_a_thin_finite_wedge() {
        // Viewer 1e-6 m off the wall's line, 1 km away.
        let v = DVec3::new(10.0 + 1e-6, -1000.0, 2.0);
        match OccluderShadow::new(v, &wall()) {
            Ok(s) => {
                assert!(s.plane.zx.is_finite() && s.plane.zy.is_finite());
                // The wedge at y = 100 is far thinner than a centimetre.
                if let Some((lo, hi)) = s.row_interval(100.0, 0.0, -1e4, 1e4) {
                    assert!(hi - lo < 1e-2, "{lo} {hi}");
                }
            }
            Err(e) => assert_eq!(e, NoShadow::ViewerOnLine),
        }
    }

    #[test]
    fn huge_extension_stays_finite() {
        // The side rays diverge slowly; rows very far away still give finite clamped intervals.
        let s = OccluderShadow::new(DVec3::new(0.0, 0.0, 1.0), &wall()).unwrap();
        let (lo, hi) = s.row_interval(1e12, 0.0, -1e15, 1e15).unwrap();
        assert!(lo.is_finite() && hi.is_finite());
        assert!(s.row_interval(0.0, 0.0, -f64::MAX, f64::MAX).is_some());
    }

    /// Brute force for the slack: every point hidden by `with_slack` is hidden by every wall
    /// whose ends lie within `plan` of the occluder's and whose top is within `height` below
    /// it (here the corners of that set of walls and random ones in it).
    #[test]
    fn slack_shadows_are_hidden_by_every_admissible_wall() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut hidden_points = 0;
        for _ in 0..1500 {
            let occ = Occluder {
                a: DVec2::new(rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0)),
                b: DVec2::new(rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0)),
                height: rng.random_range(2.0..30.0),
            };
            let slack = Slack {
                plan: rng.random_range(0.0..0.3),
                height: rng.random_range(0.0..0.5),
            };
            let v = DVec3::new(
                rng.random_range(-40.0..40.0),
                rng.random_range(-40.0..40.0),
                rng.random_range(0.0..45.0),
            );
            let Ok(s) = OccluderShadow::with_slack(v, &occ, slack) else {
                continue;
            };
            for _ in 0..40 {
                let p = DVec3::new(
                    rng.random_range(-120.0..120.0),
                    rng.random_range(-120.0..120.0),
                    rng.random_range(0.0..60.0),
                );
                if !(s.contains(p.truncate()) && p.z <= s.plane.at(p.truncate())) {
                    continue;
                }
                hidden_points += 1;
                for k in 0..12 {
                    let off = |rng: &mut rand_chacha::ChaCha8Rng| {
                        let ang = if k < 4 {
                            (k as f64) * std::f64::consts::FRAC_PI_2
                        } else {
                            rng.random_range(0.0..std::f64::consts::TAU)
                        };
                        DVec2::from_angle(ang) * slack.plan * rng.random_range(0.0..=1.0f64).sqrt()
                    };
                    let a = occ.a + off(&mut rng);
                    let b = occ.b + off(&mut rng);
                    let h = occ.height - slack.height * rng.random_range(0.0..=1.0);
                    // Segment v→p against the vertical rectangle over a–b up to h.
                    let (vp, ab) = (p.truncate() - v.truncate(), b - a);
                    let den = vp.perp_dot(ab);
                    assert!(den != 0.0, "{v} {p} {a} {b}");
                    let t = (a - v.truncate()).perp_dot(ab) / den;
                    let u = (a - v.truncate()).perp_dot(vp) / den;
                    assert!(
                        (-1e-9..=1.0 + 1e-9).contains(&t) && (-1e-9..=1.0 + 1e-9).contains(&u),
                        "ray misses the wall: t {t} u {u}, {v} {p} {occ:?} {slack:?}"
                    );
                    let z = v.z + (p.z - v.z) * t;
                    assert!(z <= h + 1e-9, "over the wall: {z} > {h}, {v} {p}");
                }
            }
        }
        assert!(hidden_points > 1000, "vacuous: {hidden_points}");
    }

    #[test]
    fn zero_slack_is_the_exact_shadow() {
        let v = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(
            OccluderShadow::with_slack(v, &wall(), Slack::default()),
            OccluderShadow::new(v, &wall())
        );
        // Slack only ever shrinks the region.
        let s = OccluderShadow::with_slack(
            v,
            &wall(),
            Slack {
                plan: 0.1,
                height: 0.1,
            },
        )
        .unwrap();
        assert!(s.contains(DVec2::new(20.0, 0.0)));
        assert!(!s.contains(DVec2::new(10.05, 0.0)), "inside the slab");
        assert!(
            !s.contains(DVec2::new(20.0, 9.99)),
            "outside the narrowed wedge"
        );
        assert!(s.plane.at(DVec2::new(20.0, 0.0)) < 18.0);
    }

    #[test]
    fn hidden_points_really_are_behind_the_wall() {
        // Brute force: for random points, "inside region and below plane" must imply that the
        // segment from the viewer crosses the wall rectangle.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let occ = wall();
        for _ in 0..2000 {
            let v = DVec3::new(
                rng.random_range(-50.0..9.0),
                rng.random_range(-30.0..30.0),
                rng.random_range(0.0..40.0),
            );
            let Ok(s) = OccluderShadow::new(v, &occ) else {
                continue;
            };
            let p = DVec3::new(
                rng.random_range(-50.0..80.0),
                rng.random_range(-60.0..60.0),
                rng.random_range(0.0..60.0),
            );
            let hidden = s.contains(p.truncate()) && p.z <= s.plane.at(p.truncate());
            if hidden {
                // Crossing of segment v→p with the plane x = 10.
                let t = (10.0 - v.x) / (p.x - v.x);
                assert!((0.0..=1.0 + 1e-9).contains(&t));
                let w = v + (p - v) * t;
                assert!(w.y >= -5.0 - 1e-6 && w.y <= 5.0 + 1e-6, "{v} {p} {w}");
                assert!(w.z >= -1e-6 && w.z <= 10.0 + 1e-6, "{v} {p} {w}");
            }
        }
    }
}
