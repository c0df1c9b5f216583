//! The block stage's entry point: [`detect`] on a [`City`], or [`detect_geometry`] on plain
//! geometry.

use super::assign::{assign, outskirts_groups, DEFAULT_OUTSKIRTS_LINK};
use super::faces::faces;
use super::infer::{
    blocks_from_footprints, blocks_from_parcels, gap_centrelines, DEFAULT_STREET_WIDTH,
};
use super::noding::{node_lines, DEFAULT_SNAP_TOLERANCE};
use super::types::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use crate::city::{BuildingId, City};
use geo_types::{LineString, Polygon};
use std::borrow::Borrow;

/// Parameters of block detection. Lengths in metres (the city's metric world units).
#[derive(Clone, Debug, PartialEq)]
pub struct BlockOptions {
    /// Points closer than this are one node; a line end this close to another line joins it.
    /// Default [`DEFAULT_SNAP_TOLERANCE`] (0.05 m).
    pub snap_tolerance: f64,
    /// Use this source instead of the first available of streets → parcels → footprints.
    pub force_source: Option<BlockSource>,
    /// Honour grade separation: leave bridges and tunnels (`Street::grade_separated`) out of the
    /// street graph, so a street passing over or under land does not bound a block.
    ///
    /// Default `false`: every street line bounds blocks, as in the planar reference (Pina, Serón and Cerezo, §3
    /// "completely surrounded by streets"; momepy's `enclosures` and shapely's
    /// `polygonize(union_all(lines))` use every line). A bridge over water or a railway then closes
    /// the blocks on either side, which is what a block layer is expected to show. Set it when the
    /// layer holds bridges or tunnels that cross the middle of built land (a flyover above a
    /// street block, a road tunnel under one): with the default they would split that block in
    /// two.
    pub grade_separation: bool,
    /// Outskirts buildings within this distance of each other form one group. Default
    /// [`DEFAULT_OUTSKIRTS_LINK`] (30 m).
    pub outskirts_link: f64,
    /// Blocks from footprints: buildings closer than this are in one block. Default
    /// [`DEFAULT_STREET_WIDTH`] (20 m).
    pub street_width: f64,
}

impl Default for BlockOptions {
    fn default() -> Self {
        Self {
            snap_tolerance: DEFAULT_SNAP_TOLERANCE,
            force_source: None,
            grade_separation: false,
            outskirts_link: DEFAULT_OUTSKIRTS_LINK,
            street_width: DEFAULT_STREET_WIDTH,
        }
    }
}

/// Why blocks could not be detected.
#[derive(Debug, thiserror::Error)]
pub enum BlockError {
    /// A source was forced but the city has no such layer.
    #[error("blocks from {wanted:?} were asked for, but the city has no {layer} layer")]
    MissingLayer {
        /// The forced source.
        wanted: BlockSource,
        /// The missing layer.
        layer: &'static str,
    },
    /// A feature has a NaN or infinite coordinate.
    #[error("{layer} feature {id}: non-finite coordinate")]
    NonFinite {
        /// Which layer.
        layer: &'static str,
        /// The feature's source id.
        id: String,
    },
    /// An option is out of range.
    #[error("option {name} = {value} is out of range ({why})")]
    BadOption {
        /// Option name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The valid range.
        why: &'static str,
    },
}

fn finite_line(l: &LineString<f64>) -> bool {
    l.0.iter().all(|c| c.x.is_finite() && c.y.is_finite())
}

fn finite_poly(p: &Polygon<f64>) -> bool {
    finite_line(p.exterior()) && p.interiors().iter().all(finite_line)
}

/// Detects the blocks of a city and assigns every building to exactly one block (Pina, Serón and Cerezo, §3).
///
/// The source is the street layer when there is one, else the parcels, else the footprints (or
/// [`BlockOptions::force_source`]). Blocks are in the city's metric world coordinates.
///
/// # Errors
/// [`BlockError`] for a forced source without its layer, a non-finite coordinate, or a bad option.
pub fn detect(city: &City, opts: &BlockOptions) -> Result<BlockLayout, BlockError> {
    for b in &city.buildings {
        if !finite_poly(&b.footprint) {
            return Err(BlockError::NonFinite {
                layer: "building",
                id: b.source_id.clone(),
            });
        }
    }
    let source = match opts.force_source {
        Some(s) => {
            let missing = match s {
                BlockSource::Streets if city.streets.is_empty() => Some("street"),
                BlockSource::Parcels if city.parcels.is_empty() => Some("parcel"),
                _ => None,
            };
            if let Some(layer) = missing {
                return Err(BlockError::MissingLayer { wanted: s, layer });
            }
            s
        }
        None if !city.streets.is_empty() => BlockSource::Streets,
        None if !city.parcels.is_empty() => BlockSource::Parcels,
        None => BlockSource::Footprints,
    };
    for s in &city.streets {
        if !finite_line(&s.line) {
            return Err(BlockError::NonFinite {
                layer: "street",
                id: s.source_id.clone(),
            });
        }
    }
    for p in &city.parcels {
        if !finite_poly(&p.polygon) {
            return Err(BlockError::NonFinite {
                layer: "parcel",
                id: p.source_id.clone(),
            });
        }
    }
    // The geometry is borrowed, not copied; parcels are only dissolved when they are the source.
    let lines = city
        .streets
        .iter()
        .filter(|s| !(opts.grade_separation && s.grade_separated))
        .map(|s| &s.line);
    let parcels: Vec<Polygon<f64>> = if source == BlockSource::Parcels {
        city.parcels.iter().map(|p| p.polygon.clone()).collect()
    } else {
        Vec::new()
    };
    let footprints: Vec<&Polygon<f64>> = city.buildings.iter().map(|b| &b.footprint).collect();
    detect_parts(source, lines, &parcels, &footprints, opts)
}

