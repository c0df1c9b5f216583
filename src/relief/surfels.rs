//! The choice of oblique maps by façade votes (Andujar et al., §4.2).
//!
//! The node's walls are cut into **surfels** of about the node's texel size: each wall (a ring
//! edge of a building's footprint, from the building's base to its top) is divided into
//! `⌈length/t⌉ × ⌈height/t⌉` patches, each with its centre, outward normal and area. Each surfel
//! **votes** for every direction it is visible from. Directions are the paper's bins: 10
//! elevations θ (centres `(i + ½)·9°`) × 48 azimuths ψ (centres `(k + ½)·7.5°`). A surfel is
//! visible from `(θ, ψ)` when it faces the azimuth (outward normal · horizontal direction > 0)
//! and θ is above its **horizon** in that azimuth: the largest elevation of the node's height
//! field (its zenithal map) seen from the surfel along the azimuth, found by walking the map's
//! texels from one texel out of the wall (the point-sampled map places a wall anywhere within
//! its boundary texel, so the walk starts past it). One walk per azimuth answers all ten
//! elevations.
//!
//! The benefit of a direction is the paper's `C(θ, ψ)`: the area of the voting surfels times the
//! sampling quality `cos θ` (the sine of the angle to the vertical: low views sample walls
//! better). The best direction becomes the next oblique map; the surfels it sees stop voting;
//! the vote repeats until the maps see the coverage target of the **seeable** area (surfels
//! visible from at least one bin; a wall against a neighbour is seen from nowhere, and is
//! counted apart), or the map limit is reached, or no direction sees anything new. The maps
//! come out in decreasing order of the area they add; the first four are the core set.
//!
//! More than [`MAX_SURFELS`] surfels are thinned by a fixed stride, the kept ones weighted by
//! the stride, so the coverage is an unbiased estimate on large nodes.

use super::map::{MapFrame, ReliefMap, EMPTY, Q_MAX};
use crate::blockmap::Source;
use glam::{DVec2, DVec3};
use serde::Serialize;

/// Elevation bins.
pub const ELEVATIONS: usize = 10;
/// Azimuth bins.
pub const AZIMUTHS: usize = 48;
/// Surfels voting per node at most (see the module doc).
pub const MAX_SURFELS: usize = 16_384;

/// The centre of elevation bin `i`, radians.
pub fn elevation(i: usize) -> f64 {
    ((i as f64 + 0.5) * 90.0 / ELEVATIONS as f64).to_radians()
}

/// The centre of azimuth bin `k`, radians (counter-clockwise from east).
pub fn azimuth(k: usize) -> f64 {
    ((k as f64 + 0.5) * 360.0 / AZIMUTHS as f64).to_radians()
}

/// The unit viewing direction (from the viewer into the scene) of bin `(i, k)`: the viewer
/// stands at elevation θ and azimuth ψ of the scene.
pub fn bin_direction(i: usize, k: usize) -> DVec3 {
    let (t, p) = (elevation(i), azimuth(k));
    -DVec3::new(t.cos() * p.cos(), t.cos() * p.sin(), t.sin())
}

/// One wall patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surfel {
    /// Centre (local frame).
    pub p: DVec3,
    /// Outward horizontal normal (unit).
    pub n: DVec2,
    /// Area it stands for, m² (its own, times the thinning stride).
    pub area: f64,
}

