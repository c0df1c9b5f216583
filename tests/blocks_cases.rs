//! Hard cases for the street graph and the face walk, and grid properties (proptest).

use blockwalk::blocks::noding::node_lines;
use blockwalk::blocks::{
    detect_geometry, BlockError, BlockKind, BlockLayout, BlockOptions, BlockSource,
};
use blockwalk::geom::predicates::{point_in_polygon, polygon_area, ring_signed_area, Location};
use geo_types::{line_string, polygon, Coord, LineString, Polygon};
use proptest::prelude::*;

fn streets(lines: &[LineString<f64>], buildings: &[Polygon<f64>], tol: f64) -> BlockLayout {
    let opts = BlockOptions {
        snap_tolerance: tol,
        ..BlockOptions::default()
    };
    detect_geometry(BlockSource::Streets, lines, &[], buildings, &opts).unwrap()
}

fn face_areas(l: &BlockLayout) -> Vec<f64> {
    let mut a: Vec<f64> = l
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Block)
        .map(|b| polygon_area(&b.polygon))
        .collect();
    a.sort_by(f64::total_cmp);
    a
}

fn square(x: f64, y: f64, s: f64) -> Polygon<f64> {
    polygon![(x: x, y: y), (x: x + s, y: y), (x: x + s, y: y + s), (x: x, y: y + s)]
}

fn once_each(l: &BlockLayout, n: usize) -> bool {
    let mut seen = vec![0; n];
    for b in &l.blocks {
        for id in &b.buildings {
            seen[id.0 as usize] += 1;
        }
    }
    seen.iter().all(|&c| c == 1)
}

#[test]
fn collinear_overlapping_streets_make_one_face() {
    let lines = vec![
        line_string![(x: 0., y: 0.), (x: 70., y: 0.)],
        line_string![(x: 30., y: 0.), (x: 100., y: 0.)],
        line_string![(x: 100., y: 0.), (x: 0., y: 0.)],
        line_string![(x: 100., y: 0.), (x: 100., y: 100.), (x: 0., y: 100.), (x: 0., y: 0.)],
        line_string![(x: 0., y: 100.), (x: 50., y: 100.)],
    ];
    let l = streets(&lines, &[], 0.05);
    assert_eq!(face_areas(&l), vec![10_000.0]);
    assert_eq!(l.dangles, 0);
}

#[test]
fn t_junctions_missing_by_a_millimetre_join() {
    let lines = vec![
        line_string![(x: 0., y: 0.), (x: 200., y: 0.), (x: 200., y: 100.), (x: 0., y: 100.), (x: 0., y: 0.)],
        // Misses the bottom street by 1 mm and overshoots the top one by 1 mm.
        line_string![(x: 100., y: 0.001), (x: 100., y: 100.001)],
    ];
    let l = streets(&lines, &[], 0.05);
    let a = face_areas(&l);
    assert_eq!(a.len(), 2);
    assert!(
        (a[0] - 10_000.0).abs() < 0.2 && (a[1] - 10_000.0).abs() < 0.2,
        "{a:?}"
    );
    // Noding without snapping keeps them apart: one face.
    assert_eq!(exact_face_areas(&lines).len(), 1);
}

/// Areas of the bounded faces of `lines` noded at tolerance 0 (exact for lines whose crossings
/// need no computing; `detect_geometry` takes at least `MIN_SNAP_TOLERANCE`), sorted.
fn exact_face_areas(lines: &[LineString<f64>]) -> Vec<f64> {
    let fs = blockwalk::blocks::faces::faces(&node_lines(lines, 0.0));
    let mut a: Vec<f64> = fs.bounded().map(|i| fs.area(i)).collect();
    a.sort_by(f64::total_cmp);
    a
}

#[test]
fn streets_at_1e9_angles_are_ordered_exactly() {
    // Two streets leave (0,0) at angles 0 and ~1e-9 rad, closed by a 1e-7 m link.
    let lines = vec![
        line_string![(x: 0., y: 0.), (x: 100., y: 0.), (x: 100., y: 100.), (x: 0., y: 100.), (x: 0., y: 0.)],
        line_string![(x: 0., y: 0.), (x: 100., y: 1e-7)],
    ];
    let a = exact_face_areas(&lines);
    assert_eq!(a.len(), 2, "{a:?}");
    assert!((a[0] - 5e-6).abs() < 1e-12);
    assert!((a[0] + a[1] - 10_000.0).abs() < 1e-9);
    // With the default tolerance the sliver is one street.
    assert_eq!(face_areas(&streets(&lines, &[], 0.05)).len(), 1);
}

