//! One [`Scene`]: a city with its blocks, one mesh per block (merged once), the blocks' bounds, the
//! spatial structures asked for and, when wanted, the occlusion culler. Every command and test
//! that walks, views or benchmarks a city builds its scene here, and nowhere else.
//!
//! - [`source`]: where a city comes from ([`CitySource`]: files, a city folder, a synthetic grid).
//! - [`units`]: pages of the scene-graph tree and single buildings as draw units
//!   ([`DrawUnits`], [`Scene::build_units`]).
//!
//! # Examples
//! ```
//! use blockwalk::index::Structure;
//! use blockwalk::scene::{CitySource, Scene, SceneOptions};
//! use std::path::Path;
//!
//! let source = CitySource::parse(Path::new("synthetic:3x2"), None, None, &[], 7).unwrap();
//! let loaded = source.load(&Default::default(), &mut |_| {}).unwrap();
//! let opts = SceneOptions {
//!     structures: vec![Structure::Bqr, Structure::Vamsplit],
//!     ..SceneOptions::default()
//! };
//! let scene = Scene::from_loaded(loaded, &opts, &mut |_| {}).unwrap();
//! assert_eq!(scene.bounds.len(), 6);
//! assert!(scene.index(Structure::Bqr).is_some());
//! assert!(scene.index(Structure::Rstar).is_none());
//! ```

pub mod source;
pub mod terrain;
pub mod units;

pub use source::{CitySource, LoadedCity, SourceError};
pub use units::{BuildingsMode, DrawOrder, DrawUnits, Unit};

use crate::blocks::{detect, BlockError, BlockId, BlockLayout, BlockOptions};
use crate::city::extrude::extrude_city;
use crate::city::{City, Mesh};
use crate::geom::Aabb3;
use crate::index::{block_bounds, BlockBounds, CityIndex, IndexError, SceneGraphParams, Structure};
use crate::visibility::{CullerOptions, OcclusionCuller, VisibilityError};

/// What a scene is built with.
#[derive(Clone, Debug)]
pub struct SceneOptions {
    /// How blocks are detected (ignored when the source brings its blocks).
    pub blocks: BlockOptions,
    /// The spatial structures to build, in this order.
    pub structures: Vec<Structure>,
    /// The occlusion culler's settings; `None` builds no culler.
    pub occlusion: Option<CullerOptions>,
    /// For a city on terrain: the largest projected error of a drawn terrain tile, pixels.
    pub terrain_tau_px: f64,
    /// For a city on terrain: the terrain takes part in occlusion culling (its min-filtered
    /// cells as occluders, [`crate::visibility::occluders::terrain_occluders`]).
    pub terrain_occludes: bool,
}

impl Default for SceneOptions {
    /// Default blocks, the BqR-tree alone, no occlusion culler.
    fn default() -> Self {
        Self {
            blocks: BlockOptions::default(),
            structures: vec![Structure::Bqr],
            occlusion: None,
            terrain_tau_px: terrain::DEFAULT_TERRAIN_TAU_PX,
            terrain_occludes: true,
        }
    }
}

/// Why a scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// Loading the city failed.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// Block detection failed.
    #[error("detecting the blocks of {city}")]
    Blocks {
        /// City name.
        city: String,
        /// What went wrong.
        #[source]
        source: BlockError,
    },
    /// A structure could not be built.
    #[error("building the {structure} structure over {city}")]
    Index {
        /// City name.
        city: String,
        /// The structure.
        structure: Structure,
        /// What went wrong.
        #[source]
        source: IndexError,
    },
    /// The occlusion culler could not be built.
    #[error("building the occlusion culler for {city}")]
    Occlusion {
        /// City name.
        city: String,
        /// What went wrong.
        #[source]
        source: VisibilityError,
    },
    /// The terrain tree could not be built.
    #[error("building the terrain of {city}: {problem}")]
    Terrain {
        /// City name.
        city: String,
        /// What went wrong.
        problem: String,
    },
}

