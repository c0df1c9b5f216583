//! A tiled city as a client holds it: the index and every tile's hierarchy (blocks' boxes,
//! BlockMap nodes with their errors, content files, ranges and hashes), nothing of the content.

use std::sync::Arc;
use std::time::Instant;

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::blockmap::{BlockMapMeta, SelectNode};
use crate::blocks::BlockId;
use crate::geom::{Aabb3, LocalFrame};
use crate::index::BlockBounds;
use crate::jobs::pack::TileHierarchy;
use crate::jobs::{TileIndex, INDEX_FORMAT};

use super::source::{FetchError, Source};
use super::StreamError;

/// A piece of content a client fetches: a block's mesh record or a node's map.
#[derive(Clone, Debug, PartialEq)]
pub struct Content {
    /// What it is.
    pub kind: ContentKind,
    /// File relative to the city's folder.
    pub file: String,
    /// Byte range in the file (`None`: the whole file).
    pub range: Option<(u64, u64)>,
    /// Bytes to fetch.
    pub bytes: u64,
    /// CRC-32 of those bytes, 8 hex digits.
    pub crc32: String,
    /// The tile it belongs to.
    pub tile: usize,
}

/// What a [`Content`] is.
#[derive(Clone, Debug, PartialEq)]
pub enum ContentKind {
    /// The mesh of a block.
    Mesh {
        /// Its slot in [`StreamCity::bounds`].
        slot: usize,
        /// The record is a zlib stream (else raw).
        zlib: bool,
        /// Bytes of the raw record.
        inflated: u64,
    },
    /// The map of node `usize` ([`StreamCity::nodes`]), with its box and error.
    Map(usize, Box<BlockMapMeta>),
}

/// Index of a [`Content`] in [`StreamCity::contents`].
pub type ContentId = u32;

/// A tile left out at startup, and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RefusedTile {
    /// The tile.
    pub tile: usize,
    /// Its buildings, not drawn.
    pub buildings: usize,
    /// The file and the reason.
    pub why: String,
}

/// What opening the city took.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Startup {
    /// Where the city comes from.
    pub source: String,
    /// Seconds to read and check the index and the hierarchies.
    pub seconds: f64,
    /// Bytes read (index and hierarchies).
    pub bytes_read: u64,
    /// Bytes the hierarchy takes in memory (blocks, nodes, contents), estimated from its sizes.
    pub hierarchy_bytes: u64,
    /// Tiles, blocks, buildings and map nodes of the city.
    pub tiles: usize,
    /// Blocks.
    pub blocks: usize,
    /// Buildings.
    pub buildings: usize,
    /// Map nodes.
    pub maps: usize,
    /// Bytes of all the content (meshes and maps) the hierarchy names.
    pub content_bytes: u64,
    /// Tiles left out, with the reason.
    pub refused: Vec<RefusedTile>,
}

/// A tiled city opened for streaming (see the module doc).
#[derive(Debug)]
pub struct StreamCity {
    /// Where its files come from.
    pub source: Arc<Source>,
    /// The index.
    pub index: TileIndex,
    /// The whole city's local frame.
    pub frame: LocalFrame,
    /// Every block's bounds (block ids are the plan's), by slot.
    pub bounds: Vec<BlockBounds>,
    /// The far-field nodes, parents first (keys are their indices).
    pub nodes: Vec<SelectNode>,
    /// Every piece of content (shared with the loader's workers).
    pub contents: Arc<Vec<Content>>,
    /// Per block slot, its mesh's content (`None`: no triangles).
    pub block_content: Vec<Option<ContentId>>,
    /// Per node, its map's content.
    pub node_content: Vec<ContentId>,
    /// Per block slot, the deepest node holding it.
    pub block_leaf: Vec<Option<usize>>,
    /// Block id → slot.
    pub slot: std::collections::HashMap<BlockId, usize>,
    /// What opening took.
    pub startup: Startup,
}

fn fetch_err(e: FetchError) -> StreamError {
    StreamError::Fetch(e)
}

