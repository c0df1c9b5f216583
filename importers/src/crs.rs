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

mod wkt;

use proj4rs::proj::Proj;
use serde::Serialize;
use std::sync::Arc;

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
    /// The linear unit is not metres.
    #[error("{name}: the linear unit is {unit} ({factor} m), not metres")]
    NotMetres {
        /// The CRS name.
        name: String,
        /// The unit's name.
        unit: String,
        /// Metres per unit.
        factor: f64,
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
    #[error("longitude {lon}° is beyond ±180° in {crs}")]
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

/// A `proj4rs` projection and whether it takes degrees (geographic) rather than metres.
#[derive(Clone)]
struct Frame {
    proj: Arc<Proj>,
    degrees: bool,
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Frame({})", self.proj.projname())
    }
}

impl Frame {
    fn new(definition: &str) -> Result<Frame, CrsError> {
        let proj = proj(definition)?;
        Ok(Frame {
            degrees: proj.is_latlong(),
            proj: Arc::new(proj),
        })
    }

    /// `p` in this frame → `to` (degrees in and out for geographic frames).
    fn project(&self, to: &Frame, p: [f64; 2]) -> Result<[f64; 2], proj4rs::errors::Error> {
        let mut q = if self.degrees {
            (p[0].to_radians(), p[1].to_radians(), 0.0)
        } else {
            (p[0], p[1], 0.0)
        };
        proj4rs::transform::transform(&self.proj, &to.proj, &mut q)?;
        let out = if to.degrees {
            [q.0.to_degrees(), q.1.to_degrees()]
        } else {
            [q.0, q.1]
        };
        if out[0].is_finite() && out[1].is_finite() {
            Ok(out)
        } else {
            Err(proj4rs::errors::Error::CoordinateOutOfRange)
        }
    }
}

/// The geographic frame on the same datum as `definition` (the datum tokens kept, the
/// projection dropped), so that checking a point needs no datum shift.
fn lonlat_on_same_datum(definition: &str) -> String {
    let keep = [
        "datum", "ellps", "a", "b", "rf", "f", "R", "towgs84", "nadgrids", "pm",
    ];
    let mut out = String::from("+proj=longlat");
    for tok in definition.split_whitespace() {
        let key = tok
            .trim_start_matches('+')
            .split('=')
            .next()
            .unwrap_or_default();
        if keep.contains(&key) {
            out.push(' ');
            out.push_str(tok);
        }
    }
    out.push_str(" +no_defs");
    out
}

/// Maps a layer's own coordinates to a metric ground frame and back, checking them against
/// their CRS on the way.
///
/// For a projected CRS the map is the identity. For Web Mercator and geographic coordinates it
/// is a local transverse Mercator on WGS84 centred on the data, so that distances and areas are
/// ground metres. [`MetricTransform::for_layer`] gives the map of another layer (in its own
/// CRS) into the same frame.
#[derive(Clone, Debug, Serialize)]
pub struct MetricTransform {
    /// The CRS it maps from.
    pub crs: Crs,
    /// Longitude/latitude (degrees) of the local projection's centre, for non-projected CRS.
    pub center_lonlat: Option<[f64; 2]>,
    /// The metric frame's own CRS, when the layer was reprojected into another layer's frame.
    pub frame_crs: Option<Crs>,
    #[serde(skip)]
    inner: Option<Inner>,
}

impl PartialEq for MetricTransform {
    fn eq(&self, other: &Self) -> bool {
        self.crs == other.crs
            && self.center_lonlat == other.center_lonlat
            && self.frame_crs == other.frame_crs
    }
}

#[derive(Clone, Debug)]
struct Inner {
    /// The layer's CRS.
    source: Frame,
    /// Geographic on the source's datum, for checks.
    source_lonlat: Frame,
    /// The metric frame.
    metric: Frame,
    /// True when source and metric frame are the same CRS: coordinates pass unchanged.
    identity: bool,
}

