//! Reads cadastral and street layers into neutral, format-free layers.
//!
//! Every reader returns a [`Layer`]: geo-types geometry in the file's own coordinates (f64), the
//! attributes of each feature, the coordinate reference system found ([`Crs`]) and an
//! [`ImportReport`] that accounts for every feature read (imported, or refused with a reason).
//! Geometric repair of footprints (ring closing, winding, spikes, self-intersections) is the city
//! model's job; this crate refuses only what cannot be read at all (NaN, empty geometry, truncated
//! records) and says why.
//!
//! | reader | reads | CRS from |
//! |---|---|---|
//! | [`shp::read`] | `.shp` + `.shx` + `.dbf` (attributes) | `.prj` WKT |
//! | [`geojson_reader::read`] | FeatureCollection, Feature or bare geometry | legacy `crs` member, else WGS84 |
//! | `gpkg::read` (feature `gpkg`) | one feature table of a GeoPackage, chosen by [`Theme`] | `gpkg_spatial_ref_sys` |
//! | `osm::read` (feature `osm`) | OSM PBF buildings (ways and multipolygon relations) or streets | WGS84 |
//! | [`read_dem`] | a single-band GeoTIFF elevation grid ([`DemGrid`], not a layer) | GeoKeys (EPSG codes) |
//!
//! [`read_layer`] picks the reader by extension. [`Crs::metric_transform`] maps a layer's
//! coordinates to ground metres (identity for projected data; a local transverse Mercator for
//! Web Mercator and geographic data).
//!
//! This crate knows nothing of `blockwalk`: it can be used alone to read cadastral data.

#![forbid(unsafe_code)]
#![warn(missing_docs)]
// `ImportError` keeps the libraries' own errors as its sources (a few of them are large); it is
// returned once per file, never in a loop, so its size costs nothing measurable.
#![allow(clippy::result_large_err)]

pub mod crs;
pub mod dem;
pub mod fuzzing;
pub mod geojson_reader;
#[cfg(feature = "gpkg")]
pub mod gpkg;
pub mod memory;
#[cfg(feature = "osm")]
pub mod osm;
pub mod report;
mod rings;
pub mod shp;
pub mod wkb;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use crs::{CoordError, Crs, CrsError, MetricTransform};
pub use dem::{read_dem, DemError, DemGrid, PixelIs};
pub use report::{format_groups, group_reasons, ImportReport, ReasonGroup, Refusal};

/// One attribute value of a feature.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum AttrValue {
    /// Missing or null (a DBF `*****`, a JSON `null`).
    Null,
    /// A boolean.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A floating-point number.
    Float(f64),
    /// Text.
    Text(String),
}

impl AttrValue {
    /// The value as a number; `None` for null, booleans, non-finite numbers and text that holds
    /// no leading number. Text is read as its longest leading number in Rust's float syntax
    /// (`"12.5"`, `"12.13 m"`, `"1e9"` and `"-3"` are read whole; a decimal comma `"12,5"` is
    /// read as 12.5), so that scientific notation is never cut to its mantissa.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            AttrValue::Int(i) => Some(*i as f64),
            AttrValue::Float(f) if f.is_finite() => Some(*f),
            AttrValue::Text(s) => leading_number(s),
            _ => None,
        }
    }
}

/// The longest leading prefix of `s` (trimmed) that parses as a finite `f64`.
fn leading_number(s: &str) -> Option<f64> {
    let t = s.trim();
    // A decimal comma between digits ("12,5") is a decimal point; a list ("5;6", "5,6,7") is not.
    let t: String = if t.matches(',').count() == 1
        && !t.contains('.')
        && t.split(',')
            .all(|p| p.trim().chars().next().is_some_and(|c| c.is_ascii_digit()))
    {
        t.replacen(',', ".", 1)
    } else {
        t.to_string()
    };
    // Only number characters can be in the prefix; words such as "inf" or "nan" never count.
    let end = t
        .char_indices()
        .find(|(_, c)| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .map(|(i, _)| i)
        .unwrap_or(t.len());
    (1..=end)
        .rev()
        .filter(|&k| t.is_char_boundary(k))
        .find_map(|k| t[..k].parse::<f64>().ok())
        .filter(|v| v.is_finite())
}

/// The attributes of one feature, by field name.
pub type Attributes = BTreeMap<String, AttrValue>;

/// One feature of a layer.
#[derive(Clone, Debug)]
pub struct Feature {
    /// Zero-based index of the feature in its file (the record number for a Shapefile, the feature
    /// index for GeoJSON, the row id for GeoPackage, the OSM id for OSM).
    pub fid: u64,
    /// Geometry in the layer's own coordinates ([`Layer::crs`]).
    pub geometry: geo_types::Geometry<f64>,
    /// Attributes by field name.
    pub attributes: Attributes,
}

/// What a layer holds, as far as the importer could tell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LayerKind {
    /// Polygons or multipolygons (footprints, parcels, blocks).
    Polygons,
    /// Line strings (streets).
    Lines,
    /// Points.
    Points,
    /// A mix, or no features at all.
    Mixed,
}

