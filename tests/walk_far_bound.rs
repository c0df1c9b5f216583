//! The silhouette bound of hybrid frames checked with the exact geometry (`walk::bound`), on small
//! hand-made cities drawn by the CPU renderers: a tower narrower than a pixel that only the map's
//! one-texel column shows (raw distance beyond the bound, settled by the second look), a map
//! displaced by several pixels (real violations), and a building the map drops (thin, and a
//! violation once the map no longer declares it).

use blockwalk::blockmap::{
    build_map, measure, BuildOptions, CpuHybridRenderer, MapTree, NodeMap, Selection, Source,
};
use blockwalk::blocks::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use blockwalk::city::{Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Mesh};
use blockwalk::geom::Camera;
use blockwalk::visibility::{CpuFrameRenderer, FrameRenderer};
use blockwalk::walk::{
    image_error, image_error_with_bound, BoundGeometry, FrameBound, ImageError, PixelBound,
};
use geo_types::{LineString, Polygon};
use glam::{DVec2, DVec3};

/// Boxes `(min, max, height)` as buildings of one block, local frame at the origin.
fn city(boxes: &[(DVec2, DVec2, f64)]) -> (City, BlockLayout) {
    let rect = |a: DVec2, b: DVec2| {
        Polygon::new(
            LineString::from(vec![
                (a.x, a.y),
                (b.x, a.y),
                (b.x, b.y),
                (a.x, b.y),
                (a.x, a.y),
            ]),
            vec![],
        )
    };
    let buildings: Vec<Building> = boxes
        .iter()
        .enumerate()
        .map(|(i, &(a, b, h))| Building {
            id: BuildingId(i as u32),
            source_id: format!("test:{i}"),
            footprint: rect(a, b),
            height_m: h,
            min_height_m: 0.0,
            base_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        })
        .collect();
    let lo = boxes
        .iter()
        .fold(DVec2::splat(f64::INFINITY), |m, b| m.min(b.0));
    let hi = boxes
        .iter()
        .fold(DVec2::splat(f64::NEG_INFINITY), |m, b| m.max(b.1));
    let layout = BlockLayout {
        blocks: vec![Block {
            id: BlockId(0),
            kind: BlockKind::Block,
            polygon: rect(lo - 1.0, hi + 1.0),
            buildings: (0..boxes.len() as u32).map(BuildingId).collect(),
        }],
        source: BlockSource::Streets,
        street_edges: Vec::new(),
        dangles: 0,
    };
    let city = City {
        name: "bound test".into(),
        transform: blockwalk::importers::Crs::Unknown.metric_transform([0.0, 0.0]),
        frame: LocalFrame {
            origin: DVec3::ZERO,
        },
        buildings,
        streets: Vec::new(),
        parcels: Vec::new(),
        report: CityReport::default(),
        terrain: None,
    };
    (city, layout)
}

/// One map of every building of the block, its ε the measured one.
fn one_map(source: &Source, n: usize, opts: &BuildOptions) -> MapTree {
    let all: Vec<u32> = (0..n as u32).collect();
    let (mut map, kept, stats) = build_map(source, &all, opts).unwrap();
    let error = measure(&map, source, &kept);
    map.meta.eps_m = error.declared_m;
    MapTree {
        maps: vec![NodeMap {
            node: 0,
            key: 0,
            level: 0,
            parent: None,
            blocks: vec![BlockId(0)],
            buildings: kept,
            map,
            stats,
            error,
        }],
    }
}

/// The mesh-only, hybrid (the one map, no near mesh) and background frames of `cam`, and their
/// image error with and without the geometry.
struct Frames {
    raw: ImageError,
    checked: ImageError,
    /// The allowed distance at the image centre.
    r_centre: f64,
}

const SIZE: (u32, u32) = (160, 90);