/// [`detect`] on plain geometry in any planar units (lengths in the options are in those units):
/// `lines` for [`BlockSource::Streets`], `parcels` for [`BlockSource::Parcels`]; `footprints` are
/// the buildings, `BuildingId(i)` for `footprints[i]`.
///
/// # Errors
/// [`BlockError::BadOption`] for a negative or non-finite length, or a snap tolerance outside
/// [`super::noding::MIN_SNAP_TOLERANCE`]..=[`super::noding::MAX_SNAP_TOLERANCE`].
pub fn detect_geometry(
    source: BlockSource,
    lines: &[LineString<f64>],
    parcels: &[Polygon<f64>],
    footprints: &[Polygon<f64>],
    opts: &BlockOptions,
) -> Result<BlockLayout, BlockError> {
    detect_parts(source, lines, parcels, footprints, opts)
}

/// [`detect_geometry`] on borrowed lines and footprints.
fn detect_parts<'a, P: Borrow<Polygon<f64>> + Sync>(
    source: BlockSource,
    lines: impl IntoIterator<Item = &'a LineString<f64>>,
    parcels: &[Polygon<f64>],
    footprints: &[P],
    opts: &BlockOptions,
) -> Result<BlockLayout, BlockError> {
    let max_snap = super::noding::MAX_SNAP_TOLERANCE;
    if opts.snap_tolerance.is_finite() && opts.snap_tolerance > max_snap {
        return Err(BlockError::BadOption {
            name: "snap_tolerance",
            value: opts.snap_tolerance,
            why: "at most MAX_SNAP_TOLERANCE = 5 m: larger tolerances merge street corners and collapse blocks",
        });
    }
    if opts.snap_tolerance.is_finite() && opts.snap_tolerance < super::noding::MIN_SNAP_TOLERANCE {
        return Err(BlockError::BadOption {
            name: "snap_tolerance",
            value: opts.snap_tolerance,
            why: "at least MIN_SNAP_TOLERANCE = 1 mm: computed crossings are rounded, so a smaller tolerance cannot promise a planar street graph",
        });
    }
    for (name, value) in [
        ("snap_tolerance", opts.snap_tolerance),
        ("outskirts_link", opts.outskirts_link),
        ("street_width", opts.street_width),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(BlockError::BadOption {
                name,
                value,
                why: "a finite length >= 0",
            });
        }
    }
    let tol = opts.snap_tolerance;
    let (polys, street_edges, dangles) = match source {
        BlockSource::Streets => {
            let graph = node_lines(lines, tol);
            let fs = faces(&graph);
            let polys: Vec<Polygon<f64>> = fs.bounded().map(|i| fs.polygon(i)).collect();
            (polys, graph.edge_lines(), graph.dangles())
        }
        BlockSource::Parcels | BlockSource::Footprints => {
            let polys = if source == BlockSource::Parcels {
                blocks_from_parcels(parcels, tol)
            } else {
                let owned: Vec<Polygon<f64>> =
                    footprints.iter().map(|p| p.borrow().clone()).collect();
                blocks_from_footprints(&owned, opts.street_width, tol)
            };
            let step = 0.5 * opts.street_width.max(1.0);
            let centre = gap_centrelines(&polys, step, 3.0 * opts.street_width.max(1.0));
            let graph = node_lines(&centre, tol);
            (polys, graph.edge_lines(), graph.dangles())
        }
    };
    let which = assign(footprints, &polys);
    let mut blocks: Vec<Block> = polys
        .into_iter()
        .enumerate()
        .map(|(i, polygon)| Block {
            id: BlockId(i as u32),
            kind: BlockKind::Block,
            polygon,
            buildings: Vec::new(),
        })
        .collect();
    let mut unassigned = Vec::new();
    for (b, w) in which.iter().enumerate() {
        match w {
            Some(k) => blocks[*k].buildings.push(BuildingId(b as u32)),
            None => unassigned.push(b),
        }
    }
    for (polygon, group) in outskirts_groups(footprints, &unassigned, opts.outskirts_link) {
        let id = BlockId(blocks.len() as u32);
        blocks.push(Block {
            id,
            kind: BlockKind::Outskirts,
            polygon,
            buildings: group.into_iter().map(|b| BuildingId(b as u32)).collect(),
        });
    }
    Ok(BlockLayout {
        blocks,
        source,
        street_edges,
        dangles,
    })
}
