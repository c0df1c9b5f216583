//! 3D Tiles 1.1 export: the block quadtree as a tileset that CesiumJS and other 3D Tiles viewers
//! stream (OGC 3D Tiles 1.1: `tileset.json`, glTF 2.0 content, `refine: "REPLACE"`).
//!
//! - The tile tree is the BqR-tree's ([`crate::index::BqrTree`]), as far as
//!   [`crate::blockmap::build_tree`] gives its nodes a BlockMap: each mapped node is an inner
//!   tile whose content is its map's height field as a coarse mesh ([`heightfield`]), with
//!   `geometricError` = the map's declared ε (Cignoni et al., §3.3; made monotone by the map tree);
//!   below it, each quadrant that has no map of its own becomes a leaf tile holding the meshes
//!   of that quadrant's whole blocks (`geometricError` 0). Blocks are never cut, so every block
//!   lies in exactly one leaf and REPLACE refinement swaps a node's map for exactly its blocks'
//!   meshes (Cignoni et al., §4: the far field reuses the spatial partition).
//! - Leaves are glTF with one feature per building: a per-vertex `_FEATURE_ID_0`
//!   (`EXT_mesh_features`) indexing a property table (`EXT_structural_metadata`, class
//!   `building`: `source_id`, `height_m`, `min_height_m`, `base_m`); see
//!   [`crate::city::export::tile_glb`].
//! - Contents are compact by default ([`TilesetOptions::content`]): positions within 1 mm
//!   (`KHR_mesh_quantization`), octahedral normals, every stream compressed with
//!   `EXT_meshopt_compression` (required); [`ContentEncoding::Plain`] writes core glTF for
//!   viewers without that extension. See the `compact` module of [`crate::city::export`]'s glTF
//!   writer.
//! - Bounding volumes are `box`es in the local frame (x east, y north, z up, metres from the
//!   city's origin). The root's `transform` places that frame on the WGS84 ellipsoid
//!   ([`geodesy`]): the east-north-up frame at the origin's longitude/latitude (ellipsoidal
//!   height = the origin's z: heights are above the ellipsoid, not the geoid), turned by the
//!   projection's grid convergence and its x, y scaled by the scale factor at the origin (both measured
//!   on the CRS, so that grid north and grid metres land where they belong). A city without a
//!   geodetic CRS gets no transform (the tileset then sits at the Earth's centre; the summary
//!   says so).
//! - glTF is Y-up and 3D Tiles rotates glTF content Y-up → Z-up: the content is written with
//!   local (x, y, z) as glTF (x, z, −y), which that rotation takes back to (x, y, z).
//! - Terrain (optional, [`TilesetOptions::terrain`]): a second tileset, `terrain/tileset.json`
//!   ([`terrain`]: a quadtree of square cells, leaves holding the TIN's triangles by centroid at
//!   full resolution, the same root transform). The main `tileset.json` then gets a root without
//!   content and without transform, refined by `ADD`, with two children: the buildings' tree as
//!   above (carrying the root transform) and a tile whose content is `terrain/tileset.json`
//!   (an external tileset, whose own root transform places it; its bounding box written in
//!   ECEF). A viewer loading `tileset.json` gets both, each refined on its own; one loading
//!   `terrain/tileset.json` gets the terrain alone. Without terrain `tileset.json` is as before.
//! - Implicit tiling (optional, [`TilesetOptions::implicit`]): the same tiles written as a
//!   3D Tiles 1.1 implicit quadtree, subtree files carrying each tile's own box and error as
//!   tile metadata ([`implicit`]: how BqR keys become (level, x, y), and where a node's own
//!   blocks go). The terrain's tileset stays explicit.
//! - One file (optional, [`TilesetOptions::archive`]): either form packed into a 3D Tiles
//!   archive, `.3tz` ([`archive`]), written under a temporary name and renamed when complete.
//! - Output is deterministic: the same city gives the same bytes.

pub mod archive;
pub mod geodesy;
pub mod heightfield;
pub mod implicit;
pub mod terrain;

