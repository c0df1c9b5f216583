//! One building's footprint inside its parcel: strips across the frontage with their own front
//! and back lines (facade jogs, bays, entrances, wings, stair towers, party walls), chamfered
//! corners and an optional courtyard.

use geo_types::{Coord, LineString, Polygon};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::tuning::*;
use crate::geom::repair::check_polygon;

/// A ring of `(u, depth)` points in the front-south frame, not closed.
pub(super) type Ring = Vec<(f64, f64)>;

/// Where a building stands in its parcel row: a corner parcel has a street corner at its
/// front-left (`Some(false)`) or front-right (`Some(true)`) in the front-south frame.
pub(super) type Corner = Option<bool>;

/// The closed ring of the axis-aligned rectangle `[x0, x1] × [y0, y1]`, counter-clockwise.
pub(super) fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Coord<f64>> {
    vec![
        Coord { x: x0, y: y0 },
        Coord { x: x1, y: y0 },
        Coord { x: x1, y: y1 },
        Coord { x: x0, y: y1 },
        Coord { x: x0, y: y0 },
    ]
}

/// A polygon from closed rings.
pub(super) fn poly(ext: Vec<Coord<f64>>, holes: Vec<Vec<Coord<f64>>>) -> Polygon<f64> {
    Polygon::new(
        LineString::from(ext),
        holes.into_iter().map(LineString::from).collect(),
    )
}

/// One vertical strip `[u0, u1]` of a footprint in the front-south frame, spanning `[f, g]` in
/// depth (front line `f`, back line `g`).
#[derive(Clone, Copy, Debug)]
struct Strip {
    u1: f64,
    f: f64,
    g: f64,
}

/// The ring of the region between a front chain and a back chain over strips (a u-monotone
/// orthogonal polygon), counter-clockwise, with no repeated or collinear vertices. `slant`
/// moves the four side-wall ends inwards (`[front-left, back-left, front-right, back-right]`),
/// so party walls need not be square to the street.
fn strips_ring(strips: &[Strip], w: f64, slant: [f64; 4]) -> Ring {
    let mut ring: Ring = Vec::with_capacity(strips.len() * 4 + 4);
    // Front chain, left to right.
    ring.push((slant[0], strips[0].f));
    for k in 0..strips.len() - 1 {
        let (a, b) = (strips[k], strips[k + 1]);
        if a.f != b.f {
            ring.push((a.u1, a.f));
            ring.push((a.u1, b.f));
        }
    }
    let last = strips[strips.len() - 1];
    ring.push((w - slant[2], last.f));
    // Back chain, right to left.
    ring.push((w - slant[3], last.g));
    for k in (0..strips.len() - 1).rev() {
        let (a, b) = (strips[k], strips[k + 1]);
        if a.g != b.g {
            ring.push((a.u1, b.g));
            ring.push((a.u1, a.g));
        }
    }
    ring.push((slant[1], strips[0].g));
    ring
}

/// Cuts convex corners of a counter-clockwise (`ccw`) or clockwise ring at 45°-ish, each with
/// probability `p`, by up to `max_cut` metres and at most [`CHAMFER_MAX_EDGE_FRACTION`] of either
/// adjacent edge. `force` lists vertex indices always cut (a street corner) when the edges
/// allow it.
fn chamfer(
    rng: &mut ChaCha8Rng,
    ring: &Ring,
    ccw: bool,
    p: f64,
    max_cut: f64,
    force: &[usize],
) -> Ring {
    let n = ring.len();
    let mut out = Vec::with_capacity(n + 4);
    for i in 0..n {
        let (a, b, c) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
        let cross = (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0);
        let convex = if ccw { cross > 0.0 } else { cross < 0.0 };
        let forced = force.contains(&i);
        let roll: f64 = rng.random();
        if convex && (forced || roll < p) {
            let l1 = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
            let l2 = ((c.0 - b.0).powi(2) + (c.1 - b.1).powi(2)).sqrt();
            let want = if forced {
                rng.random_range(STREET_CORNER_CUT_M.0..STREET_CORNER_CUT_M.1)
            } else {
                rng.random_range(CHAMFER_FRACTION.0..CHAMFER_FRACTION.1) * max_cut
            };
            let cut = want
                .min(CHAMFER_MAX_EDGE_FRACTION * l1)
                .min(CHAMFER_MAX_EDGE_FRACTION * l2);
            if cut >= MIN_CHAMFER_M {
                out.push((b.0 + (a.0 - b.0) * cut / l1, b.1 + (a.1 - b.1) * cut / l1));
                out.push((b.0 + (c.0 - b.0) * cut / l2, b.1 + (c.1 - b.1) * cut / l2));
                continue;
            }
        }
        out.push(b);
    }
    out
}

