//! OpenStreetMap PBF reader (the `osmpbf` crate), by theme.
//!
//! Two passes over the file: the first keeps the relations of interest and the ids of their
//! member ways; the second stores every node's coordinates (a `HashMap` by id) and the ways of
//! interest. Coordinates are WGS84 longitude/latitude ([`Crs::Geographic`], EPSG:4326).
//!
//! - [`Theme::Buildings`] (also [`Theme::Any`]): closed ways tagged `building=*` (not
//!   `building=no`) → `Polygon`; relations with a `building` tag and `type=multipolygon` (or
//!   `type=building`) → `Polygon` when they make one polygon, else `MultiPolygon`. Member ways with
//!   role `outer` (or no role) and `inner` are joined end to end into rings (reversing ways as
//!   needed); each inner ring goes into the outer ring that contains it.
//!   A building way that is also an outer member of a building relation is read only as part of
//!   the relation (a note counts them), so a building is not counted twice.
//! - [`Theme::Streets`]: ways tagged `highway=*` → `LineString`.
//! - Attributes: every tag as text, plus `osm_id` (integer) and `osm_type` (`way`/`relation`).
//!   [`Feature::fid`] is the OSM id.
//! - Refused, with the reason: ways or relations that reference nodes or member ways missing from
//!   the extract (typically cut by the extract's bounding box: "N of M nodes missing from the
//!   extract"), building ways that are not closed, rings that cannot be closed, and geometry
//!   with too few nodes. Nothing is guessed back.

use crate::crs::Crs;
use crate::rings;
use crate::{AttrValue, Attributes, Feature, ImportError, ImportReport, Layer, Theme};
use geo_types::{Coord, Geometry, LineString, MultiPolygon};
use osmpbf::{Element, ElementReader, RelMemberType};
use std::collections::{HashMap, HashSet};
use std::path::Path;

type Tags = Vec<(String, String)>;

struct Way {
    id: i64,
    refs: Vec<i64>,
    tags: Tags,
}

struct Relation {
    id: i64,
    tags: Tags,
    /// (way id, is inner)
    members: Vec<(i64, bool)>,
    /// Members that are not ways (nodes, relations), ignored.
    other_members: usize,
}

fn tag<'a>(tags: &'a Tags, key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

fn is_building(tags: &Tags) -> bool {
    matches!(tag(tags, "building"), Some(v) if v != "no")
}

fn is_building_relation(tags: &Tags) -> bool {
    is_building(tags) && matches!(tag(tags, "type"), Some("multipolygon") | Some("building"))
}

fn collect_tags<'a>(it: impl Iterator<Item = (&'a str, &'a str)>) -> Tags {
    it.map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

/// Runs one pass of the decoder over `path`. A panic inside `osmpbf` (its coordinate
/// arithmetic overflows on crafted offsets and granularities when overflow checks are on) ends
/// the read with [`ImportError::Format`] naming the file, not the process.
fn decoding(
    path: &Path,
    pass: impl FnOnce() -> Result<(), ImportError>,
) -> Result<(), ImportError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(pass)).unwrap_or_else(|p| {
        let what = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".into());
        Err(ImportError::Format {
            file: path.to_path_buf(),
            message: format!("the OSM PBF decoder failed ({what}): the file is corrupt"),
        })
    })
}

