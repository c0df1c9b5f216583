//! The local frame: world coordinates (f64) relative to an origin, for everything that goes to
//! f32 and the GPU.

use super::Xy;
use geo_types::{Coord, LineString, Polygon};
use glam::{DMat4, DVec2, DVec3, Mat4, Vec3};
use serde::Serialize;

/// The local frame: world coordinates (f64) minus `origin` are what goes to f32 and the GPU.
///
/// Near 6e6 m an f32 keeps only about 0.5 m; relative to an origin inside the city it keeps
/// millimetres. Every conversion between world and local coordinates, and every rounding of a
/// local position (or a matrix acting on local positions) to f32, goes through the methods here:
///
/// | from | to | method |
/// |---|---|---|
/// | world f64 | local f32 | [`LocalFrame::to_local`] |
/// | world f64 | local f64 | [`LocalFrame::to_local_f64`], plan view [`LocalFrame::to_local_xy`], [`LocalFrame::to_local_polygon`] |
/// | local f64 | local f32 | [`LocalFrame::round_to_f32`], [`LocalFrame::round_matrix_to_f32`] |
/// | local f64 / f32 | world f64 | [`LocalFrame::to_world`], [`LocalFrame::to_world_f32`] |
///
/// # Examples
/// ```
/// use blockwalk::geom::LocalFrame;
/// use glam::DVec3;
/// let frame = LocalFrame { origin: DVec3::new(500_000.0, 5_500_000.0, 0.0) };
/// let world = DVec3::new(500_012.345, 5_500_006.789, 3.0);
/// // f32 straight from the world coordinates would be off by decimetres; locally it is exact to
/// // well under a millimetre.
/// let local = frame.to_local(world);
/// assert!((frame.to_world_f32(local) - world).length() < 1e-3);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LocalFrame {
    /// World coordinates of the local origin (x, y metric; z = 0 is the ground).
    pub origin: DVec3,
}

impl LocalFrame {
    /// World (f64) → local (f32): the origin is subtracted in f64, then the one rounding to f32.
    pub fn to_local(&self, world: DVec3) -> Vec3 {
        Self::round_to_f32(self.to_local_f64(world))
    }
    /// World (f64) → local (f64), for culling and anything that stays in f64.
    pub fn to_local_f64(&self, world: DVec3) -> DVec3 {
        world - self.origin
    }
    /// Plan view: a world point (x, y) → local (f64) x, y.
    pub fn to_local_xy<P: Xy>(&self, world: P) -> DVec2 {
        DVec2::new(world.x() - self.origin.x, world.y() - self.origin.y)
    }
    /// Plan view: a world polygon → the same polygon in local (f64) coordinates (rings and
    /// their order kept).
    pub fn to_local_polygon(&self, world: &Polygon<f64>) -> Polygon<f64> {
        let ring = |l: &LineString<f64>| -> LineString<f64> {
            l.0.iter()
                .map(|&c| self.to_local_xy(c).to::<Coord<f64>>())
                .collect::<Vec<_>>()
                .into()
        };
        Polygon::new(
            ring(world.exterior()),
            world.interiors().iter().map(ring).collect(),
        )
    }
    /// Local (f64) → local (f32): the one place where a local position becomes f32 (round to
    /// nearest). Directions (normals, the sun) are the same in both frames and are rounded here
    /// too.
    pub fn round_to_f32(local: DVec3) -> Vec3 {
        local.as_vec3()
    }
    /// A matrix that acts on local positions (e.g. `clip_from_local` of a camera in the local
    /// frame), rounded to f32 for the GPU.
    pub fn round_matrix_to_f32(local_matrix: DMat4) -> Mat4 {
        local_matrix.as_mat4()
    }
    /// Local (f64) → world (f64).
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        local + self.origin
    }
    /// Local (f32, e.g. a mesh vertex) → world (f64).
    pub fn to_world_f32(&self, local: Vec3) -> DVec3 {
        self.to_world(local.as_dvec3())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::polygon;

    fn frame() -> LocalFrame {
        LocalFrame {
            origin: DVec3::new(463_512.25, 5_546_077.5, 0.0),
        }
    }

    #[test]
    fn every_route_to_local_agrees_bit_for_bit() {
        let f = frame();
        for (x, y, z) in [
            (463_600.123, 5_546_000.987, 12.5),
            (0.0, 0.0, 0.0),
            (-1e7, 1e7, -3.0),
        ] {
            let w = DVec3::new(x, y, z);
            let l64 = f.to_local_f64(w);
            // The hand-written conversion these methods replace.
            assert_eq!(
                l64,
                DVec3::new(x - f.origin.x, y - f.origin.y, z - f.origin.z)
            );
            let xy = f.to_local_xy(Coord { x, y });
            assert_eq!(xy, l64.truncate());
            assert_eq!(f.to_local_xy(DVec2::new(x, y)), xy);
            let l32 = f.to_local(w);
            assert_eq!(l32, LocalFrame::round_to_f32(l64));
            assert_eq!(
                l32,
                Vec3::new(l64.x as f32, l64.y as f32, l64.z as f32),
                "round to nearest, per component"
            );
            assert_eq!(
                f.to_world(l64),
                DVec3::new(l64.x + f.origin.x, l64.y + f.origin.y, z)
            );
            assert_eq!(f.to_world_f32(l32), f.to_world(l32.as_dvec3()));
        }
    }

    #[test]
    fn polygons_move_ring_by_ring() {
        let f = frame();
        let o = f.origin;
        let p = polygon!(
            exterior: [(x: o.x, y: o.y), (x: o.x + 10.0, y: o.y), (x: o.x + 10.0, y: o.y + 10.0)],
            interiors: [[(x: o.x + 6.0, y: o.y + 1.0), (x: o.x + 9.0, y: o.y + 1.0), (x: o.x + 9.0, y: o.y + 4.0)]],
        );
        let l = f.to_local_polygon(&p);
        assert_eq!(l.exterior().0[1], Coord { x: 10.0, y: 0.0 });
        assert_eq!(l.interiors()[0].0[2], Coord { x: 9.0, y: 4.0 });
        assert_eq!(l.exterior().0.len(), p.exterior().0.len());
        assert_eq!(l.interiors().len(), 1);
    }

    #[test]
    fn local_f32_keeps_millimetres_where_world_f32_does_not() {
        let f = frame();
        let w = DVec3::new(f.origin.x + 123.456, f.origin.y - 654.321, 7.0);
        let local = f.to_local(w);
        assert!((f.to_world_f32(local) - w).length() < 1e-4);
        let naive = w.as_vec3().as_dvec3();
        assert!(
            (naive - w).length() > 0.01,
            "f32 world coordinates lose centimetres"
        );
    }

    #[test]
    fn matrices_round_per_element() {
        let m = DMat4::from_cols_array(&[
            0.1,
            0.2,
            0.3,
            0.4,
            1.0 / 3.0,
            2.0,
            3.0,
            4.0,
            5.0,
            6.0,
            7.0,
            8.0,
            9.0,
            10.0,
            11.0,
            1e-9,
        ]);
        let r = LocalFrame::round_matrix_to_f32(m);
        let want: Vec<f32> = m.to_cols_array().iter().map(|&v| v as f32).collect();
        assert_eq!(r.to_cols_array().to_vec(), want);
    }
}
