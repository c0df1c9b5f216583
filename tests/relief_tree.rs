//! The relief-impostor tree (Andujar et al. §3, §4.1) on real cities and on a regular grid:
//! merging against a brute-force distance test, the tree's structure (every group in one leaf,
//! cells the boxes of their groups, each child's groups in its quadrant), formula (6) exactly,
//! and a regular city's negative overlap ratio, as the paper says of axis-aligned streets.

mod support;

use std::path::Path;

use blockwalk::city::model::{BuildingId, CityReport, HeightSource, LocalFrame};
use blockwalk::city::{Building, City};
use blockwalk::relief::tree::{merge, quadrant, Formulas, ReliefTree, TreeParams};
use geo::{Distance, Euclidean};
use geo_types::{LineString, Polygon};
use support::data::load_city;

/// Every pair closer than the gap shares a group, and every group is connected by such pairs:
/// the groups are the connected components, by brute force.
fn check_merge(city: &City, gap: f64) -> usize {
    let groups = merge(city, gap, None);
    let mut group_of = vec![usize::MAX; city.buildings.len()];
    for (g, grp) in groups.iter().enumerate() {
        for b in &grp.buildings {
            assert_eq!(group_of[b.0 as usize], usize::MAX, "building {} twice", b.0);
            group_of[b.0 as usize] = g;
        }
    }
    assert!(
        group_of.iter().all(|&g| g != usize::MAX),
        "a building in no group"
    );
    let n = city.buildings.len();
    let close = |i: usize, j: usize| {
        Euclidean.distance(&city.buildings[i].footprint, &city.buildings[j].footprint) <= gap
    };
    let mut close_pairs = 0;
    for i in 0..n {
        for j in i + 1..n {
            if close(i, j) {
                close_pairs += 1;
                assert_eq!(
                    group_of[i], group_of[j],
                    "buildings {i} and {j} are within {gap} m"
                );
            }
        }
    }
    for grp in &groups {
        // Connected: a walk over close pairs from the first building reaches all.
        let ids: Vec<usize> = grp.buildings.iter().map(|b| b.0 as usize).collect();
        let mut seen = vec![ids[0]];
        let mut k = 0;
        while k < seen.len() {
            let a = seen[k];
            for &b in &ids {
                if !seen.contains(&b) && close(a, b) {
                    seen.push(b);
                }
            }
            k += 1;
        }
        assert_eq!(
            seen.len(),
            ids.len(),
            "group of {:?} is not connected",
            ids[0]
        );
    }
    close_pairs
}

/// The tree's structure, whatever the city.
fn check_tree(city: &City, tree: &ReliefTree) {
    let root = &tree.nodes[0];
    assert_eq!(root.groups.len(), tree.groups.len());
    let mut in_leaves = vec![0u32; tree.groups.len()];
    for (i, n) in tree.nodes.iter().enumerate() {
        // The cell is the box of its groups' footprints.
        let b = n
            .groups
            .iter()
            .map(|&g| tree.groups[g as usize].bounds)
            .reduce(|a, b| a.union(b))
            .unwrap();
        assert_eq!(n.bounds, b, "node {i}");
        if n.is_leaf() {
            for &g in &n.groups {
                in_leaves[g as usize] += 1;
            }
            assert!(
                n.groups.len() == 1 || n.depth == tree.params.max_depth || n.split_at.is_none(),
                "node {i}"
            );
            continue;
        }
        let at = n.split_at.expect("an interior node was split");
        let mut union: Vec<u32> = Vec::new();
        for (k, c) in n.children.iter().enumerate() {
            let Some(c) = c else { continue };
            let c = &tree.nodes[*c as usize];
            assert_eq!(c.depth, n.depth + 1);
            for &g in &c.groups {
                assert_eq!(
                    quadrant(tree.groups[g as usize].barycentre, at),
                    k,
                    "node {i}"
                );
            }
            // Inside the parent's cell (sibling cells may overlap).
            assert!(c.bounds.min[0] >= n.bounds.min[0] && c.bounds.max[0] <= n.bounds.max[0]);
            assert!(c.bounds.min[1] >= n.bounds.min[1] && c.bounds.max[1] <= n.bounds.max[1]);
            union.extend(&c.groups);
        }
        union.sort_unstable();
        assert_eq!(
            union, n.groups,
            "node {i}: the children partition the groups"
        );
        assert!(
            n.children.iter().flatten().count() >= 2,
            "node {i} split into one"
        );
    }
    assert!(
        in_leaves.iter().all(|&k| k == 1),
        "every group in exactly one leaf"
    );
    let buildings: usize = tree.groups.iter().map(|g| g.buildings.len()).sum();
    assert_eq!(buildings, city.buildings.len());
    // Formula (6), exact for a quaternary tree: I = (T + W − 1) / 3.
    let (i, t, w) = tree.counts();
    assert_eq!(3 * i, t + w - 1, "I = {i}, T = {t}, W = {w}");
}

