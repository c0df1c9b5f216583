use super::*;

const BUBENEC_PRJ: &str = r#"PROJCS["WGS_1984_Web_Mercator_Auxiliary_Sphere",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Mercator_Auxiliary_Sphere"],PARAMETER["False_Easting",0.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",0.0],PARAMETER["Standard_Parallel_1",0.0],PARAMETER["Auxiliary_Sphere_Type",0.0],UNIT["Meter",1.0]]"#;
const UTM33_PRJ: &str = r#"PROJCS["WGS_1984_UTM_Zone_33N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",15.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
const TM35_PRJ: &str = r#"PROJCS["EUREF-FIN_TM35FIN",GEOGCS["GCS_EUREF_FIN",DATUM["EUREF-FIN",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",27.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
const OGC_3857: &str = r#"PROJCS["WGS 84 / Pseudo-Mercator",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Mercator_1SP"],PARAMETER["central_meridian",0],PARAMETER["scale_factor",1],PARAMETER["false_easting",0],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],EXTENSION["PROJ4","+proj=merc +a=6378137 +b=6378137 +lat_ts=0 +lon_0=0 +x_0=0 +y_0=0 +k=1 +units=m +nadgrids=@null +wktext +no_defs"]]"#;

const BNG_ESRI_NO_EPSG: &str = r#"PROJCS["British_National_Grid",GEOGCS["GCS_OSGB_1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",400000.0],PARAMETER["False_Northing",-100000.0],PARAMETER["Central_Meridian",-2.0],PARAMETER["Scale_Factor",0.9996012717],PARAMETER["Latitude_Of_Origin",49.0],UNIT["Meter",1.0]]"#;

fn utm33() -> Crs {
    Crs::from_wkt(UTM33_PRJ).unwrap()
}