/// A layer read from one file (or one table of a GeoPackage, or one theme of an OSM file).
#[derive(Clone, Debug)]
pub struct Layer {
    /// The layer's name (file stem or table name).
    pub name: String,
    /// The file it came from.
    pub source: PathBuf,
    /// The coordinate reference system found (from `.prj`, the GeoJSON `crs` member, the
    /// GeoPackage `gpkg_spatial_ref_sys`, or WGS84 for OSM and RFC 7946 GeoJSON).
    pub crs: Crs,
    /// The features that were read, in file order.
    pub features: Vec<Feature>,
    /// What was read and what was refused.
    pub report: ImportReport,
}

impl Layer {
    /// The kind of geometry the layer holds.
    pub fn kind(&self) -> LayerKind {
        use geo_types::Geometry as G;
        let mut kind = None;
        for f in &self.features {
            let k = match f.geometry {
                G::Polygon(_) | G::MultiPolygon(_) | G::Rect(_) | G::Triangle(_) => {
                    LayerKind::Polygons
                }
                G::LineString(_) | G::MultiLineString(_) | G::Line(_) => LayerKind::Lines,
                G::Point(_) | G::MultiPoint(_) => LayerKind::Points,
                G::GeometryCollection(_) => LayerKind::Mixed,
            };
            match kind {
                None => kind = Some(k),
                Some(prev) if prev != k => return LayerKind::Mixed,
                _ => {}
            }
        }
        kind.unwrap_or(LayerKind::Mixed)
    }
}

/// What went wrong reading a file. Every variant names the file; variants that come from a
/// library keep its error as their source.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be opened or read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A companion file a format needs is missing (`.dbf` for a Shapefile).
    #[error("{file}: missing companion file {missing} ({why})")]
    MissingCompanion {
        /// The main file.
        file: PathBuf,
        /// The missing file.
        missing: PathBuf,
        /// Why it is needed.
        why: String,
    },
    /// The file is empty, or holds no data at all.
    #[error("{file}: the file is empty ({what})")]
    Empty {
        /// The file.
        file: PathBuf,
        /// What was expected.
        what: String,
    },
    /// The file ends before its own structure says it should.
    #[error("{file}: truncated: {what}")]
    Truncated {
        /// The file.
        file: PathBuf,
        /// Where and how.
        what: String,
    },
    /// The file is not in the format its name says, or is corrupt (found by this crate's own
    /// checks).
    #[error("{file}: {message}")]
    Format {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The `shapefile` crate could not read the `.shp` / `.shx`.
    #[error("{file}: {what}: {source}")]
    Shapefile {
        /// The file.
        file: PathBuf,
        /// What was being read.
        what: String,
        /// The reader's error.
        #[source]
        source: shapefile::Error,
    },
    /// The `dbase` crate could not read the `.dbf` table.
    #[error("{file}: {what}: {source}")]
    Dbase {
        /// The file.
        file: PathBuf,
        /// What was being read.
        what: String,
        /// The reader's error.
        #[source]
        source: shapefile::dbase::Error,
    },
    /// The file is not valid JSON.
    #[error("{file}: not valid JSON: {source}")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's error.
        #[source]
        source: serde_json::Error,
    },
    /// SQLite could not read the GeoPackage.
    #[cfg(feature = "gpkg")]
    #[error("{file}: {what}: {source}")]
    Sqlite {
        /// The file.
        file: PathBuf,
        /// What was being read.
        what: String,
        /// SQLite's error.
        #[source]
        source: rusqlite::Error,
    },
    /// The `osmpbf` crate could not read the file.
    #[cfg(feature = "osm")]
    #[error("{file}: not a readable OSM PBF file: {source}")]
    Pbf {
        /// The file.
        file: PathBuf,
        /// The reader's error.
        #[source]
        source: osmpbf::Error,
    },
    /// The file's CRS (`.prj`, `crs` member, `gpkg_spatial_ref_sys`) is unknown or unusable.
    #[error("{file}: CRS from {from}: {source}; {}", crs_hint(.source))]
    Crs {
        /// The file.
        file: PathBuf,
        /// Where the CRS was read.
        from: String,
        /// Why it is unusable.
        #[source]
        source: CrsError,
    },
    /// The format is not supported (unknown extension, or a Cargo feature left out).
    #[error("{file}: unsupported input: {message}")]
    Unsupported {
        /// The file.
        file: PathBuf,
        /// Why.
        message: String,
    },
}

