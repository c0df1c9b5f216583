//! blockwalk: cadastral maps to navigable 3D cities, and fast walks and flights through them.
//!
//! The pipeline, one module per stage; data flows one way:
//!
//! | stage | module | seed |
//! |---|---|---|
//! | read files into layers | crate `blockwalk_importers` | |
//! | crash-safe writing: temporary names renamed when complete, staged folders | [`output`] | |
//! | geometric primitives, robust predicates, ring repair, frustum | [`geom`] | |
//! | elevation grids in the city's frame: base heights under footprints, the terrain LOD tree (L∞ bound per level, skirts, occluder level) | [`terrain`] | 002 ch. 3, 004 §4.1 |
//! | city model, local frame, extrusion, glTF/GeoJSON export, generator | [`city`] | 003 §3 |
//! | street graph, urban blocks, building assignment | [`blocks`] | 003 §3 |
//! | spatial structures (BqR-tree, VAMSplit R-tree, flat, none, rstar) | [`index`] | 003 §4 |
//! | occlusion culling (occluder shadows, cull map) and the visibility oracle | [`visibility`] | 004 §3.2 |
//! | far field: BlockMaps, their construction, reference ray caster, error bound | [`blockmap`] | 000 §3–5, 002 ch. 4 |
//! | far field: multi-level relief impostors (the tree over building groups) | [`relief`] | 001 §3–4 |
//! | 3D Tiles 1.1 export: the block quadtree as a tileset (BlockMap height fields, building meshes) | [`tiles`] | 000 §4 |
//! | a city in tiles for batch engines: plan, one tile per job, merge | [`jobs`] | 003 §3–4 |
//! | one scene: city, blocks, meshes, bounds, structures, culler | [`scene`] | |
//! | camera routes | [`route`] | 003 §5 |
//! | playing a route: cull → draw → check, per frame | [`walk`] | 003 §5.1 |
//! | rendering (wgpu, feature `render`) | `render` | 000 |
//! | tables, plots, reports (writing only) | [`report`] | |

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use blockwalk_importers as importers;
pub use choice::{Choice, ChoiceError};

pub mod blockmap;
pub mod blocks;
pub mod choice;
pub mod city;
pub mod fuzzing;
pub mod geom;
pub mod index;
pub mod jobs;
pub mod output;
pub mod process;
pub mod relief;
#[cfg(feature = "render")]
pub mod render;
pub mod report;
pub mod route;
pub mod scene;
pub mod stream;
pub mod terrain;
pub mod tiles;
pub mod visibility;
pub mod walk;
