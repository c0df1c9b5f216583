//! Robustness checks of the library's file readers and geometry stages against arbitrary bytes,
//! shared by the `cargo fuzz` targets (`tests/fuzz/`) and the stable tests that replay their
//! findings (`tests/fuzz_regressions.rs`). The readers of the importers crate have theirs in
//! [`blockwalk_importers::fuzzing`].
//!
//! Each `check_*` function decodes one input, runs one stage the way the pipeline runs it, and
//! asserts what that stage promises; a broken promise panics (that is what a fuzzer reports).
//! Geometry is decoded from the bytes by [`Decoder`]: either coordinates on a 12.5 cm grid within
//! ±4 km (small integers make the coincident, collinear and touching cases a fuzzer should find),
//! or raw `f64` bit patterns (NaN, infinities, 1e300, subnormals).

use std::path::Path;

use geo_types::{Coord, LineString, Polygon};
use glam::DVec3;

use crate::blocks::faces::faces;
use crate::blocks::noding::node_lines;
use crate::city::extrude::{check_closed, signed_volume, try_extrude_building, ExtrudeError};
use crate::city::{Building, BuildingId, HeightSource, LocalFrame};
use crate::geom::predicates::{
    on_segment, orient2d, polygon_area, segments_intersect, Orientation, SegmentIntersection,
};
use crate::geom::repair::{check_polygon, repair_polygon, COORD_RANGE};
use crate::geom::tolerance::MAX_WORLD_COORD_M;
use crate::jobs::{write_plan, Plan};
use crate::route::{check_frames, RouteChoice, RouteContext};

/// Reads geometry out of fuzz bytes; every read past the end gives `None`.
#[derive(Clone, Debug)]
pub struct Decoder<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Decoder<'a> {
    /// A decoder at the start of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    /// The next byte.
    pub fn byte(&mut self) -> Option<u8> {
        let b = *self.bytes.get(self.pos)?;
        self.pos += 1;
        Some(b)
    }

    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let s = self.bytes.get(self.pos..self.pos + N)?;
        self.pos += N;
        s.try_into().ok()
    }

    /// The next coordinate: two little-endian `i16` in eighths of a metre, or with `raw` two
    /// little-endian `f64` as they are.
    pub fn coord(&mut self, raw: bool) -> Option<Coord<f64>> {
        if raw {
            let x = f64::from_le_bytes(self.take::<8>()?);
            let y = f64::from_le_bytes(self.take::<8>()?);
            Some(Coord { x, y })
        } else {
            let x = i16::from_le_bytes(self.take::<2>()?);
            let y = i16::from_le_bytes(self.take::<2>()?);
            Some(Coord {
                x: f64::from(x) / 8.0,
                y: f64::from(y) / 8.0,
            })
        }
    }

    /// A ring of `n` points (fewer when the input ends).
    pub fn ring(&mut self, n: usize, raw: bool) -> Vec<Coord<f64>> {
        (0..n).map_while(|_| self.coord(raw)).collect()
    }

    /// A polygon: a header byte (bit 0: raw `f64` coordinates; bits 1–2: number of holes), then
    /// each ring as a point count byte and its points. Rings come open or closed as the bytes
    /// say.
    pub fn polygon(&mut self) -> Option<(Polygon<f64>, bool)> {
        let h = self.byte()?;
        let raw = h & 1 == 1;
        let holes = usize::from((h >> 1) & 3);
        let mut rings = Vec::new();
        for _ in 0..=holes {
            let n = usize::from(self.byte().unwrap_or(0));
            rings.push(LineString::new(self.ring(n, raw)));
        }
        let mut rings = rings.into_iter();
        let exterior = rings.next().unwrap_or_else(|| LineString::new(vec![]));
        Some((Polygon::new(exterior, rings.collect()), raw))
    }
}

/// What a geometry check saw (for the tests that replay inputs).
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// The stage produced this many things (polygons, faces, triangles, cameras).
    Made(usize),
    /// The stage refused the input, with this message.
    Refused(String),
}

