//! The city's `.glb`: one node per building, streamed from the meshes, and optionally a terrain
//! node.

use std::io::Write;
use std::path::Path;

use glam::Vec3;
use serde_json::json;

use super::*;
use crate::city::export::terrain::TerrainTin;
use crate::city::export::ExportError;
use crate::city::{City, Mesh};

/// What [`write_glb`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GlbStats {
    /// Building nodes.
    pub nodes: usize,
    /// Meshes (buildings with at least one triangle).
    pub meshes: usize,
    /// Triangles (buildings' and terrain's).
    pub triangles: usize,
    /// Terrain triangles (0 without terrain).
    pub terrain_triangles: usize,
    /// File size in bytes.
    pub bytes: usize,
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

/// The terrain's mesh in the city's local frame, after checking it.
fn terrain_mesh(city: &City, terrain: Option<&TerrainTin>) -> Result<Option<Mesh>, ExportError> {
    terrain
        .map(|t| {
            t.check().map_err(|source| ExportError::Terrain {
                file: "<glb>".into(),
                source,
            })?;
            Ok(t.local_mesh(&city.frame))
        })
        .transpose()
}

/// Sizes and JSON chunk of the `.glb` of `city` and its terrain mesh (see the module
/// documentation), refusing a file over `limit` bytes.
///
/// The document's members are written in the order `serde_json` gives an object's keys (sorted),
/// so the bytes are those of serialising the whole document as one [`Value`].
fn prepare(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&Mesh>,
    limit: u64,
) -> Result<Prepared, ExportError> {
    if meshes.len() != city.buildings.len() {
        return Err(ExportError::MeshCount {
            file: "<glb>".into(),
            meshes: meshes.len(),
            buildings: city.buildings.len(),
        });
    }
    // The terrain's data follows the buildings' in each buffer view, as one more mesh.
    let terrain = terrain.filter(|t| t.triangle_count() > 0);
    let all = || meshes.iter().chain(terrain);
    let sum = |f: fn(&Mesh) -> usize| -> Option<u64> {
        all().try_fold(0u64, |acc, m| acc.checked_add(f(m) as u64))
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
    let n_building_meshes = with_tris().count();
    let n_meshes = n_building_meshes + usize::from(terrain.is_some());
    let terrain_triangles = terrain.map_or(0, Mesh::triangle_count);
    let mut stats = GlbStats {
        nodes: city.buildings.len() + usize::from(terrain.is_some()),
        meshes: n_meshes,
        triangles: with_tris().map(|(_, m)| m.triangle_count()).sum::<usize>() + terrain_triangles,
        terrain_triangles,
        bytes: 0,
    };

    let mut out: Vec<u8> = Vec::new();
    out.push(b'{');
    if n_meshes > 0 {
        // Accessors: POSITION, NORMAL and indices of each mesh, at the mesh's offsets.
        let mut offsets = Vec::with_capacity(n_meshes);
        let (mut vert_off, mut idx_off) = (0u64, 0u64);
        for m in all() {
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
    let mut materials = vec![json!({
        "name": "building",
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.82, 0.80, 0.76, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 0.9,
        },
    })];
    if terrain.is_some() {
        materials.push(terrain_material());
    }
    put_array(&mut out, "materials", materials)?;
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
        let a_pos = 3 * n_building_meshes;
        let terrain_mesh = terrain.map(|_| {
            json!({
                "name": "terrain",
                "primitives": [{
                    "attributes": { "POSITION": a_pos, "NORMAL": a_pos + 1 },
                    "indices": a_pos + 2,
                    "material": 1,
                    "mode": 4,
                }]
            })
        });
        put_array(&mut out, "meshes", gl_meshes.chain(terrain_mesh))?;
    }
    out.push(b',');
    // Nodes: the root (children 1..=n, and n + 1 for the terrain), then one per building, then
    // the terrain.
    let o = city.frame.origin;
    let n_children = city.buildings.len() + usize::from(terrain.is_some());
    let mut root = json!({
        "name": city.name,
        "children": (1..=n_children).collect::<Vec<usize>>(),
        "extras": {
            "origin": [o.x, o.y, o.z],
            "crs": city.transform.describe(),
            "frame": "local metres: x east, y up, z south of the origin (glTF Y-up)",
        }
    });
    if n_children == 0 {
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
                "base_m": b.base_m,
            }
        });
        if m.triangle_count() > 0 {
            node["mesh"] = json!(mesh_idx);
            mesh_idx += 1;
        }
        node
    }));
    let terrain_node = terrain.map(|t| {
        json!({
            "name": "terrain",
            "mesh": n_building_meshes,
            "extras": { "kind": "terrain", "triangles": t.triangle_count(), "vertices": t.positions.len() },
        })
    });
    let nodes = nodes.chain(terrain_node);
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

