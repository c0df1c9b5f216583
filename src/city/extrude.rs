//! Footprint + heights → a closed, outward-oriented prism [`Mesh`] (Pina, Serón and Cerezo, §3: each building is
//! its footprint extruded to its height).
//!
//! - Walls: two triangles per ring edge, with the edge's own outward normal; wall vertices are
//!   not shared with other faces (flat shading), so closedness is a property of *positions*.
//! - Roof and floor: a footprint without holes of at most 64 vertices that exact tests prove
//!   simple is ear-clipped (about three times cheaper than a triangulation for the usual dozen
//!   vertices); any other footprint is triangulated with spade's constrained Delaunay
//!   triangulation,
//!   every ring edge a constraint; triangles outside the footprint (in a courtyard, or in the
//!   convex hull outside the exterior) are dropped. Which triangles are inside is found by a
//!   flood fill from the outer face that flips inside/outside at every constraint edge it
//!   crosses (the even-odd rule, decided by the triangulation's own topology): O(n) after the
//!   O(n log n) triangulation, where testing each triangle's centroid against the polygon cost
//!   O(n) per triangle, O(n²) in all. For a valid footprint both give the same triangles (a
//!   test compares them); the flood fill also stays right for slivers whose rounded centroid
//!   falls on or across an edge.
//! - Coordinates: the frame origin is subtracted in f64 before the one conversion to f32. A
//!   footprint with a detail finer than f32 resolves at its distance from the origin is refused
//!   with the building named: two vertices that round to one point
//!   ([`ExtrudeError::BelowPrecision`]), or a ring so thin that rounding turns it over
//!   ([`ExtrudeError::Sliver`]), either of which would leave the prism open or inside out.

use std::collections::HashMap;

use glam::{DVec2, DVec3, Vec3};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::appearance::building_style;
use super::mesh::{Mesh, VertexAppearance};
use super::model::{Building, City, LocalFrame};
use crate::geom::predicates::{
    open_ring, orient2d, ring_signed_area, segments_intersect, Orientation, SegmentIntersection,
};

/// Why a building could not be extruded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ExtrudeError {
    /// spade refused a vertex of the footprint (a coordinate too small, too large or NaN).
    #[error("building {id}: footprint cannot be triangulated: {source}")]
    Triangulation {
        /// Source id.
        id: String,
        /// What spade said.
        #[source]
        source: spade::InsertionError,
    },
    /// The footprint's rings cross or touch, or repeat a vertex: not a valid footprint.
    #[error(
        "building {id}: footprint cannot be triangulated: {crossings} crossing constraint(s), \
         {duplicates} duplicate vertex(es)"
    )]
    CrossingRings {
        /// Source id.
        id: String,
        /// Ring edges that crossed another (spade's constraint conflicts).
        crossings: usize,
        /// Vertices that fell on another.
        duplicates: usize,
    },
    /// Two vertices of the footprint round to the same f32 point in the local frame.
    #[error(
        "building {id}: vertex {first:?} and vertex {second:?} (ring, index) are {gap:e} m \
         apart, below f32 resolution at {from_origin:.0} m from the local origin"
    )]
    BelowPrecision {
        /// Source id.
        id: String,
        /// The first vertex: (ring, index in the ring); ring 0 is the exterior.
        first: (usize, usize),
        /// The second vertex.
        second: (usize, usize),
        /// Their distance, metres.
        gap: f64,
        /// The first vertex's distance from the local origin, metres.
        from_origin: f64,
    },
    /// A footprint that is valid as given (exactly, in world coordinates) has rings so close
    /// that they cross once the local origin is subtracted (a hole's edge a few ulps inside the
    /// shell's, say): a detail finer than the local frame resolves.
    #[error(
        "building {id}: its rings come closer than the local frame resolves ({from_origin:.0} m          from the local origin): once the origin is subtracted, {crossings} ring edge(s) cross"
    )]
    RingsBelowPrecision {
        /// Source id.
        id: String,
        /// Ring edges that crossed another in local coordinates.
        crossings: usize,
        /// The farthest vertex's distance from the local origin, metres.
        from_origin: f64,
    },
    /// A ring is so thin that rounding its vertices to f32 turns it over (or flattens it): the
    /// prism would be inside out.
    #[error(
        "building {id}: ring {ring} ({area_m2:e} m², {from_origin:.0} m from the local origin) is \
         thinner than f32 resolves there: rounded to f32 its area is {rounded_m2:e} m²"
    )]
    Sliver {
        /// Source id.
        id: String,
        /// The ring (0 is the exterior).
        ring: usize,
        /// Its signed area in f64, m².
        area_m2: f64,
        /// Its signed area after rounding to f32, m².
        rounded_m2: f64,
        /// Its farthest vertex's distance from the local origin, metres.
        from_origin: f64,
    },
    /// Heights are not finite or the top is not above the bottom.
    #[error("building {id}: top {top} m is not above bottom {bottom} m")]
    Heights {
        /// Source id.
        id: String,
        /// Top.
        top: f64,
        /// Bottom.
        bottom: f64,
    },
}

