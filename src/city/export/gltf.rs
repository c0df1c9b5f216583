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
//!
//! # Streaming and the size limit
//!
//! The file is written in one pass to any [`Write`] ([`write_glb_to`]): the sizes of the binary
//! chunk are computed from the meshes first, then the JSON chunk is serialised (one element at a
//! time, never as one document tree), then the header, the JSON chunk and the binary chunk are
//! written, the binary data straight from the meshes. Apart from the meshes themselves only the
//! JSON text is held in memory (a few hundred bytes per building). All sizes are computed in
//! `u64` with checked arithmetic; a `.glb` stores its total length in a `u32`, so a file over
//! 4 GiB − 1 byte cannot be written ([`GLB_MAX_BYTES`]) and is refused with
//! [`ExportError::TooLarge`] before anything is written (the message says to export a smaller
//! area; splitting one city into several files is not done).

use std::io::Write;
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

/// The largest `.glb` file: its header stores the total length as a `u32` (glTF 2.0, "Binary
/// glTF Layout").
pub const GLB_MAX_BYTES: u64 = u32::MAX as u64;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const UNSIGNED_BYTE: u32 = 5121;

fn y_up(v: Vec3) -> [f32; 3] {
    [v.x, v.z, -v.y]
}

/// `n` rounded up to a multiple of 4 (chunks are 4-byte aligned).
fn padded(n: u64) -> Option<u64> {
    n.checked_add(3).map(|m| m & !3)
}

/// A `.glb` ready to be written: the JSON chunk (unpadded) and the sizes.
struct Prepared {
    json: Vec<u8>,
    /// Bytes of the binary buffer (positions, normals, indices), unpadded.
    bin_len: u64,
    /// Total file size.
    total: u64,
    stats: GlbStats,
}

/// The error for a file over `limit` bytes (`bytes` is `None` when the size overflows `u64`).
fn too_large(bytes: Option<u64>, limit: u64) -> ExportError {
    ExportError::TooLarge {
        file: "<glb>".into(),
        bytes,
        limit,
    }
}

fn json_error(source: serde_json::Error) -> ExportError {
    ExportError::Json {
        file: "<glb>".into(),
        source,
    }
}

/// Appends the compact JSON of `v` to `out`.
fn put(out: &mut Vec<u8>, v: &Value) -> Result<(), ExportError> {
    serde_json::to_writer(&mut *out, v).map_err(json_error)
}

/// Appends `"key":[items…]` to `out`, each item serialised as it comes.
fn put_array<I>(out: &mut Vec<u8>, key: &str, items: I) -> Result<(), ExportError>
where
    I: IntoIterator<Item = Value>,
{
    put(out, &Value::String(key.into()))?;
    out.extend_from_slice(b":[");
    for (k, v) in items.into_iter().enumerate() {
        if k > 0 {
            out.push(b',');
        }
        put(out, &v)?;
    }
    out.push(b']');
    Ok(())
}