#[test]
fn coordinates_near_1e7_give_the_same_faces() {
    let grid = |o: f64| -> Vec<LineString<f64>> {
        let mut v = Vec::new();
        for k in 0..4 {
            let t = o + 37.3 * k as f64;
            v.push(line_string![(x: o, y: t), (x: o + 111.9, y: t)]);
            v.push(line_string![(x: t, y: o), (x: t, y: o + 111.9)]);
        }
        v
    };
    let near = face_areas(&streets(&grid(0.0), &[], 0.05));
    let far = face_areas(&streets(&grid(1.0e7), &[], 0.05));
    assert_eq!(near.len(), 9);
    assert_eq!(far.len(), 9);
    for (a, b) in near.iter().zip(&far) {
        assert!((a - b).abs() < 1e-6 * a, "{a} {b}");
    }
}

#[test]
fn street_loop_inside_a_block_is_a_hole() {
    let lines = vec![
        line_string![(x: 0., y: 0.), (x: 100., y: 0.), (x: 100., y: 100.), (x: 0., y: 100.), (x: 0., y: 0.)],
        line_string![(x: 30., y: 30.), (x: 70., y: 30.), (x: 70., y: 70.), (x: 30., y: 70.), (x: 30., y: 30.)],
        // A cul-de-sac off the loop stays inside the ring block.
        line_string![(x: 70., y: 50.), (x: 85., y: 50.)],
    ];
    let buildings = vec![
        square(45.0, 45.0, 10.0),
        square(5.0, 5.0, 10.0),
        square(80.0, 52.0, 5.0),
    ];
    let l = streets(&lines, &buildings, 0.05);
    assert_eq!(face_areas(&l), vec![1600.0, 8400.0]);
    assert_eq!(l.dangles, 1);
    let ring = l
        .blocks
        .iter()
        .find(|b| b.polygon.interiors().len() == 1)
        .unwrap();
    let mut ids: Vec<u32> = ring.buildings.iter().map(|b| b.0).collect();
    ids.sort();
    assert_eq!(ids, vec![1, 2]);
    let hole = &ring.polygon.interiors()[0];
    assert!(
        ring_signed_area(&hole.0[..hole.0.len() - 1]) < 0.0,
        "holes are clockwise"
    );
    assert!(once_each(&l, 3));
}

#[test]
fn empty_street_layer_gives_only_outskirts() {
    let buildings = vec![
        square(0.0, 0.0, 10.0),
        square(15.0, 0.0, 10.0),
        square(500.0, 0.0, 10.0),
    ];
    let l = streets(&[], &buildings, 0.05);
    assert!(l.blocks.iter().all(|b| b.kind == BlockKind::Outskirts));
    assert_eq!(l.blocks.len(), 2, "two groups: 5 m apart, and 475 m away");
    assert!(once_each(&l, 3));
    assert!(l.street_edges.is_empty());
    let none = streets(&[], &[], 0.05);
    assert!(none.blocks.is_empty());
    // Degenerate input lines do not panic either.
    let junk = vec![
        line_string![(x: 1., y: 1.)],
        line_string![(x: 2., y: 2.), (x: 2., y: 2.)],
    ];
    assert!(streets(&junk, &buildings, 0.05)
        .blocks
        .iter()
        .all(|b| b.kind == BlockKind::Outskirts));
}

