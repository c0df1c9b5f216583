//! The far-field interface: what the walk, the selector, the silhouette bound, the sweep and the
//! viewer need of a far-field representation, and nothing more.
//!
//! A representation is a set of nodes of the block quadtree, each standing for the blocks under
//! it with a declared world-space error. The walk asks it for:
//! - a [`Selector`] over the scene's blocks: per view, the nodes whose projected error is at most
//!   τ pixels, the rest as meshes (the top-down selection of Cignoni et al., §5, which needs of a
//!   node only its box, its declared error, its parent and its blocks);
//! - a CPU reference renderer of meshes and nodes composited by depth ([`FarField::cpu_renderer`]),
//!   the fallback of hybrid walks and the truth the GPU renderer is compared with;
//! - the data the GPU renderer uploads ([`FarField::gpu`]);
//! - the exact-geometry check of the silhouette bound ([`FarField::silhouette_bound`]), which
//!   measures a hybrid frame against the mesh frame of the same camera.
//!
//! BlockMaps ([`crate::blockmap::MapTree`]) are the first implementation, relief impostors
//! ([`crate::relief::ReliefField`], [`super::relief`]) the second. A representation is a module
//! that implements [`FarField`] (and [`BuildFar`] to be built from a scene), its GPU pass behind
//! [`FarGpu`], and [`crate::walk::bound::BoundMaps`] for the silhouette bound's second look.

use crate::blockmap::{BlockMap, MapTree, SelectError, SelectOptions, Selection, Selector, Source};
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::index::BlockBounds;
use crate::scene::Scene;
use crate::visibility::{FrameRenderer, TerrainDraw};
use serde::Serialize;

use super::super::bound::{BoundFigures, BoundGeometry, FrameBound};

/// A far-field representation of a scene's blocks (see the module doc).
pub trait FarField: Sync {
    /// The representation's name in reports ("BlockMaps").
    fn name(&self) -> &'static str;

    /// Nodes that have a representation (the indices [`Selection::maps`] refers to).
    fn len(&self) -> usize;

    /// True when no node has a representation (meshes are cheaper everywhere).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// What was built: nodes, bytes, declared errors.
    fn build_summary(&self) -> FarBuildSummary;

    /// A selector over the scene's block bounds `blocks` with τ and hysteresis `opts`.
    ///
    /// # Errors
    /// [`SelectError`] when the nodes do not fit the blocks.
    fn selector(
        &self,
        blocks: &[BlockBounds],
        opts: SelectOptions,
    ) -> Result<Selector, SelectError>;

    /// The CPU reference renderer of hybrid frames: `meshes` (the scene's draw meshes) and
    /// `ground` (or, when given, the `terrain`'s cut instead) by a z-buffer, the nodes by the
    /// representation's reference caster, composited by depth, at `size`.
    fn cpu_renderer<'a>(
        &'a self,
        meshes: &'a [(BlockId, Mesh)],
        ground: &'a Mesh,
        terrain: Option<&'a dyn TerrainDraw>,
        size: (u32, u32),
    ) -> Box<dyn FrameRenderer + 'a>;

    /// What the GPU renderer uploads to draw the nodes.
    fn gpu(&self) -> FarGpu<'_>;

    /// The exact-geometry check of the silhouette bound for hybrid frames of this far field,
    /// with the city's buildings as prisms (`source`, built from the same city).
    fn silhouette_bound<'a>(&'a self, source: &'a Source<'a>) -> Box<dyn SilhouetteBound + 'a>;
}

/// A far field that can be built for a scene.
pub trait BuildFar: FarField + Sized {
    /// The build settings.
    type Options;
    /// Why a build failed.
    type Error: std::error::Error + Send + Sync + 'static;

    /// Builds the representation of `scene`'s block quadtree nodes with `opts`;
    /// `progress(done, total)` hears the nodes as they finish.
    ///
    /// # Errors
    /// The representation's build error.
    fn build(
        scene: &Scene,
        opts: &Self::Options,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, Self::Error>;
}

/// The data a GPU renderer uploads for a far field (one variant per representation).
#[non_exhaustive]
pub enum FarGpu<'a> {
    /// BlockMaps, ray-cast in WGSL: the maps in node order.
    BlockMaps(Vec<&'a BlockMap>),
    /// Relief impostors, ray-cast in WGSL over each node's max pyramid.
    Relief(&'a crate::relief::ReliefField),
}

/// What a far field holds, as the walk report and the sweep state it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FarBuildSummary {
    /// The representation's name.
    pub representation: String,
    /// Nodes with a representation.
    pub nodes: usize,
    /// Bytes of all nodes' images.
    pub bytes: u64,
    /// Largest declared world-space error of a node, metres.
    pub max_error_m: f64,
}

/// The silhouette bound `1 + τ/cos²θ` of hybrid frames, checked with the exact geometry.
pub trait SilhouetteBound: Sync {
    /// The check of one frame: `selection` drawn from `camera` at threshold `tau_px`.
    fn frame<'g>(
        &'g self,
        selection: &'g Selection,
        camera: &'g Camera,
        tau_px: f64,
    ) -> Box<dyn PixelBound + 'g>;
}