/// Sizes and JSON chunk of the `.glb` of `city` (see the module documentation), refusing a file
/// over `limit` bytes.
///
/// The document's members are written in the order `serde_json` gives an object's keys (sorted),
/// so the bytes are those of serialising the whole document as one [`Value`].
fn prepare(city: &City, meshes: &[Mesh], limit: u64) -> Result<Prepared, ExportError> {
    if meshes.len() != city.buildings.len() {
        return Err(ExportError::MeshCount {
            file: "<glb>".into(),
            meshes: meshes.len(),
            buildings: city.buildings.len(),
        });
    }
    let sum = |f: fn(&Mesh) -> usize| -> Option<u64> {
        meshes
            .iter()
            .try_fold(0u64, |acc, m| acc.checked_add(f(m) as u64))
    };
    let n_vert = sum(|m| m.positions.len());
    let n_idx = sum(|m| m.indices.len());
    let pos_len = n_vert.and_then(|n| n.checked_mul(12));
    let idx_len = n_idx.and_then(|n| n.checked_mul(4));
    let bin_len = pos_len
        .and_then(|p| p.checked_mul(2))
        .and_then(|p| idx_len.and_then(|i| p.checked_add(i)));
    let (Some(n_vert), Some(pos_len), Some(idx_len), Some(bin_len)) =
        (n_vert, pos_len, idx_len, bin_len)
    else {
        return Err(too_large(None, limit));
    };
    // Refuse before serialising anything when the binary chunk alone is too large.
    if bin_len > limit {
        return Err(too_large(
            padded(bin_len).and_then(|b| b.checked_add(28)),
            limit,
        ));
    }
    let with_tris = || {
        city.buildings
            .iter()
            .zip(meshes)
            .filter(|(_, m)| m.triangle_count() > 0)
    };
    let n_meshes = with_tris().count();
    let mut stats = GlbStats {
        nodes: city.buildings.len(),
        meshes: n_meshes,
        triangles: with_tris().map(|(_, m)| m.triangle_count()).sum(),
        bytes: 0,
    };

    let mut out: Vec<u8> = Vec::new();
    out.push(b'{');
    if n_meshes > 0 {
        // Accessors: POSITION, NORMAL and indices of each mesh, at the mesh's offsets.
        let mut offsets = Vec::with_capacity(n_meshes);
        let (mut vert_off, mut idx_off) = (0u64, 0u64);
        for m in meshes {
            if m.triangle_count() > 0 {
                offsets.push((vert_off, idx_off, m));
            }
            vert_off += m.positions.len() as u64;
            idx_off += m.indices.len() as u64;
        }
        let accessors = offsets.into_iter().flat_map(|(vert_off, idx_off, m)| {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in &m.positions {
                let q = y_up(*p);
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            [
                json!({
                    "bufferView": 0, "byteOffset": vert_off * 12, "componentType": FLOAT,
                    "count": m.positions.len(), "type": "VEC3", "min": lo, "max": hi,
                }),
                json!({
                    "bufferView": 1, "byteOffset": vert_off * 12, "componentType": FLOAT,
                    "count": m.normals.len(), "type": "VEC3",
                }),
                json!({
                    "bufferView": 2, "byteOffset": idx_off * 4, "componentType": UNSIGNED_INT,
                    "count": m.indices.len(), "type": "SCALAR",
                }),
            ]
        });
        put_array(&mut out, "accessors", accessors)?;
        out.push(b',');
    }
    out.extend_from_slice(br#""asset":"#);
    put(
        &mut out,
        &json!({ "version": "2.0", "generator": "blockwalk" }),
    )?;
    if n_meshes > 0 {
        out.push(b',');
        let mut views = Vec::new();
        if n_vert > 0 {
            views.push(json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER}));
            views.push(json!({"buffer": 0, "byteOffset": pos_len, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER}));
            views.push(json!({"buffer": 0, "byteOffset": 2 * pos_len, "byteLength": idx_len, "target": ELEMENT_ARRAY_BUFFER}));
        }
        put_array(&mut out, "bufferViews", views)?;
    }
    if bin_len > 0 {
        out.push(b',');
        put_array(&mut out, "buffers", [json!({ "byteLength": bin_len })])?;
    }
    out.push(b',');
    put_array(
        &mut out,
        "materials",
        [json!({
            "name": "building",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.82, 0.80, 0.76, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9,
            },
        })],
    )?;
    if n_meshes > 0 {
        out.push(b',');
        let gl_meshes = with_tris().enumerate().map(|(k, (b, _))| {
            let a_pos = 3 * k;
            json!({
                "name": b.source_id,
                "primitives": [{
                    "attributes": { "POSITION": a_pos, "NORMAL": a_pos + 1 },
                    "indices": a_pos + 2,
                    "material": 0,
                    "mode": 4,
                }]
            })
        });
        put_array(&mut out, "meshes", gl_meshes)?;
    }
    out.push(b',');
    // Nodes: the root (children 1..=n), then one per building.
    let o = city.frame.origin;
    let mut root = json!({
        "name": city.name,
        "children": (1..=city.buildings.len()).collect::<Vec<usize>>(),
        "extras": {
            "origin": [o.x, o.y, o.z],
            "crs": city.transform.describe(),
            "frame": "local metres: x east, y up, z south of the origin (glTF Y-up)",
        }
    });
    if city.buildings.is_empty() {
        root.as_object_mut().map(|n| n.remove("children"));
    }
    let mut mesh_idx = 0usize;
    let nodes = std::iter::once(root).chain(city.buildings.iter().zip(meshes).map(|(b, m)| {
        let mut node = json!({
            "name": b.source_id,
            "extras": {
                "source_id": b.source_id,
                "height_m": b.height_m,
                "min_height_m": b.min_height_m,
            }
        });
        if m.triangle_count() > 0 {
            node["mesh"] = json!(mesh_idx);
            mesh_idx += 1;
        }
        node
    }));
    put_array(&mut out, "nodes", nodes)?;
    out.extend_from_slice(br#","scene":0,"#);
    put_array(
        &mut out,
        "scenes",
        [json!({ "name": city.name, "nodes": [0] })],
    )?;
    out.push(b'}');

    let total = padded(out.len() as u64)
        .and_then(|j| j.checked_add(12 + 8))
        .and_then(|t| {
            if bin_len > 0 {
                padded(bin_len)
                    .and_then(|b| b.checked_add(8))
                    .and_then(|b| t.checked_add(b))
            } else {
                Some(t)
            }
        });
    match total {
        Some(t) if t <= limit => {
            stats.bytes = usize::try_from(t).map_err(|_| too_large(Some(t), limit))?;
            Ok(Prepared {
                json: out,
                bin_len,
                total: t,
                stats,
            })
        }
        other => Err(too_large(other, limit)),
    }
}

