//! Cities on terrain: buildings put on the ground (base rules, the report, refusals), checked
//! against brute-force sampling of the terrain; real DEMs under generated cities (a steep valley,
//! a lon/lat DEM, a 1 m LiDAR grid and the same grid at 90 m); routes lifted onto the ground.

mod support;

use blockwalk::city::build::ground::{place_buildings, GroundOptions};
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::model::CityReport;
use blockwalk::city::{Building, City};
use blockwalk::route::RouteChoice;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::terrain::{BaseRule, GridSpec, Synthetic, Terrain};
use geo_types::{Coord, LineString, Polygon};
use glam::DVec2;
use std::path::PathBuf;
use support::data::shared_data;
use support::skip::{or_skip, Need};

const NEPAL: &str = "dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif";
const GRENOBLE: &str =
    "dem/grenoble-copernicus-demcompare/Copernicus_DSM_10_N45_00_E005_00_DEM.tif";
const MINNESOTA: &str = "dem/minnesota-lidar-1m/lidar_dem_1m_26915.tif";

fn dem(rel: &str, test: &str) -> Option<PathBuf> {
    let p = shared_data(rel);
    or_skip(
        Need::Dem,
        test,
        if p.is_file() {
            Ok(p)
        } else {
            Err(format!("../shared/data/{rel} absent"))
        },
    )
}

/// A generated city of `n` buildings in EPSG:`epsg` centred at `centre`, written to a folder.
fn generated(n: usize, seed: u64, epsg: u32, centre: (f64, f64)) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let city = generate_city(&GenerateParams {
        buildings: n,
        seed,
        epsg,
        centre: Some(centre),
        ..Default::default()
    })
    .unwrap();
    write_city(&city, &dir.path().join("city")).unwrap();
    dir
}

fn load_on(dir: &tempfile::TempDir, g: GroundOptions) -> City {
    CitySource::parse(&dir.path().join("city"), None, None, &[], 0)
        .unwrap()
        .with_ground(Some(g))
        .load(&Default::default(), &mut |_| {})
        .unwrap()
        .city
}

/// Points densely over a footprint: its vertices, points along its edges and a lattice inside.
fn dense_points(p: &Polygon<f64>, step: f64) -> Vec<DVec2> {
    use geo::{BoundingRect, Contains};
    let mut out = Vec::new();
    for r in std::iter::once(p.exterior()).chain(p.interiors()) {
        for w in r.0.windows(2) {
            let (a, b) = (DVec2::new(w[0].x, w[0].y), DVec2::new(w[1].x, w[1].y));
            let n = ((b - a).length() / step).ceil().max(1.0) as usize;
            out.extend((0..=n).map(|k| a + (b - a) * (k as f64 / n as f64)));
        }
    }
    let bb = p.bounding_rect().unwrap();
    let mut y = bb.min().y;
    while y <= bb.max().y {
        let mut x = bb.min().x;
        while x <= bb.max().x {
            if p.contains(&Coord { x, y }) {
                out.push(DVec2::new(x, y));
            }
            x += step;
        }
        y += step;
    }
    out
}

/// Every building's base is the lowest point of the terrain under it (of the bilinear surface
/// and the drawn triangles): no dense sample of either is lower,
/// and one comes within the sampling's reach of it; no footprint vertex is buried by more than
/// the relief under the footprint.
fn check_min_bases(city: &City, terrain: &Terrain, step: f64, slack_per_m: f64) -> usize {
    let mut checked = 0;
    for b in &city.buildings {
        let pts = dense_points(&b.footprint, step);
        // Both surfaces: the bilinear one and the drawn triangles (bases take the lower).
        let hs: Vec<f64> = pts
            .iter()
            .filter_map(|&p| {
                let h = terrain.sample(p)?;
                Some(terrain.sample_drawn(p).map_or(h, |d| h.min(d)))
            })
            .collect();
        assert_eq!(
            hs.len(),
            pts.len(),
            "{}: terrain under every point",
            b.source_id
        );
        let lo = hs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = pts
            .iter()
            .filter_map(|&p| terrain.sample(p))
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            lo >= b.base_m - 1e-9,
            "{}: a dense sample at {lo} m is below the base {} m",
            b.source_id,
            b.base_m
        );
        // The base is attained: the dense minimum is within the slope times the step of it.
        assert!(
            lo - b.base_m <= slack_per_m * step + 1e-9,
            "{}: base {} m, dense minimum {lo} m",
            b.source_id,
            b.base_m
        );
        for c in b.footprint.exterior().coords() {
            let h = terrain.sample(DVec2::new(c.x, c.y)).unwrap();
            assert!(h - b.base_m <= hi - b.base_m + 1e-9 && h >= b.base_m - 1e-9);
        }
        checked += 1;
    }
    checked
}