/// Which features to read from a multi-theme source such as an OSM file or a GeoPackage.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Theme {
    /// Whatever the file holds (a Shapefile, a GeoJSON, the first feature table of a GeoPackage).
    #[default]
    Any,
    /// Building footprints (OSM `building=*`; a GeoPackage table named like `buildings`).
    Buildings,
    /// Street centre lines (OSM `highway=*`; a GeoPackage table named like `streets`).
    Streets,
    /// Cadastral parcels (a GeoPackage table named like `plots` or `parcels`).
    Parcels,
    /// A named table of a GeoPackage.
    Table(String),
}

/// Which attribute columns a reader keeps (a projection of the attribute table).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Columns {
    /// Every column.
    #[default]
    All,
    /// Only the columns of these names (exact, case-sensitive); the others are not parsed
    /// where the format allows it (the Shapefile reader skips their `.dbf` bytes), else
    /// dropped after reading.
    Only(std::collections::BTreeSet<String>),
}

impl Columns {
    /// The projection on the given names.
    pub fn only<S: Into<String>>(names: impl IntoIterator<Item = S>) -> Self {
        Columns::Only(names.into_iter().map(Into::into).collect())
    }

    /// True when the column `name` is kept.
    pub fn wants(&self, name: &str) -> bool {
        match self {
            Columns::All => true,
            Columns::Only(set) => set.contains(name),
        }
    }
}

/// Reads a layer, choosing the reader by the file's extension (`.shp`, `.geojson`/`.json`,
/// `.gpkg`, `.osm.pbf`/`.pbf`). A GeoPackage path may name a table as `file.gpkg:table`.
///
/// # Errors
/// [`ImportError`] naming the file when it cannot be read at all. Features that cannot be read are
/// not errors: they are refused in the layer's [`ImportReport`].
pub fn read_layer(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    read_layer_with(path, theme, &Columns::All)
}

/// [`read_layer`] keeping only the attribute `columns` asked for. A Shapefile's other columns
/// are not parsed at all (so a value that cannot be read in a column not asked for costs its
/// feature nothing); other formats drop them after reading.
///
/// # Errors
/// As [`read_layer`].
pub fn read_layer_with(
    path: &Path,
    theme: &Theme,
    columns: &Columns,
) -> Result<Layer, ImportError> {
    read_layer_with_stated_crs(path, theme, columns, None)
}

/// What a user can do about a CRS that cannot be used.
fn crs_hint(_: &CrsError) -> &'static str {
    "state the CRS instead: `--crs EPSG:XXXX` on the command line overrides the file's"
}

/// [`read_layer_with`] with a CRS `stated` by the caller: a Shapefile's `.prj` is then not read
/// (one that cannot be understood does not stop the import) and the layer is in the stated CRS.
/// Other formats are read as usual (the caller applies the stated CRS to the layer).
///
/// # Errors
/// As [`read_layer`].
pub fn read_layer_with_stated_crs(
    path: &Path,
    theme: &Theme,
    columns: &Columns,
    stated: Option<&Crs>,
) -> Result<Layer, ImportError> {
    let s = path.to_string_lossy();
    if s.to_ascii_lowercase().ends_with(".shp") {
        return shp::read_with_stated_crs(path, columns, stated);
    }
    let mut layer = read_any(path, theme)?;
    if let Columns::Only(_) = columns {
        for f in &mut layer.features {
            f.attributes.retain(|k, _| columns.wants(k));
        }
    }
    Ok(layer)
}

fn read_any(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    let s = path.to_string_lossy();
    let lower = s.to_ascii_lowercase();
    if let Some(idx) = lower.find(".gpkg:") {
        let (file, table) = s.split_at(idx + 5);
        return read_gpkg(Path::new(file), &Theme::Table(table[1..].to_string()));
    }
    if lower.ends_with(".shp") {
        shp::read(path)
    } else if lower.ends_with(".geojson") || lower.ends_with(".json") {
        geojson_reader::read(path)
    } else if lower.ends_with(".gpkg") {
        read_gpkg(path, theme)
    } else if lower.ends_with(".pbf") {
        read_osm(path, theme)
    } else {
        Err(ImportError::Unsupported {
            file: path.to_path_buf(),
            message: "unknown extension (expected .shp, .geojson, .json, .gpkg or .osm.pbf)".into(),
        })
    }
}

#[cfg(feature = "gpkg")]
fn read_gpkg(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    gpkg::read(path, theme)
}
#[cfg(not(feature = "gpkg"))]
fn read_gpkg(path: &Path, _theme: &Theme) -> Result<Layer, ImportError> {
    Err(ImportError::Unsupported {
        file: path.to_path_buf(),
        message: "GeoPackage support was left out of this build (Cargo feature `gpkg`)".into(),
    })
}
#[cfg(feature = "osm")]
fn read_osm(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    osm::read(path, theme)
}
#[cfg(not(feature = "osm"))]
fn read_osm(path: &Path, _theme: &Theme) -> Result<Layer, ImportError> {
    Err(ImportError::Unsupported {
        file: path.to_path_buf(),
        message: "OSM PBF support was left out of this build (Cargo feature `osm`)".into(),
    })
}