impl StreamCity {
    /// Opens the tiled city at `location` (see [`Source::parse`]): reads `index.json`, then every
    /// tile's hierarchy, each checked against the size and CRC-32 the index gives. A tile whose
    /// hierarchy is missing or damaged is left out and listed in [`Startup::refused`].
    ///
    /// # Errors
    /// An index that cannot be read or is not a `jobs` index; a city where every tile is
    /// refused.
    pub fn open(location: &str) -> Result<Self, StreamError> {
        let t0 = Instant::now();
        let (source, name) = Source::parse(location);
        let text = source.fetch(&name, None).map_err(|e| match e {
            FetchError::Missing(file) => StreamError::Format {
                file,
                why: "missing: a tiled city's index, written by `blockwalk jobs merge DIR` once every tile has run".into(),
            },
            e => fetch_err(e),
        })?;
        let iname = source.name_of(&name);
        let index: TileIndex = serde_json::from_slice(&text).map_err(|e| StreamError::Format {
            file: iname.clone(),
            why: format!("not a tile index written by `blockwalk jobs merge`: {e}"),
        })?;
        if index.format != INDEX_FORMAT {
            return Err(StreamError::Format {
                file: iname,
                why: format!("format {:?}, expected {INDEX_FORMAT:?}", index.format),
            });
        }
        let mut bytes_read = text.len() as u64;
        // Every tile's hierarchy, read in parallel.
        let read: Vec<Result<Option<TileHierarchy>, String>> = index
            .tiles
            .par_iter()
            .map(|t| {
                let Some(f) = t.files.iter().find(|f| f.path.ends_with(".hier.json")) else {
                    return if t.buildings == 0 {
                        Ok(None)
                    } else {
                        Err(format!(
                            "tile {}: no hierarchy in the index (its job ran with an older blockwalk: run it again, then `jobs merge`)",
                            t.id
                        ))
                    };
                };
                let bytes = source.fetch(&f.path, None).map_err(|e| e.to_string())?;
                let crc = crate::jobs::pack::crc32_hex(&bytes);
                if bytes.len() as u64 != f.bytes || crc != f.crc32 {
                    return Err(format!(
                        "{}: {} bytes, CRC-32 {crc}; the index says {} bytes, {}",
                        source.name_of(&f.path),
                        bytes.len(),
                        f.bytes,
                        f.crc32
                    ));
                }
                TileHierarchy::parse(&bytes, std::path::Path::new(&source.name_of(&f.path)))
                    .map(Some)
                    .map_err(|e| e.to_string())
            })
            .collect();
        let mut city = StreamCity {
            frame: LocalFrame {
                origin: DVec3::new(index.frame_origin[0], index.frame_origin[1], 0.0),
            },
            source: Arc::new(source),
            bounds: Vec::new(),
            nodes: Vec::new(),
            contents: Arc::new(Vec::new()),
            block_content: Vec::new(),
            node_content: Vec::new(),
            block_leaf: Vec::new(),
            slot: Default::default(),
            startup: Startup {
                source: String::new(),
                seconds: 0.0,
                bytes_read: 0,
                hierarchy_bytes: 0,
                tiles: index.tiles.len(),
                blocks: 0,
                buildings: 0,
                maps: 0,
                content_bytes: 0,
                refused: Vec::new(),
            },
            index,
        };
        for (t, r) in read.into_iter().enumerate() {
            let tile = &city.index.tiles[t];
            match r {
                Ok(None) => {}
                Ok(Some(h)) => {
                    bytes_read += tile
                        .files
                        .iter()
                        .find(|f| f.path.ends_with(".hier.json"))
                        .map_or(0, |f| f.bytes);
                    if h.plan_id != city.index.plan_id || h.tile != tile.id {
                        city.startup.refused.push(RefusedTile {
                            tile: tile.id,
                            buildings: tile.buildings,
                            why: format!(
                                "hierarchy of tile {} of plan {}, the index is tile {} of plan {}",
                                h.tile, h.plan_id, tile.id, city.index.plan_id
                            ),
                        });
                        continue;
                    }
                    city.add_tile(t, h);
                }
                Err(why) => city.startup.refused.push(RefusedTile {
                    tile: tile.id,
                    buildings: tile.buildings,
                    why,
                }),
            }
        }
        if city.bounds.is_empty() && !city.startup.refused.is_empty() {
            return Err(StreamError::Format {
                file: city.source.name_of(&name),
                why: format!(
                    "every tile was refused; the first: {}",
                    city.startup.refused[0].why
                ),
            });
        }
        city.startup.source = city.source.describe();
        city.startup.bytes_read = bytes_read;
        city.startup.blocks = city.bounds.len();
        city.startup.maps = city.nodes.len();
        city.startup.content_bytes = city.contents.iter().map(|c| c.bytes).sum();
        city.startup.hierarchy_bytes = (city.bounds.len() * std::mem::size_of::<BlockBounds>()
            + city
                .nodes
                .iter()
                .map(|n| std::mem::size_of::<SelectNode>() + 4 * n.blocks.len())
                .sum::<usize>()
            + city
                .contents
                .iter()
                .map(|c| std::mem::size_of::<Content>() + c.file.len() + c.crc32.len() + 96)
                .sum::<usize>()
            + city.bounds.len() * 48) as u64;
        city.startup.seconds = t0.elapsed().as_secs_f64();
        Ok(city)
    }

