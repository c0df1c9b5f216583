//! Per-block bounds for the structures: box, tight sphere, outline centre, triangle count (seed
//! 003 §4: "identify all the blocks in the town and calculate its geometric centers and bounding
//! spheres").

use super::{enclosing_sphere, BlockBounds};
use crate::blocks::BlockLayout;
use crate::city::{Building, City};
use crate::geom::{Aabb3, BoundingSphere};
use geo::Centroid;
use geo_types::{Coord, LineString, Polygon};
use glam::{DVec2, DVec3};

/// Triangles of one extruded footprint prism.
///
/// With `V` ring vertices in all (exterior and holes, closing point not counted) and `H` holes:
/// walls are one quad (2 triangles) per ring edge, `2V`; each cap (top and bottom) is a
/// triangulated polygon with holes, `V + 2H − 2` triangles; in all `2V + 2(V + 2H − 2)`.
/// Zero for a footprint with fewer than 3 exterior vertices.
pub fn extruded_triangles(footprint: &Polygon<f64>) -> u32 {
    let ext = ring_vertices(footprint.exterior());
    if ext < 3 {
        return 0;
    }
    let holes: Vec<usize> = footprint
        .interiors()
        .iter()
        .map(ring_vertices)
        .filter(|&n| n >= 3)
        .collect();
    let v = ext + holes.iter().sum::<usize>();
    let h = holes.len();
    let walls = 2 * v;
    let caps = 2 * (v + 2 * h - 2);
    u32::try_from(walls + caps).unwrap_or(u32::MAX)
}

fn ring_vertices(r: &LineString<f64>) -> usize {
    let n = r.0.len();
    if n >= 2 && r.0[0] == r.0[n - 1] {
        n - 1
    } else {
        n
    }
}

/// Bounds of every block of `layout`, in the city's local frame (f64), `result[i].id ==
/// layout.blocks[i].id`.
///
/// - `aabb`: the buildings' footprints (x, y minus the frame origin) from the lowest
///   `min_height_m` to the highest `height_m`. A block without buildings keeps its outline's box
///   at z 0..0 and zero triangles: it has nothing to draw, but it stays in the list so that ids
///   stay aligned with positions.
/// - `sphere`: the smallest sphere ([`enclosing_sphere`]) around every building's exterior
///   vertices at its own `min_height_m` and `height_m` (the extruded prisms' vertices, so it
///   holds the prisms); for a block without buildings, its box's sphere.
/// - `center`: the centroid of the block outline (local), or of its box when the outline is
///   degenerate (Pina, Serón and Cerezo, §4 assigns blocks to quadrants by this "geometric center").
/// - `triangles`: the sum of [`extruded_triangles`] over its buildings.
///
/// Building ids that are not in `city` are skipped (the layout and city disagree; blocks are
/// built from the same city in the pipeline).
pub fn block_bounds(city: &City, layout: &BlockLayout) -> Vec<BlockBounds> {
    let to_local = |c: &Coord<f64>| city.frame.to_local_xy(*c);
    layout
        .blocks
        .iter()
        .map(|block| {
            let mut aabb = Aabb3::EMPTY;
            let mut triangles = 0u32;
            let mut vertices = Vec::new();
            for bid in &block.buildings {
                let Some(b) = city.buildings.get(bid.0 as usize) else {
                    continue;
                };
                aabb = aabb.union(building_box(b, &to_local));
                triangles = triangles.saturating_add(extruded_triangles(&b.footprint));
                push_prism_vertices(b, &to_local, &mut vertices);
            }
            let outline_box = block
                .polygon
                .exterior()
                .coords()
                .map(|c| to_local(c).extend(0.0))
                .fold(Aabb3::EMPTY, Aabb3::including);
            if aabb.is_empty() {
                aabb = outline_box;
            }
            let local_outline = Polygon::new(
                block
                    .polygon
                    .exterior()
                    .coords()
                    .map(|c| {
                        let p = to_local(c);
                        Coord { x: p.x, y: p.y }
                    })
                    .collect(),
                vec![],
            );
            let center = local_outline
                .centroid()
                .map(|p| DVec2::new(p.x(), p.y()))
                .filter(|c| c.is_finite())
                .unwrap_or_else(|| {
                    let b = if outline_box.is_empty() {
                        aabb
                    } else {
                        outline_box
                    };
                    b.center().truncate()
                });
            let sphere = enclosing_sphere(&vertices)
                .map(pad_for_f32)
                .unwrap_or_else(|| BoundingSphere::from_aabb(&aabb));
            BlockBounds {
                id: block.id,
                aabb,
                sphere,
                center,
                triangles,
            }
        })
        .collect()
}

/// The meshes are drawn in f32 relative to the frame origin: a drawn vertex may lie up to half an
/// f32 ulp of its coordinate's magnitude away from its f64 position. Grow the sphere by that (a
/// whole ulp of the largest coordinate per axis, √3 over three axes, rounded up to 2) so that it
/// holds what is drawn, not only the f64 vertices.
fn pad_for_f32(s: BoundingSphere) -> BoundingSphere {
    let magnitude = s.center.abs().max_element() + s.radius;
    BoundingSphere {
        center: s.center,
        radius: s.radius + 2.0 * magnitude * f64::from(f32::EPSILON),
    }
}

/// The vertices of a building's extruded prism: its exterior ring at both heights (holes lie
/// inside the exterior, so they add nothing to a convex volume).
fn push_prism_vertices(
    b: &Building,
    to_local: &impl Fn(&Coord<f64>) -> DVec2,
    out: &mut Vec<DVec3>,
) {
    let (lo, hi) = (b.bottom_z(), b.top_z());
    for c in b.footprint.exterior().coords() {
        let p = to_local(c);
        out.push(DVec3::new(p.x, p.y, lo));
        out.push(DVec3::new(p.x, p.y, hi));
    }
}

fn building_box(b: &Building, to_local: &impl Fn(&Coord<f64>) -> DVec2) -> Aabb3 {
    let (lo, hi) = (b.bottom_z(), b.top_z());
    let mut bx = Aabb3::EMPTY;
    for c in b.footprint.exterior().coords() {
        let p = to_local(c);
        bx = bx.including(DVec3::new(p.x, p.y, lo));
    }
    if !bx.is_empty() {
        bx = bx.including(DVec3::new(bx.min.x, bx.min.y, hi));
    }
    bx
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::polygon;

    #[test]
    fn triangle_formula_square_and_square_with_hole() {
        let sq = polygon![(x: 0., y: 0.), (x: 1., y: 0.), (x: 1., y: 1.), (x: 0., y: 1.)];
        // Walls 4 × 2 = 8; caps 2 × (4 − 2) = 4.
        assert_eq!(extruded_triangles(&sq), 12);
        let holed = polygon!(
            exterior: [(x: 0., y: 0.), (x: 4., y: 0.), (x: 4., y: 4.), (x: 0., y: 4.)],
            interiors: [[(x: 1., y: 1.), (x: 1., y: 2.), (x: 2., y: 2.), (x: 2., y: 1.)]],
        );
        // V = 8, H = 1: walls 16; each cap 8 + 2 − 2 = 8 (a square annulus triangulates into
        // 8 triangles); total 32.
        assert_eq!(extruded_triangles(&holed), 32);
        let tri = polygon![(x: 0., y: 0.), (x: 1., y: 0.), (x: 0., y: 1.)];
        assert_eq!(extruded_triangles(&tri), 6 + 2);
    }
}
