//! Well-Known Binary (OGC 06-103r4 §8): the decoder of GeoPackage geometry blobs (the `GP`
//! header, GeoPackage 1.3 §2.1.3, followed by WKB) and of plain WKB, both byte orders, ISO
//! (1000/2000/3000 + type) and EWKB (high-bit flags) Z/M type codes, Z and M values read and
//! dropped; and the encoder of 2D geometry to little-endian WKB ([`encode_wkb`]), for callers that
//! hand geometry to other GIS software (Python's shapely reads it with `from_wkb`).

use geo_types::{
    Coord, Geometry, GeometryCollection, LineString, MultiLineString, MultiPoint, MultiPolygon,
    Point, Polygon,
};

/// Deepest nesting of geometry collections accepted.
const MAX_DEPTH: usize = 32;

/// A decoded GeoPackage geometry blob.
#[derive(Debug)]
pub struct GpGeometry {
    /// The `srs_id` in the header.
    pub srs_id: i32,
    /// `None` when the header's empty flag is set or the WKB is an empty geometry.
    pub geometry: Option<Geometry<f64>>,
}

/// Decodes a GeoPackage binary geometry.
///
/// # Errors
/// What is wrong with the blob, in words (never a panic: the decoder is fuzzed).
pub fn decode_gpkg(blob: &[u8]) -> Result<GpGeometry, String> {
    if blob.len() < 8 || &blob[0..2] != b"GP" {
        return Err("not a GeoPackage geometry blob (no `GP` magic)".into());
    }
    let version = blob[2];
    if version != 0 {
        return Err(format!("unsupported GeoPackage geometry version {version}"));
    }
    let flags = blob[3];
    if flags & 0x20 != 0 {
        return Err("extended GeoPackage geometry types are not supported".into());
    }
    let empty = flags & 0x10 != 0;
    let env_size = match (flags >> 1) & 0x07 {
        0 => 0,
        1 => 32,
        2 | 3 => 48,
        4 => 64,
        e => return Err(format!("invalid envelope indicator {e}")),
    };
    let le = flags & 0x01 != 0;
    let srs_bytes = [blob[4], blob[5], blob[6], blob[7]];
    let srs_id = if le {
        i32::from_le_bytes(srs_bytes)
    } else {
        i32::from_be_bytes(srs_bytes)
    };
    let start = 8 + env_size;
    if blob.len() < start {
        return Err("geometry blob shorter than its header".into());
    }
    if empty {
        return Ok(GpGeometry {
            srs_id,
            geometry: None,
        });
    }
    let mut r = Reader {
        b: &blob[start..],
        pos: 0,
    };
    let g = read_geometry(&mut r, 0)?;
    Ok(GpGeometry {
        srs_id,
        geometry: g,
    })
}

/// Decodes plain WKB. `Ok(None)` for an empty geometry.
///
/// # Errors
/// What is wrong with the bytes, in words (never a panic: the decoder is fuzzed).
pub fn decode_wkb(bytes: &[u8]) -> Result<Option<Geometry<f64>>, String> {
    let mut r = Reader { b: bytes, pos: 0 };
    read_geometry(&mut r, 0)
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let end = self.pos.checked_add(N).filter(|&e| e <= self.b.len());
        let Some(end) = end else {
            return Err(format!("WKB truncated at byte {}", self.pos));
        };
        let mut a = [0u8; N];
        a.copy_from_slice(&self.b[self.pos..end]);
        self.pos = end;
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take::<1>()?[0])
    }
    fn u32(&mut self, le: bool) -> Result<u32, String> {
        let a = self.take::<4>()?;
        Ok(if le {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        })
    }
    fn f64(&mut self, le: bool) -> Result<f64, String> {
        let a = self.take::<8>()?;
        Ok(if le {
            f64::from_le_bytes(a)
        } else {
            f64::from_be_bytes(a)
        })
    }
    fn remaining(&self) -> usize {
        self.b.len() - self.pos
    }
    /// A count, checked against the bytes left (each item takes at least `min_size` bytes) so
    /// that a corrupt count cannot ask for a huge allocation.
    fn count(&mut self, le: bool, min_size: usize) -> Result<usize, String> {
        let n = self.u32(le)? as usize;
        if n.saturating_mul(min_size) > self.remaining() {
            return Err(format!(
                "WKB truncated or corrupt: a count of {n} needs at least {} bytes, {} are left",
                n.saturating_mul(min_size),
                self.remaining()
            ));
        }
        Ok(n)
    }
}

