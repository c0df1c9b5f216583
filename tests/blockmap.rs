//! BlockMaps end to end: the f32 caster against its f64 twin (proptest), PNG round trip, the
//! error bound on the bundled real data, and ray-cast images against the oracle's mesh images.

use blockwalk::blockmap::cast::{cast_f32, cast_f64, surface, CastOptions, Hit, TexRay};
use blockwalk::blockmap::compare::{compare_view, random_views};
use blockwalk::blockmap::{
    build_map, build_tree, BlockMap, BuildOptions, Source, Stop, TreeOptions,
};
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions as CityOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::importers::{read_layer, Theme};
use blockwalk::index::{block_bounds, BqrParams, BqrTree};
use blockwalk::visibility::synthetic::SyntheticCity;
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(rel)
}

/// A map with random heights: `fill` of the texels non-empty, some at the top level 255.
fn random_map(k: u32, seed: u64, fill: f64, slices: u32) -> BlockMap {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut m = BlockMap::empty(k, DVec3::new(-37.0, 12.0, 0.0), 250.0, 60.0).unwrap();
    m.meta.slices = slices;
    for j in 0..k {
        for i in 0..k {
            if rng.random_bool(fill) {
                let code = if rng.random_bool(0.1) {
                    255
                } else {
                    rng.random_range(1..=255)
                };
                let t = m.texel_mut(i, j);
                t[0] = code;
                t[1] = rng.random_range(0..=255);
                let c = m.texel_mut(2 * k + (i * 7 + j) % 255, j);
                *c = [rng.random(), rng.random(), rng.random(), 255];
            }
        }
    }
    m
}

/// f32 and f64 casts agree exactly unless the twin names a tie.
fn agree(m: &BlockMap, r: &TexRay<f64>, leap: bool) -> Result<bool, TestCaseError> {
    let dm = m.distance_map();
    let opts = CastOptions {
        leap: leap.then_some(&dm[..]),
    };
    let a = cast_f32(m, &r.to_f32(), &opts);
    let b = cast_f64(m, r, &opts);
    if b.is_tie(1e-4) {
        return Ok(false);
    }
    match (a.hit, b.hit) {
        (Hit::Miss, Hit::Miss) => {}
        (
            Hit::Roof { i, j, t },
            Hit::Roof {
                i: i2,
                j: j2,
                t: t2,
            },
        ) => {
            prop_assert_eq!((i, j), (i2, j2));
            prop_assert!((t - t2).abs() <= 1e-4 * (1.0 + t2.abs()), "{} vs {}", t, t2);
        }
        (
            Hit::Wall { i, j, face, t },
            Hit::Wall {
                i: i2,
                j: j2,
                face: f2,
                t: t2,
            },
        ) => {
            prop_assert_eq!((i, j, face), (i2, j2, f2));
            prop_assert!((t - t2).abs() <= 1e-4 * (1.0 + t2.abs()), "{} vs {}", t, t2);
        }
        (x, y) => prop_assert!(false, "f32 {:?} vs f64 {:?} (margin {})", x, y, b.margin),
    }
    if b.hit != Hit::Miss {
        prop_assert_eq!(
            surface(m, r, &a.hit).map(|s| s.color),
            surface(m, r, &b.hit).map(|s| s.color)
        );
    }
    Ok(true)
}

