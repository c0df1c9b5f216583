//! The metric transform on real data: Bubeneč in Web Mercator against its UTM 33N copy.

use blockwalk_importers::{shp, Crs, Layer};
use geo::{Area, MapCoords};
use geo_types::{Coord, Geometry};
use std::path::{Path, PathBuf};

fn data(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data")).join(rel)
}

fn centre(l: &Layer) -> [f64; 2] {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for f in &l.features {
        if let Geometry::Polygon(p) = &f.geometry {
            for c in &p.exterior().0 {
                lo = [lo[0].min(c.x), lo[1].min(c.y)];
                hi = [hi[0].max(c.x), hi[1].max(c.y)];
            }
        }
    }
    [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0]
}

#[test]
fn bubenec_areas_match_the_utm_copy() {
    let merc = shp::read(&data("bubenec/buildings.shp")).unwrap();
    let utm = shp::read(&data("bubenec_utm33n/buildings.shp")).unwrap();
    assert_eq!(merc.crs, Crs::WebMercator);
    let t = merc.crs.metric_transform(centre(&merc));
    let u = utm.crs.metric_transform(centre(&utm));
    assert!(u.is_identity() && !t.is_identity());
    assert_eq!(merc.features.len(), utm.features.len());
    let (mut total_merc, mut total_metric, mut total_utm) = (0.0f64, 0.0f64, 0.0f64);
    for (a, b) in merc.features.iter().zip(&utm.features) {
        assert_eq!(a.attributes["uID"], b.attributes["uID"]);
        let m = a.geometry.map_coords(|c| {
            let [x, y] = t.to_metric([c.x, c.y]);
            Coord { x, y }
        });
        let (am, au) = (m.unsigned_area(), b.geometry.unsigned_area());
        assert!(
            (am - au).abs() / au < 0.003,
            "uID {:?}: {am} vs {au}",
            a.attributes["uID"]
        );
        total_merc += a.geometry.unsigned_area();
        total_metric += am;
        total_utm += au;
    }
    println!(
        "areas: mercator {total_merc:.1}, local TM {total_metric:.1} m², UTM {total_utm:.1} m²"
    );
    // data/README.md: 104,843 in Mercator units, 43,151 m² in UTM.
    assert!((total_merc - 104_843.0).abs() < 1.0, "{total_merc}");
    assert!((total_utm - 43_151.0).abs() < 1.0, "{total_utm}");
    assert!(
        (total_metric - 43_151.0).abs() / 43_151.0 < 0.005,
        "{total_metric}"
    );
    // UTM 33N at 14.4°E has a scale of about 0.99962 (k0 = 0.9996 and ~43 km off the central
    // meridian), so its areas are about 0.08 % smaller than true ground areas.
    let ratio: f64 = total_utm / total_metric;
    assert!((ratio - 0.99924).abs() < 0.0003, "{ratio}");
    // Round trip on every vertex.
    for f in &merc.features {
        if let Geometry::Polygon(p) = &f.geometry {
            for c in &p.exterior().0 {
                let m = t.to_metric([c.x, c.y]);
                let back = t.from_metric(m);
                assert!((back[0] - c.x).abs() < 1e-6 && (back[1] - c.y).abs() < 1e-6);
            }
        }
    }
    println!("{}", t.describe());
    assert!(t
        .describe()
        .starts_with("EPSG:3857 Web Mercator: reprojected"));
}
