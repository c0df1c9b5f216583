//! Occlusion culling with occluder shadows and a cull map (seed 004 §3.2), and the visibility
//! oracle that checks it.
//!
//! - [`shadow`]: [`Occluder`] (a facade's top edge) and its [`OccluderShadow`] from a viewpoint.
//! - [`cullmap`]: [`CullMap`], conservative rasterisation of shadows, and its [`cullmap::MinPyramid`].
//! - [`occluders`]: facade edges per block, collinear runs merged along block fronts.
//! - [`oracle`]: CPU z-buffer id renderer, the ground truth; [`oracle::shade`] fallback images.
//! - [`culler`]: [`OcclusionCuller`], per-frame occluder selection and culling through a
//!   [`crate::index::CityIndex`].
//! - [`frame`]: the per-frame roles as traits ([`OcclusionCulling`], [`VisibilityOracle`],
//!   [`FrameRenderer`]) with their CPU implementations.
//! - [`views`]: seeded random street-level and flying views over a city.
//! - [`synthetic`]: a synthetic grid city with exact meshes, for tests and benches.
//! - [`bench`]: the culler against the oracle over random views, per cull map resolution.

pub mod bench;
pub mod culler;
pub mod cullmap;
pub mod frame;
pub mod occluders;
pub mod oracle;
pub mod shadow;
pub mod synthetic;
pub mod views;

pub use culler::{CullerOptions, OcclusionCuller, OcclusionStats, SkipReason};
pub use cullmap::{CullMap, Resolution};
pub use frame::{
    CpuFrameRenderer, DrawError, DrawnFrame, FrameRenderer, MeshOracle, OcclusionCulling,
    VisibilityOracle,
};
pub use occluders::{BlockOccluders, OccluderOptions};
pub use shadow::{NoShadow, Occluder, OccluderShadow};

/// What went wrong in occlusion culling or the oracle.
#[derive(Debug, thiserror::Error)]
pub enum VisibilityError {
    /// The cull map's bounds are not a finite box.
    #[error("cull map bounds are not a finite box: min {min:?}, max {max:?}")]
    BadBounds {
        /// Lower corner.
        min: [f64; 2],
        /// Upper corner.
        max: [f64; 2],
    },
    /// The resolution is out of range.
    #[error("cull map resolution out of range: {0}")]
    BadResolution(String),
    /// A parameter is out of range.
    #[error("bad parameter: {0}")]
    BadParameter(String),
}