fn report(name: &str, tree: &ReliefTree, f: &Formulas) {
    eprintln!(
        "{name}: {} groups, {} nodes (bound (7) {:.0}, (8) {:.0}), depth {} (formula (5) {:?}), \
         L {:.0} m, ω {:.3}, δ {:.3}, M {}, median splits {}",
        tree.groups.len(),
        f.nodes,
        f.node_bound,
        f.node_bound_two_virtual_levels,
        f.built_depth,
        f.predicted_depth,
        f.universe_m,
        f.coverage,
        f.delta,
        f.map_size,
        tree.median_splits
    );
    for l in tree.levels() {
        eprintln!(
            "  level {}: {} nodes ({} leaves), mean edge {:.1} m, δ {:?}",
            l.depth, l.nodes, l.leaves, l.mean_edge_m, l.mean_delta
        );
    }
}

#[test]
fn real_cities_merge_exactly_and_build_a_sound_tree() {
    for (name, path) in [
        ("Bubeneč", "data/bubenec/buildings.shp"),
        ("Helsinki", "data/helsinki/buildings.shp"),
    ] {
        let city = load_city(Path::new(path), None);
        for gap in [0.0, 0.5, 3.0] {
            let pairs = check_merge(&city, gap);
            eprintln!("{name}: {pairs} pairs within {gap} m");
        }
        let tree = ReliefTree::build(&city, TreeParams::default()).unwrap();
        check_tree(&city, &tree);
        // Merging joins something in both (terraced houses, shared walls).
        assert!(tree.groups.len() < city.buildings.len(), "{name}");
        let f = Formulas::new(&tree, 0.17, 100.0).unwrap();
        report(name, &tree, &f);
        assert_eq!(f.nodes, tree.nodes.len());
        assert!(
            f.coverage > 0.0 && f.coverage < 1.0,
            "{name}: ω {}",
            f.coverage
        );
        // Formula (9): 100 m blocks at 17 cm need M ≥ 294: 512.
        assert_eq!(f.map_size, 512);
    }
}