impl MetricTransform {
    /// Layer coordinates → metric ground coordinates, without checks: NaN for a point that the
    /// projection refuses. [`Self::try_to_metric`] checks and says why.
    pub fn to_metric(&self, p: [f64; 2]) -> [f64; 2] {
        match &self.inner {
            Some(i) if !i.identity => i
                .source
                .project(&i.metric, p)
                .unwrap_or([f64::NAN, f64::NAN]),
            _ => p,
        }
    }

    /// Layer coordinates → metric ground coordinates, after [`Self::check`].
    ///
    /// # Errors
    /// [`CoordError`] when the point does not fit the layer's CRS or cannot be transformed.
    pub fn try_to_metric(&self, p: [f64; 2]) -> Result<[f64; 2], CoordError> {
        self.check(p)?;
        match &self.inner {
            Some(i) if !i.identity => {
                i.source
                    .project(&i.metric, p)
                    .map_err(|source| CoordError::Transform {
                        x: p[0],
                        y: p[1],
                        crs: self.crs.describe(),
                        source,
                    })
            }
            _ => Ok(p),
        }
    }

    /// Metric ground coordinates → layer coordinates (inverse of [`Self::to_metric`]); NaN for a
    /// point the projection refuses.
    pub fn from_metric(&self, p: [f64; 2]) -> [f64; 2] {
        match &self.inner {
            Some(i) if !i.identity => i
                .metric
                .project(&i.source, p)
                .unwrap_or([f64::NAN, f64::NAN]),
            _ => p,
        }
    }

    /// Checks one coordinate against the layer's CRS: finite; for geographic systems a latitude
    /// within ±90° and a longitude within ±180°; for projected systems (Web Mercator included) a
    /// point that the projection takes to the ellipsoid, within those bounds, and back to itself
    /// within 1 mm (beyond a projection's valid range the inverse fails or does not come back).
    ///
    /// # Errors
    /// The [`CoordError`] that says what does not fit.
    pub fn check(&self, p: [f64; 2]) -> Result<(), CoordError> {
        self.check_within(p, 1.0)
    }

    /// [`Self::check`] with the round-trip tolerance scaled by `scale`.
    fn check_within(&self, p: [f64; 2], scale: f64) -> Result<(), CoordError> {
        let [x, y] = p;
        if !(x.is_finite() && y.is_finite()) {
            return Err(CoordError::NonFinite { x, y });
        }
        let Some(i) = &self.inner else {
            return Ok(());
        };
        let crs = || self.crs.describe();
        // EPSG:3857's area of use ends at ±85.06° latitude: |x|, |y| ≤ π·R (the formula goes on
        // to the pole, the system does not).
        if self.crs == Crs::WebMercator
            && (x.abs() > WEB_MERCATOR_LIMIT || y.abs() > WEB_MERCATOR_LIMIT)
        {
            return Err(CoordError::OutsideProjection { x, y, crs: crs() });
        }
        let lonlat = if i.source.degrees {
            p
        } else {
            i.source
                .project(&i.source_lonlat, p)
                .map_err(|_| CoordError::OutsideProjection { x, y, crs: crs() })?
        };
        let [lon, lat] = lonlat;
        if lat.abs() > 90.0 {
            return Err(CoordError::Latitude { lat, crs: crs() });
        }
        if lon.abs() > 180.0 + 1e-9 {
            return Err(CoordError::Longitude { lon, crs: crs() });
        }
        if !i.source.degrees {
            let back = i
                .source_lonlat
                .project(&i.source, lonlat)
                .map_err(|_| CoordError::OutsideProjection { x, y, crs: crs() })?;
            let tol = scale * (ROUND_TRIP_TOLERANCE_M + 1e-9 * x.abs().max(y.abs()));
            if (back[0] - x).abs() > tol || (back[1] - y).abs() > tol {
                return Err(CoordError::OutsideProjection { x, y, crs: crs() });
            }
        }
        Ok(())
    }

