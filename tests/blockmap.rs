//! BlockMaps end to end: the f32 caster against its f64 twin (proptest), PNG round trip, the
//! error bound on the bundled real data, and ray-cast images against the oracle's mesh images.

mod support;
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
use support::data::data;

/// A map with random heights: `fill` of the texels non-empty, some at the top level 255, and
/// half of the non-empty ones with a random footprint edge (a half-plane through the texel).
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
                if rng.random_bool(0.5) {
                    // Offsets within ±0.7 texel: the line crosses the square or just misses it.
                    let e = [rng.random(), rng.random(), rng.random_range(9..=247u8)];
                    m.set_edge_bytes(i, j, Some(e));
                }
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
    // 256 compared cases each; ties (a margin under 1e-4 anywhere on the walk) are rejected. On
    // the sparse maps of the leap test about three rays in four are ties (a leap lands D − 1
    // texels on, often on a grid line): counted and bounded in
    // `leap_ties_are_counted_and_bounded`, and the reason for the larger reject limit.
    #![proptest_config(ProptestConfig { cases: 256, max_global_rejects: 16_384, ..ProptestConfig::default() })]

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

    #[test]
    fn leap_gives_the_hits_of_the_plain_walk(seed in 0u64..1000, k in prop::sample::select(vec![32u32, 64, 128]),
        fill in 0.0f64..0.3, ox in -300.0f64..500.0, oy in -300.0f64..500.0, oz in 1.0f64..400.0,
        tx in 0.0f64..1.0, ty in 0.0f64..1.0, tz in 0.0f64..1.0, inside in any::<bool>()) {
        // Sparse maps, where leaps happen; the eye outside the box or inside it.
        let m = random_map(k, seed, fill * fill, 1);
        let dm = m.distance_map();
        let b = m.aabb();
        let target = b.min + (b.max - b.min) * DVec3::new(tx, ty, tz);
        let o = if inside {
            b.min + (b.max - b.min) * DVec3::new(ty, tz, tx)
        } else {
            DVec3::new(ox, oy, oz)
        };
        prop_assume!((target - o).length() > 1e-3);
        let r = ray(&m, o, target - o);
        let plain = cast_f64(&m, &r, &CastOptions::default());
        let leap = cast_f64(&m, &r, &CastOptions { leap: Some(&dm) });
        prop_assume!(!plain.is_tie(1e-4) && !leap.is_tie(1e-4));
        prop_assert_eq!(plain.hit.texel(), leap.hit.texel());
        prop_assert_eq!(std::mem::discriminant(&plain.hit), std::mem::discriminant(&leap.hit));
        if let (Hit::Wall { face: a, .. }, Hit::Wall { face: b, .. }) = (plain.hit, leap.hit) {
            prop_assert_eq!(a, b);
        }
        if let (Some(a), Some(b)) = (plain.hit.t(), leap.hit.t()) {
            prop_assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "{} vs {}", a, b);
        }
        prop_assert!(leap.steps <= plain.steps, "{} > {}", leap.steps, plain.steps);
        // The GPU's f32 walk with the leap gives the same hit as without it.
        let p32 = cast_f32(&m, &r.to_f32(), &CastOptions::default());
        let l32 = cast_f32(&m, &r.to_f32(), &CastOptions { leap: Some(&dm) });
        prop_assert_eq!(p32.hit.texel(), l32.hit.texel());
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

