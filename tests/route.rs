//! Camera routes: interpolation, continuity, poles, determinism, files, generated routes.

mod support;

use blockwalk::city::LocalFrame;
use blockwalk::geom::{Aabb3, Camera};
use blockwalk::route::file::RouteFile;
use blockwalk::route::{
    orbit_route, paper_route, street_walk, CameraRoute, FrameSpec, KeyFrame, Lens, Obstacles,
    PaperRouteParams, RouteError, StreetGraph,
};
use geo_types::LineString;
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::f64::consts::FRAC_PI_2;

fn routes_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/routes")
}

fn zigzag() -> CameraRoute {
    let keys = vec![
        KeyFrame::new(0.0, DVec3::new(0.0, 0.0, 2.0), 0.0, 0.0),
        KeyFrame::new(1.0, DVec3::new(10.0, 3.0, 2.0), 0.5, 0.1),
        KeyFrame::new(3.0, DVec3::new(20.0, -5.0, 30.0), 1.5, -FRAC_PI_2),
        KeyFrame::new(4.0, DVec3::new(25.0, 0.0, 60.0), 2.5, -FRAC_PI_2),
        KeyFrame::new(6.0, DVec3::new(40.0, 40.0, 1.7), -2.0, -0.5),
    ];
    CameraRoute::new("zigzag", keys, Lens::default()).unwrap()
}

fn same_direction(a: &Camera, b: &Camera) -> bool {
    a.forward().distance(b.forward()) < 1e-9 && a.up().distance(b.up()) < 1e-9
}

#[test]
fn passes_through_every_key_frame() {
    let r = zigzag();
    for k in r.keys() {
        let c = r.camera_at(k.time);
        assert!(c.position.distance(k.position) < 1e-9, "{k:?} → {c:?}");
        let (yaw, pitch) = blockwalk::route::yaw_pitch_from_orientation(k.orientation);
        let expect = Camera::new(k.position, yaw, pitch);
        assert!(same_direction(&c, &expect), "{k:?} → {c:?}");
    }
}

#[test]
fn positions_and_directions_are_continuous() {
    let r = zigzag();
    let n = 6001;
    let cams = r.sample(n);
    assert_eq!(cams.len(), n);
    // A bound on the speed of this route (its chords are at most ~40 m per second of route
    // time, the spline overshoots little): 6 s / 6000 steps moves well under 0.5 m and turns
    // well under 2°.
    for w in cams.windows(2) {
        assert!(w[0].position.distance(w[1].position) < 0.5);
        let turn = w[0].forward().dot(w[1].forward()).clamp(-1.0, 1.0).acos();
        assert!(turn < 2f64.to_radians(), "turn {turn} at {:?}", w[0]);
        let roll = w[0].up().dot(w[1].up()).clamp(-1.0, 1.0).acos();
        assert!(roll < 2f64.to_radians(), "image-up jumps at {:?}", w[0]);
    }
}

#[test]
fn looking_straight_down_never_produces_nan_or_flips() {
    // Two keys straight down with different headings, and a pass through the pole.
    let keys = vec![
        KeyFrame::new(0.0, DVec3::new(0.0, 0.0, 100.0), 0.3, -FRAC_PI_2),
        // A corner: the turn from straight down towards the horizon starts here, so the first
        // segment only spins about the vertical.
        KeyFrame::new(1.0, DVec3::new(0.0, 0.0, 50.0), 2.0, -FRAC_PI_2).corner(),
        KeyFrame::new(2.0, DVec3::new(0.0, 0.0, 10.0), 2.0, -0.2),
        KeyFrame::new(
            3.0,
            DVec3::new(0.0, 0.0, 10.0),
            2.0 + std::f64::consts::PI,
            -0.2,
        ),
    ];
    let r = CameraRoute::new("pole", keys, Lens::default()).unwrap();
    let cams = r.sample(3001);
    for c in &cams {
        let m = c.clip_from_world();
        assert!(m.to_cols_array().iter().all(|v| v.is_finite()), "{c:?}");
        assert!(c.yaw.is_finite() && c.pitch.is_finite());
        assert!(c.pitch >= -FRAC_PI_2 - 1e-12 && c.pitch <= FRAC_PI_2 + 1e-12);
    }
    for w in cams[..1000].windows(2) {
        // While looking straight down the image-up vector turns smoothly with the heading.
        assert!((w[0].forward().z + 1.0).abs() < 1e-9);
        assert!(w[0].up().dot(w[1].up()) > 0.999, "flip at {:?}", w[0]);
    }
    assert!(
        cams[0]
            .up()
            .distance(DVec3::new(0.3f64.cos(), 0.3f64.sin(), 0.0))
            < 1e-9
    );
}

