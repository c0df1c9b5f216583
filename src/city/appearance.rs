//! Procedural appearance: one deterministic definition of what buildings, streets and the ground
//! look like, shared by the mesh shader (`render/mesh.wgsl` mirrors [`facade_color`] and
//! [`shade`] line for line), the CPU fallback renderer (`visibility::oracle::shade`) and BlockMap
//! construction (seed 000 §3.3 and seed 002 §4.3 take wall and roof colours "from the geometry";
//! here the geometry's colours are these functions).
//!
//! # The definition
//! A building's [`BuildingStyle`] is a pure function of the building ([`building_style`]): no RNG
//! state, only a 32-bit hash of its `source_id` ([`style_hash`]), its height, its levels and its
//! type attribute ([`BuildingKind`]). Colours are 8-bit levels `k / 255` (so they survive an
//! `Rgba8Unorm` target exactly); the style also stores the reciprocals the shader needs, rounded
//! once on the CPU, so the GPU never divides.
//!
//! A wall point is given by `u` (metres along the unfolded ring, [`ring_u`]) and `z` (metres above
//! the ground). [`facade_color`] is, with `fl` = floor and every operation one f32 operation:
//!
//! ```text
//! t = z · inv_storey_m          s = fl(t)        v = t − s          (storey s, height v in it)
//! b = u · inv_bay_m             f = b − fl(b)                        (position f in its bay)
//! plain  if levels = 0, s < 0 or s ≥ levels            → facade
//! window if v ≥ v0 and v < v1 and |f − 0.5| < window_half   → window
//!        with (v0, v1) = (GROUND_SILL, GROUND_LINTEL) on the ground floor (s < 1),
//!        else (SILL, LINTEL)
//! else   ground floor (s < 1)  → facade · GROUND_FLOOR_SHADE,  upper floors → facade
//! ```
//!
//! So each storey has exactly one row of windows, bays of `bay_m` with a pier of
//! `(1 − 2·window_half)·bay_m` between windows, and a darker ground floor. Roofs are
//! [`roof_color`] (by [`BuildingKind`], varied by the hash), the undersides of raised parts
//! [`UNDERSIDE`]. Lighting ([`shade`]) is `base · (AMBIENT + (1 − AMBIENT)·max(n·sun, 0))`,
//! clamped to 1, with the sun of [`sun_direction`].
//!
//! # Reproducibility on the GPU
//! Only IEEE-754 f32 multiplication, subtraction, `floor`, `abs` and comparisons are used; each is
//! correctly rounded in WGSL as in Rust, and the style values are uploaded as computed here, so
//! the GPU reproduces the function bit for bit. Two caveats, both confined to the edges of the
//! pattern: a shader compiler may fuse `z·inv − fl(…)` into one FMA (which moves an edge by at
//! most one ulp of `t`), and the rasteriser interpolates `u` and `z` (so a pixel samples a point
//! that differs from the exact ray hit by the interpolation error). The image test compares
//! colours away from pattern edges. Lighting uses `normalize` and `dot`, which are not correctly
//! rounded in WGSL: lit colours agree within 1/255.
//!
//! # Ground
//! [`ground_mesh`] lays the blocks' ground ([`BLOCK_GROUND`]) and then the street layer as strips
//! ([`street_width_m`], [`street_color`]) flat at z = 0. The renderers draw the ground plane
//! ([`GROUND`]), then these, in that order, with the depth test set to always pass (painter's
//! order, no z offsets and so no z-fighting), and the buildings after them with the normal depth
//! test. Ground geometry never takes part in the block-id pass.

use std::hash::Hasher;

use blockwalk_importers::{AttrValue, Attributes};
use geo::TriangulateEarcut;
use geo_types::{Coord, Polygon};
use glam::{DVec3, Vec3};
use serde::Serialize;

use super::mesh::Mesh;
use super::model::{Building, LocalFrame, Street};

