//! The street grid and the parcels of a block.

use geo_types::{Coord, LineString};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::footprint::Corner;
use super::tuning::*;
use super::{GenStreet, GenerateParams};

/// A street across the grid: its centre line's coordinate (x for a north–south street, y for
/// an east–west one) and its width between block edges, metres.
pub(super) type StreetLine = (f64, f64);

/// The grid's columns: `k` blocks west to east from the origin, each after a street, and the
/// street after the last. Returns the blocks' `(x0, x1)` and the `k + 1` streets.
pub(super) fn columns(
    rng: &mut ChaCha8Rng,
    p: &GenerateParams,
    k: usize,
) -> (Vec<(f64, f64)>, Vec<StreetLine>) {
    let mut xs = Vec::with_capacity(k);
    let mut street_x = Vec::with_capacity(k + 1);
    let mut x = p.origin.0;
    for _ in 0..k {
        let sw = rng.random_range(p.street_m.0..p.street_m.1);
        street_x.push((x + sw / 2.0, sw));
        x += sw;
        let bw = rng.random_range(p.block_m.0..p.block_m.1);
        xs.push((x, x + bw));
        x += bw;
    }
    let sw = rng.random_range(p.street_m.0..p.street_m.1);
    street_x.push((x + sw / 2.0, sw));
    (xs, street_x)
}

/// A parcel: its box `[x0, y0, x1, y1]`, the side facing the street (0 south, 1 east, 2 north,
/// 3 west) and whether it holds a street corner.
#[derive(Clone, Copy, Debug)]
pub(super) struct Parcel {
    pub bounds: [f64; 4],
    pub front: u8,
    pub corner: Corner,
}

/// The parcels of the block `[x0, x1] × [y0, y0 + height]`, counter-clockwise from its
/// south-west corner: a perimeter block, with south and north rows over the full width and east
/// and west rows between them, all of one depth, leaving a yard inside.
pub(super) fn block_parcels(
    rng: &mut ChaCha8Rng,
    (bx0, bx1): (f64, f64),
    by0: f64,
    height: f64,
    frontage_m: (f64, f64),
) -> Vec<Parcel> {
    let by1 = by0 + height;
    let depth = rng
        .random_range(PARCEL_DEPTH_M.0..PARCEL_DEPTH_M.1)
        .min((bx1 - bx0) / PARCEL_DEPTH_DIVISOR)
        .min(height / PARCEL_DEPTH_DIVISOR);
    let mut parcels: Vec<([f64; 4], u8)> = Vec::new();
    for (a, b) in cuts(rng, bx0, bx1, frontage_m) {
        parcels.push(([a, by0, b, by0 + depth], 0));
    }
    for (a, b) in cuts(rng, by0 + depth, by1 - depth, frontage_m) {
        parcels.push(([bx1 - depth, a, bx1, b], 1));
    }
    for (a, b) in cuts(rng, bx0, bx1, frontage_m).into_iter().rev() {
        parcels.push(([a, by1 - depth, b, by1], 2));
    }
    for (a, b) in cuts(rng, by0 + depth, by1 - depth, frontage_m)
        .into_iter()
        .rev()
    {
        parcels.push(([bx0, a, bx0 + depth, b], 3));
    }
    // A parcel at either end of the south or north row has a street corner.
    let mut corners: Vec<Corner> = vec![None; parcels.len()];
    for side in [0u8, 2] {
        let row: Vec<usize> = (0..parcels.len())
            .filter(|&i| parcels[i].1 == side)
            .collect();
        if let (Some(&first), Some(&last)) = (row.first(), row.last()) {
            corners[first] = Some(false);
            if last != first {
                corners[last] = Some(true);
            }
        }
    }
    parcels
        .into_iter()
        .zip(corners)
        .map(|((bounds, front), corner)| Parcel {
            bounds,
            front,
            corner,
        })
        .collect()
}

/// The box a parcel's building may fill: the parcel less side gaps, a street setback and a
/// back yard (each drawn at random); `None` when it is too small for a building.
pub(super) fn buildable(rng: &mut ChaCha8Rng, parcel: &Parcel) -> Option<[f64; 4]> {
    let [x0, y0, x1, y1] = parcel.bounds;
    let g = rng.random_range(SIDE_GAP_M.0..SIDE_GAP_M.1);
    let setback = rng.random_range(STREET_SETBACK_M.0..STREET_SETBACK_M.1);
    let back = rng.random_range(BACK_YARD_M.0..BACK_YARD_M.1);
    let inner = match parcel.front {
        0 => [x0 + g, y0 + setback, x1 - g, y1 - back],
        1 => [x0 + back, y0 + g, x1 - setback, y1 - g],
        2 => [x0 + g, y0 + back, x1 - g, y1 - setback],
        _ => [x0 + setback, y0 + g, x1 - back, y1 - g],
    };
    if inner[2] - inner[0] < MIN_BUILDABLE_SIDE_M || inner[3] - inner[1] < MIN_BUILDABLE_SIDE_M {
        return None;
    }
    Some(inner)
}

/// Cuts `[a, b]` into pieces of length in `range` (the last piece absorbs the remainder).
fn cuts(rng: &mut ChaCha8Rng, a: f64, b: f64, range: (f64, f64)) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut x = a;
    while b - x > range.1 {
        let w = rng.random_range(range.0..range.1);
        if b - (x + w) < range.0 {
            break;
        }
        out.push((x, x + w));
        x += w;
    }
    if b - x > MIN_PARCEL_REMAINDER_M {
        out.push((x, b));
    }
    out
}

/// Street segments between consecutive intersections (a noded grid): north–south streets span
/// the rows generated, east–west ones the columns.
pub(super) fn street_segments(street_x: &[StreetLine], street_y: &[StreetLine]) -> Vec<GenStreet> {
    let line = |a: (f64, f64), b: (f64, f64)| {
        LineString::from(vec![Coord { x: a.0, y: a.1 }, Coord { x: b.0, y: b.1 }])
    };
    let mut streets = Vec::new();
    for &(sx, w) in street_x {
        for r in 0..street_y.len() - 1 {
            streets.push(GenStreet {
                line: line((sx, street_y[r].0), (sx, street_y[r + 1].0)),
                width_m: w,
            });
        }
    }
    for &(sy, w) in street_y {
        for c in 0..street_x.len() - 1 {
            streets.push(GenStreet {
                line: line((street_x[c].0, sy), (street_x[c + 1].0, sy)),
                width_m: w,
            });
        }
    }
    streets
}
