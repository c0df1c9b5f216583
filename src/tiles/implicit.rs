//! The tile tree as a 3D Tiles 1.1 implicit quadtree ("3D Tiles 1.1, Implicit Tiling" and
//! "Subtrees"): the same tiles, contents, boxes and geometric errors as the explicit
//! `tileset.json`, laid out by (level, x, y) instead of nested JSON.
//!
//! - Coordinates: the root tile is (0, 0, 0); a child in BqR quadrant `q` (`q = east + 2·north`,
//!   [`crate::index::BqrTree`]) of a tile at (l, x, y) is at (l + 1, 2x + east, 2y + north): the
//!   box's first axis is local x (east), its second local y (north), which is the Morton child
//!   order of the implicit quadtree. A tile whose node lies deeper than one level below its
//!   parent's (a chain of single-child nodes) takes the quadrant of its first step.
//! - The leaf of a mapped node's own blocks (key `4k + 4`, which is no quadrant) takes the first
//!   free child slot of its parent (south-west, south-east, north-west, north-east); a node whose
//!   four quadrants all hold tiles as well as blocks of its own cannot be written implicitly
//!   (an error names the node).
//! - The root tile in `tileset.json` carries `implicitTiling` (`QUADTREE`, `subtreeLevels`,
//!   `availableLevels`, subtrees at `subtrees/{level}/{x}/{y}.subtree`), the content template
//!   `tiles/{level}/{x}/{y}.glb` and the root transform. Its box is the root node's quadrant
//!   square (the square the keys subdivide) with the tiles' height range, grown to hold the root
//!   tile's box should that stick out.
//! - Implied volumes and halved errors are not the tiles': blocks are never cut, so a leaf's box
//!   is its blocks', not its square, and errors are the maps' ε. Each tile carries its own box
//!   and error as tile metadata ("3D Tiles 1.1, Metadata", semantics `TILE_BOUNDING_BOX` and
//!   `TILE_GEOMETRIC_ERROR`, which CesiumJS and 3d-tiles-tools apply to implicit tiles), with its
//!   BqR key (`node_key`) and kind (`blockmap` or `buildings`) as the explicit form's `extras`.
//!   A child subtree's placeholder, before its subtree file is read, has the implied volume.
//! - Subtree files are binary (`subt`, version 1): a JSON header and one buffer holding the
//!   availability bitstreams (tiles, contents, child subtrees: bit `i` at byte `i / 8`, bit
//!   `i % 8`, levels one after the other, Morton order inside a level; `constant` where every bit
//!   is equal) and the `tile` property table (one row per available tile, in availability order).
//! - Content files are the explicit form's, byte for byte, under the templated names.

use super::{Tile, TileKind, TilesError};
use crate::geom::Aabb3;
use glam::{DVec2, DVec3};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::Path;

/// Subtree levels by default.
pub const DEFAULT_SUBTREE_LEVELS: u32 = 6;

/// A tile's place in the implicit quadtree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileCoord {
    /// Level (root 0).
    pub level: u32,
    /// Column (eastward).
    pub x: u32,
    /// Row (northward).
    pub y: u32,
}

