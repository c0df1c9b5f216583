//! Import + extrusion of a generated city (5,000 buildings): Shapefile read, repair and heights
//! (`build_city`), extrusion, and the glTF export. The 80,000-building figure comes from
//! `blockwalk import --json` on `blockwalk generate --buildings 80000`.
//!
//! Indicative figures (release build, seed 1, 80,000 buildings, on a busy 2-core machine):
//! generate 0.91 s + write 0.60 s; import 1.73 s, extrusion 4.23 s, 4,042,800 triangles
//! (50.5 per building), 0 footprints repaired, peak memory 0.41 GB.
use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::export::glb_bytes;
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::importers::{read_layer, Theme};
use criterion::{criterion_group, criterion_main, Criterion};

fn import(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("tempdir");
    let params = GenerateParams {
        buildings: 5000,
        seed: 1,
        ..Default::default()
    };
    let gen = generate_city(&params).expect("generate");
    write_city(&gen, dir.path()).expect("write");
    let shp = dir.path().join("buildings.shp");
    let layer = read_layer(&shp, &Theme::Buildings).expect("read");
    let opts = BuildOptions::default();
    let city = build_city(&layer, None, None, &opts).expect("build");
    let meshes = extrude_city(&city);

    let mut g = c.benchmark_group("import_5k");
    g.sample_size(10);
    g.bench_function("generate", |b| b.iter(|| generate_city(&params).unwrap()));
    g.bench_function("read_shapefile", |b| {
        b.iter(|| read_layer(&shp, &Theme::Buildings).unwrap())
    });
    g.bench_function("build_city", |b| {
        b.iter(|| build_city(&layer, None, None, &opts).unwrap())
    });
    g.bench_function("extrude", |b| b.iter(|| extrude_city(&city)));
    g.bench_function("read_build_extrude", |b| {
        b.iter(|| {
            let l = read_layer(&shp, &Theme::Buildings).unwrap();
            let c = build_city(&l, None, None, &opts).unwrap();
            extrude_city(&c)
        })
    });
    g.bench_function("glb_export", |b| {
        b.iter(|| glb_bytes(&city, &meshes).unwrap())
    });
    g.finish();
}

criterion_group!(benches, import);
criterion_main!(benches);
