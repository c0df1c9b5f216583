//! Occlusion culling with occluder shadows and a cull map (Willmott et al., §3.2), and the visibility
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
//! - [`adversarial`]: seeded adversarial views (eyes at the near plane's distance from corners
//!   and walls, on wall planes, over roofs, straight up and down).
//! - [`terrain`]: [`TerrainDraw`], a terrain as the oracle and the renderers draw it (tiles, a
//!   per-frame cut, the full mesh), [`FixedTerrain`] and height fields on a grid.
//! - [`synthetic`]: a synthetic grid city with exact meshes, for tests and benches.
//! - [`buildings`]: per-building culling inside the blocks that survived (Willmott et al., §3.2.8).
//! - [`bench`]: the culler against the oracle over random views, per cull map resolution.
//! - [`route_proof`]: the culler and the per-building test against the supersampled oracle on
//!   every frame of whole routes, for every structure and several cull map resolutions.

pub mod adversarial;
pub mod bench;
pub mod buildings;
pub mod culler;
pub mod cullmap;
pub mod frame;
pub mod occluders;
pub mod oracle;
pub mod route_proof;
pub mod shadow;
pub mod synthetic;
pub mod terrain;
pub mod views;

pub use culler::{CullerOptions, OcclusionCuller, OcclusionStats, SkipReason};
pub use cullmap::{CullMap, Resolution};
pub use frame::{
    CpuFrameRenderer, DrawError, DrawnFrame, FrameRenderer, MeshOracle, OcclusionCulling,
    VisibilityOracle,
};
pub use occluders::{BlockOccluders, OccluderOptions};
pub use shadow::{NoShadow, Occluder, OccluderShadow};
pub use terrain::{
    draws_flat_ground, FixedTerrain, HeightGrid, SharedTerrain, TerrainDraw, TERRAIN_ID,
};

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
    /// The resolution asks for no cells, more than [`cullmap::MAX_CELLS_PER_SIDE`] per side, or a
    /// cell size that is not a finite positive length.
    #[error(
        "cull map resolution {resolution:?} is out of range (1..={max} cells per side, or a \
         finite cell size > 0 m)"
    )]
    BadResolution {
        /// The resolution asked for.
        resolution: Resolution,
        /// Most cells allowed per side.
        max: usize,
    },
    /// The cell size gives too many cells over the bounds.
    #[error(
        "cull map resolution {resolution:?} gives {nx}×{ny} cells over {width:.0}×{height:.0} m \
         (at most {max} per side)"
    )]
    TooManyCells {
        /// The resolution asked for.
        resolution: Resolution,
        /// Cells along x it would give.
        nx: usize,
        /// Cells along y it would give.
        ny: usize,
        /// Width of the bounds, metres.
        width: f64,
        /// Height of the bounds, metres.
        height: f64,
        /// Most cells allowed per side.
        max: usize,
    },
    /// A parameter is out of range.
    #[error("bad parameter {name} = {value}: must be {expected}")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// A benchmark was given no cull map resolution to measure.
    #[error("no cull map resolution given")]
    NoResolutions,
}
