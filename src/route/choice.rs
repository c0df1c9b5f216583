//! The route a command plays: a named generated route or a route file.

use super::{
    orbit_route, paper_route, street_walk, CameraRoute, FrameSpec, Lens, Obstacles,
    PaperRouteParams, RouteError, RouteFile, StreetGraph,
};
use crate::city::{Building, LocalFrame};
use crate::geom::Aabb3;
use geo_types::LineString;
use std::path::PathBuf;
use std::str::FromStr;

/// Orbit radius as a multiple of the buildings' spread (the distance from their centre holding
/// 90 % of their footprint area, see [`super::orbit_route`]; without buildings, the box's larger
/// half-side).
pub const ORBIT_RADIUS_FACTOR: f64 = 1.3;
/// Orbit eye height above the ground, metres.
pub const ORBIT_HEIGHT_M: f64 = 80.0;
/// Seconds for one orbit.
pub const ORBIT_DURATION_S: f64 = 60.0;
/// Eye height of the street walk, metres (a standing adult).
pub const STREET_EYE_HEIGHT_M: f64 = 1.7;
/// Walking speed of the street walk, metres per second.
pub const STREET_SPEED_M_S: f64 = 1.4;
/// The street walk's pace in frames: its default frame count (what [`RouteChoice::resolve`]
/// reports when the caller gives none) puts consecutive frames at most this many metres apart,
/// 15 m, whatever the walk's length ([`CameraRoute::frames_for_step`]). This is a step per
/// frame, not a frame rate: the walk's own time runs at [`STREET_SPEED_M_S`].
pub const STREET_FRAME_STEP_M: f64 = 15.0;

/// A route by name or file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RouteChoice {
    /// The paper's route (Pina, Serón and Cerezo, §5): along the streets, rise, look down, fly down.
    Paper,
    /// A circle around the city, looking at its centre.
    Orbit,
    /// A street-level walk across the street graph, corner to corner.
    Street,
    /// A high fly-over with the whole city in view ([`super::flyover_route`]).
    Flyover,
    /// A route file (`.toml` / `.json`, see [`RouteFile`]).
    File(PathBuf),
}

impl RouteChoice {
    /// The generated routes' names, in the order they are listed.
    pub const NAMES: [&'static str; 4] = ["paper", "orbit", "street", "flyover"];

    /// The generated route called `name`.
    pub fn named(name: &str) -> Option<Self> {
        Some(match name {
            "paper" => RouteChoice::Paper,
            "orbit" => RouteChoice::Orbit,
            "street" => RouteChoice::Street,
            "flyover" => RouteChoice::Flyover,
            _ => return None,
        })
    }
}

impl FromStr for RouteChoice {
    type Err = RouteError;
    /// A generated route's name ([`RouteChoice::NAMES`]), or else an existing route file.
    ///
    /// # Errors
    /// [`RouteError::Unknown`] (its message lists the names) when `s` is no route name and no
    /// file by that name can be read; [`RouteError::Bad`] for a folder.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Some(c) = RouteChoice::named(s) {
            return Ok(c);
        }
        let path = PathBuf::from(s);
        match std::fs::metadata(&path) {
            Ok(m) if m.is_file() => Ok(RouteChoice::File(path)),
            Ok(_) => Err(RouteError::Bad {
                route: s.into(),
                problem: format!(
                    "not a route file (a folder), and not a route name ({})",
                    RouteChoice::NAMES.join(", ")
                ),
            }),
            Err(source) => Err(RouteError::Unknown {
                name: s.into(),
                source,
            }),
        }
    }
}

impl std::fmt::Display for RouteChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RouteChoice::Paper => f.write_str("paper"),
            RouteChoice::Orbit => f.write_str("orbit"),
            RouteChoice::Street => f.write_str("street"),
            RouteChoice::Flyover => f.write_str("flyover"),
            RouteChoice::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// What a route is made for: the city's box (local frame), its street edges and buildings
/// (metric world) and frame, and the image's aspect ratio.
#[derive(Clone, Copy, Debug)]
pub struct RouteContext<'a> {
    /// City name, for messages.
    pub city: &'a str,
    /// Box of the city's blocks, local frame.
    pub bounds: Aabb3,
    /// Street edges, metric world coordinates (may be empty).
    pub street_edges: &'a [LineString<f64>],
    /// The buildings generated routes keep their eye clear of (metric world; may be empty).
    pub buildings: &'a [Building],
    /// The city's local frame.
    pub frame: &'a LocalFrame,
    /// Image width / height.
    pub aspect: f64,
}

