//! ESRI Shapefile reader (`.shp` + `.shx` + `.dbf` + `.prj`).
//!
//! Geometry comes from the `.shp` (read with the `shapefile` crate), attributes from the `.dbf`
//! (the `dbase` crate re-exported by `shapefile`), and the CRS from the `.prj` WKT
//! ([`Crs::from_wkt`]). [`read`] and the bounded-memory [`read_streaming`] find the records the
//! same way and give the same features, refusals and notes:
//!
//! - The `.shp`'s record headers are walked by their lengths. When they hold together, each
//!   record is read at the offset they give, and a `.shx` that disagrees with them is named in a
//!   note and not used. When they do not (a record length that lies), the `.shx` is used if every
//!   shape reads through it, and the records are read one after the other otherwise; a note says
//!   which.
//! - Points and multipoints → `Point` / `MultiPoint`; polylines → `LineString` (one part) or
//!   `MultiLineString`; polygons → `Polygon` or `MultiPolygon`. Z and M values are dropped.
//! - Polygon rings: clockwise rings are outer rings, counter-clockwise rings are holes (the
//!   Shapefile convention). Each hole goes into the smallest outer ring that contains it, by an
//!   exact point-in-ring test; ring order in the record is not trusted. A hole that lies in no
//!   outer ring becomes a polygon of its own, with a note. Vertex order is kept as read.
//! - DBF values: `Character` → text, `Numeric` → integer when the field has no decimals and the
//!   value is integral, else float; `*****` and blanks → null; `Logical` → bool; `Date` → ISO text.
//! - A missing `.dbf` is an error ([`ImportError::MissingCompanion`]): the attributes are part of
//!   the data. A missing or damaged `.shx` is not: a note says so.
//! - A truncated or corrupt `.shp` is an [`ImportError::Shapefile`] naming the file and the
//!   record; an empty one is [`ImportError::Empty`]. A value of a numeric `.dbf` field that is
//!   not a number is read as empty, with a note naming record, field and text; a `.dbf` record
//!   that still cannot be read costs that feature only: it is refused with the reason. A null shape, an empty
//!   shape, a MultiPatch or a record with NaN/infinite coordinates is refused in the report with
//!   its record number.
//! - A `.prj` that cannot be understood, or names an unknown EPSG code, is an
//!   [`ImportError::Crs`]; only a missing `.prj` leaves the CRS unknown (with a note).

use crate::crs::Crs;
use crate::rings;
use crate::{AttrValue, Attributes, Columns, Feature, ImportError, ImportReport, Layer};
use geo_types::{Coord, Geometry, LineString, MultiLineString, MultiPoint, MultiPolygon, Point};
use rayon::prelude::*;
use shapefile::dbase;
use shapefile::{Shape, ShapeReader};
use std::cell::RefCell;
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek};
use std::path::{Path, PathBuf};
use std::rc::Rc;

mod dbf;

/// Reads a Shapefile layer. `path` names the `.shp`; its companions are found beside it
/// (`.shx`, `.dbf`, `.prj`, with lower- or upper-case extensions).
///
/// # Errors
/// [`ImportError::Io`] when the `.shp` cannot be read, [`ImportError::Empty`] for an empty one,
/// [`ImportError::MissingCompanion`] when the `.dbf` is missing, [`ImportError::Shapefile`] /
/// [`ImportError::Dbase`] for a file that is not a Shapefile / dBase table or is truncated,
/// [`ImportError::Format`] when the `.shp` and `.dbf` disagree on the number of records,
/// [`ImportError::Crs`] for a `.prj` that cannot be used.
pub fn read(path: &Path) -> Result<Layer, ImportError> {
    read_with(path, &Columns::All)
}

/// [`read`] keeping only the attribute `columns` asked for: the `.dbf` bytes of the other
/// columns are skipped, not parsed (so a value that cannot be read in a column not asked for
/// costs its feature nothing).
///
/// The `.shp` and the `.dbf` are parsed side by side, and the records converted in parallel
/// (rayon); the features, their order and the report are those of a sequential read.
///
/// # Errors
/// As [`read`].
pub fn read_with(path: &Path, columns: &Columns) -> Result<Layer, ImportError> {
    read_with_stated_crs(path, columns, None)
}

