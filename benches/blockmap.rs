//! BlockMap construction figures (a plain main that prints them; no timing assertions): all maps
//! at K = 64 (seed 000 §4's competitive stop) of the 80,000-building generated city, of Helsinki,
//! and of Astana from `../shared/data/astana` when it is there; each without and with ambient
//! occlusion, and the distance-map leap against the plain grid walk.
//!
//! Group `parents` (`cargo bench --bench blockmap -- parents` runs it alone): the whole tree's
//! build time with inner nodes built from the polygons and from their children's maps
//! (`blockmap::children`), on Helsinki, the 20,000-building generated city of seed 7 and Astana,
//! with ε (declared, measured, derived) and the coverage error of one random view per map.
//!
//! `cargo bench --bench blockmap` (release). Prints maps, bytes (96 KiB per map at K = 64), MiB
//! per km² of the city's box, build seconds (construction + error measurement), ε, the AO cost
//! and effect, and the leap's steps and time per ray.

use blockwalk::blockmap::cast::{cast_f32, CastOptions, Hit};
use blockwalk::blockmap::children::{node_square, resample_distances};
use blockwalk::blockmap::compare::{compare_view, random_views};
use blockwalk::blockmap::compare::{pixel_ray, view_at};
use blockwalk::blockmap::{
    build_from_children, build_map, build_tree, measure, BlockMap, BuildOptions, MapTree, Parents,
    Source, Stop, TreeOptions,
};
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions as CityOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::importers::{read_layer, Layer, Theme};
use blockwalk::index::{block_bounds, BqrParams, BqrTree};
use std::path::PathBuf;
use std::time::Instant;

fn run(name: &str, fp: &Layer, st: Option<&Layer>) {
    if std::env::args().any(|a| a == "parents") {
        return parents(name, fp, st);
    }
    let city = build_city(fp, st, None, &CityOptions::default()).expect("city");
    let layout = detect(&city, &BlockOptions::default()).expect("blocks");
    let meshes = extrude_city(&city);
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).expect("bqr");
    let source = Source::new(&city, &layout, &meshes).expect("source");
    let b = bounds
        .iter()
        .fold(blockwalk::geom::Aabb3::EMPTY, |a, b| a.union(b.aabb));
    let km2 = b.extent().x * b.extent().y / 1e6;
    let mut plain_s = 0.0;
    for (stop, ao) in [(Stop::Competitive, false), (Stop::Competitive, true)] {
        let t = Instant::now();
        let maps = build_tree(
            &source,
            &layout,
            &tree,
            &TreeOptions {
                build: BuildOptions {
                    ao,
                    ..BuildOptions::default()
                },
                stop,
                ..TreeOptions::default()
            },
            &|_, _| {},
        )
        .expect("maps");
        let s = t.elapsed().as_secs_f64();
        let bytes: usize = maps.maps.iter().map(|m| m.map.bytes()).sum();
        let eps = maps
            .maps
            .iter()
            .map(|m| m.map.meta.eps_m)
            .fold(0.0, f64::max);
        let thin: usize = maps.maps.iter().map(|m| m.error.thin.len()).sum();
        println!(
            "{name}: {} buildings, {} blocks, {km2:.2} km²; stop {stop:?}, AO {ao}: {} maps, {} KiB each, {:.1} MiB, {:.2} MiB/km², built in {s:.2} s ({:.1} ms/map), ε max {eps:.2} m, {thin} thin features",
            city.buildings.len(),
            layout.blocks.len(),
            maps.maps.len(),
            maps.maps.first().map(|m| m.map.bytes() / 1024).unwrap_or(0),
            bytes as f64 / 1048576.0,
            bytes as f64 / 1048576.0 / km2.max(1e-9),
            1e3 * s / maps.maps.len().max(1) as f64,
        );
        if !ao {
            plain_s = s;
            leap_figures(name, &maps);
        } else {
            let st: Vec<_> = maps
                .maps
                .iter()
                .filter_map(|m| m.stats.ao.clone())
                .collect();
            let n = st.len().max(1) as f64;
            println!(
                "{name}: AO costs {:.2} s ({:+.0} %); mean openness roofs {:.3}, ground {:.3}, walls {:.3}; {:.1} % of texels below 0.9",
                s - plain_s,
                100.0 * (s - plain_s) / plain_s.max(1e-9),
                st.iter().map(|a| a.roof_mean).sum::<f64>() / n,
                st.iter().map(|a| a.ground_mean).sum::<f64>() / n,
                st.iter().map(|a| a.wall_mean).sum::<f64>() / n,
                100.0 * st.iter().map(|a| a.occluded_share).sum::<f64>() / n,
            );
        }
    }
}

