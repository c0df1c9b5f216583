//! Spatial structures over blocks behind one interface (seed 003 §4).
//!
//! - [`block_bounds`]: per block, its 3D box, outline centre and triangle count.
//! - [`BqrTree`]: the BqR-tree (seed 003 §4), adaptive quadtree of bounding spheres ending in
//!   box∩sphere leaves; also holds small mobile objects.
//! - [`VamSplitTree`]: the VAMSplit R-tree (White & Jain 1996), the paper's comparison.
//! - [`FlatList`], [`NoStructure`]: test every block, or none.
//! - [`RstarIndex`]: the same queries through the `rstar` crate.
//! - [`synthetic`]: seeded synthetic block grids for benches and tests.
//! - [`mod@bench`]: the `cull-bench` core (random views, timings, false culls against brute force).
//!
//! Every structure is immutable after its build and `Send + Sync`; per-frame state (temporal
//! coherence) is owned by the caller.

pub mod bench;
mod bounds;
mod bqr;
mod bqr_layout;
mod flat;
mod rstar_index;
mod scene_graph;
mod sphere;
pub mod synthetic;
mod vamsplit;

pub use bounds::{block_bounds, extruded_triangles};
pub use bqr::{BqrNodeKind, BqrNodeView, BqrParams, BqrTree, ObjectId};
pub use flat::{FlatList, NoStructure};
pub use rstar_index::RstarIndex;
pub use scene_graph::{SceneGraphParams, SceneGraphTree};
pub use sphere::enclosing_sphere;
pub use vamsplit::{VamSplitParams, VamSplitTree};

use crate::blocks::BlockId;
use crate::choice::Choice;
use crate::geom::{Aabb3, BoundingSphere, Frustum};
use glam::DVec3;
use serde::Serialize;

/// Bad parameters or input for an index build.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IndexError {
    /// A parameter is out of its range.
    #[error("{structure}: parameter `{name}` = {value} is invalid: {reason}")]
    BadParam {
        /// Structure being built.
        structure: Structure,
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: String,
        /// What is expected.
        reason: &'static str,
    },
    /// A mobile object's box is empty or not finite.
    #[error("{structure}: object {id} has a non-finite or empty box")]
    BadObject {
        /// Structure.
        structure: Structure,
        /// The object's id.
        id: u32,
    },
    /// An object id inserted twice.
    #[error("{structure}: object {id} is already in the index")]
    DuplicateObject {
        /// Structure.
        structure: Structure,
        /// The object's id.
        id: u32,
    },
    /// An object id not in the index.
    #[error("{structure}: object {id} is not in the index")]
    UnknownObject {
        /// Structure.
        structure: Structure,
        /// The object's id.
        id: u32,
    },
    /// A block's bounds hold NaN or infinite coordinates, an empty box or a negative radius.
    #[error(
        "{structure}: block {index} (id {id}) has a non-finite or empty box, centre or sphere"
    )]
    BadBlock {
        /// Structure being built.
        structure: Structure,
        /// Position in the input slice.
        index: usize,
        /// The block's id.
        id: u32,
    },
}

/// Checks what every structure needs of its input: finite, non-empty boxes, finite centres and
/// spheres.
pub(crate) fn validate_bounds(
    structure: Structure,
    bounds: &[BlockBounds],
) -> Result<(), IndexError> {
    for (index, b) in bounds.iter().enumerate() {
        let finite = b.aabb.min.is_finite()
            && b.aabb.max.is_finite()
            && b.center.is_finite()
            && b.sphere.center.is_finite()
            && b.sphere.radius.is_finite();
        // `finite` has ruled NaN out: a plain comparison is enough.
        if !finite || b.aabb.is_empty() || b.sphere.radius < 0.0 {
            return Err(IndexError::BadBlock {
                structure,
                index,
                id: b.id.0,
            });
        }
    }
    Ok(())
}

/// A view query: the frustum (local frame) and the eye, for front-to-back order.
#[derive(Clone, Copy, Debug)]
pub struct CullQuery<'a> {
    /// The view frustum, local frame.
    pub frustum: &'a Frustum,
    /// Eye position, local frame: children are visited nearest first.
    pub eye: DVec3,
}

