//! Parents built from their children's maps (an option): the max filter on
//! handmade maps, the parent's solid holding its children's (proptest, checked point by point),
//! and on Helsinki and a generated city every parent agreeing with the polygon-built parent
//! within ε, its error measured against the polygons within its derived ε, and the coverage
//! error of a random view per map for both options.

mod support;
use blockwalk::blockmap::children::{
    build_from_children, column_height, directed_distance, Parents,
};
use blockwalk::blockmap::compare::{compare_view, random_views};
use blockwalk::blockmap::{build_tree, BlockMap, BuildOptions, MapTree, Source, Stop, TreeOptions};
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions as CityOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::importers::{read_layer, Theme};
use blockwalk::index::{block_bounds, BqrParams, BqrTree};
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use support::data::data;

/// A child map with one texel of height `h` and roof colour `rgb`.
fn one_texel(min: DVec2, side: f64, zmax: f64, at: (u32, u32), h: f64, rgb: [u8; 3]) -> BlockMap {
    let mut m = BlockMap::empty(32, min.extend(0.0), side, zmax).unwrap();
    let code = (h / zmax * 255.0).round() as u8;
    m.texel_mut(at.0, at.1)[0] = code;
    *m.texel_mut(32 + at.0, at.1) = [rgb[0], rgb[1], rgb[2], 255];
    m
}

const RED: [u8; 3] = [200, 0, 0];
const BLUE: [u8; 3] = [0, 0, 200];

#[test]
fn the_max_filter_takes_the_taller_of_two_overlapping_child_texels() {
    // Child A: 1 m texels from (0, 0); its texel (10, 10) covers [10, 11]², 10 m high.
    // Child B: 1 m texels from (0.5, 0.5); its texel (9, 9) covers [9.5, 10.5]², 20 m high.
    // Parent: 2 m texels from (0, 0); its texel (5, 5) covers [10, 12]² and overlaps both.
    let a = one_texel(DVec2::ZERO, 32.0, 20.0, (10, 10), 10.0, RED);
    let b = one_texel(DVec2::splat(0.5), 32.0, 20.0, (9, 9), 20.0, BLUE);
    let opts = BuildOptions {
        k: 32,
        edges: false,
        ..BuildOptions::default()
    };
    for order in [[&a, &b], [&b, &a]] {
        let (p, st) = build_from_children(&order, DVec2::ZERO, 64.0, 20.0, &opts).unwrap();
        assert_eq!(p.height_code(5, 5), 255, "the taller child wins");
        assert!(p.texel_height_m(5, 5).unwrap() >= 20.0);
        assert_eq!(&p.texel(32 + 5, 5)[..3], &BLUE, "roof colour of the taller");
        // Parent texel (4, 4) = [8, 10]² overlaps only B's texel (A's touches its corner).
        assert_eq!(p.height_code(4, 4), 255);
        assert_eq!(&p.texel(32 + 4, 4)[..3], &BLUE);
        // (4, 5) = x [8, 10], y [10, 12]: B overlaps, A touches an edge only.
        assert_eq!(p.height_code(4, 5), 255);
        // (5, 4) likewise; nothing else is filled.
        assert_eq!(p.height_code(5, 4), 255);
        assert_eq!(st.filled_texels, 4);
        assert_eq!(p.height_code(6, 5), 0);
        // Both texels are exposed, with wall columns.
        assert!(p.wall_offset(5, 5) > 0 && p.wall_offset(4, 4) > 0);
    }
    // A taller than B: A wins, its height rounded up in the parent's levels (zmax 25 m).
    let a = one_texel(DVec2::ZERO, 32.0, 25.0, (10, 10), 25.0, RED);
    let b = one_texel(DVec2::splat(0.5), 32.0, 25.0, (9, 9), 13.3, BLUE);
    let (p, _) = build_from_children(&[&b, &a], DVec2::ZERO, 64.0, 25.0, &opts).unwrap();
    assert_eq!(p.height_code(5, 5), 255);
    assert_eq!(&p.texel(32 + 5, 5)[..3], &RED);
    // (4, 4) holds B only: its decoded height is at least B's, and less than one level above.
    let hb = b.texel_height_m(9, 9).unwrap();
    let h44 = p.texel_height_m(4, 4).unwrap();
    assert!(h44 >= hb && h44 < hb + p.dz_m(), "{h44} vs {hb}");
    assert_eq!(&p.texel(32 + 4, 4)[..3], &BLUE);
}

