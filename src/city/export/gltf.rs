//! glTF 2.0 binary (`.glb`) export of the extruded city.
//!
//! One node per building (`name` = source id; `extras` = `{source_id, height_m, min_height_m}`)
//! holding one mesh with one primitive (POSITION with the min/max the specification requires,
//! NORMAL, u32 indices) and a shared default material. All buildings hang under one root node
//! whose `extras` carry the local origin (metric world coordinates) and the CRS, so a reader can
//! put the city back in the world. glTF is Y-up: local (x, y, z-up) is written as (x, z, −y), a
//! proper rotation, so triangle winding and outward normals are kept.
//!
//! The JSON document is written with `serde_json` following the glTF 2.0 schema; the tests read
//! the file back with the `gltf` crate, which validates it.

use std::path::Path;

use glam::Vec3;
use serde_json::{json, Value};

use super::ExportError;
use crate::city::{City, Mesh};

/// What [`write_glb`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GlbStats {
    /// Building nodes.
    pub nodes: usize,
    /// Meshes (buildings with at least one triangle).
    pub meshes: usize,
    /// Triangles.
    pub triangles: usize,
    /// File size in bytes.
    pub bytes: usize,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

fn y_up(v: Vec3) -> [f32; 3] {
    [v.x, v.z, -v.y]
}

fn pad4(buf: &mut Vec<u8>, byte: u8) {
    while buf.len() & 3 != 0 {
        buf.push(byte);
    }
}

/// The `.glb` file of a city and its meshes (`meshes[i]` is building `i`'s).
///
/// # Errors
/// [`ExportError::MeshCount`] when `meshes` does not match the buildings (its file is `<glb>`).
pub fn glb_bytes(city: &City, meshes: &[Mesh]) -> Result<(Vec<u8>, GlbStats), ExportError> {
    if meshes.len() != city.buildings.len() {
        return Err(ExportError::MeshCount {
            file: "<glb>".into(),
            meshes: meshes.len(),
            buildings: city.buildings.len(),
        });
    }
    let n_vert: usize = meshes.iter().map(|m| m.positions.len()).sum();
    let n_idx: usize = meshes.iter().map(|m| m.indices.len()).sum();
    let pos_len = n_vert * 12;
    let idx_len = n_idx * 4;
    let mut bin: Vec<u8> = Vec::with_capacity(2 * pos_len + idx_len);
    for m in meshes {
        for p in &m.positions {
            for c in y_up(*p) {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for m in meshes {
        for n in &m.normals {
            for c in y_up(*n) {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for m in meshes {
        for i in &m.indices {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let bin_len = bin.len();

    let mut accessors: Vec<Value> = Vec::new();
    let mut gl_meshes: Vec<Value> = Vec::new();
    let mut nodes: Vec<Value> = vec![Value::Null]; // root, filled below
    let mut children: Vec<usize> = Vec::new();
    let (mut vert_off, mut idx_off) = (0usize, 0usize);
    let mut stats = GlbStats::default();
    for (b, m) in city.buildings.iter().zip(meshes) {
        let mut node = json!({
            "name": b.source_id,
            "extras": {
                "source_id": b.source_id,
                "height_m": b.height_m,
                "min_height_m": b.min_height_m,
            }
        });
        if m.triangle_count() > 0 {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in &m.positions {
                let q = y_up(*p);
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            let a_pos = accessors.len();
            accessors.push(json!({
                "bufferView": 0, "byteOffset": vert_off * 12, "componentType": FLOAT,
                "count": m.positions.len(), "type": "VEC3", "min": lo, "max": hi,
            }));
            accessors.push(json!({
                "bufferView": 1, "byteOffset": vert_off * 12, "componentType": FLOAT,
                "count": m.normals.len(), "type": "VEC3",
            }));
            accessors.push(json!({
                "bufferView": 2, "byteOffset": idx_off * 4, "componentType": UNSIGNED_INT,
                "count": m.indices.len(), "type": "SCALAR",
            }));
            node["mesh"] = json!(gl_meshes.len());
            gl_meshes.push(json!({
                "name": b.source_id,
                "primitives": [{
                    "attributes": { "POSITION": a_pos, "NORMAL": a_pos + 1 },
                    "indices": a_pos + 2,
                    "material": 0,
                    "mode": 4,
                }]
            }));
            stats.meshes += 1;
            stats.triangles += m.triangle_count();
        }
        vert_off += m.positions.len();
        idx_off += m.indices.len();
        children.push(nodes.len());
        nodes.push(node);
        stats.nodes += 1;
    }
    let o = city.frame.origin;
    nodes[0] = json!({
        "name": city.name,
        "children": children,
        "extras": {
            "origin": [o.x, o.y, o.z],
            "crs": city.transform.describe(),
            "frame": "local metres: x east, y up, z south of the origin (glTF Y-up)",
        }
    });
    if children.is_empty() {
        nodes[0].as_object_mut().map(|n| n.remove("children"));
    }
    let mut views = Vec::new();
    if n_vert > 0 {
        views.push(json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER}));
        views.push(json!({"buffer": 0, "byteOffset": pos_len, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER}));
        views.push(json!({"buffer": 0, "byteOffset": 2 * pos_len, "byteLength": idx_len, "target": ELEMENT_ARRAY_BUFFER}));
    }
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "blockwalk" },
        "scene": 0,
        "scenes": [{ "name": city.name, "nodes": [0] }],
        "nodes": nodes,
        "materials": [{
            "name": "building",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.82, 0.80, 0.76, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9,
            },
        }],
    });
    if !gl_meshes.is_empty() {
        doc["meshes"] = Value::Array(gl_meshes);
        doc["accessors"] = Value::Array(accessors);
        doc["bufferViews"] = Value::Array(views);
    }
    if bin_len > 0 {
        doc["buffers"] = json!([{ "byteLength": bin_len }]);
    }
    let mut json_bytes = serde_json::to_vec(&doc).map_err(|source| ExportError::Json {
        file: "<glb>".into(),
        source,
    })?;
    pad4(&mut json_bytes, b' ');
    pad4(&mut bin, 0);
    let total = 12 + 8 + json_bytes.len() + if bin_len > 0 { 8 + bin.len() } else { 0 };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    if bin_len > 0 {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    stats.bytes = out.len();
    Ok((out, stats))
}

/// Writes the city's meshes as a `.glb` file (see the module documentation).
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_glb(city: &City, meshes: &[Mesh], path: &Path) -> Result<GlbStats, ExportError> {
    let (bytes, stats) = glb_bytes(city, meshes).map_err(|e| e.for_file(path))?;
    std::fs::write(path, bytes).map_err(|source| ExportError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    Ok(stats)
}