impl<'a> CullQuery<'a> {
    /// A query whose eye is the frustum's apex (or the centre of its corners for a degenerate
    /// frustum).
    pub fn new(frustum: &'a Frustum) -> Self {
        let eye = frustum
            .apex()
            .or_else(|| {
                frustum
                    .corners()
                    .map(|c| c.iter().copied().sum::<DVec3>() / 8.0)
            })
            .unwrap_or(DVec3::ZERO);
        Self { frustum, eye }
    }
    /// A query with an explicit eye.
    pub fn with_eye(frustum: &'a Frustum, eye: DVec3) -> Self {
        Self { frustum, eye }
    }
}

/// What a structure indexes for each block: its 3D bounds in the local frame (f64) and how many
/// triangles drawing it costs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlockBounds {
    /// The block.
    pub id: BlockId,
    /// Box around all of the block's geometry (footprint × [0, max height]), local frame.
    pub aabb: Aabb3,
    /// The block's own bounding sphere: the smallest sphere around its geometry's vertices
    /// (footprint vertices × [min height, height] of every building, [`enclosing_sphere`]), local
    /// frame. The BqR-tree's leaf volume is this sphere ∩ `aabb` (seed 003 §4); it holds every
    /// vertex, so the intersection holds the geometry.
    pub sphere: BoundingSphere,
    /// Geometric centre of the block's outline (x, y), local frame.
    pub center: glam::DVec2,
    /// Triangles of the block's meshes.
    pub triangles: u32,
}

impl BlockBounds {
    /// Bounds of a block whose geometry fills its box (or of which only the box is known): the
    /// sphere is the box's circumscribed sphere, so box ∩ sphere is the box.
    pub fn from_box(id: BlockId, aabb: Aabb3, center: glam::DVec2, triangles: u32) -> Self {
        Self {
            id,
            aabb,
            sphere: BoundingSphere::from_aabb(&aabb),
            center,
            triangles,
        }
    }
}

/// Per-query work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CullStats {
    /// Nodes whose volume was tested or accepted.
    pub nodes_visited: u64,
    /// Plane tests done.
    pub plane_tests: u64,
    /// Blocks pushed to the output.
    pub blocks_accepted: u64,
    /// Triangles of the accepted blocks.
    pub triangles_accepted: u64,
}

impl std::ops::AddAssign for CullStats {
    fn add_assign(&mut self, o: Self) {
        self.nodes_visited += o.nodes_visited;
        self.plane_tests += o.plane_tests;
        self.blocks_accepted += o.blocks_accepted;
        self.triangles_accepted += o.triangles_accepted;
    }
}

/// The spatial structures blockwalk can build, named once: the command line's `--structure`
/// values, the reports' column names and the serialized names all come from this enum.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Structure {
    /// No structure: every block is drawn (the baseline).
    None,
    /// Every block tested on its own against the frustum.
    Flat,
    /// The VAMSplit R-tree (White & Jain 1996), the paper's comparison.
    Vamsplit,
    /// The BqR-tree (seed 003 §4).
    Bqr,
    /// An R*-tree from the `rstar` crate, as an external anchor.
    Rstar,
    /// The VAMSplit R-tree over buildings with leaves (pages of buildings) drawn whole, the
    /// scene-graph semantics of seed 003 §5.1 ([`SceneGraphTree`]). Its output ids are *page*
    /// ids, not block ids, so it is not in [`Structure::ALL`]; [`crate::scene::Scene`] builds it
    /// over the buildings.
    #[serde(rename = "scenegraph")]
    SceneGraph,
}

impl Structure {
    /// Every structure over blocks, in the order reports list them (not
    /// [`Structure::SceneGraph`], whose output ids are pages).
    pub const ALL: [Structure; 5] = [
        Structure::None,
        Structure::Flat,
        Structure::Vamsplit,
        Structure::Bqr,
        Structure::Rstar,
    ];

    /// True when the structure's output ids are blocks (every structure but
    /// [`Structure::SceneGraph`], whose ids are pages of buildings).
    pub fn culls_blocks(self) -> bool {
        self != Structure::SceneGraph
    }

    /// The structure's name (its command-line value, [`Choice::name`]).
    pub fn name(self) -> String {
        Choice::name(self).to_string()
    }