impl RouteChoice {
    /// The route for `ctx`, and its default frame count: the one a route file asks for, or for
    /// the street walk the count that keeps its frames [`STREET_FRAME_STEP_M`] apart at most
    /// (the other generated routes leave it to the caller).
    ///
    /// # Errors
    /// A route that cannot be made (no street graph for `street`, a bad file, …).
    pub fn resolve(
        &self,
        ctx: &RouteContext<'_>,
    ) -> Result<(CameraRoute, Option<usize>), RouteError> {
        let lens = Lens {
            aspect: ctx.aspect,
            ..Lens::default()
        };
        let graph = || StreetGraph::from_world_lines(ctx.street_edges, ctx.frame);
        let obstacles = || Obstacles::from_buildings(ctx.buildings, ctx.frame);
        Ok(match self {
            RouteChoice::Paper => {
                let g = graph();
                let route = paper_route(
                    &ctx.bounds,
                    Some(&g).filter(|g| !g.is_empty()),
                    &obstacles(),
                    &PaperRouteParams::default(),
                    lens,
                )?;
                (route, None)
            }
            RouteChoice::Orbit => (
                orbit_route(
                    &ctx.bounds,
                    &obstacles(),
                    ORBIT_RADIUS_FACTOR,
                    ORBIT_HEIGHT_M,
                    ORBIT_DURATION_S,
                    lens,
                )?,
                None,
            ),
            RouteChoice::Street => {
                let g = graph();
                if g.is_empty() {
                    return Err(RouteError::Bad {
                        route: "street".into(),
                        problem: format!("{} has no street graph to walk", ctx.city),
                    });
                }
                let from = ctx.bounds.min.truncate();
                let to = ctx.bounds.max.truncate();
                let route = street_walk(
                    &g,
                    &obstacles(),
                    from,
                    to,
                    STREET_EYE_HEIGHT_M,
                    STREET_SPEED_M_S,
                    lens,
                )?;
                let frames = route.frames_for_step(STREET_FRAME_STEP_M);
                (route, Some(frames))
            }
            RouteChoice::Flyover => (super::flyover_route(ctx.bounds, ctx.aspect)?, None),
            RouteChoice::File(path) => {
                let f = RouteFile::read(path)?;
                let mut r = f.to_route(Some(ctx.frame))?;
                r.lens.aspect = ctx.aspect;
                let frames = match f.frame_spec() {
                    FrameSpec::Count(n) => n,
                    FrameSpec::Rate(fps) => r.frames_at_rate(fps),
                };
                (r, Some(frames))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_files() {
        assert_eq!("paper".parse::<RouteChoice>().unwrap(), RouteChoice::Paper);
        assert_eq!("orbit".parse::<RouteChoice>().unwrap(), RouteChoice::Orbit);
        assert_eq!(
            "street".parse::<RouteChoice>().unwrap(),
            RouteChoice::Street
        );
        assert_eq!(
            "flyover".parse::<RouteChoice>().unwrap(),
            RouteChoice::Flyover
        );
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.toml");
        std::fs::write(&file, "").unwrap();
        let name = file.to_str().unwrap();
        assert_eq!(
            name.parse::<RouteChoice>().unwrap(),
            RouteChoice::File(file.clone())
        );
        for c in ["paper", "orbit", "street", "flyover", name] {
            assert_eq!(c.parse::<RouteChoice>().unwrap().to_string(), c);
        }
    }

    #[test]
    fn an_unknown_name_lists_the_routes_and_says_there_is_no_such_file() {
        let e = "streets".parse::<RouteChoice>().unwrap_err().to_string();
        assert!(
            e.starts_with("route 'streets': not a route name (paper, orbit, street, flyover)"),
            "{e}"
        );
        assert!(e.contains("(os error 2)"), "{e}");
    }

    #[test]
    fn street_walk_without_streets_is_an_error() {
        let frame = LocalFrame {
            origin: glam::DVec3::ZERO,
        };
        let ctx = RouteContext {
            city: "empty",
            bounds: Aabb3::from_points([glam::DVec3::ZERO, glam::DVec3::new(100.0, 100.0, 10.0)]),
            street_edges: &[],
            buildings: &[],
            frame: &frame,
            aspect: 16.0 / 9.0,
        };
        let e = RouteChoice::Street.resolve(&ctx).unwrap_err();
        assert!(
            matches!(e, RouteError::Bad { ref problem, .. } if problem.contains("no street graph"))
        );
        assert!(RouteChoice::Orbit.resolve(&ctx).is_ok());
    }
}