/// Reads one theme of an OSM PBF file.
///
/// # Errors
/// [`ImportError::Io`] when the file cannot be opened, [`ImportError::Empty`] /
/// [`ImportError::Truncated`] / [`ImportError::Format`] when its blob framing is empty, cut short
/// or not PBF, [`ImportError::Pbf`] when `osmpbf` cannot decode it, [`ImportError::Unsupported`] for the themes an OSM file has no answer for
/// (`Parcels`, `Table`).
pub fn read(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    let buildings = match theme {
        Theme::Buildings | Theme::Any => true,
        Theme::Streets => false,
        other => {
            return Err(ImportError::Unsupported {
                file: path.to_path_buf(),
                message: format!("an OSM file has no {other:?} theme (use Buildings or Streets)"),
            })
        }
    };
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    check_framing(path, &bytes)?;
    drop(bytes);
    let format = |source: osmpbf::Error| ImportError::Pbf {
        file: path.to_path_buf(),
        source,
    };
    let open = || ElementReader::from_path(path).map_err(format);

    // Pass 1: relations of interest.
    let mut relations = Vec::new();
    if buildings {
        decoding(path, || {
            open()?
                .for_each(|e| {
                    if let Element::Relation(r) = e {
                        let tags = collect_tags(r.tags());
                        if is_building_relation(&tags) {
                            let mut members = Vec::new();
                            let mut other_members = 0;
                            for m in r.members() {
                                match m.member_type {
                                    RelMemberType::Way => {
                                        let inner = m.role().map(|s| s == "inner").unwrap_or(false);
                                        members.push((m.member_id, inner));
                                    }
                                    _ => other_members += 1,
                                }
                            }
                            relations.push(Relation {
                                id: r.id(),
                                tags,
                                members,
                                other_members,
                            });
                        }
                    }
                })
                .map_err(format)
        })?;
    }
    let member_ways: HashSet<i64> = relations
        .iter()
        .flat_map(|r| r.members.iter().map(|m| m.0))
        .collect();
    let outer_members: HashSet<i64> = relations
        .iter()
        .flat_map(|r| r.members.iter().filter(|m| !m.1).map(|m| m.0))
        .collect();
    let mut skipped_outer = 0usize;

    // Pass 2: nodes and ways.
    let mut nodes: HashMap<i64, (f64, f64)> = HashMap::new();
    let mut ways: Vec<Way> = Vec::new();
    let mut member_refs: HashMap<i64, Vec<i64>> = HashMap::new();
    decoding(path, || {
        open()?
            .for_each(|e| match e {
                Element::Node(n) => {
                    nodes.insert(n.id(), (n.lon(), n.lat()));
                }
                Element::DenseNode(n) => {
                    nodes.insert(n.id(), (n.lon(), n.lat()));
                }
                Element::Way(w) => {
                    let id = w.id();
                    let wanted = {
                        let mut t = w.tags();
                        if buildings {
                            t.any(|(k, v)| k == "building" && v != "no")
                        } else {
                            t.any(|(k, _)| k == "highway")
                        }
                    };
                    // A building way that is an outer ring of a building relation is that
                    // relation's building, read with it: not a second building.
                    let wanted = if wanted && buildings && outer_members.contains(&id) {
                        skipped_outer += 1;
                        false
                    } else {
                        wanted
                    };
                    if wanted {
                        ways.push(Way {
                            id,
                            refs: w.refs().collect(),
                            tags: collect_tags(w.tags()),
                        });
                    }
                    if member_ways.contains(&id) {
                        member_refs.insert(id, w.refs().collect());
                    }
                }
                Element::Relation(_) => {}
            })
            .map_err(format)
    })?;

    let mut report = ImportReport::default();
    let mut features = Vec::new();
    report.read = ways.len() + relations.len();
    for w in &ways {
        let fid = w.id.max(0) as u64;
        match way_geometry(w, &nodes, buildings) {
            Ok(geometry) => features.push(Feature {
                fid,
                geometry,
                attributes: attributes(&w.tags, w.id, "way"),
            }),
            Err(reason) => report.refuse(fid, format!("way {}: {reason}", w.id)),
        }
    }
    for r in &relations {
        let fid = r.id.max(0) as u64;
        match relation_geometry(r, &member_refs, &nodes, &mut report) {
            Ok(geometry) => features.push(Feature {
                fid,
                geometry,
                attributes: attributes(&r.tags, r.id, "relation"),
            }),
            Err(reason) => report.refuse(fid, format!("relation {}: {reason}", r.id)),
        }
    }
    report.imported = features.len();
    report.group_refusals();
    if skipped_outer > 0 {
        report.notes.push(format!(
            "{skipped_outer} building ways are outer rings of building relations and were read \
             as part of those relations, not as separate buildings"
        ));
    }
    report.notes.push(format!(
        "OSM {}: {} ways and {} relations selected, {} nodes in the extract; WGS84 lon/lat",
        if buildings { "buildings" } else { "streets" },
        ways.len(),
        relations.len(),
        nodes.len()
    ));
    let stem = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = stem
        .trim_end_matches(".pbf")
        .trim_end_matches(".osm")
        .to_string();
    Ok(Layer {
        name: format!("{stem} {}", if buildings { "buildings" } else { "streets" }),
        source: path.to_path_buf(),
        crs: Crs::Geographic { epsg: Some(4326) },
        features,
        report,
    })
}

/// The largest BlobHeader the format allows (OSM PBF specification: 64 KiB).
const MAX_BLOB_HEADER: usize = 64 * 1024;
/// The largest Blob the format allows (32 MiB).
const MAX_BLOB: usize = 32 * 1024 * 1024;

/// Reads a protobuf varint at `*pos`.
fn varint(b: &[u8], pos: &mut usize) -> Option<u64> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let byte = *b.get(*pos)?;
        *pos += 1;
        v |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// The `type` (field 1) and `datasize` (field 3) of a BlobHeader message.
