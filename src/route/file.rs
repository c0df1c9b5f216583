//! The route file format (TOML or JSON; same fields).
//!
//! ```toml
//! name = "along the avenue"
//! frame = "local"          # "local": metres from the city's local origin (default);
//!                          # "world": the city's metric world coordinates (origin subtracted on load)
//! speed = 1.4              # m/s between keys without a time (default 1.4, walking pace)
//! turn_rate_deg = 45.0     # °/s for keys that only turn in place (default 45)
//! frames = 300             # frame count over the route; or `fps = 30` (default: 30 fps)
//! fov_deg = 60.0           # lens (defaults: 60°, 16:9, near 0.5 m, far 5000 m)
//! aspect = 1.7777778
//! near = 0.5
//! far = 5000.0
//! orientation = "squad"    # or "slerp"
//! heights = "world"        # or "above_ground": z is metres above the terrain under the eye
//!
//! [[keys]]
//! position = [-300.0, 0.0, 1.7]
//! look_at = [0.0, 0.0, 1.7]    # or yaw_deg / pitch_deg (counter-clockwise from east; up positive)
//! time = 0.0                   # optional; seconds (the first key defaults to 0)
//!
//! [[keys]]
//! position = [0.0, 0.0, 1.7]
//! yaw_deg = 0.0
//! pitch_deg = 0.0
//! speed = 2.0                  # optional: m/s on the way to this key (instead of a time)
//! corner = true                # optional: break the spline here
//! ```
//!
//! Each key gives its orientation by `look_at` or by `yaw_deg` (+ optional `pitch_deg`, default
//! 0); giving both, or neither, is an error. A key's time is its `time`, else the previous
//! key's time plus the chord length over `speed` (the key's, else the route's), or, when the key
//! does not move, the turn angle over `turn_rate_deg`.

use super::{CameraRoute, FrameSpec, KeyFrame, Lens, OrientationInterpolation, RouteError};
use crate::city::LocalFrame;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Largest coordinate a route file's positions and `look_at` may have, metres (local or world):
/// 100,000 km, far beyond any city on the globe.
pub const MAX_COORD_M: f64 = 1.0e8;
/// Largest time a key may have, seconds (about 31 years).
pub const MAX_TIME_S: f64 = 1.0e9;
/// Largest speed a key may give, m/s.
pub const MAX_SPEED_M_S: f64 = 1.0e6;
/// Largest heading magnitude, degrees.
pub const MAX_ANGLE_DEG: f64 = 1.0e6;

/// Every number in `values` (the key field `what`) finite and within ±`max` `unit`.
fn check_numbers(
    bad_key: &dyn Fn(String) -> RouteError,
    what: &str,
    values: &[f64],
    max: f64,
    unit: &str,
) -> Result<(), RouteError> {
    let one = |v: f64| {
        if v.is_finite() && v.abs() >= 1e12 {
            format!("{v:e}")
        } else {
            v.to_string()
        }
    };
    let shown = || {
        if values.len() == 1 {
            one(values[0])
        } else {
            let all: Vec<String> = values.iter().map(|&v| one(v)).collect();
            format!("[{}]", all.join(", "))
        }
    };
    if values.iter().any(|v| !v.is_finite()) {
        return Err(bad_key(format!(
            "{what} = {}: not a finite number",
            shown()
        )));
    }
    if values.iter().any(|v| v.abs() > max) {
        return Err(bad_key(format!(
            "{what} = {}: out of range; expected -{max} to {max} {unit}",
            shown()
        )));
    }
    Ok(())
}

/// Which coordinates a route file's positions are in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoordFrame {
    /// Metres from the city's local origin (x east, y north, z up from the ground).
    #[default]
    Local,
    /// The city's metric world coordinates (z up from the ground); needs the city's frame.
    World,
}

/// What a route file's heights (z) are measured from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Heights {
    /// The frame's z (the world's heights; on terrain, a pose nearer the ground than the street
    /// eye height is raised to it).
    #[default]
    World,
    /// Metres above the ground under the eye (on terrain; the same as `world` in a flat city).
    AboveGround,
}