#[test]
fn buildings_on_the_nepal_valley_stand_on_its_lowest_ground() {
    let Some(path) = dem(
        NEPAL,
        "buildings_on_the_nepal_valley_stand_on_its_lowest_ground",
    ) else {
        return;
    };
    let dir = generated(400, 7, 32645, (333_000.0, 3_110_000.0));
    let city = load_on(&dir, GroundOptions::new(&path));
    let terrain = city.terrain.clone().expect("a terrain");
    let r = city.report.ground.as_ref().expect("a ground report");
    assert_eq!(r.placed, city.buildings.len());
    assert_eq!(r.refused_count, 0);
    assert_eq!(r.rule, "min");
    // The steepest slope under a footprint bounds how far the dense minimum can miss.
    let slope = r.slope_deg.max.to_radians().tan();
    let n = check_min_bases(&city, &terrain, 0.5, slope);
    assert_eq!(n, 400);
    // The report's spreads are the buildings' own numbers.
    let bases: Vec<f64> = city.buildings.iter().map(|b| b.base_m).collect();
    let lo = bases.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = bases.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert_eq!((r.base_m.min, r.base_m.max), (lo, hi));
    // Steep footprints are those whose relief passes the threshold, and listed largest first.
    assert!(r.steep.windows(2).all(|w| w[0].relief_m >= w[1].relief_m));
    assert!(r.steep.iter().all(|s| s.relief_m > r.steep_threshold_m));
    // Heights stay heights above the ground; the prisms stand on the base.
    let meshes = blockwalk::city::extrude::extrude_city(&city);
    for (b, m) in city.buildings.iter().zip(&meshes) {
        let zmin = m
            .positions
            .iter()
            .map(|p| p.z)
            .fold(f32::INFINITY, f32::min);
        let zmax = m
            .positions
            .iter()
            .map(|p| p.z)
            .fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(zmin, b.base_m as f32, "{}", b.source_id);
        assert_eq!(zmax, (b.base_m + b.height_m) as f32, "{}", b.source_id);
    }
}

#[test]
fn a_percentile_base_lies_between_the_lowest_and_highest_ground() {
    let Some(path) = dem(
        NEPAL,
        "a_percentile_base_lies_between_the_lowest_and_highest_ground",
    ) else {
        return;
    };
    let dir = generated(150, 3, 32645, (333_000.0, 3_110_000.0));
    let min = load_on(&dir, GroundOptions::new(&path));
    let mut g = GroundOptions::new(&path);
    g.rule = BaseRule::Percentile(50.0);
    let med = load_on(&dir, g.clone());
    g.rule = BaseRule::Percentile(100.0);
    let top = load_on(&dir, g);
    let t = min.terrain.clone().unwrap();
    let mut raised = 0;
    for ((a, b), c) in min.buildings.iter().zip(&med.buildings).zip(&top.buildings) {
        let fg = t.ground_under(&a.footprint, BaseRule::Min).unwrap();
        assert_eq!(a.base_m, fg.min_m);
        assert!(a.base_m <= b.base_m && b.base_m <= c.base_m);
        assert!(
            (c.base_m - fg.max_m).abs() < 1e-9,
            "p100 is the highest ground"
        );
        raised += (b.base_m > a.base_m) as usize;
    }
    assert!(
        raised > 0,
        "on a steep valley the median is above the minimum somewhere"
    );
}

