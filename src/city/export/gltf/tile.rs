//! The content `.glb` of one 3D Tiles tile: one primitive with feature ids and a property table.

use glam::Vec3;
use serde_json::{json, Value};

use super::*;
use crate::city::export::ExportError;

/// One building of a 3D Tiles content `.glb` ([`tile_glb_bytes`]): a row of its property table.
#[derive(Clone, Debug, PartialEq)]
pub struct TileFeature {
    /// The building's source id.
    pub source_id: String,
    /// Roof height above the ground, metres.
    pub height_m: f64,
    /// Bottom of the building (raised parts), metres.
    pub min_height_m: f64,
    /// Height of the ground under the building (its base) in the city's vertical datum,
    /// metres (0 without terrain).
    pub base_m: f64,
}

/// One primitive of a 3D Tiles content `.glb`, local frame (x east, y north, z up; metres
/// relative to the city's origin), written by [`tile_glb_bytes`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileMesh {
    /// Vertex positions (local, z up).
    pub positions: Vec<Vec3>,
    /// Unit normals, one per position.
    pub normals: Vec<Vec3>,
    /// Linear RGB vertex colours in `[0, 1]` (`COLOR_0`, stored as normalised bytes): empty or
    /// one per position.
    pub colors: Vec<[f32; 3]>,
    /// Feature id of each vertex (`_FEATURE_ID_0`, an index into `features`): empty, or one per
    /// position.
    pub feature_ids: Vec<u32>,
    /// Three indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    /// The features' property table (`EXT_structural_metadata`), indexed by feature id.
    pub features: Vec<TileFeature>,
}

/// Appends `bytes` to `bin` at an offset aligned to 8 bytes (`EXT_structural_metadata` asks
/// for 8-byte aligned property buffer views; 8 covers the 4 that vertex data needs) and returns
/// the buffer view describing it.
fn push_view(bin: &mut Vec<u8>, bytes: &[u8], target: Option<u32>, stride: Option<u32>) -> Value {
    while !bin.len().is_multiple_of(8) {
        bin.push(0);
    }
    let mut v = json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
    if let Some(t) = target {
        v["target"] = json!(t);
    }
    if let Some(s) = stride {
        v["byteStride"] = json!(s);
    }
    bin.extend_from_slice(bytes);
    v
}

