//! Validation and repair of footprint rings and polygons.
//!
//! Cadastral and OSM footprints come with small defects: unclosed rings, repeated points,
//! zero-width spikes, the wrong winding, holes outside their shell, rings cut by an extract's
//! bounding box that cross themselves. [`repair_polygon`] turns one input polygon into zero or
//! more valid polygons and says what it did ([`RepairAction`]) or why it could not
//! ([`Refusal`]); it never changes geometry silently and never panics.
//!
//! A polygon is *valid* here when every ring has at least three distinct points, is simple (no
//! two edges meet except consecutive edges at their shared vertex), has non-zero area, the
//! exterior is counter-clockwise and every hole clockwise, the rings do not touch or cross each
//! other, and every hole lies inside the exterior and outside every other hole. This is
//! stricter than the OGC rules, which let a hole touch the exterior or another hole at a single
//! point, because the extruded prism of such a footprint would not be a 2-manifold (four walls
//! would meet along the vertical edge above the point).
//!
//! # Rings touching at a point
//!
//! Footprints whose rings touch at isolated points are still accepted: a courtyard hole that
//! touches the exterior at one point, two holes that touch at a corner (both OGC-valid), and an
//! exterior that touches itself at one point around a courtyard, the "inverted courtyard"
//! (not OGC-valid, since OGC rings must be simple, but the form some GIS software writes for
//! the same shape). Each touch is separated ([`RepairAction::SeparatedTouch`]). Of the visits of
//! the point (a vertex there, or an edge passing through it) the one of the lowest ring stays
//! as it is (the exterior before the holes; in a self-touching ring, its first visit), and every
//! other visit is replaced by a notch (an edge first gets the point as a vertex): two points on
//! its edges and one on the bisector of its angle, each [`TOUCH_SEPARATION_M`] (1 mm) from the
//! point, cut into the region that ring bounds (the void of a hole, the inside of the exterior). The rings then no
//! longer meet, the polygon is valid and its prism is a closed 2-manifold; the area changes by
//! the notch's quadrilateral, at most δ² (1 mm²) per touch. The separation is only kept when all
//! rings come out simple and apart; rings that cross, share an edge, or two lobes that meet at a
//! point without one enclosing the other (a bow-tie, whose notch would cross the other lobe) go
//! to the overlay below, as if nothing had been tried.
//!
//! Self-intersections and crossing rings are resolved with a polygon overlay (geo's
//! `BooleanOps`, i.e. the `i_overlay` crate): the exterior is unioned with itself under the
//! non-zero fill rule (a figure-eight becomes its two lobes, a ring that loops over itself is
//! filled), each hole is treated the same way, and the holes are subtracted. The overlay may
//! snap coordinates to its integer grid (sub-micrometre at building scale). Every resulting part
//! is validated again; a part that is still invalid refuses the polygon.
//!
//! # Cost
//!
//! Every step is O(n log n) in the number of vertices for footprints whose edges are short
//! relative to the footprint (any real or generated one). Spikes are removed with a min-heap over
//! a linked ring instead of rescanning the ring after each removal. Simplicity, contacts between
//! rings and hole containment look edges up in an R-tree ([`rstar`]) of their bounding boxes: an
//! edge is tested exactly only against the edges whose boxes meet its own, and a point only
//! against the edges whose boxes meet the ray of its crossing test. The exact tests themselves
//! are unchanged, so the answers are those of the plain pairwise loops, which are kept as the
//! tests' brute-force references and used below [`INDEX_MIN_EDGES`] edges (where they are
//! faster). The indexed search costs O(n log n + k), with k the number of pairs of overlapping
//! edge boxes: k is O(n) for rings of short edges, but a pathological ring of long, mutually
//! overlapping edges (a spiral turned 45°) can still make it grow as n².

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fmt;

use geo::algorithm::bool_ops::{BooleanOps, FillRule, OpType};
use geo_types::{Coord, LineString, MultiPolygon, Polygon};
use rstar::{RTree, RTreeObject, AABB};

use super::predicates::{
    on_segment, open_ring, orient2d, point_in_ring, ring_signed_area, segments_intersect, Location,
    Orientation, SegmentIntersection,
};
use super::tolerance::TOUCH_SEPARATION_M;

/// One thing [`repair_polygon`] did. `ring` is 0 for the exterior and `k` for the k-th hole.
#[derive(Clone, Debug, PartialEq)]
pub enum RepairAction {
    /// The ring's last point did not repeat its first; it was closed.
    ClosedRing {
        /// Ring index.
        ring: usize,
    },
    /// Consecutive repeated points were dropped.
    DroppedRepeatedPoints {
        /// Ring index.
        ring: usize,
        /// How many points.
        count: usize,
    },
    /// Zero-width spikes (a vertex where the boundary goes back along itself) were removed.
    RemovedSpikes {
        /// Ring index.
        ring: usize,
        /// How many vertices.
        count: usize,
    },
    /// The ring was reversed (exterior to counter-clockwise, hole to clockwise). A normalisation,
    /// not a repair: Shapefiles store exteriors clockwise by convention.
    Rewound {
        /// Ring index.
        ring: usize,
    },
    /// A hole was dropped.
    DroppedHole {
        /// Ring index.
        ring: usize,
        /// Why.
        why: String,
    },
    /// Two rings that touched at one point, or a ring that touched itself there (`rings.0 ==
    /// rings.1`), were separated: the vertex of ring `rings.1` at `at` was replaced by a notch
    /// `moved_m` deep cut into the region that ring bounds (see the module doc).
    SeparatedTouch {
        /// The ring left as it was, and the ring that was notched (equal for a self-touch).
        rings: (usize, usize),
        /// Where they touched.
        at: [f64; 2],
        /// How far the vertex moved, in metres.
        moved_m: f64,
    },
    /// Self-intersecting or crossing rings were resolved by a polygon overlay into `parts`
    /// polygons.
    Overlay {
        /// What was wrong.
        why: String,
        /// Number of polygons produced.
        parts: usize,
    },
}

impl RepairAction {
    /// True for actions that only normalise the representation (winding), which do not count
    /// as a repair in reports.
    pub fn is_normalization(&self) -> bool {
        matches!(self, RepairAction::Rewound { .. })
    }
}

impl fmt::Display for RepairAction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RepairAction::ClosedRing { ring } => write!(f, "closed ring {ring}"),
            RepairAction::DroppedRepeatedPoints { ring, count } => {
                write!(f, "dropped {count} repeated point(s) in ring {ring}")
            }
            RepairAction::RemovedSpikes { ring, count } => {
                write!(f, "removed {count} spike vertex(es) in ring {ring}")
            }
            RepairAction::Rewound { ring } => write!(f, "rewound ring {ring}"),
            RepairAction::DroppedHole { ring, why } => write!(f, "dropped hole {ring}: {why}"),
            RepairAction::SeparatedTouch { rings, at, moved_m } => {
                let mm = (moved_m * 1e6).round() / 1e3;
                let into = if rings.1 == 0 {
                    "the footprint"
                } else {
                    "the hole"
                };
                let (x, y) = (at[0], at[1]);
                if rings.0 == rings.1 {
                    write!(
                        f,
                        "ring {} touched itself at ({x:.3}, {y:.3}): separated by moving one of \
                         its two vertices there {mm} mm into {into}",
                        rings.0
                    )
                } else {
                    write!(
                        f,
                        "ring {} touched ring {} at ({x:.3}, {y:.3}): separated by moving ring \
                         {}'s vertex there {mm} mm into {into}",
                        rings.1, rings.0, rings.1
                    )
                }
            }
            RepairAction::Overlay { why, parts } => {
                write!(f, "{why}: resolved by overlay into {parts} polygon(s)")
            }
        }
    }
}

/// Why a polygon could not be repaired.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// A coordinate is NaN or infinite.
    #[error("ring {ring}, point {index}: coordinate is not finite")]
    NonFinite {
        /// Ring index.
        ring: usize,
        /// Point index.
        index: usize,
    },
    /// A coordinate's magnitude is outside [`COORD_RANGE`] (and not zero).
    #[error(
        "ring {ring}, point {index}: coordinate {value:e} is outside the range the exact \
         predicates handle (0, or 1e-100 to 1e100 in magnitude)"
    )]
    OutOfRange {
        /// Ring index.
        ring: usize,
        /// Point index.
        index: usize,
        /// The coordinate.
        value: f64,
    },
    /// The exterior has fewer than three distinct points (after dropping repeats and spikes).
    #[error("exterior has {n} distinct point(s) after cleaning, need 3")]
    TooFewPoints {
        /// Distinct points left.
        n: usize,
    },
    /// The exterior encloses no area.
    #[error("exterior has zero area")]
    ZeroArea,
    /// The overlay produced nothing, or parts that are still invalid.
    #[error("could not repair: {why}")]
    Unrepairable {
        /// What remained wrong.
        why: String,
    },
}

/// The magnitudes a non-zero coordinate may have: between them no product of two coordinate
/// differences, nor the error terms of the exact predicates, overflows or falls into the
/// subnormals, so orientation and crossing tests stay exact. Footprints are far inside.
pub const COORD_RANGE: (f64, f64) = (1e-100, 1e100);