struct Header {
    le: bool,
    base: u32,
    dims: usize,
}

fn read_header(r: &mut Reader) -> Result<Header, String> {
    let order = r.u8()?;
    let le = match order {
        0 => false,
        1 => true,
        o => return Err(format!("invalid WKB byte order {o}")),
    };
    let raw = r.u32(le)?;
    // EWKB flags.
    let (mut z, mut m) = (raw & 0x8000_0000 != 0, raw & 0x4000_0000 != 0);
    if raw & 0x2000_0000 != 0 {
        r.u32(le)?; // EWKB SRID, ignored
    }
    let code = raw & 0x0FFF_FFFF;
    let base = code % 1000;
    match code / 1000 {
        0 => {}
        1 => z = true,
        2 => m = true,
        3 => {
            z = true;
            m = true;
        }
        _ => return Err(format!("unknown WKB geometry type {raw}")),
    }
    Ok(Header {
        le,
        base,
        dims: 2 + z as usize + m as usize,
    })
}

fn read_coord(r: &mut Reader, h: &Header) -> Result<Coord<f64>, String> {
    let x = r.f64(h.le)?;
    let y = r.f64(h.le)?;
    for _ in 2..h.dims {
        r.f64(h.le)?;
    }
    Ok(Coord { x, y })
}

fn read_points(r: &mut Reader, h: &Header) -> Result<Vec<Coord<f64>>, String> {
    let n = r.count(h.le, 8 * h.dims)?;
    (0..n).map(|_| read_coord(r, h)).collect()
}

fn read_polygon(r: &mut Reader, h: &Header) -> Result<Option<Polygon<f64>>, String> {
    let n = r.count(h.le, 4)?;
    let mut rings = Vec::with_capacity(n);
    for _ in 0..n {
        rings.push(LineString::new(read_points(r, h)?));
    }
    if rings.is_empty() {
        return Ok(None);
    }
    let ext = rings.remove(0);
    Ok(Some(Polygon::new(ext, rings)))
}

/// Reads one nested geometry of the expected base type (for Multi* members).
fn read_member(r: &mut Reader, depth: usize, want: u32) -> Result<Option<Geometry<f64>>, String> {
    let save = r.pos;
    let h = read_header(r)?;
    if h.base != want {
        return Err(format!(
            "member of type {} inside a collection of type {want}",
            h.base
        ));
    }
    r.pos = save;
    read_geometry(r, depth + 1)
}