impl TileCoord {
    /// The Morton index of (x, y) inside its level: x in the even bits, y in the odd.
    pub fn morton(&self) -> u64 {
        let spread = |v: u32| -> u64 {
            let mut v = v as u64;
            v = (v | (v << 16)) & 0x0000_FFFF_0000_FFFF;
            v = (v | (v << 8)) & 0x00FF_00FF_00FF_00FF;
            v = (v | (v << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
            v = (v | (v << 2)) & 0x3333_3333_3333_3333;
            v = (v | (v << 1)) & 0x5555_5555_5555_5555;
            v
        };
        spread(self.x) | (spread(self.y) << 1)
    }

    /// The templated path `{prefix}/{level}/{x}/{y}.{ext}`.
    pub fn path(&self, prefix: &str, ext: &str) -> String {
        format!("{prefix}/{}/{}/{}.{ext}", self.level, self.x, self.y)
    }
}

/// The implicit layout of a tileset (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Implicit {
    /// Levels per subtree file.
    pub subtree_levels: u32,
    /// Levels holding tiles (the deepest tile's level + 1).
    pub available_levels: u32,
    /// Each tile's coordinates (parallel to [`super::Tileset::tiles`]).
    pub coords: Vec<TileCoord>,
    /// The root tile's box in `tileset.json`: the box the coordinates subdivide.
    pub root_box: Aabb3,
    /// Subtree files written.
    pub subtrees: usize,
    /// Their bytes.
    pub subtree_bytes: u64,
}

/// Depth of a linear quadtree key (root 1 → 0).
fn key_depth(k: u64) -> u32 {
    (63 - k.leading_zeros()) / 2
}

/// The quadrant of `parent` that holds the node `child`, or `None` when `child` is no
/// descendant of `parent`.
fn quadrant_below(parent: u64, child: u64) -> Option<u32> {
    let (dp, dc) = (key_depth(parent), key_depth(child));
    if dc <= dp || child >> (2 * (dc - dp)) != parent {
        return None;
    }
    Some(((child >> (2 * (dc - dp - 1))) & 3) as u32)
}

/// The quadrant square of node `key`, subdividing the root square `root`.
fn key_square(root: (DVec2, DVec2), key: u64) -> (DVec2, DVec2) {
    let (mut lo, mut hi) = root;
    for d in (0..key_depth(key)).rev() {
        let q = (key >> (2 * d)) & 3;
        let mid = 0.5 * (lo + hi);
        if q & 1 == 1 {
            lo.x = mid.x;
        } else {
            hi.x = mid.x;
        }
        if q & 2 == 2 {
            lo.y = mid.y;
        } else {
            hi.y = mid.y;
        }
    }
    (lo, hi)
}

/// The implicit coordinates of `tiles` (preorder, root first) and the root box.
/// `root_square` is the BqR root's quadrant (`None`: the root tile's box is used).
///
/// # Errors
/// [`TilesError::Implicit`] for a node whose children cannot take distinct slots.
pub fn layout(
    city: &str,
    tiles: &[Tile],
    root_square: Option<(DVec2, DVec2)>,
    subtree_levels: u32,
) -> Result<Implicit, TilesError> {
    let err = |what: String| TilesError::Implicit {
        city: city.to_string(),
        what,
    };
    if subtree_levels == 0 {
        return Err(err("subtree levels must be at least 1".into()));
    }
    let mut coords = vec![
        TileCoord {
            level: 0,
            x: 0,
            y: 0
        };
        tiles.len()
    ];
    for (i, t) in tiles.iter().enumerate() {
        let p = coords[i];
        let mut slots: [Option<usize>; 4] = [None; 4];
        let mut own = None;
        for &c in &t.children {
            let ck = tiles[c].key;
            if tiles[c].kind == TileKind::Buildings && ck == t.key.wrapping_mul(4) + 4 {
                own = Some(c);
                continue;
            }
            let q = quadrant_below(t.key, ck).ok_or_else(|| {
                err(format!(
                    "tile of node {ck:#x} is no descendant of its parent node {:#x}",
                    t.key
                ))
            })?;
            if let Some(o) = slots[q as usize] {
                return Err(err(format!(
                    "nodes {:#x} and {ck:#x} both lie in quadrant {q} of node {:#x}",
                    tiles[o].key, t.key
                )));
            }
            slots[q as usize] = Some(c);
        }
        if let Some(c) = own {
            let q = slots.iter().position(Option::is_none).ok_or_else(|| {
                err(format!(
                    "node {:#x} has tiles in all four quadrants and blocks of its own: no free \
                     child slot for them in an implicit quadtree (write the explicit form)",
                    t.key
                ))
            })?;
            slots[q] = Some(c);
        }
        for (q, c) in slots.iter().enumerate() {
            if let Some(c) = *c {
                if p.level >= 31 {
                    return Err(err(format!("node {:#x}: deeper than 31 levels", t.key)));
                }
                coords[c] = TileCoord {
                    level: p.level + 1,
                    x: 2 * p.x + (q as u32 & 1),
                    y: 2 * p.y + (q as u32 >> 1),
                };
            }
        }
    }
    let available_levels = coords.iter().map(|c| c.level).max().unwrap_or(0) + 1;
    let root = tiles.first().map_or(Aabb3::EMPTY, |t| t.aabb);
    let root_box = match root_square {
        Some(sq) => {
            let (lo, hi) = key_square(sq, tiles.first().map_or(1, |t| t.key));
            Aabb3::new(
                DVec3::new(lo.x, lo.y, root.min.z),
                DVec3::new(hi.x, hi.y, root.max.z),
            )
            .union(root)
        }
        None => root,
    };
    Ok(Implicit {
        subtree_levels,
        available_levels,
        coords,
        root_box,
        subtrees: 0,
        subtree_bytes: 0,
    })
}

/// The `schema` of `tileset.json`: the class of the tile metadata.
pub fn schema() -> Value {
    json!({
        "id": "blockwalk_tiles",
        "classes": {
            "tile": {
                "description": "A tile's own box and geometric error, and the BqR node it stands for.",
                "properties": {
                    "bounding_box": {
                        "type": "SCALAR", "componentType": "FLOAT64", "array": true, "count": 12,
                        "semantic": "TILE_BOUNDING_BOX",
                    },
                    "geometric_error": {
                        "type": "SCALAR", "componentType": "FLOAT64",
                        "semantic": "TILE_GEOMETRIC_ERROR",
                    },
                    "node_key": {
                        "description": "Linear quadtree key of the BqR node (root 1, child 4k + q; 4k + 4 for a node's own blocks).",
                        "type": "SCALAR", "componentType": "UINT64",
                    },
                    "kind": { "type": "ENUM", "enumType": "tile_kind" },
                },
            },
        },
        "enums": {
            "tile_kind": {
                "valueType": "UINT8",
                "values": [
                    { "name": "blockmap", "value": 0 },
                    { "name": "buildings", "value": 1 },
                ],
            },
        },
    })
}

/// The root tile of `tileset.json` (without transform).
pub fn root_json(tiles: &[Tile], imp: &Implicit) -> Value {
    json!({
        "boundingVolume": { "box": super::box_json(&imp.root_box) },
        "geometricError": tiles[0].geometric_error,
        "refine": "REPLACE",
        "content": { "uri": "tiles/{level}/{x}/{y}.glb" },
        "implicitTiling": {
            "subdivisionScheme": "QUADTREE",
            "subtreeLevels": imp.subtree_levels,
            "availableLevels": imp.available_levels,
            "subtrees": { "uri": "subtrees/{level}/{x}/{y}.subtree" },
        },
    })
}

/// Bits of one availability bitstream.
struct Bits(Vec<u8>, usize);

impl Bits {
    fn new(n: usize) -> Self {
        Self(vec![0; n.div_ceil(8)], n)
    }
    fn set(&mut self, i: usize) {
        self.0[i / 8] |= 1 << (i % 8);
    }
    fn count(&self) -> usize {
        self.0.iter().map(|b| b.count_ones() as usize).sum()
    }
}

/// The bytes of the subtree file rooted at tile `root`: `by_coord` finds tiles by coordinates.
fn subtree_bytes(
    tiles: &[Tile],
    imp: &Implicit,
    root: usize,
    by_coord: &HashMap<TileCoord, usize>,
) -> Vec<u8> {
    let s = imp.subtree_levels;
    let r = imp.coords[root];
    let n_tiles = ((1u64 << (2 * s)) - 1) / 3;
    let mut tile_bits = Bits::new(n_tiles as usize);
    let mut content_bits = Bits::new(n_tiles as usize);
    let mut child_bits = Bits::new(1usize << (2 * s));
    // (bit index, tile) of the subtree's tiles, found by walking down from its root.
    let mut rows: Vec<(usize, usize)> = Vec::new();
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let c = imp.coords[i];
        let l = c.level - r.level;
        let local = TileCoord {
            level: l,
            x: c.x - (r.x << l),
            y: c.y - (r.y << l),
        };
        if l == s {
            child_bits.set(local.morton() as usize);
            continue;
        }
        let bit = (((1u64 << (2 * l)) - 1) / 3 + local.morton()) as usize;
        tile_bits.set(bit);
        if tiles[i].content.is_some() {
            content_bits.set(bit);
        }
        rows.push((bit, i));
        stack.extend(tiles[i].children.iter().copied());
    }
    debug_assert!(rows
        .iter()
        .all(|&(_, i)| by_coord.get(&imp.coords[i]) == Some(&i)));
    rows.sort_unstable();