/// Whether `v` is zero or of a magnitude inside [`COORD_RANGE`].
fn in_coord_range(v: f64) -> bool {
    v == 0.0 || (COORD_RANGE.0..=COORD_RANGE.1).contains(&v.abs())
}

/// A repaired polygon: valid parts (see the module doc) and what was done.
#[derive(Clone, Debug, PartialEq)]
pub struct Repaired {
    /// Valid polygons: exterior CCW, holes CW, rings closed. Usually one.
    pub polygons: Vec<Polygon<f64>>,
    /// What was done, in order. Empty when the input was already valid.
    pub actions: Vec<RepairAction>,
}

impl Repaired {
    /// True when something other than a normalisation was done.
    pub fn was_repaired(&self) -> bool {
        self.actions.iter().any(|a| !a.is_normalization())
    }
}

/// Validates and repairs a polygon. See the module documentation for what is done.
///
/// # Errors
/// [`Refusal`] when the polygon has non-finite coordinates, a degenerate exterior, or defects
/// the overlay cannot resolve.
pub fn repair_polygon(poly: &Polygon<f64>) -> Result<Repaired, Refusal> {
    let holes: Vec<&[Coord<f64>]> = poly.interiors().iter().map(|h| &h.0[..]).collect();
    repair_rings(&poly.exterior().0, &holes)
}

/// Validates and repairs a polygon given as raw rings, which may be open or closed.
///
/// # Errors
/// As [`repair_polygon`].
pub fn repair_rings(exterior: &[Coord<f64>], holes: &[&[Coord<f64>]]) -> Result<Repaired, Refusal> {
    let r = repair_rings_unchecked(exterior, holes)?;
    // A ring whose area rounds to zero in f64 (coordinates near the bottom of its range) is
    // refused as [`check_polygon`] would call it invalid: its winding and its area mean nothing.
    let zero = |l: &LineString<f64>| ring_signed_area(open_ring(&l.0)) == 0.0;
    if r.polygons
        .iter()
        .any(|p| zero(p.exterior()) || p.interiors().iter().any(zero))
    {
        return Err(Refusal::ZeroArea);
    }
    Ok(r)
}

fn repair_rings_unchecked(
    exterior: &[Coord<f64>],
    holes: &[&[Coord<f64>]],
) -> Result<Repaired, Refusal> {
    for (ring, pts) in std::iter::once(exterior)
        .chain(holes.iter().copied())
        .enumerate()
    {
        if let Some(index) = pts
            .iter()
            .position(|c| !c.x.is_finite() || !c.y.is_finite())
        {
            return Err(Refusal::NonFinite { ring, index });
        }
        let far = pts.iter().enumerate().find_map(|(i, c)| {
            [c.x, c.y]
                .into_iter()
                .find(|&v| !in_coord_range(v))
                .map(|v| (i, v))
        });
        if let Some((index, value)) = far {
            return Err(Refusal::OutOfRange { ring, index, value });
        }
    }
    let mut actions = Vec::new();
    let ext = match clean_ring(exterior, 0, true, &mut actions) {
        Ok(r) => r,
        Err(RingProblem::TooFew(n)) => return Err(Refusal::TooFewPoints { n }),
        Err(RingProblem::ZeroArea) => return Err(Refusal::ZeroArea),
    };
    let mut hs: Vec<(usize, Vec<Coord<f64>>)> = Vec::new();
    for (k, h) in holes.iter().enumerate() {
        match clean_ring(h, k + 1, true, &mut actions) {
            Ok(r) => hs.push((k + 1, r)),
            Err(p) => actions.push(RepairAction::DroppedHole {
                ring: k + 1,
                why: p.to_string(),
            }),
        }
    }
    let mut problems = Vec::new();
    if !ring_is_simple(&ext) {
        problems.push("exterior crosses itself".to_string());
    }
    for (k, h) in &hs {
        if !ring_is_simple(h) {
            problems.push(format!("hole {k} crosses itself"));
        }
    }
    if problems.is_empty() {
        let all: Vec<&[Coord<f64>]> = std::iter::once(&ext[..])
            .chain(hs.iter().map(|(_, h)| &h[..]))
            .collect();
        if let Some((i, j)) = first_interacting_rings(&all) {
            problems.push(format!("ring {i} touches or crosses ring {j}"));
        }
    }
    let mut ext = ext;
    if !problems.is_empty() {
        match separate_touches(&ext, &hs) {
            Some((e, h, separated)) => {
                ext = e;
                hs = h;
                actions.extend(separated);
            }
            None => return overlay_repair(ext, hs, problems.join("; "), actions),
        }
    }
    // Simple, non-touching rings: orient, then check that holes lie inside the exterior and
    // outside each other.
    if !simple_ring_is_ccw(&ext) {
        ext.reverse();
        actions.push(RepairAction::Rewound { ring: 0 });
    }
    // Where each hole's first point lies against the exterior (ring 0) and the other holes.
    let locs = {
        let rings: Vec<&[Coord<f64>]> = std::iter::once(&ext[..])
            .chain(hs.iter().map(|(_, h)| &h[..]))
            .collect();
        let firsts: Vec<Coord<f64>> = hs.iter().map(|(_, h)| h[0]).collect();
        ring_locations(&rings, &firsts)
    };
    // `kept` holds (ring index, hole, position in `hs`).
    let mut kept: Vec<(usize, Vec<Coord<f64>>, usize)> = Vec::new();
    for (pos, (k, mut h)) in hs.into_iter().enumerate() {
        if location_in(&locs[pos], 0) != Location::Inside {
            actions.push(RepairAction::DroppedHole {
                ring: k,
                why: "outside the exterior".into(),
            });
            continue;
        }
        if simple_ring_is_ccw(&h) {
            h.reverse();
            actions.push(RepairAction::Rewound { ring: k });
        }
        kept.push((k, h, pos));
    }
    // A hole inside another hole lies in the void: drop it. Hole i is nested when its first
    // point is inside a kept hole j that is not itself nested (j > i is not decided yet, so it
    // counts).
    let mut kept_at: Vec<Option<usize>> = vec![None; locs.len()];
    for (i, (_, _, pos)) in kept.iter().enumerate() {
        kept_at[*pos] = Some(i);
    }
    let mut nested = vec![false; kept.len()];
    for i in 0..kept.len() {
        nested[i] = locs[kept[i].2].iter().any(|&(ring, l)| {
            // Ring 0 is the exterior; ring r ≥ 1 is `hs[r - 1]`.
            l == Location::Inside
                && ring > 0
                && kept_at[ring - 1].is_some_and(|j| j != i && (j > i || !nested[j]))
        });
    }
    let mut interiors = Vec::new();
    for ((k, h, _), n) in kept.into_iter().zip(nested) {
        if n {
            actions.push(RepairAction::DroppedHole {
                ring: k,
                why: "inside another hole".into(),
            });
        } else {
            interiors.push(LineString::from(h));
        }
    }
    Ok(Repaired {
        polygons: vec![Polygon::new(LineString::from(ext), interiors)],
        actions,
    })
}

/// Checks a polygon against the validity rules of this module (see the module doc).
///
/// # Errors
/// A description of the first rule broken.
pub fn check_polygon(poly: &Polygon<f64>) -> Result<(), String> {
    let mut rings: Vec<&[Coord<f64>]> = vec![&poly.exterior().0];
    rings.extend(poly.interiors().iter().map(|h| &h.0[..]));
    for (k, r) in rings.iter().enumerate() {
        if r.len() < 4 || r[0] != r[r.len() - 1] {
            return Err(format!("ring {k} is not closed or has fewer than 3 points"));
        }
        let open = &r[..r.len() - 1];
        if open.iter().any(|c| !c.x.is_finite() || !c.y.is_finite()) {
            return Err(format!("ring {k} has a non-finite coordinate"));
        }
        if open
            .iter()
            .any(|c| !in_coord_range(c.x) || !in_coord_range(c.y))
        {
            return Err(format!("ring {k} has a coordinate outside COORD_RANGE"));
        }
        if !ring_is_simple(open) {
            return Err(format!("ring {k} is not simple"));
        }
        if ring_signed_area(open) == 0.0 {
            return Err(format!("ring {k} has zero area"));
        }
        let ccw = simple_ring_is_ccw(open);
        if k == 0 && !ccw {
            return Err("exterior is not counter-clockwise".into());
        }
        if k > 0 && ccw {
            return Err(format!("hole {k} is not clockwise"));
        }
    }
    let open: Vec<&[Coord<f64>]> = rings.iter().map(|r| &r[..r.len() - 1]).collect();
    if let Some((i, j)) = first_interacting_rings(&open) {
        return Err(format!("ring {i} touches or crosses ring {j}"));
    }
    let firsts: Vec<Coord<f64>> = open[1..].iter().map(|h| h[0]).collect();
    let locs = ring_locations(&open, &firsts);
    for k in 1..open.len() {
        let l = &locs[k - 1];
        if location_in(l, 0) != Location::Inside {
            return Err(format!("hole {k} is outside the exterior"));
        }
        // Ascending ring order: the first hole that holds it.
        if let Some(&(j, _)) = l
            .iter()
            .find(|&&(j, loc)| j >= 1 && j != k && loc == Location::Inside)
        {
            return Err(format!("hole {k} is inside hole {j}"));
        }
    }
    Ok(())
}

