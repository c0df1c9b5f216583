//! The generator's tuning numbers, named.
//!
//! These fix the look of a generated city: what a block, a parcel and a building look like, and
//! how often each kind of detail appears. None comes from a paper; they were chosen by eye so that
//! a generated district resembles a European perimeter-block city and so that a building carries
//! about 50 prism triangles on average (the bundled real footprints carry about as much detail).
//! Changing any of them changes the output for a given seed (the test
//! `pinned_output_for_fixed_seeds` in the parent module pins it).
//!
//! Lengths are metres; a `(lo, hi)` pair is a uniform range `lo..hi`; a probability is per
//! building (or per corner, for chamfers) and in `0..1`. In the footprint's own frame the street
//! is to the south: `u` runs along the frontage, depth is measured from the parcel's street side.

// ---------------------------------------------------------------------------------------------
// Street grid and parcels (`layout`)

/// Average buildings per block: the grid is about `sqrt(buildings / 14)` blocks on a side. A
/// perimeter block of 60–150 m with 12–30 m frontages holds about this many parcels.
pub const BUILDINGS_PER_BLOCK: f64 = 14.0;

/// Smallest block side allowed in [`super::GenerateParams::block_m`], metres: below this two
/// parcel rows of the shallowest depth and their back yards do not fit.
pub const MIN_BLOCK_SIDE_M: f64 = 40.0;

/// Parcel depth from the street, metres, before [`PARCEL_DEPTH_DIVISOR`] limits it: the depth
/// of a city house with its back yard.
pub const PARCEL_DEPTH_M: (f64, f64) = (18.0, 32.0);

/// A parcel row is at most the block side divided by this, so the two facing rows leave a
/// shared yard of at least a fifth of the block in the middle.
pub const PARCEL_DEPTH_DIVISOR: f64 = 2.5;

/// The last piece of a side cut into parcels is kept when it is longer than this, metres;
/// shorter remainders are dropped (a sliver is no parcel).
pub const MIN_PARCEL_REMAINDER_M: f64 = 1.0;

/// Gap between a building and each side of its parcel, metres: narrow passages between
/// neighbours, so footprints never touch and blocks never merge into one building.
pub const SIDE_GAP_M: (f64, f64) = (0.5, 2.0);

/// Setback of the facade from the parcel's street side, metres (front gardens up to 4 m).
pub const STREET_SETBACK_M: (f64, f64) = (0.0, 4.0);

/// Back yard between the building and the parcel's back line, metres.
pub const BACK_YARD_M: (f64, f64) = (2.0, 6.0);

/// A parcel whose buildable box is narrower or shallower than this, metres, gets no building.
pub const MIN_BUILDABLE_SIDE_M: f64 = 4.0;

// ---------------------------------------------------------------------------------------------
// Heights (`heights`)

/// Share of buildings that are towers.
pub const TOWER_P: f64 = 0.01;

/// Storeys of a tower (inclusive).
pub const TOWER_STOREYS: (u32, u32) = (15, 60);

/// Median storeys of an ordinary building (the median of the log-normal law).
pub const MEDIAN_STOREYS: f64 = 4.0;

/// Standard deviation of the natural log of the storeys: most buildings have 2–8 storeys.
pub const STOREYS_LOG_SIGMA: f64 = 0.45;

/// Storeys of an ordinary building are clamped to this range (inclusive); taller ones are towers.
pub const STOREYS_CLAMP: (u32, u32) = (1, 14);

/// Added to storeys × storey height, metres: roof structure, parapet, raised ground floor.
pub const ROOF_EXTRA_M: (f64, f64) = (0.0, 2.0);

/// Heights and street widths are rounded to `1 / HEIGHT_ROUNDING` metres (centimetres), as a
/// surveyed attribute would be.
pub const HEIGHT_ROUNDING: f64 = 100.0;

// ---------------------------------------------------------------------------------------------
// Footprints (`footprint`)

/// Keeps a uniform range `lo..hi` non-empty when `hi` may equal `lo`, metres (`rand` refuses an
/// empty range). Far below any length that matters.
pub const RANGE_PAD_M: f64 = 1e-3;

/// The detail level is `(sqrt(area) − DETAIL_SIZE_ZERO_M) / DETAIL_SIZE_SPAN_M`, clamped to
/// `0..1`: about 60 m² (8 m × 8 m) gives 0 (a plain box), 700 m² (26 m × 26 m) gives 1.
pub const DETAIL_SIZE_ZERO_M: f64 = 8.0;