#[test]
fn a_lon_lat_dem_is_reprojected_under_a_utm_city() {
    let Some(path) = dem(GRENOBLE, "a_lon_lat_dem_is_reprojected_under_a_utm_city") else {
        return;
    };
    // Grenoble (5.72° E, 45.19° N) in UTM 31N, from proj4rs (independent of the importers).
    let utm = proj4rs::Proj::from_proj_string("+proj=utm +zone=31 +datum=WGS84 +units=m").unwrap();
    let wgs = proj4rs::Proj::from_proj_string("+proj=longlat +datum=WGS84").unwrap();
    let mut p = (5.72f64.to_radians(), 45.19f64.to_radians(), 0.0);
    proj4rs::transform::transform(&wgs, &utm, &mut p).unwrap();
    let dir = generated(200, 5, 32631, (p.0, p.1));
    let city = load_on(&dir, GroundOptions::new(&path));
    let r = city.report.ground.as_ref().unwrap();
    assert!(r.terrain.resampled, "a lon/lat grid is resampled");
    assert_eq!(r.refused_count, 0);
    // Each base against the source grid read directly: the footprint's first vertex back to
    // lon/lat (proj4rs), bilinear in the DEM's own samples. Resampling twice smooths by at most
    // the local relief of a source cell (a DSM: up to a few tens of metres in town).
    let grid = blockwalk::importers::read_dem(&path).unwrap();
    let mut worst: f64 = 0.0;
    for b in &city.buildings {
        let c = b.footprint.exterior().0[0];
        let mut q = (c.x, c.y, 0.0);
        proj4rs::transform::transform(&utm, &wgs, &mut q).unwrap();
        let [fc, fr] = grid
            .fractional_index(q.0.to_degrees(), q.1.to_degrees())
            .unwrap();
        let (c0, r0) = (fc.floor() as usize, fr.floor() as usize);
        let (u, v) = (fc - c0 as f64, fr - r0 as f64);
        let h = grid.value(c0, r0) * (1.0 - u) * (1.0 - v)
            + grid.value(c0 + 1, r0) * u * (1.0 - v)
            + grid.value(c0, r0 + 1) * (1.0 - u) * v
            + grid.value(c0 + 1, r0 + 1) * u * v;
        let here = city
            .terrain
            .as_ref()
            .unwrap()
            .sample(DVec2::new(c.x, c.y))
            .unwrap();
        worst = worst.max((here - h).abs());
        assert!(b.base_m <= here + 1e-9);
    }
    assert!(worst < 40.0, "terrain vs the source grid: {worst} m");
    eprintln!("Grenoble: resampled terrain within {worst:.2} m of the source grid at 200 vertices");
}

