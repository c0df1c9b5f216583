//! Reads cadastral and street layers into neutral, format-free layers.
//!
//! Every reader returns a [`Layer`]: geo-types geometry in the file's own coordinates (f64), the
//! attributes of each feature, the coordinate reference system found ([`Crs`]) and an
//! [`ImportReport`] that accounts for every feature read (imported, or refused with a reason).
//! Geometric repair of footprints (ring closing, winding, spikes, self-intersections) is the city
//! model's job; this crate refuses only what cannot be read at all (NaN, empty geometry, truncated
//! records) and says why.
//!
//! This crate knows nothing of `blockwalk`: it can be used alone to read cadastral data.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod crs;
pub mod geojson_reader;
#[cfg(feature = "gpkg")]
pub mod gpkg;
#[cfg(feature = "osm")]
pub mod osm;
pub mod report;
mod rings;
pub mod shp;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use crs::{Crs, MetricTransform};
pub use report::{ImportReport, Refusal};

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
    /// The value as a number, parsing text such as `"12.5"` or `"12.13 m"`; `None` for null,
    /// booleans and text that holds no leading number.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            AttrValue::Int(i) => Some(*i as f64),
            AttrValue::Float(f) if f.is_finite() => Some(*f),
            AttrValue::Text(s) => {
                let t = s.trim();
                let end = t
                    .char_indices()
                    .find(|(_, c)| !(c.is_ascii_digit() || *c == '.' || *c == '-' || *c == '+'))
                    .map(|(i, _)| i)
                    .unwrap_or(t.len());
                t[..end].parse::<f64>().ok().filter(|v| v.is_finite())
            }
            _ => None,
        }
    }
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

/// What went wrong reading a file. Every variant names the file.
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
    /// A companion file a format needs is missing (`.shx`, `.dbf` for a Shapefile).
    #[error("{file}: missing companion file {missing} ({why})")]
    MissingCompanion {
        /// The main file.
        file: PathBuf,
        /// The missing file.
        missing: PathBuf,
        /// Why it is needed.
        why: String,
    },
    /// The file is not in the format its name says, or is truncated or corrupt.
    #[error("{file}: {message}")]
    Format {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        message: String,
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

/// Reads a layer, choosing the reader by the file's extension (`.shp`, `.geojson`/`.json`,
/// `.gpkg`, `.osm.pbf`/`.pbf`). A GeoPackage path may name a table as `file.gpkg:table`.
///
/// # Errors
/// [`ImportError`] naming the file when it cannot be read at all. Features that cannot be read are
/// not errors: they are refused in the layer's [`ImportReport`].
pub fn read_layer(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
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