#[test]
fn parent_edges_trim_the_dilation_and_keep_the_children() {
    // B's texel [9.5, 10.5]² covers only the upper-right sixteenth of parent texel (4, 4).
    let b = one_texel(DVec2::splat(0.5), 32.0, 20.0, (9, 9), 20.0, BLUE);
    let (p, st) = build_from_children(
        &[&b],
        DVec2::ZERO,
        64.0,
        20.0,
        &BuildOptions {
            k: 32,
            ..BuildOptions::default()
        },
    )
    .unwrap();
    assert_eq!(st.edge_texels, 4, "{st:?}");
    assert!(p.edge(4, 4).is_some());
    // Every point of the child's column is in the parent's, at least as high.
    for q in [(9.6, 9.6), (9.99, 9.51), (10.4, 10.4), (9.51, 10.49)] {
        let xy = DVec2::new(q.0, q.1);
        assert!(column_height(&p, xy) >= column_height(&b, xy), "{q:?}");
        assert!(column_height(&b, xy) >= 20.0 - 1e-9);
    }
    // The far corner of the parent texel is not filled.
    assert_eq!(column_height(&p, DVec2::new(8.2, 8.2)), 0.0);
    // Rejected inputs name the problem.
    assert!(matches!(
        build_from_children(&[&b], DVec2::ZERO, 64.0, 10.0, &BuildOptions::default()),
        Err(blockwalk::blockmap::BlockMapError::BadParameter(_))
    ));
    assert!("children".parse::<Parents>().unwrap() == Parents::Children);
    assert!(matches!(
        "kids".parse::<Parents>(),
        Err(blockwalk::blockmap::BlockMapError::BadParameter(_))
    ));
}

/// A child map with random heights and footprint edges over a random square.
fn random_child(seed: u64, fill: f64) -> BlockMap {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let side = rng.random_range(20.0..60.0);
    let min = DVec2::new(rng.random_range(0.0..50.0), rng.random_range(0.0..50.0));
    let zmax = rng.random_range(5.0..40.0);
    let mut m = BlockMap::empty(32, min.extend(0.0), side, zmax).unwrap();
    for j in 0..32 {
        for i in 0..32 {
            if rng.random_bool(fill) {
                m.texel_mut(i, j)[0] = rng.random_range(1..=255);
                if rng.random_bool(0.5) {
                    let e = [rng.random(), rng.random(), rng.random_range(9..=247u8)];
                    m.set_edge_bytes(i, j, Some(e));
                }
            }
        }
    }
    m
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Independent truth: at random points the parent's column is at least as high as every
    /// child's, and a parent texel is filled only where a child's column is.
    #[test]
    fn the_parent_holds_every_child(seeds in prop::collection::vec(0u64..10_000, 1..=4),
        fill in 0.05f64..0.6, k in prop::sample::select(vec![32u32, 64]), edges in any::<bool>()) {
        let kids: Vec<BlockMap> = seeds.iter().map(|&s| random_child(s, fill)).collect();
        let refs: Vec<&BlockMap> = kids.iter().collect();
        let zmax = kids.iter().map(|c| c.meta.zmax).fold(0.0, f64::max);
        // The parent's square: around the children's squares.
        let lo = kids.iter().fold(DVec2::splat(f64::INFINITY), |a, c| a.min(DVec2::new(c.meta.min[0], c.meta.min[1])));
        let hi = kids.iter().fold(DVec2::splat(f64::NEG_INFINITY), |a, c| a.max(DVec2::new(c.meta.min[0] + c.meta.side, c.meta.min[1] + c.meta.side)));
        let side = (hi - lo).max_element() * (1.0 + 1e-9);
        let (p, _) = build_from_children(&refs, lo, side, zmax, &BuildOptions { k, edges, ..BuildOptions::default() }).unwrap();
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seeds[0]);
        for _ in 0..2000 {
            let xy = lo + DVec2::new(rng.random_range(0.0..side), rng.random_range(0.0..side));
            let want = kids.iter().map(|c| column_height(c, xy)).fold(0.0, f64::max);
            prop_assert!(column_height(&p, xy) >= want, "at {:?}: parent {} < child {}", xy, column_height(&p, xy), want);
        }
        for j in 0..k {
            for i in 0..k {
                if p.height_code(i, j) == 0 {
                    continue;
                }
                // Some non-empty child texel's square overlaps the texel's interior (a sliver
                // counts: the filter is conservative).
                let s = p.texel_m();
                let t0 = lo + DVec2::new(i as f64, j as f64) * s;
                let t1 = t0 + DVec2::splat(s);
                let any = kids.iter().any(|c| {
                    let cs = c.texel_m();
                    (0..32u32).any(|cj| (0..32u32).any(|ci| {
                        let c0 = DVec2::new(c.meta.min[0] + ci as f64 * cs, c.meta.min[1] + cj as f64 * cs);
                        let c1 = c0 + DVec2::splat(cs);
                        c.height_code(ci, cj) > 0 && c0.x < t1.x && c1.x > t0.x && c0.y < t1.y && c1.y > t0.y
                    }))
                });
                prop_assert!(any, "texel ({}, {}) filled with no child under it", i, j);
            }
        }
    }
}