use crate::blockmap::{
    build_tree, BlockMapError, BuildOptions, MapTree, Source, Stop, TreeOptions,
};
use crate::blocks::{BlockId, BlockLayout};
use crate::city::appearance::{surface_color, to_rgb8, BuildingStyle};
pub use crate::city::export::ContentEncoding;
use crate::city::export::{tile_glb, ExportError, TerrainError, TerrainTin, TileFeature, TileMesh};
use crate::city::{City, Mesh};
use crate::geom::Aabb3;
use crate::index::{BlockBounds, BqrParams, BqrTree};
use glam::{DMat4, DVec3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// What went wrong while exporting a tileset.
#[derive(Debug, thiserror::Error)]
pub enum TilesError {
    /// The output folder could not be placed or swapped in (see [`crate::output`]).
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A file or directory could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A tile's glTF could not be made.
    #[error("{path}: {source}")]
    Content {
        /// The content file.
        path: PathBuf,
        /// Why.
        #[source]
        source: ExportError,
    },
    /// The BlockMaps of the inner tiles could not be built.
    #[error("tileset of {city}: {source}")]
    Maps {
        /// City name.
        city: String,
        /// Why.
        #[source]
        source: BlockMapError,
    },
    /// The block quadtree could not be built.
    #[error("tileset of {city}: the block quadtree: {what}")]
    Quadtree {
        /// City name.
        city: String,
        /// Why.
        what: String,
    },
    /// The terrain given cannot be tiled (see [`TerrainTin::check`]).
    #[error("terrain: {source}")]
    Terrain {
        /// What is wrong with it.
        #[source]
        source: TerrainError,
    },
    /// The tile tree cannot be written as an implicit quadtree.
    #[error("implicit tileset of {city}: {what}")]
    Implicit {
        /// City name.
        city: String,
        /// Why.
        what: String,
    },
    /// The `.3tz` archive could not be written.
    #[error(transparent)]
    Archive(#[from] archive::ArchiveError),
    /// The city has no block with a building: there is nothing to tile.
    #[error("tileset of {city}: no block holds a building, nothing to export")]
    Empty {
        /// City name.
        city: String,
    },
}

/// Options of [`build_tileset`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TilesetOptions<'a> {
    /// BlockMap height-map side K of the inner tiles (32, 64 or 128).
    pub k: u32,
    /// Which quadtree nodes get a map (inner tiles); [`Stop::Competitive`] by default (Cignoni et al.
    /// §4: a map where it costs fewer bytes than the meshes).
    pub stop: Stop,
    /// Write the buildings' tree as an implicit quadtree (subtree files, templated content
    /// names; see [`implicit`]); `false` (explicit `tileset.json`) by default.
    pub implicit: bool,
    /// Levels per subtree file of the implicit form; [`implicit::DEFAULT_SUBTREE_LEVELS`] by
    /// default.
    pub subtree_levels: u32,
    /// Write one `.3tz` file (the 3D Tiles archive, [`archive`]) at the output path instead of a
    /// folder; `false` by default.
    pub archive: bool,
    /// A terrain to write as a second tileset, `terrain/tileset.json` (see the module
    /// documentation); `None` by default.
    #[serde(skip)]
    pub terrain: Option<&'a TerrainTin>,
    /// Most triangles in one terrain leaf (a cell with more is cut in four); 16 384 by default.
    pub terrain_leaf_triangles: usize,
    /// How every content `.glb` (building leaves, BlockMap height fields, terrain) is stored:
    /// [`ContentEncoding::Compact`] by default (quantised, `EXT_meshopt_compression` required),
    /// [`ContentEncoding::Plain`] for viewers without that extension.
    pub content: ContentEncoding,
}

impl Default for TilesetOptions<'_> {
    fn default() -> Self {
        Self {
            k: 64,
            stop: Stop::Competitive,
            implicit: false,
            subtree_levels: implicit::DEFAULT_SUBTREE_LEVELS,
            archive: false,
            terrain: None,
            terrain_leaf_triangles: 16_384,
            content: ContentEncoding::Compact,
        }
    }
}

/// What a tile holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TileKind {
    /// An inner tile: a BlockMap's height field (the map's index in the map tree).
    Map(usize),
    /// A leaf: the meshes of its blocks' buildings.
    Buildings,
}

/// One tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// Linear quadtree key of its BqR node (root 1).
    pub key: u64,
    /// Inner (map) or leaf (meshes).
    pub kind: TileKind,
    /// Bounding box, local frame; holds the content and every child's box.
    pub aabb: Aabb3,
    /// Geometric error, metres (the map's declared ε; 0 at leaves).
    pub geometric_error: f64,
    /// The blocks the tile stands for (all of the subtree's for an inner tile).
    pub blocks: Vec<BlockId>,
    /// Buildings in the content (indices into `City::buildings`; leaves only, each building
    /// is feature `position in this list`).
    pub buildings: Vec<u32>,
    /// Content file, relative to the tileset directory (`None` for a tile with nothing to draw).
    pub content: Option<String>,
    /// Content bytes.
    pub content_bytes: usize,
    /// Child tiles (indices into [`Tileset::tiles`]).
    pub children: Vec<usize>,
}