#[test]
fn recognises_the_bundled_prj_files() {
    assert_eq!(Crs::from_wkt(BUBENEC_PRJ).unwrap(), Crs::WebMercator);
    assert_eq!(Crs::from_wkt(OGC_3857).unwrap(), Crs::WebMercator);
    match utm33() {
        Crs::Projected { epsg, name, proj4 } => {
            assert_eq!(epsg, Some(32633));
            assert_eq!(name, "WGS_1984_UTM_Zone_33N");
            assert!(
                proj4.contains("+proj=tmerc") && proj4.contains("+lon_0=15"),
                "{proj4}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        Crs::from_wkt(TM35_PRJ).unwrap(),
        Crs::Projected {
            epsg: Some(3067),
            ..
        }
    ));
    assert_eq!(
        linear_unit(&wkt::parse(TM35_PRJ).unwrap()),
        Some(("Meter".to_string(), 1.0))
    );
}

#[test]
fn geographic_authority_unknown_codes_and_garbage() {
    let g = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
    assert_eq!(
        Crs::from_wkt(g).unwrap(),
        Crs::Geographic { epsg: Some(4326) }
    );
    let p = r#"PROJCS["Some grid",GEOGCS["x",DATUM["y",SPHEROID["z",1,2]]],PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["metre",1],AUTHORITY["EPSG","2154"]]"#;
    assert!(matches!(
        Crs::from_wkt(p).unwrap(),
        Crs::Projected { epsg: Some(2154), ref name, .. } if name == "Some grid"
    ));
    assert!(matches!(
        Crs::from_wkt("not a wkt"),
        Err(CrsError::NotWkt { .. })
    ));
    assert!(matches!(
        Crs::from_wkt("PROJCS[\"unterminated\""),
        Err(CrsError::NotWkt { .. })
    ));
    assert!(matches!(
        Crs::from_epsg(99999),
        Err(CrsError::UnknownEpsg { code: 99999 })
    ));
    assert!(matches!(
        Crs::from_epsg(1),
        Err(CrsError::UnknownEpsg { code: 1 })
    ));
    let unknown_authority = p.replace("2154", "99999");
    assert!(matches!(
        Crs::from_wkt(&unknown_authority),
        Err(CrsError::UnknownEpsg { code: 99999 })
    ));
    assert_eq!(Crs::from_epsg(3857).unwrap(), Crs::WebMercator);
    assert_eq!(Crs::from_epsg(900913).unwrap(), Crs::WebMercator);
    assert_eq!(
        Crs::from_epsg(4326).unwrap(),
        Crs::Geographic { epsg: Some(4326) }
    );
    assert_eq!(
        Crs::from_epsg(32633).unwrap().describe(),
        "EPSG:32633 WGS 84 / UTM zone 33N"
    );
    // US survey feet are taken in their unit, not as metres.
    let feet = Crs::from_epsg(2263).unwrap();
    assert!(!feet.is_metric_projected());
    assert!((feet.metres_per_unit().unwrap() - 1200.0 / 3937.0).abs() < 1e-12);
    assert!(Crs::from_epsg(32118).unwrap().is_metric_projected());
}

/// EPSG:2263 (NAD83 / New York Long Island, US survey feet) and EPSG:32118 (the same projection
/// in metres, false easting 300 000 m = 984 250 ft) are two registry entries: the same point
/// written in each lands on the same ground, and 1000 ft on the map are 304.8 m on the ground
/// up to the projection's scale error.
#[test]
fn us_survey_feet_are_ground_metres_in_the_frame() {
    let us_ft = 1200.0 / 3937.0;
    let feet = Crs::from_epsg(2263).unwrap();
    let metres = Crs::from_epsg(32118).unwrap();
    let p_ft = [988_000.0, 190_000.0];
    let p_m = [p_ft[0] * us_ft, p_ft[1] * us_ft];
    let tf = feet.metric_transform(p_ft);
    let tm = metres.metric_transform(p_m);
    assert!(tm.is_identity() && !tf.is_identity());
    let (a, b) = (
        tf.to_wgs84_lonlat(tf.to_metric(p_ft)).unwrap(),
        tm.to_wgs84_lonlat(p_m).unwrap(),
    );
    assert!(
        (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9,
        "{a:?} {b:?}"
    );
    let q = tf.to_metric([p_ft[0] + 1000.0, p_ft[1]]);
    let o = tf.to_metric(p_ft);
    let d = ((q[0] - o[0]).powi(2) + (q[1] - o[1]).powi(2)).sqrt();
    assert!((d / (1000.0 * us_ft) - 1.0).abs() < 2e-4, "{d} m");
    // Back to feet within a micrometre, and the summary says what was done.
    let back = tf.from_metric(o);
    assert!((back[0] - p_ft[0]).abs() < 1e-5 && (back[1] - p_ft[1]).abs() < 1e-5);
    assert!(
        tf.describe().contains("local transverse Mercator"),
        "{}",
        tf.describe()
    );
}

/// The textbook spherical formula, written independently: lat = 2·atan(e^(y/R)) − π/2.
#[test]
fn web_mercator_known_point() {
    let (x, y) = (1_603_599.221, 6_464_369.816);
    let r = 6_378_137.0_f64;
    let lon = (x / r).to_degrees();
    let lat = (2.0 * (y / r).exp().atan() - std::f64::consts::FRAC_PI_2).to_degrees();
    let merc = Frame::new(WEB_MERCATOR).unwrap();
    let wgs = Frame::new(WGS84_LONLAT).unwrap();
    let [lo, la] = merc.project(&wgs, [x, y]).unwrap();
    assert!(
        (lo - lon).abs() < 1e-9 && (la - lat).abs() < 1e-9,
        "{lo} {la}"
    );
    // Prague Bubeneč is near 14.40°E 50.10°N.
    assert!((lo - 14.405).abs() < 0.01 && (la - 50.104).abs() < 0.01);
    let back = wgs.project(&merc, [lo, la]).unwrap();
    assert!((back[0] - x).abs() < 1e-6 && (back[1] - y).abs() < 1e-6);
}

/// On the central meridian, northing differences are meridian arcs: checked against a numerical
/// integral of the meridian radius of curvature (an independent truth, not the series).
#[test]
fn local_tm_meridian_arc_and_scale() {
    let a = 6_378_137.0_f64;
    let f = 1.0 / 298.257_223_563;
    let e2 = f * (2.0 - f);
    let t = Crs::Geographic { epsg: Some(4326) }
        .try_metric_transform([15.0, 50.0])
        .unwrap();
    let y0 = t.to_metric([15.0, 49.5])[1];
    let y1 = t.to_metric([15.0, 50.5])[1];
    let n = 20_000;
    let (p0, p1) = (49.5_f64.to_radians(), 50.5_f64.to_radians());
    let h = (p1 - p0) / n as f64;
    let mut s = 0.0;
    for i in 0..n {
        let p = p0 + (i as f64 + 0.5) * h;
        s += a * (1.0 - e2) / (1.0 - e2 * p.sin().powi(2)).powf(1.5) * h;
    }
    assert!(((y1 - y0) - s).abs() < 1e-4, "{} vs {s}", y1 - y0);
    // East-west at the centre: the parallel's radius N cos φ per radian.
    let p = 50.0_f64.to_radians();
    let nrad = a / (1.0 - e2 * p.sin().powi(2)).sqrt();
    let dx = t.to_metric([15.0 + 1e-4, 50.0])[0] - t.to_metric([15.0 - 1e-4, 50.0])[0];
    let expect = nrad * p.cos() * (2e-4_f64).to_radians();
    assert!((dx - expect).abs() / expect < 1e-9, "{dx} vs {expect}");
    let o = t.to_metric([15.0, 50.0]);
    assert!(o[0].abs() < 1e-9 && o[1].abs() < 1e-9, "{o:?}");
}

#[test]
fn round_trips() {
    let t = Crs::WebMercator.metric_transform([1_603_900.0, 6_464_700.0]);
    assert!(!t.is_identity());
    for dx in [-3000.0, -500.0, 0.0, 700.0, 2500.0] {
        for dy in [-2000.0, 0.0, 1000.0, 4000.0] {
            let p = [1_603_900.0 + dx, 6_464_700.0 + dy];
            let m = t.try_to_metric(p).unwrap();
            let q = t.from_metric(m);
            assert!((q[0] - p[0]).abs() < 1e-6 && (q[1] - p[1]).abs() < 1e-6);
        }
    }
    let g = Crs::Geographic { epsg: Some(4326) }.metric_transform([24.94, 60.17]);
    for p in [[24.93, 60.16], [24.96, 60.18], [24.94, 60.17]] {
        let m = g.to_metric(p);
        let q = g.from_metric(m);
        assert!((q[0] - p[0]).abs() < 1e-11 && (q[1] - p[1]).abs() < 1e-11);
    }
    let p = Crs::from_epsg(3067)
        .unwrap()
        .metric_transform([385_000.0, 6_672_000.0]);
    assert!(p.is_identity());
    assert_eq!(p.to_metric([1.0, 2.0]), [1.0, 2.0]);
    assert!(t.describe().contains("1.56×"), "{}", t.describe());
    assert!(t.describe().contains("50.10"), "{}", t.describe());
}

#[test]
fn coordinates_are_checked_against_their_crs() {
    let g = Crs::Geographic { epsg: Some(4326) }.metric_transform([24.94, 60.17]);
    assert!(g.check([24.9, 60.1]).is_ok());
    assert!(matches!(
        g.check([24.9, 95.0]),
        Err(CoordError::Latitude { lat, .. }) if lat == 95.0
    ));
    assert!(matches!(
        g.check([385_421.0, 6_671_459.0]),
        Err(CoordError::Latitude { .. })
    ));
    assert!(matches!(
        g.check([200.0, 10.0]),
        Err(CoordError::Longitude { .. })
    ));
    // A hair past the antimeridian (rounding) is taken, and lands where 180° does; clearly
    // beyond is refused, saying by how much is accepted.
    for lon in [180.000_000_1, -180.000_000_1] {
        assert!(g.check([lon, 10.0]).is_ok(), "{lon}");
    }
    let e = g.check([180.001, 10.0]).unwrap_err();
    assert!(matches!(e, CoordError::Longitude { .. }), "{e:?}");
    assert!(e.to_string().contains("1e-6°"), "{e}");
    let t = Crs::Geographic { epsg: Some(4326) }.metric_transform([179.9, 10.0]);
    let (a, b) = (
        t.try_to_metric([180.000_000_1, 10.0]).unwrap(),
        t.try_to_metric([180.0, 10.0]).unwrap(),
    );
    assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 0.05, "{a:?} {b:?}");
    assert!(matches!(
        g.check([f64::NAN, 10.0]),
        Err(CoordError::NonFinite { .. })
    ));
    // Web Mercator beyond the pole (|y| > π·R) has no latitude to come back from.
    let m = Crs::WebMercator.metric_transform([1_603_900.0, 6_464_700.0]);
    assert!(m.check([1_603_900.0, 6_464_700.0]).is_ok());
    assert!(matches!(
        m.check([1_603_900.0, 1e12]),
        Err(CoordError::OutsideProjection { .. })
    ));
    let u = utm33().metric_transform([457_000.0, 5_550_000.0]);
    assert!(u.check([457_000.0, 5_550_000.0]).is_ok());
    assert!(u.check([4.6e7, 5_550_000.0]).is_err());
    assert!(u.check([457_000.0, 1e9]).is_err());
}

/// British National Grid on OSGB36 as ESRI writes it (no EPSG code, no TOWGS84): the datum
/// shift is found by the datum's name and the result agrees with EPSG:27700's own definition.
#[test]
fn british_national_grid_without_epsg_keeps_its_datum_shift() {
    let bng = Crs::from_wkt(BNG_ESRI_NO_EPSG).unwrap();
    let Crs::Projected { epsg, proj4, .. } = &bng else {
        panic!("{bng:?}")
    };
    assert_eq!(*epsg, None);
    assert!(proj4.contains("+datum=OSGB36"), "{proj4}");
    let reference = Crs::from_epsg(27700).unwrap();
    let frame = Crs::WebMercator.metric_transform([-14_200.0, 6_711_000.0]);
    let a = frame.for_layer(&bng).unwrap();
    let b = frame.for_layer(&reference).unwrap();
    // Without the shift: the same grid on a bare Airy ellipsoid.
    let bare = Crs::Projected {
        epsg: None,
        name: "no shift".into(),
        proj4: proj4.replace(" +datum=OSGB36", ""),
    };
    let c = frame.for_layer(&bare).unwrap();
    let p = [530_000.0, 180_000.0];
    let (pa, pb, pc) = (
        a.try_to_metric(p).unwrap(),
        b.try_to_metric(p).unwrap(),
        c.try_to_metric(p).unwrap(),
    );
    let d = |u: [f64; 2], v: [f64; 2]| (u[0] - v[0]).hypot(u[1] - v[1]);
    assert!(d(pa, pb) < 0.01, "{pa:?} vs {pb:?}");
    // The OSGB36 → WGS84 shift is about 100 m in London.
    assert!(d(pa, pc) > 50.0 && d(pa, pc) < 200.0, "{}", d(pa, pc));
}

#[test]
fn layers_in_other_crs_land_in_the_same_frame() {
    // A point of Bubeneč in Web Mercator and its UTM 33N coordinates (pyproj, in data/).
    let merc = Crs::WebMercator.metric_transform([1_603_599.221, 6_464_369.816]);
    let utm = merc.for_layer(&utm33()).unwrap();
    assert!(!utm.is_identity());
    let wgs = Frame::new(WGS84_LONLAT).unwrap();
    let u = Frame::new(&utm33().proj4().unwrap()).unwrap();
    let m = Frame::new(WEB_MERCATOR).unwrap();
    let ll = m.project(&wgs, [1_603_599.221, 6_464_369.816]).unwrap();
    let pu = wgs.project(&u, ll).unwrap();
    let a = merc.try_to_metric([1_603_599.221, 6_464_369.816]).unwrap();
    let b = utm.try_to_metric(pu).unwrap();
    assert!(
        (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6,
        "{a:?} {b:?}"
    );
    assert!(
        utm.describe().contains("reprojected into the frame"),
        "{}",
        utm.describe()
    );
}

#[test]
fn metric_points_go_to_wgs84_lonlat() {
    // On the central meridian (false easting 500 000 m) the longitude is the meridian's.
    let tm35 = Crs::from_wkt(TM35_PRJ)
        .unwrap()
        .metric_transform([385_000.0, 6_672_000.0]);
    let [lon, lat] = tm35.to_wgs84_lonlat([500_000.0, 6_672_000.0]).unwrap();
    assert!((lon - 27.0).abs() < 1e-9, "{lon}");
    assert!((lat - 60.17).abs() < 0.05, "{lat}");
    // A Web Mercator layer's local frame: its centre is the origin of the metric frame.
    let merc = Crs::WebMercator.metric_transform([1_603_000.0, 6_464_000.0]);
    let [clon, clat] = merc.center_lonlat.unwrap();
    let [lon, lat] = merc.to_wgs84_lonlat([0.0, 0.0]).unwrap();
    assert!((lon - clon).abs() < 1e-9 && (lat - clat).abs() < 1e-9);
    // No CRS, no geodetic meaning.
    assert_eq!(
        Crs::Unknown
            .metric_transform([0.0, 0.0])
            .to_wgs84_lonlat([1.0, 2.0]),
        None
    );
}

/// `box_fits` against the check of every point of a 9 × 9 grid over the box, for boxes walked
/// across the edges of each CRS's range (found by bisection on x, then on y): a box that fits
/// by its corners has no grid point that does not.
#[test]
fn boxes_that_fit_by_their_corners_fit_inside() {
    let transforms = [
        utm33().metric_transform([457_000.0, 5_550_000.0]),
        Crs::from_wkt(TM35_PRJ)
            .unwrap()
            .metric_transform([385_000.0, 6_671_000.0]),
        Crs::from_wkt(BNG_ESRI_NO_EPSG)
            .unwrap()
            .metric_transform([530_000.0, 180_000.0]),
        Crs::WebMercator.metric_transform([1_603_900.0, 6_464_700.0]),
        Crs::Geographic { epsg: Some(4326) }.metric_transform([24.94, 60.17]),
    ];
    let ok = |t: &MetricTransform, p: [f64; 2]| t.check(p).is_ok();
    // The edge between a point that passes and one that does not, along the segment a → b.
    let edge = |t: &MetricTransform, mut a: [f64; 2], mut b: [f64; 2]| {
        for _ in 0..200 {
            let m = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
            if ok(t, m) {
                a = m;
            } else {
                b = m;
            }
        }
        a
    };
    let (mut fitted, mut refused) = (0, 0);
    for t in &transforms {
        let geo = matches!(t.crs, Crs::Geographic { .. });
        let inside = if geo {
            [24.9, 60.1]
        } else {
            t.from_metric([0.0, 0.0])
        };
        let inside = if ok(t, inside) {
            inside
        } else {
            [500_000.0, 5_000_000.0]
        };
        assert!(ok(t, inside), "{:?}", t.crs);
        let far = if geo { 400.0 } else { 1e9 };
        let mut edges = Vec::new();
        for dir in [
            [1.0, 0.0],
            [-1.0, 0.0],
            [0.0, 1.0],
            [0.0, -1.0],
            [0.7, 0.7],
            [-0.6, 0.8],
        ] {
            let b = [inside[0] + dir[0] * far, inside[1] + dir[1] * far];
            if !ok(t, b) {
                edges.push(edge(t, inside, b));
            }
        }
        assert!(!edges.is_empty(), "{:?}: no edge found", t.crs);
        let sizes: &[f64] = if geo {
            &[1e-4, 0.01, 5.0]
        } else {
            &[1.0, 30.0, 300.0, 1000.0]
        };
        for e in &edges {
            for &s in sizes {
                for kx in -8..=8 {
                    for ky in -8..=8 {
                        let x0 = e[0] + kx as f64 * s / 8.0 - 0.5 * s;
                        let y0 = e[1] + ky as f64 * s / 8.0 - 0.5 * s;
                        let b = [x0, y0, x0 + s, y0 + s];
                        if !t.box_fits(b) {
                            refused += 1;
                            continue;
                        }
                        fitted += 1;
                        for i in 0..9 {
                            for j in 0..9 {
                                let p = [x0 + s * i as f64 / 8.0, y0 + s * j as f64 / 8.0];
                                assert!(ok(t, p), "{:?}: box {b:?} fits but {p:?} does not", t.crs);
                            }
                        }
                    }
                }
            }
        }
    }
    // Both answers occur: the boxes do straddle the edges.
    assert!(
        fitted > 100 && refused > 100,
        "{fitted} fitted, {refused} refused"
    );
}

#[test]
fn boxes_larger_than_the_limit_or_not_finite_are_left_to_the_vertices() {
    let u = utm33().metric_transform([457_000.0, 5_550_000.0]);
    let b = |x: f64, y: f64, s: f64| [x, y, x + s, y + s];
    assert!(u.box_fits(b(457_000.0, 5_550_000.0, BOX_CHECK_MAX)));
    assert!(!u.box_fits(b(457_000.0, 5_550_000.0, BOX_CHECK_MAX * 1.01)));
    assert!(!u.box_fits([f64::NAN, 5_550_000.0, 457_010.0, 5_550_010.0]));
    assert!(!u.box_fits([457_010.0, 5_550_000.0, 457_000.0, 5_550_010.0]));
    assert!(!u.box_fits(b(4.6e7, 5_550_000.0, 10.0)));
    // Geographic bounds are exact for any size.
    let g = Crs::Geographic { epsg: Some(4326) }.metric_transform([24.94, 60.17]);
    assert!(g.box_fits([-180.0, -90.0, 180.0, 90.0]));
    assert!(!g.box_fits([-180.0, -90.0, 180.0, 90.5]));
}