#[derive(Debug)]
enum RingProblem {
    TooFew(usize),
    ZeroArea,
}

impl fmt::Display for RingProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RingProblem::TooFew(n) => write!(f, "{n} distinct point(s) after cleaning, need 3"),
            RingProblem::ZeroArea => write!(f, "zero area"),
        }
    }
}

/// Opens, de-duplicates and de-spikes a ring (no closing point in the result).
fn clean_ring(
    ring: &[Coord<f64>],
    idx: usize,
    report_closing: bool,
    actions: &mut Vec<RepairAction>,
) -> Result<Vec<Coord<f64>>, RingProblem> {
    let mut pts: Vec<Coord<f64>> = ring.to_vec();
    if pts.len() >= 2 && pts[0] == pts[pts.len() - 1] {
        pts.pop();
    } else if pts.len() >= 3 && report_closing {
        actions.push(RepairAction::ClosedRing { ring: idx });
    }
    let dropped = dedupe_cyclic(&mut pts);
    let (pts, spikes, more_dupes) = remove_spikes(pts);
    if dropped + more_dupes > 0 {
        actions.push(RepairAction::DroppedRepeatedPoints {
            ring: idx,
            count: dropped + more_dupes,
        });
    }
    if spikes > 0 {
        actions.push(RepairAction::RemovedSpikes {
            ring: idx,
            count: spikes,
        });
    }
    if pts.len() < 3 {
        return Err(RingProblem::TooFew(pts.len()));
    }
    // The area first: it is O(n) and almost never zero, so the simplicity test is rarely run.
    if ring_signed_area(&pts) == 0.0 && ring_is_simple(&pts) {
        return Err(RingProblem::ZeroArea);
    }
    Ok(pts)
}

/// Removes zero-width spikes from a ring that has no consecutive repeated points; returns the
/// ring, the number of spikes removed and the number of repeated points dropped on the way.
///
/// The rule: while the ring has at least three points, remove the spike tip ([`is_spike`]) of
/// lowest index, then, if its two neighbours are now equal, drop the one of higher index (the
/// later one, or the last one across the ring's start), as [`dedupe_cyclic`] would. Removing a
/// vertex changes the spike test of its neighbours only, so instead of rescanning the ring after
/// each removal (O(n) per spike, O(n²) in all) the ring is a doubly linked list and every vertex
/// whose neighbours changed goes back into a min-heap of candidates: the smallest candidate that
/// is a spike is the lowest-index spike, because every vertex outside the heap has been tested
/// against its present neighbours. O(n log n).
fn remove_spikes(pts: Vec<Coord<f64>>) -> (Vec<Coord<f64>>, usize, usize) {
    let n = pts.len();
    if n < 3 {
        return (pts, 0, 0);
    }
    let mut ring = LinkedRing {
        next: (0..n).map(|i| (i + 1) % n).collect(),
        prev: (0..n).map(|i| (i + n - 1) % n).collect(),
        alive: vec![true; n],
        len: n,
    };
    let mut heap: BinaryHeap<Reverse<usize>> = (0..n).map(Reverse).collect();
    let (mut spikes, mut dupes) = (0usize, 0usize);
    while ring.len >= 3 {
        let Some(Reverse(i)) = heap.pop() else { break };
        if !ring.alive[i] || !is_spike(pts[ring.prev[i]], pts[i], pts[ring.next[i]]) {
            continue;
        }
        let (a, c) = ring.unlink(i);
        spikes += 1;
        heap.extend([Reverse(a), Reverse(c)]);
        if pts[a] == pts[c] {
            let (p, q) = ring.unlink(a.max(c));
            dupes += 1;
            heap.extend([Reverse(p), Reverse(q)]);
        }
    }
    let kept = pts
        .into_iter()
        .zip(&ring.alive)
        .filter_map(|(p, &a)| a.then_some(p))
        .collect();
    (kept, spikes, dupes)
}

/// A ring as a doubly linked list over the indices of its points.
struct LinkedRing {
    next: Vec<usize>,
    prev: Vec<usize>,
    alive: Vec<bool>,
    len: usize,
}

impl LinkedRing {
    /// Removes `i`; returns its former neighbours, now linked to each other.
    fn unlink(&mut self, i: usize) -> (usize, usize) {
        let (a, c) = (self.prev[i], self.next[i]);
        self.next[a] = c;
        self.prev[c] = a;
        self.alive[i] = false;
        self.len -= 1;
        (a, c)
    }
}

/// Drops consecutive repeated points, cyclically. Returns how many were dropped.
fn dedupe_cyclic(pts: &mut Vec<Coord<f64>>) -> usize {
    let before = pts.len();
    pts.dedup();
    while pts.len() >= 2 && pts[0] == pts[pts.len() - 1] {
        pts.pop();
    }
    before - pts.len()
}

/// `b` is the tip of a zero-width spike: the boundary goes from `a` to `b` and back along
/// itself towards `c`.
fn is_spike(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>) -> bool {
    if a == c {
        return true;
    }
    if orient2d(a, b, c) != Orientation::Collinear {
        return false;
    }
    // On one line, `b` is the tip when `a` and `c` lie on the same side of it. Compared
    // coordinate by coordinate, exactly: the sign of a dot product in floating point is wrong
    // when its terms underflow, overflow or cancel (coordinates near 1e-300 or 1e300).
    let same_side = |p: f64, q: f64, o: f64| (p > o && q > o) || (p < o && q < o);
    if a.x != b.x {
        same_side(a.x, c.x, b.x)
    } else {
        same_side(a.y, c.y, b.y)
    }
}

/// Whether a simple open ring runs counter-clockwise, decided exactly: the turn at its lowest
/// (then leftmost) vertex, a convex corner of any simple ring, has the ring's orientation. The
/// sign of the shoelace sum is not exact: with coordinates of very different magnitudes its
/// rounding can give both windings the same sign.
pub fn simple_ring_is_ccw(r: &[Coord<f64>]) -> bool {
    let n = r.len();
    let Some(i) = (0..n).min_by(|&a, &b| r[a].y.total_cmp(&r[b].y).then(r[a].x.total_cmp(&r[b].x)))
    else {
        return false;
    };
    orient2d(r[(i + n - 1) % n], r[i], r[(i + 1) % n]) == Orientation::CounterClockwise
}

/// Below this many edges the pairwise loops are faster than building an R-tree; the answers
/// are the same either way.
pub const INDEX_MIN_EDGES: usize = 48;

/// True when the open ring `r` (≥ 3 points) is simple: consecutive edges meet only at their
/// shared vertex, other edges do not meet at all.
///
/// Each edge is tested exactly ([`segments_intersect`]) against the edges whose bounding boxes
/// meet its own, found in an R-tree (see the module doc for the cost). A ring with a non-finite
/// coordinate (never simple in practice, and refused by [`repair_polygon`] before this is asked)
/// goes through the pairwise loop, whose answer for NaN is defined by the predicates.
pub fn ring_is_simple(r: &[Coord<f64>]) -> bool {
    let n = r.len();
    if n < 3 {
        return false;
    }
    if n < INDEX_MIN_EDGES || r.iter().any(|c| !c.x.is_finite() || !c.y.is_finite()) {
        return ring_is_simple_pairwise(r);
    }
    for i in 0..n {
        let (a, b, c) = (r[i], r[(i + 1) % n], r[(i + 2) % n]);
        // Consecutive edges a-b, b-c: must not fold back over each other.
        if on_segment(a, b, c) || on_segment(b, c, a) {
            return false;
        }
    }
    let tree = edge_tree(&[r]);
    for i in 0..n {
        let (a, b) = (r[i], r[(i + 1) % n]);
        for e in tree.locate_in_envelope_intersecting(&segment_box(a, b)) {
            // Each unordered pair of non-consecutive edges once: j ≥ i + 2, and not (0, n − 1).
            let j = e.edge as usize;
            if j < i + 2 || (i == 0 && j == n - 1) {
                continue;
            }
            if segments_intersect(a, b, r[j], r[(j + 1) % n]) != SegmentIntersection::None {
                return false;
            }
        }
    }
    true
}

/// [`ring_is_simple`] by the pairwise loop: O(n²) with bounding-box rejection.
fn ring_is_simple_pairwise(r: &[Coord<f64>]) -> bool {
    let n = r.len();
    if n < 3 {
        return false;
    }
    for i in 0..n {
        let (a, b) = (r[i], r[(i + 1) % n]);
        let c = r[(i + 2) % n];
        // Consecutive edges a-b, b-c: must not fold back over each other.
        if on_segment(a, b, c) || on_segment(b, c, a) {
            return false;
        }
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let (p, q) = (r[j], r[(j + 1) % n]);
            if segments_intersect(a, b, p, q) != SegmentIntersection::None {
                return false;
            }
        }
    }
    true
}

/// Edge `edge` (from point `edge` to the next, cyclically) of ring `ring`, in an R-tree.
#[derive(Clone, Copy, Debug)]
struct EdgeRef {
    ring: u32,
    edge: u32,
    bbox: AABB<[f64; 2]>,
}