/// Where the local frame stands on the Earth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Georef {
    /// Longitude of the local origin, degrees (WGS84).
    pub lon_deg: f64,
    /// Latitude of the local origin, degrees (WGS84).
    pub lat_deg: f64,
    /// Ellipsoidal height of the local origin, metres.
    pub height_m: f64,
    /// Angle from true north to grid north (the local +y), degrees, counter-clockwise positive.
    pub convergence_deg: f64,
    /// Ground metres per grid metre at the origin (applied to x and y; heights are ground
    /// metres already).
    pub scale: f64,
    /// The root transform (local → ECEF), column-major as `tileset.json` stores it.
    pub ecef_from_local: [f64; 16],
}

/// A tileset: its tiles (root first, parents before children) and where it stands.
#[derive(Clone, Debug, PartialEq)]
pub struct Tileset {
    /// Tiles, preorder; `tiles[0]` is the root.
    pub tiles: Vec<Tile>,
    /// The root transform, or `None` for a city without a geodetic CRS.
    pub georef: Option<Georef>,
    /// The CRS, as the city describes it.
    pub crs: String,
    /// Top-level geometric error (≥ the root's).
    pub geometric_error: f64,
    /// The terrain's tileset (`terrain/tileset.json`), when a terrain was given.
    pub terrain: Option<terrain::TerrainTiles>,
    /// The implicit layout, when the tileset was written as an implicit quadtree.
    pub implicit: Option<implicit::Implicit>,
}

/// What [`build_tileset`] wrote, as `blockwalk tileset` prints it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TilesetSummary {
    /// City name.
    pub city: String,
    /// Tiles.
    pub tiles: usize,
    /// Inner tiles (BlockMap height fields).
    pub map_tiles: usize,
    /// Leaf tiles (building meshes).
    pub leaf_tiles: usize,
    /// Bytes of `tileset.json`, every content and subtree file (the archive's bytes for a
    /// `.3tz`).
    pub bytes: u64,
    /// Written as an implicit quadtree.
    pub implicit: bool,
    /// Subtree files (implicit form; 0 for the explicit one).
    pub subtrees: usize,
    /// Written as one `.3tz` archive.
    pub archive: bool,
    /// Depth of the tile tree (root alone = 0).
    pub depth: u32,
    /// Seconds for the whole export (maps, contents, files).
    pub seconds: f64,
    /// Buildings in leaf contents.
    pub buildings: usize,
    /// Terrain tiles (0 without terrain).
    pub terrain_tiles: usize,
    /// Terrain triangles in terrain leaves (0 without terrain).
    pub terrain_triangles: usize,
    /// Root geometric error, metres.
    pub root_geometric_error: f64,
    /// Where the tileset stands, or `None` (no transform written).
    pub georef: Option<Georef>,
    /// The CRS and what was done with it.
    pub crs: String,
    /// The `tileset.json` file (the archive for a `.3tz`).
    pub tileset_json: PathBuf,
    /// How the contents are stored.
    pub content: ContentEncoding,
    /// The largest distance between a content position as written (decoded, dequantised) and
    /// its f32 position, metres, over every content (0 for plain contents; below
    /// [`crate::city::export::POSITION_TOLERANCE_M`] for compact ones).
    pub position_error_m: f64,
}