/// Places `n` features of width `wr` along `[a, b]` with at least `gap` metres between them
/// and from the ends; returns their intervals (fewer when they do not fit).
fn place(
    rng: &mut ChaCha8Rng,
    a: f64,
    b: f64,
    n: usize,
    wr: (f64, f64),
    gap: f64,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    if n == 0 || b - a < 2.0 * gap + wr.0 {
        return out;
    }
    let slot = (b - a - gap) / n as f64;
    for k in 0..n {
        let s0 = a + gap + k as f64 * slot;
        let room = slot - gap;
        if room < wr.0 {
            break;
        }
        let w = rng
            .random_range(wr.0..wr.1.max(wr.0 + RANGE_PAD_M))
            .min(room);
        let x = s0
            + rng
                .random_range(0.0..(room - w).max(RANGE_PAD_M))
                .min(room - w);
        out.push((x, x + w));
    }
    out
}

/// A building inside the axis-aligned box `[x0,x1]×[y0,y1]`; `front` is the side facing the
/// street (0 south, 1 east, 2 north, 3 west), where an L or U stays closed.
///
/// The footprint is built in a frame where the street is to the south, as strips across the
/// frontage, each with its own front and back line: the front carries the facade's jogs, bay
/// projections and recessed entrances, the back carries the wings (L, U, T, stepped) and
/// stair towers, the outer strips the irregular party walls. Convex corners are then chamfered
/// (always at a street corner, a *pan coupé*), and large buildings may enclose a courtyard.
/// Detail grows with size: a small house is a plain box, a large block has tens of vertices.
/// Every ring is checked ([`check_polygon`]); a decoration that would make it invalid is
/// dropped, so every footprint is valid without repair.
pub(super) fn building_shape(
    rng: &mut ChaCha8Rng,
    b: [f64; 4],
    front: u8,
    corner: Corner,
) -> Polygon<f64> {
    let [x0, y0, x1, y1] = b;
    let (w, h) = (x1 - x0, y1 - y0);
    let (fw, fd) = if front & 1 == 0 { (w, h) } else { (h, w) };
    // Detail level 0..1 from the footprint's size.
    let size = ((fw * fd).sqrt() - DETAIL_SIZE_ZERO_M) / DETAIL_SIZE_SPAN_M;
    let detail = size.clamp(0.0, 1.0) * rng.random_range(DETAIL_JITTER.0..DETAIL_JITTER.1);
    let local = detailed_local(rng, fw, fd, detail, corner);
    // Rotations that keep counter-clockwise order: front south → front `front`.
    let map = |(u, v): (f64, f64)| -> Coord<f64> {
        match front {
            0 => Coord {
                x: x0 + u,
                y: y0 + v,
            },
            1 => Coord {
                x: x1 - v,
                y: y0 + u,
            },
            2 => Coord {
                x: x1 - u,
                y: y1 - v,
            },
            _ => Coord {
                x: x0 + v,
                y: y1 - u,
            },
        }
    };
    let close = |v: &Ring| -> Vec<Coord<f64>> {
        let mut r: Vec<Coord<f64>> = v.iter().copied().map(map).collect();
        r.push(r[0]);
        r
    };
    for (ext, hole) in &local {
        let p = poly(close(ext), hole.iter().map(close).collect());
        if check_polygon(&p).is_ok() {
            return p;
        }
    }
    poly(
        close(&vec![(0.0, 0.0), (fw, 0.0), (fw, fd), (0.0, fd)]),
        vec![],
    )
}

