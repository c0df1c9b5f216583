//! The city model: buildings, streets and parcels in metric world coordinates (f64), a local
//! frame for everything that goes to f32, extrusion into watertight prisms, export, and a
//! procedural city generator.
//!
//! - [`model`]: [`City`], [`Building`], [`Street`], [`Parcel`]; [`LocalFrame`] (defined in
//!   [`crate::geom::frame`], re-exported here).
//! - [`build`]: layers → city (CRS to metric, heights, repair; the [`CityReport`]).
//! - [`appearance`]: the procedural look of buildings, streets and ground (one definition,
//!   mirrored in `render/mesh.wgsl`).
//! - [`extrude`]: footprint + heights → closed, outward-oriented [`Mesh`] (Pina, Serón and Cerezo, §3).
//! - [`export`]: glTF binary and GeoJSON.
//! - [`generate`]: deterministic procedural cities, written as Shapefiles.

pub mod appearance;
pub mod build;
pub mod export;
pub mod extrude;
pub mod generate;
pub mod mesh;
pub mod model;

pub use mesh::{Mesh, VertexAppearance};
pub use model::{Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Parcel, Street};