fn read_geometry(r: &mut Reader, depth: usize) -> Result<Option<Geometry<f64>>, String> {
    if depth > MAX_DEPTH {
        return Err("WKB nested too deeply".into());
    }
    let h = read_header(r)?;
    Ok(match h.base {
        1 => {
            let c = read_coord(r, &h)?;
            // WKB writes an empty point as NaN coordinates.
            if c.x.is_nan() && c.y.is_nan() {
                None
            } else {
                Some(Geometry::Point(Point(c)))
            }
        }
        2 => {
            let pts = read_points(r, &h)?;
            (!pts.is_empty()).then_some(Geometry::LineString(LineString::new(pts)))
        }
        3 => read_polygon(r, &h)?.map(Geometry::Polygon),
        4 => {
            let n = r.count(h.le, 5)?;
            let mut pts = Vec::with_capacity(n);
            for _ in 0..n {
                if let Some(Geometry::Point(p)) = read_member(r, depth, 1)? {
                    pts.push(p);
                }
            }
            (!pts.is_empty()).then_some(Geometry::MultiPoint(MultiPoint(pts)))
        }
        5 => {
            let n = r.count(h.le, 9)?;
            let mut ls = Vec::with_capacity(n);
            for _ in 0..n {
                if let Some(Geometry::LineString(l)) = read_member(r, depth, 2)? {
                    ls.push(l);
                }
            }
            (!ls.is_empty()).then_some(Geometry::MultiLineString(MultiLineString(ls)))
        }
        6 => {
            let n = r.count(h.le, 9)?;
            let mut ps = Vec::with_capacity(n);
            for _ in 0..n {
                if let Some(Geometry::Polygon(p)) = read_member(r, depth, 3)? {
                    ps.push(p);
                }
            }
            (!ps.is_empty()).then_some(Geometry::MultiPolygon(MultiPolygon(ps)))
        }
        7 => {
            let n = r.count(h.le, 5)?;
            let mut gs = Vec::with_capacity(n);
            for _ in 0..n {
                if let Some(g) = read_geometry(r, depth + 1)? {
                    gs.push(g);
                }
            }
            (!gs.is_empty()).then_some(Geometry::GeometryCollection(GeometryCollection(gs)))
        }
        other => return Err(format!("unsupported WKB geometry type {other}")),
    })
}

/// `Err` naming the first vertex (counted over the whole geometry) that is NaN or infinite.
pub(crate) fn check_finite(g: &Geometry<f64>) -> Result<(), String> {
    let mut bad = None;
    let mut k = 0usize;
    visit(g, &mut |c: &Coord<f64>| {
        if bad.is_none() && !(c.x.is_finite() && c.y.is_finite()) {
            bad = Some(k);
        }
        k += 1;
    });
    match bad {
        Some(k) => Err(format!(
            "non-finite coordinate (NaN or infinity) at vertex {k}"
        )),
        None => Ok(()),
    }
}

fn visit(g: &Geometry<f64>, f: &mut impl FnMut(&Coord<f64>)) {
    match g {
        Geometry::Point(p) => f(&p.0),
        Geometry::MultiPoint(m) => m.0.iter().for_each(|p| f(&p.0)),
        Geometry::LineString(l) => l.0.iter().for_each(f),
        Geometry::MultiLineString(m) => m.0.iter().flat_map(|l| l.0.iter()).for_each(f),
        Geometry::Polygon(p) => {
            p.exterior().0.iter().for_each(&mut *f);
            p.interiors().iter().flat_map(|r| r.0.iter()).for_each(f)
        }
        Geometry::MultiPolygon(m) => m.0.iter().for_each(|p| {
            p.exterior().0.iter().for_each(&mut *f);
            p.interiors()
                .iter()
                .flat_map(|r| r.0.iter())
                .for_each(&mut *f)
        }),
        Geometry::GeometryCollection(c) => c.0.iter().for_each(|g| visit(g, f)),
        Geometry::Line(l) => {
            f(&l.start);
            f(&l.end)
        }
        Geometry::Rect(r) => {
            f(&r.min());
            f(&r.max())
        }
        Geometry::Triangle(t) => t.to_array().iter().for_each(f),
    }
}

/// Encodes a 2D geometry as little-endian WKB (OGC 06-103r4 §8.2). A `Line` is written as a
/// two-point LineString, a `Rect` and a `Triangle` as their Polygon.
pub fn encode_wkb(g: &Geometry<f64>) -> Vec<u8> {
    let mut out = Vec::with_capacity(wkb_size(g));
    write_geometry(&mut out, g);
    out
}