/// Ambient share of the light (the rest is the sun's Lambert term).
pub const AMBIENT: f32 = 0.35;
/// Ground floor: the facade colour times this.
pub const GROUND_FLOOR_SHADE: f32 = 0.75;
/// Window band of upper storeys, as fractions of the storey height: sill and lintel.
pub const SILL: f32 = 0.3125;
/// See [`SILL`].
pub const LINTEL: f32 = 0.8125;
/// Window band of the ground floor (shop fronts: taller).
pub const GROUND_SILL: f32 = 0.125;
/// See [`GROUND_SILL`].
pub const GROUND_LINTEL: f32 = 0.8125;
// The constants of the pattern are exact binary fractions, so that the shader (which receives
// them as WGSL literals written from these values, see `render/mesh.rs`) has the same f32 values
// whatever way its compiler rounds literals.

/// Storey height (m) assumed when a building has no levels attribute.
pub const DEFAULT_STOREY_M: f64 = 3.0;

/// 8-bit colour levels as the f32 the shader sees (`k / 255`, correctly rounded).
pub fn unit_rgb(c: [u8; 3]) -> [f32; 3] {
    c.map(|k| k as f32 / 255.0)
}

fn rgb(r: u8, g: u8, b: u8) -> [f32; 3] {
    unit_rgb([r, g, b])
}

/// The ground plane outside blocks (8-bit levels; [`unit_rgb`] gives the f32 colour).
pub const GROUND: [u8; 3] = [140, 148, 128];
/// The ground of a block (yards, pavements): greyer than [`GROUND`].
pub const BLOCK_GROUND: [u8; 3] = [158, 156, 142];
/// Undersides of raised parts (facing down).
pub const UNDERSIDE: [u8; 3] = [89, 89, 89];
/// The sky (clear colour of lit frames).
pub const SKY: [u8; 3] = [158, 196, 237];

/// Unit direction towards the sun (from the south-east, 50° up): the one light of [`shade`].
pub fn sun_direction() -> Vec3 {
    DVec3::new(0.5, -0.6, 1.3).normalize().as_vec3()
}

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

    fn index(self) -> usize {
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
const ROOFS: [[[u8; 3]; 4]; 5] = [
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
    style_for(
        kind,
        style_hash(&b.source_id),
        b.height_m,
        building_levels(b),
    )
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
    }
}

