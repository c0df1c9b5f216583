//! A scene's terrain: the city's ground as a level-of-detail tree with its tile meshes made once,
//! the full-resolution mesh (the truth the oracle and the reference images draw), and the
//! per-frame cut at a projected error of τ pixels.

use crate::city::{LocalFrame, Mesh};
use crate::geom::Camera;
use crate::terrain::{NodeId, Terrain, TerrainMesh, TerrainTree, TreeError, TreeOptions};

/// Default projected error of the terrain's cut, pixels.
pub const DEFAULT_TERRAIN_TAU_PX: f64 = 1.0;

/// The terrain of a scene.
#[derive(Debug)]
pub struct SceneTerrain {
    /// The level-of-detail tree over the city's terrain.
    pub tree: TerrainTree,
    /// One mesh per tree node (with its skirts), local frame, indexed by node.
    pub tiles: Vec<Mesh>,
    /// The full-resolution terrain, local frame.
    pub full: Mesh,
    /// The largest projected error of a drawn tile, pixels.
    pub tau_px: f64,
    /// The city's local frame.
    pub frame: LocalFrame,
}

/// A terrain mesh as a drawable mesh (no appearance: the renderers colour terrain themselves).
fn to_mesh(m: TerrainMesh) -> Mesh {
    Mesh {
        positions: m.positions,
        normals: m.normals,
        indices: m.indices,
        ..Mesh::default()
    }
}

impl SceneTerrain {
    /// The tree of `terrain` (shared with the city, not copied; tiles of `opts.tile_cells` cells), every tile's mesh and the
    /// full-resolution mesh in `frame`, cut at `tau_px` pixels.
    ///
    /// # Errors
    /// [`TreeError`] for unusable options.
    pub fn build(
        terrain: std::sync::Arc<Terrain>,
        frame: LocalFrame,
        opts: &TreeOptions,
        tau_px: f64,
    ) -> Result<Self, TreeError> {
        use rayon::prelude::*;
        let tree = TerrainTree::build_shared(terrain, opts)?;
        let ids: Vec<NodeId> = tree.node_ids().collect();
        let tiles = ids
            .par_iter()
            .map(|&n| to_mesh(tree.node_mesh(n, &frame)))
            .collect();
        let full = to_mesh(tree.full_mesh(&frame));
        Ok(Self {
            tree,
            tiles,
            full,
            tau_px,
            frame,
        })
    }

    /// The tiles to draw for `camera` on an image of `size` pixels (indices into
    /// [`Self::tiles`]), appended to `out`.
    pub fn cut(&self, camera: &Camera, size: (u32, u32), out: &mut Vec<usize>) {
        let mut ids = Vec::new();
        self.tree
            .select(camera, &self.frame, size.1, self.tau_px, &mut ids);
        out.extend(ids.into_iter().map(|n| n.0 as usize));
    }

    /// Triangles of the tiles `cut` (a cut's cost), and of the full-resolution mesh.
    pub fn triangles(&self, cut: &[usize]) -> (usize, usize) {
        (
            cut.iter()
                .filter_map(|&k| self.tiles.get(k))
                .map(|m| m.indices.len() / 3)
                .sum(),
            self.full.indices.len() / 3,
        )
    }
}

impl crate::visibility::TerrainDraw for SceneTerrain {
    fn tiles(&self) -> &[Mesh] {
        &self.tiles
    }
    fn cut(&self, camera: &Camera, size: (u32, u32), out: &mut Vec<usize>) {
        SceneTerrain::cut(self, camera, size, out);
    }
    fn full(&self) -> &Mesh {
        &self.full
    }
}
