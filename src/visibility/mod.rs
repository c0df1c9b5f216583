//! Occlusion culling with occluder shadows and a cull map (seed 004 §3.2), and the visibility
//! oracle that checks it.
//!
//! - [`shadow`]: [`Occluder`] (a facade's top edge) and its [`OccluderShadow`] from a viewpoint.
//! - [`cullmap`]: [`CullMap`], conservative rasterisation of shadows, and its [`cullmap::MinPyramid`].
//! - [`occluders`]: facade edges per block, collinear runs merged along block fronts.
//! - [`oracle`]: CPU z-buffer id renderer, the ground truth; [`oracle::shade`] fallback images.
//! - [`bench`]: culler against oracle over random views; a synthetic test city; a list index.
//! - [`culler`]: [`OcclusionCuller`], per-frame occluder selection and culling through a
//!   [`crate::index::CityIndex`].

pub mod bench;
pub mod culler;
pub mod cullmap;
pub mod occluders;
pub mod oracle;
pub mod shadow;

pub use culler::{CullerOptions, OcclusionCuller, OcclusionStats, SkipReason};
pub use cullmap::{CullMap, Resolution};
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
