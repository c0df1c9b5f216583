//! City model types.

pub use crate::geom::LocalFrame;
use blockwalk_importers::{Attributes, MetricTransform};
use geo_types::{LineString, Polygon};
use serde::Serialize;

/// Index of a building in [`City::buildings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct BuildingId(pub u32);

/// Where a building's height came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HeightSource {
    /// A height attribute in metres.
    Height,
    /// A levels attribute × storey height.
    Levels,
    /// The documented default rule.
    Default,
}

/// A building: a footprint prism from `min_height_m` to `height_m` above its ground, which lies
/// at `base_m` in the world frame (0 for a city without terrain; the terrain under the
/// footprint by the base rule of [`crate::city::build::BuildOptions`] otherwise). World z of the
/// prism: [`Building::bottom_z`] to [`Building::top_z`].
#[derive(Clone, Debug)]
pub struct Building {
    /// Index in [`City::buildings`].
    pub id: BuildingId,
    /// The feature's id in its source (`layer:fid`, or the OSM id).
    pub source_id: String,
    /// Footprint in metric world coordinates: exterior counter-clockwise, holes clockwise, rings
    /// closed, valid (repaired on import).
    pub footprint: Polygon<f64>,
    /// Top of the prism above ground, metres.
    pub height_m: f64,
    /// Bottom of the prism above ground, metres (0 for most buildings).
    pub min_height_m: f64,
    /// World z of the ground the building stands on, metres (0 without terrain). Heights stay
    /// heights above this ground.
    pub base_m: f64,
    /// Where `height_m` came from.
    pub height_source: HeightSource,
    /// The source attributes.
    pub attributes: Attributes,
}

impl Building {
    /// World z of the prism's bottom: `base_m + min(min_height_m, height_m)`.
    #[inline]
    pub fn bottom_z(&self) -> f64 {
        self.base_m + self.min_height_m.min(self.height_m)
    }
    /// World z of the prism's top (the roof): `base_m + max(height_m, min_height_m)`.
    #[inline]
    pub fn top_z(&self) -> f64 {
        self.base_m + self.height_m.max(self.min_height_m)
    }
}

/// A street centre line in metric world coordinates.
#[derive(Clone, Debug)]
pub struct Street {
    /// The feature's id in its source.
    pub source_id: String,
    /// Centre line, metric world coordinates.
    pub line: LineString<f64>,
    /// True for bridges and tunnels. They bound blocks like any street unless the block stage is
    /// asked to honour grade separation (`blocks::BlockOptions::grade_separation`).
    pub grade_separated: bool,
    /// The source attributes.
    pub attributes: Attributes,
}

/// A cadastral parcel in metric world coordinates.
#[derive(Clone, Debug)]
pub struct Parcel {
    /// The feature's id in its source.
    pub source_id: String,
    /// Parcel polygon, metric world coordinates (exterior CCW, holes CW).
    pub polygon: Polygon<f64>,
    /// The source attributes.
    pub attributes: Attributes,
}

/// What building the city did with every input feature.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CityReport {
    /// Footprint features read from the files.
    pub buildings_read: usize,
    /// Footprints imported as they were.
    pub buildings_imported: usize,
    /// Footprints imported after repair, with what was done.
    pub buildings_repaired: Vec<RepairNote>,
    /// Footprints refused, with the reason.
    pub buildings_refused: Vec<RefusalNote>,
    /// Buildings per height source.
    pub height_sources: std::collections::BTreeMap<String, usize>,
    /// The refused footprints grouped by reason, with counts.
    pub refused_by_reason: Vec<blockwalk_importers::ReasonGroup>,
    /// Height attributes that cannot be a building's height (negative, zero, not a number, above
    /// 1000 m), per building; the next height source was used for them.
    pub implausible_heights: Vec<crate::city::build::HeightNote>,
    /// The CRS found and what was done with it.
    pub crs: String,
    /// Why the street layer that was given yields no street (every feature refused or excluded),
    /// so that blocks cannot come from it; `None` when it is usable or none was given.
    pub street_layer_unusable: Option<String>,
    /// The same for the parcel layer.
    pub parcel_layer_unusable: Option<String>,
    /// Street features read (0 without a street layer).
    pub streets_read: usize,
    /// Street features (or parts) refused, with the reason (the importer's refusals included).
    pub streets_refused: Vec<RefusalNote>,
    /// Parcel features read (0 without a parcel layer).
    pub parcels_read: usize,
    /// Parcel features (or parts) refused, with the reason.
    pub parcels_refused: Vec<RefusalNote>,
    /// Where the local origin is and how far the model reaches from it (f32 precision).
    pub frame: crate::city::build::FrameReport,
    /// Other notes (per layer).
    pub notes: Vec<String>,
    /// The buildings put on an elevation model: terrain, rule, bases, slopes, steep and partly
    /// covered footprints (`None` for a flat city).
    pub ground: Option<crate::city::build::GroundReport>,
}

/// A repaired feature.
#[derive(Clone, Debug, Serialize)]
pub struct RepairNote {
    /// Source id.
    pub id: String,
    /// What was done.
    pub what: String,
}

/// A refused feature.
#[derive(Clone, Debug, Serialize)]
pub struct RefusalNote {
    /// Source id.
    pub id: String,
    /// Why.
    pub reason: String,
}

/// A city: buildings, streets and parcels in metric world coordinates.
///
/// # Examples
/// ```
/// use blockwalk::scene::CitySource;
/// use std::path::Path;
///
/// // The bundled Bubeneč footprints (a cadastral sample in EPSG:3857) with their streets.
/// let source = CitySource::parse(
///     Path::new("data/bubenec/buildings.shp"),
///     Some("data/bubenec/streets.shp".into()),
///     None,
///     &[],
///     0,
/// )
/// .unwrap();
/// let city = source.load(&Default::default(), &mut |_| {}).unwrap().city;
/// assert_eq!(city.buildings.len(), 144);
/// assert!(!city.streets.is_empty());
/// // Heights are metres above the ground; coordinates are metres in the metric world frame.
/// assert!(city.buildings.iter().all(|b| b.height_m > 0.0));
/// ```
#[derive(Clone, Debug)]
pub struct City {
    /// Name (from the footprint file).
    pub name: String,
    /// Maps the input's own coordinates to the metric world coordinates used here, and back.
    pub transform: MetricTransform,
    /// The local frame for f32 geometry (origin at the median of the footprints' centres, see
    /// [`crate::city::build::robust_origin`]).
    pub frame: LocalFrame,
    /// Buildings; `buildings[i].id == BuildingId(i)`.
    pub buildings: Vec<Building>,
    /// Street centre lines (empty when no street layer was given).
    pub streets: Vec<Street>,
    /// Cadastral parcels (empty when none were given).
    pub parcels: Vec<Parcel>,
    /// The import account.
    pub report: CityReport,
    /// The ground the buildings stand on, in the metric world frame (`None`: a flat city whose
    /// ground is z = 0).
    pub terrain: Option<std::sync::Arc<crate::terrain::Terrain>>,
}