/// Writes a prepared `.glb`: header, JSON chunk, then the binary chunk from the meshes.
fn emit<W: Write>(p: &Prepared, meshes: &[Mesh], w: &mut W) -> std::io::Result<()> {
    // `prepare` refused totals over u32::MAX, so every length below fits.
    let u32_of = |n: u64| u32::try_from(n).expect("checked against GLB_MAX_BYTES");
    let json_padded = padded(p.json.len() as u64).expect("checked in prepare");
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&u32_of(p.total).to_le_bytes())?;
    w.write_all(&u32_of(json_padded).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&p.json)?;
    w.write_all(&b"   "[..(json_padded - p.json.len() as u64) as usize])?;
    if p.bin_len == 0 {
        return Ok(());
    }
    let bin_padded = padded(p.bin_len).expect("checked in prepare");
    w.write_all(&u32_of(bin_padded).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    // One mesh at a time through a small buffer.
    let mut buf: Vec<u8> = Vec::new();
    let mut vec3s = |w: &mut W, f: fn(&Mesh) -> &[Vec3]| -> std::io::Result<()> {
        for m in meshes {
            buf.clear();
            for v in f(m) {
                for c in y_up(*v) {
                    buf.extend_from_slice(&c.to_le_bytes());
                }
            }
            w.write_all(&buf)?;
        }
        Ok(())
    };
    vec3s(w, |m| &m.positions)?;
    vec3s(w, |m| &m.normals)?;
    for m in meshes {
        buf.clear();
        for i in &m.indices {
            buf.extend_from_slice(&i.to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    w.write_all(&[0u8; 3][..(bin_padded - p.bin_len) as usize])?;
    Ok(())
}

/// Writes the `.glb` of a city and its meshes (`meshes[i]` is building `i`'s) to `w`, streaming
/// the binary chunk from the meshes (see the module documentation).
///
/// # Errors
/// [`ExportError::MeshCount`] when `meshes` does not match the buildings,
/// [`ExportError::TooLarge`] for a file over [`GLB_MAX_BYTES`] (nothing is written then), and
/// [`ExportError::Io`] when writing fails; their file is `<glb>`.
pub fn write_glb_to<W: Write>(
    city: &City,
    meshes: &[Mesh],
    w: &mut W,
) -> Result<GlbStats, ExportError> {
    write_glb_to_limited(city, meshes, w, GLB_MAX_BYTES)
}

fn write_glb_to_limited<W: Write>(
    city: &City,
    meshes: &[Mesh],
    w: &mut W,
    limit: u64,
) -> Result<GlbStats, ExportError> {
    let p = prepare(city, meshes, limit)?;
    emit(&p, meshes, w).map_err(|source| ExportError::Io {
        file: "<glb>".into(),
        source,
    })?;
    Ok(p.stats)
}

/// The `.glb` file of a city and its meshes (`meshes[i]` is building `i`'s), in memory.
///
/// # Errors
/// As [`write_glb_to`].
pub fn glb_bytes(city: &City, meshes: &[Mesh]) -> Result<(Vec<u8>, GlbStats), ExportError> {
    let mut out = Vec::new();
    let stats = write_glb_to(city, meshes, &mut out)?;
    Ok((out, stats))
}

/// Writes the city's meshes as a `.glb` file (see the module documentation), streaming it
/// through a buffered writer.
///
/// # Errors
/// [`ExportError`] naming the file; a file over [`GLB_MAX_BYTES`] is refused before it is
/// created, and a file whose writing failed is removed.
pub fn write_glb(city: &City, meshes: &[Mesh], path: &Path) -> Result<GlbStats, ExportError> {
    write_glb_limited(city, meshes, path, GLB_MAX_BYTES)
}

fn write_glb_limited(
    city: &City,
    meshes: &[Mesh],
    path: &Path,
    limit: u64,
) -> Result<GlbStats, ExportError> {
    let p = prepare(city, meshes, limit).map_err(|e| e.for_file(path))?;
    let io = |source| ExportError::Io {
        file: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    let written = emit(&p, meshes, &mut w).and_then(|()| w.flush());
    if let Err(source) = written {
        drop(w);
        let _ = std::fs::remove_file(path);
        return Err(io(source));
    }
    Ok(p.stats)
}

/// One building of a 3D Tiles content `.glb` ([`tile_glb_bytes`]): a row of its property table.
#[derive(Clone, Debug, PartialEq)]
pub struct TileFeature {
    /// The building's source id.
    pub source_id: String,
    /// Roof height above the ground, metres.
    pub height_m: f64,
    /// Bottom of the building (raised parts), metres.
    pub min_height_m: f64,
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
/// `min_height_m` FLOAT64). `extras` goes on the root node. Deterministic.
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
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_padded as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.resize(out.len() + (json_padded as usize - json_bytes.len()), b' ');
    out.extend_from_slice(&(bin_padded as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out.resize(total as usize, 0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::build::{build_city, BuildOptions};
    use crate::city::extrude::try_extrude_city;
    use crate::importers::{read_layer, Theme};

    fn pad4(buf: &mut Vec<u8>, byte: u8) {
        while buf.len() & 3 != 0 {
            buf.push(byte);
        }
    }

    /// The former writer, kept as the reference: the whole document as one `Value`, the binary
    /// buffer and the file each assembled in memory.
    fn glb_bytes_in_memory(city: &City, meshes: &[Mesh]) -> Vec<u8> {
        let n_vert: usize = meshes.iter().map(|m| m.positions.len()).sum();
        let n_idx: usize = meshes.iter().map(|m| m.indices.len()).sum();
        let pos_len = n_vert * 12;
        let idx_len = n_idx * 4;
        let mut bin: Vec<u8> = Vec::new();
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
        let mut nodes: Vec<Value> = vec![Value::Null];
        let mut children: Vec<usize> = Vec::new();
        let (mut vert_off, mut idx_off) = (0usize, 0usize);
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
            }
            vert_off += m.positions.len();
            idx_off += m.indices.len();
            children.push(nodes.len());
            nodes.push(node);
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
        let mut json_bytes = serde_json::to_vec(&doc).unwrap();
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
        out
    }

    fn bundled(p: &str) -> (City, Vec<Mesh>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data")
            .join(p);
        let layer = read_layer(&path, &Theme::Buildings).expect("read");
        let city = build_city(&layer, None, None, &BuildOptions::default()).expect("build");
        let (meshes, _) = try_extrude_city(&city);
        (city, meshes)
    }

    #[test]
    fn streamed_file_is_byte_identical_to_the_in_memory_writer() {
        for p in ["bubenec/buildings.shp", "helsinki/buildings.shp"] {
            let (mut city, mut meshes) = bundled(p);
            let (bytes, stats) = glb_bytes(&city, &meshes).unwrap();
            assert_eq!(bytes, glb_bytes_in_memory(&city, &meshes), "{p}");
            assert_eq!(stats.bytes, bytes.len());
            assert_eq!(
                u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
                bytes.len()
            );
            // Through a file as well.
            let dir = tempfile::tempdir().unwrap();
            let f = dir.path().join("c.glb");
            assert_eq!(write_glb(&city, &meshes, &f).unwrap(), stats);
            assert_eq!(std::fs::read(&f).unwrap(), bytes);
            // Buildings whose extrusion failed (no mesh) and a mesh with vertices but no
            // triangle: nodes without meshes, the offsets of the others move on.
            meshes[1] = Mesh::default();
            meshes[2].indices.clear();
            assert_eq!(
                glb_bytes(&city, &meshes).unwrap().0,
                glb_bytes_in_memory(&city, &meshes),
                "{p}"
            );
            // No buildings at all.
            city.buildings.clear();
            assert_eq!(
                glb_bytes(&city, &[]).unwrap().0,
                glb_bytes_in_memory(&city, &[]),
                "{p}"
            );
        }
    }

    #[test]
    fn files_over_the_limit_are_refused_before_anything_is_written() {
        let (city, meshes) = bundled("bubenec/buildings.shp");
        let (bytes, _) = glb_bytes(&city, &meshes).unwrap();
        let size = bytes.len() as u64;
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("big.glb");
        // Exactly at the limit: written.
        assert_eq!(
            write_glb_limited(&city, &meshes, &f, size).unwrap().bytes as u64,
            size
        );
        std::fs::remove_file(&f).unwrap();
        // One byte less: refused, naming the file and both sizes; no file left behind.
        let e = write_glb_limited(&city, &meshes, &f, size - 1).unwrap_err();
        assert!(
            matches!(&e, ExportError::TooLarge { file, bytes: Some(b), limit }
                if file == &f && *b == size && *limit == size - 1),
            "{e:?}"
        );
        let msg = e.to_string();
        assert!(
            msg.contains("big.glb") && msg.contains(&size.to_string()),
            "{msg}"
        );
        assert!(msg.contains("smaller area"), "{msg}");
        assert!(!f.exists());
        // A limit below the binary chunk alone: refused before the JSON is made.
        let mut sink = Vec::new();
        let e = write_glb_to_limited(&city, &meshes, &mut sink, 1000).unwrap_err();
        assert!(
            matches!(e, ExportError::TooLarge { bytes: Some(b), limit: 1000, .. } if b > 1000),
            "{e:?}"
        );
        assert!(sink.is_empty());
    }

    fn two_triangles() -> TileMesh {
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        TileMesh {
            positions: vec![
                p(0., 0., 1.),
                p(1., 0., 1.),
                p(0., 1., 1.),
                p(5., 5., 2.),
                p(6., 5., 2.),
                p(5., 6., 2.),
            ],
            normals: vec![Vec3::Z; 6],
            colors: vec![[0.5, 0.25, 0.125]; 6],
            feature_ids: vec![0, 0, 0, 1, 1, 1],
            indices: vec![0, 1, 2, 3, 4, 5],
            features: vec![
                TileFeature {
                    source_id: "a".into(),
                    height_m: 1.0,
                    min_height_m: 0.0,
                },
                TileFeature {
                    source_id: "bé".into(),
                    height_m: 2.0,
                    min_height_m: 0.5,
                },
            ],
        }
    }

    /// The JSON chunk of a `.glb`.
    fn json_of(bytes: &[u8]) -> Value {
        let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        serde_json::from_slice(&bytes[20..20 + n]).unwrap()
    }

    #[test]
    fn tile_glb_holds_features_colours_and_y_up_positions() {
        let m = two_triangles();
        let bytes = tile_glb_bytes("t", &m, json!({"k": 1})).unwrap();
        assert_eq!(bytes, tile_glb_bytes("t", &m, json!({"k": 1})).unwrap());
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            bytes.len()
        );
        let doc = json_of(&bytes);
        let prim = &doc["meshes"][0]["primitives"][0];
        for want in ["POSITION", "NORMAL", "COLOR_0", "_FEATURE_ID_0"] {
            assert!(prim["attributes"][want].is_number(), "{want}: {prim}");
        }
        // Y-up: the local z = 2 of the second triangle is glTF y; local y is −z.
        let pos = &doc["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
        assert_eq!(pos["max"], json!([6.0, 2.0, 0.0]));
        assert_eq!(pos["min"], json!([0.0, 1.0, -6.0]));
        let col = &doc["accessors"][prim["attributes"]["COLOR_0"].as_u64().unwrap() as usize];
        assert_eq!(
            (col["componentType"].as_u64(), col["normalized"].as_bool()),
            (Some(5121), Some(true))
        );
        assert_eq!(
            prim["extensions"]["EXT_mesh_features"]["featureIds"][0]["featureCount"],
            2
        );
        let table = &doc["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
        assert_eq!(table["count"], 2);
        // Every buffer view is 8-byte aligned; the string offsets end at the strings' length.
        for v in doc["bufferViews"].as_array().unwrap() {
            assert_eq!(v["byteOffset"].as_u64().unwrap() % 8, 0);
        }
        let jl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let bin = &bytes[28 + jl..];
        let view = |k: u64| {
            let v = &doc["bufferViews"][k as usize];
            let o = v["byteOffset"].as_u64().unwrap() as usize;
            &bin[o..o + v["byteLength"].as_u64().unwrap() as usize]
        };
        let strings = view(table["properties"]["source_id"]["values"].as_u64().unwrap());
        assert_eq!(std::str::from_utf8(strings).unwrap(), "abé");
        let offs = view(
            table["properties"]["source_id"]["stringOffsets"]
                .as_u64()
                .unwrap(),
        );
        assert_eq!(offs, [0, 0, 0, 0, 1, 0, 0, 0, 4, 0, 0, 0]);
        // Without features: no extension, no feature attribute.
        let plain = TileMesh {
            feature_ids: Vec::new(),
            features: Vec::new(),
            ..m
        };
        let doc = json_of(&tile_glb_bytes("p", &plain, Value::Null).unwrap());
        assert!(doc.get("extensionsUsed").is_none());
        assert!(doc["meshes"][0]["primitives"][0]["attributes"]["_FEATURE_ID_0"].is_null());
    }

    #[test]
    fn tile_glb_refuses_arrays_that_do_not_match_the_positions() {
        let mut m = two_triangles();
        m.feature_ids.pop();
        let e = tile_glb_bytes("t", &m, Value::Null).unwrap_err();
        assert!(
            matches!(
                e,
                ExportError::AttributeCount {
                    attribute: "_FEATURE_ID_0",
                    count: 5,
                    vertices: 6,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .contains("_FEATURE_ID_0 has 5 entries for 6 vertices"),
            "{e}"
        );
        let mut m = two_triangles();
        m.colors.push([0.0; 3]);
        assert!(matches!(
            tile_glb_bytes("t", &m, Value::Null).unwrap_err(),
            ExportError::AttributeCount {
                attribute: "COLOR_0",
                count: 7,
                ..
            }
        ));
        let mut m = two_triangles();
        m.features.pop();
        assert!(matches!(
            tile_glb_bytes("t", &m, Value::Null).unwrap_err(),
            ExportError::AttributeCount {
                attribute: "_FEATURE_ID_0",
                count: 1,
                ..
            }
        ));
    }

    #[test]
    fn sizes_are_checked_not_wrapped() {
        assert_eq!(padded(5), Some(8));
        assert_eq!(padded(8), Some(8));
        assert_eq!(padded(u64::MAX), None);
        assert_eq!(GLB_MAX_BYTES, 4_294_967_295);
    }
}