/// The number of bytes [`encode_wkb`] writes for `g`.
fn wkb_size(g: &Geometry<f64>) -> usize {
    let ring = |l: &LineString<f64>| 4 + 16 * l.0.len();
    let poly =
        |p: &Polygon<f64>| 9 + ring(p.exterior()) + p.interiors().iter().map(ring).sum::<usize>();
    match g {
        Geometry::Point(_) => 21,
        Geometry::Line(_) => 9 + 32,
        Geometry::LineString(l) => 5 + ring(l),
        Geometry::Polygon(p) => poly(p),
        Geometry::MultiPoint(m) => 9 + 21 * m.0.len(),
        Geometry::MultiLineString(m) => 9 + m.0.iter().map(|l| 5 + ring(l)).sum::<usize>(),
        Geometry::MultiPolygon(m) => 9 + m.0.iter().map(poly).sum::<usize>(),
        Geometry::GeometryCollection(c) => 9 + c.0.iter().map(wkb_size).sum::<usize>(),
        Geometry::Rect(_) => 9 + 4 + 16 * 5,
        Geometry::Triangle(_) => 9 + 4 + 16 * 4,
    }
}

fn put_header(out: &mut Vec<u8>, kind: u32) {
    out.push(1);
    out.extend_from_slice(&kind.to_le_bytes());
}

fn put_count(out: &mut Vec<u8>, n: usize) {
    // Counts beyond u32 cannot be written in WKB; no geometry held in memory comes near it.
    out.extend_from_slice(&u32::try_from(n).unwrap_or(u32::MAX).to_le_bytes());
}

fn put_coords(out: &mut Vec<u8>, cs: &[Coord<f64>]) {
    put_count(out, cs.len());
    for c in cs {
        out.extend_from_slice(&c.x.to_le_bytes());
        out.extend_from_slice(&c.y.to_le_bytes());
    }
}

fn put_polygon(out: &mut Vec<u8>, p: &Polygon<f64>) {
    put_header(out, 3);
    put_count(out, 1 + p.interiors().len());
    put_coords(out, &p.exterior().0);
    for r in p.interiors() {
        put_coords(out, &r.0);
    }
}

