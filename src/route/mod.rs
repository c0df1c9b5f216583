//! Scripted camera routes (Pina, Serón and Cerezo, §5): key frames, interpolation, sampling into cameras.
//!
//! - [`CameraRoute`]: timed key frames (local frame, metres) interpolated with centripetal
//!   Catmull–Rom (positions) and squad (orientations), sampled into [`Camera`]s.
//! - [`choice`]: [`RouteChoice`], a named generated route or a route file, resolved for a city.
//! - [`mod@file`]: the route file format (TOML or JSON), see [`file::RouteFile`].
//! - [`generate`]: routes for any city: the paper's route, a street-level walk, a walk rounding
//!   building corners, an orbit; the street graph and its shortest paths.
//! - [`obstacles`]: the buildings a generated route keeps its eye [`EYE_CLEARANCE_M`] away from.
//! - [`spline`]: the interpolation kernels.

pub mod choice;
pub mod file;
pub mod flyover;
pub mod generate;
pub mod obstacles;
pub mod spline;

pub use choice::{RouteChoice, RouteContext, CORNERS_FRAME_STEP_M, STREET_FRAME_STEP_M};
pub use file::RouteFile;
pub use flyover::{flyover_route, flyover_route_with_near, FLYOVER_NEAR_SHARE};
pub use generate::{
    corner_walk, orbit_route, paper_route, street_walk, CornerWalkParams, PaperRouteParams,
    StreetGraph, ORBIT_SPREAD_QUANTILE,
};
pub use obstacles::{FootprintCorner, Obstacles, EYE_CLEARANCE_M};

/// Most frames a walk may sample (a route file or a caller's count): 100,000, about an hour at
/// 30 fps.
pub const MAX_FRAMES: usize = 100_000;

/// `frames` checked for the route `route`: 1 to [`MAX_FRAMES`].
///
/// # Errors
/// [`RouteError::Bad`] (naming the route and the count) outside that range.
pub fn check_frames(route: &str, frames: usize) -> Result<usize, RouteError> {
    if (1..=MAX_FRAMES).contains(&frames) {
        Ok(frames)
    } else {
        Err(RouteError::Bad {
            route: route.into(),
            problem: format!("{frames} frames; expected 1 to {MAX_FRAMES}"),
        })
    }
}

use crate::city::LocalFrame;
use crate::geom::Camera;
use glam::{DQuat, DVec3};
use std::f64::consts::FRAC_PI_2;

/// What is wrong with a route.
#[derive(Debug, thiserror::Error)]
pub enum RouteError {
    /// Fewer than two key frames.
    #[error("{route}: a route needs at least 2 key frames, got {n}")]
    TooFewKeys {
        /// Route name or file.
        route: String,
        /// Key frames given.
        n: usize,
    },
    /// A key frame's values are unusable.
    #[error("{route}: key frame {key}: {problem}")]
    BadKey {
        /// Route name or file.
        route: String,
        /// Index of the key frame.
        key: usize,
        /// What is wrong.
        problem: String,
    },
    /// A route-level value is unusable.
    #[error("{route}: {problem}")]
    Bad {
        /// Route name or file.
        route: String,
        /// What is wrong.
        problem: String,
    },
    /// A route that is neither a generated route's name nor a file that can be read.
    #[error("route '{name}': not a route name (paper, orbit, street, flyover, corners), and not a route file: {source}")]
    Unknown {
        /// What was given.
        name: String,
        /// Why it cannot be read as a file.
        #[source]
        source: std::io::Error,
    },
    /// The route file could not be read.
    #[error("{file}: {source}")]
    Read {
        /// The file.
        file: std::path::PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The route file is not valid route JSON.
    #[error("{file}: invalid route JSON: {source}")]
    Json {
        /// The file.
        file: std::path::PathBuf,
        /// What the parser said (with line and column).
        #[source]
        source: serde_json::Error,
    },
    /// The route file (or text) is not valid route TOML.
    #[error("{file}: invalid route TOML: {source}")]
    Toml {
        /// The file, or `<toml>` for text given directly.
        file: std::path::PathBuf,
        /// What the parser said (with line and column).
        #[source]
        source: toml::de::Error,
    },
}

/// How orientations are interpolated between key frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OrientationInterpolation {
    /// Spherical quadrangle interpolation: C¹ across keys (default).
    #[default]
    Squad,
    /// Spherical linear interpolation per segment: C⁰ across keys.
    Slerp,
}

