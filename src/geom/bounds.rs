//! Axis-aligned boxes and spheres in f64.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// An axis-aligned box. Empty when any `min > max`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Aabb3 {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb3 {
    /// The empty box (the identity of [`Aabb3::union`]).
    pub const EMPTY: Aabb3 = Aabb3 {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// A box from two corners.
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Self { min, max }
    }
    /// The smallest box holding all points (empty for no points).
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.including(p))
    }
    /// True when the box holds no point.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    /// This box grown to hold `p`.
    pub fn including(self, p: DVec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }
    /// The smallest box holding both.
    pub fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }
    /// Centre point.
    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }
    /// Edge lengths.
    pub fn extent(&self) -> DVec3 {
        self.max - self.min
    }
    /// True when the boxes share at least one point.
    pub fn intersects(&self, o: &Self) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }
    /// True when `p` lies in the closed box.
    pub fn contains_point(&self, p: DVec3) -> bool {
        self.min.cmple(p).all() && p.cmple(self.max).all()
    }
    /// The eight corners.
    pub fn corners(&self) -> [DVec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            DVec3::new(a.x, a.y, a.z),
            DVec3::new(b.x, a.y, a.z),
            DVec3::new(a.x, b.y, a.z),
            DVec3::new(b.x, b.y, a.z),
            DVec3::new(a.x, a.y, b.z),
            DVec3::new(b.x, a.y, b.z),
            DVec3::new(a.x, b.y, b.z),
            DVec3::new(b.x, b.y, b.z),
        ]
    }
}

/// A sphere.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoundingSphere {
    /// Centre.
    pub center: DVec3,
    /// Radius (≥ 0).
    pub radius: f64,
}

impl BoundingSphere {
    /// The sphere circumscribing a box (centre at the box centre).
    pub fn from_aabb(b: &Aabb3) -> Self {
        Self {
            center: b.center(),
            radius: b.extent().length() * 0.5,
        }
    }
    /// The smallest sphere holding both spheres.
    pub fn merge(self, o: Self) -> Self {
        let d = o.center - self.center;
        let dist = d.length();
        if dist + o.radius <= self.radius {
            return self;
        }
        if dist + self.radius <= o.radius {
            return o;
        }
        let radius = (dist + self.radius + o.radius) * 0.5;
        let center = self.center + d * ((radius - self.radius) / dist);
        // Round the radius up by a relative epsilon so that floating error never makes it
        // non-conservative.
        Self {
            center,
            radius: radius * (1.0 + 1e-12) + 1e-9,
        }
    }
    /// True when `p` lies in the closed ball.
    pub fn contains_point(&self, p: DVec3) -> bool {
        (p - self.center).length_squared() <= self.radius * self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_sphere_holds_both() {
        let a = BoundingSphere {
            center: DVec3::ZERO,
            radius: 1.0,
        };
        let b = BoundingSphere {
            center: DVec3::new(5.0, 0.0, 0.0),
            radius: 2.0,
        };
        let m = a.merge(b);
        assert!(m.contains_point(DVec3::new(-1.0, 0.0, 0.0)));
        assert!(m.contains_point(DVec3::new(7.0, 0.0, 0.0)));
        assert!((m.radius - 4.0).abs() < 1e-6);
    }

    #[test]
    fn empty_box_is_union_identity() {
        let b = Aabb3::new(DVec3::ZERO, DVec3::ONE);
        assert_eq!(Aabb3::EMPTY.union(b), b);
        assert!(Aabb3::EMPTY.is_empty());
    }
}