fn write_geometry(out: &mut Vec<u8>, g: &Geometry<f64>) {
    match g {
        Geometry::Point(p) => {
            put_header(out, 1);
            out.extend_from_slice(&p.0.x.to_le_bytes());
            out.extend_from_slice(&p.0.y.to_le_bytes());
        }
        Geometry::Line(l) => {
            put_header(out, 2);
            put_coords(out, &[l.start, l.end]);
        }
        Geometry::LineString(l) => {
            put_header(out, 2);
            put_coords(out, &l.0);
        }
        Geometry::Polygon(p) => put_polygon(out, p),
        Geometry::MultiPoint(m) => {
            put_header(out, 4);
            put_count(out, m.0.len());
            for p in &m.0 {
                write_geometry(out, &Geometry::Point(*p));
            }
        }
        Geometry::MultiLineString(m) => {
            put_header(out, 5);
            put_count(out, m.0.len());
            for l in &m.0 {
                put_header(out, 2);
                put_coords(out, &l.0);
            }
        }
        Geometry::MultiPolygon(m) => {
            put_header(out, 6);
            put_count(out, m.0.len());
            for p in &m.0 {
                put_polygon(out, p);
            }
        }
        Geometry::GeometryCollection(c) => {
            put_header(out, 7);
            put_count(out, c.0.len());
            for g in &c.0 {
                write_geometry(out, g);
            }
        }
        Geometry::Rect(r) => put_polygon(out, &r.to_polygon()),
        Geometry::Triangle(t) => put_polygon(out, &t.to_polygon()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wkb_polygon_be_z() -> Vec<u8> {
        // Big-endian ISO PolygonZ (1003) with one ring of 4 points.
        let mut b = vec![0u8];
        b.extend(1003u32.to_be_bytes());
        b.extend(1u32.to_be_bytes());
        b.extend(4u32.to_be_bytes());
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0)] {
            for v in [x, y, 9.0f64] {
                b.extend(f64::to_be_bytes(v));
            }
        }
        b
    }

    #[test]
    fn big_endian_iso_z_polygon() {
        let g = decode_wkb(&wkb_polygon_be_z()).unwrap().unwrap();
        let Geometry::Polygon(p) = g else { panic!() };
        assert_eq!(p.exterior().0.len(), 4);
        assert_eq!(p.exterior().0[2], Coord { x: 1.0, y: 1.0 });
    }

    #[test]
    fn gp_header_with_envelope_and_little_endian_multipoint() {
        let mut b = b"GP".to_vec();
        b.push(0);
        b.push(0b0000_0011); // envelope [minx,maxx,miny,maxy], little endian
        b.extend(3857i32.to_le_bytes());
        for v in [0.0f64, 1.0, 0.0, 1.0] {
            b.extend(v.to_le_bytes());
        }
        b.push(1);
        b.extend(4u32.to_le_bytes());
        b.extend(2u32.to_le_bytes());
        for (x, y) in [(0.5f64, 0.25f64), (1.0, 1.0)] {
            b.push(1);
            b.extend(1u32.to_le_bytes());
            b.extend(x.to_le_bytes());
            b.extend(y.to_le_bytes());
        }
        let g = decode_gpkg(&b).unwrap();
        assert_eq!(g.srs_id, 3857);
        let Some(Geometry::MultiPoint(m)) = g.geometry else {
            panic!()
        };
        assert_eq!(m.0[0].0, Coord { x: 0.5, y: 0.25 });
    }

    #[test]
    fn corrupt_blobs_are_errors() {
        assert!(decode_gpkg(b"XX\0\0\0\0\0\0").is_err());
        let mut b = wkb_polygon_be_z();
        b.truncate(30);
        assert!(decode_wkb(&b).is_err());
        // A huge count does not allocate.
        let mut h = vec![1u8];
        h.extend(2u32.to_le_bytes());
        h.extend(u32::MAX.to_le_bytes());
        assert!(decode_wkb(&h).unwrap_err().contains("truncated"));
        // Empty flag.
        let g = decode_gpkg(&[b'G', b'P', 0, 0x11, 0, 0, 0, 0]).unwrap();
        assert!(g.geometry.is_none());
    }

    #[test]
    fn encoding_round_trips_every_kind_and_matches_the_size() {
        use geo_types::{line_string, point, polygon};
        let sq = polygon![
            exterior: [(x: 0.0, y: 0.0), (x: 4.0, y: 0.0), (x: 4.0, y: 4.0), (x: 0.0, y: 0.0)],
            interiors: [[(x: 1.0, y: 1.0), (x: 2.0, y: 1.0), (x: 1.5, y: 2.0), (x: 1.0, y: 1.0)]],
        ];
        let ls = line_string![(x: 0.5, y: -1.0), (x: 1e9, y: 3.25)];
        let cases: Vec<Geometry<f64>> = vec![
            Geometry::Point(point!(x: -7.5, y: 1e-300)),
            Geometry::LineString(ls.clone()),
            Geometry::Polygon(sq.clone()),
            Geometry::MultiPoint(MultiPoint(vec![
                point!(x: 1.0, y: 2.0),
                point!(x: 3.0, y: 4.0),
            ])),
            Geometry::MultiLineString(MultiLineString(vec![ls.clone(), ls])),
            Geometry::MultiPolygon(MultiPolygon(vec![sq.clone(), sq.clone()])),
            Geometry::GeometryCollection(GeometryCollection(vec![
                Geometry::Polygon(sq),
                Geometry::Point(point!(x: 0.0, y: 0.0)),
            ])),
        ];
        for g in cases {
            let b = encode_wkb(&g);
            assert_eq!(b.len(), wkb_size(&g), "{g:?}");
            assert_eq!(decode_wkb(&b).unwrap(), Some(g));
        }
        // The shapes geo-types adds are written as the OGC geometry they stand for.
        let r = geo_types::Rect::new(Coord { x: 0.0, y: 0.0 }, Coord { x: 2.0, y: 1.0 });
        let b = encode_wkb(&Geometry::Rect(r));
        assert_eq!(b.len(), wkb_size(&Geometry::Rect(r)));
        assert_eq!(
            decode_wkb(&b).unwrap(),
            Some(Geometry::Polygon(r.to_polygon()))
        );
    }
}