    /// Builds this structure over `bounds` with default parameters.
    ///
    /// # Errors
    /// The structure's own build errors ([`IndexError::BadBlock`] for a non-finite box).
    ///
    /// # Examples
    /// ```
    /// use blockwalk::index::{synthetic::block_grid, CullQuery, Structure};
    /// use blockwalk::geom::Camera;
    /// use glam::DVec3;
    ///
    /// let bounds = block_grid(100, 7);
    /// let tree = Structure::Bqr.build(&bounds).unwrap();
    /// assert_eq!(tree.structure(), Structure::Bqr);
    /// let camera = Camera::new(DVec3::new(0.0, 0.0, 1.7), 0.3, 0.0);
    /// let frustum = camera.frustum();
    /// let mut visible = Vec::new();
    /// let stats = tree.cull(&CullQuery::new(&frustum), None, &mut visible);
    /// assert_eq!(stats.blocks_accepted as usize, visible.len());
    /// ```
    pub fn build(self, bounds: &[BlockBounds]) -> Result<Box<dyn CityIndex>, IndexError> {
        Ok(match self {
            Structure::Bqr => Box::new(BqrTree::build(bounds, &BqrParams::default())?),
            Structure::Vamsplit => {
                Box::new(VamSplitTree::build(bounds, &VamSplitParams::default())?)
            }
            Structure::Flat => Box::new(FlatList::build(bounds)?),
            Structure::None => Box::new(NoStructure::build(bounds)?),
            Structure::Rstar => Box::new(RstarIndex::build(bounds)?),
            // The items are whatever `bounds` holds (the scene passes buildings).
            Structure::SceneGraph => {
                Box::new(SceneGraphTree::build(bounds, &SceneGraphParams::default())?)
            }
        })
    }
}

crate::choice::choices!(Structure, "structure",
    None => "none", "No structure: every block is drawn (the baseline)";
    Flat => "flat", "Every block tested on its own against the frustum";
    Vamsplit => "vamsplit", "The VAMSplit R-tree (White & Jain 1996), the paper's comparison";
    Bqr => "bqr", "The BqR-tree (Pina, Serón and Cerezo, §4)";
    Rstar => "rstar", "An R*-tree from the `rstar` crate, as an external anchor";
    SceneGraph => "scenegraph", "The VAMSplit R-tree over buildings with leaves (pages of buildings) drawn whole, the scene-graph semantics of Pina, Serón and Cerezo, §5.1";
);

/// A spatial structure that returns the blocks to draw for a view.
///
/// Block ids in the output are those of the [`BlockBounds`] the structure was built from.
pub trait CityIndex: Send + Sync {
    /// Which structure this is.
    fn structure(&self) -> Structure;

    /// The one cull entry point: pushes every block that may intersect `query.frustum` to `out`
    /// (never drops one that does), front to back from `query.eye` when the structure can.
    ///
    /// `hidden_filter`, when given, is asked about every node and block that survives the
    /// frustum test, and a volume for which it answers `false` (proven hidden, e.g. by the cull
    /// map of seed 004 §3.2) is dropped with its subtree. Without it, a node completely inside
    /// the frustum is accepted with its whole subtree without further tests (seed 003 §5): pass
    /// `None` whenever there is nothing to filter, so that this shortcut applies.
    fn cull(
        &self,
        query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats;

    /// Number of blocks indexed.
    fn len(&self) -> usize;

    /// True when no block is indexed.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of nodes (0 for flat structures).
    fn node_count(&self) -> usize {
        0
    }
}

/// Collects accepted blocks and counts; shared by the traversals.
pub(crate) struct Sink<'k, 'o> {
    pub keep: Option<&'k mut dyn FnMut(&Aabb3) -> bool>,
    pub out: &'o mut Vec<BlockId>,
    pub stats: CullStats,
}

impl Sink<'_, '_> {
    #[inline]
    pub fn keep(&mut self, b: &Aabb3) -> bool {
        match &mut self.keep {
            Some(k) => k(b),
            None => true,
        }
    }
    #[inline]
    pub fn accept(&mut self, b: &BlockBounds) {
        self.out.push(b.id);
        self.stats.blocks_accepted += 1;
        self.stats.triangles_accepted += u64::from(b.triangles);
    }
}