/// [`read_with`], with the CRS `stated` by the caller in place of the `.prj` (which is then not
/// read, so a `.prj` that cannot be understood does not stop the import; a note says so).
///
/// # Errors
/// As [`read`], except [`ImportError::Crs`] when a CRS is stated.
pub fn read_with_stated_crs(
    path: &Path,
    columns: &Columns,
    stated: Option<&Crs>,
) -> Result<Layer, ImportError> {
    let io = |file: &Path| {
        let file = file.to_path_buf();
        move |source| ImportError::Io { file, source }
    };
    let shp_bytes = std::fs::read(path).map_err(io(path))?;
    if shp_bytes.is_empty() {
        return Err(ImportError::Empty {
            file: path.to_path_buf(),
            what: "a Shapefile starts with a 100-byte header".into(),
        });
    }
    let dbf_path = companion(path, "dbf").ok_or_else(|| ImportError::MissingCompanion {
        file: path.to_path_buf(),
        missing: path.with_extension("dbf"),
        why: "the .dbf holds the attribute table of the features".into(),
    })?;
    let mut report = ImportReport::default();
    let shx_path = companion(path, "shx");
    let shx_bytes = match &shx_path {
        Some(shx) => Some(std::fs::read(shx).map_err(io(shx))?),
        None => None,
    };

    // The record headers of the .shp, walked by their lengths, and the index checked against
    // them: a lie in either is named with its record. Geometry (by the chosen way) and
    // attributes are read side by side.
    let walk = walk_records_by(shp_bytes.len(), |at| {
        Ok(shp_bytes[at..at + 8].try_into().expect("8 bytes"))
    })
    .map_err(io(path))?;
    let (shapes, attributes) = rayon::join(
        || -> Result<Vec<Shape>, ImportError> {
            let (order, notes) = record_order(
                path,
                shx_path.as_deref(),
                shx_bytes,
                &walk,
                &shp_bytes,
                |shx| {
                    let mut reader =
                        ShapeReader::with_shx(Cursor::new(&shp_bytes[..]), Cursor::new(shx))?;
                    reader.iter_shapes().try_for_each(|s| s.map(drop))
                },
            );
            report.notes.extend(notes);
            let mut reader = order.reader(path, Cursor::new(&shp_bytes[..]))?;
            let mut shapes = Vec::new();
            for (i, s) in reader.iter_shapes().enumerate() {
                shapes.push(s.map_err(|source| order.record_error(path, i, source))?);
            }
            Ok(shapes)
        },
        || read_dbf(&dbf_path, columns),
    );
    let shapes = shapes?;
    drop(shp_bytes);
    // Attributes: a record that cannot be read costs its feature, not the layer.
    let (declared, records, blanked) = attributes?;
    report.notes.extend(blanked_note(&dbf_path, &blanked));
    let why = |walk: &Result<Vec<(usize, usize)>, String>| match walk {
        Err(e) => format!(" ({e})"),
        Ok(r) if r.len() != shapes.len() => {
            format!(" (the .shp's record headers give {} records)", r.len())
        }
        Ok(_) => String::new(),
    };
    if declared != shapes.len() {
        return Err(ImportError::Format {
            file: path.to_path_buf(),
            message: format!(
                "{} shapes in the .shp but {declared} records in {}{}",
                shapes.len(),
                dbf_path.display(),
                why(&walk)
            ),
        });
    }
    if records.len() != shapes.len() {
        return Err(ImportError::Format {
            file: path.to_path_buf(),
            message: format!(
                "{} shapes in the .shp but {} records in {}",
                shapes.len(),
                records.len(),
                dbf_path.display()
            ),
        });
    }

    // CRS.
    let crs = match stated {
        Some(crs) => {
            report.notes.push(format!(
                "CRS stated: {}{}",
                crs.describe(),
                match companion(path, "prj") {
                    Some(prj) => format!(" ({} not read)", prj.display()),
                    None => String::new(),
                }
            ));
            crs.clone()
        }
        None => read_prj(path, &mut report)?,
    };

    // Shapes to geometry in parallel; refusals and notes in record order.
    let converted: Vec<(Result<Geometry, String>, Option<String>)> = shapes
        .into_par_iter()
        .enumerate()
        .map(|(i, shape)| {
            let mut notes = ImportReport::default();
            let g = convert_shape(shape, i as u64, &mut notes);
            (g, notes.notes.pop())
        })
        .collect();
    let mut features = Vec::with_capacity(converted.len());
    report.read = converted.len();
    for (i, ((geometry, note), record)) in converted.into_iter().zip(records).enumerate() {
        let fid = i as u64;
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                report.refuse(
                    fid,
                    format!(
                        "attribute record cannot be read from {}: {e}",
                        dbf_path.display()
                    ),
                );
                continue;
            }
        };
        report.notes.extend(note);
        match geometry {
            Ok(geometry) => features.push(Feature {
                fid,
                geometry,
                attributes: record,
            }),
            Err(reason) => report.refuse(fid, reason),
        }
    }
    report.imported = features.len();
    report.group_refusals();
    Ok(Layer {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        source: path.to_path_buf(),
        crs,
        features,
        report,
    })
}

/// Every record of the `.dbf` as attributes (the `columns` asked for), with the number of
/// records its header declares.
#[allow(clippy::type_complexity)]
fn read_dbf(
    dbf_path: &Path,
    columns: &Columns,
) -> Result<
    (
        usize,
        Vec<Result<Attributes, dbase::Error>>,
        Vec<(usize, String, String)>,
    ),
    ImportError,
