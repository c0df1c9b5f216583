//! Writes a [`WalkRecord`] (Pina, Serón and Cerezo, §5.1, Fig. 4 and Table 1): per-frame CSV, the Table-1
//! summary as Markdown, one JSON object, frame-time and triangle plots along the route, the kept
//! frames as PNG, and a self-contained HTML page that links them.
//!
//! - [`csv`]: the per-frame table.
//! - [`markdown`]: Table 1.
//! - [`html`]: the page (every picture embedded: it opens alone).
//! - [`map`]: the city in plan view with the route.
//! - [`context`]: what the report needs besides the record (plan, machine, command).

pub mod context;
pub mod csv;
pub mod html;
pub mod map;
pub mod markdown;
pub mod verdict;

pub use context::{Machine, Plan, ReportContext};

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
    json_with(record, &ReportContext::default())
}

/// The figures of one frame of one structure, times in ms, as the page shows them.
fn frame_json(r: &FrameRecord) -> serde_json::Value {
    serde_json::json!({
        "frame": r.frame,
        "structure": r.structure,
        "mode": r.mode,
        "cull_ms": r.cull_s * 1e3,
        "render_ms": r.render_s.map(|v| v * 1e3),
        "frame_ms": r.frame_s * 1e3,
        "blocks": r.blocks,
        "buildings": r.buildings,
        "triangles": r.triangles,
        "nodes_visited": r.stats.nodes_visited,
        "false_culls": r.false_culls,
    })
}

/// The far-field figures of one hybrid frame, times in ms.
fn far_frame_json(r: &crate::walk::FarRecord) -> serde_json::Value {
    serde_json::json!({
        "frame": r.frame,
        "mode": r.mode,
        "select_ms": r.select_s * 1e3,
        "render_ms": r.render_s.map(|v| v * 1e3),
        "frame_ms": r.frame_s * 1e3,
        "mesh_frame_ms": r.mesh_frame_s * 1e3,
        "mesh_blocks": r.mesh_blocks,
        "mesh_triangles": r.mesh_triangles,
        "far_nodes": r.far_nodes,
        "far_blocks": r.far_blocks,
        "coverage_error": r.image.map(|i| i.coverage_error),
        "psnr_db": r.image.map(|i| i.psnr_db).filter(|v| v.is_finite()),
    })
}

/// The culling mode the kept images were drawn in (the last block culling mode walked: the
/// per-building modes keep no image).
pub fn image_mode(record: &WalkRecord) -> Option<CullMode> {
    record.modes().into_iter().rfind(|m| !m.buildings())
}

/// The per-frame figures shown under a kept frame: one row per structure in
/// [`image_mode`], and the far field's record of that frame and mode, when there is one.
pub fn kept_frame_rows(
    record: &WalkRecord,
    frame: usize,
) -> (Vec<&FrameRecord>, Option<&crate::walk::FarRecord>) {
    let mode = image_mode(record);
    let rows = record
        .frames
        .iter()
        .filter(|r| r.frame == frame && Some(r.mode) == mode)
        .collect();
    let far_mode = record.far.last().map(|r| r.mode);
    let far = record
        .far
        .iter()
        .find(|r| r.frame == frame && Some(r.mode) == far_mode);
    (rows, far)
}

/// [`json`] with the machine, the command, every per-frame figure (times in ms) and the
/// figures of the kept frames, as `report.html` shows them.
pub fn json_with(record: &WalkRecord, ctx: &ReportContext) -> serde_json::Value {
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
        "buildings_decision": record.buildings_decision,
    });
    // The far field: its object, and its headline figures at the top level (`coverage_error_max`,
    // `psnr_min`, `silhouette_px_max`, `far_nodes`, `frame_time_ratio_vs_mesh`, …).
    if let Some(summary) = record.far_summary() {
        let f = serde_json::to_value(&summary).unwrap_or_default();
        if let Some(m) = f.as_object() {
            for (k, v) in m {
                j[k.as_str()] = v.clone();
            }
        }
        j["far_used"] = serde_json::json!(summary.used);
        j["far"] = f;
    }
    j["total_ms"] = serde_json::json!(record.total_s * 1e3);
    j["machine"] = serde_json::json!(ctx.machine);
    j["command"] = serde_json::json!(ctx.command);
    j["per_frame"] = record.frames.iter().map(frame_json).collect();
    if !record.far.is_empty() {
        j["far_frames"] = record.far.iter().map(far_frame_json).collect();
    }
    j["kept_frames"] = record
        .images
        .iter()
        .map(|(f, _)| {
            let (rows, far) = kept_frame_rows(record, *f);
            let pos = record
                .cameras
                .get(*f)
                .map(|c| [c.position.x, c.position.y, c.position.z]);
            serde_json::json!({
                "frame": f,
                "mode": image_mode(record),
                "position": pos,
                "structures": rows.into_iter().map(frame_json).collect::<Vec<_>>(),
                "far": far.map(far_frame_json),
            })
        })
        .collect();
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
            name: format!(
                "meshes + {}",
                record
                    .far_decision
                    .as_ref()
                    .map_or("far field", |d| d.representation.as_str())
            ),
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