fn frames(
    city: &City,
    layout: &BlockLayout,
    source: &Source,
    tree: &MapTree,
    cam: &Camera,
    tau: f64,
) -> Frames {
    let meshes: Vec<(BlockId, Mesh)> = blockwalk::scene::block_meshes(city, layout);
    let ground = Mesh::default();
    let mesh_r = CpuFrameRenderer::new(&meshes, SIZE).with_ground(&ground);
    let hyb_r = CpuHybridRenderer::new(
        &meshes,
        &ground,
        tree.maps.iter().map(|m| &m.map).collect(),
        SIZE,
    );
    let mesh = mesh_r
        .draw(cam, &[BlockId(0)], true)
        .unwrap()
        .image
        .unwrap();
    let bg = mesh_r.draw(cam, &[], true).unwrap().image.unwrap();
    let hyb = hyb_r
        .draw_with_far(cam, &[], &[0], true)
        .unwrap()
        .image
        .unwrap();
    let sel = Selection {
        maps: vec![0],
        meshes: Vec::new(),
        stats: Default::default(),
    };
    let geom = BoundGeometry::new(source, tree);
    let fb = FrameBound::new(&geom, &sel, cam, tau);
    Frames {
        raw: image_error(&mesh, &hyb, &bg),
        checked: image_error_with_bound(&mesh, &hyb, &bg, Some(&fb as &dyn PixelBound)),
        r_centre: fb.allowed_px(SIZE.0 / 2, SIZE.1 / 2, SIZE.0, SIZE.1),
    }
}

/// A camera at `eye` looking at `target`, 16:9 like [`SIZE`].
fn cam(eye: DVec3, target: DVec3) -> Camera {
    let mut c = Camera::looking_at(eye, target);
    c.near = 1.0;
    c.far = 3000.0;
    c
}

/// τ for a frame: the map's projected error (seed 000 §3.3) from `cam`, at least 1 px.
fn tau_of(tree: &MapTree, cam: &Camera) -> f64 {
    let m = &tree.maps[0].map;
    let b = m.aabb();
    let d = ((cam.position - b.center()).length() - 0.5 * b.extent().length()).max(cam.near);
    let f = SIZE.1 as f64 / (2.0 * (0.5 * cam.fov_y).tan());
    (m.meta.eps_m * f / d).max(1.0)
}

#[test]
fn a_tower_narrower_than_a_pixel_is_found_at_quarter_pixels() {
    // A long low building fixes the map's square (200 m, K = 32: 6.25 m texels); a tower of
    // 3.3 × 3.4 m, 80 m tall, stands inside one texel, which the map fills (6 of its 16
    // samples) and cuts with at most two half-planes: its column stays wider than the tower.
    let (city, layout) = city(&[
        (DVec2::new(0.0, 0.0), DVec2::new(200.0, 100.0), 5.0),
        (DVec2::new(100.7, 152.0), DVec2::new(104.0, 155.4), 80.0),
    ]);
    let meshes = blockwalk::city::extrude::extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let tree = one_map(
        &source,
        2,
        &BuildOptions {
            k: 32,
            ..BuildOptions::default()
        },
    );
    assert!(tree.maps[0].stats.dropped_buildings.is_empty());
    // From the south, 600 m away at the tower's mid-height: the tower is 0.43 px wide, its
    // texel's column up to 0.8 px. Slide the eye sideways until the mesh frame's pixel centres
    // miss the tower and the map's column meets one, so that only the map shows it, far above
    // the low building's silhouette.
    let mut checked = 0;
    for q in 0..40 {
        let x = 102.35 + q as f64 * 0.21;
        let c = cam(
            DVec3::new(x, 153.7 - 600.0, 40.0),
            DVec3::new(x, 153.7, 40.0),
        );
        let tau = tau_of(&tree, &c);
        let f = frames(&city, &layout, &source, &tree, &c, tau);
        if f.raw.silhouette_px <= f.r_centre + 2.0 {
            continue;
        }
        checked += 1;
        let e = f.checked;
        eprintln!("q {q}: τ {tau:.2}, r {:.2}: {e:?}", f.r_centre);
        // The image-only measure is the same with or without the geometry.
        assert_eq!(e.silhouette_px, f.raw.silhouette_px);
        assert_eq!(f.raw.beyond_bound, None);
        assert_eq!(f.raw.silhouette_ratio_max, None);
        assert_eq!(e.beyond_bound, Some(0), "{e:?}");
        assert!(e.beyond_bound_subpixel.unwrap() > 0, "{e:?}");
        assert!(e.silhouette_ratio_max.unwrap() <= 1.0, "{e:?}");
        assert_eq!(e.beyond_bound_thin, Some(0));
    }
    assert!(checked > 0, "no eye put the tower between pixel centres");
}