/// A run `[from, to)` along the frontage with a depth (a front line, a back line, or a change
/// of the back line); later runs override earlier ones.
type Run = (f64, f64, f64);

/// The back line over the frontage: a courtyard building's full depth, a box, or a main body
/// with wings (L, U, T or a stepped back line).
fn back_line(
    rng: &mut ChaCha8Rng,
    fw: f64,
    fd: f64,
    detail: f64,
    r: f64,
    body: f64,
    court: bool,
) -> Vec<Run> {
    let mut back: Vec<Run> = Vec::new();
    let wing = |rng: &mut ChaCha8Rng| rng.random_range(WING_FRACTION.0..WING_FRACTION.1) * fw;
    if court {
        back.push((0.0, fw, fd));
    } else if fd - body < MIN_WING_ROOM_M
        || fw < MIN_WINGED_FRONTAGE_M
        || r < BOX_P - BOX_P_PER_DETAIL * detail
    {
        // Simple depth: a box (with what the facade adds).
        back.push((
            0.0,
            fw,
            if fd - body < MIN_WING_ROOM_M {
                fd
            } else {
                rng.random_range(body..fd)
            },
        ));
    } else {
        back.push((0.0, fw, body));
        let s: f64 = rng.random();
        if s < WING_LAYOUT_P[0] {
            // L.
            let ww = wing(rng).max(MIN_WING_WIDTH_M);
            if rng.random::<bool>() {
                back.push((0.0, ww, fd));
            } else {
                back.push((fw - ww, fw, fd));
            }
        } else if s < WING_LAYOUT_P[1] && fw >= U_MIN_FRONTAGE_M {
            // U.
            let (a, c) = (
                wing(rng).min(U_MAX_WING_FRACTION * fw),
                wing(rng).min(U_MAX_WING_FRACTION * fw),
            );
            back.push((0.0, a, fd));
            back.push((
                fw - c,
                fw,
                rng.random_range(body + U_SECOND_WING_MIN_M..fd + RANGE_PAD_M)
                    .min(fd),
            ));
        } else if s < WING_LAYOUT_P[2] {
            // T: a rear wing in the middle.
            let ww = wing(rng)
                .max(MIN_WING_WIDTH_M)
                .min(fw - 2.0 * T_WING_MARGIN_M);
            let x = rng.random_range(
                T_WING_MARGIN_M..(fw - ww - T_WING_MARGIN_M).max(T_WING_MARGIN_M + RANGE_PAD_M),
            );
            back.push((x, x + ww, fd));
        } else {
            // Stepped back line.
            let n = rng.random_range(BACK_STEPS.0..BACK_STEPS.1);
            for k in 0..n {
                let a = fw * k as f64 / n as f64;
                back.push((
                    a,
                    fw * (k + 1) as f64 / n as f64,
                    rng.random_range(body..fd),
                ));
            }
        }
    }
    back
}