> {
    let (mut dbf, blanked, decimals) = open_dbf(dbf_path, columns)?;
    let declared = dbf.header().num_records as usize;
    let plan = FieldPlan {
        keep: dbf
            .fields()
            .iter()
            .map(|f| columns.wants(f.name()))
            .collect(),
        decimals: dbf
            .fields()
            .iter()
            .map(|f| decimals.get(f.name()).copied().unwrap_or(0))
            .collect(),
    };
    // The reader yields the same I/O error forever once the file ends: stop at the first one.
    // Each record becomes its attributes as it is read (no dBase map in between).
    let mut records: Vec<Result<Attributes, dbase::Error>> = Vec::with_capacity(declared);
    let previous = PLAN.replace(plan);
    for (i, r) in dbf
        .iter_records_as::<ProjectedRecord>()
        .take(declared)
        .enumerate()
    {
        if let Err(e) = &r {
            if matches!(e.kind(), dbase::ErrorKind::IoError(_)) {
                PLAN.set(previous);
                return Err(ImportError::Dbase {
                    file: dbf_path.to_path_buf(),
                    what: format!("record {i} of {declared} cannot be read (truncated file)"),
                    source: r.err().expect("an error"),
                });
            }
        }
        records.push(r.map(|r| r.0));
    }
    PLAN.set(previous);
    drop(dbf);
    let blanked = std::mem::take(&mut *blanked.borrow_mut());
    Ok((declared, records, blanked))
}

/// The `.dbf` at `dbf_path` as a dBase reader over a [`dbf::BlankingSource`] (bad numbers in
/// the `columns` asked for read as empty), with the list the blanked values are collected in
/// and the fields' decimal counts.
#[allow(clippy::type_complexity)]
fn open_dbf(
    dbf_path: &Path,
    columns: &Columns,
) -> Result<
    (
        dbase::Reader<dbf::BlankingSource<BufReader<File>>>,
        Rc<RefCell<Vec<dbf::Blanked>>>,
        HashMap<String, u8>,
    ),
    ImportError,
> {
    let io = |source| ImportError::Io {
        file: dbf_path.to_path_buf(),
        source,
    };
    let file = File::open(dbf_path).map_err(io)?;
    let (source, blanked) = dbf::BlankingSource::new(BufReader::new(file), columns).map_err(io)?;
    let decimals = dbf_decimals(source.head());
    let reader = dbase::Reader::new(source).map_err(|source| ImportError::Dbase {
        file: dbf_path.to_path_buf(),
        what: "not a readable dBase table".into(),
        source,
    })?;
    Ok((reader, blanked, decimals))
}

/// How the fields of the table being read are turned into attributes: per field (in the
/// table's order) whether it is kept, and its decimal count.
#[derive(Clone, Debug, Default)]
struct FieldPlan {
    keep: Vec<bool>,
    decimals: Vec<u8>,
}

thread_local! {
    /// The plan of the table this thread is reading (`dbase` builds each record through a
    /// trait function that takes no context).
    static PLAN: std::cell::Cell<FieldPlan> = std::cell::Cell::new(FieldPlan::default());
}

/// One `.dbf` record as attributes, its fields parsed or skipped as [`PLAN`] says.
struct ProjectedRecord(Attributes);

impl dbase::ReadableRecord for ProjectedRecord {
    fn read_using<S, M>(fields: &mut dbase::FieldIterator<S, M>) -> Result<Self, dbase::FieldError>
    where
        S: std::io::Read + std::io::Seek,
        M: std::io::Read + std::io::Seek,
    {
        let plan = PLAN.take();
        let mut out = Attributes::new();
        let mut result = Ok(());
        for (k, &keep) in plan.keep.iter().enumerate() {
            if keep {
                match fields.read_next_field() {
                    Ok(v) => {
                        out.insert(v.name.to_string(), field_value(v.value, plan.decimals[k]));
                    }
                    Err(e) => {
                        result = Err(e);
                        break;
                    }
                }
            } else if let Err(e) = fields.skip_next_field() {
                result = Err(e);
                break;
            }
        }
        PLAN.set(plan);
        result.map(|()| ProjectedRecord(out))
    }
}

