//! The content `.glb` of one 3D Tiles tile: one primitive with feature ids and a property table,
//! written plain ([`tile_glb_bytes`]) or compact ([`tile_glb`] with [`ContentEncoding::Compact`],
//! file `compact.rs`).

use glam::Vec3;
use serde::Serialize;
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

/// How a tile's content `.glb` stores its mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContentEncoding {
    /// Quantised and compressed (see `compact.rs`): positions within [`POSITION_TOLERANCE_M`]
    /// of the plain ones, octahedral byte normals, 16-bit feature ids, every vertex and index
    /// stream compressed with `EXT_meshopt_compression` (required: the file has no uncompressed
    /// copy). Read by viewers that implement `EXT_meshopt_compression` and
    /// `KHR_mesh_quantization` (CesiumJS, three.js with its meshopt decoder, Babylon.js).
    #[default]
    Compact,
    /// Core glTF 2.0 without compression: f32 positions and normals, RGBA8 colours, FLOAT
    /// feature ids, u32 indices; for viewers without `EXT_meshopt_compression`.
    Plain,
}

/// The largest distance (metres, in the tile's frame) between a position of a compact content
/// as a reader decodes it and the f32 position of the plain content: every compact `.glb` stays
/// strictly below it.
pub const POSITION_TOLERANCE_M: f64 = 1e-3;

/// A tile's content as [`tile_glb`] wrote it.
#[derive(Clone, Debug, PartialEq)]
pub struct TileContent {
    /// The `.glb`.
    pub bytes: Vec<u8>,
    /// The largest distance between a position as written (decoded and dequantised) and the
    /// mesh's f32 position, metres: 0 for plain content (and for compact content that kept
    /// f32 positions), below [`POSITION_TOLERANCE_M`] otherwise. Also in the root node's
    /// `extras` (`position_error_m`) of a compact content.
    pub position_error_m: f64,
}

/// Appends `bytes` to `bin` at an offset aligned to 8 bytes (`EXT_structural_metadata` asks
/// for 8-byte aligned property buffer views; 8 covers the 4 that vertex data needs) and returns
/// the buffer view describing it.
pub(super) fn push_view(
    bin: &mut Vec<u8>,
    bytes: &[u8],
    target: Option<u32>,
    stride: Option<u32>,
) -> Value {
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

/// Checks that every per-vertex array of `mesh` has one entry per position, every feature id a
/// row, and that the indices are whole triangles of its vertices.
pub(super) fn check(mesh: &TileMesh) -> Result<(), ExportError> {
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
    let bad = |what: String| ExportError::Indices {
        file: "<glb>".into(),
        what,
    };
    if !mesh.indices.len().is_multiple_of(3) {
        return Err(bad(format!(
            "{} indices are not whole triangles",
            mesh.indices.len()
        )));
    }
    if let Some(&i) = mesh.indices.iter().find(|&&i| i as usize >= n) {
        return Err(bad(format!("index {i} refers to no vertex ({n} vertices)")));
    }
    Ok(())
}

/// The feature ids' property table: the primitive's `EXT_mesh_features` (its feature id set
/// reading `_FEATURE_ID_0`) and the document's `EXT_structural_metadata`, its buffer views
/// appended (uncompressed, 8-byte aligned) to `bin` and `views`.
pub(super) fn metadata(
    features: &[TileFeature],
    bin: &mut Vec<u8>,
    views: &mut Vec<Value>,
) -> (Value, Value) {
    let f = features;
    let mut view_of = |bytes: Vec<u8>| -> usize {
        views.push(push_view(bin, &bytes, None, None));
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
    let primitive = json!({
        "featureIds": [{
            "featureCount": f.len(),
            "attribute": 0,
            "propertyTable": 0,
            "label": "building",
        }]
    });
    let doc = json!({
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
    });
    (primitive, doc)
}

/// The parts of a tile's glTF document that differ between encodings.
pub(super) struct Parts {
    /// The root node (name, mesh and extras are set here; a compact content adds its
    /// dequantisation transform).
    pub node: Value,
    pub primitive: Value,
    pub accessors: Vec<Value>,
    pub views: Vec<Value>,
    /// Buffers after buffer 0 (the binary chunk).
    pub more_buffers: Vec<Value>,
    pub used: Vec<&'static str>,
    pub required: Vec<&'static str>,
    pub doc_extensions: serde_json::Map<String, Value>,
}

/// The whole `.glb` of a tile: the document around `parts` (one scene, one node, one mesh, the
/// tile material) and the binary chunk `bin`.
pub(super) fn assemble(
    name: &str,
    extras: Value,
    parts: Parts,
    bin: &[u8],
) -> Result<Vec<u8>, ExportError> {
    let Parts {
        mut node,
        primitive,
        accessors,
        views,
        more_buffers,
        used,
        required,
        doc_extensions,
    } = parts;
    node["name"] = json!(name);
    node["mesh"] = json!(0);
    node["extras"] = extras;
    let bin_len = bin.len() as u64;
    let mut buffers = vec![json!({ "byteLength": bin_len })];
    buffers.extend(more_buffers);
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "blockwalk" },
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [0] }],
        "nodes": [node],
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
        "buffers": buffers,
    });
    if !used.is_empty() {
        doc["extensionsUsed"] = json!(used);
    }
    if !required.is_empty() {
        doc["extensionsRequired"] = json!(required);
    }
    if !doc_extensions.is_empty() {
        doc["extensions"] = Value::Object(doc_extensions);
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
    out.extend_from_slice(bin);
    out.resize(total as usize, 0);
    Ok(out)
}

