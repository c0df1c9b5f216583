//! View frustum: six planes from a view-projection matrix, and the sphere / box / box∩sphere
//! tests with plane masking and temporal coherence (Willmott et al., §3.1, Pina, Serón and Cerezo, §4).
//!
//! Everything is f64 and meant for the local frame (world minus `LocalFrame::origin`): a frustum
//! built from a world-space camera far from the origin is moved into the local frame with
//! [`Frustum::translated`].
//!
//! # Plane masks
//! A [`PlaneMask`] has bit `i` set when plane `i` (left, right, bottom, top, near, far) still has
//! to be tested. A masked test clears the bits of the planes the volume lies fully inside, so the
//! children of a node skip the planes their parent is fully inside (the volumes of a hierarchy
//! are nested for the purpose of culling: a child's geometry lies inside its parent's volume).

use super::{Aabb3, BoundingSphere};
use glam::{DMat4, DVec3, DVec4};

/// Where a volume lies with respect to a frustum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Containment {
    /// Entirely outside (cull).
    Outside,
    /// Crosses at least one plane.
    Intersecting,
    /// Entirely inside (accept the subtree without further tests).
    Inside,
}

/// Bit `i` set: plane `i` of [`Frustum::planes`] still to be tested.
pub type PlaneMask = u8;

/// Every plane still to be tested.
pub const ALL_PLANES: PlaneMask = 0b11_1111;

/// A plane `n·p + d = 0`, `n` unit length, inside where `n·p + d ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal, pointing into the frustum.
    pub normal: DVec3,
    /// Offset.
    pub d: f64,
}

/// A view frustum as six inward-facing planes, in the local frame's coordinates (f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, right, bottom, top, near, far.
    pub planes: [Plane; 6],
}

/// Index of the left plane in [`Frustum::planes`].
pub const LEFT: usize = 0;
/// Index of the right plane.
pub const RIGHT: usize = 1;
/// Index of the bottom plane.
pub const BOTTOM: usize = 2;
/// Index of the top plane.
pub const TOP: usize = 3;
/// Index of the near plane.
pub const NEAR: usize = 4;
/// Index of the far plane.
pub const FAR: usize = 5;