/// The root transform of a city: `None` when its CRS has no geodetic meaning.
///
/// Grid convergence and scale are measured on the CRS: the points 100 m grid-east and
/// grid-north of the origin are taken to WGS84 and to the origin's east-north-up frame; their
/// mean angle from the ENU axes is the rotation, their mean length / 100 the scale.
pub fn georef(city: &City) -> Option<Georef> {
    let o = city.frame.origin;
    let ll = |dx: f64, dy: f64| city.transform.to_wgs84_lonlat([o.x + dx, o.y + dy]);
    let [lon, lat] = ll(0.0, 0.0)?;
    let h = o.z;
    let enu = geodesy::ecef_from_enu(lon, lat, h);
    let local_of = |p: [f64; 2]| {
        enu.inverse()
            .transform_point3(geodesy::ecef_from_geodetic(p[0], p[1], h))
    };
    const D: f64 = 100.0;
    let e = local_of(ll(D, 0.0)?);
    let n = local_of(ll(0.0, D)?);
    // Grid east at angle a_e from true east, grid north at a_n from true north (ccw positive).
    let a_e = e.y.atan2(e.x);
    let a_n = (-n.x).atan2(n.y);
    let gamma = 0.5 * (a_e + a_n);
    let scale = 0.5 * (e.truncate().length() + n.truncate().length()) / D;
    if !(gamma.is_finite() && scale.is_finite() && scale > 0.5 && scale < 2.0) {
        return None;
    }
    let m = enu * DMat4::from_rotation_z(gamma) * DMat4::from_scale(DVec3::new(scale, scale, 1.0));
    Some(Georef {
        lon_deg: lon,
        lat_deg: lat,
        height_m: h,
        convergence_deg: gamma.to_degrees(),
        scale,
        ecef_from_local: m.to_cols_array(),
    })
}

/// The leaf content of `buildings`: their meshes merged, one feature per building, vertex
/// colours from the city's appearance (roof, underside or plain facade colour).
fn leaf_mesh(city: &City, meshes: &[Mesh], buildings: &[u32]) -> TileMesh {
    let mut t = TileMesh::default();
    for (fid, &b) in buildings.iter().enumerate() {
        let m = &meshes[b as usize];
        let base = t.positions.len() as u32;
        let default = BuildingStyle::default();
        for (v, (&p, &n)) in m.positions.iter().zip(&m.normals).enumerate() {
            let (style, u) = match m.appearance.get(v) {
                Some(a) => (m.styles.get(a.style as usize).unwrap_or(&default), a.u_m),
                None => (m.styles.first().unwrap_or(&default), 0.0),
            };
            t.positions.push(p);
            t.normals.push(n);
            // Walls take the plain facade colour: the window pattern sampled at the corners
            // of a wall would only streak it.
            let c = if n.z.abs() > 0.5 {
                surface_color(style, n, u, p.z)
            } else {
                style.facade
            };
            t.colors.push(to_rgb8(c).map(heightfield::srgb_to_linear));
            t.feature_ids.push(fid as u32);
        }
        t.indices.extend(m.indices.iter().map(|i| base + i));
        let bd = &city.buildings[b as usize];
        t.features.push(TileFeature {
            source_id: bd.source_id.clone(),
            height_m: bd.height_m,
            min_height_m: bd.min_height_m,
            base_m: bd.base_m,
        });
    }
    t
}

fn mesh_aabb(m: &TileMesh) -> Aabb3 {
    m.positions.iter().fold(Aabb3::EMPTY, |a, p| {
        let p = p.as_dvec3();
        a.union(Aabb3::new(p, p))
    })
}