/// Per-thread buffers reused from one building to the next, so that extruding a city allocates
/// only what the meshes keep (and what spade allocates for each triangulation).
#[derive(Default)]
struct Scratch {
    /// The footprint's rings in local f64 coordinates, open (no repeated closing point), one
    /// after the other.
    local: Vec<DVec2>,
    /// One ring of `local` rounded to f32.
    rounded_ring: Vec<DVec2>,
    /// Where each ring starts in `local`, plus its end.
    starts: Vec<usize>,
    /// Face classification of the flood fill: 0 unknown, 1 outside, 2 inside.
    inside: Vec<u8>,
    /// Faces of the flood fill still to visit.
    stack: Vec<spade::handles::FixedFaceHandle<spade::handles::InnerTag>>,
    /// The cap's triangles.
    cap: Vec<[u32; 3]>,
    /// The footprint's vertices rounded to f32 (bit patterns) with their indices in `local`.
    rounded: Vec<([u32; 2], usize)>,
    /// Along-wall coordinates of one ring.
    us: Vec<f32>,
    /// The ear clipper's ring links (previous, next).
    ears: Vec<(u32, u32)>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Extrudes a building into a closed prism in the local frame.
///
/// # Errors
/// [`ExtrudeError`] for a footprint that is not valid or impossible heights; buildings of a
/// [`City`] are valid by construction.
pub fn try_extrude_building(b: &Building, frame: &LocalFrame) -> Result<Mesh, ExtrudeError> {
    EXTRUSIONS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    SCRATCH.with(|s| match s.try_borrow_mut() {
        Ok(mut s) => extrude_with(b, frame, &mut s),
        // Only reachable if extrusion re-entered itself on this thread: fresh buffers.
        Err(_) => extrude_with(b, frame, &mut Scratch::default()),
    })
}

/// Buildings extruded by this process so far ([`try_extrude_building`] calls, whatever their
/// outcome).
static EXTRUSIONS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// How many buildings this process has extruded so far (every [`try_extrude_building`] call,
/// which every other extrusion function goes through). A diagnostic: a scene extrudes each of
/// its buildings once, and a test checks it.
pub fn extrusions() -> u64 {
    EXTRUSIONS.load(std::sync::atomic::Ordering::Relaxed)
}

/// [`try_extrude_building`] with the given buffers.
fn extrude_with(b: &Building, frame: &LocalFrame, s: &mut Scratch) -> Result<Mesh, ExtrudeError> {
    let (z0, z1) = (b.base_m + b.min_height_m, b.base_m + b.height_m);
    if !(z0.is_finite() && z1.is_finite() && z1 > z0) {
        return Err(ExtrudeError::Heights {
            id: b.source_id.clone(),
            top: z1,
            bottom: z0,
        });
    }
    // Local f64 rings (the origin subtracted in f64), each opened after the subtraction as
    // `to_local_polygon` + `open_ring` would.
    s.local.clear();
    s.starts.clear();
    for ring in std::iter::once(b.footprint.exterior()).chain(b.footprint.interiors()) {
        let start = s.local.len();
        s.starts.push(start);
        s.local.extend(ring.0.iter().map(|&c| frame.to_local_xy(c)));
        let n = open_ring(&s.local[start..]).len();
        s.local.truncate(start + n);
    }
    s.starts.push(s.local.len());
    let n_in = s.local.len();
    // Vertices that round to one f32 point would make degenerate or doubled triangles and an
    // open prism: the footprint has a detail finer than f32 resolves this far from the origin.
    s.rounded.clear();
    s.rounded.extend(s.local.iter().enumerate().map(|(i, p)| {
        let r = p.as_vec2();
        ([r.x.to_bits(), r.y.to_bits()], i)
    }));
    s.rounded.sort_unstable();
    if let Some(w) = s.rounded.windows(2).find(|w| w[0].0 == w[1].0) {
        let (i, j) = (w[0].1.min(w[1].1), w[0].1.max(w[1].1));
        let at = |k: usize| {
            let ring = s.starts.partition_point(|&st| st <= k) - 1;
            (ring, k - s.starts[ring])
        };
        return Err(ExtrudeError::BelowPrecision {
            id: b.source_id.clone(),
            first: at(i),
            second: at(j),
            gap: s.local[i].distance(s.local[j]),
            from_origin: s.local[i].length(),
        });
    }

    // A ring thinner than f32 resolves (a sliver kilometres from the origin) can turn over when
    // rounded, though no two vertices meet: its prism would be inside out.
    for (ring, w) in s.starts.windows(2).enumerate() {
        let local = &s.local[w[0]..w[1]];
        let area = ring_signed_area(local);
        s.rounded_ring.clear();
        s.rounded_ring
            .extend(local.iter().map(|p| p.as_vec2().as_dvec2()));
        let rounded = ring_signed_area(&s.rounded_ring);
        if area != 0.0 && (rounded == 0.0 || (rounded > 0.0) != (area > 0.0)) {
            return Err(ExtrudeError::Sliver {
                id: b.source_id.clone(),
                ring,
                area_m2: area,
                rounded_m2: rounded,
                from_origin: local.iter().map(|p| p.length()).fold(0.0, f64::max),
            });
        }
    }

    // A simple footprint without holes and with few vertices (most buildings) is ear-clipped
    // (exact predicates; a ring the clipper cannot prove simple, or finds no ear in, falls
    // through); everything else goes through spade's constrained Delaunay triangulation.
    let clipped = s.starts.len() == 2 && {
        let (local, cap, next) = (&s.local, &mut s.cap, &mut s.ears);
        ear_clip(local, cap, next)
    };
    let cdt = if clipped {
        for p in &s.local {
            spade::validate_vertex(&Point2::new(p.x, p.y)).map_err(|source| {
                ExtrudeError::Triangulation {
                    id: b.source_id.clone(),
                    source,
                }
            })?;
        }
        None
    } else {
        // Triangulate in local f64 (spade takes its vertex and edge lists by value).
        let verts: Vec<Point2<f64>> = s.local.iter().map(|p| Point2::new(p.x, p.y)).collect();
        let mut edges: Vec<[usize; 2]> = Vec::with_capacity(n_in);
        for w in s.starts.windows(2) {
            let (start, len) = (w[0], w[1] - w[0]);
            edges.extend((0..len).map(|i| [start + i, start + (i + 1) % len]));
        }
        let mut conflicts = 0usize;
        let cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(
            verts,
            edges,
            |_| conflicts += 1,
        )
        .map_err(|source| ExtrudeError::Triangulation {
            id: b.source_id.clone(),
            source,
        })?;
        if conflicts > 0 || cdt.num_vertices() != n_in {
            // Valid as given, crossing here: the origin's subtraction moved a vertex across a
            // ring edge it was ulps from.
            if crate::geom::repair::check_polygon(&b.footprint).is_ok() {
                return Err(ExtrudeError::RingsBelowPrecision {
                    id: b.source_id.clone(),
                    crossings: conflicts,
                    from_origin: s.local.iter().map(|p| p.length()).fold(0.0, f64::max),
                });
            }
            return Err(ExtrudeError::CrossingRings {
                id: b.source_id.clone(),
                crossings: conflicts,
                duplicates: n_in - cdt.num_vertices(),
            });
        }
        cap_triangles_into(&cdt, s);
        Some(cdt)
    };

    // The footprint is already local (origin subtracted in f64): this is the one f32 rounding.
    let p32 = |x: f64, y: f64, z: f64| LocalFrame::round_to_f32(DVec3::new(x, y, z));

    let n_walls = n_in;
    let n_v = 2 * n_in + 4 * n_walls;
    let mut m = Mesh {
        positions: Vec::with_capacity(n_v),
        normals: Vec::with_capacity(n_v),
        indices: Vec::with_capacity(6 * s.cap.len() + 6 * n_walls),
        appearance: Vec::with_capacity(n_v),
        styles: vec![building_style(b)],
    };
    // Appearance: one style (index 0); u = 0 on roof and floor, the unfolded ring on walls.
    let va = |u_m: f32| VertexAppearance { u_m, style: 0 };
    // Roof (z1, normal +z) and floor (z0, normal −z, reversed).
    for (z, nz, flip) in [(z1, 1.0f32, false), (z0, -1.0, true)] {
        let base = m.positions.len() as u32;
        match &cdt {
            Some(cdt) => {
                for v in cdt.vertices() {
                    let p = v.position();
                    m.positions.push(p32(p.x, p.y, z));
                }
            }
            None => m.positions.extend(s.local.iter().map(|p| p32(p.x, p.y, z))),
        }
        m.normals.resize(m.positions.len(), Vec3::new(0.0, 0.0, nz));
        m.appearance.resize(m.positions.len(), va(0.0));
        for t in &s.cap {
            if flip {
                m.indices.extend([base + t[0], base + t[2], base + t[1]]);
            } else {
                m.indices.extend([base + t[0], base + t[1], base + t[2]]);
            }
        }
    }
    // Walls: the exterior is CCW and holes CW, so the solid is always left of each directed
    // edge and the outward normal points right.
    for w in s.starts.windows(2) {
        let r = &s.local[w[0]..w[1]];
        ring_u_into(r, &mut s.us);
        for i in 0..r.len() {
            let (a, b2) = (r[i], r[(i + 1) % r.len()]);
            let (ua, ub) = (s.us[i], s.us[i + 1]);
            let (dx, dy) = (b2.x - a.x, b2.y - a.y);
            let len = (dx * dx + dy * dy).sqrt();
            let n = LocalFrame::round_to_f32(DVec3::new(dy / len, -dx / len, 0.0));
            let base = m.positions.len() as u32;
            m.positions.extend([
                p32(a.x, a.y, z0),
                p32(b2.x, b2.y, z0),
                p32(b2.x, b2.y, z1),
                p32(a.x, a.y, z1),
            ]);
            m.normals.extend([n; 4]);
            m.appearance.extend([va(ua), va(ub), va(ub), va(ua)]);
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    Ok(m)
}

/// The most vertices a ring may have for [`ear_clip`] (its checks are quadratic; larger rings go
/// to spade).
const EAR_CLIP_MAX: usize = 64;

/// True when the open ring is simple: no repeated point, edges that are not neighbours share no
/// point, neighbours share only their common end (no spike folding back), exact predicates.
fn ring_is_simple(r: &[DVec2]) -> bool {
    let n = r.len();
    for i in 0..n {
        let (a, b) = (r[i], r[(i + 1) % n]);
        let c = r[(i + 2) % n];
        if a == b {
            return false;
        }
        // Neighbours a→b, b→c: a fold back onto a→b is a spike.
        if orient2d(a, b, c) == Orientation::Collinear && (b - a).dot(c - b) <= 0.0 {
            return false;
        }
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue; // the closing edge is a neighbour of the first
            }
            let (p, q) = (r[j], r[(j + 1) % n]);
            if segments_intersect(a, b, p, q) != SegmentIntersection::None {
                return false;
            }
        }
    }
    true
}

/// Ear clipping of a simple, counter-clockwise open ring of at most [`EAR_CLIP_MAX`] vertices into
/// `cap` (vertex indices, counter-clockwise): a vertex that turns strictly left and whose
/// triangle holds no other remaining vertex, even on its boundary, is cut off until three are
/// left. Exact `orient2d` throughout. Every ring vertex is kept, so the cap's border is exactly
/// the walls' edges. Returns false (and `cap` empty) for a ring it does not take: holes are the
/// caller's test; more vertices than the limit, not simple, clockwise, or no ear found in a full
/// turn (possible only with collinear vertices in degenerate positions).
fn ear_clip(r: &[DVec2], cap: &mut Vec<[u32; 3]>, links: &mut Vec<(u32, u32)>) -> bool {
    let n = r.len();
    cap.clear();
    if !(3..=EAR_CLIP_MAX).contains(&n) || !ring_is_simple(r) {
        return false;
    }
    // Counter-clockwise, exactly: the turn at the lowest-leftmost vertex, which is convex in a
    // simple ring (collinear there only for a degenerate ring, refused as well).
    let m = (0..n)
        .min_by(|&a, &b| {
            (r[a].x, r[a].y)
                .partial_cmp(&(r[b].x, r[b].y))
                .unwrap_or(std::cmp::Ordering::Equal)
        })
        .unwrap_or(0);
    if orient2d(r[(m + n - 1) % n], r[m], r[(m + 1) % n]) != Orientation::CounterClockwise {
        return false;
    }
    links.clear();
    links.extend((0..n).map(|i| (((i + n - 1) % n) as u32, ((i + 1) % n) as u32)));
    let mut remaining = n;
    let mut i = 0usize;
    let mut misses = 0usize;
    let is_ear = |links: &[(u32, u32)], i: usize| -> bool {
        let (p, q) = (links[i].0 as usize, links[i].1 as usize);
        let (a, b, c) = (r[p], r[i], r[q]);
        if orient2d(a, b, c) != Orientation::CounterClockwise {
            return false;
        }
        let mut v = links[q].1 as usize;
        while v != p {
            let x = r[v];
            if orient2d(a, b, x) != Orientation::Clockwise
                && orient2d(b, c, x) != Orientation::Clockwise
                && orient2d(c, a, x) != Orientation::Clockwise
            {
                return false;
            }
            v = links[v].1 as usize;
        }
        true
    };
    while remaining > 3 {
        if misses > remaining {
            cap.clear();
            return false;
        }
        if is_ear(links, i) {
            let (p, q) = links[i];
            cap.push([p, i as u32, q]);
            links[p as usize].1 = q;
            links[q as usize].0 = p;
            remaining -= 1;
            misses = 0;
            i = p as usize;
        } else {
            misses += 1;
            i = links[i].1 as usize;
        }
    }
    let (p, q) = links[i];
    if orient2d(r[p as usize], r[i], r[q as usize]) != Orientation::CounterClockwise {
        cap.clear();
        return false;
    }
    cap.push([p, i as u32, q]);
    true
}

/// [`super::appearance::ring_u`] of an open ring of local points, into `out` (cleared first): the same sums in the
/// same order.
fn ring_u_into(ring: &[DVec2], out: &mut Vec<f32>) {
    out.clear();
    let mut acc = 0.0f64;
    for (i, a) in ring.iter().enumerate() {
        out.push(acc as f32);
        let b = ring[(i + 1) % ring.len()];
        acc += (b.x - a.x).hypot(b.y - a.y);
    }
    out.push(acc as f32);
}

/// The footprint's CDT.
type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

/// The triangles of the CDT inside the footprint, in spade's face order, counter-clockwise (as
/// vertex indices).
///
/// A flood fill over the faces: the outer face is outside, and crossing an edge flips
/// inside/outside exactly when the edge is a constraint (a ring edge). A face is inside when an
/// odd number of ring edges separate it from the outer face: inside the exterior and outside
/// every hole. O(faces). The parity does not depend on the order in which faces are reached
/// (the rings do not cross), so a stack serves as well as a queue.
#[cfg(test)]
fn cap_triangles(cdt: &Cdt) -> Vec<[u32; 3]> {
    let mut s = Scratch::default();
    cap_triangles_into(cdt, &mut s);
    s.cap
}

/// [`cap_triangles`] into `s.cap`, with `s`'s buffers.
fn cap_triangles_into(cdt: &Cdt, s: &mut Scratch) {
    const UNKNOWN: u8 = 0;
    const OUT: u8 = 1;
    const IN: u8 = 2;
    let class = |inside: bool| if inside { IN } else { OUT };
    s.inside.clear();
    s.inside.resize(cdt.num_all_faces(), UNKNOWN);
    s.inside[cdt.outer_face().fix().index()] = OUT;
    s.stack.clear();
    // Seeds: the faces on the convex hull, next to the outer face.
    for f in cdt.inner_faces() {
        for e in f.adjacent_edges() {
            if e.rev().face().is_outer() && s.inside[f.fix().index()] == UNKNOWN {
                s.inside[f.fix().index()] = class(e.is_constraint_edge());
                s.stack.push(f.fix());
            }
        }
    }
    while let Some(fix) = s.stack.pop() {
        let f = cdt.face(fix);
        let here = s.inside[fix.index()] == IN;
        for e in f.adjacent_edges() {
            if let Some(g) = e.rev().face().as_inner() {
                let slot = &mut s.inside[g.fix().index()];
                if *slot == UNKNOWN {
                    *slot = class(here != e.is_constraint_edge());
                    s.stack.push(g.fix());
                }
            }
        }
    }
    s.cap.clear();
    s.cap.extend(
        cdt.inner_faces()
            .filter(|f| s.inside[f.fix().index()] == IN)
            .map(|f| oriented(f.vertices())),
    );
}

/// A face's vertex indices, counter-clockwise by the exact orientation (spade's faces are
/// counter-clockwise; this makes sure).
fn oriented(
    v: [spade::handles::VertexHandle<'_, Point2<f64>, (), spade::CdtEdge<()>>; 3],
) -> [u32; 3] {
    let idx = v.map(|h| h.fix().index() as u32);
    let [a, b, c] = v.map(|h| DVec2::new(h.position().x, h.position().y));
    if orient2d(a, b, c) != Orientation::Clockwise {
        idx
    } else {
        [idx[0], idx[2], idx[1]]
    }
}

/// Extrudes a building of a [`City`] (valid by construction) into a closed prism in the local
/// frame. A footprint that is not valid gives an empty mesh; use [`try_extrude_building`] to
/// learn why.
pub fn extrude_building(b: &Building, frame: &LocalFrame) -> Mesh {
    try_extrude_building(b, frame).unwrap_or_default()
}

/// Extrudes every building, in parallel; `result[i]` is building `i`'s mesh.
pub fn extrude_city(city: &City) -> Vec<Mesh> {
    use rayon::prelude::*;
    city.buildings
        .par_iter()
        .map(|b| extrude_building(b, &city.frame))
        .collect()
}

/// Like [`extrude_city`], but every failure is returned (in building order) instead of an empty
/// mesh.
///
/// The meshes are collected straight into their vector (failures are rare and kept aside with
/// their building's index), so no second vector of results is held beside the meshes.
pub fn try_extrude_city(city: &City) -> (Vec<Mesh>, Vec<ExtrudeError>) {
    use rayon::prelude::*;
    let failed = std::sync::Mutex::new(Vec::new());
    let meshes: Vec<Mesh> = city
        .buildings
        .par_iter()
        .enumerate()
        .map(|(i, b)| {
            try_extrude_building(b, &city.frame).unwrap_or_else(|e| {
                failed
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .push((i, e));
                Mesh::default()
            })
        })
        .collect();
    let mut failed = failed.into_inner().unwrap_or_else(|p| p.into_inner());
    failed.sort_by_key(|f| f.0);
    (meshes, failed.into_iter().map(|f| f.1).collect())
}

/// Checks that a mesh is closed and consistently oriented: after welding vertices with equal
/// positions, every directed edge `a → b` of a triangle is matched by exactly one `b → a` and
/// appears only once.
///
/// # Errors
/// A description of the first defect found.
pub fn check_closed(m: &Mesh) -> Result<(), String> {
    if !m.indices.chunks_exact(3).remainder().is_empty() {
        return Err("index count is not a multiple of 3".into());
    }
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            let k = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            let n = weld.len() as u32;
            *weld.entry(k).or_insert(n)
        })
        .collect();
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in m.indices.chunks_exact(3) {
        let v = [ids[t[0] as usize], ids[t[1] as usize], ids[t[2] as usize]];
        if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
            return Err(format!("degenerate triangle {t:?}"));
        }
        for i in 0..3 {
            *directed.entry((v[i], v[(i + 1) % 3])).or_insert(0) += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        if n != 1 {
            return Err(format!("directed edge {a}→{b} used {n} times"));
        }
        if directed.get(&(b, a)) != Some(&1) {
            return Err(format!("edge {a}→{b} has no opposite edge"));
        }
    }
    Ok(())
}

