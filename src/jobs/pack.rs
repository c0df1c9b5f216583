//! What a viewer streams from a finished tile: its blocks' meshes packed in one file, each
//! block an independently readable byte range with its own CRC-32 (so a client fetches one block
//! with one HTTP range request and checks it before decoding), and the tile's hierarchy,
//! `tile_NNNNN.hier.json`: every block's box, sphere and mesh range, and every BlockMap node's
//! key, parent, blocks, box, declared error and file. A client holds the hierarchies and fetches
//! the content on demand (Di Benedetto, *Multiresolution techniques for real-time visualization
//! of urban environments and terrains*, §4.4).
//!
//! # The block mesh record (`tile_NNNNN.pack`)
//! Each record is stored as a zlib stream ([`TileHierarchy::compression`] `"zlib"`, RFC 1950;
//! about a sixth of the raw bytes: normals, styles and appearance repeat) of the raw record,
//! which is little-endian: `"BWMB"`, version `u32 = 1`, then four `u32` counts: positions `P`, indices
//! `I`, appearance entries `A` (0 or `P`), styles `S`; then `P × 3` `f32` positions (local
//! frame), `P × 3` `f32` normals, `I` `u32` indices, `A × (f32 u, u32 style)`, and `S` styles of
//! 17 four-byte fields each (kind, facade RGB, window RGB, roof RGB, storey height, its inverse,
//! levels, bay, its inverse, window half-width, ground z). The decoded [`Mesh`] is bit for bit
//! the one written.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::blockmap::BlockMapMeta;
use crate::city::appearance::{BuildingKind, BuildingStyle};
use crate::city::mesh::VertexAppearance;
use crate::city::Mesh;
use crate::geom::{Aabb3, BoundingSphere};

use super::{JobsError, TileFile};

/// The format tag of a tile's hierarchy.
pub const HIERARCHY_FORMAT: &str = "blockwalk-tile-hierarchy/1";
/// The first bytes of a block mesh record.
pub const MESH_MAGIC: &[u8; 4] = b"BWMB";
/// The record's version.
pub const MESH_VERSION: u32 = 1;
const HEADER: usize = 24;
const STYLE_WORDS: usize = 17;

/// A byte range of a file, with the CRC-32 of those bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ByteRange {
    /// Offset of the first byte.
    pub offset: u64,
    /// Length.
    pub bytes: u64,
    /// CRC-32 of the range, 8 hex digits.
    pub crc32: String,
    /// Length of the record once inflated (equal to `bytes` for a raw record).
    #[serde(default)]
    pub inflated: u64,
}

/// A block of a tile's hierarchy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HierBlock {
    /// The block's id (the one-job run's).
    pub id: u32,
    /// An outskirts group.
    pub outskirts: bool,
    /// Its buildings.
    pub buildings: usize,
    /// Triangles of its mesh.
    pub triangles: u64,
    /// Box around its geometry, local frame.
    pub aabb: Aabb3,
    /// Its bounding sphere, local frame.
    pub sphere: BoundingSphere,
    /// Centre of its outline (x, y), local frame.
    pub center: [f64; 2],
    /// Its mesh record in the tile's pack; `None` for a block without triangles.
    pub mesh: Option<ByteRange>,
}

/// A BlockMap node of a tile's hierarchy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HierMap {
    /// The node's quadtree key (within the tile's own block quadtree).
    pub key: u64,
    /// Index of the parent map in [`TileHierarchy::maps`] (parents first).
    pub parent: Option<usize>,
    /// Map level.
    pub level: u32,
    /// Its blocks (ids of the one-job run).
    pub blocks: Vec<u32>,
    /// Box, quantisation and declared error.
    pub meta: BlockMapMeta,
    /// The map's PNG (path relative to the plan's folder).
    pub png: TileFile,
}

/// `tiles/tile_NNNNN.hier.json`: what a client needs to choose and fetch a tile's content.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TileHierarchy {
    /// [`HIERARCHY_FORMAT`].
    pub format: String,
    /// The plan's id.
    pub plan_id: String,
    /// The tile.
    pub tile: usize,
    /// The block mesh pack (path relative to the plan's folder), `None` for a tile without
    /// buildings.
    pub pack: Option<String>,
    /// How the pack's records are stored: `"zlib"`, or raw when absent.
    #[serde(default)]
    pub compression: Option<String>,
    /// Blocks, in the tile's order.
    pub blocks: Vec<HierBlock>,
    /// BlockMap nodes, parents first (empty without `--blockmaps`).
    pub maps: Vec<HierMap>,
}