/// One key frame as written in a route file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeySpec {
    /// Eye position `[x, y, z]`.
    pub position: [f64; 3],
    /// A point to look at (same coordinates as `position`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub look_at: Option<[f64; 3]>,
    /// Heading, degrees counter-clockwise from east.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_deg: Option<f64>,
    /// Elevation, degrees, −90 looks straight down.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_deg: Option<f64>,
    /// Time in seconds from the start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// Speed (m/s) on the way to this key, when `time` is not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// Break the spline at this key.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub corner: bool,
}

/// A route file (see the [module docs](self) for the format).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
///
/// # Examples
/// ```
/// use blockwalk::route::RouteFile;
///
/// let file = RouteFile::from_toml(r#"
///     name = "two keys"
///     frames = 10
///     [[keys]]
///     position = [0.0, 0.0, 1.7]
///     yaw_deg = 0.0
///     [[keys]]
///     position = [14.0, 0.0, 1.7]
///     yaw_deg = 0.0
/// "#).unwrap();
/// let route = file.to_route(None).unwrap();
/// let cameras = route.sample(10);
/// assert_eq!(cameras.len(), 10);
/// // 14 m at the default walking pace of 1.4 m/s.
/// assert!((route.duration() - 10.0).abs() < 1e-9);
/// assert!((cameras[9].position.x - 14.0).abs() < 1e-9);
/// ```
pub struct RouteFile {
    /// Route name.
    #[serde(default = "default_name")]
    pub name: String,
    /// Coordinates of the positions.
    #[serde(default)]
    pub frame: CoordFrame,
    /// Default speed between keys, m/s.
    #[serde(default = "default_speed")]
    pub speed: f64,
    /// Turning speed for keys that do not move, degrees per second.
    #[serde(default = "default_turn_rate")]
    pub turn_rate_deg: f64,
    /// Frame count over the route.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<usize>,
    /// Frames per second (when `frames` is not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_deg: f64,
    /// Width / height.
    #[serde(default = "default_aspect")]
    pub aspect: f64,
    /// Near plane, metres.
    #[serde(default = "default_near")]
    pub near: f64,
    /// Far plane, metres.
    #[serde(default = "default_far")]
    pub far: f64,
    /// Orientation interpolation.
    #[serde(default)]
    pub orientation: OrientationInterpolation,
    /// What the keys' heights are measured from.
    #[serde(default)]
    pub heights: Heights,
    /// The key frames.
    pub keys: Vec<KeySpec>,
}

fn default_name() -> String {
    "route".into()
}
fn default_speed() -> f64 {
    1.4
}
fn default_turn_rate() -> f64 {
    45.0
}
fn default_fov() -> f64 {
    60.0
}
fn default_aspect() -> f64 {
    16.0 / 9.0
}
fn default_near() -> f64 {
    0.5
}
fn default_far() -> f64 {
    5000.0
}

impl RouteFile {
    /// Reads a route file; `.json` is JSON, anything else TOML.
    ///
    /// # Errors
    /// [`RouteError::Read`], [`RouteError::Json`] or [`RouteError::Toml`], naming the file.
    pub fn read(path: &Path) -> Result<Self, RouteError> {
        let file = || path.to_path_buf();
        let text = std::fs::read_to_string(path).map_err(|source| RouteError::Read {
            file: file(),
            source,
        })?;
        let is_json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        if is_json {
            serde_json::from_str(&text).map_err(|source| RouteError::Json {
                file: file(),
                source,
            })
        } else {
            toml::from_str(&text).map_err(|source| RouteError::Toml {
                file: file(),
                source,
            })
        }
    }

    /// Parses TOML text.
    ///
    /// # Errors
    /// [`RouteError::Toml`] (its file is `<toml>`).
    pub fn from_toml(text: &str) -> Result<Self, RouteError> {
        toml::from_str(text).map_err(|source| RouteError::Toml {
            file: "<toml>".into(),
            source,
        })
    }