/// The `.shp`'s records as (byte offset, content bytes), found by walking the record headers
/// from the end of the 100-byte file header (`header(at)` gives the 8 bytes at `at`): each holds
/// its record's number (from 1) and its content length in 16-bit words. A file length in the
/// header that is not the file's, a length that runs past the end of the file, or a record
/// whose number is not the next one (the previous record's length is then wrong), is named.
///
/// # Errors
/// Only those of `header`; the walk's own verdict is the inner result.
fn walk_records_by(
    len: usize,
    mut header: impl FnMut(usize) -> std::io::Result<[u8; 8]>,
) -> std::io::Result<Result<Vec<(usize, usize)>, String>> {
    let be = |h: &[u8; 8], k: usize| i32::from_be_bytes([h[k], h[k + 1], h[k + 2], h[k + 3]]);
    if len < 100 {
        return Ok(Err(format!(
            "{len} bytes, shorter than the 100-byte header"
        )));
    }
    let stated = i64::from(be(&header(24)?, 0)) * 2;
    if stated != len as i64 {
        return Ok(Err(format!(
            "the header gives a file length of {stated} bytes, the file holds {len}"
        )));
    }
    let mut records: Vec<(usize, usize)> = Vec::new();
    let mut at = 100usize;
    while at + 8 <= len {
        let h = header(at)?;
        let (number, words) = (be(&h, 0), be(&h, 4));
        let k = records.len();
        if i64::from(number) != k as i64 + 1 {
            return Ok(Err(match records.last() {
                Some(&(prev, len)) => format!(
                    "the record header at byte {at} is numbered {number}, not {}: the length \
                     of record {} ({len} bytes at byte {prev}) is wrong",
                    k + 1,
                    k - 1
                ),
                None => format!("the first record header (byte 100) is numbered {number}, not 1"),
            }));
        }
        let Ok(words) = usize::try_from(words) else {
            return Ok(Err(format!(
                "record {k} (byte {at}) gives a negative length ({words} words)"
            )));
        };
        let rec = words * 2;
        if at + 8 + rec > len {
            return Ok(Err(format!(
                "record {k} (byte {at}) gives a length of {rec} bytes, past the end of the \
                 .shp ({len} bytes)"
            )));
        }
        records.push((at, rec));
        at += 8 + rec;
    }
    if at != len {
        return Ok(Err(format!(
            "{} stray bytes after record {} at the end of the .shp",
            len - at,
            records.len().saturating_sub(1)
        )));
    }
    Ok(Ok(records))
}

/// Whether the `.shx` index holds exactly the `.shp`'s records (offsets and lengths, in
/// 16-bit words): the first disagreement, named by record, when not.
fn index_agrees(shx: &[u8], walk: &Result<Vec<(usize, usize)>, String>) -> Result<(), String> {
    if shx.len() < 100 || !(shx.len() - 100).is_multiple_of(8) {
        return Err(format!(
            "{} bytes, not a 100-byte header and 8 bytes a record",
            shx.len()
        ));
    }
    let word = |o: usize| i32::from_be_bytes([shx[o], shx[o + 1], shx[o + 2], shx[o + 3]]);
    let stated = i64::from(word(24)) * 2;
    if stated != shx.len() as i64 {
        return Err(format!(
            "its header gives a file length of {stated} bytes, it holds {}",
            shx.len()
        ));
    }
    // A lie in the .shp's own headers: the index is checked by the shapes it leads to instead.
    let Ok(records) = walk else {
        return Ok(());
    };
    let n = (shx.len() - 100) / 8;
    for (i, &(at, len)) in records.iter().enumerate().take(n) {
        let e = 100 + 8 * i;
        let (off, bytes) = (i64::from(word(e)) * 2, i64::from(word(e + 4)) * 2);
        if off != at as i64 || bytes != len as i64 {
            return Err(format!(
                "record {i}: the .shx gives offset {off} and length {bytes} bytes, the .shp's \
                 record is at offset {at} with length {len} bytes"
            ));
        }
    }
    if n != records.len() {
        return Err(format!(
            "the .shx indexes {n} records, the .shp holds {}",
            records.len()
        ));
    }
    Ok(())
}

/// The way a `.shp`'s records are read, the same for [`read`] and [`read_streaming`].
enum RecordOrder {
    /// Through an index (the `.shx`'s bytes, or one made from the record headers): each record
    /// is read at its offset.
    Indexed { shx: Vec<u8> },
    /// One after the other from the end of the header, each by its content (what is left when
    /// neither the headers nor the `.shx` can be trusted), with the headers' problem.
    Sequence { problem: Option<String> },
}

impl RecordOrder {
    /// A shape reader over `shp` that reads in this order.
    fn reader<R: std::io::Read + Seek>(
        &self,
        path: &Path,
        shp: R,
    ) -> Result<ShapeReader<R>, ImportError> {
        match self {
            RecordOrder::Indexed { shx } => ShapeReader::with_shx(shp, Cursor::new(shx)),
            RecordOrder::Sequence { .. } => ShapeReader::new(shp),
        }
        .map_err(|source| ImportError::Shapefile {
            file: path.to_path_buf(),
            what: "not a readable Shapefile header".into(),
            source,
        })
    }

    /// The error for record `i`, which cannot be read.
    fn record_error(&self, path: &Path, i: usize, source: shapefile::Error) -> ImportError {
        let what = match self {
            RecordOrder::Indexed { .. } => format!("record {i} cannot be read (corrupt record)"),
            RecordOrder::Sequence { problem: Some(w) } => {
                format!("record {i} cannot be read (truncated or corrupt file; {w})")
            }
            RecordOrder::Sequence { problem: None } => {
                format!("record {i} cannot be read (truncated or corrupt file)")
            }
        };
        ImportError::Shapefile {
            file: path.to_path_buf(),
            what,
            source,
        }
    }
}

