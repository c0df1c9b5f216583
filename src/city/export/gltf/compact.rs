//! The compact content `.glb` of a 3D Tiles tile ([`super::ContentEncoding::Compact`]): the
//! plain content's mesh, features and property table, quantised (`KHR_mesh_quantization`) and
//! compressed (`EXT_meshopt_compression`), both listed in `extensionsRequired`.
//!
//! - Order: triangles reordered for the post-transform vertex cache, then vertices renumbered
//!   in order of first use (meshoptimizer's vertex cache and vertex fetch optimisation; both
//!   deterministic). Each triangle keeps its vertices and their order (its winding); vertices
//!   no triangle uses are dropped.
//! - Positions (glTF Y-up, as in the plain content) are snapped to one grid of step
//!   2^-10 m (0.98 mm, [`GRID_LOG2`]) in the local frame, the same for every tile, so that a
//!   vertex that two tiles share (terrain leaves) decodes to the same point in both, and each
//!   position moves by at most √3/2 · 2^-10 m = 0.85 mm, under
//!   [`super::POSITION_TOLERANCE_M`]. Each tile stores its snapped positions exactly, in the
//!   smallest of these once compressed (the distance to the f32 positions is measured after
//!   decoding, for every vertex, and written to the root node's `extras` as
//!   `position_error_m`, with `position_encoding`):
//!   - `u16`: unsigned 16-bit grid steps from the content's low corner, when it spans at most
//!     65 535 steps (64 m): the root node's translation (the corner) and uniform scale (the
//!     step) dequantise them (`KHR_mesh_quantization`).
//!   - `exp<K>`: f32 offsets from the content's centre (the node's translation) through the
//!     EXPONENTIAL filter, one exponent per axis and K mantissa bits, K the fewest that make
//!     the filter's step the grid's or finer (K ≤ 24: within 8 km of the centre).
//!   - `f32`: the f32 positions as they are (error 0), for a tile wider than that.
//! - Normals: octahedral, 8 bits per component (OCTAHEDRAL filter), read as normalised BYTE
//!   VEC3 (`KHR_mesh_quantization`).
//! - `COLOR_0`: the plain content's RGBA bytes. `_FEATURE_ID_0`: UNSIGNED_SHORT (FLOAT over
//!   65 536 features), as `EXT_mesh_features` allows.
//! - Indices: u16 (u32 over 65 536 vertices), TRIANGLES mode.
//! - Vertex streams are compressed in ATTRIBUTES mode with the version 0 vertex codec (the
//!   one `EXT_meshopt_compression` specifies; meshoptimizer's default is newer), one stream per
//!   attribute; the property table's buffer views are stored uncompressed. The compressed
//!   buffer views point at a fallback buffer (buffer 1) that has a length but no data
//!   (`"fallback": true`), so a viewer without the extension cannot read the content: the
//!   extension is required (EXT_meshopt_compression, "Fallback buffers").

use glam::Vec3;
use meshopt::EncodeExpMode;
use serde_json::{json, Value};

use super::tile::{
    assemble, check, metadata, rgba8, y_up_bounds, Parts, TileContent, TileMesh,
    POSITION_TOLERANCE_M,
};
use super::*;

const MESHOPT: &str = "EXT_meshopt_compression";
const QUANTIZATION: &str = "KHR_mesh_quantization";

/// Compressed buffer views: their data in the binary chunk, their decoded layout in the
/// fallback buffer.
struct Streams {
    bin: Vec<u8>,
    views: Vec<Value>,
    /// Bytes of the fallback buffer so far.
    fallback: usize,
}

impl Streams {
    /// Appends a compressed stream of `count` elements of `stride` bytes and returns its view.
    fn push(
        &mut self,
        data: &[u8],
        count: usize,
        stride: usize,
        mode: &str,
        filter: Option<&str>,
        target: u32,
    ) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut ext = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": data.len(),
            "byteStride": stride,
            "count": count,
            "mode": mode,
        });
        if let Some(f) = filter {
            ext["filter"] = json!(f);
        }
        self.bin.extend_from_slice(data);
        let mut view = json!({
            "buffer": 1,
            "byteOffset": self.fallback,
            "byteLength": stride * count,
            "target": target,
            "extensions": { MESHOPT: ext },
        });
        // Index buffer views have no stride (glTF 2.0, "bufferView.byteStride").
        if target == ARRAY_BUFFER {
            view["byteStride"] = json!(stride);
        }
        self.fallback += (stride * count).next_multiple_of(4);
        self.views.push(view);
        self.views.len() - 1
    }
}