/// The whole tree (competitive stop, K = 64) built both ways: seconds (construction and error
/// measurement, plus the resampling distances for children), ε, and the coverage error of one
/// random view per map (160×90; the same camera for both, placed by the polygon map's ε).
fn parents(name: &str, fp: &Layer, st: Option<&Layer>) {
    let city = build_city(fp, st, None, &CityOptions::default()).expect("city");
    let layout = detect(&city, &BlockOptions::default()).expect("blocks");
    let meshes = extrude_city(&city);
    let bounds = block_bounds(&city, &layout);
    let tree = BqrTree::build(&bounds, &BqrParams::default()).expect("bqr");
    let source = Source::new(&city, &layout, &meshes).expect("source");
    let mut trees = Vec::new();
    for parents in [Parents::Polygons, Parents::Children] {
        let t = Instant::now();
        let maps = build_tree(
            &source,
            &layout,
            &tree,
            &TreeOptions {
                build: BuildOptions::default(),
                stop: Stop::Competitive,
                parents,
            },
            &|_, _| {},
        )
        .expect("maps");
        let s = t.elapsed().as_secs_f64();
        let slots: std::collections::HashSet<usize> =
            maps.maps.iter().filter_map(|m| m.parent).collect();
        let inner: Vec<_> = maps
            .maps
            .iter()
            .enumerate()
            .filter(|(i, _)| slots.contains(i))
            .map(|(_, m)| m)
            .collect();
        let fmax = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0, f64::max);
        println!(
            "{name}: parents from {parents:?}: {} maps ({} inner), tree built in {s:.2} s; inner ε declared max {:.2} m, measured max {:.2} m, derived max {:.2} m, {} measured above derived",
            maps.maps.len(),
            inner.len(),
            fmax(&mut inner.iter().map(|m| m.map.meta.eps_m)),
            fmax(&mut inner.iter().map(|m| m.error.measured_m)),
            fmax(&mut maps.maps.iter().filter_map(|m| m.stats.from_children.as_ref()).map(|r| r.derived_eps_m)),
            maps.maps.iter().filter_map(|m| m.stats.from_children.as_ref()).filter(|r| r.measured_over_derived).count(),
        );
        trees.push(maps);
    }
    let (poly, kids) = (&trees[0], &trees[1]);
    // Where the time goes, per inner map, one at a time: polygon construction and its
    // measurement against the resample from the kept children's maps (kids without a map, built
    // from the polygons first in the tree, left out here), the resampling distances and the
    // measurement of the result.
    let mut t = [0.0f64; 5];
    let opts = BuildOptions::default();
    for (q, c) in kids.maps.iter().enumerate() {
        if c.stats.from_children.is_none() {
            continue;
        }
        let clock = Instant::now();
        let (pm, kept, _) = build_map(&source, &c.buildings, &opts).expect("map");
        t[0] += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        std::hint::black_box(measure(&pm, &source, &kept));
        t[1] += clock.elapsed().as_secs_f64();
        let under: Vec<&BlockMap> = kids
            .maps
            .iter()
            .filter(|m| m.parent == Some(q))
            .map(|m| &m.map)
            .collect();
        let (min, side, zmax) = node_square(&source, &c.buildings).expect("square");
        let clock = Instant::now();
        let (cm, _) = build_from_children(&under, min, side, zmax, &opts).expect("resample");
        t[2] += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        std::hint::black_box(resample_distances(&cm, &under));
        t[3] += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        std::hint::black_box(measure(&cm, &source, &c.buildings));
        t[4] += clock.elapsed().as_secs_f64();
    }
    println!(
        "{name}: inner maps one at a time: polygons build {:.3} s + measure {:.3} s; children resample {:.3} s + resampling distances {:.3} s + measure {:.3} s",
        t[0], t[1], t[2], t[3], t[4]
    );
    let mut cov = [Vec::new(), Vec::new()];
    for (q, (p, c)) in poly.maps.iter().zip(&kids.maps).enumerate() {
        if c.stats.from_children.is_none() {
            continue;
        }
        let cam = random_views(&p.map, 1, q as u64, 90)[0];
        cov[0].push(compare_view(&p.map, &source, &p.buildings, &cam, 160, 90).coverage_error);
        cov[1].push(compare_view(&c.map, &source, &c.buildings, &cam, 160, 90).coverage_error);
    }
    let stat = |v: &[f64]| {
        (
            v.iter().sum::<f64>() / v.len().max(1) as f64,
            v.iter().copied().fold(0.0, f64::max),
        )
    };
    let ((pm, px), (cm, cx)) = (stat(&cov[0]), stat(&cov[1]));
    println!(
        "{name}: coverage error of one view per inner map ({} maps, same camera): polygons mean {:.4} max {:.4}, children mean {:.4} max {:.4}",
        cov[0].len(),
        pm,
        px,
        cm,
        cx
    );
}