/// See [`DETAIL_SIZE_ZERO_M`].
pub const DETAIL_SIZE_SPAN_M: f64 = 18.0;

/// The detail level is multiplied by a factor drawn from this range, so buildings of one size
/// differ.
pub const DETAIL_JITTER: (f64, f64) = (0.6, 1.2);

/// A buildable box narrower or shallower than this, metres, gets a plain rectangle.
pub const MIN_DETAILED_SIDE_M: f64 = 6.0;

/// Depth of the main body along the street, metres (a double-loaded house is 10–16 m deep);
/// wings reach further back.
pub const BODY_DEPTH_M: (f64, f64) = (10.0, 16.0);

/// Probability of a courtyard building: `COURT_P + COURT_P_PER_DETAIL × detail`.
pub const COURT_P: f64 = 0.12;

/// See [`COURT_P`].
pub const COURT_P_PER_DETAIL: f64 = 0.1;

/// A courtyard building needs a box at least this wide and deep, metres.
pub const COURT_MIN_BOX_M: f64 = 20.0;

/// Probability of a simple box (no wings): `BOX_P − BOX_P_PER_DETAIL × detail`; detailed
/// buildings more often have wings.
pub const BOX_P: f64 = 0.35;

/// See [`BOX_P`].
pub const BOX_P_PER_DETAIL: f64 = 0.15;

/// Wings need at least this much depth behind the main body, metres; with less the building is
/// a box as deep as the buildable box.
pub const MIN_WING_ROOM_M: f64 = 4.0;

/// Wings need a frontage of at least this, metres.
pub const MIN_WINGED_FRONTAGE_M: f64 = 12.0;

/// Cumulative probabilities of the wing layouts, given there are wings: L below the first, U
/// below the second (when the frontage allows), T below the third, stepped back line above.
pub const WING_LAYOUT_P: [f64; 3] = [0.3, 0.55, 0.8];

/// A U needs a frontage of at least this, metres (two wings and a yard between them).
pub const U_MIN_FRONTAGE_M: f64 = 18.0;

/// Wing width as a fraction of the frontage.
pub const WING_FRACTION: (f64, f64) = (0.25, 0.45);

/// A wing of an L or T is at least this wide, metres (a room and a corridor).
pub const MIN_WING_WIDTH_M: f64 = 5.0;

/// Each wing of a U is at most this fraction of the frontage, so the yard between stays open.
pub const U_MAX_WING_FRACTION: f64 = 0.4;

/// The second wing of a U reaches at least this far behind the main body, metres.
pub const U_SECOND_WING_MIN_M: f64 = 3.0;

/// A T's rear wing keeps at least this from either side of the frontage, metres.
pub const T_WING_MARGIN_M: f64 = 2.0;

/// Number of steps of a stepped back line (`lo..hi`, so 2 to 4).
pub const BACK_STEPS: (usize, usize) = (2, 5);

/// Stair towers and light wells on the back: `round(detail × BACK_FEATURES_AT_FULL_DETAIL × u)`
/// of them, `u` uniform in `0..1`.
pub const BACK_FEATURES_AT_FULL_DETAIL: f64 = 2.5;

/// Width of a stair tower or light well, metres.
pub const BACK_FEATURE_WIDTH_M: (f64, f64) = (2.5, 5.0);

/// Least distance between back features and from the ends of the frontage, metres.
pub const BACK_FEATURE_GAP_M: f64 = 2.0;

/// How far a back feature moves the back line, metres: negative cuts a light well in, positive
/// adds a stair tower (only where the parcel has room).
pub const BACK_FEATURE_DEPTH_M: (f64, f64) = (-3.0, 2.5);

/// Bays on the facade: `floor(detail × frontage / spacing)` of them, one per this many metres.
pub const BAY_SPACING_M: (f64, f64) = (8.0, 14.0);

/// How far bays project from the facade, metres (the facade is set back by this from the box).
pub const BAY_PROJECTION_M: (f64, f64) = (0.6, 1.2);

/// Width of a bay, metres.
pub const BAY_WIDTH_M: (f64, f64) = (2.5, 4.5);

/// Least distance between bays and from the ends of the frontage, metres.
pub const BAY_GAP_M: f64 = 1.5;

/// Facade jogs (the frontage read as 2–3 houses) need at least this detail level.
pub const JOG_MIN_DETAIL: f64 = 0.3;

/// Probability of facade jogs, when the detail allows them.
pub const JOG_P: f64 = 0.6;

/// Number of houses the frontage is read as (`lo..hi`, so 2 or 3).
pub const JOG_HOUSES: (usize, usize) = (2, 4);