/// [`write_with`] without a plan, machine or command (the page says they are unknown).
///
/// # Errors
/// [`ReportError`] naming the file that could not be written.
pub fn write(
    record: &WalkRecord,
    dir: &Path,
    frames_dir: Option<&Path>,
) -> Result<Vec<PathBuf>, ReportError> {
    write_with(record, dir, frames_dir, &ReportContext::default())
}

/// Long side of a frame's thumbnail in the page's strip, pixels.
pub const THUMB_SIZE: u32 = 320;

/// `bytes` as a `data:` URL of type `mime`.
fn data_url(mime: &str, bytes: &[u8]) -> String {
    use base64::Engine as _;
    format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// Writes `frames.csv`, `summary.md`, `report.json`, the plots (`frame_time_<mode>.png/.svg`,
/// `triangles_<mode>.png/.svg`, times in ms), the kept frames (`frames/frame_NNNN.png`, or under
/// `frames_dir`) and `report.html`, which embeds the plots, the route map drawn from
/// `ctx.plan` and thumbnails of the frames, so that it opens alone. Returns the files written.
///
/// # Errors
/// [`ReportError`] naming the file that could not be written.
pub fn write_with(
    record: &WalkRecord,
    dir: &Path,
    frames_dir: Option<&Path>,
    ctx: &ReportContext,
) -> Result<Vec<PathBuf>, ReportError> {
    let werr = |file: &Path| {
        let file = file.to_path_buf();
        move |source| ReportError::Write { file, source }
    };
    std::fs::create_dir_all(dir).map_err(werr(dir))?;
    let mut written = Vec::new();
    let mut put = |name: &str, text: String| -> Result<(), ReportError> {
        let p = dir.join(name);
        crate::output::write_bytes(&p, text)
            .map(drop)
            .map_err(crate::output::OutputError::into_io)
            .map_err(werr(&p))?;
        written.push(p);
        Ok(())
    };
    put("frames.csv", csv::frames_csv(record))?;
    let mut md: String = verdict::conclusion(record)
        .iter()
        .map(|l| format!("{l}\n\n"))
        .collect();
    md.push_str(&markdown::summary_markdown(&record.summary));
    put("summary.md", md)?;
    put(
        "report.json",
        serde_json::to_string_pretty(&json_with(record, ctx)).unwrap_or_default(),
    )?;
    if !record.far.is_empty() {
        put("far_frames.csv", csv::far_csv(record))?;
    }
    let mut plots = Vec::new();
    for mode in record.modes() {
        let tag = mode_tag(mode);
        let ft = series(record, mode, |r| r.frame_s * 1e3);
        let tri = series(record, mode, |r| r.triangles as f64);
        for ext in ["png", "svg"] {
            let p = dir.join(format!("frame_time_{tag}.{ext}"));
            write_plot(
                &p,
                &format!("Time per frame along the {} route ({mode})", record.route),
                "frame",
                "milliseconds",
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
        let png = |name: String| -> Result<String, ReportError> {
            let p = dir.join(name);
            let bytes = std::fs::read(&p).map_err(werr(&p))?;
            Ok(data_url("image/png", &bytes))
        };
        plots.push(html::ModePlots {
            mode,
            frame_time: png(format!("frame_time_{tag}.png"))?,
            triangles: png(format!("triangles_{tag}.png"))?,
        });
    }
    let mut far_plot = None;
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
        let p = dir.join("far_frame_time.png");
        let bytes = std::fs::read(&p).map_err(werr(&p))?;
        far_plot = Some(data_url("image/png", &bytes));
    }
    let mut extra = Vec::new();
    for (caption, p) in &ctx.extra_plots {
        let bytes = std::fs::read(p).map_err(werr(p))?;
        extra.push((caption.clone(), data_url("image/png", &bytes)));
    }
    let fdir = frames_dir
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join("frames"));
    let mut thumbs = Vec::new();
    if !record.images.is_empty() {
        std::fs::create_dir_all(&fdir).map_err(werr(&fdir))?;
        for (f, img) in &record.images {
            let p = fdir.join(format!("frame_{f:04}.png"));
            crate::output::write_png(&p, img).map_err(|source| ReportError::Image {
                file: p.clone(),
                source,
            })?;
            let t = image::imageops::thumbnail(
                img,
                THUMB_SIZE.min(img.width()).max(1),
                ((THUMB_SIZE.min(img.width()) as u64 * img.height() as u64
                    / img.width().max(1) as u64) as u32)
                    .max(1),
            );
            let mut bytes = Vec::new();
            t.write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Png,
            )
            .map_err(|source| ReportError::Image {
                file: p.clone(),
                source,
            })?;
            thumbs.push((*f, data_url("image/png", &bytes)));
            written.push(p);
        }
    }
    let positions: Vec<glam::DVec2> = record
        .cameras
        .iter()
        .map(|c| c.position.truncate())
        .collect();
    let markers: Vec<usize> = if record.images.is_empty() {
        // No kept frames: mark about six evenly spaced frames.
        let step = (positions.len() / 6).max(1);
        (0..positions.len()).step_by(step).collect()
    } else {
        record.images.iter().map(|(f, _)| *f).collect()
    };
    let embedded = html::Embedded {
        map_svg: map::route_map_svg(&ctx.plan, &positions, &markers),
        plots,
        far_plot,
        thumbs,
        extra,
    };
    let page = html::page(record, ctx, &embedded);
    let p = dir.join("report.html");
    crate::output::write_bytes(&p, page)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(werr(&p))?;
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
                        buildings: None,
                        triangles: 120 + f as u64,
                        draws: 4,
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
            buildings_decision: Vec::new(),
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

    /// A context with a one-block plan around the route, a machine and a command.
    pub(crate) fn context() -> ReportContext {
        let sq = |x: f64, y: f64, d: f64| {
            vec![
                glam::DVec2::new(x, y),
                glam::DVec2::new(x + d, y),
                glam::DVec2::new(x + d, y + d),
                glam::DVec2::new(x, y + d),
            ]
        };
        ReportContext {
            plan: Plan {
                blocks: vec![sq(-10.0, -10.0, 20.0)],
                footprints: vec![sq(-5.0, 2.0, 3.0)],
            },
            machine: Some(Machine {
                cpu: Some("Test CPU <9000>".into()),
                cores: 7,
                os: "TestOS".into(),
                version: "0.0.1".into(),
                commit: None,
            }),
            command: vec!["blockwalk".into(), "walk".into(), "data/my city".into()],
            extra_plots: Vec::new(),
        }
    }

    /// Every `src=` / `href=` value of `html`.
    pub(crate) fn references(html: &str) -> Vec<String> {
        let mut v = Vec::new();
        for attr in ["src=\"", "href=\""] {
            for part in html.split(attr).skip(1) {
                v.push(part[..part.find('"').unwrap_or(part.len())].to_string());
            }
        }
        v
    }

    #[test]
    fn the_page_stands_alone_with_map_strip_machine_and_command() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = record();
        r.images.push((
            2,
            image::RgbaImage::from_pixel(640, 360, image::Rgba([9, 99, 199, 255])),
        ));
        write_with(&r, dir.path(), None, &context()).unwrap();
        let h = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        let refs = references(&h);
        // 2 Fig.-4 plots per mode (2 modes) + 2 thumbnails, all embedded.
        assert_eq!(refs.len(), 6, "{refs:?}");
        for r in &refs {
            assert!(
                r.starts_with("data:image/png;base64,"),
                "external reference {r}"
            );
        }
        assert!(!h.contains("href="));
        assert_eq!(h.matches("<svg").count(), 1, "the route map");
        assert_eq!(
            h.matches("class=\"marker\"").count(),
            2,
            "one marker per kept frame"
        );
        assert_eq!(h.matches("<figcaption>").count(), r.images.len());
        assert!(h.contains("<b>frame 2</b>"));
        assert!(h.contains("Test CPU &lt;9000&gt; (7 hardware threads)"));
        assert!(h.contains("TestOS"));
        assert!(h.contains("blockwalk walk 'data/my city'"));
        assert!(h.contains("total 500 ms"));
        // The thumbnail is downscaled to THUMB_SIZE wide.
        use base64::Engine as _;
        let sizes: Vec<(u32, u32)> = refs
            .iter()
            .map(|r| {
                let b64 = r.trim_start_matches("data:image/png;base64,");
                let png = base64::engine::general_purpose::STANDARD
                    .decode(b64)
                    .unwrap();
                let t = image::load_from_memory(&png).unwrap();
                (t.width(), t.height())
            })
            .collect();
        assert!(sizes.contains(&(THUMB_SIZE, 180)), "{sizes:?}");
        assert!(
            sizes.contains(&(4, 3)),
            "a small frame stays as it is: {sizes:?}"
        );
        // The full-size frame is still written beside the page.
        assert!(dir.path().join("frames/frame_0002.png").is_file());
    }

    #[test]
    fn plots_made_beside_the_walk_are_embedded_under_their_caption() {
        use base64::Engine as _;
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("extra.png");
        image::RgbaImage::from_pixel(3, 2, image::Rgba([1, 2, 3, 255]))
            .save(&png)
            .unwrap();
        let mut ctx = context();
        ctx.extra_plots = vec![("Error <against> time".into(), png.clone())];
        let out = dir.path().join("report");
        write_with(&record(), &out, None, &ctx).unwrap();
        let h = std::fs::read_to_string(out.join("report.html")).unwrap();
        assert!(h.contains("<figcaption>Error &lt;against&gt; time</figcaption>"));
        let url = format!(
            "data:image/png;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(std::fs::read(&png).unwrap())
        );
        assert!(references(&h).contains(&url));
        // A missing plot is an error naming the file, not a silent gap.
        ctx.extra_plots = vec![("gone".into(), dir.path().join("missing.png"))];
        let e = write_with(&record(), &out, None, &ctx).unwrap_err();
        assert!(e.to_string().contains("missing.png"), "{e}");
    }

    #[test]
    fn report_json_has_the_machine_command_and_the_figures_of_the_page() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = record();
        r.frames[7].cull_s = 0.012_345; // frame 1, flat, frustum+occlusion
        r.images.push((1, image::RgbaImage::new(8, 6)));
        write_with(&r, dir.path(), None, &context()).unwrap();
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
                .unwrap();
        let h = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        assert_eq!(j["machine"]["cores"], 7);
        assert_eq!(j["command"][2], "data/my city");
        assert_eq!(j["per_frame"].as_array().unwrap().len(), r.frames.len());
        assert_eq!(j["total_ms"], 500.0);
        let kept = j["kept_frames"].as_array().unwrap();
        assert_eq!(kept.len(), 2);
        assert_eq!(kept[1]["frame"], 1);
        assert_eq!(kept[1]["mode"], "frustum+occlusion");
        assert_eq!(kept[1]["position"][0], 1.0);
        let rows = kept[1]["structures"].as_array().unwrap();
        assert_eq!(rows.len(), 2, "one row per structure");
        let flat = rows.iter().find(|x| x["structure"] == "flat").unwrap();
        let cull = flat["cull_ms"].as_f64().unwrap();
        assert!((cull - 12.345).abs() < 1e-9);
        // The same figure under the frame on the page.
        let caption = h.split("<b>frame 1</b>").nth(1).unwrap();
        let caption = &caption[..caption.find("</figcaption>").unwrap()];
        assert!(caption.contains("<td>12.345</td>"), "{caption}");
        assert!(caption.contains(&format!("<td>{}</td>", flat["triangles"])));
    }

    #[test]
    fn without_a_context_the_page_says_what_is_missing() {
        let dir = tempfile::tempdir().unwrap();
        write(&record(), dir.path(), None).unwrap();
        let h = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        assert!(h.contains("No map"));
        assert!(h.contains("<dt>machine</dt><dd>not recorded</dd>"));
        assert!(h.contains("<dt>command</dt><dd>not recorded</dd>"));
        assert!(!h.contains("<svg"));
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