/// The per-pixel check of one frame's coverage-mismatched pixels.
pub trait PixelBound {
    /// Checks the bound over the mismatched pixels of a `w × h` frame: `mismatched` lists
    /// `(x, y, extra, raw)` (`extra`: only the hybrid frame covers it; `raw`: its distance to the
    /// silhouette of the frame that does not cover it), `mesh_sil` marks the mesh frame's
    /// silhouette pixels (row-major).
    fn check(
        &self,
        w: u32,
        h: u32,
        mismatched: &[(u32, u32, bool, f64)],
        mesh_sil: &[bool],
    ) -> BoundFigures;
}

impl PixelBound for FrameBound<'_, '_> {
    fn check(
        &self,
        w: u32,
        h: u32,
        mismatched: &[(u32, u32, bool, f64)],
        mesh_sil: &[bool],
    ) -> BoundFigures {
        FrameBound::check(self, w, h, mismatched, mesh_sil)
    }
}

impl SilhouetteBound for BoundGeometry<'_> {
    fn frame<'g>(
        &'g self,
        selection: &'g Selection,
        camera: &'g Camera,
        tau_px: f64,
    ) -> Box<dyn PixelBound + 'g> {
        Box::new(FrameBound::new(self, selection, camera, tau_px))
    }
}

impl FarField for MapTree {
    fn name(&self) -> &'static str {
        "BlockMaps"
    }

    fn len(&self) -> usize {
        self.maps.len()
    }

    fn build_summary(&self) -> FarBuildSummary {
        FarBuildSummary {
            representation: self.name().to_string(),
            nodes: self.maps.len(),
            bytes: self.maps.iter().map(|m| m.map.bytes() as u64).sum(),
            max_error_m: self
                .maps
                .iter()
                .map(|m| m.map.meta.eps_m)
                .fold(0.0, f64::max),
        }
    }

    fn selector(
        &self,
        blocks: &[BlockBounds],
        opts: SelectOptions,
    ) -> Result<Selector, SelectError> {
        Selector::new(self, blocks, opts)
    }

    fn cpu_renderer<'a>(
        &'a self,
        meshes: &'a [(BlockId, Mesh)],
        ground: &'a Mesh,
        terrain: Option<&'a dyn TerrainDraw>,
        size: (u32, u32),
    ) -> Box<dyn FrameRenderer + 'a> {
        let r = crate::blockmap::CpuHybridRenderer::new(
            meshes,
            ground,
            self.maps.iter().map(|m| &m.map).collect(),
            size,
        );
        match terrain {
            Some(t) => Box::new(r.with_terrain(t)),
            None => Box::new(r),
        }
    }

    fn gpu(&self) -> FarGpu<'_> {
        FarGpu::BlockMaps(self.maps.iter().map(|m| &m.map).collect())
    }

    fn silhouette_bound<'a>(&'a self, source: &'a Source<'a>) -> Box<dyn SilhouetteBound + 'a> {
        Box::new(BoundGeometry::new(source, self))
    }
}

/// The BlockMaps of a scene at the competitive stop (Cignoni et al., §4), no image checks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BlockMapsOptions {
    /// The maps' construction settings (the side K is `build.k`).
    pub build: crate::blockmap::BuildOptions,
}

impl BuildFar for MapTree {
    type Options = BlockMapsOptions;
    type Error = crate::blockmap::BlockMapError;

    fn build(
        scene: &Scene,
        opts: &BlockMapsOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, Self::Error> {
        use crate::blockmap::{CityMapsOptions, Stop, TreeOptions};
        let city = CityMapsOptions {
            tree: TreeOptions {
                build: opts.build,
                stop: Stop::Competitive,
                ..TreeOptions::default()
            },
            checks: 0,
            ..CityMapsOptions::default()
        };
        Ok(scene.blockmaps(&city, progress)?.maps)
    }
}