/// A city ready to cull, walk and draw.
pub struct Scene {
    /// City name.
    pub name: String,
    /// The city (metric world coordinates, its local frame).
    pub city: City,
    /// Its blocks; every building is in exactly one.
    pub layout: BlockLayout,
    /// One mesh per block (local frame): the block's buildings' meshes merged once (or the exact
    /// block meshes a synthetic grid brings); held by the draw units once they are built
    /// ([`Scene::block_meshes`] reads them either way).
    meshes: Vec<(BlockId, Mesh)>,
    /// One mesh per building (local frame, indexed by building id), extruded once for the whole
    /// scene: the draw units, the far field's construction, the silhouette bound's exact prisms
    /// and the tile export take these instead of extruding again. Empty for a building whose
    /// extrusion failed (drawn as nothing).
    pub building_meshes: Vec<Mesh>,
    /// The ground layers (local frame, z = 0): the blocks' ground and the street strips
    /// ([`crate::city::appearance::ground_mesh`]), which the lit renderers draw under the
    /// buildings. Never part of culling or visibility.
    pub ground: Mesh,
    /// Per-block bounds (local frame), as the structures index them.
    pub bounds: Vec<BlockBounds>,
    /// The structures asked for, in [`SceneOptions::structures`] order.
    pub indexes: Vec<Box<dyn CityIndex>>,
    /// The occlusion culler, when asked for.
    pub occlusion: Option<OcclusionCuller>,
    /// Pages and buildings as draw units, when asked for ([`Scene::build_units`]; always with
    /// [`Structure::SceneGraph`]).
    pub units: Option<DrawUnits>,
    /// The terrain the city stands on, when there is one (`None` by default: flat ground at
    /// z = 0). The walk hands its full mesh to the oracle (an occluder) and the terrain to the
    /// renderers, which draw its cut instead of the flat ground
    /// ([`crate::visibility::draws_flat_ground`]); shared, so that renderers that outlive a
    /// borrow of the scene (the GPU's) keep it.
    pub terrain: Option<crate::visibility::SharedTerrain>,
    /// The same terrain with its level-of-detail tree (errors, cut sizes), for a city on terrain.
    pub terrain_lod: Option<std::sync::Arc<terrain::SceneTerrain>>,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("name", &self.name)
            .field("buildings", &self.city.buildings.len())
            .field("blocks", &self.bounds.len())
            .field(
                "structures",
                &self
                    .indexes
                    .iter()
                    .map(|s| s.structure())
                    .collect::<Vec<_>>(),
            )
            .field("occlusion", &self.occlusion.is_some())
            .field(
                "terrain_tiles",
                &self.terrain.as_ref().map(|t| t.tiles().len()),
            )
            .finish()
    }
}