    /// True when every point of the box `[xmin, ymin, xmax, ymax]` passes [`Self::check`], as
    /// its four corners tell; false when the box is not finite, is larger than
    /// [`BOX_CHECK_MAX`] in a projected CRS, or a corner does not pass (the caller then checks
    /// each point, to name the one that does not fit).
    ///
    /// For a geographic CRS, and for a CRS without a projection, the checks are bounds on each
    /// coordinate, and a box whose corners are within them is within them: the answer is exact.
    /// For a projected CRS (Web Mercator included) the corners must pass with a round trip
    /// a thousand times closer than a single point needs ([`BOX_CHECK_TOLERANCE_SCALE`]): away
    /// from the edge of the projection's range the round trip is smooth and far below the
    /// tolerance, so that within a box of at most [`BOX_CHECK_MAX`] units whose corners pass,
    /// every point passes; at the edge, where the round trip turns to noise (a box whose
    /// corners passed at the plain tolerance had an inner point that did not), boxes are left
    /// to their vertices. This is a deviation from checking each vertex, taken for speed (the
    /// footprints' CRS check was a quarter of an import's instructions); a test walks boxes
    /// across the edges of the Transverse Mercator and Web Mercator ranges and finds no box
    /// that fits with a point inside that does not.
    pub fn box_fits(&self, b: [f64; 4]) -> bool {
        let [x0, y0, x1, y1] = b;
        if !(b.iter().all(|v| v.is_finite()) && x0 <= x1 && y0 <= y1) {
            return false;
        }
        if self.inner.as_ref().is_some_and(|i| {
            !i.source.degrees && (x1 - x0 > BOX_CHECK_MAX || y1 - y0 > BOX_CHECK_MAX)
        }) {
            return false;
        }
        [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
            .into_iter()
            .all(|c| self.check_within(c, BOX_CHECK_TOLERANCE_SCALE).is_ok())
    }

    /// Metric ground coordinates → WGS84 longitude/latitude in degrees (the datum shift is the
    /// CRS's `+towgs84`/`+datum` when it has one); `None` for a frame without geodetic meaning
    /// ([`Crs::Unknown`]) or a point the projection refuses.
    pub fn to_wgs84_lonlat(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        let i = self.inner.as_ref()?;
        let wgs84 = Frame::new(WGS84_LONLAT).ok()?;
        i.metric.project(&wgs84, p).ok()
    }

    /// True when [`Self::to_metric`] is the identity.
    pub fn is_identity(&self) -> bool {
        self.inner.as_ref().is_none_or(|i| i.identity)
    }

    /// The map of a layer in `crs` into this transform's metric frame (a street layer in UTM
    /// into the frame of footprints in Web Mercator, say). The same CRS gives a copy of `self`.
    ///
    /// # Errors
    /// [`CrsError`] when `crs` cannot be set up. A layer without CRS ([`Crs::Unknown`]), or a frame
    /// without one, cannot be reprojected: the caller decides (blockwalk takes it as being in
    /// the frame, with a note); this returns the identity for it.
    pub fn for_layer(&self, crs: &Crs) -> Result<MetricTransform, CrsError> {
        if crs == &self.crs {
            return Ok(self.clone());
        }
        let (Some(frame), Some(def)) = (&self.inner, crs.proj4()) else {
            return Ok(MetricTransform {
                crs: crs.clone(),
                center_lonlat: self.center_lonlat,
                frame_crs: Some(self.crs.clone()),
                inner: None,
            });
        };
        let source = Frame::new(&def)?;
        let source_lonlat = Frame::new(&lonlat_on_same_datum(&def))?;
        Ok(MetricTransform {
            crs: crs.clone(),
            center_lonlat: self.center_lonlat,
            frame_crs: Some(self.crs.clone()),
            inner: Some(Inner {
                source,
                source_lonlat,
                metric: frame.metric.clone(),
                identity: false,
            }),
        })
    }

    /// One line for the summary: what CRS was found and what was done with it.
    pub fn describe(&self) -> String {
        let centre = self
            .center_lonlat
            .map(|[lon, lat]| format_lonlat(lon, lat))
            .unwrap_or_default();
        if let Some(frame) = &self.frame_crs {
            return format!(
                "{}: reprojected into the frame of {}",
                self.crs.describe(),
                frame.describe()
            );
        }
        match &self.crs {
            Crs::WebMercator => {
                let lat = self.center_lonlat.map(|c| c[1]).unwrap_or(0.0);
                let k = 1.0 / lat.to_radians().cos();
                format!(
                    "EPSG:3857 Web Mercator: reprojected to a local transverse Mercator at \
                     {centre} (ground metres; Mercator units are {k:.2}× too long here)"
                )
            }
            Crs::Geographic { .. } => format!(
                "{}: projected to a local transverse Mercator at {centre} (ground metres)",
                self.crs.describe()
            ),
            Crs::Projected { .. } => {
                format!(
                    "{}: projected metres, used as they are",
                    self.crs.describe()
                )
            }
            Crs::Unknown => "no CRS found: coordinates taken as metres, used as they are".into(),
        }
    }
}

fn format_lonlat(lon: f64, lat: f64) -> String {
    let ns = if lat >= 0.0 { 'N' } else { 'S' };
    let ew = if lon >= 0.0 { 'E' } else { 'W' };
    format!("{:.3}°{ns} {:.3}°{ew}", lat.abs(), lon.abs())
}

/// The name of an EPSG definition, from its WKT (`PROJCS["name", …`).
fn epsg_name(code: u32) -> Option<String> {
    let def = crs_definitions::from_code(u16::try_from(code).ok()?)?;
    wkt::parse(def.wkt).and_then(|n| n.name().map(str::to_string))
}

fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_lowercase()
        .trim_start_matches('d')
        .to_string()
}