/// Ring repair ([`repair_polygon`]): a polygon decoded from `data` is repaired into valid parts
/// (each passes [`check_polygon`]; never an empty list) or refused with a message. A polygon that
/// is already valid comes back as itself (at most rewound), and a repaired part repaired again
/// needs nothing.
///
/// # Panics
/// When a property breaks.
pub fn check_repair(data: &[u8]) -> Outcome {
    let Some((poly, _)) = Decoder::new(data).polygon() else {
        return Outcome::Refused("no input".into());
    };
    let valid_input = check_polygon(&poly).is_ok();
    match repair_polygon(&poly) {
        Ok(r) => {
            assert!(
                !r.polygons.is_empty(),
                "repair returned no polygon and no refusal"
            );
            for (i, p) in r.polygons.iter().enumerate() {
                if let Err(e) = check_polygon(p) {
                    panic!(
                        "repaired part {i} is not valid: {e}\n{p:?}\nactions {:?}",
                        r.actions
                    );
                }
                let again = repair_polygon(p).unwrap_or_else(|e| {
                    panic!("repaired part {i} is refused when repaired again: {e}")
                });
                assert!(
                    !again.was_repaired() && again.polygons.len() == 1,
                    "repaired part {i} needs repair again: {:?}",
                    again.actions
                );
            }
            if valid_input {
                assert!(
                    !r.was_repaired() && r.polygons.len() == 1,
                    "a valid polygon was changed: {:?}",
                    r.actions
                );
                let (a, b) = (
                    polygon_area(&poly).abs(),
                    polygon_area(&r.polygons[0]).abs(),
                );
                assert!(
                    (a - b).abs() <= 1e-9 * a.max(1.0),
                    "a valid polygon's area changed from {a} to {b}"
                );
            }
            Outcome::Made(r.polygons.len())
        }
        Err(e) => {
            assert!(!valid_input, "a valid polygon was refused: {e}");
            let msg = e.to_string();
            assert!(!msg.is_empty());
            Outcome::Refused(msg)
        }
    }
}

/// Zero, or a magnitude from the bottom of [`COORD_RANGE`] (where the exact predicates stay
/// exact) to [`MAX_WORLD_COORD_M`]: the coordinates a city's streets can have (the build checks
/// them against their CRS and refuses a vertex beyond the world's bound).
fn in_range(v: f64) -> bool {
    v == 0.0 || (COORD_RANGE.0..=MAX_WORLD_COORD_M).contains(&v.abs())
}

/// Most segments [`check_faces`] decodes (its planarity check is quadratic).
pub const FACES_MAX_SEGMENTS: usize = 96;

