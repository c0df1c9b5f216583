//! Line and scatter plots to PNG or SVG (plotters).
//!
//! PNG text is drawn with DejaVu Sans, shipped in `assets/fonts/` (license next to it) and
//! registered with plotters once, so that plots look the same on every machine.

use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

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

/// What went wrong writing a plot. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The extension names no format plots are written in.
    #[error("{file}: unknown plot format (expected .png or .svg)")]
    Format {
        /// The output file.
        file: PathBuf,
    },
    /// The file could not be written (see [`crate::output`]).
    #[error(transparent)]
    Write(#[from] crate::output::OutputError),
    /// plotters failed to draw.
    #[error("{file}: drawing the plot failed: {source}")]
    Draw {
        /// The output file.
        file: PathBuf,
        /// plotters' error (its type depends on the backend).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The PNG could not be encoded or written.
    #[error("{file}: writing the image failed: {source}")]
    Image {
        /// The output file.
        file: PathBuf,
        /// What `image` said.
        #[source]
        source: image::ImageError,
    },
}

/// DejaVu Sans (Bitstream Vera license; see `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the shipped font as plotters' `sans-serif` (idempotent).
fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TrueType font shipped with the crate; failure would be a
        // packaging error, reported as missing text rather than a panic.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Image size of written plots, pixels.
pub const PLOT_SIZE: (u32, u32) = (1024, 576);

/// A palette that stays readable in print: black, grey-blue, orange, green, red, purple.
const COLOURS: [RGBColor; 6] = [
    RGBColor(0, 0, 0),
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
];

/// Writes a plot; the format follows the extension (`.png` or `.svg`).
pub fn write_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    kind: PlotKind,
) -> Result<(), PlotError> {
    let draw_err = |source: Box<dyn std::error::Error + Send + Sync>| PlotError::Draw {
        file: path.to_path_buf(),
        source,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    register_font();
    match ext.as_deref() {
        Some("svg") => {
            let mut text = String::new();
            {
                let backend = SVGBackend::with_string(&mut text, PLOT_SIZE);
                draw(backend, title, x_label, y_label, series, kind)
                    .map_err(|e| draw_err(e.into()))?;
            }
            crate::output::write_bytes(path, text)?;
            Ok(())
        }
        Some("png") => {
            let (w, h) = PLOT_SIZE;
            let mut buf = vec![0u8; (w * h * 3) as usize];
            {
                let backend = BitMapBackend::with_buffer(&mut buf, PLOT_SIZE);
                draw(backend, title, x_label, y_label, series, kind)
                    .map_err(|e| draw_err(e.into()))?;
            }
            let img = image::RgbImage::from_raw(w, h, buf)
                .expect("the buffer was allocated as width × height × 3");
            crate::output::write_png(path, &img)
                .map(drop)
                .map_err(|source| PlotError::Image {
                    file: path.to_path_buf(),
                    source,
                })
        }
        _ => Err(PlotError::Format {
            file: path.to_path_buf(),
        }),
    }
}

/// Range of `values` padded by 5 % (a unit range around a single value; 0..1 when empty).
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Tick labels that stay readable from microseconds to millions of triangles.
fn fmt_tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 || a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 0.1 {
        format!("{v:.2}")
    } else {
        format!("{v:.1e}")
    }
}

fn draw<DB: DrawingBackend>(
    backend: DB,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    kind: PlotKind,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let root = backend.into_drawing_area();
    root.fill(&WHITE)?;
    let (x0, x1) = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let (y0, y1) = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    // Times and counts are never negative: start the y axis at 0 when all values are.
    let y0 = if y0 < 0.0 && series.iter().all(|s| s.points.iter().all(|p| p.1 >= 0.0)) {
        0.0
    } else {
        y0
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&fmt_tick)
        .y_label_formatter(&fmt_tick)
        .label_style(("sans-serif", 14))
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        let width = if kind == PlotKind::Lines { 2 } else { 1 };
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(width)))?
            .label(s.name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        if kind == PlotKind::Points {
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
        }
    }
    if series.iter().any(|s| !s.name.is_empty()) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo() -> Vec<Series> {
        vec![
            Series {
                name: "series one".into(),
                points: (0..50)
                    .map(|i| (i as f64, (i as f64 * 0.2).sin() + 2.0))
                    .collect(),
            },
            Series {
                name: "series two".into(),
                points: (0..50).map(|i| (i as f64, 3.5)).collect(),
            },
        ]
    }

    #[test]
    fn png_has_ink_in_both_colours_and_text() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.png");
        write_plot(&p, "frame time", "frame", "s", &demo(), PlotKind::Lines).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), PLOT_SIZE);
        let black = img.pixels().filter(|p| p.0 == [0, 0, 0]).count();
        let blue = img.pixels().filter(|p| p.0 == [31, 119, 180]).count();
        assert!(black > 100, "black series, axes and text drawn");
        assert!(blue > 100, "second series drawn");
        // Text rendered with the shipped font leaves anti-aliased grey pixels.
        let grey = img
            .pixels()
            .filter(|p| p.0[0] == p.0[1] && p.0[1] == p.0[2] && p.0[0] > 20 && p.0[0] < 200)
            .count();
        assert!(grey > 50, "anti-aliased text present: {grey}");
    }

    #[test]
    fn svg_names_every_series_and_bad_extension_fails() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.svg");
        write_plot(&p, "frame time", "frame", "s", &demo(), PlotKind::Points).unwrap();
        let s = std::fs::read_to_string(&p).unwrap();
        assert!(s.contains("<svg") && s.contains("series one") && s.contains("series two"));
        let bad = write_plot(
            &dir.path().join("t.gif"),
            "",
            "",
            "",
            &demo(),
            PlotKind::Lines,
        );
        let e = bad.unwrap_err();
        assert!(
            matches!(&e, PlotError::Format { file } if file.ends_with("t.gif")),
            "{e:?}"
        );
        assert!(e.to_string().contains("t.gif"), "{e}");
        // An SVG into a missing directory: the write error names the file and keeps the cause.
        let missing = dir.path().join("no such dir").join("t.svg");
        let e = write_plot(&missing, "", "", "", &demo(), PlotKind::Lines).unwrap_err();
        assert!(
            matches!(&e, PlotError::Write(o) if o.path() == missing),
            "{e:?}"
        );
        assert!(e.to_string().contains("t.svg"), "{e}");
        assert!(std::error::Error::source(&e).is_some());
        // A PNG into a missing directory: the image crate's error is kept.
        let missing = dir.path().join("no such dir").join("t.png");
        let e = write_plot(&missing, "", "", "", &demo(), PlotKind::Lines).unwrap_err();
        assert!(
            matches!(&e, PlotError::Image { file, source: image::ImageError::IoError(_) } if file == &missing),
            "{e:?}"
        );
    }
}
