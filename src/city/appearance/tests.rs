use super::ground::{ground_mesh_with, JOINT_SIDES};
use super::style::ROOFS;
use super::*;

use blockwalk_importers::{AttrValue, Attributes};
use geo_types::{Coord, Polygon};
use glam::{DVec3, Vec3};

use crate::city::mesh::Mesh;
use crate::city::model::{Building, LocalFrame, Street};
use crate::city::model::{BuildingId, HeightSource};
use geo_types::LineString;

fn building(source_id: &str, height_m: f64, attrs: &[(&str, AttrValue)]) -> Building {
    Building {
        id: BuildingId(0),
        source_id: source_id.into(),
        footprint: Polygon::new(
            LineString::from(vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 0.0)]),
            vec![],
        ),
        height_m,
        min_height_m: 0.0,
        base_m: 0.0,
        height_source: HeightSource::Height,
        attributes: attrs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect(),
    }
}

fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[test]
fn styles_are_deterministic_and_depend_on_the_id_not_the_index() {
    let a = building("b:17", 15.0, &[]);
    let mut b = a.clone();
    b.id = BuildingId(99);
    assert_eq!(building_style(&a), building_style(&b));
    // A fixed value: the hash must not change between runs or platforms.
    assert_eq!(style_hash(""), mix32(0x811c_9dc5));
    assert_eq!(style_hash("b:17"), style_hash("b:17"));
    // Different ids give different hashes (and over many ids, all palette entries).
    let mut facades = std::collections::BTreeSet::new();
    for i in 0..200 {
        let s = building_style(&building(&format!("b:{i}"), 15.0, &[]));
        facades.insert(to_rgb8(s.facade));
    }
    assert_eq!(facades.len(), 4, "{facades:?}");
}

#[test]
fn one_window_row_per_storey() {
    for levels in [1u32, 2, 5, 17] {
        for (i, h) in [4.0, 9.5, 31.0].into_iter().enumerate() {
            let b = building(
                &format!("x:{levels}:{i}"),
                h,
                &[("levels", AttrValue::Int(levels as i64))],
            );
            let s = building_style(&b);
            assert_eq!(s.levels, levels);
            // At the centre of a bay: rising z crosses into a window once per storey.
            let u = 0.5 * s.bay_m + 7.0 * s.bay_m;
            let n = 20_000;
            let mut rows = 0;
            let mut was = false;
            for k in 0..n {
                let z = (k as f64 + 0.5) / n as f64 * h;
                let is = facade_color(&s, u, z as f32) == s.window;
                rows += (is && !was) as u32;
                was = is;
            }
            assert_eq!(rows, levels, "levels {levels}, height {h}");
            // At the centre of a pier there is no window at all.
            let pier = 7.0 * s.bay_m + 0.01;
            for k in 0..200 {
                let z = (k as f32 + 0.5) / 200.0 * h as f32;
                assert_ne!(facade_color(&s, pier, z), s.window);
            }
        }
    }
}

#[test]
fn windows_repeat_per_bay_along_the_wall() {
    let s = building_style(&building("r:1", 12.0, &[("levels", AttrValue::Int(4))]));
    let z = 1.55 * s.storey_height_m; // second storey, in the window band
    let n = 10_000;
    let len = 10.0 * s.bay_m;
    let mut windows = 0;
    let mut was = false;
    for k in 0..n {
        let u = (k as f32 + 0.5) / n as f32 * len;
        let is = facade_color(&s, u, z) == s.window;
        windows += (is && !was) as u32;
        was = is;
    }
    assert_eq!(windows, 10);
}

#[test]
fn ground_floor_is_darker() {
    for i in 0..50 {
        let s = building_style(&building(&format!("g:{i}"), 20.0, &[]));
        let pier = 0.02 * s.bay_m;
        let ground = facade_color(&s, pier, 0.5 * s.storey_height_m);
        let upper = facade_color(&s, pier, 2.5 * s.storey_height_m);
        assert_eq!(upper, s.facade);
        assert!(
            luminance(ground) < 0.8 * luminance(upper),
            "{ground:?} {upper:?}"
        );
    }
}

