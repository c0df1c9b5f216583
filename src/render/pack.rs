//! The CPU side of the mesh renderer: every unit's meshes packed into one vertex buffer, one
//! index buffer (absolute indices) and one style table, with where each unit and the ground lie
//! in the index buffer. [`super::mesh::MeshRenderer`] uploads what [`pack_meshes`] returns as
//! it is; nothing here needs a GPU.

use super::RenderError;
use crate::blocks::BlockId;
use crate::city::appearance::{self, BuildingStyle};
use crate::city::Mesh;
use bytemuck::{Pod, Zeroable};

/// Unit id of the ground's vertices (never a block id).
pub(crate) const GROUND: u32 = 0x00FF_FFFF;
/// Unit id of the terrain's vertices ([`crate::visibility::TERRAIN_ID`], just below the
/// ground's; never a block id when a terrain is drawn, which `MeshRenderer::with_terrain`
/// checks): the id pass writes it like a block's, the lit pass colours those vertices as
/// terrain.
pub(crate) const TERRAIN: u32 = crate::visibility::TERRAIN_ID;
const _: () = assert!(TERRAIN < GROUND);

/// One vertex as the shader reads it (36 bytes): position and normal (local frame), the
/// along-wall coordinate `u` (m), the index of its style in the style table and its unit's id
/// (what the id pass writes; per vertex, so that one call may draw many units).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub(crate) struct Vertex {
    pub(crate) position: [f32; 3],
    pub(crate) normal: [f32; 3],
    pub(crate) u_m: f32,
    pub(crate) style: u32,
    pub(crate) unit: u32,
}

/// [`BuildingStyle`] as `mesh.wgsl`'s `Style` (storage buffer, 64 bytes): the values exactly as
/// computed on the CPU, so the shader's arithmetic starts from the same f32s.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuStyle {
    /// rgb facade, w window_half.
    facade: [f32; 4],
    /// rgb window, w inv_storey_m.
    window: [f32; 4],
    /// rgb roof, w inv_bay_m.
    roof: [f32; 4],
    /// x levels, y the bits of ground_z.
    levels: [u32; 4],
}

impl From<&BuildingStyle> for GpuStyle {
    fn from(s: &BuildingStyle) -> Self {
        let c = |rgb: [f32; 3], w: f32| [rgb[0], rgb[1], rgb[2], w];
        GpuStyle {
            facade: c(s.facade, s.window_half),
            window: c(s.window, s.inv_storey_m),
            roof: c(s.roof, s.inv_bay_m),
            levels: [s.levels, s.ground_z.to_bits(), 0, 0],
        }
    }
}

/// Where one unit lives in the index buffer (indices are absolute).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct BlockRange {
    pub(crate) first_index: u32,
    pub(crate) index_count: u32,
}

/// The buffers' contents, ready to upload.
#[derive(Clone, Debug, Default)]
pub(crate) struct PackedMeshes {
    /// Every vertex: the ground plane's, the ground layers', then the units' in layout order.
    pub(crate) vertices: Vec<Vertex>,
    /// Every triangle's indices into `vertices`.
    pub(crate) indices: Vec<u32>,
    /// The style table; style 0 is the default, for meshes without appearance.
    pub(crate) styles: Vec<GpuStyle>,
    /// Each unit's range, indexed by `BlockId.0`.
    pub(crate) ranges: Vec<Option<BlockRange>>,
    /// The ground plane's triangles (first in the buffer).
    pub(crate) plane: BlockRange,
    /// The ground layers' triangles, in drawing order (after the plane).
    pub(crate) ground: BlockRange,
}

