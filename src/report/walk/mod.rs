//! Writes a [`WalkRecord`] (seed 003 §5.1, Fig. 4 and Table 1): per-frame CSV, the Table-1
//! summary as Markdown, one JSON object, frame-time and triangle plots along the route, the kept
//! frames as PNG, and a self-contained HTML page that links them.
//!
//! - [`csv`]: the per-frame table.
//! - [`markdown`]: Table 1.
//! - [`html`]: the page.

pub mod csv;
pub mod html;
pub mod markdown;

use crate::report::plot::{write_plot, PlotError, PlotKind, Series};
use crate::walk::{CullMode, FrameRecord, WalkRecord};
use std::path::{Path, PathBuf};

/// What went wrong while writing a report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file or folder could not be written.
    #[error("writing {}", file.display())]
    Write {
        /// The file.
        file: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A frame could not be saved.
    #[error("saving the frame {}", file.display())]
    Image {
        /// The file.
        file: PathBuf,
        /// The cause.
        #[source]
        source: image::ImageError,
    },
    /// A plot failed.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// One JSON object: settings, summary, notes, false culls (the per-frame rows are in the CSV).
pub fn json(record: &WalkRecord) -> serde_json::Value {
    let mut j = serde_json::json!({
        "city": record.city,
        "route": record.route,
        "frames": record.cameras.len(),
        "renderer": record.renderer,
        "summary": record.summary,
        "false_culls": record.false_culls(),
        "notes": record.notes,
        "total_s": record.total_s,
        "occlusion_decision": record.occlusion_decision,
    });
    // The far field: its object, and its headline figures at the top level (`coverage_error_max`,
    // `psnr_min`, `silhouette_px_max`, `far_nodes`, `frame_time_ratio_vs_mesh`, …).
    if let (Some(d), Some(o)) = (&record.far_decision, &record.far_options) {
        let f = crate::walk::far_json(&record.far, d, o);
        if let Some(m) = f.as_object() {
            for (k, v) in m {
                j[k.as_str()] = v.clone();
            }
        }
        j["far_used"] = serde_json::json!(d.used);
        j["far"] = f;
    }
    j
}

/// Frame time along the route, mesh-only against hybrid, in the last culling mode of the far
/// records.
fn far_series(record: &WalkRecord) -> Vec<Series> {
    let mode = record.far.last().map(|r| r.mode);
    let rows: Vec<&crate::walk::FarRecord> =
        record.far.iter().filter(|r| Some(r.mode) == mode).collect();
    vec![
        Series {
            name: "mesh only".into(),
            points: rows
                .iter()
                .map(|r| (r.frame as f64, r.mesh_frame_s * 1e3))
                .collect(),
        },
        Series {
            name: "meshes + BlockMaps".into(),
            points: rows
                .iter()
                .map(|r| (r.frame as f64, r.frame_s * 1e3))
                .collect(),
        },
    ]
}

/// One series per structure of `value` along the route, for `mode`.
fn series(record: &WalkRecord, mode: CullMode, value: impl Fn(&FrameRecord) -> f64) -> Vec<Series> {
    record
        .structures()
        .into_iter()
        .map(|st| Series {
            points: record
                .frames
                .iter()
                .filter(|r| r.structure == st && r.mode == mode)
                .map(|r| (r.frame as f64, value(r)))
                .collect(),
            name: st.name(),
        })
        .collect()
}

/// A file-name tag for a mode (`frustum`, `frustum_occlusion`).
pub fn mode_tag(mode: CullMode) -> String {
    mode.name().replace('+', "_")
}

/// Writes `frames.csv`, `summary.md`, `report.json`, the plots (`frame_time_<mode>.png/.svg`,
/// `triangles_<mode>.png/.svg`), the kept frames (`frames/frame_NNNN.png`, or under
/// `frames_dir`) and `report.html`, which links them all. Returns the files written.
///
/// # Errors
/// [`ReportError`] naming the file that could not be written.
pub fn write(
    record: &WalkRecord,
    dir: &Path,
    frames_dir: Option<&Path>,
) -> Result<Vec<PathBuf>, ReportError> {
    let werr = |file: &Path| {
        let file = file.to_path_buf();
        move |source| ReportError::Write { file, source }
    };
    std::fs::create_dir_all(dir).map_err(werr(dir))?;
    let mut written = Vec::new();
    let mut put = |name: &str, text: String| -> Result<(), ReportError> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(werr(&p))?;
        written.push(p);
        Ok(())
    };
    put("frames.csv", csv::frames_csv(record))?;
    put("summary.md", markdown::summary_markdown(&record.summary))?;
    put(
        "report.json",
        serde_json::to_string_pretty(&json(record)).unwrap_or_default(),
    )?;
    if !record.far.is_empty() {
        put("far_frames.csv", csv::far_csv(record))?;
    }
    let mut plots = Vec::new();
    for mode in record.modes() {
        let tag = mode_tag(mode);
        let ft = series(record, mode, |r| r.frame_s);
        let tri = series(record, mode, |r| r.triangles as f64);
        for ext in ["png", "svg"] {
            let p = dir.join(format!("frame_time_{tag}.{ext}"));
            write_plot(
                &p,
                &format!("Time per frame along the {} route ({mode})", record.route),
                "frame",
                "seconds",
                &ft,
                PlotKind::Lines,
            )?;
            written.push(p);
            let q = dir.join(format!("triangles_{tag}.{ext}"));
            write_plot(
                &q,
                &format!("Triangles drawn along the {} route ({mode})", record.route),
                "frame",
                "triangles",
                &tri,
                PlotKind::Lines,
            )?;
            written.push(q);
        }
        plots.push(mode);
    }
    if !record.far.is_empty() {
        let ft = far_series(record);
        for ext in ["png", "svg"] {
            let p = dir.join(format!("far_frame_time.{ext}"));
            write_plot(
                &p,
                &format!(
                    "Mesh-only vs hybrid frame time along the {} route",
                    record.route
                ),
                "frame",
                "milliseconds",
                &ft,
                PlotKind::Lines,
            )?;
            written.push(p);
        }
    }
    let fdir = frames_dir
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join("frames"));
    let mut frame_files = Vec::new();
    if !record.images.is_empty() {
        std::fs::create_dir_all(&fdir).map_err(werr(&fdir))?;
        for (f, img) in &record.images {
            let p = fdir.join(format!("frame_{f:04}.png"));
            img.save(&p).map_err(|source| ReportError::Image {
                file: p.clone(),
                source,
            })?;
            frame_files.push((*f, p.clone()));
            written.push(p);
        }
    }
    let page = html::page(record, dir, &plots, &frame_files);
    let p = dir.join("report.html");
    std::fs::write(&p, page).map_err(werr(&p))?;
    written.push(p);
    Ok(written)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geom::Camera;
    use crate::index::{CullStats, Structure};
    use crate::walk::summarise;
    use glam::DVec3;

    /// A small record: 3 frames × {bqr, flat} × {frustum, frustum+occlusion}, one image.
    pub(crate) fn record() -> WalkRecord {
        let mut frames = Vec::new();
        for f in 0..3 {
            for s in [Structure::Bqr, Structure::Flat] {
                for mode in [CullMode::Frustum, CullMode::FrustumOcclusion] {
                    frames.push(FrameRecord {
                        frame: f,
                        structure: s,
                        mode,
                        cull_s: 1e-5,
                        render_s: Some(2e-3),
                        frame_s: 2e-3 + 1e-5,
                        stats: CullStats::default(),
                        blocks: 4,
                        triangles: 120 + f as u64,
                        false_culls: Some(0),
                    });
                }
            }
        }
        WalkRecord {
            city: "Test <city>".into(),
            route: "paper".into(),
            cameras: (0..3)
                .map(|i| Camera::new(DVec3::new(i as f64, 0.0, 1.7), 0.0, 0.0))
                .collect(),
            summary: summarise(&frames, Structure::Bqr),
            frames,
            renderer: "test".into(),
            images: vec![(0, image::RgbaImage::new(4, 3))],
            notes: vec!["a note & more".into()],
            total_s: 0.5,
            far: Vec::new(),
            far_decision: None,
            far_options: None,
            occlusion_decision: None,
        }
    }

    #[test]
    fn writes_every_file_and_links_them() {
        let dir = tempfile::tempdir().unwrap();
        let r = record();
        let files = write(&r, dir.path(), None).unwrap();
        let names: Vec<String> = files
            .iter()
            .map(|p| {
                p.strip_prefix(dir.path())
                    .unwrap()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        for want in [
            "frames.csv",
            "summary.md",
            "report.json",
            "frame_time_frustum.png",
            "frame_time_frustum_occlusion.svg",
            "triangles_frustum.svg",
            "frames/frame_0000.png",
            "report.html",
        ] {
            assert!(
                names.iter().any(|n| n == want),
                "{want} missing from {names:?}"
            );
        }
        for f in &files {
            assert!(
                std::fs::metadata(f).unwrap().len() > 0,
                "{} is empty",
                f.display()
            );
        }
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
                .unwrap();
        assert_eq!(json["frames"], 3);
        assert_eq!(json["false_culls"], 0);
        assert_eq!(json["summary"].as_array().unwrap().len(), 4);
        assert_eq!(json["summary"][0]["structure"], "bqr");
        assert_eq!(json["summary"][1]["mode"], "frustum+occlusion");
    }

    #[test]
    fn an_unwritable_folder_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, "x").unwrap();
        let e = write(&record(), &blocker.join("sub"), None).unwrap_err();
        assert!(matches!(e, ReportError::Write { ref file, .. } if file.ends_with("sub")));
    }
}