/// The front line: a base line set back by the bays' projection, facade jogs, the bays, and a
/// recessed entrance. Returns the runs and the base setback.
fn front_line(rng: &mut ChaCha8Rng, fw: f64, detail: f64) -> (Vec<Run>, f64) {
    let n_bays =
        (detail * fw / rng.random_range(BAY_SPACING_M.0..BAY_SPACING_M.1)).floor() as usize;
    let bay = if n_bays > 0 {
        rng.random_range(BAY_PROJECTION_M.0..BAY_PROJECTION_M.1)
    } else {
        0.0
    };
    let mut front: Vec<Run> = vec![(0.0, fw, bay)];
    // Facade jogs: the frontage read as a few houses with slightly different building lines.
    if detail > JOG_MIN_DETAIL && rng.random::<f64>() < JOG_P {
        let n = rng.random_range(JOG_HOUSES.0..JOG_HOUSES.1);
        for k in 1..n {
            let a = fw * k as f64 / n as f64 + rng.random_range(JOG_SHIFT_M.0..JOG_SHIFT_M.1);
            front.push((
                a,
                fw,
                bay + rng.random_range(JOG_STEP_M.0..JOG_STEP_M.1) * (k % 2) as f64
                    + JOG_STAGGER_M * k as f64,
            ));
        }
    }
    for (a, c) in place(rng, 0.0, fw, n_bays, BAY_WIDTH_M, BAY_GAP_M) {
        front.push((a, c, 0.0));
    }
    if detail > ENTRANCE_MIN_DETAIL && rng.random::<f64>() < ENTRANCE_P {
        for (a, c) in place(rng, 0.0, fw, 1, ENTRANCE_WIDTH_M, ENTRANCE_GAP_M) {
            front.push((
                a,
                c,
                bay + rng.random_range(ENTRANCE_RECESS_M.0..ENTRANCE_RECESS_M.1),
            ));
        }
    }
    (front, bay)
}

/// Candidate footprints in the front-south frame `[0, fw] × [0, fd]`, most detailed first.
fn detailed_local(
    rng: &mut ChaCha8Rng,
    fw: f64,
    fd: f64,
    detail: f64,
    corner: Corner,
) -> Vec<(Ring, Option<Ring>)> {
    let plain = vec![(0.0, 0.0), (fw, 0.0), (fw, fd), (0.0, fd)];
    if fw < MIN_DETAILED_SIDE_M || fd < MIN_DETAILED_SIDE_M {
        return vec![(plain, None)];
    }
    let r: f64 = rng.random();
    // Main body depth from the street; wings reach the back of the parcel.
    let body = rng.random_range(BODY_DEPTH_M.0..BODY_DEPTH_M.1).min(fd);
    let court =
        r < COURT_P + COURT_P_PER_DETAIL * detail && fw >= COURT_MIN_BOX_M && fd >= COURT_MIN_BOX_M;
    let back = back_line(rng, fw, fd, detail, r, body, court);
    // Stair towers and light wells on the back.
    let towers = (detail * BACK_FEATURES_AT_FULL_DETAIL * rng.random::<f64>()).round() as usize;
    let mut back_bumps: Vec<Run> = Vec::new();
    for (a, c) in place(
        rng,
        0.0,
        fw,
        towers,
        BACK_FEATURE_WIDTH_M,
        BACK_FEATURE_GAP_M,
    ) {
        back_bumps.push((
            a,
            c,
            rng.random_range(BACK_FEATURE_DEPTH_M.0..BACK_FEATURE_DEPTH_M.1),
        ));
    }
    let (front, bay) = front_line(rng, fw, detail);
    // Irregular party walls: a narrow end strip with its own back line.
    let mut ends: Vec<Run> = Vec::new();
    if detail > PARTY_WALL_MIN_DETAIL && rng.random::<f64>() < PARTY_WALL_P {
        let wdt = rng.random_range(PARTY_WALL_STRIP_M.0..PARTY_WALL_STRIP_M.1);
        let left = rng.random::<bool>();
        let (a, c) = if left { (0.0, wdt) } else { (fw - wdt, fw) };
        ends.push((
            a,
            c,
            rng.random_range(PARTY_WALL_DEPTH_M.0..PARTY_WALL_DEPTH_M.1),
        ));
    }
    let strips = strips(fw, fd, bay, &back, &back_bumps, &front, &ends);
    let slant = if detail > SLANT_MIN_DETAIL && rng.random::<f64>() < SLANT_P {
        let n = strips.len();
        let last_w = fw - if n >= 2 { strips[n - 2].u1 } else { 0.0 };
        let m = (SLANT_MAX_FRACTION * strips[0].u1)
            .min(SLANT_MAX_FRACTION * last_w)
            .min(SLANT_MAX_M);
        [
            0.0,
            rng.random_range(0.0..m + RANGE_PAD_M),
            0.0,
            rng.random_range(0.0..m + RANGE_PAD_M),
        ]
    } else {
        [0.0; 4]
    };
    let ext = strips_ring(&strips, fw, slant);
    // Street corner: the first (front-left) or the last front vertex.
    let front_n = ext
        .iter()
        .position(|p| p.0 >= fw - slant[2] - CORNER_FIND_TOL_M && p.1 == strips[strips.len() - 1].f)
        .unwrap_or(0);
    let force: Vec<usize> = match corner {
        Some(false) => vec![0],
        Some(true) => vec![front_n],
        None => vec![],
    };
    let ch = chamfer(
        rng,
        &ext,
        true,
        CHAMFER_P_AT_FULL_DETAIL * detail,
        CHAMFER_MAX_M,
        &force,
    );
    let hole = if court {
        courtyard(rng, &strips, fw, fd, detail)
    } else {
        None
    };
    vec![
        (ch, hole.clone()),
        (ext.clone(), hole),
        (ext, None),
        (plain, None),
    ]
}