impl Frustum {
    /// Extracts and normalises the planes of `clip_from_world` (Gribb & Hartmann), for a
    /// right-handed projection with depth in `[0, 1]` (wgpu / glam `perspective_rh`).
    pub fn from_clip_from_world(m: &DMat4) -> Self {
        let r0 = m.row(0);
        let r1 = m.row(1);
        let r2 = m.row(2);
        let r3 = m.row(3);
        let raw: [DVec4; 6] = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2];
        let planes = raw.map(|v| {
            let n = v.truncate();
            let len = n.length();
            Plane {
                normal: n / len,
                d: v.w / len,
            }
        });
        Self { planes }
    }

    /// The same frustum in coordinates `p' = p − offset` (e.g. world → local with
    /// `offset = LocalFrame::origin`).
    pub fn translated(&self, offset: DVec3) -> Self {
        // n·p + d = n·(p' + o) + d  ⇒  d' = d + n·o.
        Self {
            planes: self.planes.map(|pl| Plane {
                normal: pl.normal,
                d: pl.d + pl.normal.dot(offset),
            }),
        }
    }

    /// The eye: the common point of the four side planes (`None` when they are parallel, as in
    /// an orthographic projection).
    pub fn apex(&self) -> Option<DVec3> {
        intersect3(
            &self.planes[LEFT],
            &self.planes[RIGHT],
            &self.planes[BOTTOM],
        )
    }

    /// The eight corners: near (bottom-left, bottom-right, top-left, top-right), then far in
    /// the same order. `None` for a degenerate frustum.
    pub fn corners(&self) -> Option<[DVec3; 8]> {
        let p = &self.planes;
        let mut out = [DVec3::ZERO; 8];
        for (k, depth) in [NEAR, FAR].into_iter().enumerate() {
            for (j, vert) in [BOTTOM, TOP].into_iter().enumerate() {
                for (i, side) in [LEFT, RIGHT].into_iter().enumerate() {
                    out[k * 4 + j * 2 + i] = intersect3(&p[depth], &p[vert], &p[side])?;
                }
            }
        }
        Some(out)
    }

    /// True when `p` lies inside or on every plane.
    pub fn contains_point(&self, p: DVec3) -> bool {
        self.planes.iter().all(|pl| pl.distance(p) >= 0.0)
    }

    /// Sphere test against all six planes.
    pub fn test_sphere(&self, s: &BoundingSphere) -> Containment {
        self.test_sphere_masked(s, &mut ALL_PLANES.clone(), &mut 0)
    }

    /// Box test (n-vertex / p-vertex) against all six planes.
    pub fn test_aabb(&self, b: &Aabb3) -> Containment {
        self.test_aabb_masked(b, &mut ALL_PLANES.clone(), &mut 0)
    }

    /// True unless the box lies entirely outside one plane (its p-vertex behind it): the
    /// conservative "may be visible" test, [`Frustum::test_aabb`] `!= Outside` without the
    /// bookkeeping. A box that crosses no plane but misses the frustum near an edge or corner
    /// still passes; [`Frustum::intersects_aabb_exact`] settles those.
    pub fn intersects_aabb(&self, b: &Aabb3) -> bool {
        let c = b.center();
        let e = b.extent() * 0.5;
        self.planes
            .iter()
            .all(|pl| !matches!(box_plane(c, e, pl), PlaneSide::Out))
    }

    /// Test of the intersection of a box and a sphere (the BqR-tree leaf volume, Pina, Serón and Cerezo, §4):
    /// outside when the box or the sphere is outside a plane; a plane is cleared when the box or
    /// the sphere is fully inside it (the intersection is then inside it too).
    pub fn test_aabb_sphere(&self, b: &Aabb3, s: &BoundingSphere) -> Containment {
        self.test_aabb_sphere_masked(b, s, &mut ALL_PLANES.clone(), &mut 0)
    }

    /// Sphere test against the planes in `mask`; clears the bits of the planes the sphere is
    /// fully inside and adds the number of plane tests done to `tests`.
    pub fn test_sphere_masked(
        &self,
        s: &BoundingSphere,
        mask: &mut PlaneMask,
        tests: &mut u64,
    ) -> Containment {
        self.test_planes(mask, None, tests, |pl| sphere_plane(s, pl))
    }

    /// Box test against the planes in `mask` (as [`Frustum::test_sphere_masked`]). Per plane,
    /// the p-vertex (farthest along the normal) decides "outside" and the n-vertex "fully
    /// inside"; computed from the centre and the half extent.
    pub fn test_aabb_masked(
        &self,
        b: &Aabb3,
        mask: &mut PlaneMask,
        tests: &mut u64,
    ) -> Containment {
        let c = b.center();
        let e = b.extent() * 0.5;
        self.test_planes(mask, None, tests, |pl| box_plane(c, e, pl))
    }

    /// Box ∩ sphere test against the planes in `mask` (see [`Frustum::test_aabb_sphere`]).
    /// Each plane counts as one test.
    pub fn test_aabb_sphere_masked(
        &self,
        b: &Aabb3,
        s: &BoundingSphere,
        mask: &mut PlaneMask,
        tests: &mut u64,
    ) -> Containment {
        let c = b.center();
        let e = b.extent() * 0.5;
        self.test_planes(mask, None, tests, |pl| {
            let dist = pl.distance(s.center);
            if dist < -s.radius {
                return PlaneSide::Out;
            }
            match box_plane(c, e, pl) {
                PlaneSide::Crossing if dist >= s.radius => PlaneSide::In,
                side => side,
            }
        })
    }

    /// As [`Frustum::test_aabb_masked`], testing first the plane `*first` (the one that
    /// rejected this volume last frame: temporal coherence) and storing in `*first` the plane
    /// that rejects it now, if any.
    pub fn test_aabb_coherent(
        &self,
        b: &Aabb3,
        mask: &mut PlaneMask,
        first: &mut u8,
        tests: &mut u64,
    ) -> Containment {
        let c = b.center();
        let e = b.extent() * 0.5;
        self.test_planes(mask, Some(first), tests, |pl| box_plane(c, e, pl))
    }

    /// As [`Frustum::test_sphere_masked`] with temporal coherence (see
    /// [`Frustum::test_aabb_coherent`]).
    pub fn test_sphere_coherent(
        &self,
        s: &BoundingSphere,
        mask: &mut PlaneMask,
        first: &mut u8,
        tests: &mut u64,
    ) -> Containment {
        self.test_planes(mask, Some(first), tests, |pl| sphere_plane(s, pl))
    }

    /// The one plane loop of the culling tests: each plane in `mask` in turn (from `*first`,
    /// cyclically, when given; else from plane 0) is tested with `side`, counted in `tests`;
    /// a plane the volume is fully inside leaves the mask, and the first plane it is outside
    /// ends the loop (stored in `*first` when given).
    #[inline]
    fn test_planes(
        &self,
        mask: &mut PlaneMask,
        mut first: Option<&mut u8>,
        tests: &mut u64,
        side: impl Fn(&Plane) -> PlaneSide,
    ) -> Containment {
        let start = first.as_deref().map_or(0, |f| *f as usize % 6);
        for k in 0..6 {
            let i = (start + k) % 6;
            let bit = 1u8 << i;
            if *mask & bit == 0 {
                continue;
            }
            *tests += 1;
            match side(&self.planes[i]) {
                PlaneSide::Out => {
                    if let Some(f) = first.as_deref_mut() {
                        *f = i as u8;
                    }
                    return Containment::Outside;
                }
                PlaneSide::In => *mask &= !bit,
                PlaneSide::Crossing => {}
            }
        }
        masked_result(*mask)
    }

    /// Exact test: does the box share a point with the frustum (by more than a relative
    /// tolerance of 1e-9 of the coordinates' magnitude)? Separating-axis test over the box's
    /// three axes, the six plane normals and the cross products of the box axes with the
    /// frustum's twelve edges. Slow; the brute-force oracle for "no false culls".
    ///
    /// Returns `true` for a degenerate frustum (no corners), which no oracle can judge.
    pub fn intersects_aabb_exact(&self, b: &Aabb3) -> bool {
        let Some(corners) = self.corners() else {
            return true;
        };
        let c = b.center();
        let e = b.extent() * 0.5;
        let scale = corners
            .iter()
            .chain([b.min, b.max].iter())
            .map(|p| p.abs().max_element())
            .fold(1.0f64, f64::max);
        let tol = 1e-9 * scale;
        let separated = |axis: DVec3| -> bool {
            let len = axis.length();
            if len < 1e-12 {
                return false;
            }
            let a = axis / len;
            let bc = a.dot(c);
            let br = a.abs().dot(e);
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in &corners {
                let v = a.dot(*p);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            bc + br <= lo + tol || bc - br >= hi - tol
        };
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        if axes.iter().any(|&a| separated(a)) {
            return false;
        }
        if self.planes.iter().any(|pl| separated(pl.normal)) {
            return false;
        }
        // Edges: 4 lateral, 4 near, 4 far (corner order: bl, br, tl, tr).
        let ring = [(0usize, 1usize), (1, 3), (3, 2), (2, 0)];
        let mut edges = Vec::with_capacity(12);
        for i in 0..4 {
            edges.push(corners[i + 4] - corners[i]);
        }
        for (a, bb) in ring {
            edges.push(corners[bb] - corners[a]);
            edges.push(corners[bb + 4] - corners[a + 4]);
        }
        for ed in &edges {
            for ax in &axes {
                if separated(ax.cross(*ed)) {
                    return false;
                }
            }
        }
        true
    }
}