/// The datum part (`+datum=…` or `+towgs84=…`) of the first EPSG definition whose WKT datum
/// has the same name as `datum` (compared without case, spaces, `_` and ESRI's `D_` prefix) and
/// a datum shift: what PROJ would take from its database for a WKT without `TOWGS84`.
pub fn datum_shift_for(datum: &str) -> Option<String> {
    let want = normalise(datum);
    if want.is_empty() {
        return None;
    }
    (1024..=32767u16).find_map(|code| {
        let def = crs_definitions::from_code(code)?;
        // Geographic 2D definitions name the datum in their first DATUM node.
        if !def.proj4.starts_with("+proj=longlat") {
            return None;
        }
        let node = wkt::parse(def.wkt)?;
        let d = node.find("DATUM")?;
        if normalise(d.name()?) != want {
            return None;
        }
        def.proj4
            .split_whitespace()
            .find(|t| t.starts_with("+datum=") || t.starts_with("+towgs84="))
            .map(str::to_string)
    })
}

impl Crs {
    /// The PROJ string of this CRS (`None` for [`Crs::Unknown`]).
    pub fn proj4(&self) -> Option<String> {
        match self {
            Crs::Projected { proj4, .. } => Some(proj4.clone()),
            Crs::WebMercator => Some(WEB_MERCATOR.into()),
            Crs::Geographic { epsg: Some(code) } => {
                let def = u16::try_from(*code)
                    .ok()
                    .and_then(crs_definitions::from_code)
                    .map(|d| d.proj4)
                    .unwrap_or(WGS84_LONLAT);
                Some(def.into())
            }
            Crs::Geographic { epsg: None } => Some(WGS84_LONLAT.into()),
            Crs::Unknown => None,
        }
    }

