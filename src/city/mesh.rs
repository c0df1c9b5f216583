//! Triangle meshes in the local frame (f32).

use glam::Vec3;

/// An indexed triangle mesh in local-frame coordinates. Triangles are counter-clockwise seen
/// from outside (outward normals).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, local frame, metres.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (flat shading: vertices are not shared between faces of different
    /// orientation).
    pub normals: Vec<Vec3>,
    /// Three indices per triangle.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Appends `other`'s vertices and triangles (its indices shifted past this mesh's vertices).
    pub fn append(&mut self, other: Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.indices.extend(other.indices.iter().map(|k| k + base));
    }
}