impl Scene {
    /// The city's buildings as exact prisms (`blockmap::Source` over the scene's building
    /// meshes), standing on the scene's terrain when it has one: what the silhouette bound and
    /// the diagnosis check frames with.
    ///
    /// # Errors
    /// As [`crate::blockmap::Source::new`].
    pub fn exact_prisms(
        &self,
    ) -> Result<crate::blockmap::Source<'_>, crate::blockmap::BlockMapError> {
        let source = crate::blockmap::Source::new(&self.city, &self.layout, &self.building_meshes)?;
        Ok(match &self.terrain {
            Some(t) => source.with_terrain(t.full()),
            None => source,
        })
    }
    /// The terrain, borrowed as the CPU renderers take it.
    pub fn terrain_draw(&self) -> Option<&dyn crate::visibility::TerrainDraw> {
        self.terrain
            .as_deref()
            .map(|t| t as &dyn crate::visibility::TerrainDraw)
    }

    /// Loads the city from `source` (default height rules) and builds its scene.
    ///
    /// # Errors
    /// See [`SceneError`].
    pub fn load(
        source: &CitySource,
        opts: &SceneOptions,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Self, SceneError> {
        let loaded = source.load(&Default::default(), progress)?;
        Self::from_loaded(loaded, opts, progress)
    }

    /// Builds the scene of a loaded city: its blocks (detected, unless the source brought
    /// them), per-block meshes, bounds, structures and culler. `progress` hears each stage.
    ///
    /// # Errors
    /// See [`SceneError`].
    pub fn from_loaded(
        loaded: LoadedCity,
        opts: &SceneOptions,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Self, SceneError> {
        let LoadedCity {
            city,
            layout,
            meshes,
        } = loaded;
        let layout = match layout {
            Some(l) => l,
            None => {
                progress("detecting blocks");
                detect(&city, &opts.blocks).map_err(|source| SceneError::Blocks {
                    city: city.name.clone(),
                    source,
                })?
            }
        };
        // Every building extruded once, for everything the scene draws or measures.
        progress("extruding buildings");
        let building_meshes = extrude_city(&city);
        // Which buildings have a mesh (the occlusion culler must know: an undrawn building casts
        // no shadow), and the blocks' meshes merged from them unless the source brought its own.
        let drawn: Vec<bool> = building_meshes
            .iter()
            .map(|m| !m.indices.is_empty())
            .collect();
        let meshes = meshes.unwrap_or_else(|| merge_blocks(&building_meshes, &layout));
        progress("laying out the ground");
        let ground = ground_layers(&city, &layout);
        progress("building the structures");
        let bounds = block_bounds(&city, &layout);
        let indexes = opts
            .structures
            .iter()
            .filter(|&&s| s != Structure::SceneGraph)
            .map(|&s| {
                s.build(&bounds).map_err(|source| SceneError::Index {
                    city: city.name.clone(),
                    structure: s,
                    source,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let terrain = match &city.terrain {
            Some(t) => {
                progress("building the terrain tree");
                let st = terrain::SceneTerrain::build(
                    t.clone(),
                    city.frame,
                    &crate::terrain::TreeOptions::default(),
                    opts.terrain_tau_px,
                )
                .map_err(|e| SceneError::Terrain {
                    city: city.name.clone(),
                    problem: e.to_string(),
                })?;
                Some(std::sync::Arc::new(st))
            }
            None => None,
        };
        let occlusion = match opts.occlusion {
            Some(o) => {
                progress("extracting occluders");
                let culler = match (&terrain, opts.terrain_occludes) {
                    (Some(t), true) => {
                        let extra = crate::visibility::occluders::terrain_occluders(
                            &t.tree,
                            &city.frame,
                            crate::visibility::occluders::TERRAIN_OCCLUDER_CELL_M,
                            &o.occluders,
                        );
                        OcclusionCuller::with_drawn_and(&city, &layout, &drawn, extra, o)
                    }
                    _ => OcclusionCuller::with_drawn(&city, &layout, &drawn, o),
                };
                Some(culler.map_err(|source| SceneError::Occlusion {
                    city: city.name.clone(),
                    source,
                })?)
            }
            None => None,
        };
        let mut scene = Self {
            name: city.name.clone(),
            city,
            layout,
            meshes,
            building_meshes,
            ground,
            bounds,
            indexes,
            occlusion,
            units: None,
            terrain: terrain
                .clone()
                .map(|t| t as crate::visibility::SharedTerrain),
            terrain_lod: terrain,
        };
        if let Some(at) = opts
            .structures
            .iter()
            .position(|&s| s == Structure::SceneGraph)
        {
            progress("building the scene graph over the buildings");
            scene.build_units(&SceneGraphParams::default(), BuildingsMode::Off)?;
            let tree = scene
                .units
                .as_ref()
                .map(|u| u.scene_graph.clone())
                .expect("units were just built");
            scene
                .indexes
                .insert(at.min(scene.indexes.len()), Box::new(tree));
        }
        Ok(scene)
    }

    /// Builds the scene's [`DrawUnits`] (pages of a scene graph made with `params`, single
    /// buildings) with the walk's per-building `mode`; a second call rebuilds them. The
    /// [`Structure::SceneGraph`] index, when the scene has one, keeps the tree it was built with.
    ///
    /// # Errors
    /// [`SceneError::Index`] for bad scene-graph parameters.
    pub fn build_units(
        &mut self,
        params: &SceneGraphParams,
        mode: BuildingsMode,
    ) -> Result<(), SceneError> {
        if let Some(old) = self.units.take() {
            self.meshes = old.into_block_meshes();
        }
        let units = DrawUnits::build(
            &self.building_meshes,
            &self.layout,
            &mut self.meshes,
            params,
            mode,
        )
        .map_err(|source| SceneError::Index {
            city: self.name.clone(),
            structure: Structure::SceneGraph,
            source,
        })?;
        self.units = Some(units);
        Ok(())
    }

    /// Releases the per-block meshes and the ground layers, for a caller that reads only
    /// [`Scene::building_meshes`] (an exporter): they are a second copy of every building's
    /// geometry. [`Scene::block_meshes`] is empty afterwards, and so is [`Scene::ground`]; draw
    /// units already built keep theirs.
    pub fn release_block_meshes(&mut self) {
        self.meshes = Vec::new();
        self.ground = Mesh::default();
    }

    /// One mesh per block (local frame, in the layout's order): the block's buildings' meshes
    /// merged once, or the exact meshes a synthetic grid brings.
    pub fn block_meshes(&self) -> &[(BlockId, Mesh)] {
        self.units
            .as_ref()
            .map_or(&self.meshes, |u| u.block_meshes())
    }

    /// The meshes a renderer of this scene must hold: [`DrawUnits::meshes`] when the scene has
    /// units, else [`Scene::block_meshes`].
    pub fn draw_meshes(&self) -> &[(BlockId, Mesh)] {
        self.units.as_ref().map_or(&self.meshes, |u| &u.meshes)
    }

    /// The structure `s`, when it was built.
    pub fn index(&self, s: Structure) -> Option<&dyn CityIndex> {
        self.indexes
            .iter()
            .find(|i| i.structure() == s)
            .map(|i| i.as_ref())
    }

    /// Box of all block bounds (local frame).
    pub fn city_bounds(&self) -> Aabb3 {
        self.bounds
            .iter()
            .fold(Aabb3::EMPTY, |b, bb| b.union(bb.aabb))
    }

    /// The BlockMaps of the scene's blocks ([`crate::blockmap::build_city_maps`]: the block
    /// quadtree over [`Scene::bounds`], a map per selected node, their measured error and
    /// `opts.checks` image checks). `progress(done, total)` hears the maps as they finish.
    ///
    /// # Errors
    /// See [`crate::blockmap::build_city_maps`].
    pub fn blockmaps(
        &self,
        opts: &crate::blockmap::CityMapsOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<crate::blockmap::CityMaps, crate::blockmap::BlockMapError> {
        crate::blockmap::build_city_maps_from(
            &self.city,
            &self.layout,
            &self.bounds,
            &self.building_meshes,
            opts,
            progress,
        )
    }

    /// Triangles of each block, indexed by block id.
    pub fn triangles_by_block(&self) -> Vec<u64> {
        let n = self
            .bounds
            .iter()
            .map(|b| b.id.0 as usize + 1)
            .max()
            .unwrap_or(0);
        let mut t = vec![0u64; n];
        for b in &self.bounds {
            t[b.id.0 as usize] = u64::from(b.triangles);
        }
        t
    }

    /// Pages of `params` and single buildings as draw units, with the walk's per-building
    /// `mode`: the units are kept when they were built with `params` (only the mode is set),
    /// rebuilt otherwise, and the [`Structure::SceneGraph`] index, when the scene has one, is
    /// replaced by the rebuilt tree so that the index and the units agree. Without units and with
    /// `mode` off nothing is built.
    ///
    /// # Errors
    /// [`SceneError::Index`] for bad scene-graph parameters.
    pub fn set_pages(
        &mut self,
        params: &SceneGraphParams,
        mode: BuildingsMode,
    ) -> Result<(), SceneError> {
        match self.units.as_mut() {
            Some(u) if u.scene_graph.params() == params => u.mode = mode,
            Some(_) => {
                self.build_units(params, mode)?;
                if let Some(tree) = self.units.as_ref().map(|u| u.scene_graph.clone()) {
                    for index in self.indexes.iter_mut() {
                        if index.structure() == Structure::SceneGraph {
                            *index = Box::new(tree.clone());
                        }
                    }
                }
            }
            None if mode != BuildingsMode::Off => self.build_units(params, mode)?,
            None => {}
        }
        Ok(())
    }
}

/// One mesh per block: its buildings extruded (in parallel) and merged, in block order.
/// Buildings in no block are left out (none are when the layout assigns every building).
pub fn block_meshes(city: &City, layout: &BlockLayout) -> Vec<(BlockId, Mesh)> {
    block_meshes_drawn(city, layout).0
}

/// As [`block_meshes`], with whether each building (by id) has a mesh: a building whose
/// extrusion failed is drawn as nothing.
pub fn block_meshes_drawn(city: &City, layout: &BlockLayout) -> (Vec<(BlockId, Mesh)>, Vec<bool>) {
    let per_building = extrude_city(city);
    let drawn = per_building.iter().map(|m| !m.indices.is_empty()).collect();
    (merge_blocks(&per_building, layout), drawn)
}

/// One mesh per block of `layout`: its buildings' meshes (`per_building[i]`: building `i`'s)
/// appended in the block's order. A building listed twice or out of range is drawn once or not
/// at all.
pub fn merge_blocks(per_building: &[Mesh], layout: &BlockLayout) -> Vec<(BlockId, Mesh)> {
    let mut used = vec![false; per_building.len()];
    layout
        .blocks
        .iter()
        .map(|block| {
            let mut m = Mesh::default();
            for b in &block.buildings {
                let i = b.0 as usize;
                if let (Some(part), Some(u)) = (per_building.get(i), used.get_mut(i)) {
                    if !*u {
                        *u = true;
                        m.append(part);
                    }
                }
            }
            (block.id, m)
        })
        .collect()
}

/// The ground layers of a city: the ground of its street blocks (outskirts groups have no
/// ground of their own: their outline is only a hull of footprints) and its street strips.
pub fn ground_layers(city: &City, layout: &BlockLayout) -> Mesh {
    let blocks: Vec<geo_types::Polygon<f64>> = layout
        .blocks
        .iter()
        .filter(|b| b.kind == crate::blocks::BlockKind::Block)
        .map(|b| b.polygon.clone())
        .collect();
    crate::city::appearance::ground_mesh(&city.frame, &city.streets, &blocks)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::extrude::try_extrude_building;
    use crate::city::BuildingId;

    /// The scene's own extrusion tells the culler which buildings are drawn: the mask must be
    /// exactly "the extrusion succeeded" (as `occluders::extract` finds it by extruding again),
    /// here on a generated city where one footprint is made to fail.
    #[test]
    fn drawn_mask_is_the_extrusion_outcome() {
        let source =
            CitySource::parse(std::path::Path::new("synthetic:3x2"), None, None, &[], 5).unwrap();
        let mut loaded = source.load(&Default::default(), &mut |_| {}).unwrap();
        let layout = detect(&loaded.city, &BlockOptions::default()).unwrap();
        // A NaN vertex makes spade refuse the footprint: that building is drawn as nothing.
        let bad = &mut loaded.city.buildings[3].footprint;
        bad.exterior_mut(|r| r.0[1].x = f64::NAN);
        let (_, drawn) = block_meshes_drawn(&loaded.city, &layout);
        let truth: Vec<bool> = loaded
            .city
            .buildings
            .iter()
            .map(|b| try_extrude_building(b, &loaded.city.frame).is_ok())
            .collect();
        assert_eq!(drawn, truth);
        assert!(!drawn[3], "the broken footprint must count as not drawn");
        assert!(drawn.iter().filter(|d| **d).count() > 100);
    }

    /// Draw ids and units are one-to-one over every block, page and building, the three ranges
    /// disjoint; a page's buildings are the scene graph's items.
    #[test]
    fn draw_ids_and_units_round_trip() {
        let source =
            CitySource::parse(std::path::Path::new("synthetic:3x2"), None, None, &[], 5).unwrap();
        let mut scene = Scene::load(&source, &SceneOptions::default(), &mut |_| {}).unwrap();
        scene
            .build_units(&SceneGraphParams::default(), BuildingsMode::On)
            .unwrap();
        let u = scene.units.as_ref().unwrap();
        let mut seen = std::collections::HashSet::new();
        let blocks = scene.layout.blocks.iter().map(|b| Unit::Block(b.id));
        let pages = (0..u.scene_graph.page_count() as u32).map(Unit::Page);
        let buildings =
            (0..scene.city.buildings.len() as u32).map(|b| Unit::Building(BuildingId(b)));
        for unit in blocks.chain(pages).chain(buildings) {
            let id = u.id(unit);
            assert_eq!(u.unit(id), unit);
            assert!(seen.insert(id), "{unit:?} shares draw id {id:?}");
        }
        let page = u.id(Unit::Page(0));
        let of_page: Vec<BuildingId> = u.buildings_of(page, &scene.layout).collect();
        let items: Vec<BuildingId> = u
            .scene_graph
            .page_items(0)
            .iter()
            .map(|b| BuildingId(b.0))
            .collect();
        assert_eq!(of_page, items);
        assert!(!items.is_empty());
    }
}