/// One key frame in the local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyFrame {
    /// Time, seconds from the start of the route (strictly increasing along the route).
    pub time: f64,
    /// Eye position, local frame, metres.
    pub position: DVec3,
    /// Orientation: maps the camera's rest frame (forward +x, image-up +z) to the local frame;
    /// see [`orientation_from_yaw_pitch`].
    pub orientation: DQuat,
    /// A corner breaks the spline: the path and the turning on either side of this key ignore
    /// the keys beyond it (C⁰ here, e.g. where a walk turns into a vertical rise).
    pub corner: bool,
}

impl KeyFrame {
    /// A key frame looking along `yaw`/`pitch` (radians, as in [`Camera`]).
    pub fn new(time: f64, position: DVec3, yaw: f64, pitch: f64) -> Self {
        Self {
            time,
            position,
            orientation: orientation_from_yaw_pitch(yaw, pitch),
            corner: false,
        }
    }

    /// This key frame marked as a corner.
    pub fn corner(mut self) -> Self {
        self.corner = true;
        self
    }
}

/// The rotation taking the camera's rest frame (forward +x, up +z) to yaw/pitch:
/// `R_z(yaw) · R_y(−pitch)`. Agrees with [`Camera::forward`] and [`Camera::up`].
pub fn orientation_from_yaw_pitch(yaw: f64, pitch: f64) -> DQuat {
    let pitch = pitch.clamp(-FRAC_PI_2, FRAC_PI_2);
    (DQuat::from_rotation_z(yaw) * DQuat::from_rotation_y(-pitch)).normalize()
}

/// Yaw and pitch (radians) of an orientation; any roll is dropped ([`Camera`] has none).
///
/// Pitch comes from the forward vector. Yaw comes from the combination
/// `up.z · forward_xy − forward.z · up_xy`, which for a roll-free orientation is exactly
/// `(cos yaw, sin yaw)` at every pitch, including straight down and straight up, where the
/// forward vector alone has no heading. So the frame never flips and nothing is NaN.
pub fn yaw_pitch_from_orientation(q: DQuat) -> (f64, f64) {
    let q = q.normalize();
    let f = q * DVec3::X;
    let u = q * DVec3::Z;
    // atan2 rather than asin: asin loses half the digits next to ±90°.
    let pitch = f.z.atan2((f.x * f.x + f.y * f.y).sqrt());
    let hx = u.z * f.x - f.z * u.x;
    let hy = u.z * f.y - f.z * u.y;
    let yaw = if hx * hx + hy * hy > 1e-24 {
        hy.atan2(hx)
    } else {
        // A rolled camera looking sideways: use the forward heading.
        f.y.atan2(f.x)
    };
    (yaw, pitch)
}

/// Lens settings copied into every sampled [`Camera`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Lens {
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Width / height.
    pub aspect: f64,
    /// Near plane, metres.
    pub near: f64,
    /// Far plane, metres.
    pub far: f64,
}

impl Default for Lens {
    /// The lens of [`Camera::new`].
    fn default() -> Self {
        let c = Camera::new(DVec3::ZERO, 0.0, 0.0);
        Self {
            fov_y: c.fov_y,
            aspect: c.aspect,
            near: c.near,
            far: c.far,
        }
    }
}

/// How a route's heights meet the ground of a city on terrain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GroundMode {
    /// Key heights are heights above the ground under the eye: every pose is lifted by the
    /// terrain height there (street walks: the eye stays at its height above the local ground).
    AboveGround,
    /// Key heights are world heights; a pose that comes nearer the ground than this many metres
    /// is raised to it (fly-overs and orbits that pass over hills higher than the city).
    Clear(f64),
}

