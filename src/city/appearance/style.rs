//! Building styles: kinds, palettes, the per-building style and the facade pattern.

use std::hash::Hasher;

use blockwalk_importers::{AttrValue, Attributes};
use geo_types::Coord;
use glam::Vec3;
use serde::Serialize;

use crate::city::model::Building;

use super::*;

/// What a building is used for, from its `building` (OSM) or `type` attribute.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BuildingKind {
    /// Homes: apartments, houses, dormitories, hotels.
    Residential,
    /// Shops and offices.
    Commercial,
    /// Industry, warehouses, service buildings, garages, sheds.
    Industrial,
    /// Public buildings: museums, churches, schools, stations, government.
    Civic,
    /// Unknown or another use (`building=yes`, no attribute).
    #[default]
    Other,
}

impl BuildingKind {
    /// The kind of a building's attributes (keys `building`, `building:use`, `type`; the first
    /// one that names a known use wins).
    pub fn from_attributes(attrs: &Attributes) -> BuildingKind {
        for key in KIND_KEYS {
            if let Some(AttrValue::Text(t)) = attrs.get(key) {
                let k = Self::from_tag(t);
                if k != BuildingKind::Other {
                    return k;
                }
            }
        }
        BuildingKind::Other
    }

    /// The kind of one tag value (OSM `building=*` vocabulary, case-insensitive).
    pub fn from_tag(tag: &str) -> BuildingKind {
        match tag.trim().to_ascii_lowercase().as_str() {
            "apartments" | "residential" | "house" | "detached" | "semidetached_house"
            | "terrace" | "dormitory" | "hotel" | "bungalow" | "cabin" | "farm" => {
                BuildingKind::Residential
            }
            "commercial" | "retail" | "office" | "kiosk" | "supermarket" | "shop" | "mall" => {
                BuildingKind::Commercial
            }
            "industrial" | "warehouse" | "service" | "garage" | "garages" | "shed" | "hangar"
            | "factory" | "storage_tank" | "transformer_tower" | "parking" | "roof"
            | "glasshouse" | "greenhouse" => BuildingKind::Industrial,
            "public" | "museum" | "church" | "chapel" | "cathedral" | "civic" | "government"
            | "school" | "university" | "college" | "hospital" | "train_station"
            | "transportation" | "theatre" | "library" | "religious" | "fire_station" => {
                BuildingKind::Civic
            }
            _ => BuildingKind::Other,
        }
    }

    pub(super) fn index(self) -> usize {
        self as usize
    }
}

/// Facade palettes per kind (8-bit levels), indexed by hash bits 0..3.
const FACADES: [[[u8; 3]; 4]; 5] = [
    // Residential: plaster tones.
    [
        [222, 205, 170],
        [214, 180, 152],
        [204, 202, 190],
        [232, 218, 188],
    ],
    // Commercial: greys and stone.
    [
        [200, 200, 198],
        [172, 178, 184],
        [216, 210, 198],
        [152, 162, 172],
    ],
    // Industrial: concrete and brick.
    [
        [172, 166, 156],
        [150, 120, 104],
        [186, 182, 172],
        [140, 146, 150],
    ],
    // Civic: light stone.
    [
        [226, 216, 192],
        [210, 196, 166],
        [236, 228, 210],
        [200, 190, 176],
    ],
    // Other.
    [
        [214, 200, 172],
        [196, 190, 180],
        [220, 190, 160],
        [184, 184, 176],
    ],
];

/// Roof palettes per kind, indexed by hash bits 8..9.
pub(super) const ROOFS: [[[u8; 3]; 4]; 5] = [
    // Residential: tiles, dark sheet metal.
    [[150, 70, 55], [96, 90, 90], [122, 80, 62], [140, 64, 52]],
    // Commercial: flat grey.
    [
        [122, 122, 126],
        [140, 140, 140],
        [108, 112, 118],
        [130, 128, 122],
    ],
    // Industrial: light sheet metal.
    [
        [166, 168, 170],
        [132, 136, 140],
        [150, 150, 146],
        [118, 122, 126],
    ],
    // Civic: copper and slate.
    [[96, 140, 120], [80, 86, 96], [104, 150, 128], [90, 92, 100]],
    // Other.
    [
        [130, 110, 100],
        [110, 110, 116],
        [142, 96, 80],
        [120, 118, 112],
    ],
];