impl Plane {
    /// Signed distance of `p` (positive inside).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) + self.d
    }
}

/// Per-node state for temporal coherence, owned by the caller so that indexes stay immutable
/// and `Sync`: for each node, the plane that rejected it last frame.
#[derive(Clone, Debug, Default)]
pub struct CoherenceState {
    last_plane: Vec<u8>,
}

impl CoherenceState {
    /// State for `nodes` nodes, every node starting with the left plane.
    pub fn new(nodes: usize) -> Self {
        Self {
            last_plane: vec![0; nodes],
        }
    }
    /// The slot of node `i` (grows the state when needed).
    pub fn slot(&mut self, i: usize) -> &mut u8 {
        if i >= self.last_plane.len() {
            self.last_plane.resize(i + 1, 0);
        }
        &mut self.last_plane[i]
    }
    /// Number of nodes tracked.
    pub fn len(&self) -> usize {
        self.last_plane.len()
    }
    /// True when no node is tracked.
    pub fn is_empty(&self) -> bool {
        self.last_plane.is_empty()
    }
}

enum PlaneSide {
    Out,
    In,
    Crossing,
}

/// Where a sphere lies against one plane: outside beyond its radius, inside when its whole
/// radius is on the inner side.
#[inline]
fn sphere_plane(s: &BoundingSphere, pl: &Plane) -> PlaneSide {
    let dist = pl.distance(s.center);
    if dist < -s.radius {
        PlaneSide::Out
    } else if dist >= s.radius {
        PlaneSide::In
    } else {
        PlaneSide::Crossing
    }
}