/// The leap test's rays (sparse maps, the eye outside the box or inside it), counted: ties of
/// the plain or the leaping walk apart, every other ray giving the same hit both ways. The
/// proptest above compares only non-ties; this bounds how many rays that leaves out.
#[test]
fn leap_ties_are_counted_and_bounded() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut n, mut ties, mut hits, mut leaps) = (0usize, 0usize, 0usize, 0usize);
    for seed in 0..30 {
        let k = [32u32, 64, 128][seed % 3];
        let fill: f64 = rng.random_range(0.0..0.3);
        let m = random_map(k, seed as u64, fill * fill, 1);
        let dm = m.distance_map();
        let b = m.aabb();
        for _ in 0..400 {
            let u = DVec3::new(rng.random(), rng.random(), rng.random());
            let target = b.min + (b.max - b.min) * u;
            let o = if rng.random_bool(0.5) {
                b.min + (b.max - b.min) * DVec3::new(u.y, u.z, u.x)
            } else {
                DVec3::new(
                    rng.random_range(-300.0..500.0),
                    rng.random_range(-300.0..500.0),
                    rng.random_range(1.0..400.0),
                )
            };
            if (target - o).length() <= 1e-3 {
                continue;
            }
            let r = ray(&m, o, target - o);
            let plain = cast_f64(&m, &r, &CastOptions::default());
            let leap = cast_f64(&m, &r, &CastOptions { leap: Some(&dm) });
            n += 1;
            leaps += usize::from(leap.steps < plain.steps);
            if plain.is_tie(1e-4) || leap.is_tie(1e-4) {
                ties += 1;
                continue;
            }
            hits += usize::from(plain.hit != Hit::Miss);
            assert_eq!(plain.hit.texel(), leap.hit.texel(), "{r:?}");
            let l32 = cast_f32(&m, &r.to_f32(), &CastOptions { leap: Some(&dm) });
            assert_eq!(l32.hit.texel(), leap.hit.texel(), "{r:?}");
        }
    }
    eprintln!("{ties} ties, {leaps} rays that leap, {hits} hits among the non-ties, {n} rays");
    assert!(leaps * 2 > n, "{leaps} of {n} rays leap");
    assert!(hits * 20 > n, "{hits} hits of {n}");
    // Measured: 8,918 ties in 12,000 rays (74.3 %), most of them leap landings on a grid line;
    // bound 76 %. The non-ties (3,082 rays, 914 hits) are compared above.
    assert!(ties * 100 <= 76 * n, "{ties} ties of {n}");
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

