//! Culling inside the surviving blocks: each building of a block that the structure kept is
//! tested on its own against the view frustum and the cull map (Willmott et al., §3.2.8, "for each B in
//! T: if B is within VF … if pointOccluded(OP)").
//!
//! Blocks are the unit the structures hand over; a block next to the viewer keeps all its
//! buildings, though most of them may be behind the viewer or in the shadow of the first row.
//! [`BlockBuildings::refine`] keeps, of the buildings of the given blocks, those whose box is not
//! outside the frustum and not hidden by the cull map.
//!
//! Deviation from Willmott et al., §3.2.8: the seed tests one occluder point per building (the centre of
//! its footprint at its top) and exempts the buildings of the "local model"; here a building's
//! whole box is tested with [`CullMap::box_hidden`], the same conservative test the blocks get
//! (every cell its footprint touches must hide its top), so a building that its own shadow
//! covers only partly is kept.

use super::CullMap;
use crate::blocks::BlockId;
use crate::city::{BuildingId, Mesh};
use crate::geom::{Aabb3, Containment, Frustum};
use serde::Serialize;

/// One building as the per-building test sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildingBox {
    /// The building.
    pub id: BuildingId,
    /// Box around its drawn mesh, local frame.
    pub aabb: Aabb3,
    /// Triangles of its mesh.
    pub triangles: u32,
}

impl BuildingBox {
    /// The box of a building's mesh (its f32 vertices, exactly), or `None` for an empty mesh
    /// (nothing drawn, nothing to test).
    pub fn from_mesh(id: BuildingId, mesh: &Mesh) -> Option<Self> {
        if mesh.indices.is_empty() {
            return None;
        }
        let aabb = mesh
            .positions
            .iter()
            .fold(Aabb3::EMPTY, |a, p| a.including(p.as_dvec3()));
        (!aabb.is_empty() && aabb.min.is_finite() && aabb.max.is_finite()).then_some(Self {
            id,
            aabb,
            triangles: u32::try_from(mesh.triangle_count()).unwrap_or(u32::MAX),
        })
    }
}

/// What one refinement did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct BuildingCullStats {
    /// Buildings of the surviving blocks (tested).
    pub tested: u64,
    /// Dropped: outside the frustum.
    pub outside_frustum: u64,
    /// Dropped: hidden by the cull map.
    pub hidden: u64,
    /// Kept.
    pub kept: u64,
    /// Triangles of the kept buildings.
    pub triangles_kept: u64,
    /// Triangles of the tested buildings (the blocks' triangles).
    pub triangles_tested: u64,
}

/// The buildings of every block (by block id), with their boxes.
#[derive(Clone, Debug, Default)]
pub struct BlockBuildings {
    /// `starts[b]..starts[b + 1]` is block `b`'s range in `entries`.
    starts: Vec<u32>,
    entries: Vec<BuildingBox>,
    /// Per block, the union of its buildings' boxes.
    boxes: Vec<Aabb3>,
}

impl BlockBuildings {
    /// From `blocks[i] = (block id, its buildings)`; blocks not listed have no buildings.
    pub fn new(blocks: impl IntoIterator<Item = (BlockId, Vec<BuildingBox>)>) -> Self {
        let mut per: Vec<(BlockId, Vec<BuildingBox>)> = blocks.into_iter().collect();
        per.sort_by_key(|(b, _)| *b);
        let n = per.last().map_or(0, |(b, _)| b.0 as usize + 1);
        let mut starts = Vec::with_capacity(n + 1);
        let mut entries = Vec::new();
        let mut it = per.into_iter().peekable();
        for b in 0..n as u32 {
            starts.push(entries.len() as u32);
            while let Some((id, _)) = it.peek() {
                if id.0 != b {
                    break;
                }
                if let Some((_, v)) = it.next() {
                    entries.extend(v);
                }
            }
        }
        starts.push(entries.len() as u32);
        let boxes = starts
            .windows(2)
            .map(|w| {
                entries[w[0] as usize..w[1] as usize]
                    .iter()
                    .fold(Aabb3::EMPTY, |a, b| a.union(b.aabb))
            })
            .collect();
        Self {
            starts,
            entries,
            boxes,
        }
    }

    /// The buildings of `block` (empty for an unknown block).
    pub fn of(&self, block: BlockId) -> &[BuildingBox] {
        let b = block.0 as usize;
        match (self.starts.get(b), self.starts.get(b + 1)) {
            (Some(&s), Some(&e)) => &self.entries[s as usize..e as usize],
            _ => &[],
        }
    }