/// Street noding and faces ([`node_lines`], [`faces`]): lines decoded from `data` (a header byte:
/// bits 0–1 the snap tolerance 1 mm, 5 cm, 0.5 m or 3 m, bit 2 raw `f64` coordinates; then each
/// line as a point count byte and its points; points that are not finite or outside
/// [`COORD_RANGE`] at the bottom or [`MAX_WORLD_COORD_M`] at the top are dropped, as the city build refuses them)
/// are noded into a graph whose edges are distinct, ordered, of non-zero length and meet only
/// at shared nodes (checked pairwise, exactly); its faces satisfy Euler's formula on the edges
/// that bound faces (nodes − edges + bounded faces = connected pieces), every bounded face has a
/// positive area and a ring that runs along each of its edges once.
///
/// # Panics
/// When a property breaks.
pub fn check_faces(data: &[u8]) -> Outcome {
    let mut d = Decoder::new(data);
    let Some(h) = d.byte() else {
        return Outcome::Refused("no input".into());
    };
    let tol = [0.001, 0.05, 0.5, 3.0][usize::from(h & 3)];
    let raw = h & 4 != 0;
    let mut lines = Vec::new();
    let mut segments = 0;
    while let Some(n) = d.byte() {
        let n = usize::from(n % 16) + 1;
        let pts: Vec<Coord<f64>> = d
            .ring(n, raw)
            .into_iter()
            .filter(|c| in_range(c.x) && in_range(c.y))
            .collect();
        segments += pts.len().saturating_sub(1);
        if segments > FACES_MAX_SEGMENTS {
            break;
        }
        lines.push(LineString::new(pts));
    }
    let g = node_lines(&lines, tol);
    let n = g.nodes.len() as u32;
    for (i, e) in g.edges.iter().enumerate() {
        assert!(e[0] < e[1] && e[1] < n, "edge {i} {e:?} with {n} nodes");
        assert!(
            g.nodes[e[0] as usize] != g.nodes[e[1] as usize],
            "edge {i} has zero length"
        );
        if i > 0 {
            assert!(g.edges[i - 1] < *e, "edges not sorted or repeated at {i}");
        }
    }
    let at = |k: u32| g.nodes[k as usize];
    for (i, a) in g.edges.iter().enumerate() {
        for (j, b) in g.edges.iter().enumerate().skip(i + 1) {
            let shared = a.iter().filter(|k| b.contains(k)).count();
            match shared {
                0 => {
                    let x = segments_intersect(at(a[0]), at(a[1]), at(b[0]), at(b[1]));
                    assert!(
                        x == SegmentIntersection::None,
                        "edges {i} {:?} and {j} {:?} meet away from a node ({x:?}), tolerance {tol}",
                        [at(a[0]), at(a[1])],
                        [at(b[0]), at(b[1])]
                    );
                }
                1 => {
                    // Sharing one node, neither may run along the other.
                    for (p, q) in [(a, b), (b, a)] {
                        let other = if q.contains(&p[0]) { p[1] } else { p[0] };
                        let overlaps = orient2d(at(q[0]), at(q[1]), at(other))
                            == Orientation::Collinear
                            && on_segment(at(q[0]), at(q[1]), at(other));
                        assert!(!overlaps, "edges {i} and {j} overlap, tolerance {tol}");
                    }
                }
                _ => panic!("edges {i} and {j} repeat"),
            }
        }
    }
    let fs = faces(&g);
    assert_eq!(fs.left.len(), 2 * fs.core_edges.len());
    assert!(fs.left.iter().all(|&f| f < fs.faces.len()));
    // Connected pieces of the core edges, by union-find.
    let mut parent: Vec<u32> = (0..n).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    let mut used = vec![false; n as usize];
    for &[a, b] in &fs.core_edges {
        used[a as usize] = true;
        used[b as usize] = true;
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let v = used.iter().filter(|&&u| u).count();
    let pieces = (0..n)
        .filter(|&k| used[k as usize] && find(&mut parent, k) == k)
        .count();
    let bounded: Vec<usize> = fs.bounded().collect();
    assert_eq!(
        v as i64 - fs.core_edges.len() as i64 + bounded.len() as i64,
        pieces as i64,
        "Euler's formula fails: {v} nodes, {} edges, {} bounded faces, {pieces} pieces{}",
        fs.core_edges.len(),
        bounded.len(),
        if g.edges.len() <= 8 {
            format!(
                " (nodes {:?}, edges {:?}, face ring areas {:?})",
                g.nodes,
                g.edges,
                fs.faces.iter().map(|f| f.ring_area).collect::<Vec<_>>()
            )
        } else {
            String::new()
        }
    );
    for &i in &bounded {
        let f = &fs.faces[i];
        assert!(f.ring_area > 0.0);
        // A face may pass a node twice (two rings of it touching there), never an edge: the
        // edges with one face on both sides were taken out.
        let mut e: Vec<[u32; 2]> = (0..f.ring.len())
            .map(|k| {
                let (a, b) = (f.ring[k], f.ring[(k + 1) % f.ring.len()]);
                [a.min(b), a.max(b)]
            })
            .collect();
        e.sort_unstable();
        let n_edges = e.len();
        e.dedup();
        assert_eq!(e.len(), n_edges, "face {i} runs along an edge twice");
        assert!(
            fs.area(i) > 0.0,
            "face {i} has a net area {} ≤ 0",
            fs.area(i)
        );
        let _ = fs.polygon(i);
    }
    Outcome::Made(bounded.len())
}

/// Extrusion ([`try_extrude_building`]): a polygon decoded from `data` is repaired as the city
/// build does; each valid part, between heights decoded from two more bytes, extrudes to a
/// closed, outward prism ([`check_closed`]) whose volume is its area times its height (within
/// the f32 rounding of the mesh), or is refused: for heights that are not a prism, or for a
/// detail finer than f32 resolves at its distance from the local origin.
///
/// # Panics
/// When a property breaks.
pub fn check_extrude(data: &[u8]) -> Outcome {
    let mut d = Decoder::new(data);
    let Some((poly, raw)) = d.polygon() else {
        return Outcome::Refused("no input".into());
    };
    let top = f64::from(d.byte().unwrap_or(9));
    let bottom = f64::from(d.byte().unwrap_or(0) % 16);
    let parts = match repair_polygon(&poly) {
        Ok(r) => r.polygons,
        Err(e) => return Outcome::Refused(e.to_string()),
    };
    let mut triangles = 0;
    for (i, footprint) in parts.into_iter().enumerate() {
        let Some(c) = footprint.exterior().0.first().copied() else {
            panic!("repaired part {i} has no exterior");
        };
        // The local origin near the data, as the city's frame puts it.
        let frame = LocalFrame {
            origin: DVec3::new(c.x, c.y, 0.0),
        };
        let area = polygon_area(&footprint).abs();
        let b = Building {
            id: BuildingId(i as u32),
            source_id: format!("fuzz:{i}"),
            footprint,
            height_m: top,
            min_height_m: bottom,
            base_m: 0.0,
            height_source: HeightSource::Default,
            attributes: Default::default(),
        };
        match try_extrude_building(&b, &frame) {
            Ok(m) => {
                assert!(top > bottom, "heights {bottom}..{top} extruded");
                if let Err(e) = check_closed(&m) {
                    panic!("part {i}: the prism is not closed: {e}\n{:?}", b.footprint);
                }
                let vol = signed_volume(&m);
                let want = area * (top - bottom);
                // Raw coordinates may be far from a metre scale: only the sign is checked. Else
                // each vertex may move by half an f32 step at its distance from the origin,
                // which changes the area by at most that much times the perimeter.
                let far = b
                    .footprint
                    .exterior()
                    .0
                    .iter()
                    .map(|p| (p.x - c.x).abs().max((p.y - c.y).abs()))
                    .fold(0.0, f64::max);
                let step = 2.0 * far * f64::from(f32::EPSILON);
                let perimeter: f64 = std::iter::once(b.footprint.exterior())
                    .chain(b.footprint.interiors())
                    .flat_map(|r| {
                        r.0.windows(2)
                            .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
                    })
                    .sum();
                let rounding = step * perimeter * (top - bottom);
                let tol = if raw {
                    want
                } else {
                    1e-3 * want + 1e-3 + rounding
                };
                assert!(
                    vol > 0.0 && (vol - want).abs() <= tol,
                    "part {i}: volume {vol}, footprint area × height {want}\n{:?}",
                    b.footprint
                );
                triangles += m.indices.len() / 3;
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(
                    msg.contains("fuzz:"),
                    "the error does not name the building: {msg}"
                );
                // A valid footprint of modest coordinates always extrudes between good heights,
                // unless a detail of it is finer than f32 resolves.
                let below = matches!(
                    e,
                    ExtrudeError::BelowPrecision { .. }
                        | ExtrudeError::Sliver { .. }
                        | ExtrudeError::RingsBelowPrecision { .. }
                );
                assert!(
                    raw || top <= bottom || below,
                    "part {i}: a valid footprint was not extruded: {msg}\n{:?}",
                    b.footprint
                );
            }
        }
    }
    Outcome::Made(triangles)
}

/// Route files ([`crate::route::RouteFile`] through [`RouteChoice::File`], as a walk resolves them): the bytes
/// written as `route.json` when they start with `{`, else `route.toml`, are resolved against a
/// small city, or refused with an error naming the file or the route. A resolved route has a
/// frame count the walk accepts or refuses ([`check_frames`]) and finite cameras.
///
/// # Panics
/// When a property breaks or `dir` cannot be written.
pub fn check_route(dir: &Path, data: &[u8]) -> Outcome {
    let json = data.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{');
    let path = dir.join(if json { "route.json" } else { "route.toml" });
    std::fs::write(&path, data).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let frame = LocalFrame {
        origin: DVec3::new(1000.0, 2000.0, 0.0),
    };
    let ctx = RouteContext {
        city: "fuzz",
        bounds: crate::geom::Aabb3 {
            min: DVec3::new(-100.0, -100.0, 0.0),
            max: DVec3::new(100.0, 100.0, 30.0),
        },
        street_edges: &[],
        buildings: &[],
        frame: &frame,
        aspect: 16.0 / 9.0,
        terrain: None,
    };
    match RouteChoice::File(path.clone()).resolve(&ctx) {
        Ok((route, frames)) => {
            let n = match frames.map(|n| check_frames(&route.name, n)) {
                Some(Ok(n)) => n,
                Some(Err(e)) => return Outcome::Refused(e.to_string()),
                None => 30,
            };
            let cams = route.sample(n.min(64));
            for c in &cams {
                assert!(
                    c.position.is_finite() && c.yaw.is_finite() && c.pitch.is_finite(),
                    "a camera of a resolved route is not finite: {c:?}"
                );
            }
            Outcome::Made(cams.len())
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.is_empty(), "empty route error");
            Outcome::Refused(msg)
        }
    }
}

/// `plan.json` ([`Plan::read`]): the bytes as a plan are read or refused with an error naming
/// the file. A plan that is read is one the tile jobs and the merge can use: tile `i` has id
/// `i`, block `i` has id `i`, every tile's blocks exist, every number is finite; and it is
/// written back and read again unchanged.
///
/// # Panics
/// When a property breaks or `dir` cannot be written.
pub fn check_plan(dir: &Path, data: &[u8]) -> Outcome {
    let path = dir.join("plan.json");
    std::fs::write(&path, data).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    match Plan::read(&path) {
        Ok(plan) => {
            for (i, t) in plan.tiles.iter().enumerate() {
                assert_eq!(t.id, i, "tile {i} has id {}", t.id);
                for &b in &t.blocks {
                    assert!((b as usize) < plan.blocks.len(), "tile {i} names block {b}");
                }
                assert!(t.bounds.iter().all(|v| v.is_finite()));
            }
            for (i, b) in plan.blocks.iter().enumerate() {
                assert_eq!(b.id as usize, i, "block {i} has id {}", b.id);
                assert!(b.rings.iter().flatten().flatten().all(|v| v.0.is_finite()));
                assert!(b.bounds.iter().all(|v| v.is_finite()));
                let _ = b.polygon();
            }
            let o = plan.frame().origin;
            assert!(o.is_finite(), "the plan's frame origin {o} is not finite");
            let back = dir.join("again");
            let p2 = write_plan(&plan, &back).unwrap_or_else(|e| panic!("{e}"));
            let again =
                Plan::read(&p2).unwrap_or_else(|e| panic!("a plan written back is refused: {e}"));
            assert_eq!(again, plan, "a plan written back reads differently");
            Outcome::Made(plan.tiles.len())
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("plan.json"),
                "the error does not name the file: {msg}"
            );
            Outcome::Refused(msg)
        }
    }
}

