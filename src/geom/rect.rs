//! Plan-view rectangles: the `[x_min, y_min, x_max, y_max]` boxes of footprints, blocks and
//! tiles, with their union, overlap and centre written once.

use serde::{Deserialize, Serialize};

/// An axis-aligned rectangle in the plane, closed (its sides belong to it). Serialised as the
/// array `[x_min, y_min, x_max, y_max]`, the layout the crate's files use.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "[f64; 4]", into = "[f64; 4]")]
pub struct Rect {
    /// Lower-left corner `[x, y]`.
    pub min: [f64; 2],
    /// Upper-right corner `[x, y]`.
    pub max: [f64; 2],
}

impl Rect {
    /// The rectangle of `[x_min, y_min, x_max, y_max]`.
    pub const fn from_array(b: [f64; 4]) -> Self {
        Self {
            min: [b[0], b[1]],
            max: [b[2], b[3]],
        }
    }

    /// `[x_min, y_min, x_max, y_max]`.
    pub const fn to_array(self) -> [f64; 4] {
        [self.min[0], self.min[1], self.max[0], self.max[1]]
    }

    /// The degenerate rectangle of one point.
    pub const fn point(p: [f64; 2]) -> Self {
        Self { min: p, max: p }
    }

    /// The smallest rectangle holding both (componentwise `min` and `max`).
    pub fn union(self, o: Self) -> Self {
        Self {
            min: [self.min[0].min(o.min[0]), self.min[1].min(o.min[1])],
            max: [self.max[0].max(o.max[0]), self.max[1].max(o.max[1])],
        }
    }

    /// `o` grown into `acc`: `acc ∪ o`, or `o` when there is nothing yet.
    pub fn grow(acc: Option<Self>, o: Self) -> Self {
        acc.map_or(o, |a| a.union(o))
    }

    /// True when the two share a point (touching counts).
    pub fn intersects(&self, o: &Self) -> bool {
        self.min[0] <= o.max[0]
            && o.min[0] <= self.max[0]
            && self.min[1] <= o.max[1]
            && o.min[1] <= self.max[1]
    }

    /// True when `p` lies in the rectangle or on its sides.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        self.min[0] <= p[0] && p[0] <= self.max[0] && self.min[1] <= p[1] && p[1] <= self.max[1]
    }

    /// The centre, `(min + max) / 2` per axis.
    pub fn centre(&self) -> [f64; 2] {
        [
            (self.min[0] + self.max[0]) * 0.5,
            (self.min[1] + self.max[1]) * 0.5,
        ]
    }
}

impl From<[f64; 4]> for Rect {
    fn from(b: [f64; 4]) -> Self {
        Self::from_array(b)
    }
}

impl From<Rect> for [f64; 4] {
    fn from(r: Rect) -> Self {
        r.to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_overlap_and_centre() {
        let a = Rect::from_array([0.0, 0.0, 2.0, 1.0]);
        let b = Rect::from_array([2.0, -1.0, 3.0, 0.5]);
        assert_eq!(a.union(b).to_array(), [0.0, -1.0, 3.0, 1.0]);
        assert_eq!(Rect::grow(None, b), b);
        assert_eq!(Rect::grow(Some(a), b), a.union(b));
        assert!(a.intersects(&b) && b.intersects(&a));
        assert!(!a.intersects(&Rect::point([2.5, 0.0])));
        assert!(a.contains([2.0, 1.0]) && !a.contains([2.0, 1.5]));
        assert_eq!(a.centre(), [1.0, 0.5]);
        let json = serde_json::to_string(&a).unwrap();
        assert_eq!(json, "[0.0,0.0,2.0,1.0]");
        assert_eq!(serde_json::from_str::<Rect>(&json).unwrap(), a);
    }
}
