//! The metric transform: a city's coordinates to a local, conformal metric frame and back, and
//! other layers reprojected into it.

use super::*;
use std::sync::Arc;

/// How far past ±180° a longitude may be written and still be taken (as the same meridian:
/// the projection wraps it): 1e-6°, about 0.1 m on the equator, for coordinates written a hair
/// past the antimeridian (180.0000001) by rounding. Farther is refused.
pub const LONGITUDE_TOLERANCE_DEG: f64 = 1e-6;

/// A `proj4rs` projection and whether it takes degrees (geographic) rather than metres.
#[derive(Clone)]
pub(super) struct Frame {
    proj: Arc<Proj>,
    degrees: bool,
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Frame({})", self.proj.projname())
    }
}

impl Frame {
    pub(super) fn new(definition: &str) -> Result<Frame, CrsError> {
        let proj = proj(definition)?;
        Ok(Frame {
            degrees: proj.is_latlong(),
            proj: Arc::new(proj),
        })
    }

    /// `p` in this frame → `to` (degrees in and out for geographic frames).
    pub(super) fn project(
        &self,
        to: &Frame,
        p: [f64; 2],
    ) -> Result<[f64; 2], proj4rs::errors::Error> {
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
/// For a projected CRS in metres the map is the identity. For Web Mercator, geographic
/// coordinates and projected systems in other units (US survey feet) it is a local transverse
/// Mercator on WGS84 centred on the data, so that distances and areas are ground metres. [`MetricTransform::for_layer`] gives the map of another layer (in its own
/// CRS) into the same frame.
#[derive(Clone, Debug, Serialize)]
pub struct MetricTransform {
    /// The CRS it maps from.
    pub crs: Crs,
    /// Longitude/latitude (degrees) of the local projection's centre, when there is one (every
    /// CRS but a projected one in metres).
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
        if lon.abs() > 180.0 + LONGITUDE_TOLERANCE_DEG {
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
            Crs::Projected { .. } if !self.crs.is_metric_projected() => format!(
                "{}: projected, in units of {} m, reprojected to a local transverse Mercator \
                 at {centre} (ground metres)",
                self.crs.describe(),
                self.crs.metres_per_unit().unwrap_or(1.0)
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

impl Crs {
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
        if self.is_metric_projected() {
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
}
