//! Adversarial cameras for occlusion culling: eyes where a conservative cull map is easiest to
//! get wrong (Willmott et al., §3.2 assumes whole walls are drawn; the frame clips at the near plane and
//! rounds meshes to f32).
//!
//! Every view stands next to one building of the city, at `k · near` from a corner or a wall
//! (`k` log-uniform in `[0.05, 3]`), with `near` taken in turn from a list (by default
//! 0.1, 0.5, 2 and 10 m). The kinds ([`AdversarialKind`]) cover: diagonally off a corner looking
//! at it, in front of a wall looking at it, at wall-top height, on a wall's plane beyond its end
//! looking along it, beside a wall looking along it, 1 mm above a roof, and straight down and
//! straight up beside a wall. Deterministic for a seed.
//!
//! Some eyes land inside a neighbouring building (a touching row of houses leaves no street
//! between them): [`BuildingSolids::contains`] tells those apart, and a test counts them
//! separately, since from inside a closed prism nothing else can be seen.

use crate::city::{BuildingId, City};
use crate::geom::predicates::{point_in_ring, ring_signed_area, Location};
use crate::geom::Camera;
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI};

/// What an adversarial view stresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AdversarialKind {
    /// Diagonally off a corner (along the bisector of its two outward normals, ± 40°), looking
    /// at the corner.
    Corner,
    /// In front of a wall, looking at it (± 70°).
    Wall,
    /// In front of a wall or off a corner at exactly the wall's top height, looking level.
    WallTop,
    /// On the wall's plane, beyond one of its ends, looking along the wall.
    WallPlane,
    /// Beside a wall, looking along it (± 3°).
    AlongWall,
    /// 1 mm above a roof, near its edge, looking anywhere.
    AboveRoof,
    /// Beside a wall or a corner, looking straight down.
    StraightDown,
    /// Beside a wall or a corner, looking straight up.
    StraightUp,
}

impl AdversarialKind {
    /// Every kind, in the order the generator cycles through them.
    pub const ALL: [AdversarialKind; 8] = [
        AdversarialKind::Corner,
        AdversarialKind::Wall,
        AdversarialKind::WallTop,
        AdversarialKind::WallPlane,
        AdversarialKind::AlongWall,
        AdversarialKind::AboveRoof,
        AdversarialKind::StraightDown,
        AdversarialKind::StraightUp,
    ];
}

/// One adversarial view.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AdversarialView {
    /// What it stresses.
    pub kind: AdversarialKind,
    /// The building it stands next to.
    pub building: BuildingId,
    /// Distance from the corner or wall in units of `camera.near` (0 for the roof views).
    pub near_factor: f64,
    /// The camera (local frame), with its near plane set.
    pub camera: Camera,
}

/// How [`adversarial_views`] places its eyes.
#[derive(Clone, Debug, PartialEq)]
pub struct AdversarialOptions {
    /// Number of views.
    pub views: usize,
    /// Seed of the generator.
    pub seed: u64,
    /// Near plane distances, metres, used in turn (view `i` gets `nears[i % nears.len()]`).
    pub nears: Vec<f64>,
    /// Range of the eye's distance from the corner or wall, in units of `near`.
    pub near_factors: (f64, f64),
}

impl Default for AdversarialOptions {
    fn default() -> Self {
        Self {
            views: 1000,
            seed: 1,
            nears: vec![0.1, 0.5, 2.0, 10.0],
            near_factors: (0.05, 3.0),
        }
    }
}

/// The buildings' solids in the local frame (footprint rings with holes, between the minimum
/// height and the height), to tell whether an eye is inside one.
#[derive(Clone, Debug)]
pub struct BuildingSolids {
    solids: Vec<Solid>,
}

#[derive(Clone, Debug)]
struct Solid {
    id: BuildingId,
    /// Exterior ring, counter-clockwise, closed.
    exterior: Vec<DVec2>,
    holes: Vec<Vec<DVec2>>,
    min: DVec2,
    max: DVec2,
    bottom: f64,
    top: f64,
}

