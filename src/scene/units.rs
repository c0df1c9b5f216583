//! Draw units finer than a block: the pages of the scene-graph VAMSplit tree (seed 003 §5.1,
//! [`crate::index::SceneGraphTree`]) and single buildings (per-building culling, seed 004
//! §3.2.8, [`crate::visibility::buildings`]).
//!
//! One renderer draws every kind of unit: [`DrawUnits::meshes`] holds the blocks' meshes (ids as
//! in [`super::Scene::meshes`]), then one mesh per page at [`DrawUnits::page_id`], then one mesh
//! per building at [`DrawUnits::building_id`]. The three id ranges are disjoint.
//!
//! The order of [`DrawUnits::meshes`] is the order the renderer lays the units out in its index
//! buffer ([`crate::render::MeshRenderer`] keeps its input order): the buildings come block by
//! block (the blocks in the layout's order, each block's buildings in its own order), so the
//! buildings of a block are contiguous, and kept buildings that are neighbours in that order are
//! one range of the index buffer, drawn with one call ([`DrawUnits::draw_calls`]). A block whose
//! buildings are all kept is one call, as its block mesh is.

use crate::blocks::{BlockId, BlockLayout};
use crate::city::{BuildingId, Mesh};
use crate::index::{BlockBounds, IndexError, SceneGraphParams, SceneGraphTree};
use crate::visibility::buildings::{BlockBuildings, BuildingBox};
use glam::DVec2;

/// Whether the walk tests the buildings of the surviving blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BuildingsMode {
    /// Blocks are drawn whole.
    Off,
    /// The buildings of every surviving block are tested (frustum, and cull map with occlusion).
    On,
    /// Both, side by side, with a decision which pays.
    #[default]
    Auto,
}

crate::choice::choices!(BuildingsMode, "buildings mode",
    Off => "off", "Blocks are drawn whole";
    On => "on", "The buildings of every surviving block are tested (frustum, and cull map with occlusion)";
    Auto => "auto", "Both, side by side, with a decision which pays";
);

/// What one draw id stands for: a block, a page of the scene-graph tree, or one building. The
/// renderer takes draw ids ([`DrawUnits::id`]); everything else speaks of units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Unit {
    /// A block, drawn whole.
    Block(BlockId),
    /// A page (leaf) of the scene-graph tree, by page index.
    Page(u32),
    /// One building.
    Building(BuildingId),
}

/// Pages and buildings as draw units (see the module docs).
#[derive(Debug)]
pub struct DrawUnits {
    /// Every unit's mesh: blocks, pages, buildings.
    pub meshes: Vec<(BlockId, Mesh)>,
    /// Triangles of every unit, indexed by unit id.
    pub triangles: Vec<u64>,
    /// The first page's draw id.
    page_offset: u32,
    /// The first building's draw id.
    building_offset: u32,
    /// Per block, its buildings' boxes (per-building culling).
    pub buildings: BlockBuildings,
    /// The scene-graph tree over the buildings (the items' ids are building ids).
    pub scene_graph: SceneGraphTree,
    /// Where the page meshes start in [`DrawUnits::meshes`] (the blocks' end).
    page_start: usize,
    /// Where the building meshes start in [`DrawUnits::meshes`].
    building_start: usize,
    /// Where each unit lies in the renderer's layout of [`DrawUnits::meshes`].
    order: DrawOrder,
    /// The walk tests buildings inside blocks.
    pub mode: BuildingsMode,
}