fn kind_code(k: BuildingKind) -> u32 {
    match k {
        BuildingKind::Residential => 0,
        BuildingKind::Commercial => 1,
        BuildingKind::Industrial => 2,
        BuildingKind::Civic => 3,
        BuildingKind::Other => 4,
    }
}

fn kind_of(code: u32) -> Option<BuildingKind> {
    Some(match code {
        0 => BuildingKind::Residential,
        1 => BuildingKind::Commercial,
        2 => BuildingKind::Industrial,
        3 => BuildingKind::Civic,
        4 => BuildingKind::Other,
        _ => return None,
    })
}

/// Appends `mesh`'s record (see the module doc) to `out`.
pub fn encode_mesh(mesh: &Mesh, out: &mut Vec<u8>) {
    let w32 = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    let wf = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    out.extend_from_slice(MESH_MAGIC);
    w32(out, MESH_VERSION);
    w32(out, mesh.positions.len() as u32);
    w32(out, mesh.indices.len() as u32);
    w32(out, mesh.appearance.len() as u32);
    w32(out, mesh.styles.len() as u32);
    for p in &mesh.positions {
        p.to_array().iter().for_each(|&v| wf(out, v));
    }
    for n in &mesh.normals {
        n.to_array().iter().for_each(|&v| wf(out, v));
    }
    mesh.indices.iter().for_each(|&i| w32(out, i));
    for a in &mesh.appearance {
        wf(out, a.u_m);
        w32(out, a.style);
    }
    for s in &mesh.styles {
        w32(out, kind_code(s.kind));
        for v in s.facade.iter().chain(&s.window).chain(&s.roof) {
            wf(out, *v);
        }
        wf(out, s.storey_height_m);
        wf(out, s.inv_storey_m);
        w32(out, s.levels);
        wf(out, s.bay_m);
        wf(out, s.inv_bay_m);
        wf(out, s.window_half);
        wf(out, s.ground_z);
    }
}

/// Decodes one record written by [`encode_mesh`], checking its length, its counts and that every
/// index and style reference is in range.
///
/// # Errors
/// What is wrong with the bytes, in words.
pub fn decode_mesh(bytes: &[u8]) -> Result<Mesh, String> {
    if bytes.len() < HEADER || &bytes[..4] != MESH_MAGIC {
        return Err("not a block mesh record (no BWMB header)".into());
    }
    let word = |i: usize| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    if word(1) != MESH_VERSION {
        return Err(format!(
            "block mesh record version {} (expected {MESH_VERSION})",
            word(1)
        ));
    }
    let (np, ni, na, ns) = (
        word(2) as usize,
        word(3) as usize,
        word(4) as usize,
        word(5) as usize,
    );
    let words = np
        .checked_mul(6)
        .and_then(|w| w.checked_add(ni))
        .and_then(|w| w.checked_add(na.checked_mul(2)?))
        .and_then(|w| w.checked_add(ns.checked_mul(STYLE_WORDS)?))
        .and_then(|w| w.checked_mul(4)?.checked_add(HEADER));
    if words != Some(bytes.len()) {
        return Err(format!(
            "block mesh record of {} bytes; its counts ({np} positions, {ni} indices, {na} appearance entries, {ns} styles) need {}",
            bytes.len(),
            words.map_or("more than memory holds".to_string(), |w| format!("{w} bytes"))
        ));
    }
    if ni % 3 != 0 || (na != 0 && na != np) {
        return Err(format!(
            "block mesh record with {ni} indices (not triangles) or {na} appearance entries for {np} positions"
        ));
    }
    let mut at = HEADER / 4;
    let mut next = || {
        let v = u32::from_le_bytes(bytes[4 * at..4 * at + 4].try_into().expect("4 bytes"));
        at += 1;
        v
    };
    let vec3s = |n: usize, next: &mut dyn FnMut() -> u32| -> Vec<glam::Vec3> {
        (0..n)
            .map(|_| {
                let (x, y, z) = (next(), next(), next());
                glam::Vec3::new(f32::from_bits(x), f32::from_bits(y), f32::from_bits(z))
            })
            .collect()
    };
    let positions = vec3s(np, &mut next);
    let normals = vec3s(np, &mut next);
    let indices: Vec<u32> = (0..ni).map(|_| next()).collect();
    if let Some(bad) = indices.iter().find(|&&i| i as usize >= np) {
        return Err(format!("index {bad} beyond the record's {np} positions"));
    }
    let appearance: Vec<VertexAppearance> = (0..na)
        .map(|_| VertexAppearance {
            u_m: f32::from_bits(next()),
            style: next(),
        })
        .collect();
    if let Some(bad) = appearance.iter().find(|a| a.style as usize >= ns) {
        return Err(format!(
            "style {} beyond the record's {ns} styles",
            bad.style
        ));
    }
    let mut styles = Vec::with_capacity(ns);
    for _ in 0..ns {
        let code = next();
        let kind = kind_of(code).ok_or_else(|| format!("unknown building kind {code}"))?;
        let mut f = || f32::from_bits(next());
        let facade = [f(), f(), f()];
        let window = [f(), f(), f()];
        let roof = [f(), f(), f()];
        let storey_height_m = f();
        let inv_storey_m = f();
        let levels = next();
        let mut f = || f32::from_bits(next());
        styles.push(BuildingStyle {
            kind,
            facade,
            window,
            roof,
            storey_height_m,
            inv_storey_m,
            levels,
            bay_m: f(),
            inv_bay_m: f(),
            window_half: f(),
            ground_z: f(),
        });
    }
    Ok(Mesh {
        positions,
        normals,
        indices,
        appearance,
        styles,
    })
}

