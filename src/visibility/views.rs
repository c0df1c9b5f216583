//! Random views over a city for occlusion benchmarks and tests: street-level eyes outside every
//! footprint (on the street edges when there are some) and flying eyes above the roofs.
//!
//! (The index benchmark's views, `index::bench::random_views`, need only block boxes; these need
//! the footprints, to keep street-level eyes out of buildings.)

use crate::blocks::BlockLayout;
use crate::city::City;
use crate::geom::predicates::{point_in_ring, Location};
use crate::geom::{Aabb3, Camera};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// Where a view is taken from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewKind {
    /// Eye at pedestrian height in a street, looking roughly level.
    Street,
    /// Eye above the roofs, looking down at an angle.
    Flying,
}

/// One view of a benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct View {
    /// Street or flying.
    pub kind: ViewKind,
    /// The camera (local frame).
    pub camera: Camera,
}

/// How [`random_views`] places its eyes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewOptions {
    /// Number of views.
    pub views: usize,
    /// Fraction of street-level views (the rest fly).
    pub street_fraction: f64,
    /// Seed of the generator.
    pub seed: u64,
    /// Eye height of street views, metres.
    pub eye_height: f64,
    /// Range of eye heights of flying views, metres.
    pub flying_heights: (f64, f64),
}

impl Default for ViewOptions {
    fn default() -> Self {
        Self {
            views: 100,
            street_fraction: 0.7,
            seed: 1,
            eye_height: 1.7,
            flying_heights: (30.0, 200.0),
        }
    }
}

/// Random views over the city (deterministic for a seed): street views at `eye_height` on the
/// street edges (or anywhere outside every footprint when there are none), flying views above.
pub fn random_views(city: &City, layout: &BlockLayout, opts: &ViewOptions) -> Vec<View> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let rings: Vec<(Aabb3, Vec<DVec2>)> = city
        .buildings
        .iter()
        .map(|b| {
            let r: Vec<DVec2> = b
                .footprint
                .exterior()
                .coords()
                .map(|c| {
                    city.frame
                        .to_local_f64(DVec3::new(c.x, c.y, 0.0))
                        .truncate()
                })
                .collect();
            (Aabb3::from_points(r.iter().map(|p| p.extend(0.0))), r)
        })
        .collect();
    let mut bounds = Aabb3::EMPTY;
    for (b, _) in &rings {
        bounds = bounds.union(*b);
    }
    if bounds.is_empty() {
        return Vec::new();
    }
    let edges: Vec<Vec<DVec2>> = layout
        .street_edges
        .iter()
        .map(|l| {
            l.coords()
                .map(|c| {
                    city.frame
                        .to_local_f64(DVec3::new(c.x, c.y, 0.0))
                        .truncate()
                })
                .collect::<Vec<_>>()
        })
        .filter(|l: &Vec<DVec2>| l.len() >= 2)
        .collect();
    let inside_any = |p: DVec2| {
        rings.iter().any(|(b, r)| {
            p.x >= b.min.x
                && p.x <= b.max.x
                && p.y >= b.min.y
                && p.y <= b.max.y
                && point_in_ring(p, r) != Location::Outside
        })
    };
    let (lo, hi) = (bounds.min.truncate(), bounds.max.truncate());
    let mut views = Vec::with_capacity(opts.views);
    for _ in 0..opts.views {
        let street = rng.random_bool(opts.street_fraction.clamp(0.0, 1.0));
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        if street {
            let mut p = lo;
            for _ in 0..100 {
                p = if edges.is_empty() {
                    DVec2::new(rng.random_range(lo.x..=hi.x), rng.random_range(lo.y..=hi.y))
                } else {
                    let e = &edges[rng.random_range(0..edges.len())];
                    let k = rng.random_range(0..e.len() - 1);
                    e[k].lerp(e[k + 1], rng.random_range(0.0..=1.0))
                };
                if !inside_any(p) {
                    break;
                }
            }
            let pitch = rng.random_range(-0.15..0.25);
            views.push(View {
                kind: ViewKind::Street,
                camera: Camera::new(p.extend(opts.eye_height), yaw, pitch),
            });
        } else {
            let p = DVec2::new(rng.random_range(lo.x..=hi.x), rng.random_range(lo.y..=hi.y));
            let (h0, h1) = opts.flying_heights;
            let z = if h1 > h0 {
                rng.random_range(h0..h1)
            } else {
                h0
            };
            let pitch = rng.random_range(-0.9..-0.1);
            views.push(View {
                kind: ViewKind::Flying,
                camera: Camera::new(p.extend(z), yaw, pitch),
            });
        }
    }
    views
}
