//! WGS84 geodesy for the tileset's root transform, in f64: geodetic ↔ Earth-centred Earth-fixed
//! (ECEF) coordinates and the east-north-up frame at a point (3D Tiles 1.1, "Coordinate
//! Reference System": tile coordinates are ECEF metres, and a local east-north-up frame goes on
//! the ellipsoid through the root tile's `transform`).

use glam::{DMat4, DVec3, DVec4};

/// WGS84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// First eccentricity squared, `f(2 − f)`.
#[inline]
fn e2() -> f64 {
    WGS84_F * (2.0 - WGS84_F)
}

/// ECEF metres of a point at longitude `lon_deg`, latitude `lat_deg` (degrees) and `h_m`
/// metres above the WGS84 ellipsoid: `((N + h) cos φ cos λ, (N + h) cos φ sin λ,
/// (N(1 − e²) + h) sin φ)` with the prime-vertical radius `N = a / √(1 − e² sin² φ)`.
pub fn ecef_from_geodetic(lon_deg: f64, lat_deg: f64, h_m: f64) -> DVec3 {
    let (sl, cl) = lon_deg.to_radians().sin_cos();
    let (sp, cp) = lat_deg.to_radians().sin_cos();
    let n = WGS84_A / (1.0 - e2() * sp * sp).sqrt();
    DVec3::new(
        (n + h_m) * cp * cl,
        (n + h_m) * cp * sl,
        (n * (1.0 - e2()) + h_m) * sp,
    )
}

/// Longitude, latitude (degrees) and ellipsoidal height (metres) of an ECEF point: the
/// fixed-point iteration on the latitude, run until it changes by less than 1e-15 rad (a few
/// iterations anywhere off the Earth's centre).
pub fn geodetic_from_ecef(p: DVec3) -> (f64, f64, f64) {
    let lon = p.y.atan2(p.x);
    let r = (p.x * p.x + p.y * p.y).sqrt();
    let mut lat = p.z.atan2(r * (1.0 - e2()));
    let mut h = 0.0;
    for _ in 0..20 {
        let s = lat.sin();
        let n = WGS84_A / (1.0 - e2() * s * s).sqrt();
        h = if lat.cos().abs() > 1e-9 {
            r / lat.cos() - n
        } else {
            p.z.abs() - n * (1.0 - e2())
        };
        let next = p.z.atan2(r * (1.0 - e2() * n / (n + h)));
        let done = (next - lat).abs() < 1e-15;
        lat = next;
        if done {
            break;
        }
    }
    (lon.to_degrees(), lat.to_degrees(), h)
}

/// The east-north-up frame at a geodetic point as a 4×4 matrix taking local metres (x east,
/// y north, z up) to ECEF metres: columns east, north, up and the point's ECEF position.
pub fn ecef_from_enu(lon_deg: f64, lat_deg: f64, h_m: f64) -> DMat4 {
    let (sl, cl) = lon_deg.to_radians().sin_cos();
    let (sp, cp) = lat_deg.to_radians().sin_cos();
    let east = DVec4::new(-sl, cl, 0.0, 0.0);
    let north = DVec4::new(-sp * cl, -sp * sl, cp, 0.0);
    let up = DVec4::new(cp * cl, cp * sl, sp, 0.0);
    let o = ecef_from_geodetic(lon_deg, lat_deg, h_m);
    DMat4::from_cols(east, north, up, o.extend(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_points_are_exact() {
        let b = WGS84_A * (1.0 - WGS84_F);
        assert!(
            (ecef_from_geodetic(0.0, 0.0, 0.0) - DVec3::new(WGS84_A, 0.0, 0.0)).length() < 1e-9
        );
        assert!(
            (ecef_from_geodetic(90.0, 0.0, 10.0) - DVec3::new(0.0, WGS84_A + 10.0, 0.0)).length()
                < 1e-6
        );
        assert!((ecef_from_geodetic(0.0, 90.0, 0.0) - DVec3::new(0.0, 0.0, b)).length() < 1e-6);
        assert!((b - 6_356_752.314_245).abs() < 1e-6);
    }

    #[test]
    fn round_trip_within_a_micrometre() {
        for &(lon, lat, h) in &[
            (24.94, 60.17, 12.0),
            (14.39, 50.10, 230.0),
            (-122.4, 37.8, -30.0),
            (179.9, -89.5, 5000.0),
            (0.0, 0.0, 0.0),
        ] {
            let (lo, la, hh) = geodetic_from_ecef(ecef_from_geodetic(lon, lat, h));
            let back = ecef_from_geodetic(lo, la, hh);
            assert!((back - ecef_from_geodetic(lon, lat, h)).length() < 1e-6);
            assert!((lo - lon).abs() < 1e-10 && (la - lat).abs() < 1e-10 && (hh - h).abs() < 1e-6);
        }
    }

    #[test]
    fn enu_frame_is_orthonormal_with_up_along_the_ellipsoid_normal() {
        let m = ecef_from_enu(24.94, 60.17, 0.0);
        let (e, n, u) = (
            m.x_axis.truncate(),
            m.y_axis.truncate(),
            m.z_axis.truncate(),
        );
        assert!((e.cross(n) - u).length() < 1e-12);
        assert!(e.dot(n).abs() < 1e-12 && (u.length() - 1.0).abs() < 1e-12);
        // One metre up in the frame raises the ellipsoidal height by one metre.
        let p = m.transform_point3(DVec3::new(0.0, 0.0, 1.0));
        let (_, _, h) = geodetic_from_ecef(p);
        assert!((h - 1.0).abs() < 1e-6);
        // North goes north.
        let (_, lat, _) = geodetic_from_ecef(m.transform_point3(DVec3::new(0.0, 100.0, 0.0)));
        assert!(lat > 60.17);
    }
}