    /// Builds the transform to metric ground coordinates for data centred at `center` (in this
    /// CRS's own coordinates).
    ///
    /// A centre that is not finite, or a latitude beyond ±89°, is clamped so that the local
    /// projection is always defined (such data are refused coordinate by coordinate anyway).
    ///
    /// # Errors
    /// [`CrsError::Projection`] when the CRS's PROJ string cannot be set up.
    pub fn try_metric_transform(&self, center: [f64; 2]) -> Result<MetricTransform, CrsError> {
        let Some(def) = self.proj4() else {
            return Ok(MetricTransform {
                crs: Crs::Unknown,
                center_lonlat: None,
                frame_crs: None,
                inner: None,
            });
        };
        let source = Frame::new(&def)?;
        let source_lonlat = Frame::new(&lonlat_on_same_datum(&def))?;
        if let Crs::Projected { .. } = self {
            return Ok(MetricTransform {
                crs: self.clone(),
                center_lonlat: None,
                frame_crs: None,
                inner: Some(Inner {
                    metric: source.clone(),
                    source,
                    source_lonlat,
                    identity: true,
                }),
            });
        }
        let wgs84 = Frame::new(WGS84_LONLAT)?;
        let [lon, lat] = source.project(&wgs84, center).unwrap_or([0.0, 0.0]);
        let lon = if lon.is_finite() { lon } else { 0.0 };
        let lon = (lon + 180.0).rem_euclid(360.0) - 180.0;
        let lat = if lat.is_finite() { lat } else { 0.0 };
        let lat = lat.clamp(-89.0, 89.0);
        let metric = Frame::new(&format!(
            "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
        ))?;
        Ok(MetricTransform {
            crs: self.clone(),
            center_lonlat: Some([lon, lat]),
            frame_crs: None,
            inner: Some(Inner {
                source,
                source_lonlat,
                metric,
                identity: false,
            }),
        })
    }

    /// [`Self::try_metric_transform`] for a CRS known to be good (every [`Crs`] this crate's
    /// readers return is).
    ///
    /// # Panics
    /// When the CRS's PROJ string cannot be set up (a hand-made [`Crs::Projected`]).
    pub fn metric_transform(&self, center: [f64; 2]) -> MetricTransform {
        self.try_metric_transform(center)
            .unwrap_or_else(|e| panic!("metric transform of {}: {e}", self.describe()))
    }

    /// The CRS for an EPSG code: Web Mercator codes (3857, 900913, 3785, 102100, 102113) give
    /// [`Crs::WebMercator`]; geographic codes [`Crs::Geographic`]; projected codes
    /// [`Crs::Projected`] with the registry's name and PROJ string.
    ///
    /// # Errors
    /// [`CrsError::UnknownEpsg`] for a code that is not in the registry; [`CrsError::NotMetres`]
    /// for a projected system whose unit is not the metre (US feet, say).
    pub fn from_epsg(code: u32) -> Result<Crs, CrsError> {
        if WEB_MERCATOR_CODES.contains(&code) {
            return Ok(Crs::WebMercator);
        }
        let def = u16::try_from(code)
            .ok()
            .and_then(crs_definitions::from_code)
            .ok_or(CrsError::UnknownEpsg { code })?;
        let name = epsg_name(code).unwrap_or_else(|| format!("EPSG:{code}"));
        let p = proj(def.proj4)?;
        if p.is_latlong() {
            return Ok(Crs::Geographic { epsg: Some(code) });
        }
        let factor = p.to_meter();
        if (factor - 1.0).abs() > 1e-9 {
            return Err(CrsError::NotMetres {
                name,
                unit: p.units().to_string(),
                factor,
            });
        }
        Ok(Crs::Projected {
            epsg: Some(code),
            name,
            proj4: def.proj4.to_string(),
        })
    }

