//! Robustness checks of the readers against arbitrary bytes, shared by the `cargo fuzz` targets
//! (`tests/fuzz/`) and the stable tests that replay their findings.
//!
//! Each `check_*` function feeds one input through one reader the way a user's file would go
//! through it, and asserts the properties every reader promises:
//!
//! - a file that cannot be read is an [`ImportError`] whose message names the file;
//! - a layer that is read accounts for every feature: `imported + refused == read`,
//!   `imported == features.len()`, the grouped refusals add up to the refusals;
//! - readers that have two paths to the same features agree (the Shapefile reader and its
//!   streaming twin give the same feature ids and refusals).
//!
//! A broken property panics (that is what a fuzzer reports); anything else returns an
//! [`Outcome`] saying what happened. Nothing here panics on bad input by itself.

use std::path::{Path, PathBuf};

use crate::{geojson_reader, shp, Crs, ImportError, Layer, Theme};

/// What one check saw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The input was read: `features` imported, `refused` refused.
    Read {
        /// Features imported.
        features: usize,
        /// Features refused.
        refused: usize,
    },
    /// The input was refused as a whole, with this message.
    Refused(String),
}

/// Splits `data` into `n` parts: each of the first `n - 1` parts is preceded by its length as a
/// little-endian `u32` (cut to what is left), the last part is the rest. Missing bytes give empty
/// parts. [`join_parts`] is its inverse.
pub fn split_parts(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut rest = data;
    let mut out = Vec::with_capacity(n);
    for _ in 1..n {
        let (len, tail) = match rest.split_first_chunk::<4>() {
            Some((head, tail)) => (u32::from_le_bytes(*head) as usize, tail),
            None => (0, &[][..]),
        };
        let len = len.min(tail.len());
        out.push(&tail[..len]);
        rest = &tail[len..];
    }
    out.push(rest);
    out
}

/// Joins parts into one input that [`split_parts`] splits back.
///
/// # Panics
/// When a part other than the last is 4 GiB or more.
pub fn join_parts(parts: &[&[u8]]) -> Vec<u8> {
    let mut out = Vec::new();
    for (i, p) in parts.iter().enumerate() {
        if i + 1 < parts.len() {
            let len = u32::try_from(p.len()).expect("part under 4 GiB");
            out.extend_from_slice(&len.to_le_bytes());
        }
        out.extend_from_slice(p);
    }
    out
}

/// Asserts that a layer accounts for every feature it read.
///
/// # Panics
/// When it does not.
pub fn assert_accounted(l: &Layer) {
    let r = &l.report;
    assert_eq!(
        r.imported,
        l.features.len(),
        "{}: report says {} imported, layer holds {} features",
        l.source.display(),
        r.imported,
        l.features.len()
    );
    assert_eq!(
        r.imported + r.refused.len(),
        r.read,
        "{}: {} imported + {} refused != {} read",
        l.source.display(),
        r.imported,
        r.refused.len(),
        r.read
    );
    let grouped: usize = r.refused_by_reason.iter().map(|g| g.count).sum();
    assert_eq!(
        grouped,
        r.refused.len(),
        "{}: refusals grouped by reason do not add up",
        l.source.display()
    );
    for f in &r.refused {
        assert!(
            !f.reason.trim().is_empty(),
            "refusal of {} has no reason",
            f.fid
        );
    }
}

/// The outcome of a read, checking the layer or the error.
fn outcome(file: &Path, read: Result<Layer, ImportError>) -> Outcome {
    match read {
        Ok(l) => {
            assert_accounted(&l);
            Outcome::Read {
                features: l.features.len(),
                refused: l.report.refused.len(),
            }
        }
        Err(e) => {
            // The file named may be a companion of `file` (`layer.dbf` beside `layer.shp`).
            let msg = e.to_string();
            let stem = file.with_extension("");
            assert!(
                msg.contains(&*stem.to_string_lossy()),
                "error does not name a file of the input {}: {msg}",
                file.display()
            );
            Outcome::Refused(msg)
        }
    }
}