impl RTreeObject for EdgeRef {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        self.bbox
    }
}

fn segment_box(a: Coord<f64>, b: Coord<f64>) -> AABB<[f64; 2]> {
    AABB::from_corners([a.x, a.y], [b.x, b.y])
}

/// An R-tree of every edge of the (open) rings, bulk loaded.
fn edge_tree(rings: &[&[Coord<f64>]]) -> RTree<EdgeRef> {
    let mut edges = Vec::with_capacity(rings.iter().map(|r| r.len()).sum());
    for (k, r) in rings.iter().enumerate() {
        let n = r.len();
        for i in 0..n {
            edges.push(EdgeRef {
                ring: k as u32,
                edge: i as u32,
                bbox: segment_box(r[i], r[(i + 1) % n]),
            });
        }
    }
    RTree::bulk_load(edges)
}

fn ring_bbox(r: &[Coord<f64>]) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in r {
        b[0] = b[0].min(c.x);
        b[1] = b[1].min(c.y);
        b[2] = b[2].max(c.x);
        b[3] = b[3].max(c.y);
    }
    b
}

/// The first pair of rings (indices, lexicographically smallest) that touch or cross, if any.
///
/// Every edge of ring i is tested exactly against the edges of later rings whose bounding boxes
/// meet its own (an R-tree lookup); the smallest such j for the smallest i is the answer.
fn first_interacting_rings(rings: &[&[Coord<f64>]]) -> Option<(usize, usize)> {
    let total: usize = rings.iter().map(|r| r.len()).sum();
    if rings.len() < 2 {
        return None;
    }
    if total < INDEX_MIN_EDGES {
        return first_interacting_rings_pairwise(rings);
    }
    let tree = edge_tree(rings);
    for (i, ri) in rings.iter().enumerate() {
        let mut best: Option<usize> = None;
        for s in 0..ri.len() {
            let (a, b) = (ri[s], ri[(s + 1) % ri.len()]);
            for e in tree.locate_in_envelope_intersecting(&segment_box(a, b)) {
                let j = e.ring as usize;
                if j <= i || best.is_some_and(|bj| j >= bj) {
                    continue;
                }
                let rj = rings[j];
                let t = e.edge as usize;
                let (p, q) = (rj[t], rj[(t + 1) % rj.len()]);
                if segments_intersect(a, b, p, q) != SegmentIntersection::None {
                    best = Some(j);
                }
            }
        }
        if let Some(j) = best {
            return Some((i, j));
        }
    }
    None
}

/// [`first_interacting_rings`] by the pairwise loop over rings whose boxes meet.
fn first_interacting_rings_pairwise(rings: &[&[Coord<f64>]]) -> Option<(usize, usize)> {
    let boxes: Vec<[f64; 4]> = rings.iter().map(|r| ring_bbox(r)).collect();
    for i in 0..rings.len() {
        for j in i + 1..rings.len() {
            let (bi, bj) = (boxes[i], boxes[j]);
            if bi[2] < bj[0] || bj[2] < bi[0] || bi[3] < bj[1] || bj[3] < bi[1] {
                continue;
            }
            let (ri, rj) = (rings[i], rings[j]);
            for s in 0..ri.len() {
                let (a, b) = (ri[s], ri[(s + 1) % ri.len()]);
                for t in 0..rj.len() {
                    let (p, q) = (rj[t], rj[(t + 1) % rj.len()]);
                    if segments_intersect(a, b, p, q) != SegmentIntersection::None {
                        return Some((i, j));
                    }
                }
            }
        }
    }
    None
}

/// For each point, the rings (ascending index) where [`point_in_ring`] would not say
/// [`Location::Outside`], with what it would say.
///
/// With an R-tree of all edges, a point is tested only against the edges whose bounding boxes
/// meet the ray of the crossing test (from the point towards +x): an edge off that ray can
/// neither hold the point nor be crossed right of it, so the parities and the boundary hits are
/// those of [`point_in_ring`] on every ring. Below [`INDEX_MIN_EDGES`] edges, [`point_in_ring`]
/// itself is called on every ring.
fn ring_locations(rings: &[&[Coord<f64>]], points: &[Coord<f64>]) -> Vec<Vec<(usize, Location)>> {
    let total: usize = rings.iter().map(|r| r.len()).sum();
    if points.is_empty() {
        return Vec::new();
    }
    if total < INDEX_MIN_EDGES {
        return points
            .iter()
            .map(|&p| {
                rings
                    .iter()
                    .enumerate()
                    .map(|(k, r)| (k, point_in_ring(p, r)))
                    .filter(|(_, l)| *l != Location::Outside)
                    .collect()
            })
            .collect();
    }
    let rings: Vec<&[Coord<f64>]> = rings.iter().map(|r| open_ring(r)).collect();
    let tree = edge_tree(&rings);
    let x_max = tree.root().envelope().upper()[0];
    points
        .iter()
        .map(|&p| {
            // (ring, odd crossings, on the boundary), for the rings the ray meets.
            let mut hits: Vec<(usize, bool, bool)> = Vec::new();
            let ray = AABB::from_corners([p.x, p.y], [x_max.max(p.x), p.y]);
            let mut found: Vec<&EdgeRef> = tree.locate_in_envelope_intersecting(&ray).collect();
            found.sort_unstable_by_key(|e| (e.ring, e.edge));
            for e in found {
                let r = rings[e.ring as usize];
                let i = e.edge as usize;
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                if hits.last().is_none_or(|h| h.0 != e.ring as usize) {
                    hits.push((e.ring as usize, false, false));
                }
                let h = hits.last_mut().expect("pushed above");
                if on_segment(a, b, p) {
                    h.2 = true;
                    continue;
                }
                let a_above = a.y >= p.y;
                let b_above = b.y >= p.y;
                if a_above != b_above {
                    let o = orient2d(a, b, p);
                    let right = if b_above {
                        o == Orientation::CounterClockwise
                    } else {
                        o == Orientation::Clockwise
                    };
                    if right {
                        h.1 = !h.1;
                    }
                }
            }
            hits.into_iter()
                .filter_map(|(k, odd, on)| match (on, odd) {
                    (true, _) => Some((k, Location::OnBoundary)),
                    (false, true) => Some((k, Location::Inside)),
                    (false, false) => None,
                })
                .collect()
        })
        .collect()
}

/// What [`point_in_ring`] says of ring `ring`, read from a [`ring_locations`] entry.
fn location_in(locs: &[(usize, Location)], ring: usize) -> Location {
    locs.iter()
        .find(|(k, _)| *k == ring)
        .map_or(Location::Outside, |(_, l)| *l)
}

fn closed_polygon(r: &[Coord<f64>]) -> Polygon<f64> {
    Polygon::new(LineString::from(r.to_vec()), vec![])
}

/// Rings after [`separate_touches`]: the exterior, the holes with their ring indices, and what
/// was done.
type Separated = (
    Vec<Coord<f64>>,
    Vec<(usize, Vec<Coord<f64>>)>,
    Vec<RepairAction>,
);