#[test]
fn bad_options_are_errors() {
    for (snap, says) in [
        (5.01, "5 m"),
        (1e9, "5 m"),
        (0.0, "1 mm"),
        (0.000_999, "1 mm"),
    ] {
        let opts = BlockOptions {
            snap_tolerance: snap,
            ..BlockOptions::default()
        };
        let e = detect_geometry(BlockSource::Streets, &[], &[], &[], &opts).unwrap_err();
        assert!(
            matches!(e, BlockError::BadOption { name: "snap_tolerance", value, .. } if value == snap),
            "{e:?}"
        );
        assert!(e.to_string().contains(says), "{e}");
    }
    for bound in [
        blockwalk::blocks::noding::MIN_SNAP_TOLERANCE,
        blockwalk::blocks::noding::MAX_SNAP_TOLERANCE,
    ] {
        let at_bound = BlockOptions {
            snap_tolerance: bound,
            ..BlockOptions::default()
        };
        assert!(detect_geometry(BlockSource::Streets, &[], &[], &[], &at_bound).is_ok());
    }
    let opts = BlockOptions {
        snap_tolerance: f64::NAN,
        ..BlockOptions::default()
    };
    let e = detect_geometry(BlockSource::Streets, &[], &[], &[], &opts).unwrap_err();
    assert!(
        matches!(e, BlockError::BadOption { name: "snap_tolerance", value, .. } if value.is_nan()),
        "{e:?}"
    );
    let opts = BlockOptions {
        street_width: -1.0,
        ..BlockOptions::default()
    };
    let e = detect_geometry(BlockSource::Streets, &[], &[], &[], &opts).unwrap_err();
    assert!(
        matches!(e, BlockError::BadOption { name: "street_width", value, .. } if value == -1.0),
        "{e:?}"
    );
    assert!(e.to_string().contains("street_width"), "{e}");
}

