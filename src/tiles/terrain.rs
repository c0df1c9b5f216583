//! The terrain's tileset (`terrain/tileset.json` beside the buildings' one): a quadtree of
//! square cells over the terrain's plan extent, each leaf a `.glb` of the TIN triangles whose
//! centroid lies in its cell.
//!
//! - The root cell is the square over the plan box of the TIN (local frame), its side the box's
//!   longer side. A cell holding more than [`super::TilesetOptions::terrain_leaf_triangles`]
//!   triangles is cut into four (a triangle goes to the quadrant holding its centroid, the
//!   lower halves half-open), down to [`MAX_DEPTH`]; empty quadrants get no tile. Every triangle
//!   lies in exactly one leaf.
//! - A leaf's content holds its triangles with their vertices shared between them; a vertex
//!   that two leaves share is written in both with the same f32 position and the same normal
//!   (area-weighted over all its triangles, not only the leaf's), so neighbouring leaves meet
//!   without a crack or a shading seam (compact contents snap positions to one grid for every
//!   tile, so a shared vertex still decodes to the same point in both). Colour: [`TERRAIN_COLOR`] as `COLOR_0`.
//! - Leaves are the full resolution: `geometricError` 0. Inner tiles have no content (no
//!   coarser terrain is made): drawing one draws nothing of its box, so its `geometricError` is
//!   its box's half diagonal, and viewers refine into the leaves wherever the terrain is more
//!   than a few pixels across.
//! - Boxes are the content's bounds (from the f32 positions written), parents the union of
//!   their children's, in the same local frame and under the same root `transform` as the
//!   buildings' tileset.

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde_json::{json, Value};

use super::{box_json, Georef, TilesError, TilesetOptions};
use crate::city::export::terrain::{TerrainTin, TERRAIN_COLOR};
use crate::city::export::{tile_glb, TileMesh};
use crate::city::{LocalFrame, Mesh};
use crate::geom::Aabb3;

/// Deepest cut of the terrain quadtree (root 0).
pub const MAX_DEPTH: u32 = 20;

/// One terrain tile.
#[derive(Clone, Debug, PartialEq)]
pub struct TerrainTile {
    /// Linear quadtree key: root 1, quadrant `q` of tile `k` is `4k + q` (q: bit 0 east, bit 1
    /// north).
    pub key: u64,
    /// The tile's square cell, local frame: south-west corner and side, metres.
    pub cell: (DVec2, f64),
    /// Bounding box, local frame; holds the content and every child's box.
    pub aabb: Aabb3,
    /// 0 at leaves (full resolution); the box's half diagonal for an inner tile (no content).
    pub geometric_error: f64,
    /// The TIN triangles in the content (indices into `TerrainTin::triangles`, ascending;
    /// leaves only).
    pub triangles: Vec<u32>,
    /// Content file, relative to the terrain tileset's folder (`None` for an inner tile).
    pub content: Option<String>,
    /// Content bytes.
    pub content_bytes: usize,
    /// Child tiles (indices into [`TerrainTiles::tiles`]).
    pub children: Vec<usize>,
}

/// The terrain tileset: its tiles, root first, parents before children.
#[derive(Clone, Debug, PartialEq)]
pub struct TerrainTiles {
    /// Tiles, preorder; `tiles[0]` is the root.
    pub tiles: Vec<TerrainTile>,
    /// Top-level geometric error (the root's).
    pub geometric_error: f64,
    /// Bytes of `terrain/tileset.json`.
    pub json_bytes: usize,
    /// The largest position error of the contents, metres (see
    /// [`super::TilesetSummary::position_error_m`]).
    pub position_error_m: f64,
}

/// Plans the quadtree (no content yet): cells and triangles, preorder.
fn plan(tin: &TerrainTin, frame: &LocalFrame, leaf_max: usize) -> Vec<TerrainTile> {
    let centroids: Vec<DVec2> = (0..tin.triangles.len())
        .map(|t| frame.to_local_f64(tin.centroid(t)).truncate())
        .collect();
    let (lo, hi) = centroids.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), &c| (lo.min(c), hi.max(c)),
    );
    let side = (hi - lo).max_element().max(1e-3);
    fn split(
        key: u64,
        cell: (DVec2, f64),
        tris: Vec<u32>,
        depth: u32,
        c: &(&[DVec2], usize),
        out: &mut Vec<TerrainTile>,
    ) -> usize {
        let me = out.len();
        out.push(TerrainTile {
            key,
            cell,
            aabb: Aabb3::EMPTY,
            geometric_error: 0.0,
            triangles: Vec::new(),
            content: None,
            content_bytes: 0,
            children: Vec::new(),
        });
        let (centroids, leaf_max) = *c;
        if tris.len() <= leaf_max || depth >= MAX_DEPTH {
            out[me].triangles = tris;
            return me;
        }
        let half = 0.5 * cell.1;
        let mid = cell.0 + DVec2::splat(half);
        let mut quads: [Vec<u32>; 4] = Default::default();
        for t in tris {
            let p = centroids[t as usize];
            let q = usize::from(p.x >= mid.x) + 2 * usize::from(p.y >= mid.y);
            quads[q].push(t);
        }
        for (q, tris) in quads.into_iter().enumerate() {
            if tris.is_empty() {
                continue;
            }
            let sw = cell.0 + DVec2::new((q & 1) as f64, (q >> 1) as f64) * half;
            let child = split(4 * key + q as u64, (sw, half), tris, depth + 1, c, out);
            out[me].children.push(child);
        }
        me
    }
    let mut out = Vec::new();
    if tin.triangles.is_empty() {
        return out;
    }
    split(
        1,
        (lo, side),
        (0..tin.triangles.len() as u32).collect(),
        0,
        &(&centroids, leaf_max),
        &mut out,
    );
    out
}