/// A vertex stream in meshoptimizer's attribute codec, version 0 (`0xa0` header).
fn encode_vertices<T>(v: &[T]) -> Vec<u8> {
    // The level is ignored by version 0; encoding into a buffer of the codec's bound cannot fail.
    meshopt::encode_vertex_buffer_level(v, 2, Some(0)).expect("a vertex buffer encodes")
}

/// The positions as stored.
enum Stored {
    /// u16 grid: node translation `lo`, scale `step`; integer bounds.
    Grid {
        lo: [f32; 3],
        step: f32,
        q: Vec<[u16; 4]>,
    },
    /// Exponential filter: node translation `centre`; decoded bounds.
    Exp {
        centre: [f32; 3],
        bits: i32,
        enc: Vec<[u32; 3]>,
        decoded: Vec<[f32; 3]>,
    },
    /// The f32 positions.
    Float,
}

/// The largest distance between `decoded(i)` and `p[i]`, metres.
fn max_error(p: &[[f32; 3]], decoded: impl Fn(usize) -> [f64; 3]) -> f64 {
    (0..p.len())
        .map(|i| {
            let d = decoded(i);
            (0..3)
                .map(|k| (d[k] - p[i][k] as f64).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// log2 of the step of the grid that compact positions are snapped to: 2^-10 m (0.98 mm), so
/// that a snapped position is within √3/2 · 2^-10 m = 0.85 mm of the f32 one.
pub const GRID_LOG2: i32 = -10;

/// `p` in grid steps (glTF axes; the grid's origin is the local frame's).
fn snap(p: &[[f32; 3]]) -> Vec<[i64; 3]> {
    let g = (GRID_LOG2 as f64).exp2();
    p.iter()
        .map(|v| v.map(|c| (c as f64 / g).round() as i64))
        .collect()
}

/// The u16 candidate: the snapped positions as steps from their low corner, when the content
/// spans at most 65 535 steps (64 m); with its measured error.
fn grid(p: &[[f32; 3]], q: &[[i64; 3]]) -> Option<(Stored, f64)> {
    let g = (GRID_LOG2 as f64).exp2();
    let lo = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).min().unwrap_or(0));
    let hi = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).max().unwrap_or(0));
    if (0..3).any(|k| hi[k] - lo[k] > 65535) {
        return None;
    }
    let corner = lo.map(|c| (c as f64 * g) as f32);
    let step = g as f32;
    let stored: Vec<[u16; 4]> = q
        .iter()
        .map(|v| {
            let [x, y, z] = [0, 1, 2].map(|k| (v[k] - lo[k]) as u16);
            [x, y, z, 0]
        })
        .collect();
    let err = max_error(p, |i| {
        [0, 1, 2].map(|k| corner[k] as f64 + step as f64 * stored[i][k] as f64)
    });
    Some((
        Stored::Grid {
            lo: corner,
            step,
            q: stored,
        },
        err,
    ))
}

/// The exponential candidate: the snapped positions as offsets from their box's centre, with
/// one exponent per axis and the mantissa bits that make the filter's step at most the grid's
/// (so the offsets are stored exactly), when 24 bits suffice (within 8 km of the centre); with
/// its measured error.
fn exponential(p: &[[f32; 3]], q: &[[i64; 3]]) -> Option<(Stored, f64)> {
    let g = (GRID_LOG2 as f64).exp2();
    let lo = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).min().unwrap_or(0));
    let hi = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).max().unwrap_or(0));
    let centre_q = [0, 1, 2].map(|k| (lo[k] + hi[k]).div_euclid(2));
    let centre = centre_q.map(|c| (c as f64 * g) as f32);
    let d: Vec<[f32; 3]> = q
        .iter()
        .map(|v| [0, 1, 2].map(|k| ((v[k] - centre_q[k]) as f64 * g) as f32))
        .collect();
    // The filter's exponent of an axis: the E with |d| < 2^E for its largest |d|; its step
    // 2^(E − bits + 1).
    let e = (0..3)
        .map(|k| {
            let m = d.iter().map(|v| v[k].abs()).fold(0.0f32, f32::max);
            if m == 0.0 {
                i32::MIN
            } else {
                ((m.to_bits() >> 23) & 0xff) as i32 - 126
            }
        })
        .max()
        .unwrap_or(i32::MIN);
    let bits = e.saturating_add(1 - GRID_LOG2).max(1);
    if bits > 24 {
        return None;
    }
    let enc = meshopt::encode_filter_exp(&d, bits, EncodeExpMode::SharedComponent);
    let mut dec = enc.clone();
    meshopt::decode_filter_exp(&mut dec);
    let decoded: Vec<[f32; 3]> = dec.iter().map(|v| v.map(f32::from_bits)).collect();
    let err = max_error(p, |i| {
        [0, 1, 2].map(|k| centre[k] as f64 + decoded[i][k] as f64)
    });
    Some((
        Stored::Exp {
            centre,
            bits,
            enc,
            decoded,
        },
        err,
    ))
}