fn ray(m: &BlockMap, o: DVec3, d: DVec3) -> TexRay<f64> {
    m.tex_ray(o, d.normalize())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn caster_f32_equals_f64_twin_general(seed in 0u64..1000, k in prop::sample::select(vec![32u32, 64, 128]),
        fill in 0.0f64..0.9, ox in -300.0f64..500.0, oy in -300.0f64..500.0, oz in 1.0f64..400.0,
        tx in 0.0f64..1.0, ty in 0.0f64..1.0, tz in 0.0f64..1.0, leap in any::<bool>()) {
        let m = random_map(k, seed, fill, 1);
        let b = m.aabb();
        let target = b.min + (b.max - b.min) * DVec3::new(tx, ty, tz);
        let o = DVec3::new(ox, oy, oz);
        agree(&m, &ray(&m, o, target - o), leap)?;
    }

    #[test]
    fn caster_axis_aligned_and_vertical(seed in 0u64..1000, fill in 0.0f64..0.9,
        x in -36.9f64..212.9, y in 12.1f64..261.9, z in 0.0f64..80.0, axis in 0usize..6) {
        let m = random_map(64, seed, fill, 1);
        let d = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::NEG_Z, DVec3::Z][axis];
        let o = DVec3::new(x, y, z) - d * 400.0;
        agree(&m, &ray(&m, o, d), false)?;
        agree(&m, &ray(&m, o, d), true)?;
    }

    #[test]
    fn caster_grazing_rays_cross_about_2k_cells(seed in 0u64..1000, k in prop::sample::select(vec![32u32, 64]),
        a in 0.05f64..1.5, z in 0.3f64..1.0, dz in -0.002f64..0.0) {
        // Low fill so that long walks happen; diagonal rays at a shallow angle across the box.
        let m = random_map(k, seed, 0.02, 1);
        let b = m.aabb();
        let o = DVec3::new(b.min.x - 1.0, b.min.y + (b.max.y - b.min.y) * (a / 1.5) * 0.2, z * 60.0);
        let d = DVec3::new(1.0, a, dz);
        let r = ray(&m, o, d);
        agree(&m, &r, false)?;
        let c = cast_f64(&m, &r, &CastOptions::default());
        prop_assert!(c.steps <= 2 * k, "{} steps", c.steps);
    }

    #[test]
    fn caster_eye_inside_the_box(seed in 0u64..1000, fill in 0.0f64..0.5,
        x in 0.0f64..1.0, y in 0.0f64..1.0, z in 0.0f64..1.0, dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0) {
        let m = random_map(64, seed, fill, 1);
        let b = m.aabb();
        let o = b.min + (b.max - b.min) * DVec3::new(x, y, z);
        let d = DVec3::new(dx, dy, dz);
        prop_assume!(d.length() > 1e-3);
        agree(&m, &ray(&m, o, d), false)?;
    }

    #[test]
    fn caster_overflowed_slices_read_the_right_rows(seed in 0u64..1000, slices in prop::sample::select(vec![2u32, 4, 8, 16, 32]),
        ox in -300.0f64..500.0, oy in -300.0f64..500.0, oz in 1.0f64..200.0, tx in 0.0f64..1.0, ty in 0.0f64..1.0) {
        let m = random_map(64, seed, 0.5, slices);
        let b = m.aabb();
        let target = b.min + (b.max - b.min) * DVec3::new(tx, ty, 0.3);
        let o = DVec3::new(ox, oy, oz);
        agree(&m, &ray(&m, o, target - o), false)?;
    }
}

#[test]
fn ties_are_rare_and_every_non_tie_agrees() {
    // The twin may only excuse a small share of rays: otherwise the comparison above says little.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let (mut ties, mut n, mut hits) = (0, 0, 0);
    for seed in 0..20 {
        let m = random_map(64, seed, 0.4, 1);
        let b = m.aabb();
        for _ in 0..2000 {
            let o = DVec3::new(
                rng.random_range(-300.0..500.0),
                rng.random_range(-300.0..500.0),
                rng.random_range(1.0..300.0),
            );
            let t = b.min + (b.max - b.min) * DVec3::new(rng.random(), rng.random(), rng.random());
            let r = ray(&m, o, t - o);
            n += 1;
            let c = cast_f64(&m, &r, &CastOptions::default());
            hits += usize::from(c.hit != Hit::Miss);
            if c.is_tie(1e-4) {
                ties += 1;
                continue;
            }
            let a = cast_f32(&m, &r.to_f32(), &CastOptions::default());
            assert_eq!(a.hit.texel(), c.hit.texel(), "{r:?}");
        }
    }
    eprintln!("{ties} ties, {hits} hits in {n} rays");
    assert!(hits > n / 4, "{hits} hits of {n}");
    assert!((ties as f64) < 0.02 * n as f64, "{ties} ties of {n}");
}

#[test]
fn empty_map_misses_everything_and_a_top_level_tower_is_hit() {
    let m = random_map(64, 1, 0.0, 1);
    for (o, d) in [
        (DVec3::new(-100.0, 50.0, 30.0), DVec3::X),
        (DVec3::new(50.0, 50.0, 300.0), DVec3::NEG_Z),
        (DVec3::new(0.0, 20.0, 0.5), DVec3::new(1.0, 1.0, 0.0)),
    ] {
        let r = ray(&m, o, d);
        assert_eq!(cast_f64(&m, &r, &CastOptions::default()).hit, Hit::Miss);
        assert_eq!(
            cast_f32(&m, &r.to_f32(), &CastOptions::default()).hit,
            Hit::Miss
        );
    }
    let mut t = BlockMap::empty(64, DVec3::ZERO, 64.0, 100.0).unwrap();
    t.texel_mut(5, 5)[0] = 255;
    // Straight down onto the tower's top, which is the box's top: a roof hit at the box entry.
    let r = ray(&t, DVec3::new(5.5, 5.5, 150.0), DVec3::NEG_Z);
    let a = cast_f64(&t, &r, &CastOptions::default()).hit;
    let b = cast_f32(&t, &r.to_f32(), &CastOptions::default()).hit;
    assert!(
        matches!(a, Hit::Roof { i: 5, j: 5, t } if (t - 50.0).abs() < 1e-9),
        "{a:?}"
    );
    assert!(
        matches!(b, Hit::Roof { i: 5, j: 5, t } if (t - 50.0).abs() < 1e-4),
        "{b:?}"
    );
}