/// Decodes a record as the pack stores it: inflated first when `compression` is `"zlib"`, to
/// at most `inflated` bytes (a stream that inflates to more, or to fewer, is refused).
///
/// # Errors
/// What is wrong with the bytes, in words.
pub fn decode_record(
    bytes: &[u8],
    compression: Option<&str>,
    inflated: u64,
) -> Result<Mesh, String> {
    match compression {
        None => decode_mesh(bytes),
        Some("zlib") => {
            use std::io::Read;
            let mut raw = Vec::with_capacity(inflated.min(1 << 30) as usize);
            flate2::read::ZlibDecoder::new(bytes)
                .take(inflated + 1)
                .read_to_end(&mut raw)
                .map_err(|e| format!("not a zlib stream: {e}"))?;
            if raw.len() as u64 != inflated {
                return Err(format!(
                    "inflates to {}{} bytes, the hierarchy says {inflated}",
                    if raw.len() as u64 > inflated {
                        "more than "
                    } else {
                        ""
                    },
                    raw.len().min(inflated as usize)
                ));
            }
            decode_mesh(&raw)
        }
        Some(other) => Err(format!("unknown compression {other:?}")),
    }
}

/// CRC-32 of `bytes` as 8 hex digits.
pub fn crc32_hex(bytes: &[u8]) -> String {
    format!("{:08x}", crc32fast::hash(bytes))
}

/// Writes the block meshes `meshes` (in order) as one pack of zlib records at `path`
/// (crash-safe) and returns each block's range; `None` for an empty mesh (nothing is written
/// for it).
///
/// # Errors
/// [`JobsError::Io`] naming the file.
pub fn write_pack<'a>(
    path: &Path,
    meshes: impl IntoIterator<Item = &'a Mesh>,
) -> Result<Vec<Option<ByteRange>>, JobsError> {
    let mut bytes = Vec::new();
    let mut ranges = Vec::new();
    for m in meshes {
        if m.indices.is_empty() {
            ranges.push(None);
            continue;
        }
        let start = bytes.len();
        let mut raw = Vec::new();
        encode_mesh(m, &mut raw);
        let mut z = flate2::write::ZlibEncoder::new(&mut bytes, flate2::Compression::new(6));
        std::io::Write::write_all(&mut z, &raw)
            .and_then(|_| z.finish().map(drop))
            .map_err(|source| JobsError::Io {
                file: path.to_path_buf(),
                source,
            })?;
        ranges.push(Some(ByteRange {
            offset: start as u64,
            bytes: (bytes.len() - start) as u64,
            crc32: crc32_hex(&bytes[start..]),
            inflated: raw.len() as u64,
        }));
    }
    crate::output::write_bytes(path, bytes)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| JobsError::Io {
            file: path.to_path_buf(),
            source,
        })?;
    Ok(ranges)
}

/// `tiles/tile_NNNNN.hier.json` beside the plan `plan_path`.
pub fn hierarchy_path(plan_path: &Path, tile: usize) -> PathBuf {
    super::tiles_dir(plan_path).join(format!("tile_{tile:05}.hier.json"))
}