fn write(path: &Path, bytes: &[u8]) -> PathBuf {
    std::fs::write(path, bytes)
        .unwrap_or_else(|e| panic!("cannot write the fuzz input {}: {e}", path.display()));
    path.to_path_buf()
}

fn write_or_remove(path: &Path, bytes: &[u8]) {
    if bytes.is_empty() {
        match std::fs::remove_file(path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => panic!("cannot remove {}: {e}", path.display()),
        }
    } else {
        write(path, bytes);
    }
}

/// The Shapefile parts of one input, in [`split_parts`] order.
pub const SHAPEFILE_PARTS: [&str; 4] = ["shp", "shx", "dbf", "prj"];

/// A Shapefile from one input: `.shp`, `.shx`, `.dbf` and `.prj` split by [`split_parts`] (an
/// empty `.shx`, `.dbf` or `.prj` part means the file is absent), written into `dir` and read
/// with [`shp::read`] and [`shp::read_streaming`]. Both must agree.
///
/// # Panics
/// When a property breaks (see the module doc) or `dir` cannot be written.
pub fn check_shapefile(dir: &Path, data: &[u8]) -> Outcome {
    let parts = split_parts(data, SHAPEFILE_PARTS.len());
    let base = dir.join("layer");
    for (ext, bytes) in SHAPEFILE_PARTS.iter().zip(&parts) {
        let p = base.with_extension(ext);
        if *ext == "shp" {
            write(&p, bytes);
        } else {
            write_or_remove(&p, bytes);
        }
    }
    let path = base.with_extension("shp");
    let whole = shp::read(&path);
    let mut chunks: Vec<Layer> = Vec::new();
    let streamed = shp::read_streaming(&path, &mut |_, _| true, 7, &mut |l| chunks.push(l));
    if let Ok(l) = &whole {
        let n = streamed.as_ref().unwrap_or_else(|e| {
            panic!("read gave a layer, read_streaming the error {e}");
        });
        assert_eq!(*n, l.report.read, "records counted differently");
        let fids: Vec<u64> = chunks
            .iter()
            .flat_map(|c| c.features.iter().map(|f| f.fid))
            .collect();
        let want: Vec<u64> = l.features.iter().map(|f| f.fid).collect();
        assert_eq!(fids, want, "streamed features differ from read's");
        let refused: Vec<u64> = chunks
            .iter()
            .flat_map(|c| c.report.refused.iter().map(|r| r.fid))
            .collect();
        let want: Vec<u64> = l.report.refused.iter().map(|r| r.fid).collect();
        assert_eq!(refused, want, "streamed refusals differ from read's");
        for c in &chunks {
            assert_accounted(c);
        }
    }
    outcome(&path, whole)
}

/// A GeoJSON file of these bytes, read with [`geojson_reader::read`].
///
/// # Panics
/// When a property breaks.
pub fn check_geojson(dir: &Path, data: &[u8]) -> Outcome {
    let path = write(&dir.join("layer.geojson"), data);
    outcome(&path, geojson_reader::read(&path))
}

/// A GeoPackage of these bytes, read for every theme.
///
/// # Panics
/// When a property breaks.
#[cfg(feature = "gpkg")]
pub fn check_gpkg(dir: &Path, data: &[u8]) -> Vec<Outcome> {
    let path = write(&dir.join("layer.gpkg"), data);
    // SQLite may leave a journal beside a file it could not finish with.
    for side in ["layer.gpkg-journal", "layer.gpkg-wal", "layer.gpkg-shm"] {
        let _ = std::fs::remove_file(dir.join(side));
    }
    let mut out = Vec::new();
    if let Err(e) = crate::gpkg::feature_tables(&path) {
        out.push(outcome(&path, Err(e)));
    }
    for theme in [Theme::Any, Theme::Buildings, Theme::Streets] {
        out.push(outcome(&path, crate::gpkg::read(&path, &theme)));
    }
    out
}

/// An OSM PBF file of these bytes, read for buildings and for streets.
///
/// # Panics
/// When a property breaks.
#[cfg(feature = "osm")]
pub fn check_osm(dir: &Path, data: &[u8]) -> Vec<Outcome> {
    let path = write(&dir.join("layer.osm.pbf"), data);
    [Theme::Buildings, Theme::Streets]
        .iter()
        .map(|t| outcome(&path, crate::osm::read(&path, t)))
        .collect()
}