/// The walls of `buildings` (indices into `source.buildings`) as surfels of side about
/// `texel_m`, thinned to [`MAX_SURFELS`].
pub fn surfels(source: &Source, buildings: &[u32], texel_m: f64) -> Vec<Surfel> {
    let mut out = Vec::new();
    for &b in buildings {
        let Some(Some(sb)) = source.buildings.get(b as usize) else {
            continue;
        };
        let h = sb.z1 - sb.z0;
        if h.is_nan() || h <= 0.0 {
            continue;
        }
        let nz = (h / texel_m).ceil().max(1.0) as usize;
        for ring in &sb.rings {
            for e in 0..ring.len() {
                let (a, c) = (ring[e], ring[(e + 1) % ring.len()]);
                let d = c - a;
                let len = d.length();
                if len.is_nan() || len <= 0.0 {
                    continue;
                }
                // Rings run with the material on their left (exterior CCW, holes CW): the
                // outward normal is on the right.
                let n = DVec2::new(d.y, -d.x) / len;
                let nu = (len / texel_m).ceil().max(1.0) as usize;
                let area = len / nu as f64 * h / nz as f64;
                for iu in 0..nu {
                    let q = a + d * ((iu as f64 + 0.5) / nu as f64);
                    for iz in 0..nz {
                        let z = sb.z0 + h * (iz as f64 + 0.5) / nz as f64;
                        out.push(Surfel {
                            p: DVec3::new(q.x, q.y, z),
                            n,
                            area,
                        });
                    }
                }
            }
        }
    }
    if out.len() > MAX_SURFELS {
        let stride = out.len().div_ceil(MAX_SURFELS);
        out = out
            .into_iter()
            .step_by(stride)
            .map(|s| Surfel {
                area: s.area * stride as f64,
                ..s
            })
            .collect();
    }
    out
}

/// The tangent of the horizon seen from `s` along the horizontal unit direction `w` over the
/// zenithal map `zen` (heights over `z_range`): the largest `(z − s.z)/dist` of a covered texel,
/// `dist` the distance to the texel's nearest point along the walk, starting one texel out;
/// −∞ when nothing is in the way.
pub fn horizon_tan(zen: &ReliefMap, z_range: [f64; 2], s: DVec3, w: DVec2, top_z: f64) -> f64 {
    let f = &zen.frame;
    let t = f.texel_m();
    let m = f.m as i64;
    let range = z_range[1] - z_range[0];
    // Texel coordinates of the start (one texel out of the wall) and the direction.
    let start = DVec2::new(
        (s.x + w.x * t - f.origin.x) / t,
        (s.y + w.y * t - f.origin.y) / t,
    );
    let mut best = f64::NEG_INFINITY;
    let (mut i, mut j) = (start.x.floor() as i64, start.y.floor() as i64);
    let step = [
        if w.x > 0.0 { 1 } else { -1 },
        if w.y > 0.0 { 1 } else { -1 },
    ];
    let next = |c: f64, i: i64, d: f64, st: i64| -> f64 {
        if d == 0.0 {
            return f64::INFINITY;
        }
        let edge = if st > 0 { (i + 1) as f64 } else { i as f64 };
        (edge - c) / d
    };
    // Parameters (texels along w) at which the walk crosses the next x and y lines.
    let mut tx = next(start.x, i, w.x, step[0]);
    let mut ty = next(start.y, j, w.y, step[1]);
    let dx = if w.x == 0.0 {
        f64::INFINITY
    } else {
        1.0 / w.x.abs()
    };
    let dy = if w.y == 0.0 {
        f64::INFINITY
    } else {
        1.0 / w.y.abs()
    };
    let mut entry = 0.0f64;
    loop {
        if i < 0 || j < 0 || i >= m || j >= m {
            // Outside the square: only entering it again could matter, and a straight walk
            // that has left it (or starts outside it and moves away) never does.
            let inside_later = (i < 0 && step[0] > 0)
                || (i >= m && step[0] < 0)
                || (j < 0 && step[1] > 0)
                || (j >= m && step[1] < 0);
            if !inside_later || (i < -m || j < -m || i >= 2 * m || j >= 2 * m) {
                break;
            }
        } else {
            let q = zen.depth[(j * m + i) as usize];
            let dist = (1.0 + entry) * t;
            if q != EMPTY {
                let z = z_range[0] + f64::from(q) / f64::from(Q_MAX) * range;
                best = best.max((z - s.z) / dist);
            }
            // Nothing farther can rise above the horizon found so far.
            if (top_z - s.z) / dist <= best {
                break;
            }
        }
        if tx < ty {
            entry = tx;
            tx += dx;
            i += step[0];
        } else {
            entry = ty;
            ty += dy;
            j += step[1];
        }
    }
    best
}

/// One chosen oblique direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Chosen {
    /// Elevation bin.
    pub elevation_bin: usize,
    /// Azimuth bin.
    pub azimuth_bin: usize,
    /// Viewing direction (into the scene).
    pub dir: [f64; 3],
    /// Seeable wall area it added, m².
    pub gain_m2: f64,
    /// Share of the seeable area seen by this map and the ones before it.
    pub coverage: f64,
}