/// A tile's streaming content ([`crate::jobs::pack`]): with an even first byte, a block mesh
/// record (the next four bytes its inflated length, little-endian, then the record) decoded as
/// zlib and as raw; a record that decodes is a valid mesh (every index below the positions,
/// every style reference in range) and encodes back to the same raw bytes. With an odd first
/// byte, a tile hierarchy (`tile.hier.json`): parsed with its parents before its children, or
/// refused naming the file.
pub fn check_tile(dir: &Path, data: &[u8]) -> Outcome {
    use crate::jobs::pack::{decode_record, encode_mesh, TileHierarchy};
    let Some((&kind, rest)) = data.split_first() else {
        return Outcome::Refused("empty input".into());
    };
    if kind % 2 == 0 {
        let Some((len, record)) = rest.split_first_chunk::<4>() else {
            return Outcome::Refused("no length".into());
        };
        let inflated = u64::from(u32::from_le_bytes(*len));
        let mut made = None;
        let mut why = String::new();
        for (c, n) in [(Some("zlib"), inflated), (None, record.len() as u64)] {
            match decode_record(record, c, n) {
                Ok(m) => {
                    let n = m.positions.len();
                    assert_eq!(m.normals.len(), n, "a normal per position");
                    assert!(
                        m.indices.iter().all(|&i| (i as usize) < n),
                        "an index beyond the positions"
                    );
                    assert!(m.appearance.is_empty() || m.appearance.len() == n);
                    assert!(m
                        .appearance
                        .iter()
                        .all(|a| (a.style as usize) < m.styles.len()));
                    let mut raw = Vec::new();
                    encode_mesh(&m, &mut raw);
                    let again = decode_record(&raw, None, raw.len() as u64)
                        .unwrap_or_else(|e| panic!("a record encoded back is refused: {e}"));
                    let mut raw2 = Vec::new();
                    encode_mesh(&again, &mut raw2);
                    assert_eq!(raw, raw2, "a record encoded back reads differently");
                    made = Some(m.triangle_count());
                }
                Err(e) => why = e,
            }
        }
        return made.map_or(Outcome::Refused(why), Outcome::Made);
    }
    let path = dir.join("tile.hier.json");
    match TileHierarchy::parse(rest, &path) {
        Ok(h) => {
            for (i, m) in h.maps.iter().enumerate() {
                assert!(m.parent.is_none_or(|p| p < i), "map {i} before its parent");
            }
            Outcome::Made(h.blocks.len() + h.maps.len())
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("tile.hier.json"),
                "the error does not name the file: {msg}"
            );
            Outcome::Refused(msg)
        }
    }
}
