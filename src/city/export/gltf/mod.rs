//! glTF 2.0 binary (`.glb`) export of the extruded city.
//!
//! Optionally (`*_with_terrain`) a terrain: one more node `terrain` under the root with one mesh
//! `terrain` and its own material, its data after the buildings' in the same buffer views.
//!
//! One node per building (`name` = source id; `extras` = `{source_id, height_m, min_height_m, base_m}`)
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
//!
//! The city's file is [`write_glb`] and its siblings (file `city.rs`); the content `.glb` of one
//! 3D Tiles tile is [`tile_glb`] (file `tile.rs`: plain, [`tile_glb_bytes`]; file `compact.rs`:
//! quantised and compressed). They share this module's glTF pieces: the Y-up axes, chunk padding
//! and the header and chunk writers.

mod city;
mod compact;
#[cfg(test)]
mod tests;
mod tile;

pub use city::{
    glb_bytes, glb_bytes_with_terrain, write_glb, write_glb_to, write_glb_to_with_terrain,
    write_glb_with_terrain, GlbStats,
};
pub use tile::{
    tile_glb, tile_glb_bytes, ContentEncoding, TileContent, TileFeature, TileMesh,
    POSITION_TOLERANCE_M,
};

use std::io::Write;

use glam::Vec3;
use serde_json::Value;

use super::ExportError;

/// The largest `.glb` file: its header stores the total length as a `u32` (glTF 2.0, "Binary
/// glTF Layout").
pub const GLB_MAX_BYTES: u64 = u32::MAX as u64;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const UNSIGNED_BYTE: u32 = 5121;
const BYTE: u32 = 5120;
const UNSIGNED_SHORT: u32 = 5123;

/// The terrain's material (the city's `.glb` and the terrain tiles): a green grey, unlike the
/// buildings' warm grey.
fn terrain_material() -> Value {
    let c = super::terrain::TERRAIN_COLOR;
    serde_json::json!({
        "name": "terrain",
        "pbrMetallicRoughness": {
            "baseColorFactor": [c[0], c[1], c[2], 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        },
    })
}

fn y_up(v: Vec3) -> [f32; 3] {
    [v.x, v.z, -v.y]
}

/// `n` rounded up to a multiple of 4 (chunks are 4-byte aligned).
fn padded(n: u64) -> Option<u64> {
    n.checked_add(3).map(|m| m & !3)
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

/// Writes a `.glb`'s 12-byte header (magic, version 2, `total` length) and its JSON chunk:
/// `json` padded with spaces to `json_padded` bytes (a multiple of 4, at most 3 more).
fn write_head<W: Write>(
    w: &mut W,
    total: u32,
    json: &[u8],
    json_padded: u32,
) -> std::io::Result<()> {
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&json_padded.to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(json)?;
    w.write_all(&b"   "[..json_padded as usize - json.len()])
}

/// Writes the 8-byte header of a `.glb`'s binary chunk of `bin_padded` bytes.
fn write_bin_head<W: Write>(w: &mut W, bin_padded: u32) -> std::io::Result<()> {
    w.write_all(&bin_padded.to_le_bytes())?;
    w.write_all(b"BIN\0")
}