#[inline]
fn box_plane(c: DVec3, e: DVec3, pl: &Plane) -> PlaneSide {
    let s = pl.distance(c);
    let r = pl.normal.abs().dot(e);
    if s + r < 0.0 {
        PlaneSide::Out
    } else if s - r >= 0.0 {
        PlaneSide::In
    } else {
        PlaneSide::Crossing
    }
}

#[inline]
fn masked_result(mask: PlaneMask) -> Containment {
    if mask == 0 {
        Containment::Inside
    } else {
        Containment::Intersecting
    }
}

/// The common point of three planes (Cramer's rule), `None` when nearly parallel.
fn intersect3(a: &Plane, b: &Plane, c: &Plane) -> Option<DVec3> {
    let bc = b.normal.cross(c.normal);
    let det = a.normal.dot(bc);
    if det.abs() < 1e-12 {
        return None;
    }
    let p = -(a.d * bc + b.d * c.normal.cross(a.normal) + c.d * a.normal.cross(b.normal)) / det;
    p.is_finite().then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Camera;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn cam(pos: DVec3, yaw: f64, pitch: f64) -> Camera {
        Camera::new(pos, yaw, pitch)
    }

    fn unit_box(c: DVec3, h: f64) -> Aabb3 {
        Aabb3::new(c - DVec3::splat(h), c + DVec3::splat(h))
    }

    #[test]
    fn points_in_front_inside_behind_outside() {
        for (yaw, pitch) in [
            (0.0, 0.0),
            (1.0, 0.3),
            (-2.5, -0.7),
            (0.4, -FRAC_PI_2),
            (2.0, FRAC_PI_2),
        ] {
            let c = cam(DVec3::new(10.0, -5.0, 1.7), yaw, pitch);
            let f = c.frustum();
            let fw = c.forward();
            for d in [0.6, 1.0, 100.0, 4999.0] {
                assert!(f.contains_point(c.position + fw * d), "in front at {d}");
            }
            for d in [0.1, 1.0, 100.0] {
                assert!(!f.contains_point(c.position - fw * d), "behind at {d}");
            }
            assert!(!f.contains_point(c.position + fw * 6000.0), "past far");
            assert!(!f.contains_point(c.position + fw * 0.4), "before near");
            // Far to the side is outside.
            let right = fw.cross(c.up());
            assert!(!f.contains_point(c.position + fw * 10.0 + right * 100.0));
            assert!(!f.contains_point(c.position + fw * 10.0 + c.up() * 100.0));
        }
    }

    #[test]
    fn apex_is_the_eye_and_corners_lie_on_planes() {
        let c = cam(DVec3::new(3.0, 4.0, 50.0), 0.7, -0.4);
        let f = c.frustum();
        let apex = f.apex().unwrap();
        assert!(
            (apex - c.position).length() < 1e-6,
            "{apex} vs {}",
            c.position
        );
        let corners = f.corners().unwrap();
        for p in corners {
            // Each corner lies inside (up to rounding) every plane.
            for pl in &f.planes {
                assert!(pl.distance(p) > -1e-6);
            }
        }
        // Near corners at near distance along forward, far corners at far distance.
        assert!(((corners[0] - c.position).dot(c.forward()) - c.near).abs() < 1e-6);
        assert!(((corners[7] - c.position).dot(c.forward()) - c.far).abs() < 1e-3);
    }

    #[test]
    fn sphere_dodges_one_plane() {
        let c = cam(DVec3::ZERO, 0.0, 0.0); // looks along +x
        let f = c.frustum();
        let inside = BoundingSphere {
            center: DVec3::new(100.0, 0.0, 0.0),
            radius: 1.0,
        };
        assert_eq!(f.test_sphere(&inside), Containment::Inside);
        let behind = BoundingSphere {
            center: DVec3::new(-100.0, 0.0, 0.0),
            radius: 1.0,
        };
        assert_eq!(f.test_sphere(&behind), Containment::Outside);
        let crossing_near = BoundingSphere {
            center: DVec3::new(0.0, 0.0, 0.0),
            radius: 2.0,
        };
        assert_eq!(f.test_sphere(&crossing_near), Containment::Intersecting);
        // Camera inside a large sphere: intersecting, never outside.
        let around = BoundingSphere {
            center: DVec3::new(-3.0, 1.0, 0.0),
            radius: 50.0,
        };
        assert_eq!(f.test_sphere(&around), Containment::Intersecting);
    }

    #[test]
    fn box_tests_p_and_n_vertex() {
        let c = cam(DVec3::ZERO, 0.0, 0.0);
        let f = c.frustum();
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(100.0, 0.0, 0.0), 1.0)),
            Containment::Inside
        );
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(-100.0, 0.0, 0.0), 1.0)),
            Containment::Outside
        );
        // Straddles the left plane (left is +y when looking along +x).
        let y_edge = 100.0 * (c.fov_y * 0.5).tan() * c.aspect;
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(100.0, y_edge, 0.0), 1.0)),
            Containment::Intersecting
        );
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(100.0, y_edge + 3.0, 0.0), 1.0)),
            Containment::Outside
        );
    }

    #[test]
    fn box_sphere_outside_if_either_inside_if_box() {
        let c = cam(DVec3::ZERO, 0.0, 0.0);
        let f = c.frustum();
        let y_edge = 100.0 * (c.fov_y * 0.5).tan() * c.aspect;
        // Box crosses the left plane, its sphere is small and inside: intersection inside.
        let b = Aabb3::new(
            DVec3::new(99.0, y_edge - 10.0, -1.0),
            DVec3::new(101.0, y_edge + 10.0, 1.0),
        );
        let s_in = BoundingSphere {
            center: DVec3::new(100.0, y_edge - 5.0, 0.0),
            radius: 1.0,
        };
        assert_eq!(f.test_aabb(&b), Containment::Intersecting);
        assert_eq!(f.test_aabb_sphere(&b, &s_in), Containment::Inside);
        // Sphere outside, box crossing: outside.
        let s_out = BoundingSphere {
            center: DVec3::new(100.0, y_edge + 8.0, 0.0),
            radius: 1.0,
        };
        assert_eq!(f.test_aabb_sphere(&b, &s_out), Containment::Outside);
        // Box outside, sphere crossing: outside.
        let b_out = unit_box(DVec3::new(-100.0, 0.0, 0.0), 1.0);
        let s_big = BoundingSphere {
            center: DVec3::ZERO,
            radius: 500.0,
        };
        assert_eq!(f.test_aabb_sphere(&b_out, &s_big), Containment::Outside);
        // Box inside: inside whatever the sphere.
        let b_in = unit_box(DVec3::new(100.0, 0.0, 0.0), 1.0);
        assert_eq!(f.test_aabb_sphere(&b_in, &s_big), Containment::Inside);
    }

    #[test]
    fn masks_clear_planes_fully_inside() {
        let c = cam(DVec3::ZERO, 0.0, 0.0);
        let f = c.frustum();
        // A big box that crosses only the near plane.
        let b = Aabb3::new(DVec3::new(0.2, -0.1, -0.1), DVec3::new(10.0, 0.1, 0.1));
        let mut mask = ALL_PLANES;
        let mut tests = 0;
        assert_eq!(
            f.test_aabb_masked(&b, &mut mask, &mut tests),
            Containment::Intersecting
        );
        assert_eq!(tests, 6);
        assert_eq!(mask, 1 << NEAR, "only near still crossing: {mask:06b}");
        // A child fully past the near plane then needs one test only.
        let child = Aabb3::new(DVec3::new(5.0, -0.1, -0.1), DVec3::new(6.0, 0.1, 0.1));
        let mut t2 = 0;
        let mut m2 = mask;
        assert_eq!(
            f.test_aabb_masked(&child, &mut m2, &mut t2),
            Containment::Inside
        );
        assert_eq!(t2, 1);
    }

    #[test]
    fn coherence_tests_the_last_rejecting_plane_first() {
        let c = cam(DVec3::ZERO, 0.0, 0.0);
        let f = c.frustum();
        let b = unit_box(DVec3::new(-100.0, 0.0, 0.0), 1.0); // behind: rejected by near
        let mut first = 0u8;
        let mut tests = 0;
        let r = f.test_aabb_coherent(&b, &mut ALL_PLANES.clone(), &mut first, &mut tests);
        assert_eq!(r, Containment::Outside);
        let rejecting = first;
        let mut t2 = 0;
        let r2 = f.test_aabb_coherent(&b, &mut ALL_PLANES.clone(), &mut first, &mut t2);
        assert_eq!(r2, Containment::Outside);
        assert_eq!(first, rejecting);
        assert_eq!(t2, 1, "rejected by the remembered plane in one test");
        let s = BoundingSphere::from_aabb(&b);
        let mut t3 = 0;
        let r3 = f.test_sphere_coherent(&s, &mut ALL_PLANES.clone(), &mut first, &mut t3);
        assert_eq!((r3, t3), (Containment::Outside, 1));
    }

    #[test]
    fn straight_down_and_up() {
        let down = cam(DVec3::new(0.0, 0.0, 300.0), 0.3, -FRAC_PI_2);
        let f = down.frustum();
        assert!(f
            .planes
            .iter()
            .all(|p| p.normal.is_finite() && p.d.is_finite()));
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(0.0, 0.0, 10.0), 5.0)),
            Containment::Inside
        );
        assert_eq!(
            f.test_aabb(&unit_box(DVec3::new(0.0, 0.0, 400.0), 5.0)),
            Containment::Outside
        );
        let up = cam(DVec3::new(0.0, 0.0, 1.7), -1.0, FRAC_PI_2);
        let g = up.frustum();
        assert_eq!(
            g.test_aabb(&unit_box(DVec3::new(0.0, 0.0, 100.0), 5.0)),
            Containment::Inside
        );
        assert_eq!(
            g.test_aabb(&unit_box(DVec3::new(0.0, 0.0, -100.0), 5.0)),
            Containment::Outside
        );
    }

    #[test]
    fn near_1e_3_far_1e6() {
        let mut c = cam(DVec3::new(5.0, 5.0, 2.0), 0.25 * PI, 0.05);
        c.near = 1e-3;
        c.far = 1e6;
        let f = c.frustum();
        let fw = c.forward();
        assert!(f.contains_point(c.position + fw * 2e-3));
        assert!(f.contains_point(c.position + fw * 9.9e5));
        assert!(!f.contains_point(c.position + fw * 1.01e6));
        assert!(!f.contains_point(c.position + fw * 5e-4));
        let apex = f.apex().unwrap();
        assert!((apex - c.position).length() < 1e-6);
        // A box 500 km away, in front: inside.
        let b = unit_box(c.position + fw * 5e5, 10.0);
        assert_eq!(f.test_aabb(&b), Containment::Inside);
        assert!(f.intersects_aabb_exact(&b));
    }

    #[test]
    fn world_camera_at_1e7_translated_to_local() {
        let origin = DVec3::new(1.0e7, -2.0e6, 0.0);
        let local_eye = DVec3::new(12_345.5, -54_321.25, 1.7);
        let world = cam(origin + local_eye, 1.1, -0.05);
        let local = cam(local_eye, 1.1, -0.05);
        let fw = world.frustum().translated(origin);
        let fl = local.frustum();
        for (a, b) in fw.planes.iter().zip(fl.planes.iter()) {
            assert!((a.normal - b.normal).length() < 1e-9);
            assert!((a.d - b.d).abs() < 1e-4, "{} vs {}", a.d, b.d);
        }
        // Classification of local points up to 1e5 agrees.
        let mut rng_state = 12345u64;
        let mut next = || {
            rng_state = rng_state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng_state >> 11) as f64 / (1u64 << 53) as f64) * 2e5 - 1e5
        };
        for _ in 0..500 {
            let b = unit_box(DVec3::new(next(), next(), next() * 1e-3), 20.0);
            assert_eq!(fw.test_aabb(&b), fl.test_aabb(&b));
        }
    }

    #[test]
    fn exact_oracle_agrees_on_clear_cases_and_is_finer_than_planes() {
        let c = cam(DVec3::ZERO, 0.0, 0.0);
        let f = c.frustum();
        assert!(f.intersects_aabb_exact(&unit_box(DVec3::new(100.0, 0.0, 0.0), 1.0)));
        assert!(!f.intersects_aabb_exact(&unit_box(DVec3::new(-100.0, 0.0, 0.0), 1.0)));
        // Camera inside the box.
        assert!(f.intersects_aabb_exact(&unit_box(DVec3::ZERO, 10.0)));
        // A box beyond the corner where the far and left planes meet: it crosses each plane
        // (so the per-plane test cannot reject it) but misses the frustum.
        let far = c.far;
        let y = far * (c.fov_y * 0.5).tan() * c.aspect;
        let corner_box = Aabb3::new(
            DVec3::new(far - 5.0, y + 5.0, -1.0),
            DVec3::new(far + 50.0, y + 50.0, 1.0),
        );
        assert_eq!(f.test_aabb(&corner_box), Containment::Intersecting);
        assert!(!f.intersects_aabb_exact(&corner_box));
    }

    proptest::proptest! {
        /// The one "may be visible" box test: equal to `test_aabb != Outside`, never false for a
        /// box the exact separating-axis oracle sees, and equal to the p-vertex formulation the
        /// occlusion culler used to carry (`n · p_vertex + d ≥ 0` on every plane) except where
        /// that distance is within rounding of zero.
        #[test]
        fn intersects_aabb_is_the_conservative_box_test(
            eye in (-50.0f64..50.0, -50.0f64..50.0, 0.0f64..80.0),
            yaw in -3.2f64..3.2, pitch in -1.5f64..1.5,
            lo in (-300.0f64..300.0, -300.0f64..300.0, -10.0f64..60.0),
            ext in (0.0f64..60.0, 0.0f64..60.0, 0.0f64..60.0),
        ) {
            let f = cam(DVec3::new(eye.0, eye.1, eye.2), yaw, pitch).frustum();
            let min = DVec3::new(lo.0, lo.1, lo.2);
            let b = Aabb3::new(min, min + DVec3::new(ext.0, ext.1, ext.2));
            let got = f.intersects_aabb(&b);
            proptest::prop_assert_eq!(got, f.test_aabb(&b) != Containment::Outside);
            if f.intersects_aabb_exact(&b) {
                proptest::prop_assert!(got);
            }
            let mut near_zero = false;
            let p_vertex = f.planes.iter().all(|p| {
                let v = DVec3::new(
                    if p.normal.x >= 0.0 { b.max.x } else { b.min.x },
                    if p.normal.y >= 0.0 { b.max.y } else { b.min.y },
                    if p.normal.z >= 0.0 { b.max.z } else { b.min.z },
                );
                let d = p.distance(v);
                near_zero |= d.abs() <= 1e-9 * (1.0 + v.abs().max_element() + p.d.abs());
                d >= 0.0
            });
            if !near_zero {
                proptest::prop_assert_eq!(got, p_vertex);
            }
        }
    }
}