/// Window glass colours, indexed by hash bits 12..13.
const WINDOWS: [[u8; 3]; 4] = [[58, 70, 88], [74, 84, 96], [48, 58, 70], [66, 74, 80]];

/// Bay width (m) per kind for hash bits 16..17 = 0, and the step per unit of those bits.
const BAYS: [(f32, f32); 5] = [
    (3.0, 0.25),
    (2.5, 0.25),
    (6.0, 1.0),
    (3.5, 0.25),
    (3.0, 0.25),
];
/// Half the window width, as a fraction of the bay, per kind.
const WINDOW_HALF: [f32; 5] = [0.25, 0.375, 0.1875, 0.25, 0.25];

/// Everything [`facade_color`] and [`roof_color`] need to know about one building (or one flat
/// ground surface, see [`BuildingStyle::flat`]).
///
/// # Units
/// Colours linear RGB in `[0, 1]`, lengths metres, `inv_*` per metre.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BuildingStyle {
    /// What the building is used for.
    pub kind: BuildingKind,
    /// Wall colour between windows (upper storeys).
    pub facade: [f32; 3],
    /// Window glass colour.
    pub window: [f32; 3],
    /// Roof colour (for a flat ground surface: its colour).
    pub roof: [f32; 3],
    /// Storey height, metres (> 0).
    pub storey_height_m: f32,
    /// `1 / storey_height_m`, rounded once here; the shader gets this value.
    pub inv_storey_m: f32,
    /// Storeys with windows; 0 for a plain wall (and for ground surfaces).
    pub levels: u32,
    /// Bay width (one window and one pier), metres.
    pub bay_m: f32,
    /// `1 / bay_m`, rounded once here.
    pub inv_bay_m: f32,
    /// Half the window width as a fraction of the bay, in `(0, 0.5)`.
    pub window_half: f32,
    /// Local z of the ground the building stands on (its base; 0 without terrain): storeys
    /// count from here.
    pub ground_z: f32,
}

impl Default for BuildingStyle {
    /// A plain light grey wall without windows and a grey roof.
    fn default() -> Self {
        Self::flat(rgb(200, 198, 190), rgb(120, 120, 120))
    }
}

impl BuildingStyle {
    /// A style without windows: walls `facade`, roof (or ground surface) `roof`.
    pub fn flat(facade: [f32; 3], roof: [f32; 3]) -> Self {
        Self {
            kind: BuildingKind::Other,
            facade,
            window: facade,
            roof,
            storey_height_m: 3.0,
            inv_storey_m: 1.0 / 3.0f32,
            levels: 0,
            bay_m: 3.0,
            inv_bay_m: 1.0 / 3.0f32,
            window_half: 0.25,
            ground_z: 0.0,
        }
    }
}

/// The 32-bit hash a building's style is drawn from: FNV-1a over the bytes of `source_id`, then
/// a 32-bit avalanche finaliser (Wellons' `lowbias32`). Stable across runs, platforms and the
/// order of buildings.
pub fn style_hash(source_id: &str) -> u32 {
    let mut h = Fnv1a32::default();
    h.write(source_id.as_bytes());
    mix32(h.0)
}

/// A 32-bit avalanche finaliser (`lowbias32`): every input bit flips each output bit with
/// probability close to ½.
pub const fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

struct Fnv1a32(u32);

impl Default for Fnv1a32 {
    fn default() -> Self {
        Self(0x811c_9dc5)
    }
}

impl Hasher for Fnv1a32 {
    fn finish(&self) -> u64 {
        self.0 as u64
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u32).wrapping_mul(0x0100_0193);
        }
    }
}

/// The attributes [`BuildingKind::from_attributes`] reads, in order.
pub const KIND_KEYS: [&str; 3] = ["building", "building:use", "type"];

/// The attributes [`building_levels`] reads, in order.
pub const LEVELS_KEYS: [&str; 4] = ["levels", "building:levels", "LEVELS", "Levels"];

/// Storeys of a building: its levels attribute (`levels`, `building:levels`, `LEVELS`,
/// `Levels`, rounded, at least 1) when usable, else `round(height / 3 m)`, at least 1; at most
/// 255.
pub fn building_levels(b: &Building) -> u32 {
    let attr = LEVELS_KEYS
        .iter()
        .filter_map(|k| b.attributes.get(*k).and_then(AttrValue::as_f64))
        .find(|l| l.is_finite() && *l >= 0.5);
    let levels = match attr {
        Some(l) => l.round(),
        None if b.height_m.is_finite() => (b.height_m / DEFAULT_STOREY_M).round(),
        None => 1.0,
    };
    levels.clamp(1.0, 255.0) as u32
}