/// Separates rings that touch at isolated points (see the module doc): `None` when there is no
/// such point, or when the rings are still not simple and apart afterwards (they cross, share
/// an edge, or the touch is a bow-tie's), so that the caller goes on as if nothing was tried.
///
/// A touch point is a vertex that another vertex repeats (of another ring, or of the same ring
/// further on), or that lies inside an edge of another ring or of its own. One visit of the point
/// stays (an edge through it, else the vertex of lowest ring and index); every other vertex at
/// the point is notched ([`notch`]).
fn separate_touches(ext: &[Coord<f64>], holes: &[(usize, Vec<Coord<f64>>)]) -> Option<Separated> {
    let rings: Vec<&[Coord<f64>]> = std::iter::once(ext)
        .chain(holes.iter().map(|(_, h)| &h[..]))
        .collect();
    let ids: Vec<usize> = std::iter::once(0)
        .chain(holes.iter().map(|(k, _)| *k))
        .collect();
    // -0.0 and 0.0 are one point: `+ 0.0` turns the first into the second.
    let key = |c: Coord<f64>| ((c.x + 0.0).to_bits(), (c.y + 0.0).to_bits());
    // Per point, its visits (ring position, 0, vertex index) and (ring position, 1, index of an
    // edge through its inside).
    type Visits = Vec<(usize, u8, usize)>;
    let mut at: std::collections::BTreeMap<(u64, u64), Visits> = Default::default();
    for (r, ring) in rings.iter().enumerate() {
        for (i, &c) in ring.iter().enumerate() {
            at.entry(key(c)).or_default().push((r, 0, i));
        }
    }
    let tree = edge_tree(&rings);
    for ring in &rings {
        for &p in ring.iter() {
            let probe = AABB::from_point([p.x, p.y]);
            for e in tree.locate_in_envelope_intersecting(&probe) {
                let (er, ei) = (e.ring as usize, e.edge as usize);
                let (a, b) = (rings[er][ei], rings[er][(ei + 1) % rings[er].len()]);
                if a != p && b != p && on_segment(a, b, p) {
                    let v = at.get_mut(&key(p)).expect("every vertex has an entry");
                    if !v.contains(&(er, 1, ei)) {
                        v.push((er, 1, ei));
                    }
                }
            }
        }
    }
    // Per ring position: (vertex index, 0) or (edge index, 1) → (position of the ring kept
    // there, the point).
    type Slots = std::collections::BTreeMap<(usize, u8), (usize, Coord<f64>)>;
    let mut notched: Vec<Slots> = vec![Slots::new(); rings.len()];
    for visits in at.values_mut() {
        if visits.len() < 2 {
            continue;
        }
        let edges = visits.iter().filter(|v| v.1 == 1).count();
        if edges > 1 {
            // Two edges through one point that is a vertex of neither: they cross there.
            return None;
        }
        visits.sort_unstable();
        let kept = visits[0].0;
        // The point itself: every point here is some ring's vertex.
        let &(vr, _, vi) = visits
            .iter()
            .find(|v| v.1 == 0)
            .expect("points are keyed by vertices");
        let p = rings[vr][vi];
        for &(r, kind, i) in &visits[1..] {
            if notched[r].insert((i, kind), (kept, p)).is_some() {
                // Two touch points inside one edge: not separated here.
                return None;
            }
        }
    }
    if notched.iter().all(|m| m.is_empty()) {
        return None;
    }
    let mut actions = Vec::new();
    let mut out: Vec<Vec<Coord<f64>>> = Vec::with_capacity(rings.len());
    for (r, ring) in rings.iter().enumerate() {
        if notched[r].is_empty() {
            out.push(ring.to_vec());
            continue;
        }
        let ccw = ring_signed_area(ring) > 0.0;
        let n = ring.len();
        let mut new = Vec::with_capacity(n + 3 * notched[r].len());
        let mut cut = |kept: usize, p: Coord<f64>, prev, next, new: &mut Vec<Coord<f64>>| {
            let (pts, moved_m) = notch(prev, p, next, ccw);
            new.extend(pts);
            actions.push(RepairAction::SeparatedTouch {
                rings: (ids[kept], ids[r]),
                at: [p.x, p.y],
                moved_m,
            });
        };
        for i in 0..n {
            let (prev, next) = (ring[(i + n - 1) % n], ring[(i + 1) % n]);
            match notched[r].get(&(i, 0)) {
                Some(&(kept, p)) => cut(kept, p, prev, next, &mut new),
                None => new.push(ring[i]),
            }
            if let Some(&(kept, p)) = notched[r].get(&(i, 1)) {
                cut(kept, p, ring[i], next, &mut new);
            }
        }
        out.push(new);
    }
    let all: Vec<&[Coord<f64>]> = out.iter().map(|r| &r[..]).collect();
    if !all.iter().all(|r| ring_is_simple(r)) || first_interacting_rings(&all).is_some() {
        return None;
    }
    let mut out = out.into_iter();
    let ext = out.next().expect("the exterior is always there");
    let holes = ids[1..].iter().copied().zip(out).collect();
    Some((ext, holes, actions))
}

/// Replaces vertex `v` (between `prev` and `next`) of a ring by three points `a, m, b`: `a` and
/// `b` on its two edges at distance δ from `v`, `m` at distance δ from `v` along the bisector of
/// the angle the ring bounds there (left of the ring's direction when `ccw`, else right), with
/// δ = [`TOUCH_SEPARATION_M`] or a quarter of the shorter edge if that is less. None of the
/// three is `v`, and the ring's area changes by the quadrilateral `a, v, b, m`:
/// |ΔA| = ½ |(b − a) × (m − v)| ≤ ½ · 2δ · δ = δ². Returns the points and δ.
fn notch(prev: Coord<f64>, v: Coord<f64>, next: Coord<f64>, ccw: bool) -> ([Coord<f64>; 3], f64) {
    let (din, dout) = (prev - v, next - v);
    let (lin, lout) = (din.x.hypot(din.y), dout.x.hypot(dout.y));
    let d = TOUCH_SEPARATION_M.min(0.25 * lin.min(lout));
    let (start, end) = if ccw {
        (dout.y.atan2(dout.x), din.y.atan2(din.x))
    } else {
        (din.y.atan2(din.x), dout.y.atan2(dout.x))
    };
    let mid = start + 0.5 * (end - start).rem_euclid(std::f64::consts::TAU);
    let a = v + din * (d / lin);
    let b = v + dout * (d / lout);
    let m = v + Coord {
        x: d * mid.cos(),
        y: d * mid.sin(),
    };
    ([a, m, b], d)
}

/// Resolves self-intersections and crossing rings with the overlay (see the module doc).
/// The smallest and largest extent (the larger side of a ring's bounding box) the overlay
/// resolves. `i_overlay` maps the bounding box of each operation onto a 2³⁰ integer grid by a
/// power of two; for a box below about 1e-290 that scale overflows to infinity, above about
/// 1e300 the box's own size does, and the grid coordinates come out as garbage (products that
/// overflow). Footprints are metres to kilometres across.
pub const OVERLAY_EXTENT_RANGE: (f64, f64) = (1e-280, 1e300);

/// Why the overlay cannot take these rings, if it cannot: a ring whose extent is outside
/// [`OVERLAY_EXTENT_RANGE`].
fn overlay_range_problem<'a>(
    rings: impl Iterator<Item = (usize, &'a [Coord<f64>])>,
) -> Option<String> {
    let (lo, hi) = OVERLAY_EXTENT_RANGE;
    for (k, r) in rings {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for c in r {
            x0 = x0.min(c.x);
            y0 = y0.min(c.y);
            x1 = x1.max(c.x);
            y1 = y1.max(c.y);
        }
        let extent = (x1 - x0).max(y1 - y0);
        if !(lo..=hi).contains(&extent) {
            return Some(format!(
                "ring {k} is {extent:e} across, outside the {lo:e} to {hi:e} the overlay resolves"
            ));
        }
    }
    None
}

fn overlay_repair(
    ext: Vec<Coord<f64>>,
    holes: Vec<(usize, Vec<Coord<f64>>)>,
    why: String,
    mut actions: Vec<RepairAction>,
) -> Result<Repaired, Refusal> {
    let rings = std::iter::once((0, &ext[..])).chain(holes.iter().map(|(k, h)| (*k, &h[..])));
    if let Some(problem) = overlay_range_problem(rings) {
        return Err(Refusal::Unrepairable {
            why: format!("{why}; {problem}"),
        });
    }
    let overlay = || {
        let empty = MultiPolygon::<f64>::new(vec![]);
        let mut area = closed_polygon(&ext).boolean_op_with_fill_rule(
            &empty,
            OpType::Union,
            FillRule::NonZero,
        );
        for (_, h) in &holes {
            let hole = closed_polygon(h).boolean_op_with_fill_rule(
                &empty,
                OpType::Union,
                FillRule::NonZero,
            );
            area = area.difference(&hole);
        }
        area
    };
    // The overlay library can fail an internal assertion on some self-crossing rings (found by
    // fuzzing): that footprint is refused with the reason instead of ending the import.
    let area = std::panic::catch_unwind(std::panic::AssertUnwindSafe(overlay)).map_err(|_| {
        Refusal::Unrepairable {
            why: format!("{why}; the polygon overlay failed on these rings"),
        }
    })?;
    let mut polygons = Vec::new();
    for part in area.0 {
        let inner: Vec<&[Coord<f64>]> = part.interiors().iter().map(|h| &h.0[..]).collect();
        let mut sub = Vec::new();
        let mut cleaned = match clean_ring(&part.exterior().0, 0, false, &mut sub) {
            Ok(r) => r,
            // Slivers of zero area can come out of the overlay: they are not footprint.
            Err(_) => continue,
        };
        if !ring_is_simple(&cleaned) {
            return Err(Refusal::Unrepairable {
                why: format!("{why}; the overlay left a non-simple ring"),
            });
        }
        if !simple_ring_is_ccw(&cleaned) {
            cleaned.reverse();
        }
        let mut hs = Vec::new();
        for h in inner {
            let mut hc = match clean_ring(h, 1, false, &mut sub) {
                Ok(r) => r,
                Err(_) => continue,
            };
            if simple_ring_is_ccw(&hc) {
                hc.reverse();
            }
            hs.push(LineString::from(hc));
        }
        let p = Polygon::new(LineString::from(cleaned), hs);
        if let Err(e) = check_polygon(&p) {
            return Err(Refusal::Unrepairable {
                why: format!("{why}; after the overlay: {e}"),
            });
        }
        polygons.push(p);
    }
    if polygons.is_empty() {
        return Err(Refusal::Unrepairable {
            why: format!("{why}; the overlay left no area"),
        });
    }
    actions.push(RepairAction::Overlay {
        why,
        parts: polygons.len(),
    });
    Ok(Repaired { polygons, actions })
}

