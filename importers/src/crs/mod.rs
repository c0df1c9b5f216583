//! Coordinate reference systems, reprojection between layers, and the metric ground frame.
//!
//! The projections themselves are `proj4rs` (a pure-Rust port of PROJ.4); EPSG codes are turned
//! into PROJ strings by `crs-definitions`, and WKT (a Shapefile `.prj`, a GeoPackage
//! `gpkg_spatial_ref_sys.definition`) by `proj4wkt`. What this module still does itself:
//!
//! - classify a CRS the way blockwalk needs it ([`Crs`]: projected metres, Web Mercator, geographic
//!   degrees, or none given) and name it, reading authority codes and names from the WKT (a small
//!   tree parser, `crs::wkt`), and recognising Web Mercator under its ESRI names;
//! - fill in the datum shift of a WKT that names its datum without a `TOWGS84` (for example British
//!   National Grid on OSGB 1936 as ESRI writes it): PROJ takes it from its database, `proj4wkt`
//!   has none, so the datum's name is looked up among the EPSG definitions that carry one
//!   ([`datum_shift_for`]);
//! - check coordinates against their CRS ([`MetricTransform::check`]): latitudes beyond ±90°,
//!   longitudes beyond ±180°, and projected coordinates that the projection cannot take back to
//!   the ellipsoid and forward again to the same point (beyond the projection's valid range);
//! - build the metric ground frame ([`Crs::try_metric_transform`]): projected systems are used as
//!   they are; Web Mercator and geographic coordinates are projected with a transverse Mercator
//!   on WGS84 (k0 = 1, no false origin) centred on the data, so that lengths and areas are ground
//!   metres (scale error below 1e-7 within 3 km of the centre);
//! - reproject another layer into that frame ([`MetricTransform::for_layer`]), datum shifts
//!   included (PROJ.4's `towgs84` Helmert transformation through WGS84).
//!
//! An EPSG code that is not in the EPSG registry (`EPSG:99999`) or a WKT that cannot be read is an
//! error ([`CrsError`]), never "metres as they are".
mod identify;
mod transform;
mod wkt;

pub use identify::{datum_shift_for, epsg_wkt};
pub use transform::MetricTransform;

#[cfg(test)]
use identify::linear_unit;
use proj4rs::proj::Proj;
use serde::{Deserialize, Serialize};
#[cfg(test)]
use transform::Frame;

/// A coordinate reference system, as far as blockwalk needs to know it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Crs {
    /// A projected CRS in metres whose units are true ground metres up to the projection's small
    /// scale error (UTM, ETRS-TM35FIN, national grids): used as it is.
    Projected {
        /// EPSG code when known.
        epsg: Option<u32>,
        /// Human-readable name.
        name: String,
        /// The PROJ string of the projection and its datum.
        proj4: String,
    },
    /// Web Mercator (EPSG:3857 / 900913): metres on the projection, 1/cos(latitude) too long on
    /// the ground.
    WebMercator,
    /// Geographic longitude/latitude in degrees (WGS84 / EPSG:4326, OSM, RFC 7946 GeoJSON). The
    /// datum is the EPSG code's (WGS84 when there is none).
    Geographic {
        /// EPSG code when known.
        epsg: Option<u32>,
    },
    /// No CRS information was found; coordinates are taken as metres.
    Unknown,
}

/// Why a CRS could not be recognised or set up.
#[derive(Debug, thiserror::Error)]
pub enum CrsError {
    /// The EPSG code is not in the registry that `crs-definitions` carries.
    #[error("EPSG:{code} is not a known coordinate reference system")]
    UnknownEpsg {
        /// The code.
        code: u32,
    },
    /// The text is not a WKT coordinate system.
    #[error("not a WKT coordinate system ({why})")]
    NotWkt {
        /// What is wrong.
        why: String,
    },
    /// The WKT was read but `proj4wkt` cannot turn it into a projection.
    #[error("the WKT coordinate system {name:?} cannot be converted to a projection: {source}")]
    WktConversion {
        /// The WKT's name.
        name: String,
        /// The converter's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// `proj4rs` cannot set up the projection.
    #[error("projection {definition:?} cannot be set up: {source}")]
    Projection {
        /// The PROJ string.
        definition: String,
        /// The projection library's error.
        #[source]
        source: proj4rs::errors::Error,
    },
}

/// Why one coordinate does not fit its CRS.
#[derive(Debug, thiserror::Error)]
pub enum CoordError {
    /// NaN or infinity.
    #[error("non-finite coordinate ({x}, {y})")]
    NonFinite {
        /// x as read.
        x: f64,
        /// y as read.
        y: f64,
    },
    /// A latitude beyond ±90°.
    #[error("latitude {lat}° is beyond ±90° in {crs}")]
    Latitude {
        /// The latitude, degrees.
        lat: f64,
        /// The CRS.
        crs: String,
    },
    /// A longitude beyond ±180°.
    #[error(
        "longitude {lon}° is beyond ±180° in {crs} (by more than the 1e-6° accepted for rounding)"
    )]
    Longitude {
        /// The longitude, degrees.
        lon: f64,
        /// The CRS.
        crs: String,
    },
    /// The projection cannot take the point back to the ellipsoid and forward to itself.
    #[error("({x}, {y}) is outside the valid range of {crs}")]
    OutsideProjection {
        /// x as read.
        x: f64,
        /// y as read.
        y: f64,
        /// The CRS.
        crs: String,
    },
    /// `proj4rs` refused the point.
    #[error("({x}, {y}) cannot be transformed from {crs}: {source}")]
    Transform {
        /// x as read.
        x: f64,
        /// y as read.
        y: f64,
        /// The CRS.
        crs: String,
        /// The projection library's error.
        #[source]
        source: proj4rs::errors::Error,
    },
}

/// The PROJ string of WGS84 longitude/latitude.
const WGS84_LONLAT: &str = "+proj=longlat +datum=WGS84 +no_defs";
/// The EPSG:3857 PROJ string (spherical Mercator on the WGS84 semi-major axis, no datum shift).
const WEB_MERCATOR: &str = "+proj=merc +a=6378137 +b=6378137 +lat_ts=0 +lon_0=0 +x_0=0 +y_0=0 \
                            +k=1 +units=m +nadgrids=@null +no_defs";
/// EPSG codes that mean Web Mercator (3857 and its historical aliases).
const WEB_MERCATOR_CODES: [u32; 5] = [3857, 900913, 3785, 102100, 102113];
/// The Web Mercator square's half side, π × 6 378 137 m.
const WEB_MERCATOR_LIMIT: f64 = std::f64::consts::PI * 6_378_137.0;
/// Coordinates that come back from lon/lat further than this (metres, plus 1e-9 of their size)
/// are outside the projection's valid range.
const ROUND_TRIP_TOLERANCE_M: f64 = 1e-3;
/// The largest box side (in a projected CRS's units, metres or feet) that
/// [`MetricTransform::box_fits`] decides by its corners: a footprint's size, far below the
/// scale on which a projection's range of validity bends.
pub const BOX_CHECK_MAX: f64 = 1_000.0;
/// [`MetricTransform::box_fits`] asks the corners of a box to come back from the ellipsoid
/// within this fraction of the tolerance of a single point: a box near the edge of a
/// projection's range (where the round trip turns to noise) is left to its vertices.
const BOX_CHECK_TOLERANCE_SCALE: f64 = 1e-3;

fn proj(definition: &str) -> Result<Proj, CrsError> {
    Proj::from_proj_string(definition).map_err(|source| CrsError::Projection {
        definition: definition.to_string(),
        source,
    })
}

#[cfg(test)]
mod tests;