/// A leaf's content: its triangles, each vertex once (in order of first use), positions and
/// normals taken from the whole TIN's mesh.
fn leaf_mesh(tin: &TerrainTin, mesh: &Mesh, tris: &[u32]) -> TileMesh {
    let mut t = TileMesh::default();
    let mut slot: HashMap<u32, u32> = HashMap::new();
    for &tri in tris {
        for v in tin.triangles[tri as usize] {
            let k = *slot.entry(v).or_insert_with(|| {
                t.positions.push(mesh.positions[v as usize]);
                t.normals.push(mesh.normals[v as usize]);
                t.colors.push(TERRAIN_COLOR);
                t.positions.len() as u32 - 1
            });
            t.indices.push(k);
        }
    }
    t
}

/// Builds the terrain's tiles and writes them into `dir` (the staged `terrain` folder;
/// `final_dir` is where it will be, for error messages): `tiles/t_<key>.glb` and
/// `tileset.json`. `georef` is the buildings' root transform, written on the terrain's root;
/// `opts` gives the leaves' size and the contents' encoding.
pub(super) fn write_terrain(
    tin: &TerrainTin,
    frame: &LocalFrame,
    opts: &TilesetOptions<'_>,
    georef: Option<&Georef>,
    crs: &str,
    dir: &Path,
    final_dir: &Path,
) -> Result<TerrainTiles, TilesError> {
    let (leaf_max, content) = (opts.terrain_leaf_triangles, opts.content);
    tin.check()
        .map_err(|source| TilesError::Terrain { source })?;
    let mesh = tin.local_mesh(frame);
    let mut tiles = plan(tin, frame, leaf_max.max(1));
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| TilesError::Io { path, source }
    };
    std::fs::create_dir_all(dir.join("tiles")).map_err(io(&final_dir.join("tiles")))?;
    type Written = (Option<String>, usize, Aabb3, f64);
    let written: Vec<Result<Written, TilesError>> = tiles
        .par_iter()
        .map(|t| {
            if t.triangles.is_empty() {
                return Ok((None, 0, Aabb3::EMPTY, 0.0));
            }
            let m = leaf_mesh(tin, &mesh, &t.triangles);
            let aabb = m.positions.iter().fold(Aabb3::EMPTY, |a, p| {
                let p = p.as_dvec3();
                a.union(Aabb3::new(p, p))
            });
            let name = format!("t_{:x}.glb", t.key);
            let path = final_dir.join("tiles").join(&name);
            let extras =
                json!({"kind": "terrain", "node_key": t.key, "triangles": t.triangles.len()});
            let c = tile_glb(&name, &m, extras, content).map_err(|source| TilesError::Content {
                path: path.clone(),
                source,
            })?;
            std::fs::write(dir.join("tiles").join(&name), &c.bytes).map_err(io(&path))?;
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
        t.aabb = aabb;
    }
    // Parents: the union of their children (after them in preorder: sweep backwards), their
    // half diagonal as error, at least their children's.
    for i in (0..tiles.len()).rev() {
        let kids = tiles[i].children.clone();
        for &c in &kids {
            let a = tiles[c].aabb;
            tiles[i].aabb = tiles[i].aabb.union(a);
        }
        // No flat box: a side of at least 2 cm (a flat terrain).
        let (c, h) = (
            tiles[i].aabb.center(),
            (0.5 * tiles[i].aabb.extent()).max(DVec3::splat(0.01)),
        );
        tiles[i].aabb = Aabb3::new(c - h, c + h);
        if !kids.is_empty() {
            let own = h.length();
            let below = kids
                .iter()
                .map(|&c| tiles[c].geometric_error)
                .fold(0.0, f64::max);
            tiles[i].geometric_error = own.max(below);
        }
    }
    let mut set = TerrainTiles {
        geometric_error: tiles.first().map_or(0.0, |t| t.geometric_error),
        tiles,
        json_bytes: 0,
        position_error_m,
    };
    let text = serde_json::to_vec_pretty(&set.to_json(georef, crs)).expect("JSON serialises");
    std::fs::write(dir.join("tileset.json"), &text).map_err(io(&final_dir.join("tileset.json")))?;
    set.json_bytes = text.len();
    Ok(set)
}

impl TerrainTiles {
    /// The root tile as the tile tree of `tileset.json` (no transform).
    pub fn root_json(&self) -> Value {
        fn tile(set: &TerrainTiles, i: usize) -> Value {
            let t = &set.tiles[i];
            let mut v = json!({
                "boundingVolume": { "box": box_json(&t.aabb) },
                "geometricError": t.geometric_error,
                "refine": "REPLACE",
                "extras": {
                    "kind": "terrain",
                    "node_key": t.key,
                    "triangles": t.triangles.len(),
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
        tile(self, 0)
    }

    /// The terrain's `tileset.json` (3D Tiles 1.1): the root carries `georef`'s transform, the
    /// buildings' tileset's, so that it stands on its own where the buildings stand.
    pub fn to_json(&self, georef: Option<&Georef>, crs: &str) -> Value {
        let mut root = self.root_json();
        if let Some(g) = georef {
            root["transform"] = json!(g.ecef_from_local);
        }
        json!({
            "asset": {
                "version": "1.1",
                "generator": "blockwalk",
                "extras": {
                    "crs": crs,
                    "frame": "local metres from the city's origin: x east, y north, z up (grid axes of the CRS)",
                    "georeferenced": georef.is_some(),
                    "content": "terrain TIN, full resolution at the leaves",
                },
            },
            "geometricError": self.geometric_error,
            "root": root,
        })
    }
}