/// Footprints whose rings touch at single points, valid in OGC terms or in the self-touching
/// ("inverted courtyard") form: (name, polygon, its area, how many touches), for the tests here
/// and the extrusion's.
#[cfg(test)]
pub(crate) fn touching_examples() -> Vec<(&'static str, Polygon<f64>, f64, usize)> {
    let ring = |v: &[(f64, f64)]| {
        let mut v = v.to_vec();
        v.push(v[0]);
        LineString::from(v)
    };
    let shell = ring(&[(0., 0.), (10., 0.), (10., 10.), (0., 10.)]);
    vec![
        (
            "hole touching a shell corner",
            Polygon::new(shell.clone(), vec![ring(&[(0., 0.), (1., 3.), (3., 1.)])]),
            100.0 - 4.0,
            1,
        ),
        (
            "hole vertex on a shell edge",
            Polygon::new(shell.clone(), vec![ring(&[(5., 0.), (4., 2.), (6., 2.)])]),
            100.0 - 2.0,
            1,
        ),
        (
            "shell vertex on a hole edge",
            Polygon::new(
                ring(&[(0., 0.), (10., 0.), (10., 10.), (5., 4.), (0., 10.)]),
                vec![ring(&[(3., 4.), (7., 4.), (5., 2.)])],
            ),
            // Shell: 100 minus the notch triangle (0,10),(5,4),(10,10) of area 30.
            70.0 - 4.0,
            1,
        ),
        (
            "two holes touching at a corner",
            Polygon::new(
                shell.clone(),
                vec![
                    ring(&[(2., 2.), (2., 4.), (4., 4.), (4., 2.)]),
                    ring(&[(4., 4.), (4., 6.), (6., 6.), (6., 4.)]),
                ],
            ),
            100.0 - 8.0,
            1,
        ),
        (
            "two holes each touching the shell and each other",
            Polygon::new(
                shell.clone(),
                vec![
                    ring(&[(0., 0.), (1., 5.), (5., 5.), (5., 1.)]),
                    ring(&[(5., 5.), (5., 8.), (10., 10.), (8., 5.)]),
                ],
            ),
            100.0 - 20.0 - 15.0,
            3,
        ),
        (
            "exterior touching itself (inverted courtyard)",
            Polygon::new(
                ring(&[
                    (0., 0.),
                    (10., 0.),
                    (10., 10.),
                    (0., 10.),
                    (0., 0.),
                    (2., 5.),
                    (5., 5.),
                    (5., 2.),
                ]),
                vec![],
            ),
            100.0 - 15.0,
            1,
        ),
        (
            "inverted courtyard, clockwise",
            Polygon::new(
                ring(&[
                    (5., 2.),
                    (5., 5.),
                    (2., 5.),
                    (0., 0.),
                    (0., 10.),
                    (10., 10.),
                    (10., 0.),
                    (0., 0.),
                ]),
                vec![],
            ),
            100.0 - 15.0,
            1,
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::predicates::polygon_area;
    use geo::Validation;
    use geo_types::coord;
    use proptest::prelude::*;

    fn c(x: f64, y: f64) -> Coord<f64> {
        coord! {x: x, y: y}
    }

    fn sq(x0: f64, y0: f64, s: f64) -> Vec<Coord<f64>> {
        vec![c(x0, y0), c(x0 + s, y0), c(x0 + s, y0 + s), c(x0, y0 + s)]
    }

    #[test]
    fn valid_square_is_untouched() {
        let mut ring = sq(0., 0., 10.);
        ring.push(ring[0]);
        let r = repair_rings(&ring, &[]).unwrap();
        assert!(r.actions.is_empty(), "{:?}", r.actions);
        assert_eq!(r.polygons.len(), 1);
        assert_eq!(polygon_area(&r.polygons[0]), 100.0);
    }

    #[test]
    fn unclosed_ring_is_closed_and_reported() {
        let r = repair_rings(&sq(0., 0., 1.), &[]).unwrap();
        assert_eq!(r.actions, vec![RepairAction::ClosedRing { ring: 0 }]);
        let mut closed = sq(0., 0., 1.);
        closed.push(closed[0]);
        let r2 = repair_rings(&closed, &[]).unwrap();
        assert_eq!(r.polygons, r2.polygons);
    }

    #[test]
    fn clockwise_exterior_is_rewound_not_repaired() {
        let mut r = sq(0., 0., 2.);
        r.reverse();
        r.push(r[0]);
        let out = repair_rings(&r, &[]).unwrap();
        assert_eq!(out.actions, vec![RepairAction::Rewound { ring: 0 }]);
        assert!(!out.was_repaired());
        assert!(ring_signed_area(&out.polygons[0].exterior().0) > 0.0);
    }

    #[test]
    fn repeated_points_and_spike_are_removed() {
        let mut r = vec![
            c(0., 0.),
            c(0., 0.),
            c(4., 0.),
            c(4., 2.),
            c(6., 2.), // spike out and back
            c(4., 2.),
            c(4., 4.),
            c(0., 4.),
        ];
        r.push(r[0]);
        let out = repair_rings(&r, &[]).unwrap();
        assert!(out.was_repaired());
        assert!(out
            .actions
            .iter()
            .any(|a| matches!(a, RepairAction::RemovedSpikes { ring: 0, .. })));
        assert_eq!(polygon_area(&out.polygons[0]), 16.0);
        check_polygon(&out.polygons[0]).unwrap();
    }

    #[test]
    fn degenerate_rings_are_refused() {
        assert!(matches!(
            repair_rings(&[c(0., 0.), c(1., 1.), c(0., 0.)], &[]),
            Err(Refusal::TooFewPoints { .. })
        ));
        assert!(matches!(
            repair_rings(&[c(0., 0.), c(1., 0.), c(2., 0.), c(0., 0.)], &[]),
            Err(Refusal::TooFewPoints { .. })
        ));
        assert!(matches!(
            repair_rings(&[c(0., 0.), c(f64::NAN, 0.), c(2., 1.)], &[]),
            Err(Refusal::NonFinite { ring: 0, index: 1 })
        ));
    }

    #[test]
    fn point_touches_are_separated_within_the_area_bound() {
        for (name, p, area, touches) in touching_examples() {
            let out = repair_polygon(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(out.polygons.len(), 1, "{name}");
            let q = &out.polygons[0];
            check_polygon(q).unwrap_or_else(|e| panic!("{name}: {e}"));
            let seps: Vec<&RepairAction> = out
                .actions
                .iter()
                .filter(|a| matches!(a, RepairAction::SeparatedTouch { .. }))
                .collect();
            assert_eq!(seps.len(), touches, "{name}: {:?}", out.actions);
            assert!(
                !out.actions.iter().any(|a| matches!(
                    a,
                    RepairAction::Overlay { .. } | RepairAction::DroppedHole { .. }
                )),
                "{name}: {:?}",
                out.actions
            );
            let mut bound = 0.0;
            for a in &seps {
                let RepairAction::SeparatedTouch { at, moved_m, .. } = a else {
                    unreachable!()
                };
                assert!(*moved_m > 0.0 && *moved_m <= TOUCH_SEPARATION_M, "{name}");
                bound += moved_m * moved_m;
                // The point is still on the boundary (the ring kept there), and every vertex of
                // the output is either the point itself or at least δ/2 away from it.
                let pt = c(at[0], at[1]);
                for r in std::iter::once(q.exterior()).chain(q.interiors()) {
                    for v in &r.0 {
                        let d = (v.x - pt.x).hypot(v.y - pt.y);
                        assert!(d == 0.0 || d >= 0.5 * moved_m, "{name}: {v:?} at {d}");
                    }
                }
                assert!(a.to_string().contains(" mm into the "), "{a}");
            }
            // Independent of the notch formula: the area of the input, computed by hand.
            let got = polygon_area(q);
            assert!(
                (got - area).abs() <= bound * (1.0 + 1e-9),
                "{name}: {got} vs {area}, bound {bound}"
            );
            assert!(got != area, "{name}: nothing moved");
            // Repairing again changes nothing more.
            let again = repair_polygon(q).unwrap();
            assert!(!again.was_repaired(), "{name}: {:?}", again.actions);
        }
    }

    /// Checks a repair of a footprint with `touches` point touches and true area `area`: one
    /// valid polygon, that many separations and nothing else but winding, area within Σ δ².
    fn assert_separated(p: &Polygon<f64>, area: f64, touches: usize) -> Result<(), TestCaseError> {
        let out = repair_polygon(p).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(out.polygons.len(), 1);
        prop_assert!(check_polygon(&out.polygons[0]).is_ok());
        let mut bound = 0.0;
        let mut n = 0;
        for a in &out.actions {
            match a {
                RepairAction::SeparatedTouch { moved_m, .. } => {
                    n += 1;
                    bound += moved_m * moved_m;
                }
                RepairAction::Rewound { .. } | RepairAction::ClosedRing { .. } => {}
                other => prop_assert!(false, "unexpected {other}"),
            }
        }
        prop_assert_eq!(n, touches);
        let got = polygon_area(&out.polygons[0]);
        prop_assert!(got != area);
        prop_assert!((got - area).abs() <= bound * (1.0 + 1e-9) + 1e-12 * area);
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// A triangular hole with one vertex on the shell's boundary (a corner or inside an
        /// edge), the others well inside (at least 0.1 s from the shell); and, when the vertex
        /// is the corner, the same courtyard written as a self-touching exterior.
        #[test]
        fn random_point_touches_are_separated(
            s in 5.0f64..200.0,
            t in 0.0f64..1.0,
            corner in any::<bool>(),
            q in prop::array::uniform4(0.1f64..0.9),
            reverse in any::<bool>(),
        ) {
            let v = if corner { c(0., 0.) } else { c(t * s, 0.) };
            let (q1, q2) = (c(q[0] * s, q[1] * s), c(q[2] * s, q[3] * s));
            let tri = ring_signed_area(&[v, q1, q2]);
            prop_assume!(tri.abs() > 0.01 * s * s);
            let mut hole = vec![v, q1, q2];
            if reverse {
                hole.reverse();
            }
            let p = Polygon::new(
                LineString::from(sq(0., 0., s)),
                vec![LineString::from(hole)],
            );
            assert_separated(&p, s * s - tri.abs(), 1)?;
            if corner {
                // Exterior, then the courtyard clockwise from the same corner.
                let (a, b) = if tri > 0.0 { (q2, q1) } else { (q1, q2) };
                let mut ext = sq(0., 0., s);
                ext.extend([c(0., 0.), a, b]);
                if reverse {
                    ext.reverse();
                }
                let p = Polygon::new(LineString::from(ext), vec![]);
                assert_separated(&p, s * s - tri.abs(), 1)?;
            }
        }
    }

    #[test]
    fn separated_touch_reads_clearly() {
        let a = RepairAction::SeparatedTouch {
            rings: (0, 2),
            at: [1.5, 2.0],
            moved_m: 0.001,
        };
        assert_eq!(
            a.to_string(),
            "ring 2 touched ring 0 at (1.500, 2.000): separated by moving ring 2's vertex there \
             1 mm into the hole"
        );
        let s = RepairAction::SeparatedTouch {
            rings: (0, 0),
            at: [0.0, 0.0],
            moved_m: 0.001,
        };
        assert_eq!(
            s.to_string(),
            "ring 0 touched itself at (0.000, 0.000): separated by moving one of its two \
             vertices there 1 mm into the footprint"
        );
    }

    #[test]
    fn bowtie_touching_at_a_vertex_is_still_two_lobes() {
        // Two lobes that meet at (1, 1) without nesting: not a courtyard, so no notch; the
        // overlay makes them two polygons, as for a crossing bow-tie.
        let r = [
            c(0., 0.),
            c(1., 1.),
            c(2., 0.),
            c(2., 2.),
            c(1., 1.),
            c(0., 2.),
            c(0., 0.),
        ];
        let out = repair_rings(&r, &[]);
        eprintln!("{out:?}");
        let out = out.unwrap();
        assert!(!out
            .actions
            .iter()
            .any(|a| matches!(a, RepairAction::SeparatedTouch { .. })));
        assert_eq!(out.polygons.len(), 2, "{:?}", out.polygons);
        let a: f64 = out.polygons.iter().map(polygon_area).sum();
        assert!((a - 2.0).abs() < 1e-9, "{a}");
        for p in &out.polygons {
            check_polygon(p).unwrap();
        }
    }

    #[test]
    fn crossing_hole_is_not_notched() {
        // A hole crossing the shell, and one sharing an edge with it: the overlay, as before.
        let shell = sq(0., 0., 10.);
        for h in [sq(8., 2., 4.), sq(6., 2., 4.)] {
            let out = repair_rings(&shell, &[&h]).unwrap();
            assert!(out
                .actions
                .iter()
                .any(|a| matches!(a, RepairAction::Overlay { .. })));
            assert!(!out
                .actions
                .iter()
                .any(|a| matches!(a, RepairAction::SeparatedTouch { .. })));
        }
    }

    #[test]
    fn bowtie_becomes_two_triangles() {
        let r = [c(0., 0.), c(2., 2.), c(2., 0.), c(0., 2.), c(0., 0.)];
        let out = repair_rings(&r, &[]).unwrap();
        assert_eq!(out.polygons.len(), 2);
        let a: f64 = out.polygons.iter().map(polygon_area).sum();
        assert!((a - 2.0).abs() < 1e-9, "{a}");
        for p in &out.polygons {
            check_polygon(p).unwrap();
        }
    }

    #[test]
    fn holes_outside_or_degenerate_are_dropped_hole_kept() {
        let ext = sq(0., 0., 10.);
        let inside = sq(2., 2., 2.);
        let outside = sq(20., 20., 1.);
        let flat = vec![c(5., 5.), c(6., 5.), c(7., 5.)];
        let out = repair_rings(&ext, &[&inside, &outside, &flat]).unwrap();
        assert_eq!(out.polygons.len(), 1);
        assert_eq!(out.polygons[0].interiors().len(), 1);
        assert_eq!(polygon_area(&out.polygons[0]), 96.0);
        let dropped = out
            .actions
            .iter()
            .filter(|a| matches!(a, RepairAction::DroppedHole { .. }))
            .count();
        assert_eq!(dropped, 2);
        check_polygon(&out.polygons[0]).unwrap();
    }

    #[test]
    fn hole_crossing_exterior_is_cut_out() {
        let ext = sq(0., 0., 10.);
        let hole = sq(8., 4., 4.); // sticks out on the right
        let out = repair_rings(&ext, &[&hole]).unwrap();
        let a: f64 = out.polygons.iter().map(polygon_area).sum();
        assert!((a - 92.0).abs() < 1e-6, "{a}");
        for p in &out.polygons {
            check_polygon(p).unwrap();
        }
    }

    /// Random rings: mostly star-shaped (simple), some scrambled (self-intersecting), some with
    /// repeated points and spikes, optionally far from the origin.
    fn ring_strategy() -> impl Strategy<Value = (Vec<Coord<f64>>, bool)> {
        (
            3usize..14,
            any::<u64>(),
            prop_oneof![Just(0.0), Just(1.0e7)],
            0u8..4,
        )
            .prop_map(|(n, seed, off, mode)| {
                use rand::{Rng, SeedableRng};
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                let mut angles: Vec<f64> = (0..n)
                    .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
                    .collect();
                angles.sort_by(f64::total_cmp);
                let mut pts: Vec<Coord<f64>> = angles
                    .iter()
                    .map(|a| {
                        let r = rng.random_range(1.0..50.0);
                        c(off + r * a.cos(), off + r * a.sin())
                    })
                    .collect();
                let simple_star = mode == 0;
                match mode {
                    1 => {
                        // Scramble: usually self-intersecting.
                        for i in (1..pts.len()).rev() {
                            let j = rng.random_range(0..=i);
                            pts.swap(i, j);
                        }
                    }
                    2 => {
                        // Repeated point and a spike.
                        let i = rng.random_range(0..pts.len());
                        pts.insert(i, pts[i]);
                        let j = rng.random_range(1..pts.len());
                        let (a, b) = (pts[j - 1], pts[j]);
                        let tip = c(b.x + (b.x - a.x) * 0.5, b.y + (b.y - a.y) * 0.5);
                        pts.insert(j + 1, tip);
                        pts.insert(j + 2, b);
                    }
                    3 => {
                        // Integer grid: many exact collinearities and touches.
                        for p in &mut pts {
                            *p = c((p.x - off).round() + off, (p.y - off).round() + off);
                        }
                    }
                    _ => {}
                }
                (pts, simple_star)
            })
    }

    /// The former spike loop: rescan from the start after every removal. O(n²).
    fn remove_spikes_rescan(mut pts: Vec<Coord<f64>>) -> (Vec<Coord<f64>>, usize, usize) {
        let (mut spikes, mut dupes) = (0, 0);
        loop {
            let n = pts.len();
            if n < 3 {
                break;
            }
            let found = (0..n).find(|&i| is_spike(pts[(i + n - 1) % n], pts[i], pts[(i + 1) % n]));
            match found {
                Some(i) => {
                    pts.remove(i);
                    spikes += 1;
                    dupes += dedupe_cyclic(&mut pts);
                }
                None => break,
            }
        }
        (pts, spikes, dupes)
    }

    /// A star-shaped ring of `n` points, then damaged by `mode`: 0 none (simple), 1 rounded to
    /// an integer grid (collinear runs, repeated points, touches), 2 a vertex moved onto another
    /// (self-touching at a vertex), 3 a vertex moved onto the exact middle of a non-adjacent
    /// edge, 4 two vertices swapped (crossing), 5 a zero-width spike folded back along an edge.
    fn damaged_ring(n: usize, seed: u64, off: f64, mode: u8) -> Vec<Coord<f64>> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut pts: Vec<Coord<f64>> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + rng.random_range(0.0..0.9)) / n as f64;
                let r = rng.random_range(20.0..60.0);
                c(off + r * a.cos(), off + r * a.sin())
            })
            .collect();
        let grid = |pts: &mut Vec<Coord<f64>>, step: f64| {
            for p in pts.iter_mut() {
                *p = c(
                    ((p.x - off) / step).round() * step + off,
                    ((p.y - off) / step).round() * step + off,
                );
            }
        };
        let i = rng.random_range(0..n);
        let j = (i + rng.random_range(2..n - 1)) % n;
        match mode {
            1 => grid(&mut pts, 1.0),
            2 => pts[i] = pts[j],
            3 => {
                grid(&mut pts, 2.0);
                let (a, b) = (pts[j], pts[(j + 1) % n]);
                if (j + 1) % n != i {
                    pts[i] = c(0.5 * (a.x + b.x), 0.5 * (a.y + b.y));
                }
            }
            4 => pts.swap(i, j),
            5 => {
                let (a, b) = (pts[i], pts[(i + 1) % n]);
                pts.insert(i + 1, c(a.x + 0.5 * (b.x - a.x), a.y + 0.5 * (b.y - a.y)));
                pts.insert(i + 1, b);
            }
            _ => {}
        }
        pts
    }

    /// A random walk on a small integer grid: many collinear runs, spikes and repeats.
    fn grid_walk(len: usize, seed: u64, size: i32) -> Vec<Coord<f64>> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..len)
            .map(|_| {
                c(
                    rng.random_range(0..size) as f64,
                    rng.random_range(0..size) as f64,
                )
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// The indexed simplicity test answers as the pairwise loop, above the size where the
        /// index is used, on simple, collinear, self-touching and crossing rings.
        #[test]
        fn indexed_simplicity_matches_pairwise(
            n in INDEX_MIN_EDGES..200, seed in any::<u64>(), mode in 0u8..6,
            off in prop_oneof![Just(0.0), Just(1.0e7)],
        ) {
            let mut r = damaged_ring(n, seed, off, mode);
            dedupe_cyclic(&mut r);
            prop_assume!(r.len() >= INDEX_MIN_EDGES);
            let simple = ring_is_simple(&r);
            prop_assert_eq!(simple, ring_is_simple_pairwise(&r));
            if mode == 0 {
                prop_assert!(simple);
            }
            if matches!(mode, 2 | 5) {
                prop_assert!(!simple);
            }
        }

        /// The spike removal by heap answers as the rescanning loop: same ring, same counts.
        #[test]
        fn heap_spike_removal_matches_rescan(
            len in 3usize..80, seed in any::<u64>(), size in 2i32..6,
        ) {
            let mut pts = grid_walk(len, seed, size);
            dedupe_cyclic(&mut pts);
            prop_assert_eq!(remove_spikes(pts.clone()), remove_spikes_rescan(pts));
        }

        #[test]
        fn heap_spike_removal_matches_rescan_on_rings(
            n in 4usize..120, seed in any::<u64>(), mode in 0u8..6,
        ) {
            let mut pts = damaged_ring(n, seed, 0.0, mode);
            dedupe_cyclic(&mut pts);
            prop_assert_eq!(remove_spikes(pts.clone()), remove_spikes_rescan(pts));
        }

        /// Indexed ring contacts and point locations answer as the pairwise loops, on an
        /// exterior with holes that may touch or cross it and each other (integer grid).
        #[test]
        fn indexed_ring_queries_match_pairwise(
            n in 12usize..80, seed in any::<u64>(), holes in 1usize..8, grid in any::<bool>(),
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
            let mut rings = vec![damaged_ring(n, seed, 0.0, if grid { 1 } else { 0 })];
            for k in 0..holes {
                let (cx, cy) = (rng.random_range(-70.0..70.0), rng.random_range(-70.0..70.0));
                let m = rng.random_range(3..12);
                let mut h = damaged_ring(m.max(4), seed.wrapping_add(k as u64 + 1), 0.0, 0);
                for p in &mut h {
                    *p = c(cx + p.x * 0.2, cy + p.y * 0.2);
                    if grid {
                        *p = c(p.x.round(), p.y.round());
                    }
                }
                dedupe_cyclic(&mut h);
                if h.len() >= 3 {
                    rings.push(h);
                }
            }
            let refs: Vec<&[Coord<f64>]> = rings.iter().map(|r| &r[..]).collect();
            let total: usize = refs.iter().map(|r| r.len()).sum();
            prop_assume!(total >= INDEX_MIN_EDGES);
            prop_assert_eq!(first_interacting_rings(&refs), first_interacting_rings_pairwise(&refs));
            // Points: every ring's vertices, edge midpoints, and random points on the grid.
            let mut pts: Vec<Coord<f64>> = Vec::new();
            for r in &rings {
                pts.extend(r.iter().step_by(3).copied());
                pts.extend(r.windows(2).step_by(5).map(|w| c(0.5 * (w[0].x + w[1].x), 0.5 * (w[0].y + w[1].y))));
            }
            pts.extend((0..40).map(|_| c(rng.random_range(-80..80) as f64, rng.random_range(-80..80) as f64)));
            let got = ring_locations(&refs, &pts);
            for (p, locs) in pts.iter().zip(&got) {
                for (k, r) in refs.iter().enumerate() {
                    prop_assert_eq!(location_in(locs, k), point_in_ring(*p, r), "point {:?} ring {}", p, k);
                }
            }
        }

        /// Many holes, some outside the exterior and some inside another hole: the holes kept
        /// and dropped are those of the pairwise rule (a hole inside a kept hole is dropped).
        #[test]
        fn many_holes_are_kept_and_dropped_as_by_the_pairwise_rule(
            seed in any::<u64>(), holes in 8usize..30,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let ext = sq(0., 0., 100.);
            // Cells of 10 m on a 12 × 12 grid over (−10, 110): some cells lie outside the
            // exterior. A cell holds a 6 m square hole, sometimes with a 2 m one inside it, and
            // sometimes just the 2 m one.
            let mut cells: Vec<(i32, i32)> = (0..12).flat_map(|i| (0..12).map(move |j| (i, j))).collect();
            for i in (1..cells.len()).rev() {
                cells.swap(i, rng.random_range(0..=i));
            }
            let mut hs: Vec<Vec<Coord<f64>>> = Vec::new();
            for &(i, j) in cells.iter().take(holes) {
                let (x, y) = (-10.0 + 10.0 * i as f64, -10.0 + 10.0 * j as f64);
                let kind = rng.random_range(0..3);
                if kind != 2 {
                    hs.push(sq(x + 2.0, y + 2.0, 6.0));
                }
                if kind != 0 {
                    hs.push(sq(x + 4.0, y + 4.0, 2.0));
                }
            }
            // Shuffle so that inner holes come before and after their outer ones.
            for i in (1..hs.len()).rev() {
                hs.swap(i, rng.random_range(0..=i));
            }
            // Cells straddling the exterior's edge make holes that cross it: keep only holes
            // fully inside or fully outside.
            hs.retain(|h| {
                let b = ring_bbox(h);
                b[2] < 0.0 || b[0] > 100.0 || b[3] < 0.0 || b[1] > 100.0
                    || (b[0] > 0.0 && b[2] < 100.0 && b[1] > 0.0 && b[3] < 100.0)
            });
            let refs: Vec<&[Coord<f64>]> = hs.iter().map(|h| &h[..]).collect();
            let out = repair_rings(&ext, &refs).unwrap();
            prop_assert_eq!(out.polygons.len(), 1);
            // The pairwise rule, as before the index.
            let inside: Vec<usize> = (0..hs.len())
                .filter(|&k| point_in_ring(hs[k][0], &ext) == Location::Inside)
                .collect();
            let mut nested = vec![false; inside.len()];
            for a in 0..inside.len() {
                for b in 0..inside.len() {
                    if a != b && !nested[b]
                        && point_in_ring(hs[inside[a]][0], &hs[inside[b]]) == Location::Inside
                    {
                        nested[a] = true;
                        break;
                    }
                }
            }
            let expect: Vec<Vec<Coord<f64>>> = inside
                .iter()
                .zip(&nested)
                .filter(|(_, n)| !**n)
                .map(|(&k, _)| {
                    let mut h = hs[k].clone();
                    h.reverse();
                    h.push(h[0]);
                    h
                })
                .collect();
            let got: Vec<Vec<Coord<f64>>> = out.polygons[0].interiors().iter().map(|h| h.0.clone()).collect();
            prop_assert_eq!(got, expect);
            prop_assert!(check_polygon(&out.polygons[0]).is_ok());
            prop_assert!(out.polygons[0].interiors().len() + 1 >= 1);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        #[test]
        fn repair_output_is_valid((pts, simple_star) in ring_strategy(), reverse in any::<bool>()) {
            let mut pts = pts;
            if reverse { pts.reverse(); }
            if simple_star { pts.push(pts[0]); }
            match repair_rings(&pts, &[]) {
                Ok(out) => {
                    prop_assert!(!out.polygons.is_empty());
                    for p in &out.polygons {
                        prop_assert!(check_polygon(p).is_ok(), "{:?}: {:?}", check_polygon(p), p);
                        prop_assert!(p.is_valid(), "geo says invalid: {:?}", p);
                        let e = &p.exterior().0;
                        prop_assert_eq!(e[0], e[e.len() - 1]);
                    }
                    if simple_star && ring_is_simple(&pts) {
                        // Already valid: exactly one polygon with the same area.
                        prop_assert!(!out.was_repaired());
                        prop_assert_eq!(out.polygons.len(), 1);
                        let a = polygon_area(&out.polygons[0]);
                        prop_assert_eq!(a, ring_signed_area(&pts).abs());
                    }
                }
                Err(e) => {
                    // Refusal is fine for degenerate input, but a simple star is never refused.
                    prop_assert!(!(simple_star && ring_is_simple(&pts) && ring_signed_area(&pts) != 0.0), "{e}");
                }
            }
        }
    }
}
