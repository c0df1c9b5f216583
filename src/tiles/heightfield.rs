//! The coarse mesh of an inner tile: a BlockMap's height field as prisms (Cignoni et al., §3: the map
//! is a height field of texel columns), their tops and their exposed walls, merged where flat.
//!
//! Tops of equal height code and colour are merged greedily into rectangles (runs along a row,
//! then rows of equal runs); walls between a texel and a lower neighbour (or the ground) are
//! merged into runs along their line with equal top, bottom and colour. Roof colours are the
//! map's roof section (times its ambient occlusion), wall colours the map's wall column at
//! mid-height (Di Benedetto, §4.2.1), or the roof colour darkened for a texel without a column. The
//! mesh is closed against the ground plane only (no floor), like the extruded prisms seen from
//! above.
//!
//! The mesh is the map's own geometry, the texel prisms that the reference caster intersects
//! (Di Benedetto, §4.2.2) and that the error measure compares with the buildings (`blockmap::error`),
//! so the map's declared ε bounds its distance to the buildings: the tile's `geometricError`.
//! Only the roof normals (sloped roofs) are not carried: tops are drawn flat.

use crate::blockmap::BlockMap;
use crate::city::export::TileMesh;
use glam::Vec3;

/// sRGB-encoded byte → linear `[0, 1]` (IEC 61966-2-1), as glTF's `COLOR_0` is linear.
pub(crate) fn srgb_to_linear(b: u8) -> f32 {
    let c = b as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear(rgb: [u8; 3]) -> [f32; 3] {
    rgb.map(srgb_to_linear)
}

/// Pushes the quad `p0 p1 p2 p3` (counter-clockwise seen from outside) with one normal and
/// colour.
fn quad(m: &mut TileMesh, p: [Vec3; 4], n: Vec3, c: [f32; 3]) {
    let base = m.positions.len() as u32;
    for q in p {
        m.positions.push(q);
        m.normals.push(n);
        m.colors.push(c);
    }
    m.indices
        .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
}

/// Roof colour of texel `(i, j)`: the roof section times its AO.
fn roof_rgb(map: &BlockMap, i: u32, j: u32) -> [u8; 3] {
    let t = map.texel(map.k() + i, j);
    let ao = t[3] as u32;
    [0, 1, 2].map(|c| ((t[c] as u32 * ao + 127) / 255) as u8)
}

/// Wall colour of texel `(i, j)`: its wall column at mid-height, else the roof darkened.
fn wall_rgb(map: &BlockMap, i: u32, j: u32) -> [u8; 3] {
    match map.wall_offset(i, j) {
        0 => roof_rgb(map, i, j).map(|c| (c as u32 * 3 / 4) as u8),
        c => {
            let t = map.texel(map.wall_u(c), map.wall_color_row(j, 0.5));
            [t[0], t[1], t[2]]
        }
    }
}

/// The coarse mesh of `map` in the local frame (see the module documentation). An empty map
/// gives an empty mesh.
pub fn heightfield_mesh(map: &BlockMap) -> TileMesh {
    let k = map.k();
    let s = map.texel_m();
    let [x0, y0, _] = map.meta.min;
    let ground = map.meta.zmin;
    let x = |i: u32| (x0 + i as f64 * s) as f32;
    let y = |j: u32| (y0 + j as f64 * s) as f32;
    let mut m = TileMesh::default();

    // Tops: greedy rectangles of equal (code, colour).
    let key = |i: u32, j: u32| (map.height_code(i, j), roof_rgb(map, i, j));
    let mut used = vec![false; (k * k) as usize];
    for j in 0..k {
        for i in 0..k {
            if used[(j * k + i) as usize] || map.height_code(i, j) == 0 {
                continue;
            }
            let kk = key(i, j);
            let mut w = 1;
            while i + w < k && !used[(j * k + i + w) as usize] && key(i + w, j) == kk {
                w += 1;
            }
            let mut h = 1;
            'rows: while j + h < k {
                for q in i..i + w {
                    if used[((j + h) * k + q) as usize] || key(q, j + h) != kk {
                        break 'rows;
                    }
                }
                h += 1;
            }
            for r in j..j + h {
                for q in i..i + w {
                    used[(r * k + q) as usize] = true;
                }
            }
            let z = map.code_height_m(kk.0) as f32;
            quad(
                &mut m,
                [
                    Vec3::new(x(i), y(j), z),
                    Vec3::new(x(i + w), y(j), z),
                    Vec3::new(x(i + w), y(j + h), z),
                    Vec3::new(x(i), y(j + h), z),
                ],
                Vec3::Z,
                linear(kk.1),
            );
        }
    }

    // Walls: per direction, runs along the wall's line of equal (top, bottom, colour).
    let code_below = |i: i64, j: i64| -> u8 {
        if i < 0 || j < 0 || i >= k as i64 || j >= k as i64 {
            0
        } else {
            map.height_code(i as u32, j as u32)
        }
    };
    let z_of = |c: u8| if c == 0 { ground } else { map.code_height_m(c) } as f32;
    // (dx, dy, outward normal)
    let dirs: [(i64, i64, Vec3); 4] = [
        (1, 0, Vec3::X),
        (-1, 0, Vec3::NEG_X),
        (0, 1, Vec3::Y),
        (0, -1, Vec3::NEG_Y),
    ];
    for (dx, dy, n) in dirs {
        for line in 0..k {
            let mut along = 0;
            while along < k {
                let (i, j) = if dx != 0 {
                    (line, along)
                } else {
                    (along, line)
                };
                let top = map.height_code(i, j);
                let below = code_below(i as i64 + dx, j as i64 + dy);
                if top == 0 || below >= top {
                    along += 1;
                    continue;
                }
                let kk = (top, below, wall_rgb(map, i, j));
                let mut len = 1;
                while along + len < k {
                    let (i2, j2) = if dx != 0 {
                        (line, along + len)
                    } else {
                        (along + len, line)
                    };
                    let k2 = (
                        map.height_code(i2, j2),
                        code_below(i2 as i64 + dx, j2 as i64 + dy),
                        wall_rgb(map, i2, j2),
                    );
                    if k2 != kk {
                        break;
                    }
                    len += 1;
                }
                let (lo, hi) = (z_of(below), z_of(top));
                // The wall's edge a → b, left to right seen from outside.
                let (a, b) = match (dx, dy) {
                    (1, _) => ((x(i + 1), y(j)), (x(i + 1), y(j + len))),
                    (-1, _) => ((x(i), y(j + len)), (x(i), y(j))),
                    (_, 1) => ((x(i + len), y(j + 1)), (x(i), y(j + 1))),
                    _ => ((x(i), y(j)), (x(i + len), y(j))),
                };
                quad(
                    &mut m,
                    [
                        Vec3::new(a.0, a.1, lo),
                        Vec3::new(b.0, b.1, lo),
                        Vec3::new(b.0, b.1, hi),
                        Vec3::new(a.0, a.1, hi),
                    ],
                    n,
                    linear(kk.2),
                );
                along += len;
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn tower_map() -> BlockMap {
        let mut map = BlockMap::empty(32, DVec3::new(10.0, 20.0, 0.0), 32.0, 50.0).unwrap();
        // A 4×2 block of equal height at (3..7, 5..7) and one taller texel beside it.
        for j in 5..7 {
            for i in 3..7 {
                map.texel_mut(i, j)[0] = 100;
            }
        }
        map.texel_mut(7, 5)[0] = 200;
        map
    }

    #[test]
    fn flat_tops_merge_and_walls_face_outward() {
        let map = tower_map();
        let m = heightfield_mesh(&map);
        // Two tops (the 4×2 rectangle and the tower texel).
        let tops = m.normals.iter().filter(|n| **n == Vec3::Z).count() / 4;
        assert_eq!(tops, 2);
        // Every triangle's winding agrees with its normal, and walls sit on texel edges.
        for t in m.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|q| m.positions[t[q] as usize]);
            let n = m.normals[t[0] as usize];
            assert!((b - a).cross(c - a).normalize().dot(n) > 0.999);
        }
        // The area of the walls: the block's perimeter minus the edge shared with the tower,
        // times its height, plus the tower's walls above the ground or the block.
        let dz = 50.0 / 255.0;
        let area: f32 = m
            .indices
            .chunks(3)
            .filter(|t| m.normals[t[0] as usize].z == 0.0)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|q| m.positions[t[q] as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let block = (2.0 * (4.0 + 2.0) - 1.0) * 100.0 * dz;
        let tower = 3.0 * 200.0 * dz + 1.0 * 100.0 * dz;
        assert!(
            (area - (block + tower)).abs() < 1e-2,
            "{area} vs {}",
            block + tower
        );
    }

    #[test]
    fn empty_map_gives_an_empty_mesh() {
        let map = BlockMap::empty(32, DVec3::ZERO, 10.0, 5.0).unwrap();
        assert!(heightfield_mesh(&map).indices.is_empty());
    }
}