    /// The frames to sample: `frames`, else `fps`, else 30 fps.
    pub fn frame_spec(&self) -> FrameSpec {
        match (self.frames, self.fps) {
            (Some(n), _) => FrameSpec::Count(n),
            (None, Some(f)) => FrameSpec::Rate(f),
            (None, None) => FrameSpec::Rate(30.0),
        }
    }

    /// The number of frames to sample over `route` (built from this file), checked: `frames`,
    /// else `fps` (default 30) × the route's duration, 1 to [`MAX_FRAMES`](super::MAX_FRAMES).
    /// `file` names the file in the error.
    ///
    /// # Errors
    /// [`RouteError::Bad`] naming the file, the fields and the cap.
    pub fn frame_count(&self, route: &CameraRoute, file: &str) -> Result<usize, RouteError> {
        let max = super::MAX_FRAMES;
        let bad = |problem: String| RouteError::Bad {
            route: file.into(),
            problem,
        };
        match self.frame_spec() {
            FrameSpec::Count(n) => super::check_frames(file, n).map_err(|_| {
                bad(format!(
                    "frames = {n}: expected 1 to {max} (the most frames a walk may sample)"
                ))
            }),
            FrameSpec::Rate(fps) => {
                let n = route.frames_at_rate(fps);
                if (1..=max).contains(&n) {
                    Ok(n)
                } else {
                    Err(bad(format!(
                        "fps = {fps} over the route's duration of {:.3} s gives {} frames; at most \
                         {max} frames (fps × duration + 1): lower fps or give `frames`",
                        route.duration(),
                        if n == usize::MAX {
                            "more than 2^64".to_string()
                        } else {
                            n.to_string()
                        }
                    )))
                }
            }
        }
    }