/// The compact `.glb` of a tile (see the module documentation).
pub(super) fn compact_glb(
    name: &str,
    mesh: &TileMesh,
    extras: Value,
) -> Result<TileContent, ExportError> {
    check(mesh)?;
    let n = mesh.positions.len();
    // Triangle order for the vertex cache, vertices in order of first use.
    let mut indices = meshopt::optimize_vertex_cache(&mesh.indices, n);
    let remap = meshopt::optimize_vertex_fetch_remap(&indices, n);
    let used = remap.iter().filter(|&&r| r != u32::MAX).count();
    let mut order = vec![0usize; used];
    for (old, &new) in remap.iter().enumerate() {
        if new != u32::MAX {
            order[new as usize] = old;
        }
    }
    for i in &mut indices {
        *i = remap[*i as usize];
    }
    let p: Vec<[f32; 3]> = order.iter().map(|&o| y_up(mesh.positions[o])).collect();
    let reordered: Vec<Vec3> = order.iter().map(|&o| mesh.positions[o]).collect();
    let (lo, hi) = y_up_bounds(&reordered);

    // Positions: the smallest stream within the tolerance.
    let mut candidates: Vec<(Stored, f64, Vec<u8>)> = Vec::new();
    if used > 0 {
        let q = snap(&p);
        for (c, err) in [grid(&p, &q), exponential(&p, &q)].into_iter().flatten() {
            if err < POSITION_TOLERANCE_M {
                let bytes = match &c {
                    Stored::Grid { q, .. } => encode_vertices(q),
                    Stored::Exp { enc, .. } => encode_vertices(enc),
                    Stored::Float => unreachable!("not a candidate here"),
                };
                candidates.push((c, err, bytes));
            }
        }
    }
    candidates.push((Stored::Float, 0.0, encode_vertices(&p)));
    // Smallest first; ties keep the order above.
    let (stored, position_error_m, position_bytes) = candidates
        .into_iter()
        .enumerate()
        .min_by_key(|(k, c)| (c.2.len(), *k))
        .map(|(_, c)| c)
        .expect("the f32 candidate is always there");

    let mut s = Streams {
        bin: Vec::new(),
        views: Vec::new(),
        fallback: 0,
    };
    let mut accessors: Vec<Value> = Vec::new();
    let mut attributes = serde_json::Map::new();
    let mut node = json!({});
    let encoding = match &stored {
        Stored::Grid { lo, step, q } => {
            node["translation"] = json!(lo);
            node["scale"] = json!([step, step, step]);
            let qmin = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).min().unwrap_or(0));
            let qmax = [0, 1, 2].map(|k| q.iter().map(|v| v[k]).max().unwrap_or(0));
            let v = s.push(&position_bytes, used, 8, "ATTRIBUTES", None, ARRAY_BUFFER);
            accessors.push(json!({"bufferView": v, "componentType": UNSIGNED_SHORT, "count": used, "type": "VEC3", "min": qmin, "max": qmax}));
            "u16".to_string()
        }
        Stored::Exp {
            centre,
            bits,
            decoded,
            ..
        } => {
            node["translation"] = json!(centre);
            let dlo = [0, 1, 2].map(|k| decoded.iter().map(|d| d[k]).fold(f32::INFINITY, f32::min));
            let dhi = [0, 1, 2].map(|k| {
                decoded
                    .iter()
                    .map(|d| d[k])
                    .fold(f32::NEG_INFINITY, f32::max)
            });
            let v = s.push(
                &position_bytes,
                used,
                12,
                "ATTRIBUTES",
                Some("EXPONENTIAL"),
                ARRAY_BUFFER,
            );
            accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": used, "type": "VEC3", "min": dlo, "max": dhi}));
            format!("exp{bits}")
        }
        Stored::Float => {
            let v = s.push(&position_bytes, used, 12, "ATTRIBUTES", None, ARRAY_BUFFER);
            accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": used, "type": "VEC3", "min": lo, "max": hi}));
            "f32".to_string()
        }
    };
    attributes.insert("POSITION".into(), json!(0));

    // Normals: octahedral, 8 bits.
    let normals: Vec<[f32; 4]> = order
        .iter()
        .map(|&o| {
            let [x, y, z] = y_up(mesh.normals[o]);
            [x, y, z, 0.0]
        })
        .collect();
    let oct: Vec<[i8; 4]> = meshopt::encode_filter_oct(&normals, 8);
    let v = s.push(
        &encode_vertices(&oct),
        used,
        4,
        "ATTRIBUTES",
        Some("OCTAHEDRAL"),
        ARRAY_BUFFER,
    );
    attributes.insert("NORMAL".into(), json!(accessors.len()));
    accessors.push(json!({"bufferView": v, "componentType": BYTE, "normalized": true, "count": used, "type": "VEC3"}));

    if !mesh.colors.is_empty() {
        let colors: Vec<[f32; 3]> = order.iter().map(|&o| mesh.colors[o]).collect();
        let rgba = rgba8(&colors);
        let v = s.push(
            &encode_vertices(&rgba),
            used,
            4,
            "ATTRIBUTES",
            None,
            ARRAY_BUFFER,
        );
        attributes.insert("COLOR_0".into(), json!(accessors.len()));
        accessors.push(json!({"bufferView": v, "componentType": UNSIGNED_BYTE, "normalized": true, "count": used, "type": "VEC4"}));
    }
    let with_features = !mesh.feature_ids.is_empty();
    if with_features {
        let (bytes, component) = if mesh.features.len() <= 1 << 16 {
            let ids: Vec<[u16; 2]> = order
                .iter()
                .map(|&o| [mesh.feature_ids[o] as u16, 0])
                .collect();
            (encode_vertices(&ids), UNSIGNED_SHORT)
        } else {
            let ids: Vec<[f32; 1]> = order
                .iter()
                .map(|&o| [mesh.feature_ids[o] as f32])
                .collect();
            (encode_vertices(&ids), FLOAT)
        };
        let v = s.push(&bytes, used, 4, "ATTRIBUTES", None, ARRAY_BUFFER);
        attributes.insert("_FEATURE_ID_0".into(), json!(accessors.len()));
        accessors.push(
            json!({"bufferView": v, "componentType": component, "count": used, "type": "SCALAR"}),
        );
    }

    let (index_bytes, index_stride, index_type) = if used <= 1 << 16 {
        (
            meshopt::encode_index_buffer(&indices, used).expect("indices encode"),
            2,
            UNSIGNED_SHORT,
        )
    } else {
        (
            meshopt::encode_index_buffer(&indices, used).expect("indices encode"),
            4,
            UNSIGNED_INT,
        )
    };
    let v = s.push(
        &index_bytes,
        indices.len(),
        index_stride,
        "TRIANGLES",
        None,
        ELEMENT_ARRAY_BUFFER,
    );
    let a_idx = accessors.len();
    accessors.push(json!({"bufferView": v, "componentType": index_type, "count": indices.len(), "type": "SCALAR"}));

    let mut primitive = json!({
        "attributes": Value::Object(attributes),
        "indices": a_idx,
        "material": 0,
        "mode": 4,
    });
    let Streams {
        mut bin,
        mut views,
        fallback,
    } = s;
    let mut doc_extensions = serde_json::Map::new();
    let mut used_ext = vec![MESHOPT, QUANTIZATION];
    if with_features {
        let (p, d) = metadata(&mesh.features, &mut bin, &mut views);
        primitive["extensions"] = json!({ "EXT_mesh_features": p });
        doc_extensions.insert("EXT_structural_metadata".into(), d);
        used_ext.extend(["EXT_mesh_features", "EXT_structural_metadata"]);
    }
    let mut extras = match extras {
        Value::Object(m) => m,
        Value::Null => serde_json::Map::new(),
        other => {
            let mut m = serde_json::Map::new();
            m.insert("value".into(), other);
            m
        }
    };
    extras.insert("position_encoding".into(), json!(encoding));
    extras.insert("position_error_m".into(), json!(position_error_m));
    let parts = Parts {
        node,
        primitive,
        accessors,
        views,
        more_buffers: vec![json!({
            "byteLength": fallback,
            "extensions": { MESHOPT: { "fallback": true } },
        })],
        used: used_ext,
        required: vec![MESHOPT, QUANTIZATION],
        doc_extensions,
    };
    Ok(TileContent {
        bytes: assemble(name, Value::Object(extras), parts, &bin)?,
        position_error_m,
    })
}
