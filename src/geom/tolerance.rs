//! Snapping tolerances, in metres, each with its reason.
//!
//! Everything else in [`crate::geom`] is exact or says how far it rounds; these are the places
//! where points that are *near* are deliberately treated as *the same*.
//!
//! The two street graphs are chained: the route graph ([`crate::route::StreetGraph`]) is built
//! from the block layout's street edges, which [`crate::blocks::noding`] has already noded at
//! [`STREET_SNAP_M`]. So the route graph must not snap again at that tolerance: its job is only to
//! recognise the copies of one node that several edges carry, and it must never merge two nodes
//! the noding kept apart. Hence a second, smaller constant, checked against the first below.

/// Snap tolerance of the blocks' street graph: street vertices closer than this are one node, and
/// a line end this close to another line joins it (Pina, Serón and Cerezo, §3 needs streets that meet).
///
/// 5 cm is far below any street width (so no two real junctions merge) and far above the
/// millimetre misses of digitised data and the coordinate round-off of UTM northings near 1e7 m
/// (about 1e-9 m), so T-junctions that miss by a millimetre still join.
pub const STREET_SNAP_M: f64 = 0.05;

/// Grid on which the route's street graph keys its vertices: vertices that round to the same
/// point of this grid are one node.
///
/// The graph is built from already noded street edges, whose distinct nodes lie more than
/// [`STREET_SNAP_M`] apart; two of them can share a grid key only if they are less than a grid
/// cell's diagonal (`√2 ×` this) apart, so any grid finer than `STREET_SNAP_M / √2` keys the copies
/// of one node together and never two nodes. 1 cm leaves a factor 3.5 of margin, and still
/// absorbs the round-off of moving the edges into the local frame.
pub const ROUTE_NODE_GRID_M: f64 = 0.01;

// The argument above, checked when the crate is compiled.
const _: () = assert!(ROUTE_NODE_GRID_M * std::f64::consts::SQRT_2 < STREET_SNAP_M);

/// How far [`crate::geom::repair`] moves a ring away from a point where it touches another ring
/// (or itself): the touching vertex is replaced by a notch of this depth cut into the region
/// the ring bounds (see that module's doc).
///
/// 1 mm is below the accuracy of any surveyed or digitised footprint, so the shape is unchanged
/// for every purpose (the area moves by at most this squared, 1 mm², per touch), and above the
/// f32 spacing of local coordinates within 4 km of the frame origin (under 0.5 mm), so the
/// notch survives the conversion to the mesh's f32 positions and the prism stays 2-manifold.
/// (Beyond about 16 km from the origin that spacing reaches 2 mm; a notch whose points round onto
/// the touch point is then refused by the extrusion, as any two vertices that round together are.)
pub const TOUCH_SEPARATION_M: f64 = 1e-3;

/// The largest magnitude a coordinate of the metric world may have: 10⁹ m, a million
/// kilometres, 25 times the Earth's circumference. No footprint or street on Earth lies further
/// from any frame's origin, so a vertex beyond it is data in the wrong unit or garbage, and is
/// refused with its feature. Within it the snap tolerance is far above the rounding of the
/// computed crossings (10⁹ m × 2⁻⁵² ≈ 0.2 µm, against a 5 cm snap), which the street noder
/// needs to leave only crossings at nodes.
pub const MAX_WORLD_COORD_M: f64 = 1e9;