/// An 8 × 8 grid of 10 m squares 20 m apart: groups are the squares, every split is at the
/// cell centre, sibling cells are disjoint (δ < 0, the paper's regular city), and the tree is
/// the complete quaternary tree of depth 3: 1 + 4 + 16 + 64 nodes.
#[test]
fn a_regular_grid_gives_the_complete_tree_with_negative_overlap() {
    let square = |x: f64, y: f64| {
        Polygon::new(
            LineString::from(vec![
                (x, y),
                (x + 10.0, y),
                (x + 10.0, y + 10.0),
                (x, y + 10.0),
                (x, y),
            ]),
            vec![],
        )
    };
    let buildings = (0..64)
        .map(|i| Building {
            id: BuildingId(i),
            source_id: format!("g:{i}"),
            footprint: square(f64::from(i % 8) * 20.0, f64::from(i / 8) * 20.0),
            height_m: 10.0,
            min_height_m: 0.0,
            base_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        })
        .collect();
    let city = City {
        name: "grid".into(),
        transform: blockwalk::importers::Crs::Unknown.metric_transform([0.0, 0.0]),
        frame: LocalFrame {
            origin: glam::DVec3::ZERO,
        },
        buildings,
        streets: vec![],
        parcels: vec![],
        report: CityReport::default(),
        terrain: None,
    };
    assert_eq!(check_merge(&city, 0.5), 0);
    let tree = ReliefTree::build(&city, TreeParams::default()).unwrap();
    check_tree(&city, &tree);
    assert_eq!(tree.groups.len(), 64);
    assert_eq!(tree.nodes.len(), 85);
    assert_eq!(tree.depth(), 3);
    assert_eq!(tree.median_splits, 0);
    let (i, t, w) = tree.counts();
    assert_eq!((i, t, w), (21, 64, 0));
    // Edges 150, 70, 30, 10 m: δ = 2 − 150/70, 2 − 70/30, 2 − 30/10.
    let levels = tree.levels();
    let want = [2.0 - 150.0 / 70.0, 2.0 - 70.0 / 30.0, 2.0 - 30.0 / 10.0];
    for (l, w) in levels[1..].iter().zip(want) {
        assert!((l.mean_delta.unwrap() - w).abs() < 1e-12, "{l:?}");
        assert!(w < 0.0);
    }
    // Formula (3) with the tree's own mean δ against the measured edges, and (6).
    let f = Formulas::new(&tree, 0.17, 10.0).unwrap();
    assert_eq!(f.interior.0, 21);
    assert!((f.interior.1 - 21.0).abs() < 1e-12);
    assert_eq!(f.map_size, 32, "10 m blocks at 17 cm: M ≥ 29.4");
    // (7) with d = 3 and ω = 6400 / 150²: 4³ω + (4³ − 1)/3. It assumes 4^d ω non-empty
    // leaves; here every one of the 64 cells is full though the squares cover 28 % of the
    // root, so the built tree (85 nodes) is above the estimate.
    assert!((f.coverage - 6400.0 / 22_500.0).abs() < 1e-12);
    assert!((f.node_bound - (64.0 * f.coverage + 21.0)).abs() < 1e-9);
    assert_eq!(f.nodes, 85);
}

/// Two groups whose barycentres fall in one quadrant of their cell (a long L with a small
/// square tucked in its corner): the cell-centre rule separates nothing, so the split is made
/// about the median barycentre, and counted.
#[test]
fn an_unseparable_pair_is_split_about_the_median() {
    let poly = |pts: &[(f64, f64)]| {
        let mut v = pts.to_vec();
        v.push(pts[0]);
        Polygon::new(LineString::from(v), vec![])
    };
    // An L along the bottom and left edges of a 100 m square, 5 m thick; a 2 m square at
    // (10, 10), inside the L's corner, 5 m from both arms.
    let l = poly(&[
        (0.0, 0.0),
        (100.0, 0.0),
        (100.0, 5.0),
        (5.0, 5.0),
        (5.0, 100.0),
        (0.0, 100.0),
    ]);
    let s = poly(&[(10.0, 10.0), (12.0, 10.0), (12.0, 12.0), (10.0, 12.0)]);
    let building = |i: u32, footprint| Building {
        id: BuildingId(i),
        source_id: format!("l:{i}"),
        footprint,
        height_m: 10.0,
        min_height_m: 0.0,
        base_m: 0.0,
        height_source: HeightSource::Height,
        attributes: Default::default(),
    };
    let city = City {
        name: "L".into(),
        transform: blockwalk::importers::Crs::Unknown.metric_transform([0.0, 0.0]),
        frame: LocalFrame {
            origin: glam::DVec3::ZERO,
        },
        buildings: vec![building(0, l), building(1, s)],
        streets: vec![],
        parcels: vec![],
        report: CityReport::default(),
        terrain: None,
    };
    let tree = ReliefTree::build(&city, TreeParams::default()).unwrap();
    check_tree(&city, &tree);
    assert_eq!(tree.groups.len(), 2);
    // Both barycentres are south-west of (50, 50).
    for g in &tree.groups {
        assert_eq!(quadrant(g.barycentre, [50.0, 50.0]), 3, "{g:?}");
    }
    assert_eq!(tree.median_splits, 1);
    assert_eq!(tree.nodes.len(), 3);
}
