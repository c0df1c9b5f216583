//! BlockMap construction figures (a plain main that prints them; no timing assertions): all maps
//! at K = 64 (seed 000 §4's competitive stop, and `--levels 6`) of the 80,000-building generated
//! city, of Helsinki, and of Astana from `../shared/data/astana` when it is there.
//!
//! `cargo bench --bench blockmap` (release). Prints maps, bytes (96 KiB per map at K = 64), MiB
//! per km² of the city's box, build seconds (construction + error measurement), and ε.

use blockwalk::blockmap::{build_tree, BuildOptions, Source, Stop, TreeOptions};
use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions as CityOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::importers::{read_layer, Layer, Theme};
use blockwalk::index::{block_bounds, BqrParams, BqrTree};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn run(name: &str, fp: &Layer, st: Option<&Layer>) {
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
    for stop in [Stop::Competitive, Stop::Levels(6)] {
        let t = Instant::now();
        let maps = build_tree(
            &source,
            &layout,
            &tree,
            &TreeOptions {
                build: BuildOptions::default(),
                stop,
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
            "{name}: {} buildings, {} blocks, {km2:.2} km²; stop {stop:?}: {} maps, {} KiB each, {:.1} MiB, {:.2} MiB/km², built in {s:.2} s ({:.1} ms/map), ε max {eps:.2} m, {thin} thin features",
            city.buildings.len(),
            layout.blocks.len(),
            maps.maps.len(),
            maps.maps.first().map(|m| m.map.bytes() / 1024).unwrap_or(0),
            bytes as f64 / 1048576.0,
            bytes as f64 / 1048576.0 / km2.max(1e-9),
            1e3 * s / maps.maps.len().max(1) as f64,
        );
    }
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // 80,000 generated buildings.
    let dir = tempfile::tempdir().expect("tempdir");
    let gen = generate_city(&GenerateParams {
        buildings: 80_000,
        seed: 1,
        ..Default::default()
    })
    .expect("generate");
    write_city(&gen, dir.path()).expect("write");
    let fp = read_layer(&dir.path().join("buildings.shp"), &Theme::Buildings).expect("read");
    let st = read_layer(&dir.path().join("streets.shp"), &Theme::Streets).ok();
    run("generated 80k", &fp, st.as_ref());
    // Helsinki.
    let h = root.join("data/helsinki");
    let fp = read_layer(&h.join("buildings.shp"), &Theme::Buildings).expect("helsinki");
    let st = read_layer(&h.join("streets_blockclass.shp"), &Theme::Streets).ok();
    run("Helsinki", &fp, st.as_ref());
    // Astana, when the shared data is there.
    let a = root.join("../shared/data/astana");
    let a = if a.exists() {
        a
    } else {
        Path::new("/work/shared/data/astana").to_path_buf()
    };
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