/// Both trees of a city (competitive stop, K = 64), checked against each other; returns the
/// printed figures' maxima `(agree_ratio, coverage polygons, coverage children)`.
fn both_ways(name: &str, city: &blockwalk::city::City, layout: &blockwalk::blocks::BlockLayout) {
    let meshes = extrude_city(city);
    let source = Source::new(city, layout, &meshes).unwrap();
    let bounds = block_bounds(city, layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    let build = |parents| -> MapTree {
        build_tree(
            &source,
            layout,
            &tree,
            &TreeOptions {
                build: BuildOptions::default(),
                stop: Stop::Competitive,
                parents,
            },
            &|_, _| {},
        )
        .unwrap()
    };
    let poly = build(Parents::Polygons);
    let kids = build(Parents::Children);
    kids.check_invariants();
    assert_eq!(poly.maps.len(), kids.maps.len());
    let inner = kids
        .maps
        .iter()
        .filter(|m| m.stats.from_children.is_some())
        .count();
    assert!(inner > 0, "{name}: no parent built from children");
    let (mut agree_max, mut cov_p, mut cov_c, mut cov_c_own) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (q, (p, c)) in poly.maps.iter().zip(&kids.maps).enumerate() {
        assert_eq!(p.key, c.key);
        assert_eq!(p.blocks, c.blocks);
        let Some(r) = &c.stats.from_children else {
            // Leaves are built from the polygons either way.
            assert_eq!(p.map.texels, c.map.texels, "{name} leaf {}", c.key);
            continue;
        };
        // Measured against the polygons, within the derived ε; declared = derived.
        assert!(
            !r.measured_over_derived && c.error.measured_m <= r.derived_eps_m,
            "{name} node {}: measured {} m > derived {} m ({r:?})",
            c.key,
            c.error.measured_m,
            r.derived_eps_m
        );
        assert!(c.map.meta.eps_m >= r.derived_eps_m);
        assert!(c.map.meta.eps_m >= c.error.measured_m);
        // The two parents agree within their ε, both ways (each is within its ε of the source).
        let (pc, cp) = (
            directed_distance(&p.map, &c.map),
            directed_distance(&c.map, &p.map),
        );
        let allowed = p.map.meta.eps_m + c.map.meta.eps_m;
        assert!(
            pc <= allowed && cp <= allowed,
            "{name} node {}: polygons→children {pc} m, children→polygons {cp} m, ε {} + {} m",
            c.key,
            p.map.meta.eps_m,
            c.map.meta.eps_m
        );
        agree_max = agree_max.max(pc.max(cp) / p.map.meta.eps_m.max(c.map.meta.eps_m));
        // Coverage error of one random view, the same camera for both (placed by the polygon
        // map's ε at 1 px), and the children's map at its own ε.
        let cam = random_views(&p.map, 1, q as u64, 90)[0];
        let vp = compare_view(&p.map, &source, &p.buildings, &cam, 160, 90);
        let vc = compare_view(&c.map, &source, &c.buildings, &cam, 160, 90);
        let own = random_views(&c.map, 1, q as u64, 90)[0];
        let vo = compare_view(&c.map, &source, &c.buildings, &own, 160, 90);
        // Hit points within ε of the source at the children's own ε.
        assert_eq!(vo.point_violations, 0, "{name} node {}: {vo:?}", c.key);
        eprintln!(
            "{name} node {:x} level {}: ε polygons {:.2} m (measured {:.2}), children {:.2} m (measured {:.2}, derived {:.2} = children {:.2} + resample max({:.2}, {:.2})); parents apart {pc:.2} / {cp:.2} m; coverage same view polygons {:.4}, children {:.4}; children at own ε {:.4}",
            c.key,
            c.level,
            p.map.meta.eps_m,
            p.error.measured_m,
            c.map.meta.eps_m,
            c.error.measured_m,
            r.derived_eps_m,
            r.child_eps_max_m,
            r.to_children_m,
            r.from_children_m,
            vp.coverage_error,
            vc.coverage_error,
            vo.coverage_error
        );
        cov_p = cov_p.max(vp.coverage_error);
        cov_c = cov_c.max(vc.coverage_error);
        cov_c_own = cov_c_own.max(vo.coverage_error);
    }
    eprintln!(
        "{name}: {} maps, {inner} built from children; parents apart at most {agree_max:.2} × the larger ε; coverage error max (same views) polygons {cov_p:.4}, children {cov_c:.4}; children at own ε {cov_c_own:.4}",
        kids.maps.len()
    );
}

#[test]
fn helsinki_parents_from_children_agree_within_eps() {
    let f = read_layer(&data("helsinki/buildings.shp"), &Theme::Buildings).unwrap();
    let s = read_layer(&data("helsinki/streets_blockclass.shp"), &Theme::Streets).unwrap();
    let city = build_city(&f, Some(&s), None, &CityOptions::default()).unwrap();
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    both_ways("Helsinki", &city, &layout);
}

#[test]
fn generated_parents_from_children_agree_within_eps() {
    let dir = tempfile::tempdir().unwrap();
    let g = generate_city(&GenerateParams {
        buildings: 1500,
        seed: 7,
        ..Default::default()
    })
    .unwrap();
    write_city(&g, dir.path()).unwrap();
    let f = read_layer(&dir.path().join("buildings.shp"), &Theme::Buildings).unwrap();
    let s = read_layer(&dir.path().join("streets.shp"), &Theme::Streets).unwrap();
    let city = build_city(&f, Some(&s), None, &CityOptions::default()).unwrap();
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    both_ways("generated 1.5k seed 7", &city, &layout);
}

#[test]
fn children_maps_are_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let g = generate_city(&GenerateParams {
        buildings: 400,
        seed: 3,
        ..Default::default()
    })
    .unwrap();
    write_city(&g, dir.path()).unwrap();
    let f = read_layer(&dir.path().join("buildings.shp"), &Theme::Buildings).unwrap();
    let city = build_city(&f, None, None, &CityOptions::default()).unwrap();
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    let meshes = extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    let opts = TreeOptions {
        build: BuildOptions {
            ..BuildOptions::default()
        },
        parents: Parents::Children,
        stop: Stop::Levels(3),
    };
    let a = build_tree(&source, &layout, &tree, &opts, &|_, _| {}).unwrap();
    let b = build_tree(&source, &layout, &tree, &opts, &|_, _| {}).unwrap();
    assert!(a.maps.iter().any(|m| m.stats.from_children.is_some()));
    for (x, y) in a.maps.iter().zip(&b.maps) {
        assert_eq!(x.map, y.map);
    }
    let _ = DVec3::ZERO;
}