    /// Recognises a WKT (WKT1 as in `.prj` files and GDAL/OGC, or WKT2) coordinate system.
    ///
    /// Web Mercator is recognised by an EPSG authority, by name (Web Mercator, Pseudo-Mercator,
    /// Mercator auxiliary sphere) or by a `Mercator_1SP` on a sphere of radius 6 378 137 m. A
    /// system with an EPSG authority takes its definition from the registry; any other is
    /// converted by `proj4wkt`, with the datum shift filled in by name when the WKT has none
    /// ([`datum_shift_for`]), and with the EPSG code inferred for UTM zones and ETRS-TM35FIN.
    ///
    /// # Errors
    /// [`CrsError::NotWkt`] when the text is not WKT, [`CrsError::UnknownEpsg`] for an authority
    /// code not in the registry, [`CrsError::WktConversion`] or [`CrsError::Projection`] for a
    /// projection `proj4rs` does not have, [`CrsError::NotMetres`] for a unit other than the metre.
    pub fn from_wkt(text: &str) -> Result<Crs, CrsError> {
        let text = text.trim().trim_start_matches('\u{feff}');
        let root = wkt::parse(text).ok_or_else(|| CrsError::NotWkt {
            why: format!(
                "expected KEYWORD[...], found {:?}",
                text.chars().take(40).collect::<String>()
            ),
        })?;
        let kw = root.keyword.to_ascii_uppercase();
        let root_epsg = root.authority_epsg();
        let name = root.name().unwrap_or("").to_string();
        match kw.as_str() {
            "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
                if let Some(code) = root_epsg {
                    return match Crs::from_epsg(code)? {
                        Crs::Projected { epsg, proj4, .. } if !name.is_empty() => {
                            Ok(Crs::Projected { epsg, name, proj4 })
                        }
                        crs => Ok(crs),
                    };
                }
                let lname = name.to_ascii_lowercase().replace(['_', '-'], " ");
                let method = root
                    .find("PROJECTION")
                    .or_else(|| root.find("METHOD"))
                    .and_then(|n| n.name())
                    .unwrap_or("")
                    .to_ascii_lowercase()
                    .replace(['_', '-'], " ");
                let is_webmerc = lname.contains("web mercator")
                    || lname.contains("pseudo mercator")
                    || method.contains("auxiliary sphere")
                    || method.contains("pseudo mercator")
                    || (method.contains("mercator 1sp") && {
                        let ext = text.to_ascii_lowercase();
                        (ext.contains("+a=6378137") && ext.contains("+b=6378137"))
                            || ext.contains("auxiliary")
                    });
                if is_webmerc {
                    return Ok(Crs::WebMercator);
                }
                if let Some((unit, factor)) = linear_unit(&root) {
                    if (factor - 1.0).abs() > 1e-9 {
                        return Err(CrsError::NotMetres { name, unit, factor });
                    }
                }
                let mut proj4 =
                    proj4wkt::wkt_to_projstring(text).map_err(|e| CrsError::WktConversion {
                        name: name.clone(),
                        source: e.into(),
                    })?;
                if !proj4.contains("+towgs84=") && !proj4.contains("+datum=") {
                    let datum = root.find("DATUM").and_then(|d| d.name()).unwrap_or("");
                    if let Some(shift) = datum_shift_for(datum) {
                        proj4.push(' ');
                        proj4.push_str(&shift);
                    }
                }
                proj(&proj4)?;
                let epsg = infer_epsg(&root, &lname, &method);
                let name = if name.is_empty() {
                    epsg.and_then(epsg_name)
                        .unwrap_or_else(|| "unnamed projected CRS".into())
                } else {
                    name
                };
                Ok(Crs::Projected { epsg, name, proj4 })
            }
            "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" | "GEODCRS" => {
                if let Some(code) = root_epsg {
                    return Crs::from_epsg(code);
                }
                let datum = root.find("DATUM").and_then(|d| d.name()).unwrap_or("");
                let d = normalise(datum);
                let epsg = if d.contains("wgs1984") || d.contains("wgs84") || d.is_empty() {
                    Some(4326)
                } else {
                    // The geographic EPSG code whose datum has this name, for its datum shift.
                    (4000..=4999u16).find_map(|code| {
                        let def = crs_definitions::from_code(code)?;
                        let node = wkt::parse(def.wkt)?;
                        (normalise(node.find("DATUM")?.name()?) == d).then_some(u32::from(code))
                    })
                };
                Ok(Crs::Geographic { epsg })
            }
            other => Err(CrsError::NotWkt {
                why: format!("{other} is not a coordinate system keyword"),
            }),
        }
    }

    /// One short human phrase, e.g. `EPSG:3067 ETRS89 / TM35FIN`.
    pub fn describe(&self) -> String {
        match self {
            Crs::Projected {
                epsg: Some(code),
                name,
                ..
            } => format!("EPSG:{code} {name}"),
            Crs::Projected {
                epsg: None, name, ..
            } => format!("{name} (projected, no EPSG code)"),
            Crs::WebMercator => "EPSG:3857 Web Mercator".into(),
            Crs::Geographic { epsg: Some(code) } => format!("EPSG:{code} geographic lon/lat"),
            Crs::Geographic { epsg: None } => "geographic lon/lat".into(),
            Crs::Unknown => "unknown CRS".into(),
        }
    }
}

