//! A streamed walk as one call: open the tiled city, make the route, play it.

use std::path::PathBuf;

use geo_types::LineString;

use crate::geom::Camera;
use crate::route::{RouteChoice, RouteContext};

use super::city::StreamCity;
use super::play::{play, StreamOptions, StreamRun};
use super::StreamError;

/// A streamed walk, checked where it is built.
#[derive(Clone, Debug)]
pub struct StreamJob {
    /// The tiled city: a folder, its `index.json`, or a URL of either.
    pub location: String,
    /// The route.
    pub route: RouteChoice,
    /// Frames (default: the route file's, the street walk's pace, else 300).
    pub frames: Option<usize>,
    /// A street layer in the city's CRS, for the `street` route.
    pub streets: Option<PathBuf>,
    /// How it streams and draws.
    pub options: StreamOptions,
}

/// What [`run_job`] returns.
#[derive(Debug)]
pub struct StreamRecord {
    /// The city as opened.
    pub city: StreamCity,
    /// The route's name.
    pub route: String,
    /// The cameras played.
    pub cameras: Vec<Camera>,
    /// Resident memory after opening the city (before any content), where the system tells.
    pub rss_after_open: Option<u64>,
    /// The walk.
    pub run: StreamRun,
    /// Notes of reading the street layer, when one was given.
    pub notes: Vec<String>,
}

/// How far beyond the blocks' box a street layer must reach for a walk over the city.
const STREETS_MARGIN_M: f64 = 1000.0;

/// The street layer `path` in the city's metric frame: read as a city's streets are
/// ([`crate::city::build`]'s street rules: repair, refusals with their reasons), reprojected from
/// its own CRS through the city's (the index's CRS and transform centre). Returns the lines and
/// the reading's notes.
fn street_lines(
    city: &StreamCity,
    path: &std::path::Path,
) -> Result<(Vec<LineString<f64>>, Vec<String>), StreamError> {
    let bad = |why: String| StreamError::Format {
        file: path.display().to_string(),
        why,
    };
    let layer = blockwalk_importers::read_layer(path, &blockwalk_importers::Theme::Streets)
        .map_err(|e| bad(e.to_string()))?;
    let centre = city.index.transform_centre.unwrap_or([0.0, 0.0]);
    let city_crs = match (&city.index.crs, &layer.crs) {
        (Some(c), _) => c.clone(),
        (None, blockwalk_importers::Crs::Unknown) => blockwalk_importers::Crs::Unknown,
        (None, other) => {
            return Err(bad(format!(
                "the street layer is in {}, but the tiled city's index does not say its CRS (run `blockwalk jobs merge` again to record it)",
                other.describe()
            )))
        }
    };
    let t = city_crs
        .try_metric_transform(centre)
        .and_then(|t| t.for_layer(&layer.crs))
        .map_err(|e| bad(e.to_string()))?;
    let mut report = crate::city::CityReport::default();
    let streets = crate::city::build::layers::build_streets(
        &layer,
        &t,
        &crate::city::build::BuildOptions::default(),
        &mut report,
    );
    if let Some(why) = report.street_layer_unusable {
        return Err(bad(why));
    }
    // A layer of another place is refused, not walked beside the city.
    let b = city.city_box();
    let (o, lo, hi) = (city.frame.origin, b.min.truncate(), b.max.truncate());
    let near = streets.iter().flat_map(|s| s.line.0.iter()).any(|c| {
        let p = glam::DVec2::new(c.x - o.x, c.y - o.y);
        p.cmpge(lo - STREETS_MARGIN_M).all() && p.cmple(hi + STREETS_MARGIN_M).all()
    });
    if !near {
        return Err(bad(format!(
            "no street line comes within {STREETS_MARGIN_M} m of the city's blocks: a layer of another place, or in another CRS than its .prj says"
        )));
    }
    Ok((streets.into_iter().map(|s| s.line).collect(), report.notes))
}

/// The route `choice` over `city`'s blocks (the street walk over the street layer `streets`,
/// read into the city's frame), for images of `aspect`; with its default frame count and the
/// notes of reading the street layer (what was kept and refused).
///
/// # Errors
/// A street layer that cannot be read; a route that cannot be made.
pub fn route_for(
    city: &StreamCity,
    choice: &RouteChoice,
    streets: Option<&std::path::Path>,
    aspect: f64,
) -> Result<(crate::route::CameraRoute, Option<usize>, Vec<String>), StreamError> {
    let (lines, notes) = match streets {
        Some(p) => street_lines(city, p)?,
        None => Default::default(),
    };
    let ctx = RouteContext {
        city: &city.index.city,
        bounds: city.city_box(),
        street_edges: &lines,
        buildings: &[],
        frame: &city.frame,
        aspect,
        terrain: None,
    };
    let (route, frames) = choice
        .resolve(&ctx)
        .map_err(|e| StreamError::Bad(e.to_string()))?;
    Ok((route, frames, notes))
}

/// Opens the city, makes the route over the blocks' box (the street walk over `streets`),
/// samples its cameras and plays them.
///
/// # Errors
/// The city cannot be opened, the route cannot be made, or the walk's settings are refused.
pub fn run_job(
    job: &StreamJob,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<StreamRecord, StreamError> {
    let city = StreamCity::open(&job.location)?;
    let rss_after_open = crate::process::rss_bytes();
    let (route, default_frames, notes) = route_for(
        &city,
        &job.route,
        job.streets.as_deref(),
        job.options.size.0 as f64 / job.options.size.1 as f64,
    )?;
    let n = job.frames.or(default_frames).unwrap_or(300);
    let cameras = route.sample(n);
    let run = play(&city, &cameras, &job.options, progress)?;
    Ok(StreamRecord {
        route: job.route.to_string(),
        city,
        cameras,
        rss_after_open,
        run,
        notes,
    })
}