/// The `.glb` of one 3D Tiles 1.1 tile in the given encoding: [`tile_glb_bytes`] for
/// [`ContentEncoding::Plain`]; for [`ContentEncoding::Compact`] the same mesh, features and
/// property table quantised and compressed (see `compact.rs`), with `position_encoding` and
/// `position_error_m` added to `extras` (an object, or null). Deterministic.
///
/// # Errors
/// As [`tile_glb_bytes`], and [`ExportError::Indices`] when the indices are not whole
/// triangles of the vertices.
pub fn tile_glb(
    name: &str,
    mesh: &TileMesh,
    extras: Value,
    encoding: ContentEncoding,
) -> Result<TileContent, ExportError> {
    match encoding {
        ContentEncoding::Plain => Ok(TileContent {
            bytes: tile_glb_bytes(name, mesh, extras)?,
            position_error_m: 0.0,
        }),
        ContentEncoding::Compact => super::compact::compact_glb(name, mesh, extras),
    }
}

/// The plain `.glb` of one 3D Tiles 1.1 tile: one mesh with one primitive (POSITION with min/max,
/// NORMAL, optional `COLOR_0` as normalised RGBA bytes, u32 indices), written Y-up as [`write_glb_to`] writes it (local
/// (x, y, z) as (x, z, −y); 3D Tiles turns glTF content back to Z-up). With feature ids, the
/// primitive carries `_FEATURE_ID_0` (FLOAT scalars holding whole numbers, as
/// `EXT_mesh_features` allows) and an `EXT_mesh_features` feature id set pointing at property
/// table 0 of `EXT_structural_metadata`, class `building` (`source_id` STRING, `height_m` and
/// `min_height_m`, `base_m` FLOAT64). `extras` goes on the root node. Core glTF 2.0 plus those
/// two metadata extensions, nothing required. Deterministic.
///
/// # Errors
/// [`ExportError::AttributeCount`] when a per-vertex array does not match the positions or a
/// feature id has no row in `features` (its count is then the id), [`ExportError::Indices`]
/// when the indices are not whole triangles of the vertices, [`ExportError::TooLarge`] over
/// [`GLB_MAX_BYTES`].
pub fn tile_glb_bytes(name: &str, mesh: &TileMesh, extras: Value) -> Result<Vec<u8>, ExportError> {
    check(mesh)?;
    let n = mesh.positions.len();
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
    let (lo, hi) = y_up_bounds(&mesh.positions);
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
        let v = vertex_view(&mut bin, rgba8(&mesh.colors).concat(), 4);
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
    let mut doc_extensions = serde_json::Map::new();
    let mut used: Vec<&'static str> = Vec::new();
    if with_features {
        let (p, d) = metadata(&mesh.features, &mut bin, &mut views);
        primitive["extensions"] = json!({ "EXT_mesh_features": p });
        doc_extensions.insert("EXT_structural_metadata".into(), d);
        used = vec!["EXT_mesh_features", "EXT_structural_metadata"];
    }
    let parts = Parts {
        node: json!({}),
        primitive,
        accessors,
        views,
        more_buffers: Vec::new(),
        used,
        required: Vec::new(),
        doc_extensions,
    };
    assemble(name, extras, parts, &bin)
}

/// Linear RGB colours as RGBA bytes (normalised, alpha 255: 4-byte aligned vertex elements,
/// glTF 2.0 §3.6.2.4).
pub(super) fn rgba8(colors: &[[f32; 3]]) -> Vec<[u8; 4]> {
    colors
        .iter()
        .map(|c| {
            let [r, g, b] = c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8);
            [r, g, b, 255]
        })
        .collect()
}

/// The Y-up bounds (min, max) of local positions.
pub(super) fn y_up_bounds(positions: &[Vec3]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in positions {
        let q = y_up(*p);
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (lo, hi)
}