/// How far each house boundary moves from an even split, metres.
pub const JOG_SHIFT_M: (f64, f64) = (-1.0, 1.0);

/// Extra setback of every other house, metres.
pub const JOG_STEP_M: (f64, f64) = (0.0, 1.2);

/// Extra setback per house along the frontage, metres (a gentle stagger).
pub const JOG_STAGGER_M: f64 = 0.3;

/// A recessed entrance needs at least this detail level.
pub const ENTRANCE_MIN_DETAIL: f64 = 0.2;

/// Probability of a recessed entrance, when the detail allows it.
pub const ENTRANCE_P: f64 = 0.4;

/// Width of the entrance recess, metres.
pub const ENTRANCE_WIDTH_M: (f64, f64) = (2.0, 3.5);

/// Least distance of the entrance from the ends of the frontage, metres.
pub const ENTRANCE_GAP_M: f64 = 2.0;

/// Depth of the entrance recess behind the facade, metres.
pub const ENTRANCE_RECESS_M: (f64, f64) = (1.0, 2.0);

/// An irregular party wall needs at least this detail level.
pub const PARTY_WALL_MIN_DETAIL: f64 = 0.15;

/// Probability of an irregular party wall, when the detail allows it.
pub const PARTY_WALL_P: f64 = 0.5;

/// Width of the end strip with its own back line, metres.
pub const PARTY_WALL_STRIP_M: (f64, f64) = (1.5, 3.5);

/// How much shallower the end strip is, metres (negative: the back line moves towards the
/// street).
pub const PARTY_WALL_DEPTH_M: (f64, f64) = (-3.0, -1.0);

/// Strip boundaries closer than this, metres, are one boundary.
pub const STRIP_MERGE_M: f64 = 1e-6;

/// The front line stays at least this far in front of the buildable box's back, metres.
pub const FRONT_LINE_MIN_DEPTH_M: f64 = 6.0;

/// Every strip is at least this deep, metres (a habitable room).
pub const MIN_STRIP_DEPTH_M: f64 = 5.0;

/// Slanted party walls (not square to the street) need at least this detail level.
pub const SLANT_MIN_DETAIL: f64 = 0.1;

/// Probability of slanted party walls, when the detail allows them.
pub const SLANT_P: f64 = 0.3;

/// A slant moves a side wall's back end inwards by at most this fraction of the outer strip's
/// width.
pub const SLANT_MAX_FRACTION: f64 = 0.3;

/// ... and by at most this many metres.
pub const SLANT_MAX_M: f64 = 1.2;

/// Finding the front-right vertex: tolerance on `u`, metres.
pub const CORNER_FIND_TOL_M: f64 = 1e-9;

/// Probability that a convex corner of the outer ring is chamfered, at detail level 1
/// (proportional to the detail).
pub const CHAMFER_P_AT_FULL_DETAIL: f64 = 0.12;

/// Longest chamfer of the outer ring, metres.
pub const CHAMFER_MAX_M: f64 = 2.5;

/// A random chamfer cuts this fraction of the longest chamfer.
pub const CHAMFER_FRACTION: (f64, f64) = (0.4, 1.0);

/// A street corner's chamfer (a *pan coupé*), metres.
pub const STREET_CORNER_CUT_M: (f64, f64) = (2.0, 4.0);

/// A chamfer takes at most this fraction of either adjacent edge, so short edges survive.
pub const CHAMFER_MAX_EDGE_FRACTION: f64 = 0.35;

/// Chamfers shorter than this, metres, are not made (they would only add vertices).
pub const MIN_CHAMFER_M: f64 = 0.5;

/// Depth of the building ring around a courtyard, metres.
pub const COURT_RING_DEPTH_M: (f64, f64) = (6.0, 9.0);

/// The ring around a courtyard is at most the box's side divided by this.
pub const COURT_RING_DIVISOR: f64 = 3.0;

/// The courtyard's sides keep this much more from the box's sides than from its front and
/// back, metres.
pub const COURT_SIDE_EXTRA_M: f64 = 1.2;

/// A courtyard narrower or shallower than this, metres, is not made.
pub const MIN_COURT_SIDE_M: f64 = 3.0;

/// Probability that a corner of the courtyard is chamfered, at detail level 1.
pub const COURT_CHAMFER_P_AT_FULL_DETAIL: f64 = 0.5;

/// Longest chamfer of a courtyard, metres.
pub const COURT_CHAMFER_MAX_M: f64 = 2.0;