/// The linear unit of a projected WKT node, as (name, metres per unit), when it states one.
fn linear_unit(root: &wkt::Node) -> Option<(String, f64)> {
    let unit = root
        .children()
        .find(|c| {
            c.keyword.eq_ignore_ascii_case("UNIT") || c.keyword.eq_ignore_ascii_case("LENGTHUNIT")
        })
        .or_else(|| root.find("LENGTHUNIT"))?;
    let name = unit.name()?.to_string();
    let factor = unit.number(1)?;
    Some((name, factor))
}

/// EPSG code of a projected WKT without an authority: UTM zones (by name, or by a transverse
/// Mercator with k0 = 0.9996 and false easting 500 000 on a 6° zone meridian) and ETRS-TM35FIN.
/// Only names the system: its definition is the WKT's own.
fn infer_epsg(root: &wkt::Node, lname: &str, method: &str) -> Option<u32> {
    let datum = root
        .find("DATUM")
        .and_then(|d| d.name())
        .unwrap_or("")
        .to_ascii_lowercase();
    let wgs84 = datum.contains("wgs") && datum.contains("84");
    let etrs =
        datum.contains("etrs") || datum.contains("european terrestrial") || datum.contains("euref");
    let nad83 =
        datum.contains("north american") && datum.contains("1983") || datum.contains("nad83");
    if lname.contains("tm35fin") {
        return Some(3067);
    }
    let zone_from_name = lname.find("utm zone ").and_then(|i| {
        let rest = &lname[i + 9..];
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        let zone: u32 = digits.parse().ok()?;
        let hemi = rest[digits.len()..].chars().next().unwrap_or('n');
        Some((zone, hemi != 's'))
    });
    let zone = zone_from_name.or_else(|| {
        if !method.contains("transverse mercator") {
            return None;
        }
        let param = |name: &str| {
            root.children()
                .filter(|c| c.keyword.eq_ignore_ascii_case("PARAMETER"))
                .find(|c| c.name().is_some_and(|n| n.eq_ignore_ascii_case(name)))
                .and_then(|c| c.number(1))
        };
        let cm = param("central_meridian")?;
        let k = param("scale_factor")?;
        let fe = param("false_easting")?;
        let fnorth = param("false_northing").unwrap_or(0.0);
        let z = (cm + 183.0) / 6.0;
        if (k - 0.9996).abs() > 1e-9
            || (fe - 500_000.0).abs() > 1e-6
            || (z - z.round()).abs() > 1e-9
        {
            return None;
        }
        Some((z.round() as u32, fnorth.abs() < 1e-6))
    })?;
    let (z, north) = zone;
    if !(1..=60).contains(&z) {
        return None;
    }
    if wgs84 {
        Some(if north { 32600 + z } else { 32700 + z })
    } else if etrs && north && (28..=38).contains(&z) {
        Some(25800 + z)
    } else if nad83 && north && z <= 23 {
        Some(26900 + z)
    } else {
        None
    }
}

#[cfg(test)]
mod tests;