    fn add_tile(&mut self, t: usize, h: TileHierarchy) {
        let contents = Arc::get_mut(&mut self.contents).expect("not shared while opening");
        self.startup.buildings += h.blocks.iter().map(|b| b.buildings).sum::<usize>();
        for b in &h.blocks {
            let slot = self.bounds.len();
            self.slot.insert(BlockId(b.id), slot);
            self.bounds.push(BlockBounds {
                id: BlockId(b.id),
                aabb: b.aabb,
                sphere: b.sphere,
                center: DVec2::from_array(b.center),
                triangles: b.triangles.min(u32::MAX as u64) as u32,
            });
            self.block_leaf.push(None);
            self.block_content.push(match (&b.mesh, &h.pack) {
                (Some(r), Some(pack)) => {
                    contents.push(Content {
                        kind: ContentKind::Mesh {
                            slot,
                            zlib: h.compression.as_deref() == Some("zlib"),
                            inflated: if r.inflated > 0 { r.inflated } else { r.bytes },
                        },
                        file: pack.clone(),
                        range: Some((r.offset, r.bytes)),
                        bytes: r.bytes,
                        crc32: r.crc32.clone(),
                        tile: t,
                    });
                    Some(contents.len() as ContentId - 1)
                }
                _ => None,
            });
        }
        let base = self.nodes.len();
        for m in h.maps {
            let i = self.nodes.len();
            let min = DVec3::from_array(m.meta.min);
            let aabb = Aabb3::new(
                min,
                DVec3::new(min.x + m.meta.side, min.y + m.meta.side, m.meta.zmax),
            );
            for b in &m.blocks {
                if let Some(&s) = self.slot.get(&BlockId(*b)) {
                    self.block_leaf[s] = Some(i);
                }
            }
            self.nodes.push(SelectNode {
                key: i as u64,
                eps_m: m.meta.eps_m,
                aabb,
                parent: m.parent.map(|p| p + base),
                blocks: m.blocks.iter().map(|&b| BlockId(b)).collect(),
            });
            contents.push(Content {
                kind: ContentKind::Map(i, Box::new(m.meta)),
                file: m.png.path.clone(),
                range: None,
                bytes: m.png.bytes,
                crc32: m.png.crc32.clone(),
                tile: t,
            });
            self.node_content.push(contents.len() as ContentId - 1);
        }
    }

    /// The box of every block, local frame.
    pub fn city_box(&self) -> Aabb3 {
        self.bounds
            .iter()
            .fold(Aabb3::EMPTY, |a, b| a.union(b.aabb))
    }
}