/// How the records of the `.shp` at `path` are to be read, with the notes that say so.
///
/// When the record headers walk cleanly (`walk` is `Ok`), they are the index: each record is
/// read at its offset, and a `.shx` that disagrees with them is named in a note and not used.
/// When they do not, the `.shx` is used if every shape reads through it (`reads_through`
/// tries), and the records are read one after the other otherwise.
fn record_order(
    path: &Path,
    shx_path: Option<&Path>,
    shx: Option<Vec<u8>>,
    walk: &Result<Vec<(usize, usize)>, String>,
    shp_head: &[u8],
    reads_through: impl FnOnce(&[u8]) -> Result<(), shapefile::Error>,
) -> (RecordOrder, Vec<String>) {
    let mut notes = Vec::new();
    let shx = match (shx_path, shx) {
        (Some(p), Some(bytes)) => match index_agrees(&bytes, walk) {
            Ok(()) => Some(bytes),
            Err(why) => {
                notes.push(format!(
                    "{} is damaged, it disagrees with the .shp ({why}): it was ignored",
                    p.display()
                ));
                None
            }
        },
        _ => {
            notes.push(format!(
                "no {} index: the records were found by their headers in the .shp",
                path.with_extension("shx").display()
            ));
            None
        }
    };
    match walk {
        Ok(records) => (
            RecordOrder::Indexed {
                shx: shx.unwrap_or_else(|| index_of(shp_head, records)),
            },
            notes,
        ),
        Err(problem) => {
            notes.push(format!(
                "{}: its record headers disagree with its records ({problem})",
                path.display()
            ));
            match shx {
                Some(shx) => match reads_through(&shx) {
                    Ok(()) => {
                        notes.push(format!(
                            "the records were read through {}",
                            shx_path.map(Path::display).expect("an index has a path")
                        ));
                        (RecordOrder::Indexed { shx }, notes)
                    }
                    Err(e) => {
                        notes.push(format!(
                            "{} is damaged ({e}): it was ignored and the records were read in \
                             sequence from the .shp",
                            shx_path.map(Path::display).expect("an index has a path")
                        ));
                        (
                            RecordOrder::Sequence {
                                problem: Some(problem.clone()),
                            },
                            notes,
                        )
                    }
                },
                None => {
                    notes.push("the records were read in sequence from the .shp".into());
                    (
                        RecordOrder::Sequence {
                            problem: Some(problem.clone()),
                        },
                        notes,
                    )
                }
            }
        }
    }
}

/// A `.shx` index for `records` (offset, content bytes) under the `.shp`'s header `shp_head`.
fn index_of(shp_head: &[u8], records: &[(usize, usize)]) -> Vec<u8> {
    let mut shx = Vec::with_capacity(100 + 8 * records.len());
    shx.extend_from_slice(&shp_head[..100]);
    let words = |n: usize| i32::try_from(n / 2).unwrap_or(i32::MAX).to_be_bytes();
    shx[24..28].copy_from_slice(&words(100 + 8 * records.len()));
    for &(at, len) in records {
        shx.extend_from_slice(&words(at));
        shx.extend_from_slice(&words(len));
    }
    shx
}

/// The note for the values of numeric fields in the `.dbf` that were not numbers, if any.
fn blanked_note(dbf_path: &Path, blanked: &[dbf::Blanked]) -> Option<String> {
    if blanked.is_empty() {
        return None;
    }
    let examples: Vec<String> = blanked
        .iter()
        .take(crate::report::GROUP_EXAMPLES)
        .map(|(i, name, raw)| format!("record {i} {name} = {raw:?}"))
        .collect();
    Some(format!(
        "{}: {} value(s) of numeric fields are not numbers and were read as empty (a height \
         read so falls back to the default height): {}{}",
        dbf_path.display(),
        blanked.len(),
        examples.join(", "),
        if blanked.len() > examples.len() {
            ", …"
        } else {
            ""
        }
    ))
}

/// The companion file with extension `ext` (lower or upper case), if it exists.
fn companion(path: &Path, ext: &str) -> Option<PathBuf> {
    [ext.to_ascii_lowercase(), ext.to_ascii_uppercase()]
        .into_iter()
        .map(|e| path.with_extension(e))
        .find(|p| p.is_file())
}