/// What the vote found for one node.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Vote {
    /// The directions, in the order chosen (decreasing gain).
    pub chosen: Vec<Chosen>,
    /// Wall area of the node, m².
    pub wall_m2: f64,
    /// Of it, seen from at least one bin.
    pub seeable_m2: f64,
    /// Share of the seeable area the chosen maps see.
    pub coverage: f64,
    /// Surfels that voted.
    pub surfels: usize,
}

/// Votes over `surfels` with the node's zenithal map `zen` (heights over `z_range`) and picks
/// oblique directions until `target` of the seeable area is seen or `max_maps` are chosen.
pub fn vote(
    surfels: &[Surfel],
    zen: &ReliefMap,
    z_range: [f64; 2],
    target: f64,
    max_maps: usize,
) -> Vote {
    let top = z_range[1];
    let tans: Vec<f64> = (0..ELEVATIONS).map(|i| elevation(i).tan()).collect();
    let dirs: Vec<DVec2> = (0..AZIMUTHS)
        .map(|k| DVec2::new(azimuth(k).cos(), azimuth(k).sin()))
        .collect();
    // Per surfel, per azimuth: the lowest elevation bin that sees it (ELEVATIONS: none).
    use rayon::prelude::*;
    let first_bin: Vec<[u8; AZIMUTHS]> = surfels
        .par_iter()
        .map(|s| {
            let mut row = [ELEVATIONS as u8; AZIMUTHS];
            for (k, w) in dirs.iter().enumerate() {
                if s.n.dot(*w) <= 0.0 {
                    continue;
                }
                let h = horizon_tan(zen, z_range, s.p, *w, top);
                if let Some(i) = tans.iter().position(|&t| t > h) {
                    row[k] = i as u8;
                }
            }
            row
        })
        .collect();
    let wall: f64 = surfels.iter().map(|s| s.area).sum();
    let seeable_of: Vec<bool> = first_bin
        .iter()
        .map(|r| r.iter().any(|&b| (b as usize) < ELEVATIONS))
        .collect();
    let seeable: f64 = surfels
        .iter()
        .zip(&seeable_of)
        .filter(|(_, &v)| v)
        .map(|(s, _)| s.area)
        .sum();
    let mut out = Vote {
        wall_m2: wall,
        seeable_m2: seeable,
        surfels: surfels.len(),
        coverage: 1.0,
        ..Vote::default()
    };
    if seeable <= 0.0 {
        return out;
    }
    let mut seen = vec![false; surfels.len()];
    let mut seen_area = 0.0;
    while out.chosen.len() < max_maps && seen_area < target * seeable {
        // Area per (lowest visible elevation bin, azimuth), then summed upwards: a surfel
        // seen from bin i is seen from every higher elevation of that azimuth.
        let mut c = [[0.0f64; AZIMUTHS]; ELEVATIONS + 1];
        for (s, (row, done)) in surfels.iter().zip(first_bin.iter().zip(&seen)) {
            if *done {
                continue;
            }
            for (k, &b) in row.iter().enumerate() {
                c[b as usize][k] += s.area;
            }
        }
        for i in 1..ELEVATIONS {
            let below = c[i - 1];
            for (v, b) in c[i].iter_mut().zip(below) {
                *v += b;
            }
        }
        let mut best: Option<(f64, usize, usize)> = None;
        for (i, ci) in c.iter().take(ELEVATIONS).enumerate() {
            let q = elevation(i).cos();
            for (k, &a) in ci.iter().enumerate() {
                let benefit = a * q;
                if benefit > 0.0 && best.is_none_or(|(b, _, _)| benefit > b) {
                    best = Some((benefit, i, k));
                }
            }
        }
        let Some((_, i, k)) = best else { break };
        let mut gain = 0.0;
        for (s, (row, done)) in surfels.iter().zip(first_bin.iter().zip(seen.iter_mut())) {
            if !*done && (row[k] as usize) <= i {
                *done = true;
                gain += s.area;
            }
        }
        seen_area += gain;
        out.chosen.push(Chosen {
            elevation_bin: i,
            azimuth_bin: k,
            dir: bin_direction(i, k).to_array(),
            gain_m2: gain,
            coverage: seen_area / seeable,
        });
    }
    out.coverage = seen_area / seeable;
    out
}