#[test]
fn a_displaced_map_breaks_the_bound() {
    // A 40 m cube seen from above at 45°; the map is moved 12 m (about 3 px) east and north:
    // bands of pixels only one frame covers, farther than the bound from every silhouette.
    let (city, layout) = city(&[(DVec2::new(0.0, 0.0), DVec2::new(40.0, 40.0), 20.0)]);
    let meshes = blockwalk::city::extrude::extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let mut tree = one_map(
        &source,
        1,
        &BuildOptions {
            k: 32,
            ..BuildOptions::default()
        },
    );
    let c = cam(
        DVec3::new(20.0, -180.0, 220.0),
        DVec3::new(20.0, 20.0, 10.0),
    );
    let tau = tau_of(&tree, &c);
    let good = frames(&city, &layout, &source, &tree, &c, tau).checked;
    eprintln!("in place: {good:?}");
    assert_eq!(good.beyond_bound, Some(0), "{good:?}");
    tree.maps[0].map.meta.min[0] += 12.0;
    tree.maps[0].map.meta.min[1] += 12.0;
    let bad = frames(&city, &layout, &source, &tree, &c, tau).checked;
    eprintln!("displaced: {bad:?}");
    assert!(bad.beyond_bound.unwrap() > 0, "{bad:?}");
    assert!(bad.silhouette_ratio_max.unwrap() > 1.0, "{bad:?}");
}

#[test]
fn a_dropped_building_is_thin_only_while_the_map_declares_it() {
    // Whole texels sampled at their centres (6.25 m apart): a 5.4 m square hut, 4 m tall,
    // between four texel centres vanishes from the map (a dropped building), its error under
    // the ½ voxel diagonal, so about one pixel wide where the map's ε projects to one pixel.
    // Far from the big building, its pixels in the mesh frame lie beyond the bound of every
    // silhouette of the hybrid frame, within it of its own.
    let (city, layout) = city(&[
        (DVec2::new(0.0, 0.0), DVec2::new(40.0, 200.0), 10.0),
        (DVec2::new(103.5, 97.2), DVec2::new(108.9, 102.6), 4.0),
    ]);
    let meshes = blockwalk::city::extrude::extrude_city(&city);
    let source = Source::new(&city, &layout, &meshes).unwrap();
    let opts = BuildOptions {
        k: 32,
        edges: false,
        two_edges: false,
        fill_samples: 1,
        ..BuildOptions::default()
    };
    let tree = one_map(&source, 2, &opts);
    assert_eq!(
        tree.maps[0].stats.dropped_buildings,
        vec![BuildingId(1)],
        "the hut must fall between texel centres"
    );
    // From the south-east, about 400 m away: slide the eye until the hut covers a pixel centre
    // of the mesh frame.
    let mut checked = 0;
    for q in 0..12 {
        let x = 106.2 + q as f64 * 0.4;
        let c = cam(DVec3::new(x, -260.0, 150.0), DVec3::new(x, 99.9, 0.0));
        let tau = tau_of(&tree, &c);
        let f = frames(&city, &layout, &source, &tree, &c, tau);
        if f.raw.silhouette_px <= f.r_centre {
            continue;
        }
        checked += 1;
        let e = f.checked;
        eprintln!("q {q}: declared: τ {tau:.2}: {e:?}");
        assert!(e.beyond_bound_thin.unwrap() > 0, "{e:?}");
        assert_eq!(e.beyond_bound, Some(0), "{e:?}");
        assert!(e.silhouette_ratio_max.unwrap() <= 1.0, "{e:?}");
        // The same frame, the map no longer declaring the hut: now a violation.
        let mut undeclared = tree.clone();
        undeclared.maps[0].stats.dropped_buildings.clear();
        undeclared.maps[0].error.thin.retain(|t| t.building != 1);
        let u = frames(&city, &layout, &source, &undeclared, &c, tau).checked;
        eprintln!("undeclared: {u:?}");
        assert_eq!(u.beyond_bound_thin, Some(0), "{u:?}");
        assert_eq!(u.beyond_bound, e.beyond_bound_thin, "{u:?}");
        assert!(u.silhouette_ratio_max.unwrap() > 1.0, "{u:?}");
    }
    assert!(checked > 0, "no eye showed the hut");
}