/// The CRS of the `.prj` beside `path`: [`Crs::Unknown`] with a note when there is none; an
/// error when there is one that cannot be read or understood (coordinates are never taken as
/// metres because a CRS was not understood).
fn read_prj(path: &Path, report: &mut ImportReport) -> Result<Crs, ImportError> {
    let Some(prj) = companion(path, "prj") else {
        report.notes.push(format!(
            "no {}: CRS unknown, coordinates taken as metres",
            path.with_extension("prj").display()
        ));
        return Ok(Crs::Unknown);
    };
    let bytes = std::fs::read(&prj).map_err(|source| ImportError::Io {
        file: prj.clone(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let crs = Crs::from_wkt(&text).map_err(|source| ImportError::Crs {
        file: path.to_path_buf(),
        from: prj.display().to_string(),
        source,
    })?;
    report
        .notes
        .push(format!("CRS from {}: {}", prj.display(), crs.describe()));
    Ok(crs)
}

/// Decimal counts of the DBF fields, by name, read from the field descriptors of the header
/// (the `dbase` crate does not expose them). Byte 17 of each 32-byte descriptor.
fn dbf_decimals(bytes: &[u8]) -> HashMap<String, u8> {
    let mut out = HashMap::new();
    let mut off = 32;
    while off + 32 <= bytes.len() && bytes[off] != 0x0D {
        let name_bytes = &bytes[off..off + 11];
        let end = name_bytes.iter().position(|&b| b == 0).unwrap_or(11);
        let name = String::from_utf8_lossy(&name_bytes[..end])
            .trim()
            .to_string();
        out.insert(name, bytes[off + 17]);
        off += 32;
    }
    out
}

fn convert_record(record: dbase::Record, decimals: &HashMap<String, u8>) -> Attributes {
    let map: HashMap<String, dbase::FieldValue> = record.into();
    map.into_iter()
        .map(|(name, v)| {
            let dec = decimals.get(&name).copied().unwrap_or(0);
            (name, field_value(v, dec))
        })
        .collect()
}

fn field_value(v: dbase::FieldValue, decimals: u8) -> AttrValue {
    use dbase::FieldValue as F;
    match v {
        F::Character(Some(s)) => AttrValue::Text(s),
        F::Memo(s) => AttrValue::Text(s),
        F::Numeric(Some(x)) => {
            if decimals == 0 && x.fract() == 0.0 && x.abs() < 9.0e15 {
                AttrValue::Int(x as i64)
            } else {
                AttrValue::Float(x)
            }
        }
        F::Float(Some(x)) => AttrValue::Float(x as f64),
        F::Logical(Some(b)) => AttrValue::Bool(b),
        F::Date(Some(d)) => {
            AttrValue::Text(format!("{:04}-{:02}-{:02}", d.year(), d.month(), d.day()))
        }
        F::Integer(i) => AttrValue::Int(i as i64),
        F::Double(x) | F::Currency(x) => AttrValue::Float(x),
        F::DateTime(dt) => {
            let (d, t) = (dt.date(), dt.time());
            AttrValue::Text(format!(
                "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}",
                d.year(),
                d.month(),
                d.day(),
                t.hours(),
                t.minutes(),
                t.seconds()
            ))
        }
        F::Character(None)
        | F::Numeric(None)
        | F::Float(None)
        | F::Logical(None)
        | F::Date(None) => AttrValue::Null,
    }
}

fn check_finite(coords: &[Coord<f64>]) -> Result<(), String> {
    match rings::first_non_finite(coords) {
        Some(k) => Err(format!(
            "non-finite coordinate (NaN or infinity) at vertex {k}"
        )),
        None => Ok(()),
    }
}

fn xy<P: Copy>(points: &[P], f: impl Fn(P) -> (f64, f64)) -> Vec<Coord<f64>> {
    points
        .iter()
        .map(|&p| {
            let (x, y) = f(p);
            Coord { x, y }
        })
        .collect()
}

/// A shape's kind (`P` point, `M` multipoint, `L` polyline, `A` polygon) and its parts in 2D.
type ShapeParts = (char, Vec<Vec<Coord<f64>>>);

/// The parts of a shape as 2D coordinates.
fn shape_parts(shape: Shape) -> Result<ShapeParts, String> {
    use shapefile::{PointM, PointZ};
    let pm = |p: PointM| (p.x, p.y);
    let pz = |p: PointZ| (p.x, p.y);
    let p2 = |p: shapefile::Point| (p.x, p.y);
    Ok(match shape {
        Shape::NullShape => return Err("null shape (the record has no geometry)".into()),
        Shape::Multipatch(_) => return Err("MultiPatch shapes are not supported".into()),
        Shape::Point(p) => ('P', vec![xy(&[p], p2)]),
        Shape::PointM(p) => ('P', vec![xy(&[p], pm)]),
        Shape::PointZ(p) => ('P', vec![xy(&[p], pz)]),
        Shape::Multipoint(m) => ('M', vec![xy(m.points(), p2)]),
        Shape::MultipointM(m) => ('M', vec![xy(m.points(), pm)]),
        Shape::MultipointZ(m) => ('M', vec![xy(m.points(), pz)]),
        Shape::Polyline(l) => ('L', l.parts().iter().map(|p| xy(p, p2)).collect()),
        Shape::PolylineM(l) => ('L', l.parts().iter().map(|p| xy(p, pm)).collect()),
        Shape::PolylineZ(l) => ('L', l.parts().iter().map(|p| xy(p, pz)).collect()),
        Shape::Polygon(g) => ('A', g.rings().iter().map(|r| xy(r.points(), p2)).collect()),
        Shape::PolygonM(g) => ('A', g.rings().iter().map(|r| xy(r.points(), pm)).collect()),
        Shape::PolygonZ(g) => ('A', g.rings().iter().map(|r| xy(r.points(), pz)).collect()),
    })
}

fn convert_shape(shape: Shape, fid: u64, report: &mut ImportReport) -> Result<Geometry, String> {
    let (kind, parts) = shape_parts(shape)?;
    let parts: Vec<Vec<Coord<f64>>> = parts.into_iter().filter(|p| !p.is_empty()).collect();
    if parts.is_empty() {
        return Err("empty geometry (no vertices)".into());
    }
    for p in &parts {
        check_finite(p)?;
    }
    match kind {
        'P' => Ok(Geometry::Point(Point(parts[0][0]))),
        'M' => Ok(Geometry::MultiPoint(MultiPoint(
            parts[0].iter().map(|&c| Point(c)).collect(),
        ))),
        'L' => {
            if let Some(k) = parts.iter().position(|p| p.len() < 2) {
                return Err(format!("line part {k} has a single vertex"));
            }
            let mut lines: Vec<LineString<f64>> = parts.into_iter().map(LineString::new).collect();
            if lines.len() == 1 {
                Ok(Geometry::LineString(lines.pop().expect("one line")))
            } else {
                Ok(Geometry::MultiLineString(MultiLineString(lines)))
            }
        }
        _ => {
            // Shapefile convention: outer rings clockwise (negative signed area), holes
            // counter-clockwise. A degenerate ring (zero area) is kept as an outer ring for the
            // city model to judge.
            let (mut outers, mut holes) = (Vec::new(), Vec::new());
            for r in parts {
                if rings::signed_area2(&r) > 0.0 {
                    holes.push(r);
                } else {
                    outers.push(r);
                }
            }
            let a = rings::assemble(outers, holes);
            if !a.orphan_holes.is_empty() {
                report.notes.push(format!(
                    "record {fid}: {} counter-clockwise ring(s) lie in no clockwise ring; each \
                     was kept as a polygon of its own",
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
    }
}

/// Reads a Shapefile layer in a streaming way: the records are read in sequence from the `.shp`
/// (never the whole file at once), `keep(fid, [xmin, ymin, xmax, ymax])` decides from each
/// shape's box (in the file's own coordinates) whether its feature is wanted, and only the
/// wanted features' `.dbf` records are read and converted. The kept features are handed to
/// `sink` in file order, in layers of at most `chunk` features (every chunk carries the CRS and
/// its own share of the refusals); memory is bounded by one chunk, not by the file.
///
/// Features are the same as [`read`] gives for the same records (same `fid`, geometry and
/// attributes). A record whose shape cannot be converted is refused in the chunk it falls in.
///
/// Returns the number of records in the file.
///
/// # Errors
/// As [`read`]: [`ImportError::Io`], [`ImportError::MissingCompanion`],
/// [`ImportError::Shapefile`], [`ImportError::Dbase`], [`ImportError::Format`] (the `.shp` and
/// `.dbf` disagree on the number of records), [`ImportError::Crs`].
pub fn read_streaming(
    path: &Path,
    keep: &mut dyn FnMut(u64, [f64; 4]) -> bool,
    chunk: usize,
    sink: &mut dyn FnMut(Layer),
) -> Result<usize, ImportError> {
    let chunk = chunk.max(1);
    let dbf_path = companion(path, "dbf").ok_or_else(|| ImportError::MissingCompanion {
        file: path.to_path_buf(),
        missing: path.with_extension("dbf"),
        why: "the .dbf holds the attribute table of the features".into(),
    })?;
    let io = |file: &Path| {
        let file = file.to_path_buf();
        move |source| ImportError::Io { file, source }
    };
    let mut head = ImportReport::default();
    let crs = read_prj(path, &mut head)?;
    let (mut dbf, blanked, decimals) = open_dbf(&dbf_path, &Columns::All)?;
    let declared = dbf.header().num_records as usize;

    // The record headers walked, the index chosen, as [`read`] does, without holding the file.
    let shp_len = std::fs::metadata(path).map_err(io(path))?.len();
    if shp_len == 0 {
        return Err(ImportError::Empty {
            file: path.to_path_buf(),
            what: "a Shapefile starts with a 100-byte header".into(),
        });
    }
    let open_shp = || File::open(path).map(BufReader::new);
    let open = || open_shp().map_err(io(path));
    let mut file = open()?;
    let mut shp_head = Vec::with_capacity(100);
    (&mut file)
        .take(100)
        .read_to_end(&mut shp_head)
        .map_err(io(path))?;
    let mut at = shp_head.len() as u64;
    let walk = walk_records_by(usize::try_from(shp_len).unwrap_or(usize::MAX), |to| {
        let to = to as u64;
        if to < 100 {
            let k = to as usize;
            return Ok(shp_head[k..k + 8].try_into().expect("8 bytes"));
        }
        file.seek_relative(to as i64 - at as i64)?;
        let mut h = [0u8; 8];
        file.read_exact(&mut h)?;
        at = to + 8;
        Ok(h)
    })
    .map_err(io(path))?;
    drop(file);
    if let Ok(records) = &walk {
        if records.len() != declared {
            return Err(ImportError::Format {
                file: path.to_path_buf(),
                message: format!(
                    "{} shapes in the .shp but {declared} records in {}",
                    records.len(),
                    dbf_path.display()
                ),
            });
        }
    }
    let shx_path = companion(path, "shx");
    let shx_bytes = match &shx_path {
        Some(shx) => Some(std::fs::read(shx).map_err(io(shx))?),
        None => None,
    };
    let (order, notes) = record_order(
        path,
        shx_path.as_deref(),
        shx_bytes,
        &walk,
        &shp_head,
        |shx| {
            let mut reader = ShapeReader::with_shx(open_shp()?, Cursor::new(shx))?;
            reader.iter_shapes().try_for_each(|s| s.map(drop))
        },
    );
    head.notes.extend(notes);
    let mut shp = order.reader(path, open()?)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let new_layer = |report: ImportReport| Layer {
        name: name.clone(),
        source: path.to_path_buf(),
        crs: crs.clone(),
        features: Vec::new(),
        report,
    };
    let mut layer = new_layer(head);
    let mut next_record = 0usize;
    let mut count = 0usize;
    let flush = |layer: &mut Layer, sink: &mut dyn FnMut(Layer)| {
        let mut done = std::mem::replace(layer, new_layer(ImportReport::default()));
        done.report.imported = done.features.len();
        done.report.group_refusals();
        sink(done);
    };
    for (i, s) in shp.iter_shapes().enumerate() {
        let shape = s.map_err(|source| order.record_error(path, i, source))?;
        count = i + 1;
        let fid = i as u64;
        layer.report.read += 1;
        let geometry = match convert_shape(shape, fid, &mut layer.report) {
            Ok(g) => g,
            Err(reason) => {
                layer.report.refuse(fid, reason);
                continue;
            }
        };
        if !keep(fid, geometry_box(&geometry)) {
            layer.report.read -= 1;
            continue;
        }
        if i >= declared {
            return Err(ImportError::Format {
                file: path.to_path_buf(),
                message: format!(
                    "more shapes in the .shp than the {declared} records in {}",
                    dbf_path.display()
                ),
            });
        }
        if next_record != i {
            dbf.seek(i).map_err(|source| ImportError::Dbase {
                file: dbf_path.clone(),
                what: format!("record {i} of {declared} cannot be reached"),
                source,
            })?;
        }
        let record = dbf.iter_records().next();
        next_record = i + 1;
        match record {
            Some(Ok(r)) => layer.features.push(Feature {
                fid,
                geometry,
                attributes: convert_record(r, &decimals),
            }),
            Some(Err(e)) if matches!(e.kind(), dbase::ErrorKind::IoError(_)) => {
                return Err(ImportError::Dbase {
                    file: dbf_path.clone(),
                    what: format!("record {i} of {declared} cannot be read (truncated file)"),
                    source: e,
                })
            }
            Some(Err(e)) => layer.report.refuse(
                fid,
                format!(
                    "attribute record cannot be read from {}: {e}",
                    dbf_path.display()
                ),
            ),
            None => {
                return Err(ImportError::Format {
                    file: path.to_path_buf(),
                    message: format!("record {i} is missing from {}", dbf_path.display()),
                })
            }
        }
        if layer.features.len() >= chunk {
            flush(&mut layer, sink);
        }
    }
    if count != declared {
        return Err(ImportError::Format {
            file: path.to_path_buf(),
            message: format!(
                "{count} shapes in the .shp but {declared} records in {}",
                dbf_path.display()
            ),
        });
    }
    drop(dbf);
    layer
        .report
        .notes
        .extend(blanked_note(&dbf_path, &blanked.borrow()));
    if !layer.features.is_empty() || layer.report.read > 0 || !layer.report.notes.is_empty() {
        flush(&mut layer, sink);
    }
    Ok(count)
}

/// The box `[xmin, ymin, xmax, ymax]` of a converted geometry (finite by construction); NaN for
/// a kind the reader never produces.
fn geometry_box(g: &Geometry) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    let mut add = |c: &Coord<f64>| {
        b = [b[0].min(c.x), b[1].min(c.y), b[2].max(c.x), b[3].max(c.y)];
    };
    match g {
        Geometry::Point(p) => add(&p.0),
        Geometry::MultiPoint(m) => m.0.iter().for_each(|p| add(&p.0)),
        Geometry::LineString(l) => l.0.iter().for_each(add),
        Geometry::MultiLineString(m) => m.0.iter().flat_map(|l| &l.0).for_each(add),
        Geometry::Polygon(p) => p.exterior().0.iter().for_each(add),
        Geometry::MultiPolygon(m) => m.0.iter().flat_map(|p| &p.exterior().0).for_each(add),
        _ => return [f64::NAN; 4],
    }
    b
}

/// The CRS of a Shapefile layer, from its `.prj` alone (as [`read`] finds it).
///
/// # Errors
/// [`ImportError::Io`] or [`ImportError::Crs`] for a `.prj` that cannot be read or understood.
pub fn read_crs(path: &Path) -> Result<Crs, ImportError> {
    read_prj(path, &mut ImportReport::default())
}