/// The style of a building (see the module docs): pure and deterministic.
pub fn building_style(b: &Building) -> BuildingStyle {
    let kind = BuildingKind::from_attributes(&b.attributes);
    BuildingStyle {
        // The local frame's origin is at z = 0, so the world base is the local one.
        ground_z: b.base_m as f32,
        ..style_for(
            kind,
            style_hash(&b.source_id),
            b.height_m,
            building_levels(b),
        )
    }
}

/// The style of a building of `kind` with hash `hash`, `height_m` tall with `levels` storeys.
/// A height that is not finite and positive gives a plain style (no windows).
pub fn style_for(kind: BuildingKind, hash: u32, height_m: f64, levels: u32) -> BuildingStyle {
    let k = kind.index();
    let pick = |shift: u32| ((hash >> shift) & 3) as usize;
    let c = |v: [u8; 3]| rgb(v[0], v[1], v[2]);
    let (bay0, step) = BAYS[k];
    let bay_m = bay0 + step * pick(16) as f32;
    let ok = height_m.is_finite() && height_m > 0.0 && levels > 0;
    let storey_height_m = if ok {
        (height_m / levels as f64) as f32
    } else {
        DEFAULT_STOREY_M as f32
    };
    BuildingStyle {
        kind,
        facade: c(FACADES[k][pick(0)]),
        window: c(WINDOWS[pick(12)]),
        roof: c(ROOFS[k][pick(8)]),
        storey_height_m,
        inv_storey_m: 1.0 / storey_height_m,
        levels: if ok { levels } else { 0 },
        bay_m,
        inv_bay_m: 1.0 / bay_m,
        window_half: WINDOW_HALF[k],
        ground_z: 0.0,
    }
}

/// Unlit colour of a wall point `u_m` metres along the unfolded ring ([`ring_u`]) at local
/// height `z_m` (`z_m − ground_z` metres above the building's ground) (see the module docs for the formula; `mesh.wgsl` has the same
/// function, operation for operation).
pub fn facade_color(style: &BuildingStyle, u_m: f32, z_m: f32) -> [f32; 3] {
    let t = (z_m - style.ground_z) * style.inv_storey_m;
    let s = t.floor();
    let v = t - s;
    if style.levels == 0 || s < 0.0 || s >= style.levels as f32 {
        return style.facade;
    }
    let ground = s < 1.0;
    let (v0, v1) = if ground {
        (GROUND_SILL, GROUND_LINTEL)
    } else {
        (SILL, LINTEL)
    };
    let b = u_m * style.inv_bay_m;
    let f = b - b.floor();
    if v >= v0 && v < v1 && (f - 0.5).abs() < style.window_half {
        style.window
    } else if ground {
        style.facade.map(|c| c * GROUND_FLOOR_SHADE)
    } else {
        style.facade
    }
}

/// Unlit roof colour (by [`BuildingKind`], varied by the hash).
pub fn roof_color(style: &BuildingStyle) -> [f32; 3] {
    style.roof
}

/// Unlit colour of a surface point with unit `normal`: roof (`n.z > 0.5`), underside
/// (`n.z < −0.5`) or facade.
pub fn surface_color(style: &BuildingStyle, normal: Vec3, u_m: f32, z_m: f32) -> [f32; 3] {
    if normal.z > 0.5 {
        roof_color(style)
    } else if normal.z < -0.5 {
        unit_rgb(UNDERSIDE)
    } else {
        facade_color(style, u_m, z_m)
    }
}

/// The along-wall coordinate `u` of an open ring's vertices: the distance from the ring's first
/// vertex along the ring (the unfolded boundary), summed in f64 and rounded once to f32. For `n`
/// vertices it returns `n + 1` values: `u` at each vertex, then the perimeter (the end of the
/// closing edge). Wall `i` runs from `u[i]` to `u[i + 1]`.
pub fn ring_u(ring: &[Coord<f64>]) -> Vec<f32> {
    let mut acc = 0.0f64;
    let mut out = Vec::with_capacity(ring.len() + 1);
    for (i, a) in ring.iter().enumerate() {
        out.push(acc as f32);
        let b = ring[(i + 1) % ring.len()];
        acc += (b.x - a.x).hypot(b.y - a.y);
    }
    out.push(acc as f32);
    out
}
