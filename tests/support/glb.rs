//! A reader of the tile contents `.glb` that blockwalk writes, plain or compact: the `gltf` crate
//! cannot decode `EXT_meshopt_compression`, so this one parses the GLB container and the JSON
//! chunk itself (`serde_json`), decodes compressed buffer views with meshoptimizer's decoder (the
//! `meshopt` crate: the reference implementation of the bitstream and its filters), reads the
//! accessors whatever their component type (`KHR_mesh_quantization`'s integer and normalised
//! ones included) and dequantises positions with the root node's translation and scale.
//! Panics (with the file's name) on anything it does not expect: it is a test's reader.

use std::path::Path;

use serde_json::Value;

/// A `.glb` read back.
pub struct Glb {
    /// Its name, for messages.
    pub name: String,
    /// The JSON chunk.
    pub doc: Value,
    /// Every buffer view's bytes, decompressed when compressed.
    views: Vec<Vec<u8>>,
    /// Whether any buffer view was compressed (`EXT_meshopt_compression`).
    pub compressed: bool,
}

/// Property table 0 (`EXT_structural_metadata`, class `building`).
#[derive(Debug, PartialEq)]
pub struct Properties {
    pub source_id: Vec<String>,
    pub height_m: Vec<f64>,
    pub min_height_m: Vec<f64>,
    pub base_m: Vec<f64>,
}

/// Decodes a vertex stream of `count` elements of type `T` (a byte array of the stride).
fn decode_attributes<T: Clone + Default + AsRef<[u8]>>(data: &[u8], count: usize) -> Vec<u8> {
    let v: Vec<T> = meshopt::decode_vertex_buffer(data, count).expect("vertex stream");
    v.iter().flat_map(|e| e.as_ref().to_vec()).collect()
}

impl Glb {
    pub fn read(path: &Path) -> Glb {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        Glb::from_bytes(&path.display().to_string(), &bytes)
    }

    pub fn from_bytes(name: &str, b: &[u8]) -> Glb {
        let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as usize;
        assert_eq!(&b[0..4], b"glTF", "{name}");
        assert_eq!(u32_at(4), 2, "{name}: version");
        assert_eq!(u32_at(8), b.len(), "{name}: header length");
        let jl = u32_at(12);
        assert_eq!(&b[16..20], b"JSON", "{name}");
        let doc: Value = serde_json::from_slice(&b[20..20 + jl]).unwrap();
        let bl = u32_at(20 + jl);
        assert_eq!(&b[24 + jl..28 + jl], b"BIN\0", "{name}");
        let bin = &b[28 + jl..28 + jl + bl];
        assert!(
            doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize <= bin.len(),
            "{name}: buffer 0 within the binary chunk"
        );
        let required: Vec<&str> = doc["extensionsRequired"]
            .as_array()
            .map(|a| a.iter().map(|x| x.as_str().unwrap()).collect())
            .unwrap_or_default();
        let mut compressed = false;
        let mut views = Vec::new();
        for (k, v) in doc["bufferViews"].as_array().unwrap().iter().enumerate() {
            let len = v["byteLength"].as_u64().unwrap() as usize;
            let Some(m) = v["extensions"].get("EXT_meshopt_compression") else {
                assert_eq!(
                    v["buffer"], 0,
                    "{name}: view {k}: uncompressed data in the GLB chunk"
                );
                let o = v["byteOffset"].as_u64().unwrap_or(0) as usize;
                views.push(bin[o..o + len].to_vec());
                continue;
            };
            compressed = true;
            assert!(
                required.contains(&"EXT_meshopt_compression"),
                "{name}: compressed views without the extension required"
            );
            // The parent view points at the fallback buffer: no data, flagged.
            let fb = &doc["buffers"][v["buffer"].as_u64().unwrap() as usize];
            assert!(fb.get("uri").is_none(), "{name}: fallback buffer with data");
            assert_eq!(
                fb["extensions"]["EXT_meshopt_compression"]["fallback"],
                true
            );
            assert_eq!(m["buffer"], 0, "{name}: compressed data in the GLB chunk");
            let o = m["byteOffset"].as_u64().unwrap_or(0) as usize;
            let data = &bin[o..o + m["byteLength"].as_u64().unwrap() as usize];
            let stride = m["byteStride"].as_u64().unwrap() as usize;
            let count = m["count"].as_u64().unwrap() as usize;
            assert_eq!(stride * count, len, "{name}: view {k}: byteLength");
            if let Some(s) = v.get("byteStride") {
                assert_eq!(s.as_u64().unwrap() as usize, stride, "{name}: view {k}");
            }
            let filter = m["filter"].as_str().unwrap_or("NONE");
            let mut out = match m["mode"].as_str().unwrap() {
                "ATTRIBUTES" => {
                    // The vertex codec of EXT_meshopt_compression is version 0.
                    assert_eq!(data[0], 0xa0, "{name}: view {k}: vertex codec version");
                    match stride {
                        4 => decode_attributes::<[u8; 4]>(data, count),
                        8 => decode_attributes::<[u8; 8]>(data, count),
                        12 => decode_attributes::<[u8; 12]>(data, count),
                        16 => decode_attributes::<[u8; 16]>(data, count),
                        s => panic!("{name}: view {k}: stride {s}"),
                    }
                }
                "TRIANGLES" => {
                    assert_eq!(data[0], 0xe1, "{name}: view {k}: index codec version");
                    assert_eq!(count % 3, 0);
                    assert_eq!(filter, "NONE");
                    match stride {
                        2 => meshopt::decode_index_buffer::<u16>(data, count)
                            .unwrap()
                            .iter()
                            .flat_map(|i| i.to_le_bytes())
                            .collect(),
                        4 => meshopt::decode_index_buffer::<u32>(data, count)
                            .unwrap()
                            .iter()
                            .flat_map(|i| i.to_le_bytes())
                            .collect(),
                        s => panic!("{name}: view {k}: index stride {s}"),
                    }
                }
                mode => panic!("{name}: view {k}: mode {mode}"),
            };
            match (filter, stride) {
                ("NONE", _) => {}
                ("OCTAHEDRAL", 4) => {
                    let mut e: Vec<[i8; 4]> = out
                        .chunks(4)
                        .map(|c| [c[0], c[1], c[2], c[3]].map(|x| x as i8))
                        .collect();
                    meshopt::decode_filter_oct(&mut e);
                    out = e.iter().flat_map(|c| c.map(|x| x as u8)).collect();
                }
                ("EXPONENTIAL", 12) => {
                    let mut e: Vec<[u32; 3]> = out
                        .chunks(12)
                        .map(|c| {
                            [0, 1, 2].map(|q| {
                                u32::from_le_bytes(c[4 * q..4 * q + 4].try_into().unwrap())
                            })
                        })
                        .collect();
                    meshopt::decode_filter_exp(&mut e);
                    out = e.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
                }
                (f, s) => panic!("{name}: view {k}: filter {f} with stride {s}"),
            }
            views.push(out);
        }
        Glb {
            name: name.to_string(),
            doc,
            views,
            compressed,
        }
    }