/// A jittered grid: `n × n` nodes, spacing 100, each interior node moved by up to `j`.
fn jittered(n: usize, jit: &[(f64, f64)]) -> Vec<Vec<Coord<f64>>> {
    (0..n)
        .map(|i| {
            (0..n)
                .map(|k| {
                    let (dx, dy) = jit[i * n + k];
                    Coord {
                        x: 100.0 * k as f64 + dx,
                        y: 100.0 * i as f64 + dy,
                    }
                })
                .collect()
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn jittered_grid_faces_tile_and_buildings_assigned_once(
        n in 2usize..7,
        jit in proptest::collection::vec((-20.0f64..20.0, -20.0f64..20.0), 49),
        spurs in proptest::collection::vec(0usize..49, 0..5),
        offset in prop_oneof![Just(0.0), Just(6.0e6)],
    ) {
        let g: Vec<Vec<Coord<f64>>> = jittered(n, &jit)
            .into_iter()
            .map(|row| row.into_iter().map(|c| Coord { x: c.x + offset, y: c.y + offset }).collect())
            .collect();
        let mut lines = Vec::new();
        for (i, row) in g.iter().enumerate() {
            lines.push(LineString(row.clone()));
            lines.push(LineString(g.iter().map(|r| r[i]).collect()));
        }
        // Dangling spurs from random nodes, and the grid drawn in pieces that overlap.
        for &s in &spurs {
            let c = g[(s / n) % n][s % n];
            lines.push(LineString(vec![c, Coord { x: c.x + 7.0, y: c.y + 3.0 }]));
        }
        lines.push(LineString(vec![g[0][0], g[0][1]]));
        // One building (a small triangle) near the centre of each cell, one far outside.
        let mut buildings = Vec::new();
        let mut centres = Vec::new();
        for i in 0..n - 1 {
            for k in 0..n - 1 {
                let q = [g[i][k], g[i][k + 1], g[i + 1][k + 1], g[i + 1][k]];
                let c = Coord {
                    x: q.iter().map(|c| c.x).sum::<f64>() / 4.0,
                    y: q.iter().map(|c| c.y).sum::<f64>() / 4.0,
                };
                centres.push(c);
                buildings.push(polygon![(x: c.x - 2., y: c.y - 2.), (x: c.x + 2., y: c.y - 2.), (x: c.x, y: c.y + 2.)]);
            }
        }
        buildings.push(square(offset - 500.0, offset - 500.0, 5.0));
        let l = streets(&lines, &buildings, 0.05);
        let areas = face_areas(&l);
        prop_assert_eq!(areas.len(), (n - 1) * (n - 1));
        let mut ring: Vec<Coord<f64>> = (0..n).map(|k| g[0][k]).collect();
        ring.extend((1..n).map(|i| g[i][n - 1]));
        ring.extend((0..n - 1).rev().map(|k| g[n - 1][k]));
        ring.extend((1..n - 1).rev().map(|i| g[i][0]));
        let enclosed = ring_signed_area(&ring);
        let total: f64 = areas.iter().sum();
        // Snapping may move a boundary by up to the tolerance (a spur end within 5 cm of an edge
        // bends the edge through it), so the faces tile the ring up to tolerance × perimeter.
        let perimeter: f64 = ring
            .iter()
            .zip(ring.iter().cycle().skip(1))
            .map(|(a, b)| ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt())
            .sum();
        prop_assert!(
            (total - enclosed).abs() <= 0.05 * perimeter + 1e-6 * enclosed,
            "{} vs {}",
            total,
            enclosed
        );
        prop_assert!(once_each(&l, buildings.len()));
        for (b, c) in centres.iter().enumerate() {
            let block = l.blocks.iter().find(|x| x.buildings.iter().any(|id| id.0 as usize == b)).unwrap();
            prop_assert_eq!(block.kind, BlockKind::Block);
            prop_assert_eq!(point_in_polygon(*c, &block.polygon), Location::Inside);
        }
        let last = l.blocks.iter().find(|x| x.buildings.iter().any(|id| id.0 as usize == buildings.len() - 1)).unwrap();
        prop_assert_eq!(last.kind, BlockKind::Outskirts);
        // The graph is exact: noding the noded edges again changes nothing.
        let again = node_lines(&l.street_edges, 0.0);
        prop_assert_eq!(again.edges.len(), l.street_edges.len());
    }
}

/// On a generated city the street faces are the generator's blocks: as many faces holding
/// buildings as blocks were used, and no building in the outskirts.
#[test]
fn generated_city_faces_are_its_blocks() {
    use blockwalk::city::generate::{generate_city, GenerateParams};
    let g = generate_city(&GenerateParams {
        buildings: 1500,
        seed: 3,
        ..GenerateParams::default()
    })
    .unwrap();
    let lines: Vec<LineString<f64>> = g.streets.iter().map(|s| s.line.clone()).collect();
    let fps: Vec<Polygon<f64>> = g.buildings.iter().map(|b| b.footprint.clone()).collect();
    let l = streets(&lines, &fps, 0.05);
    let with = l
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Block && !b.buildings.is_empty())
        .count();
    let outskirts: usize = l
        .blocks
        .iter()
        .filter(|b| b.kind == BlockKind::Outskirts)
        .map(|b| b.buildings.len())
        .sum();
    println!(
        "generated: {} blocks used, {with} faces with buildings, {outskirts} outskirts",
        g.blocks
    );
    assert_eq!(with, g.blocks);
    assert_eq!(outskirts, 0);
    assert!(once_each(&l, fps.len()));
}

/// `n` lines through the point (3, -2), at angles spread evenly over a half turn.
fn star(n: usize, radius: f64) -> Vec<LineString<f64>> {
    (0..n)
        .map(|k| {
            let a = std::f64::consts::PI * (k as f64 + 0.5) / n as f64;
            let (dx, dy) = (radius * a.cos(), radius * a.sin());
            LineString::from(vec![(3.0 - dx, -2.0 - dy), (3.0 + dx, -2.0 + dy)])
        })
        .collect()
}

#[test]
fn two_thousand_lines_through_one_point_make_one_centre_node_and_two_edges_each() {
    use blockwalk::blocks::noding::DEFAULT_SNAP_TOLERANCE;
    let n = 2000;
    let g = node_lines(&star(n, 100.0), DEFAULT_SNAP_TOLERANCE);
    assert_eq!(g.edges.len(), 2 * n, "two edges per line");
    assert_eq!(g.nodes.len(), 2 * n + 1, "the line ends and one centre");
    let deg = g.degrees();
    let centres: Vec<usize> = (0..g.nodes.len()).filter(|&i| deg[i] > 1).collect();
    assert_eq!(centres.len(), 1, "{centres:?}");
    let c = g.nodes[centres[0]];
    assert_eq!(deg[centres[0]] as usize, 2 * n);
    assert!(
        (c.x - 3.0).hypot(c.y + 2.0) <= DEFAULT_SNAP_TOLERANCE,
        "{c:?}"
    );
    // Every edge joins the centre to one line end, 100 m away.
    for e in &g.edges {
        assert!(e.contains(&(centres[0] as u32)), "{e:?}");
        let [p, q] = [g.nodes[e[0] as usize], g.nodes[e[1] as usize]];
        assert!(((p.x - q.x).hypot(p.y - q.y) - 100.0).abs() < 1e-6);
    }
    // The same as a brute-force count on a small star: every line meets every other once.
    let small = node_lines(&star(7, 10.0), DEFAULT_SNAP_TOLERANCE);
    assert_eq!((small.nodes.len(), small.edges.len()), (15, 14));
}