/// The `.glb` of one 3D Tiles 1.1 tile: one mesh with one primitive (POSITION with min/max,
/// NORMAL, optional `COLOR_0` as normalised RGBA bytes, u32 indices), written Y-up as [`write_glb_to`] writes it (local
/// (x, y, z) as (x, z, −y); 3D Tiles turns glTF content back to Z-up). With feature ids, the
/// primitive carries `_FEATURE_ID_0` (FLOAT scalars holding whole numbers, as
/// `EXT_mesh_features` allows) and an `EXT_mesh_features` feature id set pointing at property
/// table 0 of `EXT_structural_metadata`, class `building` (`source_id` STRING, `height_m` and
/// `min_height_m`, `base_m` FLOAT64). `extras` goes on the root node. Deterministic.
///
/// # Errors
/// [`ExportError::AttributeCount`] when a per-vertex array does not match the positions or a
/// feature id has no row in `features` (its count is then the id), [`ExportError::TooLarge`]
/// over [`GLB_MAX_BYTES`].
pub fn tile_glb_bytes(name: &str, mesh: &TileMesh, extras: Value) -> Result<Vec<u8>, ExportError> {
    let n = mesh.positions.len();
    let mismatch = |attribute: &'static str, count: usize| ExportError::AttributeCount {
        file: "<glb>".into(),
        attribute,
        count,
        vertices: n,
    };
    if mesh.normals.len() != n {
        return Err(mismatch("NORMAL", mesh.normals.len()));
    }
    if !mesh.colors.is_empty() && mesh.colors.len() != n {
        return Err(mismatch("COLOR_0", mesh.colors.len()));
    }
    if !mesh.feature_ids.is_empty() && mesh.feature_ids.len() != n {
        return Err(mismatch("_FEATURE_ID_0", mesh.feature_ids.len()));
    }
    if let Some(&f) = mesh
        .feature_ids
        .iter()
        .find(|&&f| f as usize >= mesh.features.len())
    {
        return Err(mismatch("_FEATURE_ID_0", f as usize));
    }
    let f32s = |it: &mut dyn Iterator<Item = f32>| -> Vec<u8> {
        it.flat_map(|c| c.to_le_bytes()).collect()
    };
    let mut bin: Vec<u8> = Vec::new();
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    let mut attributes = serde_json::Map::new();
    let mut vertex_view = |bin: &mut Vec<u8>, bytes: Vec<u8>, stride: u32| -> usize {
        views.push(push_view(bin, &bytes, Some(ARRAY_BUFFER), Some(stride)));
        views.len() - 1
    };
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &mesh.positions {
        let q = y_up(*p);
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let v = vertex_view(
        &mut bin,
        f32s(&mut mesh.positions.iter().flat_map(|p| y_up(*p))),
        12,
    );
    attributes.insert("POSITION".into(), json!(accessors.len()));
    accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": n, "type": "VEC3", "min": lo, "max": hi}));
    let v = vertex_view(
        &mut bin,
        f32s(&mut mesh.normals.iter().flat_map(|p| y_up(*p))),
        12,
    );
    attributes.insert("NORMAL".into(), json!(accessors.len()));
    accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": n, "type": "VEC3"}));
    if !mesh.colors.is_empty() {
        let v = vertex_view(
            &mut bin,
            // Normalised bytes, RGBA (4-byte aligned vertex elements, glTF 2.0 §3.6.2.4).
            mesh.colors
                .iter()
                .flat_map(|c| {
                    let [r, g, b] = c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8);
                    [r, g, b, 255]
                })
                .collect(),
            4,
        );
        attributes.insert("COLOR_0".into(), json!(accessors.len()));
        accessors.push(json!({"bufferView": v, "componentType": UNSIGNED_BYTE, "normalized": true, "count": n, "type": "VEC4"}));
    }
    let with_features = !mesh.feature_ids.is_empty();
    if with_features {
        let v = vertex_view(
            &mut bin,
            f32s(&mut mesh.feature_ids.iter().map(|&i| i as f32)),
            4,
        );
        attributes.insert("_FEATURE_ID_0".into(), json!(accessors.len()));
        accessors
            .push(json!({"bufferView": v, "componentType": FLOAT, "count": n, "type": "SCALAR"}));
    }
    let idx: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    views.push(push_view(&mut bin, &idx, Some(ELEMENT_ARRAY_BUFFER), None));
    let a_idx = accessors.len();
    accessors.push(json!({"bufferView": views.len() - 1, "componentType": UNSIGNED_INT, "count": mesh.indices.len(), "type": "SCALAR"}));

    let mut primitive = json!({
        "attributes": Value::Object(attributes),
        "indices": a_idx,
        "material": 0,
        "mode": 4,
    });
    let mut doc_ext = serde_json::Map::new();
    let mut used: Vec<&str> = Vec::new();
    if with_features {
        let f = &mesh.features;
        let mut view_of = |bytes: Vec<u8>| -> usize {
            views.push(push_view(&mut bin, &bytes, None, None));
            views.len() - 1
        };
        let heights = view_of(f.iter().flat_map(|r| r.height_m.to_le_bytes()).collect());
        let mins = view_of(
            f.iter()
                .flat_map(|r| r.min_height_m.to_le_bytes())
                .collect(),
        );
        let bases = view_of(f.iter().flat_map(|r| r.base_m.to_le_bytes()).collect());
        let mut strings = Vec::new();
        let mut offsets: Vec<u8> = Vec::new();
        for r in f {
            offsets.extend_from_slice(&(strings.len() as u32).to_le_bytes());
            strings.extend_from_slice(r.source_id.as_bytes());
        }
        offsets.extend_from_slice(&(strings.len() as u32).to_le_bytes());
        let ids = view_of(strings);
        let id_offsets = view_of(offsets);
        primitive["extensions"] = json!({
            "EXT_mesh_features": {
                "featureIds": [{
                    "featureCount": f.len(),
                    "attribute": 0,
                    "propertyTable": 0,
                    "label": "building",
                }]
            }
        });
        doc_ext.insert(
            "EXT_structural_metadata".into(),
            json!({
                "schema": {
                    "id": "blockwalk",
                    "classes": {
                        "building": {
                            "name": "Building",
                            "properties": {
                                "source_id": { "type": "STRING", "description": "id in the source data" },
                                "height_m": { "type": "SCALAR", "componentType": "FLOAT64", "description": "roof height above the ground, metres" },
                                "min_height_m": { "type": "SCALAR", "componentType": "FLOAT64", "description": "bottom of the building, metres" },
                                "base_m": { "type": "SCALAR", "componentType": "FLOAT64", "description": "ground height under the building (its base), metres" },
                            }
                        }
                    }
                },
                "propertyTables": [{
                    "class": "building",
                    "count": f.len(),
                    "properties": {
                        "source_id": { "values": ids, "stringOffsets": id_offsets, "stringOffsetType": "UINT32" },
                        "height_m": { "values": heights },
                        "min_height_m": { "values": mins },
                        "base_m": { "values": bases },
                    }
                }]
            }),
        );
        used = vec!["EXT_mesh_features", "EXT_structural_metadata"];
    }
    let bin_len = bin.len() as u64;
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "blockwalk" },
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [0] }],
        "nodes": [{ "name": name, "mesh": 0, "extras": extras }],
        "meshes": [{ "name": name, "primitives": [primitive] }],
        "materials": [{
            "name": "tile",
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9,
            },
        }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin_len }],
    });
    if !used.is_empty() {
        doc["extensionsUsed"] = json!(used);
        doc["extensions"] = Value::Object(doc_ext);
    }
    let json_bytes = serde_json::to_vec(&doc).map_err(json_error)?;
    let json_padded =
        padded(json_bytes.len() as u64).ok_or_else(|| too_large(None, GLB_MAX_BYTES))?;
    let bin_padded = padded(bin_len).ok_or_else(|| too_large(None, GLB_MAX_BYTES))?;
    let total = 12 + 8 + json_padded + 8 + bin_padded;
    if total > GLB_MAX_BYTES {
        return Err(too_large(Some(total), GLB_MAX_BYTES));
    }
    let mut out = Vec::with_capacity(total as usize);
    // Writing to a Vec cannot fail.
    let in_memory = "writing to memory";
    write_head(&mut out, total as u32, &json_bytes, json_padded as u32).expect(in_memory);
    write_bin_head(&mut out, bin_padded as u32).expect(in_memory);
    out.extend_from_slice(&bin);
    out.resize(total as usize, 0);
    Ok(out)
}