    /// A buffer view's (decoded) bytes.
    pub fn view(&self, v: usize) -> &[u8] {
        &self.views[v]
    }

    /// An accessor's components, as numbers (normalised ones as glTF maps them to [−1, 1] or
    /// [0, 1]); `count × components` values.
    pub fn accessor(&self, a: usize) -> Vec<f64> {
        let acc = &self.doc["accessors"][a];
        let count = acc["count"].as_u64().unwrap() as usize;
        let comps = match acc["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            t => panic!("{t}"),
        };
        let ct = acc["componentType"].as_u64().unwrap();
        let size = match ct {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            c => panic!("component type {c}"),
        };
        let normalized = acc["normalized"].as_bool().unwrap_or(false);
        let v = acc["bufferView"].as_u64().unwrap() as usize;
        let data = self.view(v);
        let stride = self.doc["bufferViews"][v]["byteStride"]
            .as_u64()
            .map_or(size * comps, |s| s as usize);
        let offset = acc["byteOffset"].as_u64().unwrap_or(0) as usize;
        let mut out = Vec::with_capacity(count * comps);
        for i in 0..count {
            for c in 0..comps {
                let o = offset + i * stride + c * size;
                let b = &data[o..o + size];
                let x = match ct {
                    5120 => {
                        let x = b[0] as i8 as f64;
                        if normalized {
                            (x / 127.0).max(-1.0)
                        } else {
                            x
                        }
                    }
                    5121 => b[0] as f64 / if normalized { 255.0 } else { 1.0 },
                    5122 => {
                        let x = i16::from_le_bytes([b[0], b[1]]) as f64;
                        if normalized {
                            (x / 32767.0).max(-1.0)
                        } else {
                            x
                        }
                    }
                    5123 => {
                        u16::from_le_bytes([b[0], b[1]]) as f64
                            / if normalized { 65535.0 } else { 1.0 }
                    }
                    5125 => u32::from_le_bytes(b.try_into().unwrap()) as f64,
                    _ => f32::from_le_bytes(b.try_into().unwrap()) as f64,
                };
                out.push(x);
            }
        }
        out
    }

