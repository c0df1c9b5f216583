//! The route a command plays: a named generated route or a route file.

use super::{
    corner_walk, orbit_route, paper_route, street_walk, CameraRoute, CornerWalkParams, Lens,
    Obstacles, PaperRouteParams, RouteError, RouteFile, StreetGraph,
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
/// The corner walk's pace in frames: its default frame count puts consecutive frames at most
/// this many metres apart, so that every corner's arc gets frames.
pub const CORNERS_FRAME_STEP_M: f64 = 0.5;

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
    /// A street-level walk that rounds building corners at 0.3–1 m from their walls
    /// ([`super::corner_walk`]).
    Corners,
    /// A route file (`.toml` / `.json`, see [`RouteFile`]).
    File(PathBuf),
}

impl RouteChoice {
    /// The generated routes' names, in the order they are listed.
    pub const NAMES: [&'static str; 5] = ["paper", "orbit", "street", "flyover", "corners"];

    /// Every generated route, in the order of [`RouteChoice::NAMES`].
    pub const GENERATED: [RouteChoice; 5] = [
        RouteChoice::Paper,
        RouteChoice::Orbit,
        RouteChoice::Street,
        RouteChoice::Flyover,
        RouteChoice::Corners,
    ];

    /// The generated route called `name`.
    pub fn named(name: &str) -> Option<Self> {
        Some(match name {
            "paper" => RouteChoice::Paper,
            "orbit" => RouteChoice::Orbit,
            "street" => RouteChoice::Street,
            "flyover" => RouteChoice::Flyover,
            "corners" => RouteChoice::Corners,
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
            RouteChoice::Corners => f.write_str("corners"),
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
    /// The ground the city stands on (`None`: flat, z = 0).
    pub terrain: Option<&'a std::sync::Arc<crate::terrain::Terrain>>,
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
        let (route, frames) = self.resolve_flat(ctx)?;
        Ok((self.on_ground(ctx, route)?, frames))
    }

    /// The route lifted onto `ctx`'s terrain: street walks (and route files whose heights are
    /// `above_ground`) keep their eye height above the ground under the eye; the other routes
    /// keep their world heights, raised where they would come nearer the ground than the street
    /// eye height. A flat city's route is returned as it is.
    fn on_ground(
        &self,
        ctx: &RouteContext<'_>,
        mut route: CameraRoute,
    ) -> Result<CameraRoute, RouteError> {
        let Some(t) = ctx.terrain else {
            return Ok(route);
        };
        let above = match self {
            RouteChoice::Street | RouteChoice::Corners => true,
            RouteChoice::File(path) => {
                RouteFile::read(path)?.heights == super::file::Heights::AboveGround
            }
            RouteChoice::Paper | RouteChoice::Orbit | RouteChoice::Flyover => false,
        };
        let mode = if above {
            super::GroundMode::AboveGround
        } else {
            super::GroundMode::Clear(STREET_EYE_HEIGHT_M)
        };
        route.ground = Some(super::RouteGround::new(t.clone(), *ctx.frame, mode));
        Ok(route)
    }

    /// The route as over a flat city (heights above the ground for street walks).
    fn resolve_flat(
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
            RouteChoice::Corners => {
                let g = graph();
                if g.is_empty() {
                    return Err(RouteError::Bad {
                        route: "corners".into(),
                        problem: format!("{} has no street graph to walk", ctx.city),
                    });
                }
                let (lo, hi) = (ctx.bounds.min.truncate(), ctx.bounds.max.truncate());
                let waypoints = [
                    lo,
                    hi,
                    glam::DVec2::new(hi.x, lo.y),
                    glam::DVec2::new(lo.x, hi.y),
                ];
                let route = corner_walk(
                    &g,
                    &obstacles(),
                    &waypoints,
                    &CornerWalkParams::default(),
                    lens,
                )?;
                let frames = route.frames_for_step(CORNERS_FRAME_STEP_M);
                (route, Some(frames))
            }
            RouteChoice::File(path) => {
                let f = RouteFile::read(path)?;
                let mut r = f.to_route(Some(ctx.frame))?;
                r.lens.aspect = ctx.aspect;
                let frames = f.frame_count(&r, &path.display().to_string())?;
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
        assert_eq!(
            "corners".parse::<RouteChoice>().unwrap(),
            RouteChoice::Corners
        );
        for c in ["paper", "orbit", "street", "flyover", "corners", name] {
            assert_eq!(c.parse::<RouteChoice>().unwrap().to_string(), c);
        }
    }

    #[test]
    fn an_unknown_name_lists_the_routes_and_says_there_is_no_such_file() {
        let e = "streets".parse::<RouteChoice>().unwrap_err().to_string();
        assert!(
            e.starts_with(
                "route 'streets': not a route name (paper, orbit, street, flyover, corners)"
            ),
            "{e}"
        );
        assert!(e.contains("(os error 2)"), "{e}");
    }

    #[test]
    fn a_route_file_whose_rate_gives_too_many_frames_is_refused_naming_file_fields_and_cap() {
        let frame = LocalFrame {
            origin: glam::DVec3::ZERO,
        };
        let ctx = RouteContext {
            city: "box",
            bounds: Aabb3::from_points([glam::DVec3::ZERO, glam::DVec3::new(100.0, 100.0, 10.0)]),
            street_edges: &[],
            buildings: &[],
            frame: &frame,
            aspect: 16.0 / 9.0,
            terrain: None,
        };
        let dir = tempfile::tempdir().unwrap();
        let keys = "[[keys]]\nposition = [0.0, 0.0, 1.7]\nyaw_deg = 0.0\n\
                    [[keys]]\nposition = [14.0, 0.0, 1.7]\nyaw_deg = 0.0\n";
        let resolve = |head: &str| {
            let file = dir.path().join("r.toml");
            std::fs::write(&file, format!("{head}\n{keys}")).unwrap();
            RouteChoice::File(file.clone()).resolve(&ctx)
        };
        // 10 s of route: 30 fps gives 301 frames, as sampling does.
        let (route, frames) = resolve("fps = 30.0").unwrap();
        assert_eq!(frames, Some(301));
        assert_eq!(route.sample_rate(30.0).len(), 301);
        // 1e9 fps over 10 s would be 1e10 frames: refused before anything is allocated.
        for head in ["fps = 1e9", "fps = 1e300", "frames = 100001"] {
            let e = resolve(head).unwrap_err().to_string();
            assert!(e.contains("r.toml"), "{head}: {e}");
            assert!(e.contains("100000"), "{head}: {e}");
            let field = head.split(' ').next().unwrap();
            assert!(e.contains(&format!("{field} = ")), "{head}: {e}");
        }
        let e = resolve("fps = 1e9").unwrap_err().to_string();
        assert!(e.contains("duration of 10.000 s"), "{e}");
        // The cap itself is accepted: 10,000 fps over 10 s is 100,001 frames, 9,999 fps fits.
        assert_eq!(resolve("fps = 9999.0").unwrap().1, Some(99_991));
        assert!(resolve("fps = 10000.0").is_err());
        // sample_rate never allocates past the cap.
        assert_eq!(route.sample_rate(1e9).len(), crate::route::MAX_FRAMES);
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
            terrain: None,
        };
        let e = RouteChoice::Street.resolve(&ctx).unwrap_err();
        assert!(
            matches!(e, RouteError::Bad { ref problem, .. } if problem.contains("no street graph"))
        );
        assert!(RouteChoice::Orbit.resolve(&ctx).is_ok());
    }
}
