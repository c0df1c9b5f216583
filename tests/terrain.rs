//! The terrain against independent truths: base heights against dense brute force, node errors
//! against a separate L∞ computation, the per-frame cut against all nodes, skirts against exact
//! rays through the drawn triangles, occluder cells against the surface, resampling against
//! the source sampled directly, and the Nepal DEM once the GeoTIFF reader reads it.

mod support;

use blockwalk::geom::predicates::{point_in_polygon, Location};
use blockwalk::geom::{Camera, LocalFrame};
use blockwalk::importers::dem::{read_dem, DemGrid, PixelIs};
use blockwalk::importers::Crs;
use blockwalk::terrain::{
    BaseRule, GridSpec, GroundError, NodeId, Synthetic, Terrain, TerrainTree, TreeOptions,
};
use geo_types::{polygon, Coord, LineString, Polygon};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use support::skip::{or_skip, Need};

// ---------------------------------------------------------------------------------------------
// Helpers

fn smooth(nx: usize, ny: usize, spacing: f64, origin: DVec2, seed: u64) -> Terrain {
    Terrain::synthetic(
        GridSpec::new(nx, ny, spacing, origin),
        Synthetic::Smooth {
            seed,
            relief_m: 300.0,
        },
    )
}

/// A random star-shaped polygon around `c` (radius up to `r`), counter-clockwise, closed,
/// sometimes with a square hole.
fn random_polygon(rng: &mut ChaCha8Rng, c: DVec2, r: f64) -> Polygon<f64> {
    let n = rng.random_range(5..12);
    let mut ring: Vec<Coord<f64>> = (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * (k as f64 + rng.random_range(0.0..0.8)) / n as f64;
            let rr = r * rng.random_range(0.4..1.0);
            Coord {
                x: c.x + rr * a.cos(),
                y: c.y + rr * a.sin(),
            }
        })
        .collect();
    ring.push(ring[0]);
    let holes = if rng.random_bool(0.3) {
        let h = 0.08 * r;
        vec![LineString::from(vec![
            (c.x - h, c.y - h),
            (c.x - h, c.y + h),
            (c.x + h, c.y + h),
            (c.x + h, c.y - h),
            (c.x - h, c.y - h),
        ])]
    } else {
        vec![]
    };
    Polygon::new(LineString::from(ring), holes)
}

/// Dense points of the polygon: a lattice inside it and points along every edge.
fn dense_points(p: &Polygon<f64>, n: usize) -> Vec<DVec2> {
    let cs: Vec<Coord<f64>> = p
        .exterior()
        .0
        .iter()
        .chain(p.interiors().iter().flat_map(|r| r.0.iter()))
        .copied()
        .collect();
    let (x0, x1) = cs
        .iter()
        .fold((f64::MAX, f64::MIN), |a, c| (a.0.min(c.x), a.1.max(c.x)));
    let (y0, y1) = cs
        .iter()
        .fold((f64::MAX, f64::MIN), |a, c| (a.0.min(c.y), a.1.max(c.y)));
    let mut out = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let q = Coord {
                x: x0 + (x1 - x0) * i as f64 / n as f64,
                y: y0 + (y1 - y0) * j as f64 / n as f64,
            };
            if point_in_polygon(q, p) != Location::Outside {
                out.push(DVec2::new(q.x, q.y));
            }
        }
    }
    for ring in std::iter::once(p.exterior()).chain(p.interiors()) {
        for w in ring.0.windows(2) {
            for k in 0..=4 * n {
                let t = k as f64 / (4 * n) as f64;
                out.push(DVec2::new(
                    w[0].x + t * (w[1].x - w[0].x),
                    w[0].y + t * (w[1].y - w[0].y),
                ));
            }
        }
    }
    out
}

