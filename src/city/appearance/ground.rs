//! The ground: the ground plane and the blocks' and streets' ground mesh.

use geo::TriangulateEarcut;
use geo_types::{Coord, Polygon};
use glam::{DVec3, Vec3};

use crate::city::mesh::Mesh;
use crate::city::model::{LocalFrame, Street};

use super::*;

/// The ground plane: a square of half side `half_m` metres at z = 0 around the local origin
/// (two triangles facing up, style [`GROUND`]). Both renderers draw it first.
pub fn ground_plane(half_m: f32) -> Mesh {
    let g = half_m;
    let c = unit_rgb(GROUND);
    Mesh {
        positions: vec![
            Vec3::new(-g, -g, 0.0),
            Vec3::new(g, -g, 0.0),
            Vec3::new(g, g, 0.0),
            Vec3::new(-g, g, 0.0),
        ],
        normals: vec![Vec3::Z; 4],
        indices: vec![0, 1, 2, 0, 2, 3],
        appearance: vec![crate::city::mesh::VertexAppearance::default(); 4],
        styles: vec![BuildingStyle::flat(c, c)],
    }
}

/// Half side (m) of the ground plane the renderers draw (a 40 km square).
pub const GROUND_PLANE_HALF_M: f32 = 20_000.0;

/// Sides of the polygon that fills a street's joints (a regular polygon of the street's width).
pub(super) const JOINT_SIDES: usize = 8;

/// A street as the ground lays it: style, half width, local points, and which vertices need an
/// octagon.
type LaidStreet = (u32, f64, Vec<(f64, f64)>, Vec<bool>);

/// True when a street goes straight on at `b` (from `a` to `c`, exactly collinear and forward)
/// with both segments at least `half` long: the octagon of radius `half` at `b` then lies inside
/// the two segments' quads.
fn straight_on(a: (f64, f64), b: (f64, f64), c: (f64, f64), half: f64) -> bool {
    let (ux, uy) = (b.0 - a.0, b.1 - a.1);
    let (vx, vy) = (c.0 - b.0, c.1 - b.1);
    ux * vy - uy * vx == 0.0
        && ux * vx + uy * vy > 0.0
        && ux.hypot(uy) >= half
        && vx.hypot(vy) >= half
}

/// The ground layers as one mesh at z = 0 in `frame` (normals +z, each surface its own flat
/// [`BuildingStyle`], whose `roof` is the surface colour): first each polygon of `blocks` in
/// [`BLOCK_GROUND`], then every street not below ground ([`street_below_ground`]) as a strip of
/// [`street_width_m`] in [`street_color`]: one quad per segment and a regular octagon at every
/// vertex so that joints have no gaps. Triangles are in drawing order: draw them in order with
/// the depth test always passing (later over earlier) and before the buildings.
///
/// Octagons that draw nothing new are left out, so that the picture is the same with fewer
/// triangles (a city's street graph meets three or four streets at most junctions, each ending
/// there with its own octagon; on the 80,000-building generated city the octagons were 9 in 10
/// of the ground's triangles):
/// - of identical octagons (same centre, width and colour), only the last one drawn: it paints
///   over every pixel the earlier ones painted, in the same colour;
/// - none at an inner vertex where the street goes straight on and both segments are at least
///   half its width long: the two quads drawn just before it already hold the octagon.
pub fn ground_mesh(frame: &LocalFrame, streets: &[Street], blocks: &[Polygon<f64>]) -> Mesh {
    ground_mesh_with(frame, streets, blocks, true)
}

