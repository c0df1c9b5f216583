//! Block bounds and structures on the bundled real data (Bubeneč, Helsinki): boxes hold the
//! extruded meshes, the triangle formula matches the extrusion, no false culls.

use blockwalk::blocks::{detect, BlockOptions};
use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::extrude::extrude_building;
use blockwalk::city::City;
use blockwalk::importers::{read_layer, Theme};
use blockwalk::index::bench::{run_cull_bench, CullBenchParams};
use blockwalk::index::{block_bounds, extruded_triangles, BlockBounds, BqrParams, BqrTree};
use blockwalk::index::{VamSplitParams, VamSplitTree};
use std::path::{Path, PathBuf};

fn data(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(p)
}

fn city_and_bounds(buildings: &str, streets: &str) -> (City, Vec<BlockBounds>) {
    let b = read_layer(&data(buildings), &Theme::Buildings).expect("read buildings");
    let s = read_layer(&data(streets), &Theme::Streets).expect("read streets");
    let city = build_city(&b, Some(&s), None, &BuildOptions::default()).expect("build city");
    let layout = detect(&city, &BlockOptions::default()).expect("detect blocks");
    let bounds = block_bounds(&city, &layout);
    assert_eq!(bounds.len(), layout.blocks.len());
    for (i, (bb, bl)) in bounds.iter().zip(&layout.blocks).enumerate() {
        assert_eq!(bb.id, bl.id);
        assert_eq!(bb.id.0 as usize, i);
        let mut tris = 0u64;
        for bid in &bl.buildings {
            let building = &city.buildings[bid.0 as usize];
            let mesh = extrude_building(building, &city.frame);
            tris += mesh.triangle_count() as u64;
            for p in &mesh.positions {
                let p = p.as_dvec3();
                assert!(
                    bb.aabb.min.cmple(p + 1e-3).all() && p.cmple(bb.aabb.max + 1e-3).all(),
                    "block {i}: mesh vertex {p} outside {:?}",
                    bb.aabb
                );
            }
            let formula = u64::from(extruded_triangles(&building.footprint));
            assert_eq!(
                formula,
                mesh.triangle_count() as u64,
                "formula vs extrusion, building {}",
                building.source_id
            );
        }
        assert_eq!(u64::from(bb.triangles), tris, "block {i}");
    }
    (city, bounds)
}

fn check(bounds: &[BlockBounds]) {
    let bqr = BqrTree::build(bounds, &BqrParams::default()).unwrap();
    bqr.check_invariants();
    let vam = VamSplitTree::build(bounds, &VamSplitParams::default()).unwrap();
    vam.check_invariants();
    let r = run_cull_bench(
        bounds,
        &CullBenchParams {
            views: 60,
            ..CullBenchParams::default()
        },
    )
    .unwrap();
    for s in &r.structures {
        assert_eq!(s.false_culls, 0, "{}", s.name);
    }
}

#[test]
fn bubenec_blocks_no_false_culls() {
    let (_, bounds) = city_and_bounds("bubenec/buildings.shp", "bubenec/streets.shp");
    assert!(bounds.len() > 3);
    check(&bounds);
}

#[test]
fn helsinki_blocks_no_false_culls() {
    let (_, bounds) = city_and_bounds("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    assert!(bounds.len() > 3);
    check(&bounds);
}