#[test]
fn sampling_is_deterministic_and_counts_frames() {
    let a = zigzag().sample(300);
    let b = zigzag().sample(300);
    assert_eq!(a, b);
    assert_eq!(zigzag().sample(1).len(), 1);
    assert!(zigzag().sample(0).is_empty());
    // 6 s at 10 fps: frames 0..=60.
    assert_eq!(zigzag().sample_rate(10.0).len(), 61);
}

#[test]
fn bad_routes_are_refused_with_reasons() {
    let one = vec![KeyFrame::new(0.0, DVec3::ZERO, 0.0, 0.0)];
    let e = CameraRoute::new("x", one, Lens::default()).unwrap_err();
    assert!(matches!(e, RouteError::TooFewKeys { n: 1, .. }), "{e:?}");
    assert!(e.to_string().contains("at least 2"), "{e}");
    let back = vec![
        KeyFrame::new(1.0, DVec3::ZERO, 0.0, 0.0),
        KeyFrame::new(0.5, DVec3::X, 0.0, 0.0),
    ];
    let e = CameraRoute::new("x", back, Lens::default()).unwrap_err();
    assert!(matches!(e, RouteError::BadKey { key: 1, .. }), "{e:?}");
    assert!(e.to_string().contains("key frame 1"), "{e}");
    let nan = vec![
        KeyFrame::new(0.0, DVec3::ZERO, 0.0, 0.0),
        KeyFrame::new(1.0, DVec3::new(f64::NAN, 0.0, 0.0), 0.0, 0.0),
    ];
    let e = CameraRoute::new("x", nan, Lens::default()).unwrap_err();
    assert!(matches!(e, RouteError::BadKey { key: 1, .. }), "{e:?}");
    assert!(e.to_string().contains("finite"), "{e}");
}

#[test]
fn example_route_files_load_and_sample() {
    for name in ["avenue.toml", "flyover.toml", "flyover.json"] {
        let f = RouteFile::read(&routes_dir().join(name)).unwrap();
        let r = f.to_route(None).unwrap();
        let cams = r.sample_by(f.frame_spec());
        assert!(cams.len() > 10, "{name}");
        assert!(cams
            .iter()
            .all(|c| c.position.is_finite() && c.yaw.is_finite()));
        assert!(cams[0].position.distance(r.keys()[0].position) < 1e-9);
    }
    // avenue: times from speed; 100 m at 1.4 m/s then 50 m at 1 m/s, then a 45°+25° turn in
    // place at 45°/s.
    let f = RouteFile::read(&routes_dir().join("avenue.toml")).unwrap();
    let r = f.to_route(None).unwrap();
    assert!((r.keys()[1].time - 100.0 / 1.4).abs() < 1e-9);
    assert!((r.keys()[2].time - (100.0 / 1.4 + 50.0)).abs() < 1e-9);
    assert_eq!(f.frame_spec(), FrameSpec::Count(120));
}