    let mut buffer: Vec<u8> = Vec::new();
    let mut views: Vec<Value> = Vec::new();
    let mut view = |bytes: &[u8]| -> usize {
        while !buffer.len().is_multiple_of(8) {
            buffer.push(0);
        }
        views.push(json!({ "buffer": 0, "byteOffset": buffer.len(), "byteLength": bytes.len() }));
        buffer.extend_from_slice(bytes);
        views.len() - 1
    };
    let mut availability = |b: &Bits| -> Value {
        let n = b.count();
        if n == 0 || n == b.1 {
            json!({ "constant": u8::from(n > 0) })
        } else {
            json!({ "bitstream": view(&b.0), "availableCount": n })
        }
    };
    let tile_av = availability(&tile_bits);
    let content_av = availability(&content_bits);
    let child_av = availability(&child_bits);
    let mut boxes = Vec::with_capacity(rows.len() * 96);
    let mut errors = Vec::with_capacity(rows.len() * 8);
    let mut keys = Vec::with_capacity(rows.len() * 8);
    let mut kinds = Vec::with_capacity(rows.len());
    for &(_, i) in &rows {
        let t = &tiles[i];
        for v in super::box_array(&t.aabb) {
            boxes.extend_from_slice(&v.to_le_bytes());
        }
        errors.extend_from_slice(&t.geometric_error.to_le_bytes());
        keys.extend_from_slice(&t.key.to_le_bytes());
        kinds.push(match t.kind {
            TileKind::Map(_) => 0u8,
            TileKind::Buildings => 1,
        });
    }
    let table = json!({
        "class": "tile",
        "count": rows.len(),
        "properties": {
            "bounding_box": { "values": view(&boxes) },
            "geometric_error": { "values": view(&errors) },
            "node_key": { "values": view(&keys) },
            "kind": { "values": view(&kinds) },
        },
    });
    while !buffer.len().is_multiple_of(8) {
        buffer.push(0);
    }
    let doc = json!({
        "buffers": [{ "byteLength": buffer.len() }],
        "bufferViews": views,
        "propertyTables": [table],
        "tileMetadata": 0,
        "tileAvailability": tile_av,
        "contentAvailability": [content_av],
        "childSubtreeAvailability": child_av,
    });
    let mut text = serde_json::to_vec(&doc).expect("a JSON value serialises");
    while !text.len().is_multiple_of(8) {
        text.push(b' ');
    }
    let mut out = Vec::with_capacity(24 + text.len() + buffer.len());
    out.extend_from_slice(b"subt");
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(text.len() as u64).to_le_bytes());
    out.extend_from_slice(&(buffer.len() as u64).to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&buffer);
    out
}

