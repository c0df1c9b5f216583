//! A scene extrudes each building once: a whole hybrid walk (scene with draw units, BlockMaps,
//! the silhouette bound's exact prisms, CPU hybrid frames compared with the mesh frames) adds
//! exactly one extrusion per building to the process's counter. One test in its own binary, so
//! that no other test extrudes while it counts.

mod support;

use blockwalk::blockmap::{CityMapsOptions, Source};
use blockwalk::city::extrude::extrusions;
use blockwalk::index::{SceneGraphParams, Structure};
use blockwalk::route::RouteChoice;
use blockwalk::scene::{BuildingsMode, CitySource, Scene, SceneOptions};
use blockwalk::visibility::CullerOptions;
use blockwalk::walk::job::route_context;
use blockwalk::walk::{run_walk_with_far, Drawing, FarSetup, OcclusionMode, WalkParams};
use support::data::data;

#[test]
fn a_hybrid_walk_extrudes_every_building_once() {
    let source = CitySource::parse(
        &data("helsinki/buildings.shp"),
        Some(data("helsinki/streets_blockclass.shp")),
        None,
        &[],
        0,
    )
    .unwrap();
    let loaded = source.load(&Default::default(), &mut |_| {}).unwrap();
    let n = loaded.city.buildings.len() as u64;
    assert!(n > 400, "{n} buildings");
    let before = extrusions();
    let opts = SceneOptions {
        structures: vec![Structure::Bqr, Structure::SceneGraph],
        occlusion: Some(CullerOptions::default()),
        ..SceneOptions::default()
    };
    let mut scene = Scene::from_loaded(loaded, &opts, &mut |_| {}).unwrap();
    scene
        .build_units(&SceneGraphParams::default(), BuildingsMode::Auto)
        .unwrap();
    let maps = scene
        .blockmaps(&CityMapsOptions::default(), &|_, _| {})
        .unwrap()
        .maps;
    assert!(!maps.maps.is_empty());
    let prisms = Source::new(&scene.city, &scene.layout, &scene.building_meshes).unwrap();
    let size = (96, 54);
    let ctx = route_context(&scene, size.0 as f64 / size.1 as f64);
    let (route, _) = RouteChoice::Orbit.resolve(&ctx).unwrap();
    let params = WalkParams {
        route,
        frames: 3,
        occlusion: OcclusionMode::Auto,
        image_every: 1,
        oracle: true,
        size,
    };
    let far = FarSetup {
        reference: true,
        leave_out: false,
        source: Some(&prisms),
        ..FarSetup::new(&maps)
    };
    let rec = run_walk_with_far(
        &scene,
        &params,
        Drawing::CpuFallback {
            reason: "test".into(),
        },
        Some(far),
        &mut |_, _| {},
    )
    .unwrap();
    assert!(!rec.far.is_empty(), "hybrid frames were drawn");
    assert_eq!(
        extrusions() - before,
        n,
        "one extrusion per building for the scene, its units, its maps, the bound and the walk"
    );
    // The counter counts: building the maps the stand-alone way extrudes the city again.
    let again = extrusions();
    blockwalk::blockmap::build_city_maps(
        &scene.city,
        &scene.layout,
        &scene.bounds,
        &CityMapsOptions::default(),
        &|_, _| {},
    )
    .unwrap();
    assert_eq!(extrusions() - again, n);
}