impl DrawUnits {
    /// The units of a city split into `layout`'s blocks whose meshes are `block_meshes` (moved
    /// into the units once the scene graph is built, so that the block units draw exactly the
    /// scene's meshes without a copy; left in place when the build fails), its buildings' meshes
    /// `building_meshes` (indexed by building id, as the scene extruded them), the scene graph
    /// built with `params`.
    ///
    /// # Errors
    /// [`IndexError`] from the scene graph's build (bad parameters).
    pub fn build(
        building_meshes: &[Mesh],
        layout: &BlockLayout,
        block_meshes: &mut Vec<(BlockId, Mesh)>,
        params: &SceneGraphParams,
        mode: BuildingsMode,
    ) -> Result<Self, IndexError> {
        let per_building = building_meshes;
        let mut boxes: Vec<Option<BuildingBox>> = per_building
            .iter()
            .enumerate()
            .map(|(i, m)| BuildingBox::from_mesh(BuildingId(i as u32), m))
            .collect();
        // Only buildings that belong to a block are units (the block meshes hold only those).
        let mut in_block = vec![false; boxes.len()];
        let buildings = BlockBuildings::new(layout.blocks.iter().map(|b| {
            let v: Vec<BuildingBox> = b
                .buildings
                .iter()
                .filter_map(|id| {
                    let slot = in_block.get_mut(id.0 as usize)?;
                    *slot = true;
                    boxes.get(id.0 as usize).copied().flatten()
                })
                .collect();
            (b.id, v)
        }));
        for (b, inb) in boxes.iter_mut().zip(&in_block) {
            if !inb {
                *b = None;
            }
        }
        let items: Vec<BlockBounds> = boxes
            .iter()
            .flatten()
            .map(|b| {
                BlockBounds::from_box(
                    BlockId(b.id.0),
                    b.aabb,
                    DVec2::new(b.aabb.center().x, b.aabb.center().y),
                    b.triangles,
                )
            })
            .collect();
        let scene_graph = SceneGraphTree::build(&items, params)?;
        let page_offset = block_meshes.iter().map(|(b, _)| b.0 + 1).max().unwrap_or(0);
        let building_offset = page_offset + scene_graph.page_count() as u32;
        let mut meshes: Vec<(BlockId, Mesh)> = std::mem::take(block_meshes);
        let page_start = meshes.len();
        for p in 0..scene_graph.page_count() {
            let mut m = Mesh::default();
            for id in scene_graph.page_items(p) {
                if let Some(part) = per_building.get(id.0 as usize) {
                    m.append(part);
                }
            }
            meshes.push((BlockId(page_offset + p as u32), m));
        }
        // Buildings block by block (the layout's order, each block's buildings in its order), so
        // that a block's kept buildings that are neighbours merge into one draw (module docs).
        let building_start = meshes.len();
        for b in &layout.blocks {
            for bb in buildings.of(b.id) {
                let i = bb.id.0 as usize;
                if boxes.get(i).is_some_and(Option::is_some) {
                    if let Some(m) = per_building.get(i) {
                        meshes.push((BlockId(building_offset + i as u32), m.clone()));
                    }
                }
            }
        }
        let n = meshes
            .iter()
            .map(|(b, _)| b.0 as usize + 1)
            .max()
            .unwrap_or(0);
        let mut triangles = vec![0u64; n];
        for (b, m) in &meshes {
            triangles[b.0 as usize] = m.triangle_count() as u64;
        }
        let order = DrawOrder::new(&meshes);
        Ok(Self {
            meshes,
            triangles,
            page_offset,
            building_offset,
            buildings,
            scene_graph,
            page_start,
            building_start,
            order,
            mode,
        })
    }

    /// The draw id the renderer of [`DrawUnits::meshes`] knows `unit` by.
    pub fn id(&self, unit: Unit) -> BlockId {
        match unit {
            Unit::Block(b) => b,
            Unit::Page(p) => BlockId(self.page_offset + p),
            Unit::Building(b) => BlockId(self.building_offset + b.0),
        }
    }

    /// The unit a draw id stands for.
    pub fn unit(&self, id: BlockId) -> Unit {
        if id.0 >= self.building_offset {
            Unit::Building(BuildingId(id.0 - self.building_offset))
        } else if id.0 >= self.page_offset {
            Unit::Page(id.0 - self.page_offset)
        } else {
            Unit::Block(id)
        }
    }

    /// The draw id of page `p` (`self.id(Unit::Page(p))`).
    pub fn page_id(&self, p: BlockId) -> BlockId {
        self.id(Unit::Page(p.0))
    }

    /// The draw id of building `b` (`self.id(Unit::Building(b))`).
    pub fn building_id(&self, b: BuildingId) -> BlockId {
        self.id(Unit::Building(b))
    }

    /// The building of a draw id in the building range.
    pub fn building_of(&self, id: BlockId) -> Option<BuildingId> {
        match self.unit(id) {
            Unit::Building(b) => Some(b),
            _ => None,
        }
    }