#[test]
fn colours_are_in_the_unit_range() {
    let kinds = ["apartments", "office", "warehouse", "museum", "yes"];
    for i in 0..500 {
        let b = building(
            &format!("c:{i}"),
            3.0 + i as f64,
            &[("building", AttrValue::Text(kinds[i % 5].into()))],
        );
        let s = building_style(&b);
        for c in [s.facade, s.roof, s.window, facade_color(&s, i as f32, 1.0)] {
            assert!(c.iter().all(|v| (0.0..=1.0).contains(v)), "{c:?}");
        }
        let lit = shade(facade_color(&s, 0.3, 0.3), Vec3::new(0.6, -0.8, 0.0));
        assert!(lit.iter().all(|v| (0.0..=1.0).contains(v)));
    }
    for c in [GROUND, BLOCK_GROUND, UNDERSIDE, SKY] {
        assert!(unit_rgb(c).iter().all(|v| (0.0..=1.0).contains(v)));
    }
}

#[test]
fn kinds_and_roofs_follow_the_type_attribute() {
    let k = |t: &str| {
        BuildingKind::from_attributes(
            &[("building".to_string(), AttrValue::Text(t.into()))]
                .into_iter()
                .collect(),
        )
    };
    assert_eq!(k("apartments"), BuildingKind::Residential);
    assert_eq!(k("Office"), BuildingKind::Commercial);
    assert_eq!(k("warehouse"), BuildingKind::Industrial);
    assert_eq!(k("chapel"), BuildingKind::Civic);
    assert_eq!(k("yes"), BuildingKind::Other);
    // Civic roofs come from the civic palette, never the residential one.
    let civic: Vec<[u8; 3]> = ROOFS[BuildingKind::Civic.index()].to_vec();
    for i in 0..40 {
        let b = building(
            &format!("k:{i}"),
            10.0,
            &[("building", AttrValue::Text("church".into()))],
        );
        assert!(civic.contains(&to_rgb8(roof_color(&building_style(&b)))));
    }
}

#[test]
fn levels_fall_back_to_the_height() {
    assert_eq!(building_levels(&building("l", 12.2, &[])), 4);
    assert_eq!(building_levels(&building("l", 1.0, &[])), 1);
    assert_eq!(
        building_levels(&building("l", 12.2, &[("levels", AttrValue::Float(3.5))])),
        4
    );
    assert_eq!(
        building_levels(&building("l", 12.2, &[("levels", AttrValue::Null)])),
        4
    );
    let s = style_for(BuildingKind::Other, 0, f64::NAN, 3);
    assert_eq!(s.levels, 0);
    assert_eq!(facade_color(&s, 1.0, 1.0), s.facade);
}

#[test]
fn street_widths_come_from_attributes_then_class() {
    let a = |kv: &[(&str, AttrValue)]| -> Attributes {
        kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
    };
    assert_eq!(
        street_width_m(&a(&[("width", AttrValue::Float(12.0))])),
        12.0
    );
    assert_eq!(
        street_width_m(&a(&[("lanes", AttrValue::Text("2.0".into()))])),
        3.0 * LANE_M
    );
    assert_eq!(
        street_width_m(&a(&[("highway", AttrValue::Text("primary_link".into()))])),
        14.0
    );
    assert_eq!(
        street_width_m(&a(&[
            ("highway", AttrValue::Text("footway".into())),
            ("width", AttrValue::Float(-1.0))
        ])),
        2.0
    );
    assert_eq!(street_width_m(&a(&[])), 8.0);
}

#[test]
fn ring_u_is_the_unfolded_boundary() {
    let r = [
        Coord { x: 0.0, y: 0.0 },
        Coord { x: 3.0, y: 4.0 },
        Coord { x: 3.0, y: 10.0 },
    ];
    let u = ring_u(&r);
    assert_eq!(u[..3], [0.0, 5.0, 11.0]);
    assert!((u[3] as f64 - (11.0 + 109f64.sqrt())).abs() < 1e-5, "{u:?}");
    assert_eq!(ring_u(&[]), vec![0.0]);
}