#[test]
fn a_lidar_grid_and_the_same_grid_at_90_m_give_bases_within_its_relief() {
    let Some(path) = dem(
        MINNESOTA,
        "a_lidar_grid_and_the_same_grid_at_90_m_give_bases_within_its_relief",
    ) else {
        return;
    };
    let grid = blockwalk::importers::read_dem(&path).unwrap();
    let [x0, y0, x1, y1] = grid.bounds();
    let dir = generated(12, 2, 26915, ((x0 + x1) / 2.0, (y0 + y1) / 2.0));
    let fine = load_on(&dir, GroundOptions::new(&path));
    let tf = fine.terrain.clone().unwrap();
    assert_eq!(tf.report().spacing_m, [1.0, 1.0]);
    assert!(!tf.report().resampled);
    // The same grid every 90th sample: a 90 m DEM under the same city.
    let mut coarse = grid.clone();
    let (w, h) = (grid.width.div_ceil(90), grid.height.div_ceil(90));
    coarse.values = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .map(|(c, r)| grid.value((c * 90).min(grid.width - 1), (r * 90).min(grid.height - 1)))
        .collect();
    (coarse.width, coarse.height) = (w, h);
    coarse.transform[1] *= 90.0;
    coarse.transform[5] *= 90.0;
    let t90 = Terrain::from_dem(&coarse, &fine.transform, None).unwrap();
    let mut buildings = fine.buildings.clone();
    let mut report = CityReport::default();
    let g = place_buildings(
        &mut buildings,
        &t90,
        &GroundOptions::new(&path),
        &mut report,
    );
    assert_eq!(g.refused_count + g.placed, fine.buildings.len());
    let relief = tf.report().max_m - tf.report().min_m;
    for (a, b) in fine.buildings.iter().zip(&buildings) {
        assert_eq!(a.source_id, b.source_id);
        assert!(
            (a.base_m - b.base_m).abs() <= relief,
            "{} vs {}",
            a.base_m,
            b.base_m
        );
        // On the 90 m grid a footprint lies within one or two cells: the base is still the
        // lowest of the bilinear surface and the drawn triangles there (brute force).
        let lo = dense_points(&b.footprint, 0.5)
            .into_iter()
            .filter_map(|p| {
                let h = t90.sample(p)?;
                Some(t90.sample_drawn(p).map_or(h, |d| h.min(d)))
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            lo >= b.base_m - 1e-9 && lo - b.base_m < 0.05,
            "{lo} vs {}",
            b.base_m
        );
    }
}

fn square(x: f64, y: f64, s: f64) -> Polygon<f64> {
    Polygon::new(
        LineString::from(vec![(x, y), (x + s, y), (x + s, y + s), (x, y + s), (x, y)]),
        vec![],
    )
}

fn building(i: u32, p: Polygon<f64>) -> Building {
    Building {
        id: blockwalk::city::BuildingId(i),
        source_id: format!("t:{i}"),
        footprint: p,
        height_m: 10.0,
        min_height_m: 0.0,
        base_m: 0.0,
        height_source: blockwalk::city::HeightSource::Height,
        attributes: Default::default(),
    }
}

#[test]
fn a_footprint_straddling_a_cliff_stands_on_its_foot_and_is_listed_steep() {
    // 10 m cells, a 100 m step between columns 5 and 6 (x = 50 … 60 m).
    let t = Terrain::synthetic(
        GridSpec::new(20, 20, 10.0, DVec2::ZERO),
        Synthetic::Cliff {
            column: 5,
            low_m: 200.0,
            step_m: 100.0,
        },
    );
    let mut bs = vec![
        building(0, square(45.0, 80.0, 20.0)),  // straddles the cliff
        building(1, square(10.0, 10.0, 15.0)),  // on the low side
        building(2, square(120.0, 10.0, 15.0)), // on the high side
        building(3, square(185.0, 10.0, 15.0)), // off the grid's east edge (190 m)
    ];
    let mut report = CityReport::default();
    let g = place_buildings(&mut bs, &t, &GroundOptions::new("cliff.tif"), &mut report);
    assert_eq!(g.placed, 3);
    assert_eq!(g.refused_count, 1);
    assert_eq!(report.buildings_refused.len(), 1);
    assert_eq!(report.buildings_refused[0].id, "t:3");
    assert!(report.buildings_refused[0].reason.contains("no terrain"));
    // Ids renumbered, source ids kept.
    assert_eq!(
        bs.iter()
            .map(|b| (b.id.0, b.source_id.as_str()))
            .collect::<Vec<_>>(),
        vec![(0, "t:0"), (1, "t:1"), (2, "t:2")]
    );
    assert_eq!(bs[0].base_m, 200.0);
    assert_eq!(bs[1].base_m, 200.0);
    assert_eq!(bs[2].base_m, 300.0);
    assert_eq!(g.steep_count, 1);
    assert_eq!(g.steep[0].id, "t:0");
    assert!((g.steep[0].relief_m - 100.0).abs() < 1e-9);
    assert!((g.slope_deg.max - (10.0f64).atan().to_degrees()).abs() < 1e-6);
}

#[test]
fn a_building_on_a_45_degree_slope_touches_the_ground_at_its_lowest_corner() {
    let t = Terrain::synthetic(
        GridSpec::new(40, 40, 5.0, DVec2::new(1000.0, 2000.0)),
        Synthetic::Plane {
            slope_deg: 45.0,
            azimuth_deg: 0.0,
            base_m: 500.0,
        },
    );
    let mut bs = vec![building(0, square(1050.0, 2050.0, 12.0))];
    let mut report = CityReport::default();
    let g = place_buildings(&mut bs, &t, &GroundOptions::new("slope.tif"), &mut report);
    // The plane rises 1 m per metre east: the west wall's foot is at 550 m, the east one 562 m.
    assert!((bs[0].base_m - 550.0).abs() < 1e-9);
    assert!((g.relief_m.max - 12.0).abs() < 1e-9);
    assert!((g.slope_deg.max - 45.0).abs() < 1e-9);
}

#[test]
fn nodata_under_part_of_a_footprint_is_reported_not_filled() {
    let t = Terrain::synthetic(
        GridSpec::new(30, 30, 10.0, DVec2::ZERO),
        Synthetic::Flat { height_m: 42.0 },
    )
    .with_nodata(|i, j| (10..15).contains(&i) && (10..15).contains(&j));
    let mut bs = vec![
        building(0, square(60.0, 60.0, 45.0)), // partly over the hole (nodes 10…14)
        building(1, square(112.0, 112.0, 5.0)), // inside it
        building(2, square(200.0, 200.0, 20.0)),
    ];
    let mut report = CityReport::default();
    let g = place_buildings(&mut bs, &t, &GroundOptions::new("holes.tif"), &mut report);
    assert_eq!((g.placed, g.refused_count, g.partial_count), (2, 1, 1));
    assert_eq!(g.partial[0].id, "t:0");
    assert!(
        g.partial[0].missing_samples > 0 && g.partial[0].missing_samples < g.partial[0].samples
    );
    assert_eq!(bs[0].base_m, 42.0, "from the samples that exist, never 0");
    assert_eq!(report.buildings_refused[0].id, "t:1");
    assert!(report
        .notes
        .iter()
        .any(|n| n.contains("partly over nodata")));
}

#[test]
fn a_dem_that_misses_the_city_or_has_no_crs_is_refused_naming_it() {
    let Some(path) = dem(
        NEPAL,
        "a_dem_that_misses_the_city_or_has_no_crs_is_refused_naming_it",
    ) else {
        return;
    };
    // The default city is in UTM 33N (central Europe): the Nepal grid is elsewhere.
    let dir = tempfile::tempdir().unwrap();
    let c = generate_city(&GenerateParams {
        buildings: 20,
        ..Default::default()
    })
    .unwrap();
    write_city(&c, &dir.path().join("city")).unwrap();
    let err = CitySource::parse(&dir.path().join("city"), None, None, &[], 0)
        .unwrap()
        .with_ground(Some(GroundOptions::new(&path)))
        .load(&Default::default(), &mut |_| {})
        .unwrap_err();
    let msg = format!(
        "{err}: {}",
        std::error::Error::source(&err)
            .map(|s| s.to_string())
            .unwrap_or_default()
    );
    assert!(msg.contains("nepal_30m_32645.tif"), "{msg}");
    assert!(msg.contains("overlap"), "{msg}");
}

#[test]
fn street_walks_keep_their_eye_height_above_the_ground_and_others_clear_it() {
    let Some(path) = dem(
        NEPAL,
        "street_walks_keep_their_eye_height_above_the_ground_and_others_clear_it",
    ) else {
        return;
    };
    let dir = generated(300, 11, 32645, (333_000.0, 3_110_000.0));
    let source = CitySource::parse(&dir.path().join("city"), None, None, &[], 0)
        .unwrap()
        .with_ground(Some(GroundOptions::new(&path)));
    let scene = Scene::load(&source, &SceneOptions::default(), &mut |_| {}).unwrap();
    let t = scene.city.terrain.clone().unwrap();
    let frame = scene.city.frame;
    let ground = |p: glam::DVec3| {
        let w = frame.to_world(p);
        t.sample_drawn(DVec2::new(w.x, w.y))
            .map(|g| g - frame.origin.z)
    };
    for (choice, frames) in [
        (RouteChoice::Street, 200usize),
        (RouteChoice::Orbit, 60),
        (RouteChoice::Flyover, 60),
    ] {
        let (route, _) = blockwalk::walk::job::resolve_route(&choice, &scene, 16.0 / 9.0).unwrap();
        let mut over = 0;
        for cam in route.sample(frames) {
            let Some(g) = ground(cam.position) else {
                continue;
            };
            let above = cam.position.z - g;
            match choice {
                RouteChoice::Street => assert!(
                    (above - 1.7).abs() < 1e-6,
                    "street eye {above} m above the ground"
                ),
                _ => assert!(
                    above >= 1.7 - 1e-9,
                    "{choice}: eye {above} m above the ground"
                ),
            }
            over += 1;
        }
        assert!(
            over > frames / 2,
            "{choice}: most frames over the terrain ({over})"
        );
    }
}

#[test]
fn the_steepest_slope_under_a_footprint_is_the_largest_gradient_found_by_brute_force() {
    let Some(path) = dem(
        NEPAL,
        "the_steepest_slope_under_a_footprint_is_the_largest_gradient_found_by_brute_force",
    ) else {
        return;
    };
    let dir = generated(120, 9, 32645, (333_000.0, 3_110_000.0));
    let city = load_on(&dir, GroundOptions::new(&path));
    let t = city.terrain.clone().unwrap();
    let s = t.spacing();
    let mut closest: f64 = f64::INFINITY;
    for b in &city.buildings {
        let g = t.ground_under(&b.footprint, BaseRule::Min).unwrap();
        // The bilinear gradient at dense points under the footprint, in the cell holding each.
        let mut brute: f64 = 0.0;
        for p in dense_points(&b.footprint, 0.1) {
            let Some((i, j, fu, fv)) = t.cell_of(t.grid_uv(p)) else {
                continue;
            };
            let h = [
                t.raw(i, j),
                t.raw(i + 1, j),
                t.raw(i, j + 1),
                t.raw(i + 1, j + 1),
            ];
            let gx = ((h[1] - h[0]) * (1.0 - fv) + (h[3] - h[2]) * fv) / s.x;
            let gy = ((h[2] - h[0]) * (1.0 - fu) + (h[3] - h[1]) * fu) / s.y;
            brute = brute.max((gx * gx + gy * gy).sqrt().atan().to_degrees());
        }
        assert!(
            g.slope_deg >= brute - 1e-9,
            "{}: slope {}° below a sampled {brute}°",
            b.source_id,
            g.slope_deg
        );
        // The maximum is at a vertex of a cell's part under the footprint, which the dense
        // points approach to within 0.1 m.
        assert!(
            g.slope_deg - brute < 0.5,
            "{}: slope {}° far above the sampled {brute}°",
            b.source_id,
            g.slope_deg
        );
        closest = closest.min(g.slope_deg - brute);
    }
    assert!(closest < 1e-6, "some footprint's maximum is hit exactly");
}

#[test]
fn a_city_without_crs_is_not_put_on_a_georeferenced_dem_by_guess() {
    let Some(path) = dem(
        NEPAL,
        "a_city_without_crs_is_not_put_on_a_georeferenced_dem_by_guess",
    ) else {
        return;
    };
    // The city lies right on the grid, but without its .prj nothing says so.
    let dir = generated(30, 1, 32645, (333_000.0, 3_110_000.0));
    for f in ["buildings.prj", "streets.prj", "parcels.prj"] {
        let _ = std::fs::remove_file(dir.path().join("city").join(f));
    }
    let load = |g: GroundOptions| {
        CitySource::parse(&dir.path().join("city"), None, None, &[], 0)
            .unwrap()
            .with_ground(Some(g))
            .load(&Default::default(), &mut |_| {})
    };
    let err = load(GroundOptions::new(&path)).unwrap_err();
    let msg = format!(
        "{err}: {}",
        std::error::Error::source(&err)
            .map(|s| s.to_string())
            .unwrap_or_default()
    );
    assert!(
        msg.contains("has no CRS") && msg.contains("nepal_30m_32645.tif"),
        "{msg}"
    );
    // Asked for, the DEM's coordinates are taken as the city's: here they are the same.
    let mut g = GroundOptions::new(&path);
    g.assume_city_frame = true;
    let city = load(g).unwrap().city;
    assert_eq!(city.report.ground.as_ref().unwrap().placed, 30);
}