/// The ground a route's poses are lifted onto ([`GroundMode`]); a route without one (a flat
/// city) keeps its heights.
#[derive(Clone)]
pub struct RouteGround {
    terrain: std::sync::Arc<crate::terrain::Terrain>,
    frame: LocalFrame,
    mode: GroundMode,
}

impl RouteGround {
    /// Poses over `terrain` (metric world frame), given in `frame`'s local coordinates.
    pub fn new(
        terrain: std::sync::Arc<crate::terrain::Terrain>,
        frame: LocalFrame,
        mode: GroundMode,
    ) -> Self {
        Self {
            terrain,
            frame,
            mode,
        }
    }

    /// The ground mode.
    pub fn mode(&self) -> GroundMode {
        self.mode
    }

    /// The height of the ground as drawn (the full-resolution triangles) under a local point
    /// (`None` off the grid or over nodata): the eye is placed over what is seen, not over the
    /// smooth surface between the samples, which the triangles can lie above.
    pub fn ground_at(&self, local: DVec3) -> Option<f64> {
        let w = self.frame.to_world(local);
        self.terrain
            .sample_drawn(glam::DVec2::new(w.x, w.y))
            .map(|g| g - self.frame.origin.z)
    }

    /// `local` lifted by the mode; unchanged where the terrain has no height.
    pub fn lift(&self, local: DVec3) -> DVec3 {
        match (self.ground_at(local), self.mode) {
            (Some(g), GroundMode::AboveGround) => DVec3::new(local.x, local.y, local.z + g),
            (Some(g), GroundMode::Clear(c)) => DVec3::new(local.x, local.y, local.z.max(g + c)),
            (None, _) => local,
        }
    }
}

impl PartialEq for RouteGround {
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.terrain, &other.terrain)
            && self.frame == other.frame
            && self.mode == other.mode
    }
}

impl std::fmt::Debug for RouteGround {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RouteGround")
            .field("mode", &self.mode)
            .field("terrain", &self.terrain.report().source)
            .finish()
    }
}

/// A camera route: timed key frames and how to interpolate them (Pina, Serón and Cerezo, §5).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraRoute {
    /// Name (shown in reports).
    pub name: String,
    keys: Vec<KeyFrame>,
    /// Squad control quaternion per key (equal to the key at ends and corners).
    controls: Vec<DQuat>,
    /// Lens of every sampled camera.
    pub lens: Lens,
    /// Orientation interpolation.
    pub orientation: OrientationInterpolation,
    /// The ground poses are lifted onto (`None`: heights as the keys give them).
    pub ground: Option<RouteGround>,
}