/// A GeoPackage geometry blob, and the same bytes as plain WKB: decoded or refused with a
/// message, never a panic; a decoded geometry holds at most two coordinates per 16 bytes of
/// input (a point and the copy that closes its ring), so that counts in the bytes cannot make
/// it allocate more than the input justifies.
///
/// # Panics
/// When a property breaks.
#[cfg(feature = "gpkg")]
pub fn check_wkb(data: &[u8]) -> Outcome {
    let mut last = Outcome::Refused(String::new());
    for r in [
        crate::wkb::decode_gpkg(data).map(|g| g.geometry),
        crate::wkb::decode_wkb(data),
    ] {
        last = match r {
            Ok(g) => {
                let n = g.as_ref().map_or(0, coords_count);
                // Two per 16 bytes: a point, and the copy that closes a ring left open.
                assert!(
                    n <= 2 * (data.len() / 16),
                    "{n} coordinates from {} bytes",
                    data.len()
                );
                Outcome::Read {
                    features: usize::from(g.is_some()),
                    refused: 0,
                }
            }
            Err(msg) => {
                assert!(!msg.is_empty(), "empty WKB error");
                Outcome::Refused(msg)
            }
        };
    }
    last
}

/// Number of coordinates in a geometry.
#[cfg(feature = "gpkg")]
fn coords_count(g: &geo_types::Geometry<f64>) -> usize {
    use geo_types::Geometry as G;
    let ring = |l: &geo_types::LineString<f64>| l.0.len();
    let poly = |p: &geo_types::Polygon<f64>| {
        ring(p.exterior()) + p.interiors().iter().map(ring).sum::<usize>()
    };
    match g {
        G::Point(_) => 1,
        G::Line(_) => 2,
        G::LineString(l) => ring(l),
        G::Polygon(p) => poly(p),
        G::MultiPoint(m) => m.0.len(),
        G::MultiLineString(m) => m.0.iter().map(ring).sum(),
        G::MultiPolygon(m) => m.0.iter().map(poly).sum(),
        G::GeometryCollection(c) => c.0.iter().map(coords_count).sum(),
        G::Rect(_) => 4,
        G::Triangle(_) => 3,
    }
}

/// A `.prj` WKT: recognised or refused with a message. A CRS that is recognised must set up its
/// metric transform (the readers promise that every CRS they return does), for data centred
/// anywhere, and checking or transforming coordinates must not panic.
///
/// # Panics
/// When a property breaks.
pub fn check_prj(data: &[u8]) -> Outcome {
    let text = String::from_utf8_lossy(data);
    match Crs::from_wkt(&text) {
        Ok(crs) => {
            assert!(!crs.describe().is_empty(), "a CRS without a description");
            for centre in [
                [0.0, 0.0],
                [500_000.0, 6_000_000.0],
                [14.4, 50.1],
                [f64::NAN, 1e300],
            ] {
                let t = crs.try_metric_transform(centre).unwrap_or_else(|e| {
                    panic!(
                        "{} was recognised but its metric transform fails: {e}",
                        crs.describe()
                    )
                });
                for p in [centre, [1.0, 1.0], [-1e7, 1e7]] {
                    let _ = t.check(p);
                    if let Ok(m) = t.try_to_metric(p) {
                        let _ = t.from_metric(m);
                    }
                }
            }
            Outcome::Read {
                features: 1,
                refused: 0,
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.is_empty(), "empty CRS error");
            Outcome::Refused(msg)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_split_back_as_joined() {
        let parts: [&[u8]; 4] = [b"abc", b"", b"0123456789", b"tail"];
        let joined = join_parts(&parts);
        assert_eq!(split_parts(&joined, 4), parts);
        // Short or oversized length prefixes give empty or truncated parts, never a panic.
        assert_eq!(
            split_parts(b"\xff\xff\xff\xffab", 3),
            [&b"ab"[..], b"", b""]
        );
        assert_eq!(split_parts(b"\x01", 2), [&b""[..], b""]);
    }
}