impl TileHierarchy {
    /// Parses a hierarchy; `file` names it in errors.
    ///
    /// # Errors
    /// [`JobsError::Json`] for text that does not parse, [`JobsError::Format`] for another
    /// format or parents listed after their children.
    pub fn parse(text: &[u8], file: &Path) -> Result<Self, JobsError> {
        let h: TileHierarchy = serde_json::from_slice(text).map_err(|source| JobsError::Json {
            file: file.to_path_buf(),
            source,
        })?;
        if h.format != HIERARCHY_FORMAT {
            return Err(JobsError::Format {
                file: file.to_path_buf(),
                why: format!("format {:?}, expected {HIERARCHY_FORMAT:?}", h.format),
            });
        }
        if let Some(c) = h.compression.as_deref().filter(|c| *c != "zlib") {
            return Err(JobsError::Format {
                file: file.to_path_buf(),
                why: format!("records compressed as {c:?}: this blockwalk reads raw and zlib"),
            });
        }
        if let Some((i, p)) = h
            .maps
            .iter()
            .enumerate()
            .find_map(|(i, m)| m.parent.filter(|&p| p >= i).map(|p| (i, p)))
        {
            return Err(JobsError::Format {
                file: file.to_path_buf(),
                why: format!("map {i} has parent {p}, which does not come before it"),
            });
        }
        Ok(h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::appearance::BuildingStyle;

    fn mesh() -> Mesh {
        let mut m = Mesh {
            positions: vec![
                glam::Vec3::new(1.0, 2.0, 3.0),
                glam::Vec3::new(-1.5, 0.25, 9.0),
                glam::Vec3::new(f32::MIN_POSITIVE, 7.0, -0.0),
            ],
            normals: vec![glam::Vec3::Z; 3],
            indices: vec![0, 1, 2],
            appearance: Vec::new(),
            styles: Vec::new(),
        };
        let mut styled = m.clone();
        styled
            .styles
            .push(BuildingStyle::flat([0.1, 0.2, 0.3], [0.4, 0.5, 0.6]));
        styled.appearance = vec![VertexAppearance { u_m: 3.5, style: 0 }; 3];
        m.append(&styled);
        m
    }

    #[test]
    fn a_record_decodes_to_the_mesh_written_bit_for_bit() {
        let m = mesh();
        let mut bytes = Vec::new();
        encode_mesh(&m, &mut bytes);
        let back = decode_mesh(&bytes).unwrap();
        assert_eq!(back.positions.len(), 6);
        let bits = |m: &Mesh| -> Vec<u32> {
            m.positions
                .iter()
                .chain(&m.normals)
                .flat_map(|v| v.to_array().map(f32::to_bits))
                .collect()
        };
        assert_eq!(bits(&back), bits(&m));
        assert_eq!(back.indices, m.indices);
        assert_eq!(back.appearance, m.appearance);
        assert_eq!(back.styles, m.styles);
    }

    #[test]
    fn a_pack_of_zlib_records_decodes_and_refuses_a_wrong_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.pack");
        let m = mesh();
        let ranges = write_pack(&path, [&m, &Mesh::default(), &m]).unwrap();
        assert!(ranges[1].is_none(), "an empty mesh has no record");
        let bytes = std::fs::read(&path).unwrap();
        let r = ranges[2].as_ref().unwrap();
        let rec = &bytes[r.offset as usize..(r.offset + r.bytes) as usize];
        assert_eq!(crc32_hex(rec), r.crc32);
        let back = decode_record(rec, Some("zlib"), r.inflated).unwrap();
        assert_eq!(back.indices, m.indices);
        assert!(decode_record(rec, Some("zlib"), r.inflated - 1).is_err());
        assert!(decode_record(rec, Some("zlib"), r.inflated + 1).is_err());
        assert!(
            decode_record(rec, None, r.inflated).is_err(),
            "a zlib stream is no raw record"
        );
        assert!(decode_record(&rec[..rec.len() / 2], Some("zlib"), r.inflated).is_err());
        assert!(decode_record(rec, Some("zstd"), r.inflated).is_err());
    }

    #[test]
    fn every_truncation_and_a_bad_index_are_refused() {
        let mut bytes = Vec::new();
        encode_mesh(&mesh(), &mut bytes);
        for n in 0..bytes.len() {
            assert!(decode_mesh(&bytes[..n]).is_err(), "{n} bytes");
        }
        // The first index (after the header, positions and normals) set beyond the positions.
        let at = HEADER + 6 * 4 * 6;
        bytes[at..at + 4].copy_from_slice(&99u32.to_le_bytes());
        let e = decode_mesh(&bytes).unwrap_err();
        assert!(e.contains("index 99"), "{e}");
    }
}
