//! Street classes, widths and colours.

use blockwalk_importers::{AttrValue, Attributes};
use serde::Serialize;

use crate::city::model::Street;

use super::*;

/// The classes of the street layer, from `highway` (OSM) or `class`/`type` attributes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StreetClass {
    /// Motorways, trunk, primary and secondary roads.
    Major,
    /// Tertiary, residential, unclassified and living streets; the default.
    #[default]
    Minor,
    /// Service roads and links.
    Service,
    /// Pedestrian streets and squares.
    Pedestrian,
    /// Footways, paths, cycleways, steps, tracks.
    Path,
}

impl StreetClass {
    /// The class of a street's attributes (`highway`, `class`, `type`, `fclass`; unknown →
    /// [`StreetClass::Minor`]).
    pub fn from_attributes(attrs: &Attributes) -> StreetClass {
        for key in ["highway", "class", "fclass", "type"] {
            if let Some(AttrValue::Text(t)) = attrs.get(key) {
                let t = t.trim().to_ascii_lowercase();
                let t = t.strip_suffix("_link").unwrap_or(&t);
                return match t {
                    "motorway" | "trunk" | "primary" | "secondary" => StreetClass::Major,
                    "service" | "services" => StreetClass::Service,
                    "pedestrian" | "plaza" | "square" => StreetClass::Pedestrian,
                    "footway" | "path" | "cycleway" | "steps" | "track" | "trail" | "bridleway"
                    | "corridor" => StreetClass::Path,
                    _ => StreetClass::Minor,
                };
            }
        }
        StreetClass::Minor
    }

    /// Width (m) when the street has no usable `width` or `lanes` attribute.
    pub fn default_width_m(self) -> f64 {
        match self {
            StreetClass::Major => 14.0,
            StreetClass::Minor => 8.0,
            StreetClass::Service => 4.0,
            StreetClass::Pedestrian => 8.0,
            StreetClass::Path => 2.0,
        }
    }
}

/// Metres per lane when the width comes from `lanes` (plus one lane's worth of kerbs).
pub const LANE_M: f64 = 3.25;

/// A street's width (m): its `width` attribute when finite and in (0, 80] m, else
/// `(lanes + 1) × LANE_M` from a `lanes` attribute in [1, 12], else its class default
/// ([`StreetClass::default_width_m`]).
pub fn street_width_m(attrs: &Attributes) -> f64 {
    let num = |k: &str| attrs.get(k).and_then(AttrValue::as_f64);
    if let Some(w) = num("width").filter(|w| w.is_finite() && *w > 0.0 && *w <= 80.0) {
        return w;
    }
    if let Some(l) = num("lanes").filter(|l| l.is_finite() && (1.0..=12.0).contains(l)) {
        return (l.round() + 1.0) * LANE_M;
    }
    StreetClass::from_attributes(attrs).default_width_m()
}

/// Unlit ground colour of a street class.
pub fn street_color(class: StreetClass) -> [f32; 3] {
    match class {
        StreetClass::Major => rgb(82, 84, 90),
        StreetClass::Minor => rgb(100, 100, 104),
        StreetClass::Service => rgb(118, 116, 114),
        StreetClass::Pedestrian => rgb(176, 166, 150),
        StreetClass::Path => rgb(190, 176, 144),
    }
}

/// True for streets that are not on the ground: tunnels (`tunnel` attribute other than `no`).
/// Bridges are drawn on the ground (a plan view of the deck).
pub fn street_below_ground(s: &Street) -> bool {
    matches!(s.attributes.get("tunnel"), Some(AttrValue::Text(t)) if t != "no")
        || matches!(s.attributes.get("tunnel"), Some(AttrValue::Bool(true)))
}