/// Every footprint point the whole-texel map covers lies in the kept part of a filled texel
/// (the edges are conservative), the edges cut the 2D mismatch against the footprints, and the
/// second half-planes cut it further without losing a footprint point one half-plane kept.
#[test]
fn edge_texels_hold_every_footprint_point_and_cut_the_excess() {
    use rand::{Rng, SeedableRng};
    let (city, layout) = real_city("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    let meshes = extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let blocks: Vec<_> = layout.blocks.iter().map(|b| b.id).collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut sum_two, mut sum_one, mut edge2_texels) = (0usize, 0usize, 0usize);
    for (k, take) in [(32u32, 8usize), (64, 3)] {
        // Maps of a few blocks each, so that texels are a few metres wide.
        for chunk in blocks.chunks(take).take(6) {
            let all = source.buildings_of(&layout, chunk);
            if all.is_empty() {
                continue;
            }
            let opts = BuildOptions {
                k,
                ..BuildOptions::default()
            };
            let (m, kept, st) = build_map(&source, &all, &opts).unwrap();
            let (whole, _, _) = build_map(
                &source,
                &all,
                &BuildOptions {
                    edges: false,
                    ..opts
                },
            )
            .unwrap();
            let (one, _, _) = build_map(
                &source,
                &all,
                &BuildOptions {
                    two_edges: false,
                    ..opts
                },
            )
            .unwrap();
            assert_eq!(one.edge2_texels(), 0);
            assert!(st.edge_texels > 0, "{st:?}");
            assert_eq!(st.edge_texels, m.edge_texels());
            assert_eq!(st.edge2_texels, m.edge2_texels());
            edge2_texels += st.edge2_texels;
            // The 2D cover of a map at `p` (kept part of a filled texel).
            let covers = |m: &BlockMap, p: DVec2| -> bool {
                let s = m.texel_m();
                let mn = m.meta.min;
                let (fx, fy) = ((p.x - mn[0]) / s, (p.y - mn[1]) / s);
                let (i, j) = (fx.floor(), fy.floor());
                if i < 0.0 || j < 0.0 || i >= k as f64 || j >= k as f64 {
                    return false;
                }
                let (i, j) = (i as u32, j as u32);
                if m.height_code(i, j) == 0 {
                    return false;
                }
                m.edges(i, j).iter().flatten().all(|e| {
                    let q = (fx - i as f64 - 0.5, fy - j as f64 - 0.5);
                    q.0 * e.n[0] as f64 + q.1 * e.n[1] as f64 <= e.o as f64
                })
            };
            let in_footprints = |p: DVec2| -> bool {
                kept.iter().any(|&b| {
                    let sb = source.buildings[b as usize].as_ref().unwrap();
                    p.x >= sb.min.x
                        && p.x <= sb.max.x
                        && p.y >= sb.min.y
                        && p.y <= sb.max.y
                        && even_odd(&sb.rings, p)
                })
            };
            // Uniform points over the map's square: footprint points must all be covered
            // wherever the whole-texel map covered them, and the edges must cut the 2D mismatch
            // by a third at least (on Helsinki 1.8–6.4×; what is left is mostly convex
            // corners, where one line cannot follow both edges).
            let (side, mn) = (m.meta.side, m.meta.min);
            let (mut inside_fp, mut mis_e, mut mis_w) = (0usize, 0usize, 0usize);
            let (mut missed, mut missed_w) = (0usize, 0usize);
            let mut mis_one = 0usize;
            for _ in 0..20_000 {
                let p = DVec2::new(
                    mn[0] + rng.random::<f64>() * side,
                    mn[1] + rng.random::<f64>() * side,
                );
                let f = in_footprints(p);
                let (e, w) = (covers(&m, p), covers(&whole, p));
                let o = covers(&one, p);
                mis_one += usize::from(o != f);
                if f {
                    inside_fp += 1;
                    // Nothing the one-edge map covered vanishes with two.
                    assert!(
                        e || !o,
                        "K = {k}: footprint point {p:?} is outside the two-edge columns"
                    );
                    // Nothing the whole-texel map covered vanishes.
                    assert!(
                        e || !w,
                        "K = {k}: footprint point {p:?} is outside the map's columns"
                    );
                    missed += usize::from(!e);
                    missed_w += usize::from(!w);
                }
                mis_e += usize::from(e != f);
                mis_w += usize::from(w != f);
            }
            eprintln!(
                "K = {k}: {inside_fp} footprint points ({missed} outside, whole texels \
                 {missed_w}), mismatch edges {mis_e}, whole {mis_w}"
            );
            // Footprint points left outside: only in texels that stay empty (a gap no line
            // cuts, or a sliver whose half-plane would add more than it covers).
            assert!(missed < missed_w, "{missed} vs {missed_w} of {inside_fp}");
            assert!(inside_fp > 100, "{inside_fp}");
            assert!(3 * mis_e < 2 * mis_w, "edges {mis_e}, whole texels {mis_w}");
            eprintln!("K = {k}: mismatch two edges {mis_e}, one edge {mis_one}");
            sum_two += mis_e;
            sum_one += mis_one;
        }
    }
    eprintln!(
        "mismatch with two edges {sum_two}, with one {sum_one}, {edge2_texels} texels with two"
    );
    assert!(edge2_texels > 0);
    assert!(sum_two < sum_one, "{sum_two} vs {sum_one}");
}

/// Even-odd point in rings (the builder's rule).
fn even_odd(rings: &[Vec<DVec2>], p: DVec2) -> bool {
    let mut inside = false;
    for ring in rings {
        let n = ring.len();
        let mut q = n - 1;
        for e in 0..n {
            let (a, c) = (ring[e], ring[q]);
            if (a.y > p.y) != (c.y > p.y) && p.x < (c.x - a.x) * (p.y - a.y) / (c.y - a.y) + a.x {
                inside = !inside;
            }
            q = e;
        }
    }
    inside
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
                // Every map the command builds by default (seed 000 §4's competitive stop).
                stop: Stop::Competitive,
                ..TreeOptions::default()
            },
            &|_, _| {},
        )
        .unwrap();
        maps.check_invariants();
        assert!(!maps.maps.is_empty());
        let mut worst_cov: f64 = 0.0;
        for (q, m) in maps.maps.iter().enumerate() {
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

#[test]
fn maps_are_deterministic_and_the_footprint_scan_matches_the_oracle() {
    let (city, layout) = real_city("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    let meshes = extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    let opts = TreeOptions {
        build: BuildOptions {
            ao: true,
            ..BuildOptions::default()
        },
        stop: Stop::Levels(3),
        ..TreeOptions::default()
    };
    let a = build_tree(&source, &layout, &tree, &opts, &|_, _| {}).unwrap();
    let b = build_tree(&source, &layout, &tree, &opts, &|_, _| {}).unwrap();
    assert_eq!(a.maps.len(), b.maps.len());
    for (x, y) in a.maps.iter().zip(&b.maps) {
        assert_eq!(x.map, y.map, "node {}", x.key);
        assert_eq!(x.error, y.error, "node {}", x.key);
    }
    // The footprint scan against the oracle's triangle rasteriser through the same orthographic
    // projection: the same owner at every texel centre that is not on an edge.
    use blockwalk::blockmap::build::{top_down_owners, SKY};
    use blockwalk::visibility::oracle::render_ids_clip;
    for m in a.maps.iter().take(6) {
        let k = m.map.k() as usize;
        let s = m.map.texel_m();
        let min = DVec2::new(m.map.meta.min[0], m.map.meta.min[1]);
        let side = m.map.meta.side;
        let bs: Vec<_> = m
            .buildings
            .iter()
            .filter_map(|&i| source.buildings[i as usize].as_ref())
            .collect();
        let scan = top_down_owners(&bs, min, s, k);
        let (ztop, zbot) = (m.map.meta.zmax + 1.0, -1.0);
        let clip = glam::DMat4::from_cols(
            glam::DVec4::new(2.0 / side, 0.0, 0.0, 0.0),
            glam::DVec4::new(0.0, -2.0 / side, 0.0, 0.0),
            glam::DVec4::new(0.0, 0.0, -1.0 / (ztop - zbot), 0.0),
            glam::DVec4::new(
                -2.0 * min.x / side - 1.0,
                2.0 * min.y / side + 1.0,
                ztop / (ztop - zbot),
                1.0,
            ),
        );
        let pairs: Vec<_> = bs
            .iter()
            .map(|b| (blockwalk::blocks::BlockId(b.id.0), &meshes[b.id.0 as usize]))
            .collect();
        let ids = render_ids_clip(&pairs, &clip, k as u32, k as u32).ids;
        let mut differ = 0;
        for t in 0..k * k {
            let (a, o) = (scan[t], ids[t]);
            if a == o {
                continue;
            }
            // Allowed only where the centre lies on (within 1e-6 m of) a footprint edge, or on
            // roofs of equal height (either may win).
            let c = min + DVec2::new((t % k) as f64 + 0.5, (t / k) as f64 + 0.5) * s;
            let near_edge = bs.iter().any(|b| {
                b.rings.iter().any(|r| {
                    (0..r.len()).any(|e| {
                        let (p, q) = (r[e], r[(e + 1) % r.len()]);
                        let d = q - p;
                        let u = ((c - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                        (p + d * u - c).length() < 1e-6
                    })
                })
            });
            let same_height = a != SKY
                && o != SKY
                && source.buildings[a as usize].as_ref().map(|b| b.z1)
                    == source.buildings[o as usize].as_ref().map(|b| b.z1);
            assert!(
                near_edge || same_height,
                "node {} texel {t}: scan {a} vs oracle {o}",
                m.key
            );
            differ += 1;
        }
        assert!(
            differ <= k * k / 100,
            "node {}: {differ} texels differ",
            m.key
        );
    }
}

#[test]
fn ambient_occlusion_darkens_only_the_a_channels() {
    let sc = SyntheticCity::generate(3, 3, 11, DVec2::new(5.0e5, 6.0e6));
    let meshes = extrude_city(&sc.city);
    let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
    let all: Vec<u32> = source.buildings_of(
        &sc.layout,
        &sc.layout.blocks.iter().map(|b| b.id).collect::<Vec<_>>(),
    );
    let (plain, _, ps) = build_map(&source, &all, &BuildOptions::default()).unwrap();
    let (ao, _, st) = build_map(
        &source,
        &all,
        &BuildOptions {
            ao: true,
            ..BuildOptions::default()
        },
    )
    .unwrap();
    assert!(ps.ao.is_none());
    let st = st.ao.expect("AO asked for");
    let k = plain.k();
    assert!((0..k).all(|j| (k..2 * k).all(|i| plain.texel(i, j)[3] == 255)));
    let mut darker = 0;
    for v in 0..k {
        for u in 0..plain.width() {
            let (p, a) = (plain.texel(u, v), ao.texel(u, v));
            assert_eq!(p[..3], a[..3], "texel ({u}, {v})");
            if u < k {
                assert_eq!(p[3], a[3], "the shape section is untouched at ({u}, {v})");
            } else {
                assert!(a[3] <= p[3]);
                darker += usize::from(a[3] < p[3]);
            }
        }
    }
    assert!(darker > 0);
    // Streets between blocks are darker than open roofs; walls darker than roofs.
    assert!(
        st.ground_mean < 1.0 && st.wall_mean < st.roof_mean,
        "{st:?}"
    );
    assert!(matches!(
        build_map(
            &source,
            &all,
            &BuildOptions {
                ao: true,
                ao_radius_m: f64::NAN,
                ..BuildOptions::default()
            }
        ),
        Err(blockwalk::blockmap::BlockMapError::BadParameter(_))
    ));
}

#[test]
fn scene_builds_the_maps_in_one_call() {
    use blockwalk::blockmap::CityMapsOptions;
    use blockwalk::scene::{CitySource, Scene, SceneOptions};
    let src = CitySource::parse(std::path::Path::new("synthetic:3x2"), None, None, &[], 7).unwrap();
    let scene = Scene::load(
        &src,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let maps = scene
        .blockmaps(
            &CityMapsOptions {
                tree: TreeOptions {
                    build: BuildOptions::default(),
                    stop: Stop::Levels(2),
                    ..TreeOptions::default()
                },
                checks: 2,
                check_size: (80, 45),
            },
            &|_, _| {},
        )
        .unwrap();
    assert!(!maps.maps.maps.is_empty());
    assert_eq!(maps.checks.len(), 2);
    let s = maps.summary();
    for key in [
        "maps",
        "bytes",
        "build_s",
        "eps_declared_max",
        "eps_measured_max",
        "bound_violations",
        "thin_features",
    ] {
        assert!(
            s.get(key).is_some_and(|v| !v.is_null()),
            "{key} missing: {s}"
        );
    }
    assert_eq!(s["maps"], maps.maps.maps.len());
    assert_eq!(s["bytes"], maps.maps.maps.len() * 128 * 1024);
}

#[test]
fn the_screen_space_check_catches_a_missing_building() {
    // Remove a large patch of a map's buildings: the mesh image still shows them, and the
    // pixels inside the patch lie far from every silhouette of either image.
    let sc = SyntheticCity::generate(3, 3, 11, DVec2::new(5.0e5, 6.0e6));
    let meshes = extrude_city(&sc.city);
    let source = Source::new(&sc.city, &sc.layout, &meshes).unwrap();
    let all: Vec<u32> = source.buildings_of(
        &sc.layout,
        &sc.layout.blocks.iter().map(|b| b.id).collect::<Vec<_>>(),
    );
    let (mut map, kept, _) = build_map(&source, &all, &BuildOptions::default()).unwrap();
    let err = blockwalk::blockmap::measure(&map, &source, &kept);
    map.meta.eps_m = err.declared_m;
    let cams = random_views(&map, 4, 3, 90);
    let k = map.k();
    for j in 0..k {
        for i in 0..k {
            map.texel_mut(i, j)[0] = 0;
        }
    }
    let beyond: usize = cams
        .iter()
        .map(|cam| compare_view(&map, &source, &kept, cam, 160, 90).beyond_bound)
        .sum();
    assert!(beyond > 0, "an emptied map must break the bound");
}

#[test]
fn buildings_the_map_does_not_hold_are_reported_as_vanished() {
    // Independent truth: a building none of whose nearby texels (its box grown by its own
    // height, so no map prism lies nearer than the ground below its roof) is filled has
    // vanished from the map, whatever its error; it must be reported with its id.
    let (city, layout) = real_city("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    let meshes = extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).unwrap();
    let maps = build_tree(
        &source,
        &layout,
        &tree,
        &TreeOptions {
            // Whole texels: with footprint edges every footprint lies inside a filled
            // texel's column, and nothing vanishes (see the edge test above).
            build: BuildOptions {
                edges: false,
                ..BuildOptions::default()
            },
            stop: Stop::Levels(2),
            ..TreeOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();
    let mut vanished_truth = 0;
    let mut reported_ok = 0;
    for m in &maps.maps {
        let s = m.map.texel_m();
        let o = m.map.meta.min;
        let reported: std::collections::HashSet<u32> = m
            .error
            .thin
            .iter()
            .filter(|t| t.kind == blockwalk::blockmap::ThinKind::Vanished)
            .map(|t| t.building)
            .collect();
        for &b in &m.buildings {
            let sb = source.buildings[b as usize].as_ref().unwrap();
            let grow = sb.z1;
            let idx = |v: f64, o: f64| ((v - o) / s).floor() as i64;
            let (i0, i1) = (idx(sb.min.x - grow, o[0]), idx(sb.max.x + grow, o[0]));
            let (j0, j1) = (idx(sb.min.y - grow, o[1]), idx(sb.max.y + grow, o[1]));
            let empty = (j0..=j1)
                .all(|j| (i0..=i1).all(|i| m.map.texel_height_m(i, j).unwrap_or(0.0) == 0.0));
            if empty {
                vanished_truth += 1;
                assert!(
                    reported.contains(&b),
                    "node {}: building {b} ({}) vanished but is not reported",
                    m.key,
                    sb.source_id
                );
            }
        }
        // Every report points at a place where the map holds nothing under the roof.
        for t in m
            .error
            .thin
            .iter()
            .filter(|t| t.kind == blockwalk::blockmap::ThinKind::Vanished)
        {
            let (i, j) = (
                ((t.at[0] - o[0]) / s).floor() as i64,
                ((t.at[1] - o[1]) / s).floor() as i64,
            );
            assert_eq!(m.map.texel_height_m(i, j).unwrap_or(0.0), 0.0, "{t:?}");
            reported_ok += 1;
        }
    }
    assert!(
        vanished_truth > 0,
        "no building vanished: the check is vacuous"
    );
    assert!(reported_ok >= vanished_truth);
    eprintln!("{vanished_truth} vanished buildings found by brute force, {reported_ok} reports");
}