/// Cuts the frontage at every breakpoint of every run and gives each strip its front line (the
/// last front run over it, else `bay`) and back line (the last back run, moved by the back
/// features and party walls over it), clamped so every strip stays deep enough.
fn strips(
    fw: f64,
    fd: f64,
    bay: f64,
    back: &[Run],
    back_bumps: &[Run],
    front: &[Run],
    ends: &[Run],
) -> Vec<Strip> {
    let mut cutsu: Vec<f64> = vec![0.0, fw];
    for &(a, c, _) in back.iter().chain(back_bumps).chain(front).chain(ends) {
        cutsu.push(a.clamp(0.0, fw));
        cutsu.push(c.clamp(0.0, fw));
    }
    cutsu.sort_by(f64::total_cmp);
    cutsu.dedup_by(|a, b| (*a - *b).abs() < STRIP_MERGE_M);
    let mut strips: Vec<Strip> = Vec::new();
    let mut u0 = 0.0;
    for &u1 in &cutsu[1..] {
        let m = 0.5 * (u0 + u1);
        let cover = |l: &[Run]| l.iter().rev().find(|p| p.0 <= m && m < p.1).map(|p| p.2);
        let f = cover(front)
            .unwrap_or(bay)
            .clamp(0.0, fd - FRONT_LINE_MIN_DEPTH_M);
        let mut g = cover(back).unwrap_or(fd);
        if let Some(d) = cover(back_bumps) {
            g = if d < 0.0 || g + d <= fd { g + d } else { g };
        }
        if let Some(d) = cover(ends) {
            g += d;
        }
        let g = g.clamp(f + MIN_STRIP_DEPTH_M, fd);
        strips.push(Strip { u1, f, g });
        u0 = u1;
    }
    strips
}

/// The courtyard of a courtyard building: a clockwise ring inside the strips, its corners
/// chamfered at random; `None` when the box leaves no room for it.
fn courtyard(
    rng: &mut ChaCha8Rng,
    strips: &[Strip],
    fw: f64,
    fd: f64,
    detail: f64,
) -> Option<Ring> {
    let t = rng
        .random_range(COURT_RING_DEPTH_M.0..COURT_RING_DEPTH_M.1)
        .min(fw / COURT_RING_DIVISOR)
        .min(fd / COURT_RING_DIVISOR);
    let fmax = strips.iter().map(|s| s.f).fold(0.0, f64::max);
    let gmin = strips.iter().map(|s| s.g).fold(fd, f64::min);
    let (a, c, lo, hi) = (
        t + COURT_SIDE_EXTRA_M,
        fw - t - COURT_SIDE_EXTRA_M,
        fmax + t,
        gmin - t,
    );
    if c - a >= MIN_COURT_SIDE_M && hi - lo >= MIN_COURT_SIDE_M {
        let h = vec![(a, lo), (a, hi), (c, hi), (c, lo)];
        Some(chamfer(
            rng,
            &h,
            false,
            COURT_CHAMFER_P_AT_FULL_DETAIL * detail,
            COURT_CHAMFER_MAX_M,
            &[],
        ))
    } else {
        None
    }
}