/// Signed volume of a closed mesh (divergence theorem), computed in f64 from the f32 positions.
/// Positive when the triangles face outwards.
pub fn signed_volume(m: &Mesh) -> f64 {
    m.indices
        .chunks_exact(3)
        .map(|t| {
            let a = m.positions[t[0] as usize].as_dvec3();
            let b = m.positions[t[1] as usize].as_dvec3();
            let c = m.positions[t[2] as usize].as_dvec3();
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Area of the roof cap (triangles whose normal is +z), in f64 from the f32 positions.
pub fn roof_area(m: &Mesh) -> f64 {
    m.indices
        .chunks_exact(3)
        .filter(|t| m.normals[t[0] as usize].z > 0.5)
        .map(|t| {
            let a = m.positions[t[0] as usize].as_dvec3();
            let b = m.positions[t[1] as usize].as_dvec3();
            let c = m.positions[t[2] as usize].as_dvec3();
            0.5 * (b - a).cross(c - a).z
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::model::{BuildingId, HeightSource};
    use crate::geom::predicates::polygon_area;
    use crate::geom::repair::repair_polygon;
    use geo_types::{Coord, LineString, Polygon};
    use proptest::prelude::*;

    fn building(p: Polygon<f64>, h: f64, min: f64) -> Building {
        Building {
            id: BuildingId(0),
            source_id: "t:0".into(),
            footprint: p,
            height_m: h,
            min_height_m: min,
            base_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        }
    }

    fn square(x0: f64, y0: f64, s: f64, ccw: bool) -> LineString<f64> {
        let mut v = vec![(x0, y0), (x0 + s, y0), (x0 + s, y0 + s), (x0, y0 + s)];
        if !ccw {
            v.reverse();
        }
        v.push(v[0]);
        LineString::from(v)
    }

    /// The footprint as the f32 mesh sees it: local, rounded to f32, back to f64.
    fn rounded_area(p: &Polygon<f64>, frame: &LocalFrame) -> f64 {
        let r = |l: &LineString<f64>| -> LineString<f64> {
            l.0.iter()
                .map(|c| {
                    let v = frame.to_local(DVec3::new(c.x, c.y, 0.0)).as_dvec3();
                    Coord { x: v.x, y: v.y }
                })
                .collect::<Vec<_>>()
                .into()
        };
        polygon_area(&Polygon::new(
            r(p.exterior()),
            p.interiors().iter().map(r).collect(),
        ))
    }

    /// A sliver 1.7e-5 m wide and 550 m long whose far end is 550 m from the local origin
    /// (found by fuzzing): no two vertices round together, but rounded to f32 the ring turns
    /// over, and its prism would be inside out. It is refused, naming the ring; the same ring
    /// widened to 1 mm extrudes closed and outward.
    #[test]
    fn a_sliver_that_f32_turns_over_is_refused() {
        let v = [
            DVec2::new(110.4180908203125, 2007.9095458984375),
            DVec2::new(2.3634490966796875, 2548.182746887207),
            DVec2::new(2.3634567260742188, 2548.1827087402344),
            DVec2::new(110.41810607910156, 2007.909439086914),
        ];
        let poly = |v: &[DVec2]| {
            let mut r: Vec<(f64, f64)> = v.iter().map(|p| (p.x, p.y)).collect();
            r.push(r[0]);
            Polygon::new(LineString::from(r), vec![])
        };
        let frame = LocalFrame {
            origin: DVec3::new(v[0].x, v[0].y, 0.0),
        };
        match try_extrude_building(&building(poly(&v), 10.0, 0.0), &frame) {
            Err(ExtrudeError::Sliver {
                ring: 0,
                rounded_m2,
                area_m2,
                ..
            }) => assert!(area_m2 != 0.0 && rounded_m2 * area_m2 <= 0.0),
            other => panic!("{other:?}"),
        }
        // Widened: the return side moved 1 mm away from the outward side.
        let n = (v[1] - v[0]).perp().normalize();
        let wide = |s: f64| [v[0], v[1], v[2] + s * 1e-3 * n, v[3] + s * 1e-3 * n];
        let (a, b) = (wide(1.0), wide(-1.0));
        let w = if ring_signed_area(&a).abs() > ring_signed_area(&b).abs() {
            a
        } else {
            b
        };
        let m = try_extrude_building(&building(poly(&w), 10.0, 0.0), &frame).unwrap();
        check_closed(&m).unwrap();
        assert!(signed_volume(&m) > 0.0);
    }

    #[test]
    fn courtyard_prism_is_closed_with_the_right_volume() {
        let p = Polygon::new(
            square(0., 0., 30., true),
            vec![square(10., 10., 10., false)],
        );
        let b = building(p, 12.0, 2.0);
        let frame = LocalFrame {
            origin: DVec3::new(15.0, 15.0, 0.0),
        };
        let m = try_extrude_building(&b, &frame).unwrap();
        check_closed(&m).unwrap();
        assert!((signed_volume(&m) - 800.0 * 10.0).abs() < 1e-6);
        assert!((roof_area(&m) - 800.0).abs() < 1e-9);
        // Roof and floor: V + 2H − 2 = 8 + 2 − 2 = 8 triangles each; walls: 2 × 8.
        assert_eq!(m.triangle_count(), 8 * 2 + 16);
        assert_eq!(m.positions.len(), m.normals.len());
    }

    #[test]
    fn footprints_touching_at_a_point_extrude_closed_after_repair() {
        let frame = LocalFrame {
            origin: DVec3::new(5.0, 5.0, 0.0),
        };
        for (name, p, area, _) in crate::geom::repair::touching_examples() {
            // Unrepaired, the touch makes the prism non-manifold (or untriangulable).
            let raw = try_extrude_building(&building(p.clone(), 12.0, 2.0), &frame);
            assert!(raw.map_or(true, |m| check_closed(&m).is_err()), "{name}");
            let q = repair_polygon(&p).unwrap().polygons.remove(0);
            let m = try_extrude_building(&building(q.clone(), 12.0, 2.0), &frame)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            check_closed(&m).unwrap_or_else(|e| panic!("{name}: {e}"));
            // Volume and roof are the repaired footprint's (within f32 rounding), which is
            // within 1 mm² per touch of the input's.
            let a = rounded_area(&q, &frame);
            assert!((signed_volume(&m) - a * 10.0).abs() < 1e-3, "{name}");
            assert!((roof_area(&m) - a).abs() < 1e-4, "{name}");
            assert!((a - area).abs() < 1e-5, "{name}: {a} vs {area}");
        }
    }

    #[test]
    fn far_away_city_gives_the_same_local_mesh() {
        let p = Polygon::new(square(3.0, 4.0, 17.0, true), vec![]);
        let f0 = LocalFrame {
            origin: DVec3::new(1.0, 2.0, 0.0),
        };
        let off = 1.0e7;
        let p1 = Polygon::new(square(3.0 + off, 4.0 + off, 17.0, true), vec![]);
        let f1 = LocalFrame {
            origin: DVec3::new(1.0 + off, 2.0 + off, 0.0),
        };
        let m0 = try_extrude_building(&building(p, 9.0, 0.0), &f0).unwrap();
        let m1 = try_extrude_building(&building(p1, 9.0, 0.0), &f1).unwrap();
        assert_eq!(m0.indices, m1.indices);
        for (a, b) in m0.positions.iter().zip(&m1.positions) {
            assert!((*a - *b).abs().max_element() < 1e-3, "{a} {b}");
        }
    }

    #[test]
    fn bad_heights_are_an_error() {
        let p = Polygon::new(square(0., 0., 1., true), vec![]);
        let f = LocalFrame {
            origin: DVec3::ZERO,
        };
        let e = try_extrude_building(&building(p.clone(), 3.0, 3.0), &f).unwrap_err();
        assert!(
            matches!(&e, ExtrudeError::Heights { id, top, bottom } if id == "t:0" && *top == 3.0 && *bottom == 3.0),
            "{e:?}"
        );
        assert!(e.to_string().contains("t:0"), "{e}");
        let e = try_extrude_building(&building(p, f64::NAN, 0.0), &f).unwrap_err();
        assert!(
            matches!(&e, ExtrudeError::Heights { top, .. } if top.is_nan()),
            "{e:?}"
        );
    }

    #[test]
    fn invalid_footprints_are_errors_with_the_cause() {
        let f = LocalFrame {
            origin: DVec3::ZERO,
        };
        // A bow tie: the exterior crosses itself.
        let bow = Polygon::new(
            LineString::from(vec![
                (0.0, 0.0),
                (4.0, 4.0),
                (4.0, 0.0),
                (0.0, 4.0),
                (0.0, 0.0),
            ]),
            vec![],
        );
        let e = try_extrude_building(&building(bow, 3.0, 0.0), &f).unwrap_err();
        assert!(
            matches!(&e, ExtrudeError::CrossingRings { id, crossings, .. } if id == "t:0" && *crossings > 0),
            "{e:?}"
        );
        // A NaN vertex: spade's own error is kept as the source.
        let nan = Polygon::new(
            LineString::from(vec![(0.0, 0.0), (4.0, 0.0), (f64::NAN, 4.0), (0.0, 0.0)]),
            vec![],
        );
        let e = try_extrude_building(&building(nan, 3.0, 0.0), &f).unwrap_err();
        assert!(
            matches!(
                e,
                ExtrudeError::Triangulation {
                    source: spade::InsertionError::NAN,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(std::error::Error::source(&e).is_some());
    }

    /// The former classification, kept as the reference: a triangle is kept when its centroid
    /// is inside the polygon by the exact point-in-polygon test. O(n) per triangle.
    fn cap_triangles_by_centroid(cdt: &Cdt, lp: &Polygon<f64>) -> Vec<[u32; 3]> {
        use crate::geom::predicates::{point_in_polygon, Location};
        cdt.inner_faces()
            .filter(|f| {
                let p = f.vertices().map(|h| h.position());
                let c = Coord {
                    x: (p[0].x + p[1].x + p[2].x) / 3.0,
                    y: (p[0].y + p[1].y + p[2].y) / 3.0,
                };
                point_in_polygon(c, lp) == Location::Inside
            })
            .map(|f| oriented(f.vertices()))
            .collect()
    }

    /// The CDT of a polygon's rings, as [`try_extrude_building`] builds it.
    fn cdt_of(p: &Polygon<f64>) -> Cdt {
        let mut verts = Vec::new();
        let mut edges = Vec::new();
        for ring in std::iter::once(p.exterior()).chain(p.interiors()) {
            let r = open_ring(&ring.0);
            let start = verts.len();
            verts.extend(r.iter().map(|c| Point2::new(c.x, c.y)));
            edges.extend((0..r.len()).map(|i| [start + i, start + (i + 1) % r.len()]));
        }
        Cdt::bulk_load_cdt(verts, edges).unwrap()
    }

    fn star(n: usize, seed: u64, cx: f64, cy: f64, rmin: f64, rmax: f64) -> Vec<(f64, f64)> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + rng.random_range(0.0..0.8)) / n as f64;
                let r = rng.random_range(rmin..rmax);
                (cx + r * a.cos(), cy + r * a.sin())
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn random_polygons_with_holes_extrude_closed(
            n in 3usize..30, seed in any::<u64>(), holes in 0usize..3,
            off in prop_oneof![Just(0.0), Just(1.0e7)],
            h in 1.0f64..200.0, min in 0.0f64..0.9,
        ) {
            // Star-shaped exterior with radius 40..60 around (off, off); holes are small stars
            // around points at radius 20, well inside.
            let ext = star(n, seed, off, off, 40.0, 60.0);
            let hs: Vec<LineString<f64>> = (0..holes)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / 3.0;
                    let mut s = star(3 + (seed as usize + k) % 6, seed ^ k as u64, off + 22.0 * a.cos(), off + 22.0 * a.sin(), 3.0, 8.0);
                    s.reverse();
                    LineString::from(s)
                })
                .collect();
            let raw = Polygon::new(LineString::from(ext), hs);
            let rep = repair_polygon(&raw).unwrap();
            prop_assert_eq!(rep.polygons.len(), 1);
            let p = rep.polygons[0].clone();
            let frame = LocalFrame { origin: DVec3::new(off + 5.0, off - 3.0, 0.0) };
            let b = building(p.clone(), h, min * h);
            let m = try_extrude_building(&b, &frame).unwrap();
            prop_assert!(check_closed(&m).is_ok(), "{:?}", check_closed(&m));
            let area = rounded_area(&p, &frame);
            let expect = area * (h as f32 as f64 - (min * h) as f32 as f64);
            let v = signed_volume(&m);
            prop_assert!(v > 0.0);
            prop_assert!(((v - expect) / expect).abs() < 1e-6, "{} vs {}", v, expect);
            prop_assert!(((roof_area(&m) - area) / area).abs() < 1e-9);
            // And against the exact f64 area, up to f32 rounding of the coordinates.
            prop_assert!(((area - polygon_area(&p)) / polygon_area(&p)).abs() < 1e-5);
        }

        /// The flood fill keeps exactly the triangles the centroid test kept, on star-shaped
        /// footprints with holes, comb-like ones on an integer grid (many collinear edges) and
        /// footprints whose holes touch nothing but come within a millimetre of the exterior.
        #[test]
        fn flood_fill_matches_the_centroid_test(
            n in 3usize..60, seed in any::<u64>(), holes in 0usize..3, grid in any::<bool>(),
            off in prop_oneof![Just(0.0), Just(1.0e7)],
        ) {
            let mut ext = star(n, seed, off, off, 40.0, 60.0);
            if grid {
                for p in &mut ext {
                    *p = ((p.0 - off).round() + off, (p.1 - off).round() + off);
                }
            }
            let hs: Vec<LineString<f64>> = (0..holes)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / 3.0;
                    let mut s = star(3 + (seed as usize + k) % 6, seed ^ k as u64, off + 22.0 * a.cos(), off + 22.0 * a.sin(), 3.0, 8.0);
                    s.reverse();
                    LineString::from(s)
                })
                .collect();
            // Star exteriors with holes at radius 22 inside the radius-40 circle are always
            // repairable, snapped to the grid or not: a refusal is a failure.
            let rep = repair_polygon(&Polygon::new(LineString::from(ext), hs));
            prop_assert!(rep.is_ok(), "repair refused: {:?}", rep.err());
            let rep = rep.unwrap();
            for p in &rep.polygons {
                let frame = LocalFrame { origin: DVec3::new(off, off, 0.0) };
                let lp = frame.to_local_polygon(p);
                let cdt = cdt_of(&lp);
                prop_assert_eq!(cap_triangles(&cdt), cap_triangles_by_centroid(&cdt, &lp));
            }
        }
    }

    /// Which rings the ear clipper takes, and that its triangles turn left.
    #[test]
    fn ear_clip_takes_only_simple_counter_clockwise_rings() {
        let v = |pts: &[(f64, f64)]| {
            pts.iter()
                .map(|&(x, y)| DVec2::new(x, y))
                .collect::<Vec<_>>()
        };
        let clip = |pts: &[(f64, f64)]| {
            let r = v(pts);
            let (mut cap, mut links) = (Vec::new(), Vec::new());
            let ok = ear_clip(&r, &mut cap, &mut links);
            for t in &cap {
                assert_eq!(
                    orient2d(r[t[0] as usize], r[t[1] as usize], r[t[2] as usize]),
                    Orientation::CounterClockwise
                );
            }
            ok.then_some(cap.len())
        };
        assert_eq!(
            clip(&[(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)]),
            Some(2)
        );
        assert_eq!(clip(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]), Some(1));
        // Collinear vertices on the sides are kept (the walls' edges).
        assert_eq!(
            clip(&[
                (0.0, 0.0),
                (2.0, 0.0),
                (4.0, 0.0),
                (4.0, 3.0),
                (2.0, 3.0),
                (0.0, 3.0)
            ]),
            Some(4)
        );
        // Reflex vertices: an L and an arrow.
        assert_eq!(
            clip(&[
                (0.0, 0.0),
                (4.0, 0.0),
                (4.0, 1.0),
                (1.0, 1.0),
                (1.0, 3.0),
                (0.0, 3.0)
            ]),
            Some(4)
        );
        assert_eq!(
            clip(&[(0.0, 0.0), (4.0, 0.0), (2.0, 1.0), (4.0, 3.0), (0.0, 3.0)]),
            Some(3)
        );
        // Clockwise, a spike, a bow tie, a repeated point, too few vertices.
        assert_eq!(
            clip(&[(0.0, 0.0), (0.0, 3.0), (4.0, 3.0), (4.0, 0.0)]),
            None
        );
        assert_eq!(
            clip(&[(0.0, 0.0), (4.0, 0.0), (6.0, 0.0), (4.0, 0.0), (4.0, 3.0)]),
            None
        );
        assert_eq!(
            clip(&[(0.0, 0.0), (4.0, 3.0), (4.0, 0.0), (0.0, 3.0)]),
            None
        );
        assert_eq!(
            clip(&[(0.0, 0.0), (4.0, 0.0), (4.0, 0.0), (4.0, 3.0)]),
            None
        );
        assert_eq!(clip(&[(0.0, 0.0), (4.0, 0.0)]), None);
        // A pentagram turns left at every vertex but crosses itself.
        let star: Vec<(f64, f64)> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                (a.cos(), a.sin())
            })
            .collect();
        assert_eq!(clip(&star), None);
        // More vertices than the limit go to spade.
        let many: Vec<(f64, f64)> = (0..EAR_CLIP_MAX + 1)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / (EAR_CLIP_MAX + 1) as f64;
                (10.0 * a.cos(), 10.0 * a.sin())
            })
            .collect();
        assert_eq!(clip(&many), None);
        assert_eq!(clip(&many[..EAR_CLIP_MAX]), Some(EAR_CLIP_MAX - 2));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// The ear-clipped cap tiles the footprint: every triangle turns left, the areas sum to
        /// the footprint's, each ring edge is used once in its own direction and every other
        /// edge once each way (a closed cap whose border is the walls' edges). Star-shaped
        /// footprints in general position are always clipped; snapped to a grid (collinear
        /// vertices) they may fall through to spade.
        #[test]
        fn ear_clipped_caps_tile_the_footprint(
            n in 3usize..40, seed in any::<u64>(), grid in any::<bool>(),
        ) {
            let mut ext = star(n, seed, 0.0, 0.0, 20.0, 60.0);
            if grid {
                for p in &mut ext {
                    *p = (p.0.round(), p.1.round());
                }
            }
            // A star exterior of radius 20–60, snapped to the metre grid or not, is always
            // repairable: a refusal is a failure.
            let rep = repair_polygon(&Polygon::new(LineString::from(ext), vec![]));
            prop_assert!(rep.is_ok(), "repair refused: {:?}", rep.err());
            let rep = rep.unwrap();
            for p in &rep.polygons {
                prop_assume!(p.interiors().is_empty());
                let r: Vec<DVec2> = open_ring(&p.exterior().0).iter().map(|c| DVec2::new(c.x, c.y)).collect();
                let (mut cap, mut links) = (Vec::new(), Vec::new());
                let ok = ear_clip(&r, &mut cap, &mut links);
                if !grid && r.len() <= EAR_CLIP_MAX {
                    prop_assert!(ok, "{:?}", r);
                }
                if !ok {
                    continue;
                }
                prop_assert_eq!(cap.len(), r.len() - 2);
                let mut area = 0.0;
                let mut directed: HashMap<(u32, u32), i32> = HashMap::new();
                for t in &cap {
                    let [a, b, c] = t.map(|k| r[k as usize]);
                    prop_assert_eq!(orient2d(a, b, c), Orientation::CounterClockwise);
                    area += 0.5 * (b - a).perp_dot(c - a);
                    for (x, y) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                        *directed.entry((x, y)).or_default() += 1;
                    }
                }
                let exact = polygon_area(p);
                prop_assert!(((area - exact) / exact).abs() < 1e-9, "{} vs {}", area, exact);
                let m = r.len() as u32;
                for (&(x, y), &k) in &directed {
                    prop_assert_eq!(k, 1);
                    let border = y == (x + 1) % m;
                    prop_assert_eq!(directed.contains_key(&(y, x)), !border, "edge {}→{}", x, y);
                }
                for x in 0..m {
                    prop_assert!(directed.contains_key(&(x, (x + 1) % m)));
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Convex footprints (ear-clipped) give closed prisms whose roof is the footprint and whose
        /// volume is area × height, like the triangulated ones; a hole sends the same ring
        /// through spade, with the same roof area less the hole.
        #[test]
        fn convex_footprints_extrude_into_closed_prisms(
            n in 3usize..24, seed in any::<u64>(),
            off in prop_oneof![Just(0.0), Just(1.0e7)],
            h in 1.0f64..200.0,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut angles: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect();
            angles.sort_by(f64::total_cmp);
            angles.dedup_by(|a, b| (*a - *b).abs() < 1e-3);
            prop_assume!(angles.len() >= 3);
            let mut ring: Vec<(f64, f64)> = angles.iter().map(|a| (off + 30.0 * a.cos(), off + 20.0 * a.sin())).collect();
            ring.push(ring[0]);
            let p = Polygon::new(LineString::from(ring), vec![]);
            let frame = LocalFrame { origin: DVec3::new(off + 2.0, off - 1.0, 0.0) };
            let local: Vec<DVec2> = open_ring(&p.exterior().0).iter().map(|&c| frame.to_local_xy(c)).collect();
            let (mut cap, mut links) = (Vec::new(), Vec::new());
            prop_assert!(ear_clip(&local, &mut cap, &mut links));
            let m = try_extrude_building(&building(p.clone(), h, 0.0), &frame).unwrap();
            prop_assert!(check_closed(&m).is_ok(), "{:?}", check_closed(&m));
            let area = rounded_area(&p, &frame);
            prop_assert!(((roof_area(&m) - area) / area).abs() < 1e-9);
            let v = signed_volume(&m);
            let expect = area * (h as f32 as f64);
            prop_assert!(((v - expect) / expect).abs() < 1e-6, "{} vs {}", v, expect);
            // n − 2 roof triangles.
            let roof = m.indices.chunks_exact(3).filter(|t| m.normals[t[0] as usize].z > 0.5).count();
            prop_assert_eq!(roof, local.len() - 2);
            // The same exterior with a small hole goes through the triangulation.
            let hole = LineString::from(vec![(off - 1.0, off - 1.0), (off - 1.0, off + 1.0), (off + 1.0, off + 1.0), (off + 1.0, off - 1.0), (off - 1.0, off - 1.0)]);
            // (only when the hole lies inside: a thin triangle may not hold it)
            {
                use geo::Contains;
                prop_assume!(p.contains(&hole));
            }
            let ph = Polygon::new(p.exterior().clone(), vec![hole]);
            let mh = try_extrude_building(&building(ph.clone(), h, 0.0), &frame).unwrap();
            prop_assert!(check_closed(&mh).is_ok());
            let area_h = rounded_area(&ph, &frame);
            prop_assert!(((roof_area(&mh) - area_h) / area_h).abs() < 1e-9);
        }
    }

    #[test]
    fn comb_footprint_triangles_match_the_centroid_test() {
        // A comb: 200 teeth, deep notches, many collinear vertices along the spine.
        let mut pts = vec![(0.0, 0.0)];
        for k in 0..200 {
            let x = 2.0 * k as f64;
            pts.extend([
                (x + 0.5, 0.0),
                (x + 0.5, -30.0),
                (x + 1.5, -30.0),
                (x + 1.5, 0.0),
            ]);
        }
        pts.extend([(400.0, 0.0), (400.0, 10.0), (0.0, 10.0), (0.0, 0.0)]);
        pts.dedup();
        let p = Polygon::new(LineString::from(pts), vec![square(100.0, 2.0, 5.0, false)]);
        let rep = repair_polygon(&p).unwrap();
        assert_eq!(rep.polygons.len(), 1);
        let cdt = cdt_of(&rep.polygons[0]);
        let flood = cap_triangles(&cdt);
        assert_eq!(flood, cap_triangles_by_centroid(&cdt, &rep.polygons[0]));
        // V + 2H − 2 triangles: the comb's vertices plus the hole's.
        let v = cdt.num_vertices();
        assert_eq!(flood.len(), v + 2 - 2);
        let m = try_extrude_building(
            &building(rep.polygons[0].clone(), 5.0, 0.0),
            &LocalFrame {
                origin: DVec3::ZERO,
            },
        )
        .unwrap();
        check_closed(&m).unwrap();
        assert!((roof_area(&m) - polygon_area(&rep.polygons[0])).abs() < 1e-6);
    }
}
