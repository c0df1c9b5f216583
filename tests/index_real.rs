//! Block bounds and structures on the bundled real data (Bubeneč, Helsinki): boxes and the
//! blocks' tight spheres hold the extruded meshes, the triangle formula matches the extrusion, no false culls.

mod support;
use blockwalk::city::extrude::extrude_building;
use blockwalk::index::bench::{run_cull_bench, CullBenchParams};
use blockwalk::index::{extruded_triangles, BlockBounds, BqrParams, BqrTree};
use blockwalk::index::{VamSplitParams, VamSplitTree};
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use support::data::data;

/// The scene's bounds hold its block meshes, and the triangle formula matches the extrusion of
/// every building.
fn scene_bounds(buildings: &str, streets: &str) -> Vec<BlockBounds> {
    let source = CitySource::parse(&data(buildings), Some(data(streets)), None, &[], 0).unwrap();
    let opts = SceneOptions {
        structures: Vec::new(),
        ..SceneOptions::default()
    };
    let scene = Scene::load(&source, &opts, &mut |_| {}).expect("scene");
    let (city, layout, bounds) = (&scene.city, &scene.layout, &scene.bounds);
    assert_eq!(bounds.len(), layout.blocks.len());
    assert_eq!(scene.block_meshes().len(), layout.blocks.len());
    for (i, ((bb, bl), (mid, mesh))) in bounds
        .iter()
        .zip(&layout.blocks)
        .zip(scene.block_meshes())
        .enumerate()
    {
        assert_eq!(bb.id, bl.id);
        assert_eq!(*mid, bl.id);
        assert_eq!(bb.id.0 as usize, i);
        for p in &mesh.positions {
            let p = p.as_dvec3();
            assert!(
                bb.aabb.min.cmple(p + 1e-3).all() && p.cmple(bb.aabb.max + 1e-3).all(),
                "block {i}: mesh vertex {p} outside {:?}",
                bb.aabb
            );
            // The block's own sphere holds what is drawn (f32 vertices), with no tolerance.
            assert!(
                bb.sphere.contains_point(p),
                "block {i}: mesh vertex {p} outside its sphere {:?}",
                bb.sphere
            );
        }
        let mut tris = 0u64;
        for bid in &bl.buildings {
            let building = &city.buildings[bid.0 as usize];
            let alone = extrude_building(building, &city.frame).triangle_count() as u64;
            let formula = u64::from(extruded_triangles(&building.footprint));
            assert_eq!(
                formula, alone,
                "formula vs extrusion, building {}",
                building.source_id
            );
            tris += alone;
        }
        assert_eq!(mesh.triangle_count() as u64, tris, "block {i}: merged mesh");
        assert_eq!(u64::from(bb.triangles), tris, "block {i}");
    }
    scene.bounds
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
    let bounds = scene_bounds("bubenec/buildings.shp", "bubenec/streets.shp");
    assert!(bounds.len() > 3);
    check(&bounds);
}

#[test]
fn helsinki_blocks_no_false_culls() {
    let bounds = scene_bounds("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    assert!(bounds.len() > 3);
    check(&bounds);
}