    /// Builds the route; `frame` is the city's local frame, needed when `frame = "world"`.
    pub fn to_route(&self, frame: Option<&LocalFrame>) -> Result<CameraRoute, RouteError> {
        let name = self.name.clone();
        let bad = |problem: String| RouteError::Bad {
            route: name.clone(),
            problem,
        };
        if !(self.speed > 0.0 && self.speed.is_finite()) {
            return Err(bad(format!("speed must be positive, got {}", self.speed)));
        }
        if !(self.turn_rate_deg > 0.0 && self.turn_rate_deg.is_finite()) {
            return Err(bad(format!(
                "turn_rate_deg must be positive, got {}",
                self.turn_rate_deg
            )));
        }
        if let Some(f) = self.fps {
            if !(f > 0.0 && f.is_finite()) {
                return Err(bad(format!("fps must be positive, got {f}")));
            }
        }
        if self.frames == Some(0) {
            return Err(bad("frames must be at least 1".into()));
        }
        let to_local = |p: [f64; 3]| -> Result<DVec3, RouteError> {
            let p = DVec3::from_array(p);
            match self.frame {
                CoordFrame::Local => Ok(p),
                CoordFrame::World => {
                    let f = frame.ok_or_else(|| {
                        bad("frame = \"world\" needs a city to place the route in".into())
                    })?;
                    // z stays above the ground: the local frame's origin has z = 0.
                    Ok(f.to_local_f64(p))
                }
            }
        };
        let mut keys: Vec<KeyFrame> = Vec::with_capacity(self.keys.len());
        for (i, k) in self.keys.iter().enumerate() {
            let bad_key = |problem: String| RouteError::BadKey {
                route: name.clone(),
                key: i,
                problem,
            };
            check_numbers(&bad_key, "position", &k.position, MAX_COORD_M, "m")?;
            if let Some(t) = k.look_at {
                check_numbers(&bad_key, "look_at", &t, MAX_COORD_M, "m")?;
            }
            if let Some(y) = k.yaw_deg {
                check_numbers(&bad_key, "yaw_deg", &[y], MAX_ANGLE_DEG, "°")?;
            }
            if let Some(p) = k.pitch_deg {
                check_numbers(&bad_key, "pitch_deg", &[p], 90.0, "°")?;
            }
            if let Some(t) = k.time {
                check_numbers(&bad_key, "time", &[t], MAX_TIME_S, "s")?;
            }
            if let Some(v) = k.speed {
                check_numbers(&bad_key, "speed", &[v], MAX_SPEED_M_S, "m/s")?;
            }
            let position = to_local(k.position)?;
            let (yaw, pitch) = match (k.look_at, k.yaw_deg) {
                (Some(_), Some(_)) => {
                    return Err(bad_key("give look_at or yaw_deg, not both".into()))
                }
                (None, None) => return Err(bad_key("give look_at or yaw_deg/pitch_deg".into())),
                (Some(t), None) => {
                    if k.pitch_deg.is_some() {
                        return Err(bad_key("pitch_deg goes with yaw_deg, not look_at".into()));
                    }
                    let t = to_local(t)?;
                    if t.distance(position) < 1e-9 {
                        return Err(bad_key("look_at equals the position".into()));
                    }
                    let c = crate::geom::Camera::looking_at(position, t);
                    (c.yaw, c.pitch)
                }
                (None, Some(y)) => {
                    let p = k.pitch_deg.unwrap_or(0.0);
                    if !(-90.0..=90.0).contains(&p) {
                        return Err(bad_key(format!("pitch_deg {p} is outside [-90, 90]")));
                    }
                    (y.to_radians(), p.to_radians())
                }
            };
            let mut key = KeyFrame::new(0.0, position, yaw, pitch);
            key.corner = k.corner;
            key.time = match (k.time, keys.last()) {
                (Some(t), _) => t,
                (None, None) => 0.0,
                (None, Some(prev)) => {
                    let speed = k.speed.unwrap_or(self.speed);
                    if !(speed > 0.0 && speed.is_finite()) {
                        return Err(bad_key(format!("speed must be positive, got {speed}")));
                    }
                    let d = prev.position.distance(position);
                    let turn = prev.orientation.angle_between(key.orientation).to_degrees();
                    let dt = (d / speed).max(turn / self.turn_rate_deg);
                    if dt <= 0.0 {
                        return Err(bad_key(
                            "neither moves nor turns from the previous key; give a time".into(),
                        ));
                    }
                    prev.time + dt
                }
            };
            keys.push(key);
        }
        let lens = Lens {
            fov_y: self.fov_deg.to_radians(),
            aspect: self.aspect,
            near: self.near,
            far: self.far,
        };
        let mut route = CameraRoute::new(name.clone(), keys, lens)?;
        route.orientation = self.orientation;
        Ok(route)
    }

    /// A route file describing `route`'s key frames in the local frame (for saving generated
    /// routes).
    pub fn from_route(route: &CameraRoute, frames: Option<usize>) -> Self {
        let keys = route
            .keys()
            .iter()
            .map(|k| {
                let (yaw, pitch) = super::yaw_pitch_from_orientation(k.orientation);
                KeySpec {
                    position: k.position.to_array(),
                    yaw_deg: Some(yaw.to_degrees()),
                    pitch_deg: Some(pitch.to_degrees()),
                    time: Some(k.time),
                    corner: k.corner,
                    ..Default::default()
                }
            })
            .collect();
        Self {
            name: route.name.clone(),
            frame: CoordFrame::Local,
            speed: default_speed(),
            turn_rate_deg: default_turn_rate(),
            frames,
            fps: None,
            fov_deg: route.lens.fov_y.to_degrees(),
            aspect: route.lens.aspect,
            near: route.lens.near,
            far: route.lens.far,
            orientation: route.orientation,
            heights: match route.ground.as_ref().map(|g| g.mode()) {
                Some(super::GroundMode::AboveGround) => Heights::AboveGround,
                _ => Heights::World,
            },
            keys,
        }
    }
}
