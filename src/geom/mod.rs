//! Geometric primitives shared by every stage; knows nothing of cities.
//!
//! Each predicate and helper exists once, here; the other stages call it. The plan-view ones are
//! generic over the small point trait [`Xy`], implemented for `geo_types::Coord` (world
//! coordinates of the imported layers) and `glam::DVec2` (the local frame), so neither side
//! converts or allocates to use them.
//!
//! - [`Aabb3`], [`BoundingSphere`]: bounding volumes in f64.
//! - [`frame`]: [`LocalFrame`], world (f64) ↔ local (f64, f32) coordinates: the one place where
//!   the origin is subtracted and positions become f32.
//! - [`frustum`]: view-frustum planes and the sphere / box / box∩sphere tests.
//! - [`point`]: the [`Xy`] point trait.
//! - [`predicates`]: robust orientation, signed area, point in ring / polygon, segment crossing.
//! - [`hull`]: exact convex hull.
//! - [`segment`]: distances from a point to a segment and to a rectangle.
//! - [`clip`]: clipping a polygon against a half-space (Sutherland–Hodgman step).
//! - [`tolerance`]: the snapping tolerances, with their reasons.
//! - [`repair`]: ring validation and repair for footprints.

pub mod bounds;
pub mod camera;
pub mod clip;
pub mod frame;
pub mod frustum;
pub mod hull;
pub mod point;
pub mod predicates;
pub mod rect;
pub mod repair;
pub mod segment;
pub mod tolerance;

pub use bounds::{Aabb3, BoundingSphere};
pub use camera::Camera;
pub use frame::LocalFrame;
pub use frustum::{CoherenceState, Containment, Frustum, Plane, PlaneMask, ALL_PLANES};
pub use point::Xy;
pub use rect::Rect;