fn distance_to_polygon(p: &Polygon<f64>, q: DVec2) -> f64 {
    if point_in_polygon(Coord { x: q.x, y: q.y }, p) != Location::Outside {
        return 0.0;
    }
    let mut best = f64::MAX;
    for ring in std::iter::once(p.exterior()).chain(p.interiors()) {
        for w in ring.0.windows(2) {
            let (a, b) = (DVec2::new(w[0].x, w[0].y), DVec2::new(w[1].x, w[1].y));
            let t = ((q - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            best = best.min((a + (b - a) * t - q).length());
        }
    }
    best
}

/// The full-resolution mesh height (two triangles per cell, south-west to north-east diagonal)
/// at grid coordinates `uv`, by barycentric coordinates (this test's own evaluation), in the
/// cell of `[lo, hi]` (grid nodes) that holds it, so that a point on the range's border is
/// evaluated in a cell of the range.
fn full_res_uv(t: &Terrain, uv: DVec2, lo: [usize; 2], hi: [usize; 2]) -> Option<f64> {
    let i = (uv.x.floor().max(0.0) as usize).clamp(lo[0], hi[0] - 1);
    let j = (uv.y.floor().max(0.0) as usize).clamp(lo[1], hi[1] - 1);
    let (fu, fv) = (uv.x - i as f64, uv.y - j as f64);
    let tri = if fu >= fv {
        [
            (0.0, 0.0, t.height(i, j)?),
            (1.0, 0.0, t.height(i + 1, j)?),
            (1.0, 1.0, t.height(i + 1, j + 1)?),
        ]
    } else {
        [
            (0.0, 0.0, t.height(i, j)?),
            (1.0, 1.0, t.height(i + 1, j + 1)?),
            (0.0, 1.0, t.height(i, j + 1)?),
        ]
    };
    Some(barycentric(tri, fu, fv))
}

/// The bilinear surface at grid coordinates `uv`, in the cell of `[lo, hi]` that holds it.
fn bilinear_uv(t: &Terrain, uv: DVec2, lo: [usize; 2], hi: [usize; 2]) -> Option<f64> {
    let i = (uv.x.floor().max(0.0) as usize).clamp(lo[0], hi[0] - 1);
    let j = (uv.y.floor().max(0.0) as usize).clamp(lo[1], hi[1] - 1);
    let (fu, fv) = (uv.x - i as f64, uv.y - j as f64);
    let h = [
        t.height(i, j)?,
        t.height(i + 1, j)?,
        t.height(i, j + 1)?,
        t.height(i + 1, j + 1)?,
    ];
    Some(
        h[0] * (1.0 - fu) * (1.0 - fv)
            + h[1] * fu * (1.0 - fv)
            + h[2] * (1.0 - fu) * fv
            + h[3] * fu * fv,
    )
}

fn barycentric(tri: [(f64, f64, f64); 3], x: f64, y: f64) -> f64 {
    let [(x1, y1, z1), (x2, y2, z2), (x3, y3, z3)] = tri;
    let det = (y2 - y3) * (x1 - x3) + (x3 - x2) * (y1 - y3);
    let l1 = ((y2 - y3) * (x - x3) + (x3 - x2) * (y - y3)) / det;
    let l2 = ((y3 - y1) * (x - x3) + (x1 - x3) * (y - y3)) / det;
    l1 * z1 + l2 * z2 + (1.0 - l1 - l2) * z3
}

// ---------------------------------------------------------------------------------------------
// Base heights

/// Checks one footprint's ground against dense brute force: nothing under it lower than the
/// base (Min) or higher than the max, both attained at a point of the footprint.
fn check_ground(t: &Terrain, fp: &Polygon<f64>) {
    let g = t.ground_under(fp, BaseRule::Min).unwrap();
    assert_eq!(g.base_m, g.min_m);
    let pts = dense_points(fp, 60);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for p in &pts {
        let h = t.sample(*p).expect("on the grid, with data");
        assert!(
            h >= g.base_m - 1e-9,
            "{h} under the base {} at {p}",
            g.base_m
        );
        assert!(h <= g.max_m + 1e-9, "{h} over the max {} at {p}", g.max_m);
        lo = lo.min(h);
        hi = hi.max(h);
    }
    // Attained: at a point of the footprint, and the brute force comes close from above.
    let at = DVec2::from(g.min_at);
    assert!(
        distance_to_polygon(fp, at) < 1e-6,
        "min_at {at} is not on the footprint"
    );
    // (within the rounding of the point's world coordinates, 1e-9 m at 5.5e6 m, times the slope)
    // (the lower of the two surfaces there: the base counts the drawn triangles too)
    let at_h = t
        .sample(at)
        .unwrap()
        .min(t.sample_drawn(at).unwrap_or(f64::INFINITY));
    assert!((at_h - g.base_m).abs() < 1e-6);
    assert!(lo >= g.base_m - 1e-9 && hi <= g.max_m + 1e-9);
    assert!((g.relief_m - (g.max_m - g.min_m)).abs() < 1e-12);
    // Percentiles lie between min and max, and 0 is the min.
    let p0 = t.ground_under(fp, BaseRule::Percentile(0.0)).unwrap();
    assert_eq!(p0.base_m, g.min_m);
    let p100 = t.ground_under(fp, BaseRule::Percentile(100.0)).unwrap();
    assert!(p100.base_m <= g.max_m + 1e-9);
}

#[test]
fn base_is_the_lowest_point_of_the_bilinear_surface() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let origin = DVec2::new(463_000.0, 5_546_000.0);
    let terrains = [
        smooth(60, 50, 3.0, origin, 1),
        smooth(60, 50, 1.0, origin, 2),
        Terrain::synthetic(
            GridSpec::new(60, 50, 2.0, origin),
            Synthetic::Cone {
                height_m: 80.0,
                slope_deg: 40.0,
            },
        ),
        Terrain::synthetic(
            GridSpec::new(60, 50, 2.0, origin),
            Synthetic::Cliff {
                column: 30,
                low_m: 400.0,
                step_m: 100.0,
            },
        ),
    ];
    for t in &terrains {
        let e = t.extent();
        for _ in 0..40 {
            let r = rng.random_range(1.0..25.0);
            let c = DVec2::new(
                rng.random_range(e[0] + r..e[2] - r),
                rng.random_range(e[1] + r..e[3] - r),
            );
            check_ground(t, &random_polygon(&mut rng, c, r));
        }
        // Footprints smaller than a cell, and edges along grid lines.
        let s = t.spacing().x;
        let o = t.node_xy(10, 10);
        check_ground(
            t,
            &random_polygon(&mut rng, o + DVec2::splat(0.5 * s), 0.3 * s),
        );
        let sq = polygon![(x: o.x, y: o.y), (x: o.x + 3.0 * s, y: o.y), (x: o.x + 3.0 * s, y: o.y + 2.0 * s), (x: o.x, y: o.y + 2.0 * s)];
        check_ground(t, &sq);
    }
}

#[test]
fn cliff_straddled_takes_the_low_side() {
    // 100 m between columns 20 and 21 (a 1 m cell): the footprint spans both sides.
    let t = Terrain::synthetic(
        GridSpec::new(40, 30, 1.0, DVec2::new(7_000.0, 3_000.0)),
        Synthetic::Cliff {
            column: 20,
            low_m: 500.0,
            step_m: 100.0,
        },
    );
    let fp = polygon![(x: 7_015.5, y: 3_010.0), (x: 7_026.0, y: 3_010.0), (x: 7_026.0, y: 3_020.0), (x: 7_015.5, y: 3_020.0)];
    let g = t.ground_under(&fp, BaseRule::Min).unwrap();
    assert_eq!(g.base_m, 500.0);
    assert_eq!(g.max_m, 600.0);
    assert_eq!(g.relief_m, 100.0);
    assert!(
        (g.slope_deg - 100f64.atan().to_degrees()).abs() < 1e-9,
        "{}",
        g.slope_deg
    );
    let median = t.ground_under(&fp, BaseRule::Percentile(50.0)).unwrap();
    assert!(median.base_m > 500.0, "{median:?}");
    check_ground(&t, &fp);
    // Wholly on the low side: flat.
    let low =
        polygon![(x: 7_005.0, y: 3_005.0), (x: 7_010.0, y: 3_005.0), (x: 7_010.0, y: 3_010.0)];
    let g = t.ground_under(&low, BaseRule::Min).unwrap();
    assert_eq!((g.base_m, g.relief_m, g.slope_deg), (500.0, 0.0, 0.0));
}

#[test]
fn slope_of_45_degrees_on_1_m_and_90_m_grids() {
    for spacing in [1.0, 90.0] {
        let t = Terrain::synthetic(
            GridSpec::new(30, 30, spacing, DVec2::new(500_000.0, 4_000_000.0)),
            Synthetic::Plane {
                slope_deg: 45.0,
                azimuth_deg: 90.0,
                base_m: 1000.0,
            },
        );
        let s = spacing;
        let o = t.origin();
        let fp = polygon![(x: o.x + 3.3 * s, y: o.y + 4.7 * s), (x: o.x + 9.1 * s, y: o.y + 4.7 * s), (x: o.x + 9.1 * s, y: o.y + 8.2 * s), (x: o.x + 3.3 * s, y: o.y + 8.2 * s)];
        let g = t.ground_under(&fp, BaseRule::Min).unwrap();
        assert!(
            (g.base_m - (1000.0 + 4.7 * s)).abs() < 1e-9 * s.max(1.0),
            "{g:?}"
        );
        assert!((g.relief_m - 3.5 * s).abs() < 1e-9 * s.max(1.0));
        assert!((g.slope_deg - 45.0).abs() < 1e-9, "{}", g.slope_deg);
        check_ground(&t, &fp);
    }
}

#[test]
fn nodata_under_a_footprint_is_reported_with_counts() {
    let t = smooth(30, 30, 2.0, DVec2::ZERO, 3)
        .with_nodata(|i, j| (10..=12).contains(&i) && (10..=12).contains(&j));
    // Partly on the hole: an error with the counts and the ground over the rest.
    let fp =
        polygon![(x: 14.0, y: 14.0), (x: 30.0, y: 14.0), (x: 30.0, y: 30.0), (x: 14.0, y: 30.0)];
    match t.ground_under(&fp, BaseRule::Min) {
        Err(GroundError::Nodata {
            samples,
            nodata_samples,
            partial: Some(p),
        }) => {
            assert!(nodata_samples > 0 && nodata_samples < samples);
            assert_eq!(p.nodata_samples, nodata_samples);
            assert!(p.base_m.is_finite());
        }
        other => panic!("{other:?}"),
    }
    // Wholly inside the hole.
    let fp = polygon![(x: 20.5, y: 20.5), (x: 23.5, y: 20.5), (x: 23.5, y: 23.5)];
    let e = t.ground_under(&fp, BaseRule::Min).unwrap_err();
    assert!(
        matches!(e, GroundError::Nodata { partial: None, .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("nodata"));
    // Off the grid.
    let fp = polygon![(x: 50.0, y: 20.5), (x: 70.0, y: 20.5), (x: 60.0, y: 30.0)];
    let e = t.ground_under(&fp, BaseRule::Min).unwrap_err();
    assert!(matches!(e, GroundError::OutsideGrid { .. }), "{e:?}");
    // Sampling never invents 0.
    assert_eq!(t.sample(DVec2::new(22.0, 22.0)), None);
}

// ---------------------------------------------------------------------------------------------
// Node errors

/// This test's own L∞ of a node: the coarse lattice rebuilt from the stride, each coarse cell
/// drawn only when all its samples have data, the coarse triangles evaluated by barycentric
/// coordinates against the full-resolution mesh on a dense set of points (every sample, and
/// 4 × 4 more per fine cell).
fn brute_node_error(tree: &TerrainTree, id: NodeId) -> (f64, bool) {
    let t = tree.terrain();
    let s = tree.stride(id);
    let [i0, j0, i1, j1] = tree.node_range(id);
    let lat = |a: usize, b: usize| {
        let mut v: Vec<usize> = (a..b).step_by(s).collect();
        v.push(b);
        v
    };
    let (xs, ys) = (lat(i0, i1), lat(j0, j1));
    let mut worst = 0.0f64;
    let mut square = true;
    for m in 0..ys.len() - 1 {
        for k in 0..xs.len() - 1 {
            let (xa, xb, ya, yb) = (xs[k], xs[k + 1], ys[m], ys[m + 1]);
            square &= xb - xa == yb - ya;
            let all = (ya..=yb).all(|j| (xa..=xb).all(|i| t.height(i, j).is_some()));
            if !all {
                continue;
            }
            let (wx, wy) = ((xb - xa) as f64, (yb - ya) as f64);
            let h = |i, j| t.height(i, j).unwrap();
            let lower = [
                (0.0, 0.0, h(xa, ya)),
                (wx, 0.0, h(xb, ya)),
                (wx, wy, h(xb, yb)),
            ];
            let upper = [
                (0.0, 0.0, h(xa, ya)),
                (wx, wy, h(xb, yb)),
                (0.0, wy, h(xa, yb)),
            ];
            let sub = 4;
            for jj in 0..=(yb - ya) * sub {
                for ii in 0..=(xb - xa) * sub {
                    let (u, v) = (ii as f64 / sub as f64, jj as f64 / sub as f64);
                    // Which triangle: the side of the diagonal (0,0)–(wx,wy).
                    let coarse = if u * wy >= v * wx {
                        barycentric(lower, u, v)
                    } else {
                        barycentric(upper, u, v)
                    };
                    let uv = DVec2::new(xa as f64 + u, ya as f64 + v);
                    let fine = full_res_uv(t, uv, [xa, ya], [xb, yb]).unwrap();
                    worst = worst.max((fine - coarse).abs());
                }
            }
        }
    }
    (worst, square)
}

#[test]
fn node_errors_are_the_l_infinity_distance_and_saturated() {
    for (k, t) in [
        smooth(70, 45, 10.0, DVec2::new(300_000.0, 3_000_000.0), 4),
        Terrain::synthetic(
            GridSpec::new(65, 65, 5.0, DVec2::ZERO),
            Synthetic::Cliff {
                column: 30,
                low_m: 0.0,
                step_m: 100.0,
            },
        ),
        smooth(50, 50, 30.0, DVec2::ZERO, 5).with_nodata(|i, j| i + j == 40 || (i > 44 && j < 3)),
    ]
    .into_iter()
    .enumerate()
    {
        let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
        tree.check_invariants();
        for id in tree.node_ids() {
            let (brute, square) = brute_node_error(&tree, id);
            let e = tree.measured_error_m(id);
            assert!(
                brute <= e + 1e-9,
                "terrain {k} {id:?}: brute {brute} > measured {e}"
            );
            if square {
                // All extremes are at samples, which the brute force visits.
                assert!(
                    (brute - e).abs() < 1e-9,
                    "terrain {k} {id:?}: {brute} vs {e}"
                );
            }
            // Saturated: the largest of its own and its children's.
            let want = tree.children(id).map(|c| tree.error_m(c)).fold(e, f64::max);
            assert_eq!(tree.error_m(id), want);
        }
        let levels = tree.levels();
        for l in &levels {
            let max_sat = tree
                .node_ids()
                .filter(|&n| tree.level(n) == l.level)
                .map(|n| tree.error_m(n))
                .fold(0.0, f64::max);
            assert_eq!(l.declared_error_m, max_sat);
            assert!(l.max_measured_error_m <= l.declared_error_m);
        }
        if k == 1 {
            // The cliff: every level but the finest straddles a 100 m step somewhere.
            assert!(levels[0].declared_error_m > 40.0, "{levels:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Selection

fn random_camera(rng: &mut ChaCha8Rng, t: &Terrain, frame: &LocalFrame, street: bool) -> Camera {
    let e = t.extent();
    let x = rng.random_range(e[0]..e[2]);
    let y = rng.random_range(e[1]..e[3]);
    let ground = t.sample(DVec2::new(x, y)).unwrap_or(0.0);
    let z = if street {
        ground + rng.random_range(1.5..3.0)
    } else {
        ground + rng.random_range(200.0..3000.0)
    };
    let pitch = if street {
        rng.random_range(-0.3..0.2)
    } else {
        rng.random_range(-1.5..-0.2)
    };
    let mut c = Camera::new(
        frame.to_local_f64(DVec3::new(x, y, z)),
        rng.random_range(0.0..std::f64::consts::TAU),
        pitch,
    );
    c.far = 60_000.0;
    c
}

/// The node ancestors of `id`, itself included.
fn ancestors(tree: &TerrainTree, id: NodeId) -> Vec<NodeId> {
    let mut v = vec![id];
    while let Some(p) = tree.parent(*v.last().unwrap()) {
        v.push(p);
    }
    v
}

#[test]
fn the_cut_meets_the_bound_and_covers_the_visible_grid_once() {
    let t = smooth(301, 201, 30.0, DVec2::new(330_000.0, 3_100_000.0), 9)
        .with_nodata(|i, j| i < 5 && j > 190);
    let frame = LocalFrame {
        origin: DVec3::new(334_000.0, 3_103_000.0, 0.0),
    };
    let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 8 }).unwrap();
    let t = tree.terrain();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let finest: Vec<NodeId> = tree
        .node_ids()
        .filter(|&n| tree.level(n) == tree.depth())
        .collect();
    let mut out = Vec::new();
    let mut drawn_total = 0;
    for k in 0..120 {
        let cam = random_camera(&mut rng, t, &frame, k % 2 == 0);
        let (h_px, tau) = (720u32, [0.5, 1.0, 4.0][k % 3]);
        tree.select(&cam, &frame, h_px, tau, &mut out);
        drawn_total += out.len();
        let focal = h_px as f64 / (2.0 * (cam.fov_y / 2.0).tan());
        let eye = frame.to_world(cam.position);
        let mut chosen = std::collections::HashSet::new();
        for &n in &out {
            assert!(chosen.insert(n), "{n:?} twice");
            let b = tree.extent(n);
            assert!(!b.is_empty());
            let d = (eye - eye.clamp(b.min, b.max)).length().max(cam.near);
            assert!(
                tree.level(n) == tree.depth() || tree.error_m(n) * focal / d <= tau * (1.0 + 1e-12),
                "{n:?}: {} px > τ = {tau}",
                tree.error_m(n) * focal / d
            );
        }
        // No overlap: no chosen node is an ancestor of another.
        for &n in &out {
            for a in ancestors(&tree, n).into_iter().skip(1) {
                assert!(
                    !chosen.contains(&a),
                    "{n:?} and its ancestor {a:?} both drawn"
                );
            }
        }
        // No gap: every finest tile with data whose box (with skirts) meets the frustum is
        // covered by a chosen node; the frustum in world coordinates, exact test.
        let world_frustum = cam.frustum().translated(-frame.origin);
        for &f in &finest {
            if tree.extent(f).is_empty() {
                continue;
            }
            let b = tree.draw_box(f);
            if world_frustum.intersects_aabb_exact(&b) {
                assert!(
                    ancestors(&tree, f).iter().any(|a| chosen.contains(a)),
                    "camera {k}: visible tile {f:?} not covered"
                );
            }
        }
    }
    assert!(drawn_total > 120, "the cameras see something");
}

// ---------------------------------------------------------------------------------------------
// Skirts: no ray sees through

/// Exact test: does the closed segment `p–q` meet the closed triangle `a b c`?
fn segment_hits_triangle(p: DVec3, q: DVec3, a: DVec3, b: DVec3, c: DVec3) -> bool {
    let o = |a: DVec3, b: DVec3, c: DVec3, d: DVec3| {
        let k = |v: DVec3| robust::Coord3D {
            x: v.x,
            y: v.y,
            z: v.z,
        };
        robust::orient3d(k(a), k(b), k(c), k(d))
    };
    let (sp, sq) = (o(a, b, c, p), o(a, b, c, q));
    if (sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || (sp == 0.0 && sq == 0.0) {
        return false;
    }
    let (e1, e2, e3) = (o(p, q, a, b), o(p, q, b, c), o(p, q, c, a));
    (e1 >= 0.0 && e2 >= 0.0 && e3 >= 0.0) || (e1 <= 0.0 && e2 <= 0.0 && e3 <= 0.0)
}

struct Soup {
    tris: Vec<[DVec3; 3]>,
    surface: Vec<bool>,
}

impl Soup {
    fn of(tree: &TerrainTree, cut: &[NodeId], frame: &LocalFrame) -> Soup {
        let mut s = Soup {
            tris: Vec::new(),
            surface: Vec::new(),
        };
        for &n in cut {
            let m = tree.node_mesh(n, frame);
            for (k, tri) in m.indices.chunks(3).enumerate() {
                s.tris
                    .push([0, 1, 2].map(|v| m.positions[tri[v] as usize].as_dvec3()));
                s.surface.push(3 * k < m.surface_indices);
            }
        }
        s
    }
    /// Heights of the drawn surface (skirts aside) on the vertical line through `xy` (local).
    fn surface_z(&self, xy: DVec2) -> Vec<f64> {
        let mut v = Vec::new();
        for (t, &surf) in self.tris.iter().zip(&self.surface) {
            if !surf {
                continue;
            }
            let p = DVec3::new(xy.x, xy.y, 1e6);
            let q = DVec3::new(xy.x, xy.y, -1e6);
            if segment_hits_triangle(p, q, t[0], t[1], t[2]) {
                let tri = t.map(|c| (c.x, c.y, c.z));
                v.push(barycentric(tri, xy.x, xy.y));
            }
        }
        v
    }
    fn hit(&self, p: DVec3, q: DVec3) -> bool {
        let (lo, hi) = (p.min(q), p.max(q));
        self.tris.iter().any(|t| {
            let (tl, th) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            tl.cmple(hi).all()
                && lo.cmple(th).all()
                && segment_hits_triangle(p, q, t[0], t[1], t[2])
        })
    }
}

/// A random complete cut: each node drawn with probability `stop`, else refined.
fn random_cut(
    tree: &TerrainTree,
    rng: &mut ChaCha8Rng,
    stop: f64,
    out: &mut Vec<NodeId>,
    n: NodeId,
) {
    if tree.level(n) == tree.depth() || (tree.level(n) > 0 && rng.random_bool(stop)) {
        out.push(n);
    } else {
        for c in tree.children(n).collect::<Vec<_>>() {
            random_cut(tree, rng, stop, out, c);
        }
    }
}

/// An adversarial cut: one finest tile refined all the way, everything else as coarse as can be
/// (neighbours several levels apart).
fn adversarial_cut(tree: &TerrainTree, deep: NodeId) -> Vec<NodeId> {
    let path = ancestors(tree, deep);
    let mut out = Vec::new();
    let mut stack = vec![tree.root()];
    while let Some(n) = stack.pop() {
        if path.contains(&n) && n != deep {
            stack.extend(tree.children(n));
        } else {
            out.push(n);
        }
    }
    out
}

#[test]
fn skirts_leave_no_ray_through_any_cut() {
    let frame = LocalFrame {
        origin: DVec3::new(500_100.0, 4_200_050.0, 0.0),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for (k, t) in [
        smooth(65, 49, 10.0, DVec2::new(500_000.0, 4_200_000.0), 21),
        Terrain::synthetic(
            GridSpec::new(65, 49, 10.0, DVec2::new(500_000.0, 4_200_000.0)),
            Synthetic::Cliff {
                column: 27,
                low_m: 100.0,
                step_m: 100.0,
            },
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
        let finest: Vec<NodeId> = tree
            .node_ids()
            .filter(|&n| tree.level(n) == tree.depth())
            .collect();
        let mut cuts: Vec<Vec<NodeId>> = Vec::new();
        for stop in [0.2, 0.5, 0.8] {
            for _ in 0..3 {
                let mut c = Vec::new();
                random_cut(&tree, &mut rng, stop, &mut c, tree.root());
                cuts.push(c);
            }
        }
        for _ in 0..4 {
            cuts.push(adversarial_cut(
                &tree,
                finest[rng.random_range(0..finest.len())],
            ));
        }
        let ext = tree.terrain().extent();
        let lo = frame.to_local_xy(DVec2::new(ext[0], ext[1]));
        let hi = frame.to_local_xy(DVec2::new(ext[2], ext[3]));
        // Tile borders of the finest level, in local x and y.
        let span = 4.0 * tree.terrain().spacing().x;
        let borders_x: Vec<f64> = (1..16)
            .map(|b| lo.x + b as f64 * span)
            .filter(|&x| x < hi.x)
            .collect();
        let borders_y: Vec<f64> = (1..12)
            .map(|b| lo.y + b as f64 * span)
            .filter(|&y| y < hi.y)
            .collect();
        for (ci, cut) in cuts.iter().enumerate() {
            let soup = Soup::of(&tree, cut, &frame);
            let mut rays = 0;
            let mut attempt = 0;
            while rays < 150 && attempt < 1000 {
                attempt += 1;
                let inside = |rng: &mut ChaCha8Rng| {
                    DVec2::new(
                        rng.random_range(lo.x + 0.1..hi.x - 0.1),
                        rng.random_range(lo.y + 0.1..hi.y - 0.1),
                    )
                };
                // Kinds: random; along a border (grazing); across a border at a shallow angle.
                let (a, b) = match attempt % 3 {
                    0 => (inside(&mut rng), inside(&mut rng)),
                    1 => {
                        if rng.random_bool(0.5) {
                            let x = borders_x[rng.random_range(0..borders_x.len())];
                            let (y0, y1) =
                                (rng.random_range(lo.y..hi.y), rng.random_range(lo.y..hi.y));
                            (DVec2::new(x, y0), DVec2::new(x, y1))
                        } else {
                            let y = borders_y[rng.random_range(0..borders_y.len())];
                            let (x0, x1) =
                                (rng.random_range(lo.x..hi.x), rng.random_range(lo.x..hi.x));
                            (DVec2::new(x0, y), DVec2::new(x1, y))
                        }
                    }
                    _ => {
                        let x = borders_x[rng.random_range(0..borders_x.len())];
                        let y = rng.random_range(lo.y + 1.0..hi.y - 1.0);
                        let d = rng.random_range(0.5..3.0);
                        (
                            DVec2::new(x - d, y),
                            DVec2::new(x + d, y + rng.random_range(-0.5..0.5)),
                        )
                    }
                };
                let (za, zb) = (soup.surface_z(a), soup.surface_z(b));
                if za.is_empty() || zb.is_empty() {
                    continue;
                }
                // From just above the drawn surface at a to just under it at b (and the other
                // way): grazing when a and b are far apart.
                let above = za.iter().cloned().fold(f64::MIN, f64::max) + 0.05;
                let below = zb.iter().cloned().fold(f64::MAX, f64::min) - 0.05;
                let (p, q) = (DVec3::new(a.x, a.y, above), DVec3::new(b.x, b.y, below));
                assert!(
                    soup.hit(p, q),
                    "terrain {k}, cut {ci} ({} nodes): the ray {p} → {q} sees through",
                    cut.len()
                );
                // And steeply from high above to far below.
                let (p2, q2) = (DVec3::new(a.x, a.y, 1e4), DVec3::new(b.x, b.y, -1e4));
                assert!(
                    soup.hit(p2, q2),
                    "terrain {k}, cut {ci}: {p2} → {q2} sees through"
                );
                rays += 1;
            }
            assert!(rays >= 100, "only {rays} rays placed");
        }
    }
}

#[test]
fn without_skirts_a_ray_would_see_through() {
    // The control: the adversarial cut of the cliff drawn without skirts has a crack.
    let t = Terrain::synthetic(
        GridSpec::new(33, 33, 10.0, DVec2::ZERO),
        Synthetic::Smooth {
            seed: 2,
            relief_m: 300.0,
        },
    );
    let frame = LocalFrame {
        origin: DVec3::ZERO,
    };
    let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
    let finest: Vec<NodeId> = tree
        .node_ids()
        .filter(|&n| tree.level(n) == tree.depth())
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut seen_through = 0;
    for &deep in finest.iter().step_by(7) {
        let cut = adversarial_cut(&tree, deep);
        let mut soup = Soup::of(&tree, &cut, &frame);
        let keep: Vec<bool> = soup.surface.clone();
        let mut k = 0;
        soup.tris.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        soup.surface.retain(|&s| s);
        for _ in 0..200 {
            let x = 40.0 * rng.random_range(1..8) as f64;
            let y = rng.random_range(1.0..319.0);
            let (a, b) = (DVec2::new(x - 0.01, y), DVec2::new(x + 0.01, y));
            let (za, zb) = (soup.surface_z(a), soup.surface_z(b));
            if za.is_empty() || zb.is_empty() {
                continue;
            }
            let p = DVec3::new(a.x, a.y, za[0] + 1e-3);
            let q = DVec3::new(b.x, b.y, zb[0] - 1e-3);
            if !soup.hit(p, q) {
                seen_through += 1;
            }
        }
    }
    assert!(
        seen_through > 0,
        "the control found no crack: the ray test cannot see one"
    );
}

// ---------------------------------------------------------------------------------------------
// Occluder cells

#[test]
fn occluder_cells_lie_below_the_surface() {
    let t = smooth(45, 37, 7.0, DVec2::new(100.0, 200.0), 33).with_nodata(|i, j| i == 20 && j < 5);
    let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
    let t = tree.terrain();
    let mut cells = 0;
    for id in tree.node_ids() {
        for (b, z) in tree.occluder_cells(id) {
            cells += 1;
            let mut lowest = f64::MAX;
            let (u0, v0) = (
                (b[0] - t.origin().x) / t.spacing().x,
                (b[1] - t.origin().y) / t.spacing().y,
            );
            let (u1, v1) = (
                (b[2] - t.origin().x) / t.spacing().x,
                (b[3] - t.origin().y) / t.spacing().y,
            );
            for j in v0.round() as usize..=v1.round() as usize {
                for i in u0.round() as usize..=u1.round() as usize {
                    let h = t.height(i, j).expect("an occluder cell has data");
                    assert!(h >= z, "{id:?}: sample ({i}, {j}) {h} < {z}");
                    lowest = lowest.min(h);
                }
            }
            for jj in 0..=12 {
                for ii in 0..=12 {
                    let (lo, hi) = (
                        [u0.round() as usize, v0.round() as usize],
                        [u1.round() as usize, v1.round() as usize],
                    );
                    let uv = DVec2::new(
                        lo[0] as f64 + (hi[0] - lo[0]) as f64 * ii as f64 / 12.0,
                        lo[1] as f64 + (hi[1] - lo[1]) as f64 * jj as f64 / 12.0,
                    );
                    let bil = bilinear_uv(t, uv, lo, hi).expect("an occluder cell has data");
                    let tri = full_res_uv(t, uv, lo, hi).expect("an occluder cell has data");
                    assert!(
                        bil >= z - 1e-9 && tri >= z - 1e-9,
                        "{id:?} {b:?}: {bil} / {tri} < {z}"
                    );
                }
            }
            // Tight: it is the lowest sample in the box.
            assert_eq!(lowest, z, "{id:?}");
        }
    }
    assert!(cells > 1000);
}

// ---------------------------------------------------------------------------------------------
// Meshes

#[test]
fn meshes_five_km_from_the_origin_keep_millimetres() {
    // The DEM's extent starts 5 km from the city's local origin.
    let origin = DVec3::new(463_000.0, 5_546_000.0, 0.0);
    let t = smooth(
        65,
        65,
        1.0,
        DVec2::new(origin.x + 5_000.0, origin.y + 5_000.0),
        8,
    );
    let frame = LocalFrame { origin };
    let tree = TerrainTree::build(t, &TreeOptions::default()).unwrap();
    let t = tree.terrain();
    let mut worst: f64 = 0.0;
    for id in tree.node_ids() {
        let m = tree.node_mesh(id, &frame);
        assert_eq!(m.positions.len(), m.normals.len());
        for tri in m.indices[..m.surface_indices].chunks(3) {
            for &v in tri {
                let w = frame.to_world_f32(m.positions[v as usize]);
                let uv = (w.truncate() - t.origin()) / t.spacing();
                let (i, j) = (uv.x.round() as usize, uv.y.round() as usize);
                let exact = DVec3::new(t.x(i), t.y(j), t.raw(i, j));
                worst = worst.max((w - exact).length());
            }
        }
        for n in &m.normals {
            assert!((n.length() - 1.0).abs() < 1e-5 && n.z > 0.0);
        }
    }
    assert!(worst < 1e-3, "{worst} m off");
    // The same positions in f32 world coordinates would be off by decimetres.
    let naive = DVec3::new(origin.x + 5_000.3, origin.y + 5_000.3, 0.0);
    assert!((naive.as_vec3().as_dvec3() - naive).length() > 0.05);
    // The full mesh draws every cell.
    let full = tree.full_mesh(&frame);
    assert_eq!(full.triangles(), 2 * 64 * 64);
    assert_eq!(full.positions.len(), 65 * 65);
}

#[test]
fn nodata_cells_are_holes_in_every_mesh() {
    let t = smooth(17, 17, 2.0, DVec2::ZERO, 1).with_nodata(|i, j| i == 5 && j == 5);
    let frame = LocalFrame {
        origin: DVec3::ZERO,
    };
    let tree = TerrainTree::build(t, &TreeOptions { tile_cells: 4 }).unwrap();
    let full = tree.full_mesh(&frame);
    assert_eq!(full.triangles(), 2 * (16 * 16 - 4));
    assert!(full.positions.iter().all(|p| p.is_finite()));
    for id in tree.node_ids() {
        let m = tree.node_mesh(id, &frame);
        assert!(m.positions.iter().all(|p| p.is_finite()));
        // No surface triangle covers the hole's node (10, 10) m.
        for tri in m.indices[..m.surface_indices].chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| m.positions[tri[k] as usize].as_dvec3());
            let p = DVec3::new(10.0, 10.0, 1e4);
            let q = DVec3::new(10.0, 10.0, -1e4);
            assert!(
                !segment_hits_triangle(p, q, a, b, c),
                "{id:?} covers the hole"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Memory

#[test]
fn the_tree_is_smaller_than_twice_the_grid() {
    let t = smooth(1451, 878, 30.0, DVec2::new(328_290.0, 3_097_260.0), 1);
    let grid = t.heap_bytes();
    let tree = TerrainTree::build(t, &TreeOptions::default()).unwrap();
    let ratio = tree.heap_bytes() as f64 / grid as f64;
    eprintln!(
        "1451 × 878: grid {grid} B, tree {} B ({ratio:.3}×), levels {}",
        tree.heap_bytes(),
        serde_json::to_string(&tree.levels()).unwrap()
    );
    assert!(ratio <= 2.0, "{ratio}");
    tree.check_invariants();
}

// ---------------------------------------------------------------------------------------------
// Lon/lat DEM

fn lonlat_dem() -> DemGrid {
    // 0.0005° steps around 14.40° E, 50.08° N, north-up (negative row step), a smooth field.
    let (w, h) = (240, 200);
    let transform = [14.35, 0.0005, 0.0, 50.13, 0.0, -0.0005];
    let mut values = Vec::with_capacity(w * h);
    for r in 0..h {
        for c in 0..w {
            let lon = transform[0] + transform[1] * c as f64;
            let lat = transform[3] + transform[5] * r as f64;
            values.push(250.0 + 40.0 * (lon * 90.0).sin() + 30.0 * (lat * 70.0).cos());
        }
    }
    DemGrid {
        source: PathBuf::from("synthetic_lonlat.tif"),
        width: w,
        height: h,
        values,
        transform,
        crs: Crs::Geographic { epsg: Some(4326) },
        pixel_is: PixelIs::Point,
        nodata: None,
        nodata_count: 0,
        sample_type: "float64".into(),
        layout: "strips",
    }
}

#[test]
fn a_lon_lat_dem_is_resampled_at_its_ground_spacing() {
    let dem = lonlat_dem();
    let crs = Crs::Geographic { epsg: Some(4326) };
    // The city's transform, centred as the importers centre it (on the data).
    let to_metric = crs.metric_transform([14.41, 50.07]);
    let region = [-2_000.0, -2_500.0, 1_500.0, 2_000.0];
    let t = Terrain::from_dem(&dem, &to_metric, Some(region)).unwrap();
    let r = t.report();
    assert!(r.resampled);
    assert_eq!(r.source_size, [240, 200]);
    // Ground spacing: the smaller axis, 0.0005° of longitude at 50.07° N ≈ 35.8 m.
    let want = 0.0005f64.to_radians() * 6_378_137.0 * 50.07f64.to_radians().cos();
    assert!((r.spacing_m[0] - want).abs() < 0.3, "{r:?}");
    assert!(
        t.extent()[0] >= region[0] - r.spacing_m[0] && t.extent()[2] <= region[2] + r.spacing_m[0]
    );
    // Every node against the source sampled directly at from_metric(node), by this test's
    // own inverse affine map and bilinear interpolation.
    let tr = dem.transform;
    let mut checked = 0;
    for j in 0..t.ny() {
        for i in 0..t.nx() {
            let p = t.node_xy(i, j);
            let [lon, lat] = to_metric.from_metric([p.x, p.y]);
            let c = (lon - tr[0]) / tr[1];
            let rr = (lat - tr[3]) / tr[5];
            let (c0, r0) = (c.floor() as usize, rr.floor() as usize);
            let (fc, fr) = (c - c0 as f64, rr - r0 as f64);
            let v = |c: usize, r: usize| dem.values[r * dem.width + c];
            let want = v(c0, r0) * (1.0 - fc) * (1.0 - fr)
                + v(c0 + 1, r0) * fc * (1.0 - fr)
                + v(c0, r0 + 1) * (1.0 - fc) * fr
                + v(c0 + 1, r0 + 1) * fc * fr;
            let got = t.height(i, j).expect("inside the DEM");
            assert!((got - want).abs() < 1e-9, "({i}, {j}): {got} vs {want}");
            // And the field itself, within the bilinear error of so smooth a function.
            let field = 250.0 + 40.0 * (lon * 90.0).sin() + 30.0 * (lat * 70.0).cos();
            assert!((got - field).abs() < 0.05, "({i}, {j}): {got} vs {field}");
            checked += 1;
        }
    }
    assert!(checked > 10_000, "{checked}");
    // Refusals: a region off the DEM names both extents.
    let e = Terrain::from_dem(&dem, &to_metric, Some([50_000.0, 0.0, 51_000.0, 1_000.0]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("synthetic_lonlat.tif") && e.contains("50000.0"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// The Nepal DEM

/// The Nepal DEM, or `None` after a loud skip when the file is absent (a failure where
/// `BLOCKWALK_REQUIRE` names `dem`).
fn nepal_or_skip(test: &str) -> Option<DemGrid> {
    let path = support::data::shared_data("dem/nepal-langtang-mapbox-terrain/nepal_30m_32645.tif");
    let found = if path.is_file() {
        Ok(path)
    } else {
        Err(format!("{} absent", path.display()))
    };
    let path = or_skip(Need::Dem, test, found)?;
    Some(read_dem(&path).unwrap_or_else(|e| panic!("{test}: {e}")))
}

#[test]
fn nepal_dem_is_kept_as_read_and_its_tree_holds_its_bounds() {
    let Some(dem) = nepal_or_skip("nepal_dem_is_kept_as_read_and_its_tree_holds_its_bounds") else {
        return;
    };
    let to_metric = dem.crs.metric_transform([350_000.0, 3_110_000.0]);
    let t = Terrain::from_dem(&dem, &to_metric, None).unwrap();
    let r = t.report().clone();
    assert!(!r.resampled);
    assert_eq!(r.size, [1451, 878]);
    assert_eq!(r.nodata_count, 37_682);
    assert!(
        (r.min_m - 988.28).abs() < 0.01 && (r.max_m - 6310.0).abs() < 0.01,
        "{r:?}"
    );
    let start = std::time::Instant::now();
    let tree = TerrainTree::build(t, &TreeOptions::default()).unwrap();
    eprintln!(
        "Nepal: tree built in {:?}, {}",
        start.elapsed(),
        serde_json::to_string(&tree.summary()).unwrap()
    );
    tree.check_invariants();
    assert!(tree.heap_bytes() <= 2 * tree.terrain().heap_bytes());
    // A region around the valley crops without resampling.
    let c = Terrain::from_dem(
        &dem,
        &to_metric,
        Some([340_000.0, 3_105_000.0, 345_000.0, 3_110_000.0]),
    )
    .unwrap();
    assert!(!c.report().resampled && c.nx() < 200);
    let p = DVec2::new(342_015.0, 3_107_985.0);
    assert!((c.sample(p).unwrap() - tree.terrain().sample(p).unwrap()).abs() < 1e-6);
}

#[test]
fn nepal_footprints_rest_on_the_lowest_ground() {
    let Some(dem) = nepal_or_skip("nepal_footprints_rest_on_the_lowest_ground") else {
        return;
    };
    let to_metric = dem.crs.metric_transform([350_000.0, 3_110_000.0]);
    let t = Terrain::from_dem(
        &dem,
        &to_metric,
        Some([345_000.0, 3_105_000.0, 355_000.0, 3_115_000.0]),
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let e = t.extent();
    let mut done = 0;
    for _ in 0..60 {
        let c = DVec2::new(
            rng.random_range(e[0] + 50.0..e[2] - 50.0),
            rng.random_range(e[1] + 50.0..e[3] - 50.0),
        );
        let fp = random_polygon(&mut rng, c, 40.0);
        if t.ground_under(&fp, BaseRule::Min).is_ok() {
            check_ground(&t, &fp);
            done += 1;
        }
    }
    assert!(done > 30);
}