impl BuildingSolids {
    /// The solids of every building with a finite positive height and at least three corners.
    pub fn new(city: &City) -> Self {
        let solids = city
            .buildings
            .iter()
            .filter_map(|b| {
                let ring = |l: &geo_types::LineString<f64>| -> Vec<DVec2> {
                    l.coords().map(|c| city.frame.to_local_xy(*c)).collect()
                };
                let mut exterior = ring(b.footprint.exterior());
                if exterior.len() < 4 || !(b.height_m.is_finite() && b.height_m > 0.0) {
                    return None;
                }
                if ring_signed_area(&exterior) < 0.0 {
                    exterior.reverse();
                }
                let (min, max) = exterior.iter().fold(
                    (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                    |(lo, hi), p| (lo.min(*p), hi.max(*p)),
                );
                Some(Solid {
                    id: b.id,
                    exterior,
                    holes: b.footprint.interiors().iter().map(ring).collect(),
                    min,
                    max,
                    bottom: b.base_m + b.min_height_m.max(0.0),
                    top: b.top_z(),
                })
            })
            .collect();
        Self { solids }
    }

    /// Number of solids.
    pub fn len(&self) -> usize {
        self.solids.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.solids.is_empty()
    }

    /// The building whose closed solid holds `p` (boundary included), if any.
    pub fn containing(&self, p: DVec3) -> Option<BuildingId> {
        let q = p.truncate();
        self.solids
            .iter()
            .find(|s| {
                p.z >= s.bottom
                    && p.z <= s.top
                    && q.cmpge(s.min).all()
                    && q.cmple(s.max).all()
                    && point_in_ring(q, &s.exterior) != Location::Outside
                    && s.holes
                        .iter()
                        .all(|h| point_in_ring(q, h) != Location::Inside)
            })
            .map(|s| s.id)
    }

    /// True when `p` lies in some building's closed solid.
    pub fn contains(&self, p: DVec3) -> bool {
        self.containing(p).is_some()
    }
}

/// Adversarial views next to the city's buildings (see the module doc). Deterministic for
/// `opts.seed`; empty when the city has no building or `opts.nears` is empty.
pub fn adversarial_views(city: &City, opts: &AdversarialOptions) -> Vec<AdversarialView> {
    let solids = BuildingSolids::new(city);
    let nears: Vec<f64> = opts
        .nears
        .iter()
        .copied()
        .filter(|n| n.is_finite() && *n > 0.0)
        .collect();
    if solids.is_empty() || nears.is_empty() {
        return Vec::new();
    }
    let (f0, f1) = opts.near_factors;
    let (l0, l1) = (f0.max(1e-6).ln(), f1.max(f0.max(1e-6)).ln());
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut views = Vec::with_capacity(opts.views);
    for i in 0..opts.views {
        let near = nears[i % nears.len()];
        let kind = AdversarialKind::ALL[(i / nears.len()) % AdversarialKind::ALL.len()];
        let s = &solids.solids[rng.random_range(0..solids.solids.len())];
        let ring = &s.exterior[..s.exterior.len() - 1];
        let n = ring.len();
        let k = rng.random_range(0..n);
        let (a, b) = (ring[k], ring[(k + 1) % n]);
        let prev = ring[(k + n - 1) % n];
        let along = (b - a).normalize_or_zero();
        // Outward normal of a counter-clockwise ring: right of a → b.
        let out = DVec2::new(along.y, -along.x);
        let out_prev = {
            let d = (a - prev).normalize_or_zero();
            DVec2::new(d.y, -d.x)
        };
        let factor = if l1 > l0 {
            rng.random_range(l0..=l1).exp()
        } else {
            l0.exp()
        };
        let dist = factor * near;
        let jitter = |rng: &mut ChaCha8Rng, r: f64| rng.random_range(-r..=r);
        let height = s.top;
        let corner_eye = |rng: &mut ChaCha8Rng| {
            let bis = (out + out_prev).normalize_or(out);
            let dir = DVec2::from_angle(jitter(rng, 40f64.to_radians())).rotate(bis);
            a + dir * dist
        };
        let wall_eye = |rng: &mut ChaCha8Rng| a.lerp(b, rng.random_range(0.0..=1.0)) + out * dist;
        let yaw_to = |from: DVec2, to: DVec2| {
            let d = to - from;
            d.y.atan2(d.x)
        };
        let low_z = |rng: &mut ChaCha8Rng| rng.random_range(0.0..=height.max(0.5));
        let (eye, yaw, pitch, near_factor) = match kind {
            AdversarialKind::Corner => {
                let e = corner_eye(&mut rng);
                let yaw = yaw_to(e, a) + jitter(&mut rng, 0.35);
                (
                    e.extend(low_z(&mut rng)),
                    yaw,
                    rng.random_range(-0.5..0.7),
                    factor,
                )
            }
            AdversarialKind::Wall => {
                let e = wall_eye(&mut rng);
                let yaw = (-out).y.atan2((-out).x) + jitter(&mut rng, 1.2);
                (
                    e.extend(low_z(&mut rng)),
                    yaw,
                    rng.random_range(-0.5..0.7),
                    factor,
                )
            }
            AdversarialKind::WallTop => {
                let e = if rng.random_bool(0.5) {
                    corner_eye(&mut rng)
                } else {
                    wall_eye(&mut rng)
                };
                let yaw = yaw_to(e, a.lerp(b, 0.5)) + jitter(&mut rng, 1.0);
                (e.extend(height), yaw, jitter(&mut rng, 0.1), factor)
            }
            AdversarialKind::WallPlane => {
                // Beyond `a` on the line, looking back along the wall.
                let e = a - along * dist;
                let yaw = along.y.atan2(along.x) + jitter(&mut rng, 0.05);
                (
                    e.extend(low_z(&mut rng)),
                    yaw,
                    jitter(&mut rng, 0.3),
                    factor,
                )
            }
            AdversarialKind::AlongWall => {
                let e = wall_eye(&mut rng);
                let dir = if rng.random_bool(0.5) { along } else { -along };
                let yaw = dir.y.atan2(dir.x) + jitter(&mut rng, 3f64.to_radians());
                (
                    e.extend(low_z(&mut rng)),
                    yaw,
                    jitter(&mut rng, 0.3),
                    factor,
                )
            }
            AdversarialKind::AboveRoof => {
                // Just inside the edge (when that point is inside the footprint), 1 mm up.
                let inner = a.lerp(b, rng.random_range(0.0..=1.0)) - out * dist.min(2.0);
                let p = if point_in_ring(inner, &s.exterior) == Location::Inside {
                    inner
                } else {
                    a.lerp(b, 0.5)
                };
                (
                    p.extend(height + 1e-3),
                    rng.random_range(-PI..PI),
                    rng.random_range(-FRAC_PI_2..=FRAC_PI_2),
                    0.0,
                )
            }
            AdversarialKind::StraightDown | AdversarialKind::StraightUp => {
                let e = if rng.random_bool(0.5) {
                    corner_eye(&mut rng)
                } else {
                    wall_eye(&mut rng)
                };
                let z = rng.random_range(0.0..=2.0 * height + 5.0);
                let pitch = if kind == AdversarialKind::StraightDown {
                    -FRAC_PI_2
                } else {
                    FRAC_PI_2
                };
                (e.extend(z), rng.random_range(-PI..PI), pitch, factor)
            }
        };
        let mut camera = Camera::new(eye, yaw, pitch);
        camera.near = near;
        camera.far = camera.far.max(near * 100.0);
        views.push(AdversarialView {
            kind,
            building: s.id,
            near_factor,
            camera,
        });
    }
    views
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::visibility::synthetic::SyntheticCity;

    #[test]
    fn views_are_deterministic_cover_every_kind_and_near() {
        let c = SyntheticCity::generate(2, 2, 3, DVec2::new(1000.0, 2000.0));
        let opts = AdversarialOptions {
            views: 400,
            ..Default::default()
        };
        let v = adversarial_views(&c.city, &opts);
        assert_eq!(v.len(), 400);
        assert_eq!(v, adversarial_views(&c.city, &opts));
        for kind in AdversarialKind::ALL {
            for near in [0.1, 0.5, 2.0, 10.0] {
                assert!(
                    v.iter().any(|w| w.kind == kind && w.camera.near == near),
                    "{kind:?} {near}"
                );
            }
        }
        let solids = BuildingSolids::new(&c.city);
        for w in &v {
            let cam = &w.camera;
            assert!(cam.position.is_finite() && cam.position.z >= 0.0, "{w:?}");
            assert!(cam.far > cam.near);
            match w.kind {
                AdversarialKind::StraightDown => assert_eq!(cam.pitch, -FRAC_PI_2),
                AdversarialKind::StraightUp => assert_eq!(cam.pitch, FRAC_PI_2),
                AdversarialKind::AboveRoof => {
                    // 1 mm above its own building's roof: not inside it.
                    assert!(solids.containing(cam.position) != Some(w.building));
                }
                _ => {
                    assert!((0.05 - 1e-9..=3.0 + 1e-9).contains(&w.near_factor), "{w:?}");
                }
            }
        }
    }

    #[test]
    fn solids_tell_inside_from_outside() {
        let c = SyntheticCity::generate(1, 1, 9, DVec2::ZERO);
        let s = BuildingSolids::new(&c.city);
        let b = &c.city.buildings[0];
        let p = c.city.frame.to_local_xy(b.footprint.exterior().0[0]);
        // The first corner is on the boundary (inside, closed); far away is outside.
        assert!(s.contains(p.extend(1.0)));
        assert!(!s.contains(p.extend(b.height_m + 0.01)));
        assert!(!s.contains(DVec3::new(-1e4, -1e4, 1.0)));
    }
}