fn blob_header(b: &[u8]) -> Option<(String, usize)> {
    let (mut pos, mut ty, mut size) = (0, None, None);
    while pos < b.len() {
        let key = varint(b, &mut pos)?;
        match (key >> 3, key & 7) {
            (3, 0) => size = Some(usize::try_from(varint(b, &mut pos)?).ok()?),
            (_, 0) => {
                varint(b, &mut pos)?;
            }
            (field, 2) => {
                let len = usize::try_from(varint(b, &mut pos)?).ok()?;
                let end = pos.checked_add(len).filter(|&e| e <= b.len())?;
                if field == 1 {
                    ty = Some(String::from_utf8_lossy(&b[pos..end]).into_owned());
                }
                pos = end;
            }
            _ => return None,
        }
    }
    Some((ty?, size?))
}

/// Checks the file's blob framing (OSM PBF: a 4-byte big-endian header length, a BlobHeader, a
/// Blob of the declared size, repeated to the end of the file) before `osmpbf` reads it: an
/// empty file, a file cut inside a blob, or one without an `OSMHeader` first and an `OSMData`
/// blob is an error, not an empty layer.
fn check_framing(path: &Path, bytes: &[u8]) -> Result<(), ImportError> {
    let file = || path.to_path_buf();
    if bytes.is_empty() {
        return Err(ImportError::Empty {
            file: file(),
            what: "an OSM PBF file starts with an OSMHeader blob".into(),
        });
    }
    let (mut pos, mut k, mut data_blobs) = (0usize, 0usize, 0usize);
    while pos < bytes.len() {
        let Some(len) = bytes.get(pos..pos + 4) else {
            return Err(ImportError::Truncated {
                file: file(),
                what: format!(
                    "blob {k} at byte {pos}: {} byte(s) left, a header length needs 4",
                    bytes.len() - pos
                ),
            });
        };
        let hlen = u32::from_be_bytes([len[0], len[1], len[2], len[3]]) as usize;
        pos += 4;
        if hlen == 0 || hlen > MAX_BLOB_HEADER {
            return Err(ImportError::Format {
                file: file(),
                message: format!(
                    "blob {k} at byte {}: header length {hlen} is not a PBF blob header",
                    pos - 4
                ),
            });
        }
        let Some(h) = bytes.get(pos..pos + hlen) else {
            return Err(ImportError::Truncated {
                file: file(),
                what: format!(
                    "blob {k} at byte {}: header of {hlen} bytes, {} left",
                    pos - 4,
                    bytes.len() - pos
                ),
            });
        };
        let Some((ty, size)) = blob_header(h).filter(|(_, s)| *s <= MAX_BLOB) else {
            return Err(ImportError::Format {
                file: file(),
                message: format!("blob {k} at byte {}: unreadable blob header", pos - 4),
            });
        };
        pos += hlen;
        if bytes.len() - pos < size {
            return Err(ImportError::Truncated {
                file: file(),
                what: format!(
                    "blob {k} ({ty}) declares {size} bytes, only {} are left",
                    bytes.len() - pos
                ),
            });
        }
        if k == 0 && ty != "OSMHeader" {
            return Err(ImportError::Format {
                file: file(),
                message: format!("the first blob is {ty:?}, not OSMHeader"),
            });
        }
        if ty == "OSMData" {
            data_blobs += 1;
        }
        pos += size;
        k += 1;
    }
    if data_blobs == 0 {
        return Err(ImportError::Empty {
            file: file(),
            what: "an OSMHeader but no OSMData blob".into(),
        });
    }
    Ok(())
}

fn attributes(tags: &Tags, id: i64, kind: &str) -> Attributes {
    let mut a: Attributes = tags
        .iter()
        .map(|(k, v)| (k.clone(), AttrValue::Text(v.clone())))
        .collect();
    a.insert("osm_id".into(), AttrValue::Int(id));
    a.insert("osm_type".into(), AttrValue::Text(kind.into()));
    a
}

/// Node coordinates of a way, or the count of missing nodes.
fn resolve(refs: &[i64], nodes: &HashMap<i64, (f64, f64)>) -> Result<Vec<Coord<f64>>, String> {
    let coords: Vec<Coord<f64>> = refs
        .iter()
        .filter_map(|r| nodes.get(r).map(|&(x, y)| Coord { x, y }))
        .collect();
    if coords.len() < refs.len() {
        return Err(format!(
            "{} of {} nodes missing from the extract",
            refs.len() - coords.len(),
            refs.len()
        ));
    }
    if let Some(k) = rings::first_non_finite(&coords) {
        return Err(format!("non-finite coordinate at node {}", refs[k]));
    }
    Ok(coords)
}