    pub fn primitive(&self) -> &Value {
        assert_eq!(self.doc["meshes"].as_array().unwrap().len(), 1);
        assert_eq!(
            self.doc["meshes"][0]["primitives"]
                .as_array()
                .unwrap()
                .len(),
            1
        );
        &self.doc["meshes"][0]["primitives"][0]
    }

    fn attribute(&self, semantic: &str) -> Option<Vec<f64>> {
        self.primitive()["attributes"][semantic]
            .as_u64()
            .map(|a| self.accessor(a as usize))
    }

    /// The root node's `extras`.
    pub fn extras(&self) -> &Value {
        &self.doc["nodes"][0]["extras"]
    }

    /// Positions as the scene places them (glTF Y-up): the accessor's values through the root
    /// node's translation and scale (the only transform a tile's node has), in f64.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        let node = &self.doc["nodes"][0];
        assert!(node.get("rotation").is_none() && node.get("matrix").is_none());
        let num = |v: &Value, k: usize, d: f64| v.get(k).and_then(Value::as_f64).unwrap_or(d);
        let t = [0, 1, 2].map(|k| num(&node["translation"], k, 0.0));
        let s = [0, 1, 2].map(|k| num(&node["scale"], k, 1.0));
        self.attribute("POSITION")
            .expect("POSITION")
            .chunks(3)
            .map(|c| [0, 1, 2].map(|k| t[k] + s[k] * c[k]))
            .collect()
    }

    /// Normals, normalised (a quantised normal is not exactly of unit length).
    pub fn normals(&self) -> Vec<[f64; 3]> {
        self.attribute("NORMAL")
            .expect("NORMAL")
            .chunks(3)
            .map(|c| {
                let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                [c[0] / l, c[1] / l, c[2] / l]
            })
            .collect()
    }

    /// `COLOR_0` as RGBA bytes (it is stored as normalised bytes in both encodings).
    pub fn colors(&self) -> Option<Vec<[u8; 4]>> {
        let a = self.primitive()["attributes"]["COLOR_0"].as_u64()? as usize;
        let acc = &self.doc["accessors"][a];
        assert_eq!(
            (acc["componentType"].as_u64(), acc["type"].as_str()),
            (Some(5121), Some("VEC4"))
        );
        Some(
            self.accessor(a)
                .chunks(4)
                .map(|c| {
                    c.iter()
                        .map(|x| (x * 255.0).round() as u8)
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap()
                })
                .collect(),
        )
    }

    /// `_FEATURE_ID_0` per vertex (whole numbers whatever the component type).
    pub fn feature_ids(&self) -> Option<Vec<u32>> {
        let v = self.attribute("_FEATURE_ID_0")?;
        Some(
            v.into_iter()
                .map(|f| {
                    assert_eq!(f, f.trunc(), "{}: feature ids are whole numbers", self.name);
                    f as u32
                })
                .collect(),
        )
    }

    pub fn indices(&self) -> Vec<u32> {
        let a = self.primitive()["indices"].as_u64().unwrap() as usize;
        self.accessor(a).into_iter().map(|i| i as u32).collect()
    }

    /// Property table 0, or `None` without `EXT_structural_metadata`.
    pub fn properties(&self) -> Option<Properties> {
        let ext = self.doc["extensions"].get("EXT_structural_metadata")?;
        let t = &ext["propertyTables"][0];
        assert_eq!(t["class"], "building");
        let n = t["count"].as_u64().unwrap() as usize;
        let p = &t["properties"];
        let view = |key: &str, part: &str| {
            let v = p[key][part].as_u64().unwrap() as usize;
            // Property buffer views are 8-byte aligned (EXT_structural_metadata) and stored
            // uncompressed.
            let bv = &self.doc["bufferViews"][v];
            assert_eq!(bv["byteOffset"].as_u64().unwrap_or(0) % 8, 0, "{key}");
            assert!(
                bv.get("extensions").is_none(),
                "{key}: compressed property view"
            );
            self.view(v)
        };
        let vals = view("source_id", "values");
        let offs = view("source_id", "stringOffsets");
        let off =
            |k: usize| u32::from_le_bytes(offs[4 * k..4 * k + 4].try_into().unwrap()) as usize;
        let f64s = |key: &str| -> Vec<f64> {
            let d = view(key, "values");
            (0..n)
                .map(|k| f64::from_le_bytes(d[8 * k..8 * k + 8].try_into().unwrap()))
                .collect()
        };
        Some(Properties {
            source_id: (0..n)
                .map(|k| String::from_utf8(vals[off(k)..off(k + 1)].to_vec()).unwrap())
                .collect(),
            height_m: f64s("height_m"),
            min_height_m: f64s("min_height_m"),
            base_m: f64s("base_m"),
        })
    }
}