/// Writes the implicit form into the folder `dir` (where the explicit form's contents were
/// written): moves each content to its templated name (updating `tiles[i].content`) and writes
/// the subtree files. `shown` is the final folder, named in errors.
///
/// # Errors
/// [`TilesError::Io`] naming the file.
pub fn write(
    tiles: &mut [Tile],
    imp: &mut Implicit,
    dir: &Path,
    shown: &Path,
) -> Result<(), TilesError> {
    let io = |p: &str| {
        let path = shown.join(p);
        move |source| TilesError::Io { path, source }
    };
    for (t, c) in tiles.iter_mut().zip(&imp.coords) {
        if let Some(old) = &t.content {
            let new = c.path("tiles", "glb");
            let to = dir.join(&new);
            if let Some(p) = to.parent() {
                std::fs::create_dir_all(p).map_err(io(&new))?;
            }
            std::fs::rename(dir.join(old), &to).map_err(io(&new))?;
            t.content = Some(new);
        }
    }
    let by_coord: HashMap<TileCoord, usize> = imp
        .coords
        .iter()
        .enumerate()
        .map(|(i, c)| (*c, i))
        .collect();
    let roots: Vec<usize> = (0..tiles.len())
        .filter(|&i| imp.coords[i].level.is_multiple_of(imp.subtree_levels))
        .collect();
    let mut bytes = 0u64;
    for &r in &roots {
        let b = subtree_bytes(tiles, imp, r, &by_coord);
        let name = imp.coords[r].path("subtrees", "subtree");
        let to = dir.join(&name);
        if let Some(p) = to.parent() {
            std::fs::create_dir_all(p).map_err(io(&name))?;
        }
        std::fs::write(&to, &b).map_err(io(&name))?;
        bytes += b.len() as u64;
    }
    imp.subtrees = roots.len();
    imp.subtree_bytes = bytes;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_x_low() {
        let c = |x, y| TileCoord { level: 3, x, y }.morton();
        assert_eq!(c(0, 0), 0);
        assert_eq!(c(1, 0), 1);
        assert_eq!(c(0, 1), 2);
        assert_eq!(c(1, 1), 3);
        assert_eq!(c(2, 0), 4);
        assert_eq!(c(5, 3), 0b01_10_11);
        // Brute force: bit i of x at 2i, bit i of y at 2i + 1.
        for x in 0..64u32 {
            for y in 0..64u32 {
                let mut m = 0u64;
                for i in 0..6 {
                    m |= (((x >> i) & 1) as u64) << (2 * i);
                    m |= (((y >> i) & 1) as u64) << (2 * i + 1);
                }
                assert_eq!(TileCoord { level: 6, x, y }.morton(), m);
            }
        }
    }

    #[test]
    fn quadrants_follow_the_key_bits() {
        assert_eq!(quadrant_below(1, 4), Some(0));
        assert_eq!(quadrant_below(1, 7), Some(3));
        assert_eq!(quadrant_below(1, 4 * 6 + 2), Some(2));
        assert_eq!(quadrant_below(5, 4 * 5 + 1), Some(1));
        assert_eq!(quadrant_below(5, 4 * 6), None);
        assert_eq!(quadrant_below(5, 5), None);
        let sq = key_square((DVec2::ZERO, DVec2::splat(8.0)), 4 * 7 + 1);
        assert_eq!(sq, (DVec2::new(6.0, 4.0), DVec2::new(8.0, 6.0)));
    }
}