/// Writes a prepared `.glb`: header, JSON chunk, then the binary chunk from the meshes (the
/// terrain's after the buildings').
fn emit<W: Write>(
    p: &Prepared,
    meshes: &[Mesh],
    terrain: Option<&Mesh>,
    w: &mut W,
) -> std::io::Result<()> {
    let terrain = terrain.filter(|t| t.triangle_count() > 0);
    // `prepare` refused totals over u32::MAX, so every length below fits.
    let u32_of = |n: u64| u32::try_from(n).expect("checked against GLB_MAX_BYTES");
    let json_padded = padded(p.json.len() as u64).expect("checked in prepare");
    write_head(w, u32_of(p.total), &p.json, u32_of(json_padded))?;
    if p.bin_len == 0 {
        return Ok(());
    }
    let bin_padded = padded(p.bin_len).expect("checked in prepare");
    write_bin_head(w, u32_of(bin_padded))?;
    // One mesh at a time through a small buffer.
    let mut buf: Vec<u8> = Vec::new();
    let mut vec3s = |w: &mut W, f: fn(&Mesh) -> &[Vec3]| -> std::io::Result<()> {
        for m in meshes.iter().chain(terrain) {
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
    for m in meshes.iter().chain(terrain) {
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
    write_glb_to_limited(city, meshes, None, w, GLB_MAX_BYTES)
}

/// [`write_glb_to`] with an optional terrain: one more node under the root, named `terrain`,
/// holding one mesh `terrain` (positions in the buildings' local frame, normals from the
/// triangles, every vertex shared between its triangles) with its own material (`terrain`, a
/// green grey, where buildings are a warm grey).
///
/// # Errors
/// As [`write_glb_to`]; [`ExportError::Terrain`] when the terrain fails [`TerrainTin::check`]
/// (nothing is written then).
pub fn write_glb_to_with_terrain<W: Write>(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&TerrainTin>,
    w: &mut W,
) -> Result<GlbStats, ExportError> {
    let t = terrain_mesh(city, terrain)?;
    write_glb_to_limited(city, meshes, t.as_ref(), w, GLB_MAX_BYTES)
}

pub(super) fn write_glb_to_limited<W: Write>(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&Mesh>,
    w: &mut W,
    limit: u64,
) -> Result<GlbStats, ExportError> {
    let p = prepare(city, meshes, terrain, limit)?;
    emit(&p, meshes, terrain, w).map_err(|source| ExportError::Io {
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
    glb_bytes_with_terrain(city, meshes, None)
}

/// [`glb_bytes`] with an optional terrain (see [`write_glb_to_with_terrain`]).
///
/// # Errors
/// As [`write_glb_to_with_terrain`].
pub fn glb_bytes_with_terrain(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&TerrainTin>,
) -> Result<(Vec<u8>, GlbStats), ExportError> {
    let mut out = Vec::new();
    let stats = write_glb_to_with_terrain(city, meshes, terrain, &mut out)?;
    Ok((out, stats))
}

/// Writes the city's meshes as a `.glb` file (see the module documentation), streaming it
/// through a buffered writer; a city on terrain gets its terrain as a `terrain` node
/// ([`write_glb_with_terrain`]).
///
/// # Errors
/// [`ExportError`] naming the file; a file over [`GLB_MAX_BYTES`] is refused before it is
/// created. The file is written under a temporary name and renamed when complete: a failed or
/// killed write leaves whatever was at `path` as it was.
pub fn write_glb(city: &City, meshes: &[Mesh], path: &Path) -> Result<GlbStats, ExportError> {
    match crate::city::export::terrain::city_tin(city, path)? {
        Some(tin) => write_glb_with_terrain(city, meshes, Some(&tin), path),
        None => write_glb_limited(city, meshes, None, path, GLB_MAX_BYTES),
    }
}

/// [`write_glb`] with an optional terrain (see [`write_glb_to_with_terrain`]).
///
/// # Errors
/// As [`write_glb`]; [`ExportError::Terrain`] naming the file when the terrain fails
/// [`TerrainTin::check`] (nothing is written then).
pub fn write_glb_with_terrain(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&TerrainTin>,
    path: &Path,
) -> Result<GlbStats, ExportError> {
    let t = terrain_mesh(city, terrain).map_err(|e| e.for_file(path))?;
    write_glb_limited(city, meshes, t.as_ref(), path, GLB_MAX_BYTES)
}

pub(super) fn write_glb_limited(
    city: &City,
    meshes: &[Mesh],
    terrain: Option<&Mesh>,
    path: &Path,
    limit: u64,
) -> Result<GlbStats, ExportError> {
    let p = prepare(city, meshes, terrain, limit).map_err(|e| e.for_file(path))?;
    let io = |source| ExportError::Io {
        file: path.to_path_buf(),
        source,
    };
    let mut f = crate::output::AtomicFile::create(path)?;
    emit(&p, meshes, terrain, &mut f).map_err(io)?;
    f.commit()?;
    Ok(p.stats)
}