/// [`ground_mesh`], with every octagon when `prune` is false (the reference its tests compare
/// against).
pub(super) fn ground_mesh_with(
    frame: &LocalFrame,
    streets: &[Street],
    blocks: &[Polygon<f64>],
    prune: bool,
) -> Mesh {
    let mut m = Mesh::default();
    let local = |c: Coord<f64>| -> (f64, f64) { (c.x - frame.origin.x, c.y - frame.origin.y) };
    let push_vertex = |m: &mut Mesh, x: f64, y: f64, style: u32| {
        m.positions.push(DVec3::new(x, y, 0.0).as_vec3());
        m.normals.push(Vec3::Z);
        m.appearance
            .push(crate::city::mesh::VertexAppearance { u_m: 0.0, style });
    };
    if !blocks.is_empty() {
        let style = m.styles.len() as u32;
        let c = unit_rgb(BLOCK_GROUND);
        m.styles.push(BuildingStyle::flat(c, c));
        for p in blocks {
            let raw = p.earcut_triangles_raw();
            let base = m.positions.len() as u32;
            for v in &raw.vertices {
                let (x, y) = local(Coord { x: v[0], y: v[1] });
                push_vertex(&mut m, x, y, style);
            }
            for t in raw.triangle_indices.chunks_exact(3) {
                // Counter-clockwise seen from above (normal +z).
                let p = |i: usize| {
                    let v = raw.vertices[t[i]];
                    (v[0], v[1])
                };
                let (a, b, c) = (p(0), p(1), p(2));
                let ccw = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
                let t: [u32; 3] = [t[0] as u32, t[1] as u32, t[2] as u32];
                if ccw >= 0.0 {
                    m.indices.extend([base + t[0], base + t[1], base + t[2]]);
                } else {
                    m.indices.extend([base + t[0], base + t[2], base + t[1]]);
                }
            }
        }
    }
    let mut class_style = [None::<u32>; 5];
    let mut laid: Vec<LaidStreet> = Vec::new();
    for s in streets {
        if street_below_ground(s) {
            continue;
        }
        let class = StreetClass::from_attributes(&s.attributes);
        let style = *class_style[class as usize].get_or_insert_with(|| {
            m.styles.push(BuildingStyle::flat(
                street_color(class),
                street_color(class),
            ));
            m.styles.len() as u32 - 1
        });
        let half = 0.5 * street_width_m(&s.attributes);
        let pts: Vec<(f64, f64)> = s.line.0.iter().map(|c| local(*c)).collect();
        let n = pts.len();
        let joints = (0..n)
            .map(|i| {
                n >= 2
                    && !(prune
                        && i > 0
                        && i + 1 < n
                        && straight_on(pts[i - 1], pts[i], pts[i + 1], half))
            })
            .collect();
        laid.push((style, half, pts, joints));
    }
    // The last occurrence of each octagon (centre, half width, colour) in drawing order.
    let key = |style: u32, half: f64, p: (f64, f64)| {
        (style, half.to_bits(), p.0.to_bits(), p.1.to_bits())
    };
    let mut last = std::collections::HashMap::new();
    for (si, (style, half, pts, joints)) in laid.iter().enumerate() {
        for (vi, p) in pts.iter().enumerate() {
            if joints[vi] {
                last.insert(key(*style, *half, *p), (si, vi));
            }
        }
    }
    for (si, (style, half, pts, joints)) in laid.iter().enumerate() {
        let (style, half) = (*style, *half);
        for w in pts.windows(2) {
            let ((ax, ay), (bx, by)) = (w[0], w[1]);
            let len = (bx - ax).hypot(by - ay);
            if len <= 0.0 || !len.is_finite() {
                continue;
            }
            // Left normal × half width.
            let (nx, ny) = (-(by - ay) / len * half, (bx - ax) / len * half);
            let base = m.positions.len() as u32;
            for (x, y) in [
                (ax - nx, ay - ny),
                (bx - nx, by - ny),
                (bx + nx, by + ny),
                (ax + nx, ay + ny),
            ] {
                push_vertex(&mut m, x, y, style);
            }
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        // Joints (and rounded ends).
        for (vi, &(cx, cy)) in pts.iter().enumerate() {
            if !joints[vi] || (prune && last.get(&key(style, half, (cx, cy))) != Some(&(si, vi))) {
                continue;
            }
            let base = m.positions.len() as u32;
            push_vertex(&mut m, cx, cy, style);
            for k in 0..JOINT_SIDES {
                let a = std::f64::consts::TAU * k as f64 / JOINT_SIDES as f64;
                push_vertex(&mut m, cx + half * a.cos(), cy + half * a.sin(), style);
            }
            for k in 0..JOINT_SIDES as u32 {
                let next = (k + 1) % JOINT_SIDES as u32;
                m.indices.extend([base, base + 1 + k, base + 1 + next]);
            }
        }
    }
    m
}
