//! Elevation grids (DEMs) read from GeoTIFF.
//!
//! [`read_dem`] reads a single-band GeoTIFF (strips or tiles; 8/16/32-bit integers, 32/64-bit
//! floats) with its georeferencing (GeoKeys: the CRS, the pixel-is-area / pixel-is-point
//! convention, the tie point and pixel scale or a model transformation) and its nodata value
//! (GDAL's `GDAL_NODATA` tag).

use std::path::{Path, PathBuf};

use crate::Crs;

/// What a GeoTIFF's pixel values stand for (the GeoKey `GTRasterTypeGeoKey`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PixelIs {
    /// A value is the mean over the pixel's square; the tie point is the square's corner
    /// (`RasterPixelIsArea`, the default).
    Area,
    /// A value is a sample at a point; the tie point is that point (`RasterPixelIsPoint`).
    Point,
}

/// A regular elevation grid in its own CRS.
///
/// Sample `(col, row)` (row 0 is the first row of the file) lies at the CRS position
/// `x = transform[0] + transform[1]·col + transform[2]·row`,
/// `y = transform[3] + transform[4]·col + transform[5]·row`: the affine map is to the
/// *sample's position* (a pixel-is-area file's pixel centre), so the convention is already
/// applied and a consumer never adds half a pixel.
#[derive(Clone, Debug)]
pub struct DemGrid {
    /// The file read.
    pub source: PathBuf,
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Elevations in metres, row-major (`values[row * width + col]`); nodata is `NaN`.
    pub values: Vec<f64>,
    /// Sample (col, row) → CRS position; see the type's documentation.
    pub transform: [f64; 6],
    /// The grid's CRS from its GeoKeys ([`Crs::Unknown`] when it has none).
    pub crs: Crs,
    /// The pixel convention the file declares.
    pub pixel_is: PixelIs,
    /// The file's nodata value, if it declares one.
    pub nodata: Option<f64>,
    /// Samples that are nodata (the declared value, or not finite).
    pub nodata_count: usize,
    /// The sample type as stored (`int16`, `float32`, …).
    pub sample_type: String,
    /// `strips` or `tiles`.
    pub layout: &'static str,
}

/// Why a DEM could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened or read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not a GeoTIFF this reader can use (and why).
    #[error("{file}: {problem}")]
    Format {
        /// The file.
        file: String,
        /// What is wrong.
        problem: String,
    },
}

/// Reads a single-band GeoTIFF elevation grid.
///
/// # Errors
/// [`DemError`] naming the file and the problem.
pub fn read_dem(path: &Path) -> Result<DemGrid, DemError> {
    Err(DemError::Format {
        file: path.display().to_string(),
        problem: "GeoTIFF reading is not implemented yet".into(),
    })
}
