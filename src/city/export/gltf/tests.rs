use super::city::{write_glb_limited, write_glb_to_limited};
use super::*;
use crate::city::build::{build_city, BuildOptions};
use crate::city::extrude::try_extrude_city;
use crate::city::{City, Mesh};
use crate::importers::{read_layer, Theme};
use serde_json::{json, Value};

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
                "base_m": b.base_m,
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
        write_glb_limited(&city, &meshes, None, &f, size)
            .unwrap()
            .bytes as u64,
        size
    );
    std::fs::remove_file(&f).unwrap();
    // One byte less: refused, naming the file and both sizes; no file left behind.
    let e = write_glb_limited(&city, &meshes, None, &f, size - 1).unwrap_err();
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
    let e = write_glb_to_limited(&city, &meshes, None, &mut sink, 1000).unwrap_err();
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
                base_m: 0.0,
            },
            TileFeature {
                source_id: "bé".into(),
                height_m: 2.0,
                min_height_m: 0.5,
                base_m: 0.0,
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

/// A compact tile of a mesh wider than any single grid: every vertex decodes (meshoptimizer's
/// decoder, the exponential filter, the node's translation) to within the tolerance, and the
/// document requires both extensions and states its error.
#[test]
fn compact_tile_decodes_within_the_tolerance_and_requires_its_extensions() {
    let mut m = two_triangles();
    // Spread over 3 km: neither u16 nor a few mantissa bits resolve a millimetre there.
    m.positions[4] = Vec3::new(3_000.123_4, -25.5, 40.25);
    let c = tile_glb("t", &m, json!({"k": 1}), ContentEncoding::Compact).unwrap();
    assert_eq!(
        c,
        tile_glb("t", &m, json!({"k": 1}), ContentEncoding::Compact).unwrap(),
        "deterministic"
    );
    let doc = json_of(&c.bytes);
    assert_eq!(
        doc["extensionsRequired"],
        json!(["EXT_meshopt_compression", "KHR_mesh_quantization"])
    );
    let extras = &doc["nodes"][0]["extras"];
    assert_eq!(extras["k"], 1);
    assert_eq!(extras["position_error_m"], json!(c.position_error_m));
    assert!(c.position_error_m < POSITION_TOLERANCE_M);
    assert!(extras["position_encoding"]
        .as_str()
        .unwrap()
        .starts_with("exp"));
    // Decode the positions by hand: the POSITION view's stream, the filter, the translation.
    let jl = u32::from_le_bytes(c.bytes[12..16].try_into().unwrap()) as usize;
    let bin = &c.bytes[28 + jl..];
    let acc = &doc["accessors"][0];
    let ext = &doc["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize]["extensions"]
        ["EXT_meshopt_compression"];
    assert_eq!(ext["filter"], "EXPONENTIAL");
    let o = ext["byteOffset"].as_u64().unwrap() as usize;
    let data = &bin[o..o + ext["byteLength"].as_u64().unwrap() as usize];
    assert_eq!(data[0], 0xa0, "vertex codec version 0");
    let mut v: Vec<[u32; 3]> = meshopt::decode_vertex_buffer(data, 6).unwrap();
    meshopt::decode_filter_exp(&mut v);
    let t: Vec<f64> = doc["nodes"][0]["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let mut decoded: Vec<[f64; 3]> = v
        .iter()
        .map(|e| [0, 1, 2].map(|k| t[k] + f32::from_bits(e[k]) as f64))
        .collect();
    // Vertices are renumbered: compare the sets.
    let mut want: Vec<[f64; 3]> = m
        .positions
        .iter()
        .map(|p| y_up(*p).map(f64::from))
        .collect();
    let by = |a: &[f64; 3], b: &[f64; 3]| a.partial_cmp(b).unwrap();
    decoded.sort_by(by);
    want.sort_by(by);
    let worst = decoded
        .iter()
        .zip(&want)
        .map(|(d, w)| (0..3).map(|k| (d[k] - w[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3 && worst <= c.position_error_m, "{worst}");
    // Plain through the same entry point is the plain writer's file.
    let p = tile_glb("t", &m, json!({"k": 1}), ContentEncoding::Plain).unwrap();
    assert_eq!(p.bytes, tile_glb_bytes("t", &m, json!({"k": 1})).unwrap());
    assert_eq!(p.position_error_m, 0.0);
    // Indices past the vertices are refused, not handed to the optimiser.
    let mut bad = two_triangles();
    bad.indices[2] = 6;
    assert!(matches!(
        tile_glb("t", &bad, Value::Null, ContentEncoding::Compact).unwrap_err(),
        ExportError::Indices { .. }
    ));
}
