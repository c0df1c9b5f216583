//! Triangle meshes in the local frame (f32).

use glam::Vec3;

use super::appearance::BuildingStyle;

/// What a vertex carries for the procedural appearance ([`super::appearance`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VertexAppearance {
    /// Along-wall coordinate, metres: the distance along the unfolded ring from its first vertex
    /// ([`super::appearance::ring_u`]) for wall vertices; 0 on roofs, floors and the ground.
    pub u_m: f32,
    /// Index of the vertex's style in [`Mesh::styles`].
    pub style: u32,
}

/// An indexed triangle mesh in local-frame coordinates. Triangles are counter-clockwise seen
/// from outside (outward normals).
///
/// The appearance is optional: `appearance` is either empty (every vertex has the default
/// [`BuildingStyle`]) or holds one entry per position, each naming an entry of `styles`. The
/// height used by [`super::appearance::facade_color`] is the position's z (the local frame's
/// z = 0 is the ground).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, local frame, metres.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (flat shading: vertices are not shared between faces of different
    /// orientation).
    pub normals: Vec<Vec3>,
    /// Three indices per triangle.
    pub indices: Vec<u32>,
    /// Per-vertex appearance: empty, or one per position.
    pub appearance: Vec<VertexAppearance>,
    /// The styles `appearance` refers to (usually one per building).
    pub styles: Vec<BuildingStyle>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The style of vertex `i` (the default style when the mesh carries no appearance or the
    /// entry is out of range) and its along-wall coordinate.
    pub fn vertex_style(&self, i: usize) -> (BuildingStyle, f32) {
        match self.appearance.get(i) {
            Some(a) => (
                self.styles
                    .get(a.style as usize)
                    .copied()
                    .unwrap_or_default(),
                a.u_m,
            ),
            None => (BuildingStyle::default(), 0.0),
        }
    }

    /// Appends `other` (its indices and style indices shifted); keeps the appearance of both,
    /// giving the default style to the vertices of a mesh that has none.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        let keep = !self.appearance.is_empty() || !other.appearance.is_empty();
        if keep && self.appearance.len() != self.positions.len() {
            let style = self.styles.len() as u32;
            self.styles.push(BuildingStyle::default());
            self.appearance = vec![VertexAppearance { u_m: 0.0, style }; self.positions.len()];
        }
        if keep {
            let style0 = self.styles.len() as u32;
            if other.appearance.len() == other.positions.len() {
                self.styles.extend_from_slice(&other.styles);
                self.appearance
                    .extend(other.appearance.iter().map(|a| VertexAppearance {
                        u_m: a.u_m,
                        style: a.style + style0,
                    }));
            } else {
                self.styles.push(BuildingStyle::default());
                let n = self.appearance.len() + other.positions.len();
                self.appearance.resize(
                    n,
                    VertexAppearance {
                        u_m: 0.0,
                        style: style0,
                    },
                );
            }
        }
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.indices.extend(other.indices.iter().map(|k| k + base));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::appearance::{unit_rgb, BuildingStyle};

    fn tri(style: Option<BuildingStyle>) -> Mesh {
        let mut m = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            indices: vec![0, 1, 2],
            ..Default::default()
        };
        if let Some(s) = style {
            m.styles.push(s);
            m.appearance = (0..3)
                .map(|i| VertexAppearance {
                    u_m: i as f32,
                    style: 0,
                })
                .collect();
        }
        m
    }

    #[test]
    fn append_keeps_styles_and_shifts_indices() {
        let red = BuildingStyle::flat(unit_rgb([255, 0, 0]), unit_rgb([255, 0, 0]));
        let blue = BuildingStyle::flat(unit_rgb([0, 0, 255]), unit_rgb([0, 0, 255]));
        let mut m = tri(None);
        m.append(&tri(Some(red)));
        m.append(&tri(Some(blue)));
        m.append(&tri(None));
        assert_eq!(m.positions.len(), 12);
        assert_eq!(m.appearance.len(), 12);
        assert_eq!(m.indices[3..6], [3, 4, 5]);
        assert_eq!(m.vertex_style(0).0, BuildingStyle::default());
        assert_eq!(m.vertex_style(4), (red, 1.0));
        assert_eq!(m.vertex_style(8).0, blue);
        assert_eq!(m.vertex_style(11).0, BuildingStyle::default());
        // Without any appearance nothing is added.
        let mut plain = tri(None);
        plain.append(&tri(None));
        assert!(plain.appearance.is_empty() && plain.styles.is_empty());
    }
}