/// Plans the tile tree from the quadtree and its maps (no content yet): see the module doc.
fn plan(tree: &BqrTree, maps: &MapTree, layout: &BlockLayout, meshes: &[Mesh]) -> Vec<Tile> {
    let blocks_of = |r: std::ops::Range<usize>| -> Vec<BlockId> {
        tree.blocks()[r].iter().map(|b| b.id).collect()
    };
    let leaf = |key: u64, blocks: Vec<BlockId>| -> Tile {
        let mut buildings: Vec<u32> = blocks
            .iter()
            .flat_map(|id| layout.blocks[id.0 as usize].buildings.iter().map(|b| b.0))
            .filter(|&b| {
                meshes
                    .get(b as usize)
                    .is_some_and(|m| m.triangle_count() > 0)
            })
            .collect();
        buildings.sort_unstable();
        Tile {
            key,
            kind: TileKind::Buildings,
            aabb: Aabb3::EMPTY,
            geometric_error: 0.0,
            blocks,
            buildings,
            content: None,
            content_bytes: 0,
            children: Vec::new(),
        }
    };
    let mut tiles: Vec<Tile> = Vec::new();
    let Some(root) = tree.node(0) else {
        return tiles;
    };
    if maps.maps.is_empty() {
        tiles.push(leaf(root.key, blocks_of(root.blocks.clone())));
        return tiles;
    }
    // Map slot → its children's slots.
    let mut kids_of: Vec<Vec<usize>> = vec![Vec::new(); maps.maps.len()];
    for (i, m) in maps.maps.iter().enumerate() {
        if let Some(p) = m.parent {
            kids_of[p].push(i);
        }
    }
    /// What the depth-first walk reads.
    struct Walk<'a> {
        tree: &'a BqrTree,
        maps: &'a MapTree,
        kids_of: &'a [Vec<usize>],
        leaf: &'a dyn Fn(u64, Vec<BlockId>) -> Tile,
        blocks_of: &'a dyn Fn(std::ops::Range<usize>) -> Vec<BlockId>,
    }
    // Depth-first, parents before children: (map slot, parent tile).
    fn visit(slot: usize, parent: Option<usize>, w: &Walk<'_>, tiles: &mut Vec<Tile>) {
        let Walk {
            tree,
            maps,
            kids_of,
            leaf,
            blocks_of,
        } = *w;
        let m = &maps.maps[slot];
        let v = tree.node(m.node).expect("mapped nodes exist");
        let me = tiles.len();
        tiles.push(Tile {
            key: v.key,
            kind: TileKind::Map(slot),
            aabb: Aabb3::EMPTY,
            geometric_error: m.map.meta.eps_m,
            blocks: blocks_of(v.blocks.clone()),
            buildings: Vec::new(),
            content: None,
            content_bytes: 0,
            children: Vec::new(),
        });
        if let Some(p) = parent {
            tiles[p].children.push(me);
        }
        let mut covered = vec![false; v.blocks.len()];
        let mut cover = |r: &std::ops::Range<usize>| {
            for q in r.clone() {
                covered[q - v.blocks.start] = true;
            }
        };
        for c in v.children.iter().flatten() {
            let cv = tree.node(*c).expect("children exist");
            if cv.blocks.is_empty() {
                continue;
            }
            cover(&cv.blocks);
            let mapped = kids_of[slot].iter().copied().find(|&k| {
                tree.node(maps.maps[k].node)
                    .is_some_and(|n| n.blocks == cv.blocks)
            });
            match mapped {
                Some(k) => visit(k, Some(me), w, tiles),
                None => {
                    let t = leaf(cv.key, blocks_of(cv.blocks.clone()));
                    let i = tiles.len();
                    tiles.push(t);
                    tiles[me].children.push(i);
                }
            }
        }
        // Blocks the node holds itself (none in a quadtree whose blocks all sit in leaves) and
        // a mapped node without children: one leaf of its own.
        let rest: Vec<usize> = (0..covered.len())
            .filter(|&q| !covered[q])
            .map(|q| q + v.blocks.start)
            .collect();
        if !rest.is_empty() {
            let blocks = rest.iter().map(|&q| tree.blocks()[q].id).collect();
            // Key 4k + 4 can belong to no quadrant: it names "the node's own blocks".
            let t = leaf(v.key * 4 + 4, blocks);
            let i = tiles.len();
            tiles.push(t);
            tiles[me].children.push(i);
        }
    }
    let roots: Vec<usize> = (0..maps.maps.len())
        .filter(|&i| maps.maps[i].parent.is_none())
        .collect();
    debug_assert_eq!(roots.len(), 1, "the map tree has one root");
    let w = Walk {
        tree,
        maps,
        kids_of: &kids_of,
        leaf: &leaf,
        blocks_of: &blocks_of,
    };
    visit(roots[0], None, &w, &mut tiles);
    tiles
}

/// True for the entries a tileset folder holds (`tileset.json`, `tiles`, `terrain`, and the
/// implicit form's `subtrees`): a folder of only these may be replaced by a new tileset.
pub fn is_tileset_entry(name: &std::ffi::OsStr) -> bool {
    name == "tileset.json" || name == "tiles" || name == "terrain" || name == "subtrees"
}

