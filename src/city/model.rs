//! City model types.

use crate::geom::Xy;
use blockwalk_importers::{Attributes, MetricTransform};
use geo_types::{Coord, LineString, Polygon};
use glam::{DMat4, DVec2, DVec3, Mat4, Vec3};
use serde::Serialize;

/// Index of a building in [`City::buildings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct BuildingId(pub u32);

/// Where a building's height came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HeightSource {
    /// A height attribute in metres.
    Height,
    /// A levels attribute × storey height.
    Levels,
    /// The documented default rule.
    Default,
}

/// A building: a footprint prism from `min_height_m` to `height_m` above its ground, which lies
/// at `base_m` in the world frame (0 for a city without terrain; the terrain under the
/// footprint by the base rule of [`crate::city::build::BuildOptions`] otherwise). World z of the
/// prism: [`Building::bottom_z`] to [`Building::top_z`].
#[derive(Clone, Debug)]
pub struct Building {
    /// Index in [`City::buildings`].
    pub id: BuildingId,
    /// The feature's id in its source (`layer:fid`, or the OSM id).
    pub source_id: String,
    /// Footprint in metric world coordinates: exterior counter-clockwise, holes clockwise, rings
    /// closed, valid (repaired on import).
    pub footprint: Polygon<f64>,
    /// Top of the prism above ground, metres.
    pub height_m: f64,
    /// Bottom of the prism above ground, metres (0 for most buildings).
    pub min_height_m: f64,
    /// World z of the ground the building stands on, metres (0 without terrain). Heights stay
    /// heights above this ground.
    pub base_m: f64,
    /// Where `height_m` came from.
    pub height_source: HeightSource,
    /// The source attributes.
    pub attributes: Attributes,
}

impl Building {
    /// World z of the prism's bottom: `base_m + min(min_height_m, height_m)`.
    #[inline]
    pub fn bottom_z(&self) -> f64 {
        self.base_m + self.min_height_m.min(self.height_m)
    }
    /// World z of the prism's top (the roof): `base_m + max(height_m, min_height_m)`.
    #[inline]
    pub fn top_z(&self) -> f64 {
        self.base_m + self.height_m.max(self.min_height_m)
    }
}

/// A street centre line in metric world coordinates.
#[derive(Clone, Debug)]
pub struct Street {
    /// The feature's id in its source.
    pub source_id: String,
    /// Centre line, metric world coordinates.
    pub line: LineString<f64>,
    /// True for bridges and tunnels. They bound blocks like any street unless the block stage is
    /// asked to honour grade separation (`blocks::BlockOptions::grade_separation`).
    pub grade_separated: bool,
    /// The source attributes.
    pub attributes: Attributes,
}

/// A cadastral parcel in metric world coordinates.
#[derive(Clone, Debug)]
pub struct Parcel {
    /// The feature's id in its source.
    pub source_id: String,
    /// Parcel polygon, metric world coordinates (exterior CCW, holes CW).
    pub polygon: Polygon<f64>,
    /// The source attributes.
    pub attributes: Attributes,
}

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
/// use blockwalk::city::LocalFrame;
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

/// What building the city did with every input feature.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CityReport {
    /// Footprint features read from the files.
    pub buildings_read: usize,
    /// Footprints imported as they were.
    pub buildings_imported: usize,
    /// Footprints imported after repair, with what was done.
    pub buildings_repaired: Vec<RepairNote>,
    /// Footprints refused, with the reason.
    pub buildings_refused: Vec<RefusalNote>,
    /// Buildings per height source.
    pub height_sources: std::collections::BTreeMap<String, usize>,
    /// The refused footprints grouped by reason, with counts.
    pub refused_by_reason: Vec<blockwalk_importers::ReasonGroup>,
    /// Height attributes that cannot be a building's height (negative, zero, not a number, above
    /// 1000 m), per building; the next height source was used for them.
    pub implausible_heights: Vec<crate::city::build::HeightNote>,
    /// The CRS found and what was done with it.
    pub crs: String,
    /// Why the street layer that was given yields no street (every feature refused or excluded),
    /// so that blocks cannot come from it; `None` when it is usable or none was given.
    pub street_layer_unusable: Option<String>,
    /// The same for the parcel layer.
    pub parcel_layer_unusable: Option<String>,
    /// Street features read (0 without a street layer).
    pub streets_read: usize,
    /// Street features (or parts) refused, with the reason (the importer's refusals included).
    pub streets_refused: Vec<RefusalNote>,
    /// Parcel features read (0 without a parcel layer).
    pub parcels_read: usize,
    /// Parcel features (or parts) refused, with the reason.
    pub parcels_refused: Vec<RefusalNote>,
    /// Where the local origin is and how far the model reaches from it (f32 precision).
    pub frame: crate::city::build::FrameReport,
    /// Other notes (per layer).
    pub notes: Vec<String>,
}

/// A repaired feature.
#[derive(Clone, Debug, Serialize)]
pub struct RepairNote {
    /// Source id.
    pub id: String,
    /// What was done.
    pub what: String,
}

/// A refused feature.
#[derive(Clone, Debug, Serialize)]
pub struct RefusalNote {
    /// Source id.
    pub id: String,
    /// Why.
    pub reason: String,
}

/// A city: buildings, streets and parcels in metric world coordinates.
///
/// # Examples
/// ```
/// use blockwalk::scene::CitySource;
/// use std::path::Path;
///
/// // The bundled Bubeneč footprints (a cadastral sample in EPSG:3857) with their streets.
/// let source = CitySource::parse(
///     Path::new("data/bubenec/buildings.shp"),
///     Some("data/bubenec/streets.shp".into()),
///     None,
///     &[],
///     0,
/// )
/// .unwrap();
/// let city = source.load(&Default::default(), &mut |_| {}).unwrap().city;
/// assert_eq!(city.buildings.len(), 144);
/// assert!(!city.streets.is_empty());
/// // Heights are metres above the ground; coordinates are metres in the metric world frame.
/// assert!(city.buildings.iter().all(|b| b.height_m > 0.0));
/// ```
#[derive(Clone, Debug)]
pub struct City {
    /// Name (from the footprint file).
    pub name: String,
    /// Maps the input's own coordinates to the metric world coordinates used here, and back.
    pub transform: MetricTransform,
    /// The local frame for f32 geometry (origin at the median of the footprints' centres, see
    /// [`crate::city::build::robust_origin`]).
    pub frame: LocalFrame,
    /// Buildings; `buildings[i].id == BuildingId(i)`.
    pub buildings: Vec<Building>,
    /// Street centre lines (empty when no street layer was given).
    pub streets: Vec<Street>,
    /// Cadastral parcels (empty when none were given).
    pub parcels: Vec<Parcel>,
    /// The import account.
    pub report: CityReport,
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