/// Packs the units' meshes and the ground: first the ground plane (a square of
/// [`appearance::GROUND_PLANE_HALF_M`] around the local origin at z = 0), then `ground_layers`
/// (both with the ground's id), then the units, grouped by unit in the order of each unit's
/// first appearance in `blocks` and in input order within a unit.
///
/// # Errors
/// A mesh that is malformed ([`push_mesh`]), a unit id that is not below the ground's id, or
/// more vertices or indices than `u32` counts.
pub(crate) fn pack_meshes(
    blocks: &[(BlockId, &Mesh)],
    ground_layers: &Mesh,
) -> Result<PackedMeshes, RenderError> {
    // Group meshes by block, the blocks in the order of their first appearance, keeping
    // the input order within a block.
    let mut first_seen: std::collections::HashMap<BlockId, usize> =
        std::collections::HashMap::with_capacity(blocks.len());
    for (i, (id, _)) in blocks.iter().enumerate() {
        first_seen.entry(*id).or_insert(i);
    }
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    order.sort_by_key(|&i| first_seen[&blocks[i].0]);
    let mut vertices: Vec<Vertex> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    // Style 0: the default, for meshes without appearance.
    let mut styles: Vec<GpuStyle> = vec![GpuStyle::from(&BuildingStyle::default())];
    // The ground comes first: the plane (a 40 km square at z = 0 around the local origin),
    // then the ground layers, in drawing order. The ground's own meshes report the
    // ground's id.
    let plane_mesh = appearance::ground_plane(appearance::GROUND_PLANE_HALF_M);
    push_mesh(
        &mut vertices,
        &mut indices,
        &mut styles,
        &plane_mesh,
        BlockId(GROUND),
    )?;
    let plane = BlockRange {
        first_index: 0,
        index_count: indices.len() as u32,
    };
    push_mesh(
        &mut vertices,
        &mut indices,
        &mut styles,
        ground_layers,
        BlockId(GROUND),
    )?;
    let ground = BlockRange {
        first_index: plane.index_count,
        index_count: indices.len() as u32 - plane.index_count,
    };
    let max_id = blocks.iter().map(|b| b.0 .0).max();
    if max_id.is_some_and(|m| m >= GROUND) {
        return Err(RenderError::BlockIdTooLarge {
            id: max_id.unwrap_or(0),
            limit: GROUND - 1,
        });
    }
    let mut ranges: Vec<Option<BlockRange>> = vec![None; max_id.map_or(0, |m| m as usize + 1)];
    let mut i = 0;
    while i < order.len() {
        let id = blocks[order[i]].0;
        let first_index = indices.len();
        while i < order.len() && blocks[order[i]].0 == id {
            let mesh = blocks[order[i]].1;
            push_mesh(&mut vertices, &mut indices, &mut styles, mesh, id)?;
            i += 1;
        }
        let too_many = || RenderError::TooManyVertices {
            block: id,
            vertices: vertices.len(),
        };
        ranges[id.0 as usize] = Some(BlockRange {
            first_index: u32::try_from(first_index).map_err(|_| too_many())?,
            index_count: u32::try_from(indices.len() - first_index).map_err(|_| too_many())?,
        });
    }
    Ok(PackedMeshes {
        vertices,
        indices,
        styles,
        ranges,
        plane,
        ground,
    })
}

/// A terrain packed for upload: vertices, indices (absolute) and each tile's range.
pub(crate) type PackedTerrain = (Vec<Vertex>, Vec<u32>, Vec<BlockRange>);

/// The terrain's tiles packed into one vertex and one index buffer (indices absolute), and each
/// tile's range of indices (indexed by tile). Every vertex carries the terrain's id and style 0
/// (terrain is coloured by its id, not by a style; any appearance is ignored).
///
/// # Errors
/// A malformed tile ([`push_mesh`]'s checks, naming the terrain), or more vertices or indices
/// than `u32` counts.
pub(crate) fn pack_terrain(tiles: &[Mesh]) -> Result<PackedTerrain, RenderError> {
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let mut scratch = Vec::new();
    let mut ranges = Vec::with_capacity(tiles.len());
    for tile in tiles {
        let first = indices.len();
        let bare = Mesh {
            positions: tile.positions.clone(),
            normals: tile.normals.clone(),
            indices: tile.indices.clone(),
            ..Mesh::default()
        };
        push_mesh(
            &mut vertices,
            &mut indices,
            &mut scratch,
            &bare,
            BlockId(TERRAIN),
        )?;
        let too_many = || RenderError::TooManyVertices {
            block: BlockId(TERRAIN),
            vertices: vertices.len(),
        };
        ranges.push(BlockRange {
            first_index: u32::try_from(first).map_err(|_| too_many())?,
            index_count: u32::try_from(indices.len() - first).map_err(|_| too_many())?,
        });
    }
    Ok((vertices, indices, ranges))
}