#[test]
fn route_file_errors_name_the_problem() {
    let both = r#"
        [[keys]]
        position = [0.0, 0.0, 1.0]
        look_at = [1.0, 0.0, 1.0]
        yaw_deg = 3.0
        [[keys]]
        position = [1.0, 0.0, 1.0]
        yaw_deg = 0.0
    "#;
    let e = RouteFile::from_toml(both)
        .unwrap()
        .to_route(None)
        .unwrap_err();
    assert!(matches!(e, RouteError::BadKey { key: 0, .. }), "{e:?}");
    assert!(e.to_string().contains("key frame 0") && e.to_string().contains("not both"));
    let world = r#"
        frame = "world"
        [[keys]]
        position = [0.0, 0.0, 1.0]
        yaw_deg = 0.0
        [[keys]]
        position = [1.0, 0.0, 1.0]
        yaw_deg = 0.0
    "#;
    let f = RouteFile::from_toml(world).unwrap();
    let e = f.to_route(None).unwrap_err();
    assert!(matches!(e, RouteError::Bad { .. }), "{e:?}");
    assert!(e.to_string().contains("world"), "{e}");
    let frame = LocalFrame {
        origin: DVec3::new(500.0, 600.0, 0.0),
    };
    let r = f.to_route(Some(&frame)).unwrap();
    assert_eq!(r.keys()[0].position, DVec3::new(-500.0, -600.0, 1.0));
    let e = RouteFile::from_toml("keys = 3").unwrap_err();
    assert!(matches!(e, RouteError::Toml { .. }), "{e:?}");
    assert!(e.to_string().contains("<toml>"), "{e}");
    let unknown = "nmae = \"x\"\nkeys = []";
    let e = RouteFile::from_toml(unknown).unwrap_err();
    assert!(matches!(e, RouteError::Toml { .. }), "{e:?}");
    assert!(e.to_string().contains("nmae"), "{e}");
}

#[test]
fn route_file_numbers_that_are_not_finite_or_out_of_range_are_named_with_their_key() {
    let file = |second: &str| {
        format!(
            "[[keys]]\nposition = [0.0, 0.0, 1.7]\nyaw_deg = 0.0\n\
             [[keys]]\n{second}\n"
        )
    };
    let cases = [
        (
            "position = [nan, 0.0, 1.7]\nyaw_deg = 0.0",
            "position = [NaN, 0, 1.7]: not a finite number",
        ),
        (
            "position = [inf, 0.0, 1.7]\nyaw_deg = 0.0",
            "not a finite number",
        ),
        (
            "position = [1e300, 0.0, 1.7]\nyaw_deg = 0.0",
            "out of range; expected -100000000 to 100000000 m",
        ),
        (
            "position = [-1e300, 0.0, 1.7]\nyaw_deg = 0.0",
            "out of range",
        ),
        (
            "position = [5.0, 0.0, 1.7]\nlook_at = [nan, 0.0, 0.0]",
            "look_at = [NaN, 0, 0]: not a finite number",
        ),
        (
            "position = [5.0, 0.0, 1.7]\nyaw_deg = nan",
            "yaw_deg = NaN: not a finite number",
        ),
        (
            "position = [5.0, 0.0, 1.7]\nyaw_deg = 0.0\ntime = 1e300",
            "time = 1e300: out of range",
        ),
        (
            "position = [5.0, 0.0, 1.7]\nyaw_deg = 0.0\nspeed = nan",
            "speed = NaN: not a finite number",
        ),
    ];
    for (second, want) in cases {
        let e = RouteFile::from_toml(&file(second))
            .unwrap()
            .to_route(None)
            .unwrap_err();
        assert!(
            matches!(e, RouteError::BadKey { key: 1, .. }),
            "{second}: {e:?}"
        );
        let text = e.to_string();
        assert!(text.contains("key frame 1"), "{second}: {text}");
        assert!(text.contains(want), "{second}: {text}");
        assert!(
            !text.contains("neither moves nor turns"),
            "{second}: {text}"
        );
    }
    // Large but in range is still accepted.
    let ok = file("position = [1e7, 0.0, 1.7]\nyaw_deg = 0.0");
    assert!(RouteFile::from_toml(&ok).unwrap().to_route(None).is_ok());
}