/// Builds the tileset of a city and writes it to `dir`: `tileset.json` and `tiles/*.glb`, and
/// with a terrain `terrain/tileset.json` and `terrain/tiles/*.glb` (see the module
/// documentation). `meshes` are the buildings' meshes (`city::extrude::extrude_city`);
/// `bounds` the blocks' bounds (`index::block_bounds`). `progress(done, total)` is called as
/// maps are built, then as contents are written. The folder is written under a temporary name
/// beside `dir` and swapped in when complete: a killed run or a full disk leaves `dir` as it
/// was, and a previous tileset there is replaced whole, never mixed with the new one.
///
/// # Errors
/// [`TilesError`] naming the file, node or city.
pub fn build_tileset(
    city: &City,
    layout: &BlockLayout,
    bounds: &[BlockBounds],
    meshes: &[Mesh],
    dir: &Path,
    opts: &TilesetOptions<'_>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Tileset, TilesetSummary), TilesError> {
    let t0 = std::time::Instant::now();
    // A city on terrain brings its own, unless the options give one.
    let own;
    let opts = &match (opts.terrain, &city.terrain) {
        (None, Some(t)) => {
            own = crate::city::export::TerrainTin::from_terrain(t)
                .map_err(|source| TilesError::Terrain { source })?;
            TilesetOptions {
                terrain: Some(&own),
                ..*opts
            }
        }
        _ => *opts,
    };
    if let Some(t) = opts.terrain {
        t.check().map_err(|source| TilesError::Terrain { source })?;
    }
    // Checked before any work: a folder holding anything but a previous tileset is refused.
    let staged = archive::Staged::create(dir, opts.archive)?;
    let tree = BqrTree::build(bounds, &BqrParams::default()).map_err(|e| TilesError::Quadtree {
        city: city.name.clone(),
        what: e.to_string(),
    })?;
    if tree.nodes_len() == 0 {
        return Err(TilesError::Empty {
            city: city.name.clone(),
        });
    }
    let maps_err = |source| TilesError::Maps {
        city: city.name.clone(),
        source,
    };
    let source = Source::new(city, layout, meshes).map_err(maps_err)?;
    let maps = build_tree(
        &source,
        layout,
        &tree,
        &TreeOptions {
            build: BuildOptions {
                k: opts.k,
                ..BuildOptions::default()
            },
            stop: opts.stop,
            ..TreeOptions::default()
        },
        progress,
    )
    .map_err(maps_err)?;
    // The maps are built: their source's copies of the footprints are not needed again.
    drop(source);
    let mut tiles = plan(&tree, &maps, layout, meshes);
    if tiles
        .iter()
        .all(|t| t.buildings.is_empty() && t.kind == TileKind::Buildings)
    {
        return Err(TilesError::Empty {
            city: city.name.clone(),
        });
    }

    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| TilesError::Io { path, source }
    };
    // Written into the staging folder; errors name the final paths.
    let tiles_dir = staged.path().join("tiles");
    std::fs::create_dir_all(&tiles_dir).map_err(io(&dir.join("tiles")))?;
    let block_aabb: std::collections::HashMap<BlockId, Aabb3> =
        bounds.iter().map(|b| (b.id, b.aabb)).collect();

    // Contents, in parallel; each tile's bytes depend only on the tile.
    let total = tiles.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    // (content uri, bytes, box, position error) of each tile.
    type Written = (Option<String>, usize, Aabb3, f64);
    let written: Vec<Result<Written, TilesError>> = tiles
        .par_iter()
        .map(|t| {
            let (name, mesh, extras) = match t.kind {
                TileKind::Map(slot) => {
                    let m = &maps.maps[slot];
                    (
                        format!("map_{:x}.glb", t.key),
                        heightfield::heightfield_mesh(&m.map),
                        json!({"node_key": t.key, "eps_m": m.map.meta.eps_m,
                               "eps_measured_m": m.map.meta.eps_measured_m, "k": m.map.k()}),
                    )
                }
                TileKind::Buildings => (
                    format!("leaf_{:x}.glb", t.key),
                    leaf_mesh(city, meshes, &t.buildings),
                    json!({"node_key": t.key, "buildings": t.buildings.len()}),
                ),
            };
            let mut aabb = t
                .blocks
                .iter()
                .filter_map(|b| block_aabb.get(b))
                .fold(Aabb3::EMPTY, |a, b| a.union(*b));
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(d, total);
            if mesh.indices.is_empty() {
                return Ok((None, 0, aabb, 0.0));
            }
            aabb = aabb.union(mesh_aabb(&mesh));
            let path = dir.join("tiles").join(&name);
            let c = tile_glb(&name, &mesh, extras, opts.content).map_err(|source| {
                TilesError::Content {
                    path: path.clone(),
                    source,
                }
            })?;
            std::fs::write(tiles_dir.join(&name), &c.bytes).map_err(io(&path))?;
            Ok((
                Some(format!("tiles/{name}")),
                c.bytes.len(),
                aabb,
                c.position_error_m,
            ))
        })
        .collect();
    let mut position_error_m = 0.0f64;
    for (t, w) in tiles.iter_mut().zip(written) {
        let (content, bytes, aabb, err) = w?;
        position_error_m = position_error_m.max(err);
        t.content = content;
        t.content_bytes = bytes;
        // No flat box: a side of at least 2 cm (a leaf of blocks without buildings is flat).
        let (c, h) = (aabb.center(), (0.5 * aabb.extent()).max(DVec3::splat(0.01)));
        t.aabb = Aabb3::new(c - h, c + h);
    }
    // Boxes hold their children's (children come after parents: sweep backwards).
    for i in (0..tiles.len()).rev() {
        let kids = tiles[i].children.clone();
        for c in kids {
            let a = tiles[c].aabb;
            tiles[i].aabb = tiles[i].aabb.union(a);
        }
    }
    let root_ge = tiles[0].geometric_error;
    let root_box = tiles[0].aabb;
    let georef = georef(city);
    let crs = city.transform.describe();
    let terrain = match opts.terrain {
        Some(tin) => Some(terrain::write_terrain(
            tin,
            &city.frame,
            opts,
            georef.as_ref(),
            &crs,
            &staged.path().join("terrain"),
            &dir.join("terrain"),
        )?),
        None => None,
    };
    let implicit = match opts.implicit {
        true => {
            let mut imp =
                implicit::layout(&city.name, &tiles, tree.quadrant(0), opts.subtree_levels)?;
            implicit::write(&mut tiles, &mut imp, staged.path(), dir)?;
            Some(imp)
        }
        false => None,
    };
    let set = Tileset {
        geometric_error: root_ge.max(0.5 * root_box.extent().length()),
        georef,
        crs,
        tiles,
        terrain,
        implicit,
    };
    let doc = set.to_json();
    let path = dir.join("tileset.json");
    let text = serde_json::to_vec_pretty(&doc).expect("a JSON value serialises");
    std::fs::write(staged.path().join("tileset.json"), &text).map_err(io(&path))?;
    let archive_bytes = staged.commit()?;

    let depth = {
        let mut d = vec![0u32; set.tiles.len()];
        for i in 0..set.tiles.len() {
            for &c in &set.tiles[i].children {
                d[c] = d[i] + 1;
            }
        }
        d.into_iter().max().unwrap_or(0)
    };
    let summary = TilesetSummary {
        city: city.name.clone(),
        tiles: set.tiles.len(),
        map_tiles: set
            .tiles
            .iter()
            .filter(|t| matches!(t.kind, TileKind::Map(_)))
            .count(),
        leaf_tiles: set
            .tiles
            .iter()
            .filter(|t| t.kind == TileKind::Buildings)
            .count(),
        bytes: archive_bytes.unwrap_or(
            text.len() as u64
                + set.implicit.as_ref().map_or(0, |i| i.subtree_bytes)
                + set
                    .tiles
                    .iter()
                    .map(|t| t.content_bytes as u64)
                    .sum::<u64>()
                + set.terrain.as_ref().map_or(0, |t| {
                    t.json_bytes as u64
                        + t.tiles.iter().map(|t| t.content_bytes as u64).sum::<u64>()
                }),
        ),
        implicit: set.implicit.is_some(),
        subtrees: set.implicit.as_ref().map_or(0, |i| i.subtrees),
        archive: archive_bytes.is_some(),
        depth,
        seconds: t0.elapsed().as_secs_f64(),
        buildings: set.tiles.iter().map(|t| t.buildings.len()).sum(),
        terrain_tiles: set.terrain.as_ref().map_or(0, |t| t.tiles.len()),
        terrain_triangles: set
            .terrain
            .as_ref()
            .map_or(0, |t| t.tiles.iter().map(|t| t.triangles.len()).sum()),
        root_geometric_error: root_ge,
        georef: set.georef,
        crs: set.crs.clone(),
        tileset_json: if archive_bytes.is_some() {
            dir.to_path_buf()
        } else {
            path
        },
        content: opts.content,
        position_error_m: position_error_m
            .max(set.terrain.as_ref().map_or(0.0, |t| t.position_error_m)),
    };
    Ok((set, summary))
}