    /// Number of buildings.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when there is no building.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Pushes to `out` the buildings of `blocks` whose box is not outside `frustum` and, when
    /// `map` is given (drawn for the same camera, see [`super::OcclusionCuller::build`]), not
    /// hidden by it; in the order of `blocks` (front to back when the structure gave them so).
    /// A block whose buildings lie inside the frustum skips the per-building frustum test.
    pub fn refine(
        &self,
        frustum: &Frustum,
        map: Option<&CullMap>,
        blocks: &[BlockId],
        out: &mut Vec<BuildingId>,
    ) -> BuildingCullStats {
        let mut st = BuildingCullStats::default();
        for &b in blocks {
            // A block whose buildings' box is inside the frustum needs no test per building
            // against it (and none at all without a cull map).
            let inside = self
                .boxes
                .get(b.0 as usize)
                .is_some_and(|bx| !bx.is_empty() && frustum.test_aabb(bx) == Containment::Inside);
            for bb in self.of(b) {
                st.tested += 1;
                st.triangles_tested += u64::from(bb.triangles);
                if !inside && frustum.test_aabb(&bb.aabb) == Containment::Outside {
                    st.outside_frustum += 1;
                    continue;
                }
                if map.is_some_and(|m| m.box_hidden(&bb.aabb)) {
                    st.hidden += 1;
                    continue;
                }
                st.kept += 1;
                st.triangles_kept += u64::from(bb.triangles);
                out.push(bb.id);
            }
        }
        st
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Camera;
    use glam::{DVec3, Vec3};

    fn bb(id: u32, x: f64) -> BuildingBox {
        BuildingBox {
            id: BuildingId(id),
            aabb: Aabb3::new(DVec3::new(x, 0.0, 0.0), DVec3::new(x + 10.0, 10.0, 10.0)),
            triangles: 12,
        }
    }

    #[test]
    fn blocks_keep_their_buildings_in_order() {
        let set = BlockBuildings::new(vec![
            (BlockId(2), vec![bb(5, 0.0), bb(6, 20.0)]),
            (BlockId(0), vec![bb(1, 40.0)]),
        ]);
        assert_eq!(set.len(), 3);
        assert_eq!(set.of(BlockId(0)).len(), 1);
        assert!(set.of(BlockId(1)).is_empty());
        assert_eq!(set.of(BlockId(2))[1].id, BuildingId(6));
        assert!(set.of(BlockId(9)).is_empty());
    }

    #[test]
    fn buildings_behind_the_camera_are_dropped() {
        // Camera at x = 25 looking along +x: the building at x 0..10 is behind it.
        let set = BlockBuildings::new(vec![(BlockId(0), vec![bb(0, 0.0), bb(1, 40.0)])]);
        let cam = Camera::new(DVec3::new(25.0, 5.0, 5.0), 0.0, 0.0);
        let f = cam.frustum();
        let mut out = Vec::new();
        let st = set.refine(&f, None, &[BlockId(0)], &mut out);
        assert_eq!(out, vec![BuildingId(1)]);
        assert_eq!(st.tested, 2);
        assert_eq!(st.outside_frustum, 1);
        assert_eq!(st.triangles_kept, 12);
        assert_eq!(st.triangles_tested, 24);
    }

    #[test]
    fn the_inside_shortcut_keeps_what_the_test_per_building_keeps() {
        // Blocks of ten buildings in a row; cameras all around: the kept set must be exactly
        // the buildings not outside the frustum.
        let blocks: Vec<(BlockId, Vec<BuildingBox>)> = (0..20u32)
            .map(|k| {
                let v = (0..10u32)
                    .map(|i| bb(k * 10 + i, f64::from(k) * 120.0 + f64::from(i) * 11.0))
                    .collect();
                (BlockId(k), v)
            })
            .collect();
        let set = BlockBuildings::new(blocks.clone());
        let ids: Vec<BlockId> = (0..20).map(BlockId).collect();
        let mut inside_blocks = 0;
        for step in 0..40 {
            let t = f64::from(step);
            let cam = Camera::new(
                DVec3::new(t * 60.0 - 100.0, -150.0 + t * 3.0, 5.0 + t * 10.0),
                0.3 + t * 0.15,
                -0.2 - t * 0.01,
            );
            let f = cam.frustum();
            let mut out = Vec::new();
            set.refine(&f, None, &ids, &mut out);
            let truth: Vec<BuildingId> = blocks
                .iter()
                .flat_map(|(_, v)| v.iter())
                .filter(|b| f.test_aabb(&b.aabb) != Containment::Outside)
                .map(|b| b.id)
                .collect();
            assert_eq!(out, truth, "camera {step}");
            inside_blocks += set
                .boxes
                .iter()
                .filter(|b| f.test_aabb(b) == Containment::Inside)
                .count();
        }
        assert!(inside_blocks > 0, "the shortcut was never taken");
    }

    #[test]
    fn mesh_box_is_the_vertices_box() {
        let m = Mesh {
            positions: vec![
                Vec3::new(1.0, 2.0, 0.0),
                Vec3::new(3.0, -1.0, 7.5),
                Vec3::new(2.0, 0.0, 1.0),
            ],
            normals: vec![Vec3::Z; 3],
            indices: vec![0, 1, 2],
            ..Mesh::default()
        };
        let b = BuildingBox::from_mesh(BuildingId(3), &m).unwrap();
        assert_eq!(b.aabb.min, DVec3::new(1.0, -1.0, 0.0));
        assert_eq!(b.aabb.max, DVec3::new(3.0, 2.0, 7.5));
        assert_eq!(b.triangles, 1);
        assert!(BuildingBox::from_mesh(BuildingId(0), &Mesh::default()).is_none());
    }
}
