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
}

fn street_lines(
    city: &StreamCity,
    path: &std::path::Path,
) -> Result<Vec<LineString<f64>>, StreamError> {
    let layer = blockwalk_importers::read_layer(path, &blockwalk_importers::Theme::Streets)
        .map_err(|e| StreamError::Format {
            file: path.display().to_string(),
            why: e.to_string(),
        })?;
    let centre = city.index.transform_centre.unwrap_or([0.0, 0.0]);
    let t = layer
        .crs
        .try_metric_transform(centre)
        .map_err(|e| StreamError::Format {
            file: path.display().to_string(),
            why: e.to_string(),
        })?;
    let mut out = Vec::new();
    for f in &layer.features {
        let mut push = |l: &LineString<f64>| {
            let pts: Vec<geo_types::Coord<f64>> =
                l.0.iter()
                    .filter_map(|c| t.try_to_metric([c.x, c.y]).ok())
                    .map(|[x, y]| geo_types::Coord { x, y })
                    .collect();
            if pts.len() >= 2 {
                out.push(LineString(pts));
            }
        };
        match &f.geometry {
            geo_types::Geometry::LineString(l) => push(l),
            geo_types::Geometry::MultiLineString(m) => m.0.iter().for_each(&mut push),
            _ => {}
        }
    }
    Ok(out)
}

/// The route `choice` over `city`'s blocks (the street walk over the street layer `streets`,
/// read into the city's frame), for images of `aspect`; with its default frame count.
///
/// # Errors
/// A street layer that cannot be read; a route that cannot be made.
pub fn route_for(
    city: &StreamCity,
    choice: &RouteChoice,
    streets: Option<&std::path::Path>,
    aspect: f64,
) -> Result<(crate::route::CameraRoute, Option<usize>), StreamError> {
    let lines = match streets {
        Some(p) => street_lines(city, p)?,
        None => Vec::new(),
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
    choice
        .resolve(&ctx)
        .map_err(|e| StreamError::Bad(e.to_string()))
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
    let (route, default_frames) = route_for(
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
    })
}
