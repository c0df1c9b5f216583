//! Geometric primitives shared by every stage; knows nothing of cities.
//!
//! - [`Aabb3`], [`BoundingSphere`]: bounding volumes in f64.
//! - [`frustum`]: view-frustum planes and the sphere / box / box∩sphere tests.
//! - [`predicates`]: robust orientation and point-in-polygon.
//! - [`repair`]: ring validation and repair for footprints.

pub mod bounds;
pub mod camera;
pub mod frustum;
pub mod predicates;
pub mod repair;

pub use bounds::{Aabb3, BoundingSphere};
pub use camera::Camera;
pub use frustum::{CoherenceState, Containment, Frustum, Plane, PlaneMask, ALL_PLANES};