/// The style painted last over `p` (triangles in drawing order), or `None`.
fn top_style(m: &Mesh, p: (f64, f64)) -> Option<u32> {
    let mut top = None;
    for t in m.indices.chunks_exact(3) {
        let v: Vec<(f64, f64)> = t
            .iter()
            .map(|&i| {
                let q = m.positions[i as usize];
                (q.x as f64, q.y as f64)
            })
            .collect();
        let side =
            |a: (f64, f64), b: (f64, f64)| (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
        if side(v[0], v[1]) >= 0.0 && side(v[1], v[2]) >= 0.0 && side(v[2], v[0]) >= 0.0 {
            top = Some(m.appearance[t[0] as usize].style);
        }
    }
    top
}

/// Leaving out the octagons that draw nothing new (duplicates at junctions, straight-on
/// vertices) keeps the picture: on a dense grid over four streets meeting at a junction
/// (two classes, so that painter's order matters), one street going straight on through a
/// vertex and one bending, every sample shows the same style, with fewer triangles.
#[test]
fn pruned_octagons_keep_the_picture() {
    use geo_types::LineString;
    let frame = LocalFrame {
        origin: DVec3::new(0.0, 0.0, 0.0),
    };
    let street = |id: &str, pts: Vec<(f64, f64)>, w: f64, highway: &str| Street {
        source_id: id.into(),
        line: LineString::from(pts),
        grade_separated: false,
        attributes: [
            ("width".to_string(), AttrValue::Float(w)),
            ("highway".to_string(), AttrValue::Text(highway.into())),
        ]
        .into_iter()
        .collect(),
    };
    let streets = vec![
        street("a", vec![(0.0, 0.0), (30.0, 0.0)], 8.0, "primary"),
        street("b", vec![(0.0, 0.0), (0.0, 30.0)], 6.0, "residential"),
        street(
            "c",
            vec![(0.0, 0.0), (-20.0, 0.0), (-40.0, 0.0)],
            6.0,
            "residential",
        ),
        street(
            "d",
            vec![(0.0, 0.0), (0.0, -15.0), (10.0, -25.0)],
            8.0,
            "primary",
        ),
        street("e", vec![(30.0, 0.0), (30.0, 20.0)], 6.0, "residential"),
    ];
    let full = ground_mesh_with(&frame, &streets, &[], false);
    let pruned = ground_mesh(&frame, &streets, &[]);
    assert!(
        pruned.indices.len() < full.indices.len(),
        "{} vs {}",
        pruned.indices.len(),
        full.indices.len()
    );
    // The junction's two identical residential octagons and primary octagons become one
    // each; the straight-on vertex of c loses its octagon.
    let octagons = |m: &Mesh| (m.indices.len() / 3 - 2 * 7) / JOINT_SIDES;
    assert_eq!(octagons(&full), 12);
    assert_eq!(octagons(&pruned), 9);
    let (mut covered, mut n) = (0, 0);
    for j in 0..=300 {
        for i in 0..=400 {
            let p = (-45.0 + i as f64 * 0.2125, -30.0 + j as f64 * 0.2125);
            let (a, b) = (top_style(&full, p), top_style(&pruned, p));
            assert_eq!(a, b, "at {p:?}");
            covered += a.is_some() as usize;
            n += 1;
        }
    }
    assert!(covered > n / 20, "{covered} of {n} samples on a street");
}

#[test]
fn ground_mesh_covers_blocks_then_streets() {
    use geo_types::LineString;
    let frame = LocalFrame {
        origin: DVec3::new(100.0, 200.0, 0.0),
    };
    let block = Polygon::new(
        LineString::from(vec![
            (100.0, 200.0),
            (140.0, 200.0),
            (140.0, 230.0),
            (100.0, 230.0),
            (100.0, 200.0),
        ]),
        vec![LineString::from(vec![
            (110.0, 210.0),
            (110.0, 220.0),
            (120.0, 220.0),
            (120.0, 210.0),
            (110.0, 210.0),
        ])],
    );
    let street = Street {
        source_id: "s:1".into(),
        line: LineString::from(vec![(90.0, 195.0), (150.0, 195.0), (150.0, 240.0)]),
        grade_separated: false,
        attributes: [("width".to_string(), AttrValue::Float(6.0))]
            .into_iter()
            .collect(),
    };
    let m = ground_mesh(&frame, &[street], &[block]);
    assert_eq!(m.positions.len(), m.appearance.len());
    assert_eq!(m.styles.len(), 2);
    // Every triangle faces up; the block's area (1200 − 100) comes first.
    let mut area = [0.0f64; 2];
    for t in m.indices.chunks_exact(3) {
        let p: Vec<DVec3> = t
            .iter()
            .map(|&i| m.positions[i as usize].as_dvec3())
            .collect();
        let a = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).z;
        assert!(a > 0.0);
        area[m.appearance[t[0] as usize].style as usize] += a;
    }
    assert!((area[0] - 1100.0).abs() < 1e-6, "{area:?}");
    // Two segments 60 and 45 m long, 6 m wide, plus three octagons of radius 3.
    let oct = 0.5 * 8.0 * 9.0 * (std::f64::consts::TAU / 8.0).sin();
    assert!(
        (area[1] - (105.0 * 6.0 + 3.0 * oct)).abs() < 1e-3,
        "{area:?}"
    );
    assert!(m.positions.iter().all(|p| p.z == 0.0));
}