impl CameraRoute {
    /// A route through `keys` (at least two, times strictly increasing, values finite).
    pub fn new(
        name: impl Into<String>,
        mut keys: Vec<KeyFrame>,
        lens: Lens,
    ) -> Result<Self, RouteError> {
        let name = name.into();
        if keys.len() < 2 {
            return Err(RouteError::TooFewKeys {
                route: name,
                n: keys.len(),
            });
        }
        for (i, k) in keys.iter().enumerate() {
            let bad = |problem: &str| RouteError::BadKey {
                route: name.clone(),
                key: i,
                problem: problem.to_string(),
            };
            for (what, finite) in [
                ("time", k.time.is_finite()),
                ("position", k.position.is_finite()),
                ("orientation", k.orientation.is_finite()),
            ] {
                if !finite {
                    return Err(bad(&format!(
                        "{what} is not a finite number (it overflowed or was given as NaN/inf)"
                    )));
                }
            }
            if k.orientation.length() < 1e-9 {
                return Err(bad("orientation is not a rotation"));
            }
            if i > 0 && k.time <= keys[i - 1].time {
                return Err(bad(&format!(
                    "time {} is not after the previous key's {}",
                    k.time,
                    keys[i - 1].time
                )));
            }
        }
        let lens_ok = lens.fov_y > 0.0
            && lens.fov_y < std::f64::consts::PI
            && lens.aspect > 0.0
            && lens.near > 0.0
            && lens.far > lens.near
            && lens.far.is_finite();
        if !lens_ok {
            return Err(RouteError::Bad {
                route: name,
                problem: format!(
                    "lens needs 0 < fov < 180°, aspect > 0 and 0 < near < far, got {lens:?}"
                ),
            });
        }
        let mut qs: Vec<DQuat> = keys.iter().map(|k| k.orientation.normalize()).collect();
        spline::align_hemispheres(&mut qs);
        for (k, q) in keys.iter_mut().zip(&qs) {
            k.orientation = *q;
        }
        let n = keys.len();
        let controls = (0..n)
            .map(|i| {
                let prev = (i > 0 && !keys[i].corner).then(|| qs[i - 1]);
                let next = (i + 1 < n && !keys[i].corner).then(|| qs[i + 1]);
                spline::squad_control(prev, qs[i], next)
            })
            .collect();
        Ok(Self {
            name,
            keys,
            controls,
            lens,
            orientation: OrientationInterpolation::Squad,
            ground: None,
        })
    }

    /// The key frames (orientations sign-aligned).
    pub fn keys(&self) -> &[KeyFrame] {
        &self.keys
    }

    /// Start time of the route (the first key's time).
    pub fn start(&self) -> f64 {
        self.keys[0].time
    }

    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        self.keys[self.keys.len() - 1].time - self.keys[0].time
    }

    /// Position and orientation at time `t` (clamped to the route).
    pub fn pose_at(&self, t: f64) -> (DVec3, DQuat) {
        let n = self.keys.len();
        let t = t.clamp(self.keys[0].time, self.keys[n - 1].time);
        // Segment i runs from key i to key i + 1.
        let i = match self
            .keys
            .binary_search_by(|k| k.time.partial_cmp(&t).unwrap_or(std::cmp::Ordering::Less))
        {
            Ok(i) => i.min(n - 2),
            Err(i) => i.saturating_sub(1).min(n - 2),
        };
        let (a, b) = (&self.keys[i], &self.keys[i + 1]);
        let u = ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
        let p0 = (i > 0 && !a.corner).then(|| self.keys[i - 1].position);
        let p3 = (i + 2 < n && !b.corner).then(|| self.keys[i + 2].position);
        let pos = spline::catmull_rom(p0, a.position, b.position, p3, u);
        let pos = self.ground.as_ref().map_or(pos, |g| g.lift(pos));
        let q = match self.orientation {
            OrientationInterpolation::Squad => spline::squad(
                a.orientation,
                b.orientation,
                self.controls[i],
                self.controls[i + 1],
                u,
            ),
            OrientationInterpolation::Slerp => a.orientation.slerp(b.orientation, u).normalize(),
        };
        (pos, q)
    }

    /// The camera at time `t` (clamped to the route).
    pub fn camera_at(&self, t: f64) -> Camera {
        let (position, q) = self.pose_at(t);
        let (yaw, pitch) = yaw_pitch_from_orientation(q);
        Camera {
            position,
            yaw,
            pitch,
            fov_y: self.lens.fov_y,
            aspect: self.lens.aspect,
            near: self.lens.near,
            far: self.lens.far,
        }
    }

    /// `n_frames` cameras evenly spaced in time, first and last key included (one frame gives
    /// the start).
    pub fn sample(&self, n_frames: usize) -> Vec<Camera> {
        match n_frames {
            0 => Vec::new(),
            1 => vec![self.camera_at(self.start())],
            n => (0..n)
                .map(|f| self.camera_at(self.start() + self.duration() * f as f64 / (n - 1) as f64))
                .collect(),
        }
    }

    /// How many frames [`CameraRoute::sample_rate`] gives at `fps` (0 when `fps` is not
    /// positive and finite), computed without sampling; saturates at `usize::MAX`.
    pub fn frames_at_rate(&self, fps: f64) -> usize {
        if !(fps > 0.0 && fps.is_finite()) {
            return 0;
        }
        ((self.duration() * fps + 1e-9).floor() as usize).saturating_add(1)
    }

    /// Cameras at `fps` frames per second from the start to the end (the end included when it
    /// falls on a frame). `fps` must be positive. At most [`MAX_FRAMES`] cameras: check the
    /// count with [`CameraRoute::frames_at_rate`] first (a rate past the cap stops there).
    pub fn sample_rate(&self, fps: f64) -> Vec<Camera> {
        let n = self.frames_at_rate(fps).min(MAX_FRAMES);
        (0..n)
            .map(|f| self.camera_at(self.start() + f as f64 / fps))
            .collect()
    }

    /// The fewest frames, found deterministically, for which [`CameraRoute::sample`] puts
    /// consecutive eye positions at most `max_step_m` metres apart: it starts from the keys'
    /// chord length over the step and grows the count until the sampled steps fit. At least 2,
    /// at most [`MAX_FRAMES`] (where a route too long for that many frames stops, with longer
    /// steps). A step that is not positive and finite gives 2.
    pub fn frames_for_step(&self, max_step_m: f64) -> usize {
        if !(max_step_m > 0.0 && max_step_m.is_finite()) {
            return 2;
        }
        let chords: f64 = self
            .keys
            .windows(2)
            .map(|w| w[0].position.distance(w[1].position))
            .sum();
        let mut n = ((chords / max_step_m).ceil() as usize)
            .saturating_add(1)
            .clamp(2, MAX_FRAMES);
        loop {
            let longest = self
                .sample(n)
                .windows(2)
                .map(|w| w[0].position.distance(w[1].position))
                .fold(0.0, f64::max);
            if longest <= max_step_m || n == MAX_FRAMES {
                return n;
            }
            n = n.saturating_add(n.div_ceil(8)).min(MAX_FRAMES);
        }
    }

    /// Axis-aligned box of the key positions (for reports).
    pub fn key_bounds(&self) -> crate::geom::Aabb3 {
        crate::geom::Aabb3::from_points(self.keys.iter().map(|k| k.position))
    }
}