/// The oblique frame of a chosen direction over the node's box.
pub fn oblique_frame(c: &Chosen, min: DVec3, max: DVec3, m: u32) -> MapFrame {
    MapFrame::fitting(DVec3::from_array(c.dir), min, max, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::relief::map::{MapFrame, MapKind, ReliefMap};

    fn flat_map(m: u32, side: f64, fill: impl Fn(u32, u32) -> u16) -> ReliefMap {
        let f = MapFrame::zenithal(DVec3::ZERO, DVec3::new(side, side, 10.0), m);
        let mut depth = vec![0u16; (m * m) as usize];
        for j in 0..m {
            for i in 0..m {
                depth[(j * m + i) as usize] = fill(i, j);
            }
        }
        ReliefMap {
            kind: MapKind::Zenithal,
            frame: f,
            color: vec![[0; 4]; (m * m) as usize],
            depth,
        }
    }

    #[test]
    fn bins_cover_the_upper_hemisphere() {
        for i in 0..ELEVATIONS {
            for k in 0..AZIMUTHS {
                let d = bin_direction(i, k);
                assert!((d.length() - 1.0).abs() < 1e-12);
                assert!(d.z < 0.0, "views look down");
            }
        }
        assert!((elevation(0).to_degrees() - 4.5).abs() < 1e-9);
        assert!((azimuth(47).to_degrees() - 356.25).abs() < 1e-9);
    }

    #[test]
    fn a_wall_in_front_hides_up_to_its_angle() {
        // A 10 m wall (full height) 5 texels east of the surfel on a 1 m grid.
        let zen = flat_map(32, 32.0, |i, _| if i == 10 { Q_MAX } else { 0 });
        let s = DVec3::new(5.0, 16.0, 0.0);
        let h = horizon_tan(&zen, [0.0, 10.0], s, DVec2::X, 10.0);
        // Its near face is about 5 m away (texel 10's west edge): tan = 10 / that (the walk
        // measures to the texel's near edge).
        let near = zen.frame.from_map(10.0, 0.0, 0.0).x - s.x;
        assert!((near - 5.0).abs() < 0.01, "{near}");
        assert!((h - 10.0 / near).abs() < 1e-9, "{h}");
        // Looking west there is nothing.
        let h = horizon_tan(&zen, [0.0, 10.0], s, -DVec2::X, 10.0);
        assert_eq!(h, f64::NEG_INFINITY);
    }

    #[test]
    fn the_vote_sees_an_open_wall_from_its_side_and_stops_at_the_target() {
        let zen = flat_map(32, 32.0, |_, _| 0);
        // Two walls: facing east and facing north, 10 m² each.
        let mk = |n: DVec2| Surfel {
            p: DVec3::new(16.0, 16.0, 1.0),
            n,
            area: 10.0,
        };
        let s = vec![mk(DVec2::X), mk(DVec2::Y)];
        let v = vote(&s, &zen, [0.0, 10.0], 0.95, 16);
        assert_eq!(v.seeable_m2, 20.0);
        // One direction sees both (north-east, lowest elevation: quality cos 4.5°).
        assert_eq!(v.chosen.len(), 1, "{v:?}");
        assert_eq!(v.chosen[0].elevation_bin, 0);
        let d = v.chosen[0].dir;
        assert!(
            d[0] < 0.0 && d[1] < 0.0,
            "looks south-west from the north-east: {d:?}"
        );
        assert_eq!(v.coverage, 1.0);
        // Walls facing four ways need at least two directions.
        let s4: Vec<Surfel> = [DVec2::X, DVec2::Y, -DVec2::X, -DVec2::Y]
            .into_iter()
            .map(mk)
            .collect();
        let v = vote(&s4, &zen, [0.0, 10.0], 0.95, 16);
        assert_eq!(v.chosen.len(), 2);
        assert_eq!(v.coverage, 1.0);
        // With one map allowed the target is not reached, and the vote says so.
        let v = vote(&s4, &zen, [0.0, 10.0], 0.95, 1);
        assert_eq!(v.chosen.len(), 1);
        assert!((v.coverage - 0.5).abs() < 1e-12);
    }
}
