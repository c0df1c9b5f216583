//! Block types.

use crate::city::BuildingId;
use geo_types::{LineString, Polygon};
use serde::Serialize;

/// Index of a block in [`BlockLayout::blocks`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct BlockId(pub u32);

/// Whether a block is a face enclosed by streets, or a group of buildings outside every face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockKind {
    /// Land fully surrounded by streets.
    Block,
    /// Buildings in no enclosed face (edge of the data, cul-de-sacs), grouped so none is lost.
    Outskirts,
}

/// How the blocks were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockSource {
    /// Faces of the street graph.
    Streets,
    /// Connected unions of parcels.
    Parcels,
    /// Inferred from the gaps between footprints.
    Footprints,
}

/// A block: a polygon in metric world coordinates and the buildings assigned to it.
#[derive(Clone, Debug)]
pub struct Block {
    /// Index in [`BlockLayout::blocks`].
    pub id: BlockId,
    /// Face of the street graph or outskirts group.
    pub kind: BlockKind,
    /// Outline, metric world coordinates (exterior CCW, holes CW). For an outskirts group, the
    /// outline of its buildings' footprints (a convex hull).
    pub polygon: Polygon<f64>,
    /// Buildings assigned to this block (each building is in exactly one block).
    pub buildings: Vec<BuildingId>,
}

/// The result of block detection.
#[derive(Clone, Debug)]
pub struct BlockLayout {
    /// Blocks, then outskirts groups.
    pub blocks: Vec<Block>,
    /// How they were found.
    pub source: BlockSource,
    /// The noded street graph's edges (metric world coordinates), given or inferred.
    pub street_edges: Vec<LineString<f64>>,
    /// Number of dangling street ends (cul-de-sacs, edges of the data).
    pub dangles: usize,
}