    /// The buildings a draw id draws: a block's, a page's, or the one building.
    pub fn buildings_of<'a>(
        &'a self,
        id: BlockId,
        layout: &'a BlockLayout,
    ) -> Box<dyn Iterator<Item = BuildingId> + 'a> {
        match self.unit(id) {
            Unit::Block(b) => Box::new(
                layout
                    .blocks
                    .iter()
                    .filter(move |x| x.id == b)
                    .flat_map(|x| x.buildings.iter().copied()),
            ),
            Unit::Page(p) => Box::new(
                self.scene_graph
                    .page_items(p as usize)
                    .iter()
                    .map(|b| BuildingId(b.0)),
            ),
            Unit::Building(b) => Box::new(std::iter::once(b)),
        }
    }

    /// The blocks' meshes (the first range of [`DrawUnits::meshes`]).
    pub fn block_meshes(&self) -> &[(BlockId, Mesh)] {
        &self.meshes[..self.page_start]
    }

    /// Gives the blocks' meshes back (the units are dropped).
    pub fn into_block_meshes(mut self) -> Vec<(BlockId, Mesh)> {
        self.meshes.truncate(self.page_start);
        self.meshes
    }

    /// The buildings' meshes alone, by unit id (for a building-level oracle), block by block
    /// (see the module docs).
    pub fn building_meshes(&self) -> &[(BlockId, Mesh)] {
        &self.meshes[self.building_start..]
    }

    /// Triangles of unit `u` (0 for an unknown unit).
    pub fn unit_triangles(&self, u: BlockId) -> u64 {
        self.triangles.get(u.0 as usize).copied().unwrap_or(0)
    }

    /// The draw calls that drawing the units `ids` takes when the renderer merges neighbours
    /// ([`DrawOrder::calls`] over [`DrawUnits::meshes`]).
    pub fn draw_calls(&self, ids: &[BlockId]) -> usize {
        self.order.calls(ids)
    }
}

/// Where each unit's triangles lie when a list of meshes is laid out as the renderer lays it out
/// ([`crate::render::MeshRenderer`]: grouped by unit id, the units in the order of their first
/// appearance), to count the calls of a frame: the renderer draws each maximal run of visible
/// units that are neighbours in that layout with one call ([`crate::render::Batching::Runs`]).
#[derive(Clone, Debug, Default)]
pub struct DrawOrder {
    /// Per unit id, its first triangle and its end (empty for a unit without triangles).
    spans: Vec<(u64, u64)>,
}

impl DrawOrder {
    /// The layout of `meshes` (a unit listed several times is one group, at its first place).
    pub fn new(meshes: &[(BlockId, Mesh)]) -> Self {
        let n = meshes
            .iter()
            .map(|(b, _)| b.0 as usize + 1)
            .max()
            .unwrap_or(0);
        let mut triangles = vec![0u64; n];
        let mut first: Vec<usize> = vec![usize::MAX; n];
        for (i, (b, m)) in meshes.iter().enumerate() {
            triangles[b.0 as usize] += m.triangle_count() as u64;
            first[b.0 as usize] = first[b.0 as usize].min(i);
        }
        let mut units: Vec<usize> = (0..n).filter(|&u| first[u] != usize::MAX).collect();
        units.sort_by_key(|&u| first[u]);
        let mut spans = vec![(0, 0); n];
        let mut at = 0u64;
        for u in units {
            spans[u] = (at, at + triangles[u]);
            at += triangles[u];
        }
        Self { spans }
    }

    /// The draw calls for the units `ids`: the number of maximal runs of them that are
    /// contiguous in the layout (units without triangles take no room and no call; unknown ids
    /// and repeats are ignored).
    pub fn calls(&self, ids: &[BlockId]) -> usize {
        let mut spans: Vec<(u64, u64)> = ids
            .iter()
            .filter_map(|&u| self.spans.get(u.0 as usize).copied())
            .filter(|(f, e)| e > f)
            .collect();
        spans.sort_unstable();
        spans.dedup();
        let mut calls = 0;
        let mut end = None;
        for (f, e) in spans {
            if end != Some(f) {
                calls += 1;
            }
            end = Some(e);
        }
        calls
    }
}