#[test]
fn png_round_trip_is_bit_exact() {
    let mut m = random_map(64, 7, 0.4, 4);
    m.meta.eps_m = 1.234_567_890_123;
    m.meta.node_key = 77;
    let dir = tempfile::tempdir().unwrap();
    let (png, _) = m.write(dir.path(), "m").unwrap();
    let back = BlockMap::read(&png).unwrap();
    assert_eq!(back, m);
    // A wrong size is refused, naming the file.
    let mut bad = m.clone();
    bad.meta.k = 32;
    std::fs::write(
        dir.path().join("m.json"),
        serde_json::to_string(&bad.meta).unwrap(),
    )
    .unwrap();
    match BlockMap::read(&png) {
        Err(blockwalk::blockmap::BlockMapError::BadFile { path, .. }) => assert_eq!(path, png),
        other => panic!("{other:?}"),
    }
}

#[test]
fn synthetic_city_maps_bound_holds_and_images_match() {
    let sc = SyntheticCity::generate(3, 3, 11, DVec2::new(5.0e5, 6.0e6));
    let meshes = extrude_city(&sc.city);
    let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
    let all: Vec<u32> = source.buildings_of(
        &sc.layout,
        &sc.layout.blocks.iter().map(|b| b.id).collect::<Vec<_>>(),
    );
    let (mut map, kept, stats) = build_map(&source, &all, &BuildOptions::default()).unwrap();
    let err = blockwalk::blockmap::measure(&map, &source, &kept);
    map.meta.eps_m = err.declared_m;
    assert!(stats.exposed_texels > 0 && stats.filled_texels > 0);
    assert!(err.raised_parts > 0, "the synthetic city has passages");
    assert!(
        err.thin
            .iter()
            .any(|t| t.kind == blockwalk::blockmap::ThinKind::RaisedPart),
        "raised parts must be reported: {:?}",
        err.thin
    );
    for cam in random_views(&map, 4, 3, 90) {
        let c = compare_view(&map, &source, &kept, &cam, 160, 90);
        eprintln!("{c:?}");
        assert!(c.eps_px <= 1.0 + 1e-9);
        assert_eq!(c.point_violations, 0, "{c:?}");
        assert!(c.coverage_error <= 0.01, "{c:?}");
        assert_eq!(c.beyond_bound, 0, "{c:?}");
    }
}

fn real_city(fp: &str, streets: &str) -> (blockwalk::city::City, blockwalk::blocks::BlockLayout) {
    let f = read_layer(&data(fp), &Theme::Buildings).unwrap();
    let s = read_layer(&data(streets), &Theme::Streets).unwrap();
    let city = build_city(&f, Some(&s), None, &CityOptions::default()).unwrap();
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    (city, layout)
}

#[test]
fn bound_never_violated_on_the_bundled_data() {
    for (fp, st) in [
        ("helsinki/buildings.shp", "helsinki/streets_blockclass.shp"),
        ("bubenec_utm33n/buildings.shp", "bubenec_utm33n/streets.shp"),
    ] {
        let (city, layout) = real_city(fp, st);
        let meshes = extrude_city(&city);
        let source = Source::new(&city, &layout, &meshes).unwrap();
        let bounds = block_bounds(&city, &layout);
        let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
        let maps = build_tree(
            &source,
            &layout,
            &tree,
            &TreeOptions {
                build: BuildOptions::default(),
                stop: Stop::Levels(3),
            },
            &|_, _| {},
        )
        .unwrap();
        maps.check_invariants();
        assert!(!maps.maps.is_empty());
        let mut worst_cov: f64 = 0.0;
        for (q, m) in maps.maps.iter().enumerate().filter(|(q, _)| q % 3 == 0) {
            assert!(m.map.meta.eps_m >= m.error.half_voxel_diagonal_m);
            assert!(m.map.meta.eps_m >= m.error.measured_m);
            let cam = random_views(&m.map, 1, q as u64, 90)[0];
            let c = compare_view(&m.map, &source, &m.buildings, &cam, 160, 90);
            eprintln!("{fp} node {} level {}: {c:?}", m.key, m.level);
            assert_eq!(c.point_violations, 0, "{fp} node {}: {c:?}", m.key);
            assert_eq!(c.beyond_bound, 0, "{fp} node {}: {c:?}", m.key);
            worst_cov = worst_cov.max(c.coverage_error);
        }
        assert!(worst_cov <= 0.01, "{fp}: coverage error {worst_cov}");
    }
}