/// A box as 3D Tiles writes it: centre, then the three half-axes (x, y, z) as columns.
fn box_array(a: &Aabb3) -> [f64; 12] {
    let c = a.center();
    let h = 0.5 * a.extent();
    [c.x, c.y, c.z, h.x, 0.0, 0.0, 0.0, h.y, 0.0, 0.0, 0.0, h.z]
}

/// [`box_array`] as JSON.
fn box_json(a: &Aabb3) -> Value {
    json!(box_array(a))
}

/// A local box as an oriented box through `m` (local → the tile's frame, e.g. ECEF): the centre
/// and the three half-axes mapped (an affine map takes the box onto exactly that box).
fn box_json_through(a: &Aabb3, m: &DMat4) -> Value {
    let c = m.transform_point3(a.center());
    let h = 0.5 * a.extent();
    let [x, y, z] =
        [DVec3::X * h.x, DVec3::Y * h.y, DVec3::Z * h.z].map(|v| m.transform_vector3(v));
    json!([c.x, c.y, c.z, x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z])
}

impl Tileset {
    /// The `tileset.json` document (3D Tiles 1.1).
    pub fn to_json(&self) -> Value {
        fn tile(set: &Tileset, i: usize) -> Value {
            let t = &set.tiles[i];
            let mut v = json!({
                "boundingVolume": { "box": box_json(&t.aabb) },
                "geometricError": t.geometric_error,
                "refine": "REPLACE",
                "extras": {
                    "node_key": t.key,
                    "kind": match t.kind { TileKind::Map(_) => "blockmap", TileKind::Buildings => "buildings" },
                    "blocks": t.blocks.iter().map(|b| b.0).collect::<Vec<_>>(),
                },
            });
            if let Some(c) = &t.content {
                v["content"] = json!({ "uri": c });
            }
            if !t.children.is_empty() {
                v["children"] = Value::Array(t.children.iter().map(|&c| tile(set, c)).collect());
            }
            v
        }
        let mut root = match &self.implicit {
            Some(imp) => implicit::root_json(&self.tiles, imp),
            None => tile(self, 0),
        };
        let m = self.georef.map_or(DMat4::IDENTITY, |g| {
            DMat4::from_cols_array(&g.ecef_from_local)
        });
        if let Some(g) = &self.georef {
            root["transform"] = json!(g.ecef_from_local);
        }
        let mut geometric_error = self.geometric_error;
        if let Some(t) = &self.terrain {
            // Both trees under one root without content or transform, refined by ADD: the
            // buildings' tree carries the transform, the terrain's tileset its own.
            let t_root = &t.tiles[0];
            let both = self.tiles[0].aabb.union(t_root.aabb);
            geometric_error = geometric_error.max(t.geometric_error);
            root = json!({
                "boundingVolume": { "box": box_json_through(&both, &m) },
                "geometricError": geometric_error,
                "refine": "ADD",
                "extras": { "kind": "group" },
                "children": [
                    root,
                    {
                        "boundingVolume": { "box": box_json_through(&t_root.aabb, &m) },
                        "geometricError": t.geometric_error,
                        "content": { "uri": "terrain/tileset.json" },
                        "extras": { "kind": "external_terrain" },
                    },
                ],
            });
        }
        let mut doc = json!({
            "asset": {
                "version": "1.1",
                "generator": "blockwalk",
                "extras": {
                    "crs": self.crs,
                    "frame": "local metres from the city's origin: x east, y north, z up (grid axes of the CRS)",
                    "georeferenced": self.georef.is_some(),
                },
            },
            "geometricError": geometric_error,
            "root": root,
        });
        if self.implicit.is_some() {
            doc["schema"] = implicit::schema();
        }
        doc
    }
}

impl TilesetSummary {
    /// One line on where the tileset stands.
    pub fn placement(&self) -> String {
        match &self.georef {
            Some(g) => format!(
                "placed at {:.6}° E, {:.6}° N, {:.1} m above the WGS84 ellipsoid (grid convergence {:.3}°, scale {:.6})",
                g.lon_deg, g.lat_deg, g.height_m, g.convergence_deg, g.scale
            ),
            None => format!(
                "no transform written: the CRS ({}) has no geodetic meaning, so the tileset sits at the Earth's centre",
                self.crs
            ),
        }
    }
}

/// Ellipsoid points of a tileset for checks: `ecef_from_local · p` for a local point.
pub fn local_to_ecef(g: &Georef, p: DVec3) -> DVec3 {
    DMat4::from_cols_array(&g.ecef_from_local).transform_point3(p)
}

/// glTF content position (Y-up, as written) → local frame, as 3D Tiles reads it (the Y-up → Z-up
/// rotation of 3D Tiles 1.1, "glTF transforms").
pub fn local_from_gltf(p: Vec3) -> DVec3 {
    DVec3::new(p.x as f64, -(p.z as f64), p.y as f64)
}