/// How many frames to sample: a fixed count or a rate.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameSpec {
    /// Exactly this many frames over the route.
    Count(usize),
    /// This many frames per second of route time.
    Rate(f64),
}

impl CameraRoute {
    /// Samples by a [`FrameSpec`].
    pub fn sample_by(&self, spec: FrameSpec) -> Vec<Camera> {
        match spec {
            FrameSpec::Count(n) => self.sample(n),
            FrameSpec::Rate(fps) => self.sample_rate(fps),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_pitch_round_trip_including_poles() {
        for yaw in [-3.0, -1.0, 0.0, 0.5, 2.0, 3.1] {
            for pitch in [-FRAC_PI_2, -1.0, 0.0, 0.7, FRAC_PI_2] {
                let (y, p) = yaw_pitch_from_orientation(orientation_from_yaw_pitch(yaw, pitch));
                assert!((p - pitch).abs() < 1e-9, "{yaw} {pitch}: {p}");
                let dy = (y - yaw).rem_euclid(std::f64::consts::TAU);
                assert!(
                    !(1e-9..=std::f64::consts::TAU - 1e-9).contains(&dy),
                    "{yaw} {pitch}: {y}"
                );
            }
        }
    }

    #[test]
    fn orientation_matches_camera_vectors() {
        let (yaw, pitch) = (0.8, -0.4);
        let q = orientation_from_yaw_pitch(yaw, pitch);
        let c = Camera::new(DVec3::ZERO, yaw, pitch);
        assert!((q * DVec3::X).distance(c.forward()) < 1e-12);
        assert!((q * DVec3::Z).distance(c.up()) < 1e-12);
    }
}
