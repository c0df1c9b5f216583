//! Occlusion culling on the bundled Helsinki data (footprints extruded, blocks from the street
//! layer): no block the oracle sees may be culled.

use blockwalk::blocks::{detect, BlockId, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::extrude::extrude_building;
use blockwalk::city::Mesh;
use blockwalk::importers::{read_layer, Theme};
use blockwalk::index::{build_by_name, CityIndex};
use blockwalk::visibility::bench::{
    block_bounds, run_occlusion_bench, BenchOptions, BenchScene, ListIndex,
};
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(rel)
}

#[test]
fn helsinki_no_false_culls() {
    let fp = read_layer(&data("helsinki/buildings.shp"), &Theme::Any).unwrap();
    let st = read_layer(&data("helsinki/streets_blockclass.shp"), &Theme::Any).unwrap();
    let city = build_city(&fp, Some(&st), None, &BuildOptions::default()).unwrap();
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    // One mesh per block: its buildings' prisms.
    let mut meshes: Vec<(BlockId, Mesh)> = Vec::new();
    for block in &layout.blocks {
        let mut m = Mesh::default();
        for b in &block.buildings {
            let part = extrude_building(&city.buildings[b.0 as usize], &city.frame);
            let base = m.positions.len() as u32;
            m.positions.extend_from_slice(&part.positions);
            m.normals.extend_from_slice(&part.normals);
            m.indices.extend(part.indices.iter().map(|k| k + base));
        }
        meshes.push((block.id, m));
    }
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(id, m)| (*id, m)).collect();
    let list = ListIndex::new(block_bounds(&city, &layout, &refs));
    let bqr = build_by_name("bqr", &blockwalk::index::block_bounds(&city, &layout)).unwrap();
    let opts = BenchOptions {
        resolutions: vec![64, 256, 1024],
        views: 60,
        street_fraction: 0.75,
        seed: 5,
        oracle_size: (480, 270),
        ..Default::default()
    };
    for (name, index) in [("list", &list as &dyn CityIndex), ("bqr", bqr.as_ref())] {
        let scene = BenchScene {
            city: &city,
            layout: &layout,
            meshes: &refs,
            index,
        };
        let r = run_occlusion_bench(&scene, &opts, &mut |_, _| {}).unwrap();
        eprintln!(
            "index {name}: {}",
            serde_json::to_string_pretty(&r).unwrap()
        );
        assert_eq!(r.views, 60);
        for res in &r.resolutions {
            assert_eq!(res.false_culls, 0, "{name}: {:?}", r.false_cull_examples);
        }
        // The oracle sees something in most views (the views really are inside the city).
        assert!(r.mean_visible > 1.0, "{r:?}");
    }
}
