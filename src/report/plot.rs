//! Line and scatter plots to PNG or SVG (plotters).

use std::path::Path;

/// One named series of (x, y) points.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// Points in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// How series are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlotKind {
    /// Connected lines (e.g. frame time along a route).
    Lines,
    /// Points joined by thin lines with markers (e.g. error against run time).
    Points,
}

/// What went wrong writing a plot.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Drawing or writing failed.
    #[error("{file}: {message}")]
    Draw {
        /// The output file.
        file: std::path::PathBuf,
        /// What failed.
        message: String,
    },
}

/// Writes a plot; the format follows the extension (`.png` or `.svg`).
pub fn write_plot(
    path: &Path,
    _title: &str,
    _x_label: &str,
    _y_label: &str,
    _series: &[Series],
    _kind: PlotKind,
) -> Result<(), PlotError> {
    Err(PlotError::Draw {
        file: path.to_path_buf(),
        message: "plotting not yet implemented".into(),
    })
}