/// Unlit colour of a wall point `u_m` metres along the unfolded ring ([`ring_u`]) and `z_m`
/// metres above the ground (see the module docs for the formula; `mesh.wgsl` has the same
/// function, operation for operation).
pub fn facade_color(style: &BuildingStyle, u_m: f32, z_m: f32) -> [f32; 3] {
    let t = z_m * style.inv_storey_m;
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

/// Lit colour: `base · (AMBIENT + (1 − AMBIENT)·max(n·sun, 0))`, each channel at most 1
/// (`mesh.wgsl`'s `fs_main`).
pub fn shade(base: [f32; 3], normal: Vec3) -> [f32; 3] {
    let light = AMBIENT + (1.0 - AMBIENT) * normal.dot(sun_direction()).max(0.0);
    base.map(|c| (c * light).min(1.0))
}

/// A colour in `[0, 1]` as the 8-bit levels an `Rgba8Unorm` target stores (round to nearest).
pub fn to_rgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
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

/// The ground plane: a square of half side `half_m` metres at z = 0 around the local origin
/// (two triangles facing up, style [`GROUND`]). Both renderers draw it first.
pub fn ground_plane(half_m: f32) -> Mesh {
    let g = half_m;
    let c = unit_rgb(GROUND);
    Mesh {
        positions: vec![
            Vec3::new(-g, -g, 0.0),
            Vec3::new(g, -g, 0.0),
            Vec3::new(g, g, 0.0),
            Vec3::new(-g, g, 0.0),
        ],
        normals: vec![Vec3::Z; 4],
        indices: vec![0, 1, 2, 0, 2, 3],
        appearance: vec![super::mesh::VertexAppearance::default(); 4],
        styles: vec![BuildingStyle::flat(c, c)],
    }
}

/// Half side (m) of the ground plane the renderers draw (a 40 km square).
pub const GROUND_PLANE_HALF_M: f32 = 20_000.0;

/// Sides of the polygon that fills a street's joints (a regular polygon of the street's width).
const JOINT_SIDES: usize = 8;

/// A street as the ground lays it: style, half width, local points, and which vertices need an
/// octagon.
type LaidStreet = (u32, f64, Vec<(f64, f64)>, Vec<bool>);

/// True when a street goes straight on at `b` (from `a` to `c`, exactly collinear and forward)
/// with both segments at least `half` long: the octagon of radius `half` at `b` then lies inside
/// the two segments' quads.
fn straight_on(a: (f64, f64), b: (f64, f64), c: (f64, f64), half: f64) -> bool {
    let (ux, uy) = (b.0 - a.0, b.1 - a.1);
    let (vx, vy) = (c.0 - b.0, c.1 - b.1);
    ux * vy - uy * vx == 0.0
        && ux * vx + uy * vy > 0.0
        && ux.hypot(uy) >= half
        && vx.hypot(vy) >= half
}

/// The ground layers as one mesh at z = 0 in `frame` (normals +z, each surface its own flat
/// [`BuildingStyle`], whose `roof` is the surface colour): first each polygon of `blocks` in
/// [`BLOCK_GROUND`], then every street not below ground ([`street_below_ground`]) as a strip of
/// [`street_width_m`] in [`street_color`]: one quad per segment and a regular octagon at every
/// vertex so that joints have no gaps. Triangles are in drawing order: draw them in order with
/// the depth test always passing (later over earlier) and before the buildings.
///
/// Octagons that draw nothing new are left out, so that the picture is the same with fewer
/// triangles (a city's street graph meets three or four streets at most junctions, each ending
/// there with its own octagon; on the 80,000-building generated city the octagons were 9 in 10
/// of the ground's triangles):
/// - of identical octagons (same centre, width and colour), only the last one drawn: it paints
///   over every pixel the earlier ones painted, in the same colour;
/// - none at an inner vertex where the street goes straight on and both segments are at least
///   half its width long: the two quads drawn just before it already hold the octagon.
pub fn ground_mesh(frame: &LocalFrame, streets: &[Street], blocks: &[Polygon<f64>]) -> Mesh {
    ground_mesh_with(frame, streets, blocks, true)
}

/// [`ground_mesh`], with every octagon when `prune` is false (the reference its tests compare
/// against).
fn ground_mesh_with(
    frame: &LocalFrame,
    streets: &[Street],
    blocks: &[Polygon<f64>],
    prune: bool,
) -> Mesh {
    let mut m = Mesh::default();
    let local = |c: Coord<f64>| -> (f64, f64) { (c.x - frame.origin.x, c.y - frame.origin.y) };
    let push_vertex = |m: &mut Mesh, x: f64, y: f64, style: u32| {
        m.positions.push(DVec3::new(x, y, 0.0).as_vec3());
        m.normals.push(Vec3::Z);
        m.appearance
            .push(super::mesh::VertexAppearance { u_m: 0.0, style });
    };
    if !blocks.is_empty() {
        let style = m.styles.len() as u32;
        let c = unit_rgb(BLOCK_GROUND);
        m.styles.push(BuildingStyle::flat(c, c));
        for p in blocks {
            let raw = p.earcut_triangles_raw();
            let base = m.positions.len() as u32;
            for v in &raw.vertices {
                let (x, y) = local(Coord { x: v[0], y: v[1] });
                push_vertex(&mut m, x, y, style);
            }
            for t in raw.triangle_indices.chunks_exact(3) {
                // Counter-clockwise seen from above (normal +z).
                let p = |i: usize| {
                    let v = raw.vertices[t[i]];
                    (v[0], v[1])
                };
                let (a, b, c) = (p(0), p(1), p(2));
                let ccw = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
                let t: [u32; 3] = [t[0] as u32, t[1] as u32, t[2] as u32];
                if ccw >= 0.0 {
                    m.indices.extend([base + t[0], base + t[1], base + t[2]]);
                } else {
                    m.indices.extend([base + t[0], base + t[2], base + t[1]]);
                }
            }
        }
    }
    let mut class_style = [None::<u32>; 5];
    let mut laid: Vec<LaidStreet> = Vec::new();
    for s in streets {
        if street_below_ground(s) {
            continue;
        }
        let class = StreetClass::from_attributes(&s.attributes);
        let style = *class_style[class as usize].get_or_insert_with(|| {
            m.styles.push(BuildingStyle::flat(
                street_color(class),
                street_color(class),
            ));
            m.styles.len() as u32 - 1
        });
        let half = 0.5 * street_width_m(&s.attributes);
        let pts: Vec<(f64, f64)> = s.line.0.iter().map(|c| local(*c)).collect();
        let n = pts.len();
        let joints = (0..n)
            .map(|i| {
                n >= 2
                    && !(prune
                        && i > 0
                        && i + 1 < n
                        && straight_on(pts[i - 1], pts[i], pts[i + 1], half))
            })
            .collect();
        laid.push((style, half, pts, joints));
    }
    // The last occurrence of each octagon (centre, half width, colour) in drawing order.
    let key = |style: u32, half: f64, p: (f64, f64)| {
        (style, half.to_bits(), p.0.to_bits(), p.1.to_bits())
    };
    let mut last = std::collections::HashMap::new();
    for (si, (style, half, pts, joints)) in laid.iter().enumerate() {
        for (vi, p) in pts.iter().enumerate() {
            if joints[vi] {
                last.insert(key(*style, *half, *p), (si, vi));
            }
        }
    }
    for (si, (style, half, pts, joints)) in laid.iter().enumerate() {
        let (style, half) = (*style, *half);
        for w in pts.windows(2) {
            let ((ax, ay), (bx, by)) = (w[0], w[1]);
            let len = (bx - ax).hypot(by - ay);
            if len <= 0.0 || !len.is_finite() {
                continue;
            }
            // Left normal × half width.
            let (nx, ny) = (-(by - ay) / len * half, (bx - ax) / len * half);
            let base = m.positions.len() as u32;
            for (x, y) in [
                (ax - nx, ay - ny),
                (bx - nx, by - ny),
                (bx + nx, by + ny),
                (ax + nx, ay + ny),
            ] {
                push_vertex(&mut m, x, y, style);
            }
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        // Joints (and rounded ends).
        for (vi, &(cx, cy)) in pts.iter().enumerate() {
            if !joints[vi] || (prune && last.get(&key(style, half, (cx, cy))) != Some(&(si, vi))) {
                continue;
            }
            let base = m.positions.len() as u32;
            push_vertex(&mut m, cx, cy, style);
            for k in 0..JOINT_SIDES {
                let a = std::f64::consts::TAU * k as f64 / JOINT_SIDES as f64;
                push_vertex(&mut m, cx + half * a.cos(), cy + half * a.sin(), style);
            }
            for k in 0..JOINT_SIDES as u32 {
                let next = (k + 1) % JOINT_SIDES as u32;
                m.indices.extend([base, base + 1 + k, base + 1 + next]);
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::model::{BuildingId, HeightSource};
    use geo_types::LineString;

    fn building(source_id: &str, height_m: f64, attrs: &[(&str, AttrValue)]) -> Building {
        Building {
            id: BuildingId(0),
            source_id: source_id.into(),
            footprint: Polygon::new(
                LineString::from(vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 0.0)]),
                vec![],
            ),
            height_m,
            min_height_m: 0.0,
            height_source: HeightSource::Height,
            attributes: attrs
                .iter()
                .map(|(k, v)| (k.to_string(), v.clone()))
                .collect(),
        }
    }

    fn luminance(c: [f32; 3]) -> f32 {
        0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
    }

    #[test]
    fn styles_are_deterministic_and_depend_on_the_id_not_the_index() {
        let a = building("b:17", 15.0, &[]);
        let mut b = a.clone();
        b.id = BuildingId(99);
        assert_eq!(building_style(&a), building_style(&b));
        // A fixed value: the hash must not change between runs or platforms.
        assert_eq!(style_hash(""), mix32(0x811c_9dc5));
        assert_eq!(style_hash("b:17"), style_hash("b:17"));
        // Different ids give different hashes (and over many ids, all palette entries).
        let mut facades = std::collections::BTreeSet::new();
        for i in 0..200 {
            let s = building_style(&building(&format!("b:{i}"), 15.0, &[]));
            facades.insert(to_rgb8(s.facade));
        }
        assert_eq!(facades.len(), 4, "{facades:?}");
    }

    #[test]
    fn one_window_row_per_storey() {
        for levels in [1u32, 2, 5, 17] {
            for (i, h) in [4.0, 9.5, 31.0].into_iter().enumerate() {
                let b = building(
                    &format!("x:{levels}:{i}"),
                    h,
                    &[("levels", AttrValue::Int(levels as i64))],
                );
                let s = building_style(&b);
                assert_eq!(s.levels, levels);
                // At the centre of a bay: rising z crosses into a window once per storey.
                let u = 0.5 * s.bay_m + 7.0 * s.bay_m;
                let n = 20_000;
                let mut rows = 0;
                let mut was = false;
                for k in 0..n {
                    let z = (k as f64 + 0.5) / n as f64 * h;
                    let is = facade_color(&s, u, z as f32) == s.window;
                    rows += (is && !was) as u32;
                    was = is;
                }
                assert_eq!(rows, levels, "levels {levels}, height {h}");
                // At the centre of a pier there is no window at all.
                let pier = 7.0 * s.bay_m + 0.01;
                for k in 0..200 {
                    let z = (k as f32 + 0.5) / 200.0 * h as f32;
                    assert_ne!(facade_color(&s, pier, z), s.window);
                }
            }
        }
    }

    #[test]
    fn windows_repeat_per_bay_along_the_wall() {
        let s = building_style(&building("r:1", 12.0, &[("levels", AttrValue::Int(4))]));
        let z = 1.55 * s.storey_height_m; // second storey, in the window band
        let n = 10_000;
        let len = 10.0 * s.bay_m;
        let mut windows = 0;
        let mut was = false;
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32 * len;
            let is = facade_color(&s, u, z) == s.window;
            windows += (is && !was) as u32;
            was = is;
        }
        assert_eq!(windows, 10);
    }

    #[test]
    fn ground_floor_is_darker() {
        for i in 0..50 {
            let s = building_style(&building(&format!("g:{i}"), 20.0, &[]));
            let pier = 0.02 * s.bay_m;
            let ground = facade_color(&s, pier, 0.5 * s.storey_height_m);
            let upper = facade_color(&s, pier, 2.5 * s.storey_height_m);
            assert_eq!(upper, s.facade);
            assert!(
                luminance(ground) < 0.8 * luminance(upper),
                "{ground:?} {upper:?}"
            );
        }
    }

    #[test]
    fn colours_are_in_the_unit_range() {
        let kinds = ["apartments", "office", "warehouse", "museum", "yes"];
        for i in 0..500 {
            let b = building(
                &format!("c:{i}"),
                3.0 + i as f64,
                &[("building", AttrValue::Text(kinds[i % 5].into()))],
            );
            let s = building_style(&b);
            for c in [s.facade, s.roof, s.window, facade_color(&s, i as f32, 1.0)] {
                assert!(c.iter().all(|v| (0.0..=1.0).contains(v)), "{c:?}");
            }
            let lit = shade(facade_color(&s, 0.3, 0.3), Vec3::new(0.6, -0.8, 0.0));
            assert!(lit.iter().all(|v| (0.0..=1.0).contains(v)));
        }
        for c in [GROUND, BLOCK_GROUND, UNDERSIDE, SKY] {
            assert!(unit_rgb(c).iter().all(|v| (0.0..=1.0).contains(v)));
        }
    }

    #[test]
    fn kinds_and_roofs_follow_the_type_attribute() {
        let k = |t: &str| {
            BuildingKind::from_attributes(
                &[("building".to_string(), AttrValue::Text(t.into()))]
                    .into_iter()
                    .collect(),
            )
        };
        assert_eq!(k("apartments"), BuildingKind::Residential);
        assert_eq!(k("Office"), BuildingKind::Commercial);
        assert_eq!(k("warehouse"), BuildingKind::Industrial);
        assert_eq!(k("chapel"), BuildingKind::Civic);
        assert_eq!(k("yes"), BuildingKind::Other);
        // Civic roofs come from the civic palette, never the residential one.
        let civic: Vec<[u8; 3]> = ROOFS[BuildingKind::Civic.index()].to_vec();
        for i in 0..40 {
            let b = building(
                &format!("k:{i}"),
                10.0,
                &[("building", AttrValue::Text("church".into()))],
            );
            assert!(civic.contains(&to_rgb8(roof_color(&building_style(&b)))));
        }
    }

    #[test]
    fn levels_fall_back_to_the_height() {
        assert_eq!(building_levels(&building("l", 12.2, &[])), 4);
        assert_eq!(building_levels(&building("l", 1.0, &[])), 1);
        assert_eq!(
            building_levels(&building("l", 12.2, &[("levels", AttrValue::Float(3.5))])),
            4
        );
        assert_eq!(
            building_levels(&building("l", 12.2, &[("levels", AttrValue::Null)])),
            4
        );
        let s = style_for(BuildingKind::Other, 0, f64::NAN, 3);
        assert_eq!(s.levels, 0);
        assert_eq!(facade_color(&s, 1.0, 1.0), s.facade);
    }

    #[test]
    fn street_widths_come_from_attributes_then_class() {
        let a = |kv: &[(&str, AttrValue)]| -> Attributes {
            kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
        };
        assert_eq!(
            street_width_m(&a(&[("width", AttrValue::Float(12.0))])),
            12.0
        );
        assert_eq!(
            street_width_m(&a(&[("lanes", AttrValue::Text("2.0".into()))])),
            3.0 * LANE_M
        );
        assert_eq!(
            street_width_m(&a(&[("highway", AttrValue::Text("primary_link".into()))])),
            14.0
        );
        assert_eq!(
            street_width_m(&a(&[
                ("highway", AttrValue::Text("footway".into())),
                ("width", AttrValue::Float(-1.0))
            ])),
            2.0
        );
        assert_eq!(street_width_m(&a(&[])), 8.0);
    }

    #[test]
    fn ring_u_is_the_unfolded_boundary() {
        let r = [
            Coord { x: 0.0, y: 0.0 },
            Coord { x: 3.0, y: 4.0 },
            Coord { x: 3.0, y: 10.0 },
        ];
        let u = ring_u(&r);
        assert_eq!(u[..3], [0.0, 5.0, 11.0]);
        assert!((u[3] as f64 - (11.0 + 109f64.sqrt())).abs() < 1e-5, "{u:?}");
        assert_eq!(ring_u(&[]), vec![0.0]);
    }

    /// The style painted last over `p` (triangles in drawing order), or `None`.
    fn top_style(m: &Mesh, p: (f64, f64)) -> Option<u32> {
        let mut top = None;
        for t in m.indices.chunks_exact(3) {
            let v: Vec<(f64, f64)> = t
                .iter()
                .map(|&i| {
                    let q = m.positions[i as usize];
                    (q.x as f64, q.y as f64)
                })
                .collect();
            let side = |a: (f64, f64), b: (f64, f64)| {
                (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
            };
            if side(v[0], v[1]) >= 0.0 && side(v[1], v[2]) >= 0.0 && side(v[2], v[0]) >= 0.0 {
                top = Some(m.appearance[t[0] as usize].style);
            }
        }
        top
    }

    /// Leaving out the octagons that draw nothing new (duplicates at junctions, straight-on
    /// vertices) keeps the picture: on a dense grid over four streets meeting at a junction
    /// (two classes, so that painter's order matters), one street going straight on through a
    /// vertex and one bending, every sample shows the same style, with fewer triangles.
    #[test]
    fn pruned_octagons_keep_the_picture() {
        use geo_types::LineString;
        let frame = LocalFrame {
            origin: DVec3::new(0.0, 0.0, 0.0),
        };
        let street = |id: &str, pts: Vec<(f64, f64)>, w: f64, highway: &str| Street {
            source_id: id.into(),
            line: LineString::from(pts),
            grade_separated: false,
            attributes: [
                ("width".to_string(), AttrValue::Float(w)),
                ("highway".to_string(), AttrValue::Text(highway.into())),
            ]
            .into_iter()
            .collect(),
        };
        let streets = vec![
            street("a", vec![(0.0, 0.0), (30.0, 0.0)], 8.0, "primary"),
            street("b", vec![(0.0, 0.0), (0.0, 30.0)], 6.0, "residential"),
            street(
                "c",
                vec![(0.0, 0.0), (-20.0, 0.0), (-40.0, 0.0)],
                6.0,
                "residential",
            ),
            street(
                "d",
                vec![(0.0, 0.0), (0.0, -15.0), (10.0, -25.0)],
                8.0,
                "primary",
            ),
            street("e", vec![(30.0, 0.0), (30.0, 20.0)], 6.0, "residential"),
        ];
        let full = ground_mesh_with(&frame, &streets, &[], false);
        let pruned = ground_mesh(&frame, &streets, &[]);
        assert!(
            pruned.indices.len() < full.indices.len(),
            "{} vs {}",
            pruned.indices.len(),
            full.indices.len()
        );
        // The junction's two identical residential octagons and primary octagons become one
        // each; the straight-on vertex of c loses its octagon.
        let octagons = |m: &Mesh| (m.indices.len() / 3 - 2 * 7) / JOINT_SIDES;
        assert_eq!(octagons(&full), 12);
        assert_eq!(octagons(&pruned), 9);
        let (mut covered, mut n) = (0, 0);
        for j in 0..=300 {
            for i in 0..=400 {
                let p = (-45.0 + i as f64 * 0.2125, -30.0 + j as f64 * 0.2125);
                let (a, b) = (top_style(&full, p), top_style(&pruned, p));
                assert_eq!(a, b, "at {p:?}");
                covered += a.is_some() as usize;
                n += 1;
            }
        }
        assert!(covered > n / 20, "{covered} of {n} samples on a street");
    }

    #[test]
    fn ground_mesh_covers_blocks_then_streets() {
        use geo_types::LineString;
        let frame = LocalFrame {
            origin: DVec3::new(100.0, 200.0, 0.0),
        };
        let block = Polygon::new(
            LineString::from(vec![
                (100.0, 200.0),
                (140.0, 200.0),
                (140.0, 230.0),
                (100.0, 230.0),
                (100.0, 200.0),
            ]),
            vec![LineString::from(vec![
                (110.0, 210.0),
                (110.0, 220.0),
                (120.0, 220.0),
                (120.0, 210.0),
                (110.0, 210.0),
            ])],
        );
        let street = Street {
            source_id: "s:1".into(),
            line: LineString::from(vec![(90.0, 195.0), (150.0, 195.0), (150.0, 240.0)]),
            grade_separated: false,
            attributes: [("width".to_string(), AttrValue::Float(6.0))]
                .into_iter()
                .collect(),
        };
        let m = ground_mesh(&frame, &[street], &[block]);
        assert_eq!(m.positions.len(), m.appearance.len());
        assert_eq!(m.styles.len(), 2);
        // Every triangle faces up; the block's area (1200 − 100) comes first.
        let mut area = [0.0f64; 2];
        for t in m.indices.chunks_exact(3) {
            let p: Vec<DVec3> = t
                .iter()
                .map(|&i| m.positions[i as usize].as_dvec3())
                .collect();
            let a = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).z;
            assert!(a > 0.0);
            area[m.appearance[t[0] as usize].style as usize] += a;
        }
        assert!((area[0] - 1100.0).abs() < 1e-6, "{area:?}");
        // Two segments 60 and 45 m long, 6 m wide, plus three octagons of radius 3.
        let oct = 0.5 * 8.0 * 9.0 * (std::f64::consts::TAU / 8.0).sin();
        assert!(
            (area[1] - (105.0 * 6.0 + 3.0 * oct)).abs() < 1e-3,
            "{area:?}"
        );
        assert!(m.positions.iter().all(|p| p.z == 0.0));
    }
}