fn way_geometry(
    w: &Way,
    nodes: &HashMap<i64, (f64, f64)>,
    building: bool,
) -> Result<Geometry<f64>, String> {
    if w.refs.is_empty() {
        return Err("no nodes".into());
    }
    let coords = resolve(&w.refs, nodes)?;
    if building {
        if w.refs.first() != w.refs.last() {
            return Err(format!(
                "building way is not closed ({} nodes, first and last differ)",
                w.refs.len()
            ));
        }
        if w.refs.len() < 4 {
            return Err(format!(
                "closed way has {} nodes, a ring needs at least 4",
                w.refs.len()
            ));
        }
        Ok(Geometry::Polygon(geo_types::Polygon::new(
            LineString::new(coords),
            vec![],
        )))
    } else {
        if coords.len() < 2 {
            return Err("a street way needs at least 2 nodes".into());
        }
        Ok(Geometry::LineString(LineString::new(coords)))
    }
}

/// Joins way node sequences end to end into closed rings (of node ids).
fn join_rings(mut parts: Vec<Vec<i64>>) -> Result<Vec<Vec<i64>>, String> {
    let mut rings = Vec::new();
    parts.retain(|p| !p.is_empty());
    while let Some(mut ring) = parts.pop() {
        loop {
            if ring.len() >= 4 && ring.first() == ring.last() {
                rings.push(ring);
                break;
            }
            let end = *ring.last().expect("non-empty");
            let next = parts
                .iter()
                .position(|p| p.first() == Some(&end) || p.last() == Some(&end));
            match next {
                Some(i) => {
                    let mut p = parts.swap_remove(i);
                    if p.first() != Some(&end) {
                        p.reverse();
                    }
                    ring.extend_from_slice(&p[1..]);
                }
                None => {
                    return Err(format!(
                        "a ring cannot be closed: open chain of {} nodes from node {} to node {}",
                        ring.len(),
                        ring[0],
                        end
                    ))
                }
            }
        }
    }
    Ok(rings)
}

fn relation_geometry(
    r: &Relation,
    member_refs: &HashMap<i64, Vec<i64>>,
    nodes: &HashMap<i64, (f64, f64)>,
    report: &mut ImportReport,
) -> Result<Geometry<f64>, String> {
    if r.members.is_empty() {
        return Err(format!(
            "no member ways ({} other members)",
            r.other_members
        ));
    }
    let missing = r
        .members
        .iter()
        .filter(|(id, _)| !member_refs.contains_key(id))
        .count();
    if missing > 0 {
        return Err(format!(
            "{missing} of {} member ways missing from the extract",
            r.members.len()
        ));
    }
    let (mut outer, mut inner) = (Vec::new(), Vec::new());
    for (id, is_inner) in &r.members {
        let refs = member_refs[id].clone();
        if *is_inner {
            inner.push(refs);
        } else {
            outer.push(refs);
        }
    }
    let all: Vec<i64> = outer.iter().chain(&inner).flatten().copied().collect();
    resolve(&all, nodes)?;
    let to_coords = |ring: Vec<i64>| resolve(&ring, nodes);
    let outer = join_rings(outer)?
        .into_iter()
        .map(to_coords)
        .collect::<Result<Vec<_>, _>>()?;
    let inner = join_rings(inner)?
        .into_iter()
        .map(to_coords)
        .collect::<Result<Vec<_>, _>>()?;
    if outer.is_empty() {
        return Err("no outer ring".into());
    }
    let a = rings::assemble(outer, inner);
    if !a.orphan_holes.is_empty() {
        report.notes.push(format!(
            "relation {}: {} inner ring(s) lie in no outer ring; each was kept as a polygon of \
             its own",
            r.id,
            a.orphan_holes.len()
        ));
    }
    let mut polys = a.polygons;
    if polys.len() == 1 {
        Ok(Geometry::Polygon(polys.pop().expect("one polygon")))
    } else {
        Ok(Geometry::MultiPolygon(MultiPolygon(polys)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rings_join_with_reversal_and_fail_when_open() {
        let r = join_rings(vec![vec![1, 2, 3], vec![5, 4, 3], vec![5, 6, 1]]).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].first(), r[0].last());
        assert_eq!(r[0].len(), 7);
        let mut s = r[0].clone();
        s.sort();
        s.dedup();
        assert_eq!(s, vec![1, 2, 3, 4, 5, 6]);
        let e = join_rings(vec![vec![1, 2, 3], vec![3, 4]]).unwrap_err();
        assert!(e.contains("cannot be closed"));
        let two = join_rings(vec![vec![1, 2, 3, 1], vec![7, 8, 9, 7]]).unwrap();
        assert_eq!(two.len(), 2);
    }
}