#[test]
fn route_file_read_errors_name_the_file_and_keep_the_cause() {
    use std::error::Error;
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.toml");
    let e = RouteFile::read(&missing).unwrap_err();
    match &e {
        RouteError::Read { file, source } => {
            assert_eq!(file, &missing);
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("{other:?}"),
    }
    assert!(e.source().is_some());

    let json = dir.path().join("r.json");
    std::fs::write(&json, "{\"keys\": [").unwrap();
    let e = RouteFile::read(&json).unwrap_err();
    match &e {
        RouteError::Json { file, source } => {
            assert_eq!(file, &json);
            assert!(source.is_eof(), "{source}");
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("r.json"), "{e}");

    let toml = dir.path().join("r.toml");
    std::fs::write(&toml, "speed = \"fast\"\nkeys = []").unwrap();
    let e = RouteFile::read(&toml).unwrap_err();
    match &e {
        RouteError::Toml { file, source } => {
            assert_eq!(file, &toml);
            assert!(source.span().is_some());
        }
        other => panic!("{other:?}"),
    }
    assert!(
        e.to_string().contains("r.toml") && e.to_string().contains("speed"),
        "{e}"
    );
}

#[test]
fn route_file_round_trips_a_generated_route() {
    let r = zigzag();
    let f = RouteFile::from_route(&r, Some(50));
    let text = toml::to_string(&f).unwrap();
    let back = RouteFile::from_toml(&text).unwrap().to_route(None).unwrap();
    for (a, b) in r.sample(50).iter().zip(back.sample(50).iter()) {
        assert!(a.position.distance(b.position) < 1e-6);
        assert!(same_direction_loose(a, b));
    }
}

fn same_direction_loose(a: &Camera, b: &Camera) -> bool {
    a.forward().distance(b.forward()) < 1e-6 && a.up().distance(b.up()) < 1e-6
}

/// A grid of streets 100 m apart over [0, 400]² world metres, origin at (200, 200).
fn grid() -> (Vec<LineString<f64>>, LocalFrame) {
    let mut lines = Vec::new();
    for i in 0..5 {
        let v = 100.0 * i as f64;
        lines.push(LineString::from(
            (0..5).map(|j| (v, 100.0 * j as f64)).collect::<Vec<_>>(),
        ));
        lines.push(LineString::from(
            (0..5).map(|j| (100.0 * j as f64, v)).collect::<Vec<_>>(),
        ));
    }
    let frame = LocalFrame {
        origin: DVec3::new(200.0, 200.0, 0.0),
    };
    (lines, frame)
}

#[test]
fn paper_route_walks_streets_rises_and_lands() {
    let (lines, frame) = grid();
    let g = StreetGraph::from_world_lines(&lines, &frame);
    let bounds = Aabb3::new(
        DVec3::new(-200.0, -200.0, 0.0),
        DVec3::new(200.0, 200.0, 40.0),
    );
    let p = PaperRouteParams::default();
    let r = paper_route(&bounds, Some(&g), &Obstacles::none(), &p, Lens::default()).unwrap();
    let cams = r.sample(300);
    // Starts outside the box at eye height.
    assert!(cams[0].position.y < bounds.min.y);
    assert!((cams[0].position.z - p.eye_height).abs() < 1e-9);
    // The walk's keys lie on streets (grid lines): x or y a multiple of 100 (local -200..200).
    let walk_end = r.keys().iter().position(|k| k.corner).unwrap();
    for k in &r.keys()[1..=walk_end] {
        let on = |v: f64| ((v + 200.0) / 100.0 - ((v + 200.0) / 100.0).round()).abs() < 1e-9;
        assert!(on(k.position.x) || on(k.position.y), "{k:?}");
        assert!((k.position.z - p.eye_height).abs() < 1e-9);
    }
    // The walk ends at the street node nearest the centre: (0, 0).
    assert!(r.keys()[walk_end].position.truncate().length() < 1e-9);
    // The top of the rise is right above it, above the roofs, looking straight down.
    let top = r.keys()[walk_end + 1];
    assert!(top.position.truncate().length() < 1e-9);
    assert!(top.position.z > bounds.max.z);
    let c = r.camera_at(top.time);
    assert!((c.forward().z + 1.0).abs() < 1e-9);
    // The rise is vertical: every frame between the walk's end and the top is above (0, 0).
    let (t0, t1) = (r.keys()[walk_end].time, top.time);
    for i in 0..=50 {
        let c = r.camera_at(t0 + (t1 - t0) * i as f64 / 50.0);
        assert!(c.position.truncate().length() < 1e-9, "{c:?}");
    }
    // Lands at eye height away from the centre, looking a little down (at the city, not at the
    // ground at its feet).
    let last = cams.last().unwrap();
    assert!((last.position.z - p.eye_height).abs() < 1e-9);
    assert!(last.position.truncate().length() > 50.0);
    assert!((last.pitch - p.landing_pitch).abs() < 1e-9, "{last:?}");
    // The walk takes the street path: its length is the Manhattan distance from the entry node.
    let walk: f64 = r.keys()[1..=walk_end]
        .windows(2)
        .map(|w| w[0].position.distance(w[1].position))
        .sum();
    assert!((walk - 200.0).abs() < 1e-6, "walk {walk}");
    assert!(cams
        .iter()
        .all(|c| c.position.is_finite() && c.yaw.is_finite()));
}

#[test]
fn paper_route_without_streets_goes_straight_in() {
    let bounds = Aabb3::new(
        DVec3::new(-100.0, -50.0, 0.0),
        DVec3::new(100.0, 50.0, 20.0),
    );
    let r = paper_route(
        &bounds,
        None,
        &Obstacles::none(),
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap();
    assert_eq!(r.keys()[1].position.truncate(), DVec2::ZERO);
    let e = paper_route(
        &Aabb3::EMPTY,
        None,
        &Obstacles::none(),
        &PaperRouteParams::default(),
        Lens::default(),
    )
    .unwrap_err();
    assert!(matches!(e, RouteError::Bad { .. }), "{e:?}");
}

#[test]
fn street_walk_and_orbit() {
    let (lines, frame) = grid();
    let g = StreetGraph::from_world_lines(&lines, &frame);
    let r = street_walk(
        &g,
        &Obstacles::none(),
        DVec2::new(-190.0, -190.0),
        DVec2::new(190.0, 110.0),
        1.7,
        1.4,
        Lens::default(),
    )
    .unwrap();
    // From (-200,-200) to (200,100): 700 m at 1.4 m/s.
    assert!((r.duration() - 700.0 / 1.4).abs() < 1e-6);
    let bounds = Aabb3::new(
        DVec3::new(-200.0, -200.0, 0.0),
        DVec3::new(200.0, 200.0, 40.0),
    );
    let o = orbit_route(
        &bounds,
        &Obstacles::none(),
        1.5,
        100.0,
        60.0,
        Lens::default(),
    )
    .unwrap();
    for c in o.sample(97) {
        // Always at the orbit height, roughly at the radius, looking towards the centre.
        assert!((c.position.z - 140.0).abs() < 1e-6);
        let r = c.position.truncate().length();
        assert!((r - 300.0).abs() < 5.0, "radius {r}");
        let to_centre = (DVec3::ZERO - c.position).normalize();
        assert!(c.forward().dot(to_centre) > 0.99);
    }
}

/// A square building of side `side` metres centred at `(x, y)` (world metres), `h` metres high.
fn square_building(i: u32, x: f64, y: f64, side: f64, h: f64) -> blockwalk::city::Building {
    let s = 0.5 * side;
    blockwalk::city::Building {
        id: blockwalk::city::BuildingId(i),
        source_id: format!("t:{i}"),
        footprint: geo_types::Polygon::new(
            LineString::from(vec![
                (x - s, y - s),
                (x + s, y - s),
                (x + s, y + s),
                (x - s, y + s),
                (x - s, y - s),
            ]),
            Vec::new(),
        ),
        height_m: h,
        min_height_m: 0.0,
        base_m: 0.0,
        height_source: blockwalk::city::HeightSource::Height,
        attributes: Default::default(),
    }
}

/// A sparse city: a dense 12 × 12 cluster of 20 m buildings 40 m apart around world (1000,
/// 1000), and four small outliers kilometres away, so that the box's centre (about (4500,
/// 4000)) has nothing near it.
fn sparse_city() -> Vec<blockwalk::city::Building> {
    let mut b = Vec::new();
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (780.0 + 40.0 * i as f64, 780.0 + 40.0 * j as f64);
            b.push(square_building(
                b.len() as u32,
                x,
                y,
                20.0,
                12.0 + (i + j) as f64,
            ));
        }
    }
    for (x, y) in [
        (9000.0, 1000.0),
        (9000.0, 7000.0),
        (1000.0, 7000.0),
        (6000.0, 4000.0),
    ] {
        b.push(square_building(b.len() as u32, x, y, 8.0, 6.0));
    }
    b
}

#[test]
fn orbit_frames_the_buildings_of_a_sparse_city_not_its_box() {
    use blockwalk::route::{RouteChoice, RouteContext};
    let buildings = sparse_city();
    let frame = LocalFrame {
        origin: DVec3::new(1000.0, 1000.0, 0.0),
    };
    let obstacles = Obstacles::from_buildings(&buildings, &frame);
    let boxes = obstacles.boxes();
    assert_eq!(boxes.len(), buildings.len());
    let mut bounds = Aabb3::EMPTY;
    for b in &boxes {
        bounds = bounds.union(*b);
    }
    let ctx = RouteContext {
        city: "sparse",
        bounds,
        street_edges: &[],
        buildings: &buildings,
        frame: &frame,
        aspect: 16.0 / 9.0,
        terrain: None,
    };
    let (route, frames) = RouteChoice::Orbit.resolve(&ctx).unwrap();
    assert_eq!(frames, None);
    // The cluster spans local -220..220: the orbit circles it, not the 9 km box.
    let cams = route.sample(60);
    for c in &cams {
        let r = c.position.truncate().length();
        assert!(r > 220.0 && r < 600.0, "radius {r} at {c:?}");
    }
    for (f, c) in cams.iter().enumerate() {
        let frustum = c.frustum();
        let seen = boxes
            .iter()
            .filter(|b| frustum.intersects_aabb_exact(b))
            .count();
        assert!(seen > 0, "frame {f}: no building in view from {c:?}");
        // And the cluster's middle is in view, not only a corner of it.
        assert!(frustum.contains_point(DVec3::ZERO), "frame {f}: {c:?}");
    }
    // Deterministic.
    assert_eq!(cams, RouteChoice::Orbit.resolve(&ctx).unwrap().0.sample(60));
}

/// A long street grid: 21 × 21 streets 250 m apart over [0, 5000]² world metres.
fn long_grid() -> (Vec<LineString<f64>>, LocalFrame) {
    let mut lines = Vec::new();
    for i in 0..21 {
        let v = 250.0 * i as f64;
        lines.push(LineString::from(
            (0..21).map(|j| (v, 250.0 * j as f64)).collect::<Vec<_>>(),
        ));
        lines.push(LineString::from(
            (0..21).map(|j| (250.0 * j as f64, v)).collect::<Vec<_>>(),
        ));
    }
    let frame = LocalFrame {
        origin: DVec3::new(2500.0, 2500.0, 0.0),
    };
    (lines, frame)
}

#[test]
fn street_walk_frames_keep_a_walking_pace_on_a_long_street_graph() {
    use blockwalk::route::{RouteChoice, RouteContext, STREET_FRAME_STEP_M};
    let (lines, frame) = long_grid();
    let ctx = RouteContext {
        city: "long",
        bounds: Aabb3::new(
            DVec3::new(-2500.0, -2500.0, 0.0),
            DVec3::new(2500.0, 2500.0, 20.0),
        ),
        street_edges: &lines,
        buildings: &[],
        frame: &frame,
        aspect: 16.0 / 9.0,
        terrain: None,
    };
    let (route, frames) = RouteChoice::Street.resolve(&ctx).unwrap();
    let frames = frames.expect("the street walk reports its frame count");
    // Corner to corner: 10 km of streets.
    assert!((route.duration() * 1.4 - 10_000.0).abs() < 1e-6);
    assert!(
        frames as f64 >= 10_000.0 / STREET_FRAME_STEP_M,
        "{frames} frames"
    );
    assert!(
        (frames as f64) < 1.5 * 10_000.0 / STREET_FRAME_STEP_M + 2.0,
        "{frames} frames: more than the pace needs"
    );
    let cams = route.sample(frames);
    for w in cams.windows(2) {
        let step = w[0].position.distance(w[1].position);
        assert!(
            step <= STREET_FRAME_STEP_M,
            "{step:.2} m between frames at {:?}",
            w[0].position
        );
    }
    assert_eq!(
        frames,
        RouteChoice::Street.resolve(&ctx).unwrap().1.unwrap()
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any random route hits its keys, stays finite and is reproducible.
    #[test]
    fn random_routes_hit_keys(
        pts in prop::collection::vec(
            ((-500.0f64..500.0, -500.0f64..500.0, 0.0f64..300.0), (-4.0f64..4.0, -1.6f64..1.6), 0.1f64..5.0),
            2..8,
        )
    ) {
        let mut t = 0.0;
        let keys: Vec<KeyFrame> = pts.iter().map(|((x, y, z), (yaw, pitch), dt)| {
            t += dt;
            KeyFrame::new(t, DVec3::new(*x, *y, *z), *yaw, *pitch)
        }).collect();
        let r = CameraRoute::new("p", keys.clone(), Lens::default()).unwrap();
        for k in &keys {
            let c = r.camera_at(k.time);
            prop_assert!(c.position.distance(k.position) < 1e-6);
            let f = k.orientation * DVec3::X;
            prop_assert!(c.forward().distance(f) < 1e-6);
        }
        let cams = r.sample(64);
        prop_assert!(cams.iter().all(|c| c.position.is_finite() && c.yaw.is_finite() && c.pitch.is_finite()));
        prop_assert_eq!(cams, r.sample(64));
    }
}

/// Every generated route on the bundled cities and a synthetic one: every frame's eye is at
/// least [`EYE_CLEARANCE_M`] from every building (brute force over the footprints with `geo`,
/// not through the generator's R-tree), and every frame sees at least one block in the
/// visibility oracle's image.
#[test]
fn generated_routes_keep_clear_of_buildings_and_see_the_city() {
    use blockwalk::route::{RouteChoice, EYE_CLEARANCE_M};
    use blockwalk::scene::{CitySource, Scene, SceneOptions};
    use blockwalk::walk::job::route_context;
    use geo::{Distance, Euclidean};
    const FRAMES: usize = 120;
    const SIZE: (u32, u32) = (192, 108);
    use support::data::data;
    let cities = [
        (
            data("bubenec/buildings.shp"),
            Some(data("bubenec/streets.shp")),
        ),
        (
            data("helsinki/buildings.shp"),
            Some(data("helsinki/streets_blockclass.shp")),
        ),
        (std::path::PathBuf::from("synthetic:6x5"), None),
    ];
    let mut summary = Vec::new();
    for (buildings, streets) in cities {
        let label = buildings.display().to_string();
        let label = label.rsplit("data/").next().unwrap_or(&label).to_string();
        let source = CitySource::parse(&buildings, streets, None, &[], 3).unwrap();
        let opts = SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        };
        let scene = Scene::load(&source, &opts, &mut |_| {}).expect("scene");
        let frame = &scene.city.frame;
        let prisms: Vec<(geo_types::Polygon<f64>, f64, f64)> = scene
            .city
            .buildings
            .iter()
            .map(|b| {
                (
                    frame.to_local_polygon(&b.footprint),
                    b.min_height_m,
                    b.height_m,
                )
            })
            .collect();
        let meshes: Vec<(blockwalk::blocks::BlockId, &blockwalk::city::Mesh)> = scene
            .block_meshes()
            .iter()
            .map(|(id, m)| (*id, m))
            .collect();
        let ctx = route_context(&scene, SIZE.0 as f64 / SIZE.1 as f64);
        for choice in [RouteChoice::Paper, RouteChoice::Orbit, RouteChoice::Street] {
            let (route, _) = choice
                .resolve(&ctx)
                .unwrap_or_else(|e| panic!("{}: {choice}: {e}", scene.name));
            let (mut min_visible, mut min_gap) = (usize::MAX, f64::INFINITY);
            for (f, cam) in route.sample(FRAMES).iter().enumerate() {
                let eye = cam.position;
                let p = geo_types::Point::new(eye.x, eye.y);
                let gap = prisms
                    .iter()
                    .map(|(fp, lo, hi)| {
                        let dh = Euclidean.distance(&p, fp);
                        let dv = (lo - eye.z).max(eye.z - hi).max(0.0);
                        (dh * dh + dv * dv).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    gap >= EYE_CLEARANCE_M * (1.0 - 1e-9),
                    "{}: {choice} frame {f}: eye {eye} is {gap:.3} m from a building",
                    scene.name
                );
                let seen =
                    blockwalk::visibility::oracle::visible_blocks(&meshes, cam, SIZE.0, SIZE.1);
                assert!(
                    !seen.is_empty(),
                    "{}: {choice} frame {f}: no building in view from {eye}, yaw {:.2}, pitch {:.2}",
                    scene.name,
                    cam.yaw,
                    cam.pitch
                );
                min_visible = min_visible.min(seen.len());
                min_gap = min_gap.min(gap);
            }
            summary.push(format!(
                "{label}: {choice}: {FRAMES} frames, min visible blocks {min_visible}, min eye clearance {min_gap:.2} m"
            ));
        }
    }
    println!("{}", summary.join("\n"));
}