/// Appends `mesh` to the shared buffers (indices absolute), its styles to the style table (a
/// mesh without appearance gets style 0, the default); its vertices carry `block`'s id.
fn push_mesh(
    vertices: &mut Vec<Vertex>,
    indices: &mut Vec<u32>,
    styles: &mut Vec<GpuStyle>,
    mesh: &Mesh,
    block: BlockId,
) -> Result<(), RenderError> {
    if mesh.positions.len() != mesh.normals.len() || !mesh.indices.len().is_multiple_of(3) {
        return Err(RenderError::BadMesh {
            block,
            positions: mesh.positions.len(),
            normals: mesh.normals.len(),
            indices: mesh.indices.len(),
        });
    }
    if !mesh.appearance.is_empty() && mesh.appearance.len() != mesh.positions.len() {
        return Err(RenderError::BadAppearance {
            block,
            positions: mesh.positions.len(),
            appearance: mesh.appearance.len(),
        });
    }
    if let Some(bad) = mesh
        .appearance
        .iter()
        .find(|a| a.style as usize >= mesh.styles.len())
    {
        return Err(RenderError::StyleOutOfRange {
            block,
            style: bad.style,
            styles: mesh.styles.len(),
        });
    }
    if let Some(&bad) = mesh
        .indices
        .iter()
        .find(|&&k| k as usize >= mesh.positions.len())
    {
        return Err(RenderError::IndexOutOfRange {
            block,
            index: bad,
            vertices: mesh.positions.len(),
        });
    }
    let offset = u32::try_from(vertices.len() + mesh.positions.len())
        .map(|_| vertices.len() as u32)
        .map_err(|_| RenderError::TooManyVertices {
            block,
            vertices: vertices.len() + mesh.positions.len(),
        })?;
    let style0 = styles.len() as u32;
    styles.extend(mesh.styles.iter().map(GpuStyle::from));
    vertices.extend(
        mesh.positions
            .iter()
            .zip(&mesh.normals)
            .enumerate()
            .map(|(i, (p, n))| {
                let (u_m, style) = mesh
                    .appearance
                    .get(i)
                    .map_or((0.0, 0), |a| (a.u_m, style0 + a.style));
                Vertex {
                    position: p.to_array(),
                    normal: n.to_array(),
                    u_m,
                    style,
                    unit: block.0,
                }
            }),
    );
    indices.extend(mesh.indices.iter().map(|k| k + offset));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::VertexAppearance;
    use glam::Vec3;

    fn triangle(z: f32, styled: bool) -> Mesh {
        Mesh {
            positions: vec![Vec3::new(0.0, 0.0, z), Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            indices: vec![0, 1, 2],
            appearance: if styled {
                vec![VertexAppearance { u_m: 2.5, style: 0 }; 3]
            } else {
                Vec::new()
            },
            styles: if styled {
                vec![BuildingStyle::default()]
            } else {
                Vec::new()
            },
        }
    }

    #[test]
    fn units_are_grouped_after_the_ground_with_absolute_indices() {
        let (a, b, c) = (
            triangle(1.0, false),
            triangle(2.0, true),
            triangle(3.0, false),
        );
        // Unit 3 first, then unit 1, then unit 3 again: unit 3's two meshes come together.
        let blocks = [(BlockId(3), &a), (BlockId(1), &b), (BlockId(3), &c)];
        let p = pack_meshes(&blocks, &triangle(0.0, false)).unwrap();
        let plane = appearance::ground_plane(appearance::GROUND_PLANE_HALF_M);
        let (pv, pi) = (plane.positions.len(), plane.indices.len() as u32);
        assert_eq!(
            p.plane,
            BlockRange {
                first_index: 0,
                index_count: pi
            }
        );
        assert_eq!(
            p.ground,
            BlockRange {
                first_index: pi,
                index_count: 3
            }
        );
        assert_eq!(p.vertices.len(), pv + 3 * 4);
        assert_eq!(p.indices.len() as u32, pi + 3 * 4);
        assert_eq!(p.ranges.len(), 4);
        assert_eq!(p.ranges[0], None);
        assert_eq!(p.ranges[2], None);
        assert_eq!(
            p.ranges[3],
            Some(BlockRange {
                first_index: pi + 3,
                index_count: 6
            })
        );
        assert_eq!(
            p.ranges[1],
            Some(BlockRange {
                first_index: pi + 9,
                index_count: 3
            })
        );
        // Indices are absolute: unit 3's second mesh follows its first.
        let first = pv as u32 + 3;
        let r3 = (pi + 3) as usize;
        assert_eq!(
            &p.indices[r3..r3 + 6],
            &[first, first + 1, first + 2, first + 3, first + 4, first + 5]
        );
        // Every vertex carries its unit; the styled mesh's style is its own table entry.
        assert!(p.vertices[..pv + 3].iter().all(|v| v.unit == GROUND));
        assert_eq!(p.vertices[pv + 3].unit, 3);
        assert_eq!(p.vertices[pv + 3].position, [0.0, 0.0, 1.0]);
        let v1 = p.vertices[pv + 9];
        assert_eq!((v1.unit, v1.u_m, v1.position[2]), (1, 2.5, 2.0));
        assert_eq!(v1.style as usize, p.styles.len() - 1);
        assert_eq!(p.vertices[pv + 3].style, 0);
    }

    #[test]
    fn terrain_tiles_are_packed_back_to_back_with_the_terrain_id() {
        let (a, b) = (triangle(1.0, true), triangle(2.0, false));
        let (v, i, r) = pack_terrain(&[a, Mesh::default(), b]).unwrap();
        assert_eq!(v.len(), 6);
        assert_eq!(i, vec![0, 1, 2, 3, 4, 5]);
        let range = |first_index, index_count| BlockRange {
            first_index,
            index_count,
        };
        assert_eq!(r, vec![range(0, 3), range(3, 0), range(3, 3)]);
        assert!(v.iter().all(|v| v.unit == TERRAIN && v.style == 0));
        assert_eq!(v[3].position, [0.0, 0.0, 2.0]);
        let bad = Mesh {
            indices: vec![0, 1, 7],
            ..triangle(0.0, false)
        };
        assert!(matches!(
            pack_terrain(&[bad]),
            Err(RenderError::IndexOutOfRange { .. })
        ));
    }

    #[test]
    fn ids_at_the_ground_id_are_refused() {
        let a = triangle(1.0, false);
        assert!(matches!(
            pack_meshes(&[(BlockId(GROUND), &a)], &Mesh::default()),
            Err(RenderError::BlockIdTooLarge { .. })
        ));
    }
}
