//! What maps are built from: the city's buildings in the local frame (f64 rings, prism heights,
//! appearance) beside their meshes. Construction ([`super::build`]), the error measure
//! ([`super::error`]) and the comparisons all read the buildings from here.

use super::BlockMapError;
use crate::blocks::{BlockId, BlockLayout};
use crate::city::appearance::{building_style, ring_u, BuildingStyle};
use crate::city::{BuildingId, City, Mesh};
use glam::DVec2;

/// A building as the construction and the error measure see it: local frame, f64.
#[derive(Clone, Debug)]
pub struct SourceBuilding {
    /// The building.
    pub id: BuildingId,
    /// Its source id (for reports).
    pub source_id: String,
    /// Its block.
    pub block: BlockId,
    /// Rings in the local frame (exterior CCW first, then holes CW), closing point dropped.
    pub rings: Vec<Vec<DVec2>>,
    /// The ground under the building (its base), local z, metres: 0 without terrain.
    pub ground: f64,
    /// Bottom of the prism, metres.
    pub z0: f64,
    /// Top of the prism, metres.
    pub z1: f64,
    /// Footprint box (local).
    pub min: DVec2,
    /// Footprint box (local).
    pub max: DVec2,
    /// True when the source marks it a bridge (`bridge` / `man_made=bridge` attributes).
    pub bridge: bool,
    /// Its appearance.
    pub style: BuildingStyle,
    /// Per ring, `u` (metres along the unfolded ring) at each vertex and the perimeter
    /// ([`crate::city::appearance::ring_u`]).
    pub ring_u: Vec<Vec<f32>>,
}

/// Everything maps are built from: the buildings (local frame) and their meshes.
#[derive(Clone, Debug)]
pub struct Source<'a> {
    /// Buildings, indexed like `City::buildings`; `None` for a building in no block.
    pub buildings: Vec<Option<SourceBuilding>>,
    /// One mesh per building (local frame), as `city::extrude::extrude_city` returns.
    pub meshes: &'a [Mesh],
    /// The city (for the appearance).
    pub city: &'a City,
    /// The terrain the buildings stand on (full-resolution mesh, local frame), when there is
    /// one: the ground is then that surface, not z = 0 ([`Source::with_terrain`]).
    pub terrain: Option<&'a Mesh>,
}

impl<'a> Source<'a> {
    /// The same buildings standing on `terrain` (the full mesh, local frame: see
    /// `visibility::TerrainDraw::full`).
    pub fn with_terrain(self, terrain: &'a Mesh) -> Self {
        Self {
            terrain: Some(terrain),
            ..self
        }
    }

    /// Prepares the buildings of `city` that `layout` assigns to a block.
    ///
    /// # Errors
    /// [`BlockMapError::BadParameter`] when `meshes` does not hold one mesh per building.
    pub fn new(
        city: &'a City,
        layout: &BlockLayout,
        meshes: &'a [Mesh],
    ) -> Result<Self, BlockMapError> {
        if meshes.len() != city.buildings.len() {
            return Err(BlockMapError::BadParameter(format!(
                "{} meshes for {} buildings",
                meshes.len(),
                city.buildings.len()
            )));
        }
        let o = city.frame.origin;
        let mut buildings: Vec<Option<SourceBuilding>> = vec![None; city.buildings.len()];
        for block in &layout.blocks {
            for bid in &block.buildings {
                let Some(b) = city.buildings.get(bid.0 as usize) else {
                    continue;
                };
                let ring = |r: &geo_types::LineString<f64>| -> Vec<DVec2> {
                    let mut v: Vec<DVec2> =
                        r.0.iter()
                            .map(|c| DVec2::new(c.x - o.x, c.y - o.y))
                            .collect();
                    if v.len() >= 2 && v[0] == v[v.len() - 1] {
                        v.pop();
                    }
                    v
                };
                let mut rings = vec![ring(b.footprint.exterior())];
                rings.extend(b.footprint.interiors().iter().map(ring));
                let (mut min, mut max) =
                    (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
                for p in &rings[0] {
                    min = min.min(*p);
                    max = max.max(*p);
                }
                let bridge = b.attributes.iter().any(|(k, v)| {
                    use blockwalk_importers::AttrValue;
                    let v = match v {
                        AttrValue::Text(s) => s.to_ascii_lowercase(),
                        AttrValue::Bool(true) => "yes".into(),
                        AttrValue::Int(i) if *i != 0 => "yes".into(),
                        _ => String::new(),
                    };
                    (k == "bridge" && v != "no" && v != "0" && !v.is_empty())
                        || (k == "man_made" && v.contains("bridge"))
                });
                let us = rings
                    .iter()
                    .map(|r| {
                        let c: Vec<geo_types::Coord<f64>> = r
                            .iter()
                            .map(|p| geo_types::Coord { x: p.x, y: p.y })
                            .collect();
                        ring_u(&c)
                    })
                    .collect();
                buildings[bid.0 as usize] = Some(SourceBuilding {
                    style: building_style(b),
                    ring_u: us,
                    id: b.id,
                    source_id: b.source_id.clone(),
                    block: block.id,
                    rings,
                    ground: b.base_m,
                    z0: b.bottom_z(),
                    z1: b.top_z(),
                    min,
                    max,
                    bridge,
                });
            }
        }
        Ok(Self {
            buildings,
            meshes,
            city,
            terrain: None,
        })
    }

    /// The buildings of `blocks` (by id order within each block), skipping empty footprints.
    pub fn buildings_of(&self, layout: &BlockLayout, blocks: &[BlockId]) -> Vec<u32> {
        let mut out = Vec::new();
        for id in blocks {
            if let Some(b) = layout.blocks.get(id.0 as usize) {
                for bid in &b.buildings {
                    if self
                        .buildings
                        .get(bid.0 as usize)
                        .and_then(|b| b.as_ref())
                        .is_some_and(|b| b.rings[0].len() >= 3)
                    {
                        out.push(bid.0);
                    }
                }
            }
        }
        out
    }
}
