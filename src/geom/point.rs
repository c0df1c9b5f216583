//! The plan-view point vocabulary: one small trait, [`Xy`], so that every 2D predicate and helper
//! of [`crate::geom`] is written once and works on both point types of the crate.
//!
//! Two point types meet in the pipeline: [`geo_types::Coord`] (imported layers, footprints,
//! street graphs, block polygons: world coordinates) and [`glam::DVec2`] (the local frame:
//! occluders, the cull map, routes). Rather than keeping one copy of each predicate per type, or
//! converting (and allocating) at every call, the predicates are generic over [`Xy`]. Conversions
//! between the two are exact (both are a pair of `f64`), so a predicate gives the same answer
//! whichever type it is called with.

use geo_types::Coord;
use glam::DVec2;

/// A point in the plane with `f64` coordinates (metres in this crate).
pub trait Xy: Copy {
    /// The x coordinate (east).
    fn x(self) -> f64;
    /// The y coordinate (north).
    fn y(self) -> f64;
    /// The point with these coordinates.
    fn from_xy(x: f64, y: f64) -> Self;

    /// The same point as another point type (exact).
    #[inline]
    fn to<Q: Xy>(self) -> Q {
        Q::from_xy(self.x(), self.y())
    }

    /// True when both coordinates are finite.
    #[inline]
    fn is_finite_xy(self) -> bool {
        self.x().is_finite() && self.y().is_finite()
    }
}

impl Xy for Coord<f64> {
    #[inline]
    fn x(self) -> f64 {
        self.x
    }
    #[inline]
    fn y(self) -> f64 {
        self.y
    }
    #[inline]
    fn from_xy(x: f64, y: f64) -> Self {
        Coord { x, y }
    }
}

impl Xy for DVec2 {
    #[inline]
    fn x(self) -> f64 {
        self.x
    }
    #[inline]
    fn y(self) -> f64 {
        self.y
    }
    #[inline]
    fn from_xy(x: f64, y: f64) -> Self {
        DVec2::new(x, y)
    }
}

impl Xy for geo_types::Point<f64> {
    #[inline]
    fn x(self) -> f64 {
        self.0.x
    }
    #[inline]
    fn y(self) -> f64 {
        self.0.y
    }
    #[inline]
    fn from_xy(x: f64, y: f64) -> Self {
        geo_types::Point::new(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_exact_both_ways() {
        let c = Coord {
            x: 500_000.123_456_789,
            y: -5.4e6 - 1.0 / 3.0,
        };
        let v: DVec2 = c.to();
        assert_eq!((v.x, v.y), (c.x, c.y));
        let back: Coord<f64> = v.to();
        assert_eq!(back, c);
        assert!(c.is_finite_xy());
        assert!(!DVec2::new(f64::NAN, 0.0).is_finite_xy());
    }
}