/// The distance-map leap (seed 000 §3.2) against the plain grid walk (seed 002 §4.2.2): the
/// f32 caster over every pixel of one view per map (up to 64 maps spread over the tree,
/// 320×180, projected error 8 px), mean steps and time per ray entering the box, and hits
/// compared.
fn leap_figures(name: &str, maps: &MapTree) {
    let n = maps.maps.len().min(64);
    let (w, h) = (320u32, 180u32);
    let mut rays = Vec::new();
    let mut picked = Vec::new();
    for q in 0..n {
        let m = &maps.maps[q * maps.maps.len() / n];
        // Nearer than the 1 px views of the checks (projected error 8 px), so that the map
        // spans much of the image; elevations 10°–40°, where rays run long over the map.
        let az = (m.key % 360) as f64;
        let el = 10.0 + (m.key % 31) as f64;
        let cam = view_at(&m.map, az.to_radians(), el.to_radians(), h, 8.0);
        let dm = m.map.distance_map();
        let mut rs = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let (o, d) = pixel_ray(&cam, x, y, w, h);
                rs.push(m.map.tex_ray(o, d).to_f32());
            }
        }
        rays.push(rs);
        picked.push((m, dm));
    }
    let mut times = [0.0f64; 2];
    let mut steps = [0u64; 2];
    let mut hits = [0u64; 2];
    let mut entering = [0u64; 2];
    let mut differ = 0u64;
    let mut total = 0u64;
    let mut results: Vec<Vec<Hit>> = Vec::new();
    for (mode, leap) in [false, true].into_iter().enumerate() {
        let t = Instant::now();
        for ((m, dm), rs) in picked.iter().zip(&rays) {
            let opts = CastOptions {
                leap: leap.then_some(&dm[..]),
            };
            let mut out = Vec::with_capacity(rs.len());
            for r in rs {
                let c = cast_f32(&m.map, r, &opts);
                if c.steps > 0 {
                    entering[mode] += 1;
                }
                steps[mode] += c.steps as u64;
                hits[mode] += u64::from(c.hit != Hit::Miss);
                out.push(c.hit);
            }
            results.push(out);
        }
        times[mode] = t.elapsed().as_secs_f64();
    }
    for q in 0..picked.len() {
        for (a, b) in results[q].iter().zip(&results[picked.len() + q]) {
            total += 1;
            differ += u64::from(a.texel() != b.texel());
        }
    }
    // Per ray that enters the box (the others cost the slab test only).
    let rays_n = entering[0].max(1) as f64;
    println!(
        "{name}: leap over {} maps, {} rays ({} entering the box): mean steps per entering ray {:.2} plain vs {:.2} with the leap ({:.1} % saved), {:.1} vs {:.1} ns per entering ray, hits {} vs {}, {} rays with another texel",
        picked.len(),
        total,
        entering[0],
        steps[0] as f64 / rays_n,
        steps[1] as f64 / rays_n,
        100.0 * (1.0 - steps[1] as f64 / steps[0].max(1) as f64),
        1e9 * times[0] / rays_n,
        1e9 * times[1] / rays_n,
        hits[0],
        hits[1],
        differ,
    );
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let (n, seed, name) = if std::env::args().any(|a| a == "parents") {
        // The 20,000-building city of seed 7 (as `blockwalk generate` writes it).
        (20_000, 7, "generated 20k seed 7")
    } else {
        // 80,000 generated buildings.
        (80_000, 1, "generated 80k")
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let gen = generate_city(&GenerateParams {
        buildings: n,
        seed,
        ..Default::default()
    })
    .expect("generate");
    write_city(&gen, dir.path()).expect("write");
    let fp = read_layer(&dir.path().join("buildings.shp"), &Theme::Buildings).expect("read");
    let st = read_layer(&dir.path().join("streets.shp"), &Theme::Streets).ok();
    run(name, &fp, st.as_ref());
    // Helsinki.
    let h = root.join("data/helsinki");
    let fp = read_layer(&h.join("buildings.shp"), &Theme::Buildings).expect("helsinki");
    let st = read_layer(&h.join("streets_blockclass.shp"), &Theme::Streets).ok();
    run("Helsinki", &fp, st.as_ref());
    // Astana, when the shared data is there.
    // `$BLOCKWALK_ASTANA` when set (as in `tests/blocks_conformance.rs`).
    let a = std::env::var_os("BLOCKWALK_ASTANA")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("../shared/data/astana"));
    match std::fs::read_dir(&a) {
        Ok(entries) => {
            let mut files: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
            files.sort();
            let pick = |words: &[&str]| {
                files
                    .iter()
                    .find(|p| {
                        let n = p
                            .file_name()
                            .and_then(|n| n.to_str())
                            .unwrap_or("")
                            .to_lowercase();
                        words.iter().any(|w| n.contains(w))
                            && ["shp", "geojson", "gpkg", "pbf"]
                                .iter()
                                .any(|e| n.ends_with(e))
                    })
                    .cloned()
            };
            match pick(&["building"]) {
                Some(fp) => {
                    let fp = read_layer(&fp, &Theme::Buildings).expect("astana buildings");
                    let st = pick(&["street", "road", "highway"])
                        .and_then(|p| read_layer(&p, &Theme::Streets).ok());
                    run("Astana", &fp, st.as_ref());
                }
                None => println!("Astana: no building file in {}", a.display()),
            }
        }
        Err(_) => println!("Astana: absent ({} not found)", a.display()),
    }
}
