//! Writes a streamed walk ([`crate::stream`]): per-frame CSV, the summary as JSON, and the strip
//! of kept frames (stand-in maps tinted, stand-in boxes in their colour).

use std::path::{Path, PathBuf};

use crate::stream::job::StreamRecord;

/// The record as one JSON object: the city's startup, the route, the summary.
pub fn json(record: &StreamRecord) -> serde_json::Value {
    serde_json::json!({
        "city": record.city.index.city,
        "source": record.city.startup.source,
        "startup": record.city.startup,
        "rss_after_open_bytes": record.rss_after_open,
        "route": record.route,
        "frames": record.cameras.len(),
        "kept_frames": record.run.kept.iter().map(|(f, _)| *f).collect::<Vec<_>>(),
        "summary": record.run.summary,
        "notes": record.notes,
    })
}

/// Writes `out/frames.csv`, `out/stream.json` and, when frames were kept, `out/strip.png`;
/// returns the files written.
///
/// # Errors
/// A file that cannot be written, naming it.
pub fn write(
    record: &StreamRecord,
    out: &Path,
) -> Result<Vec<PathBuf>, crate::output::OutputError> {
    let mut files = Vec::new();
    std::fs::create_dir_all(out).map_err(|source| crate::output::OutputError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let mut csv = String::from(
        "frame,at_s,needed,hits,maps,meshes,standin_maps,standin_boxes,replaced,queued_needed,queued_standins,queued_ahead,loaded,bytes_loaded,resident_bytes,wait_s,handoff_s,select_s,prefetch_s,draw_s,differing_pixels,psnr_db\n",
    );
    let opt = |v: Option<f64>| v.map(|v| format!("{v}")).unwrap_or_default();
    for f in &record.run.frames {
        csv.push_str(&format!(
            "{},{:.4},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{},{}\n",
            f.frame,
            f.at_s,
            f.needed,
            f.hits,
            f.maps,
            f.meshes,
            f.standin_maps,
            f.standin_boxes,
            f.replaced,
            f.queued[0],
            f.queued[1],
            f.queued[2],
            f.loaded,
            f.bytes_loaded,
            f.resident_bytes,
            f.wait_s,
            f.handoff_s,
            f.select_s,
            f.prefetch_s,
            f.draw_s,
            f.differing_pixels
                .map(|d| d.to_string())
                .unwrap_or_default(),
            opt(f.psnr_db),
        ));
    }
    let p = out.join("frames.csv");
    crate::output::write_bytes(&p, csv)?;
    files.push(p);
    let p = out.join("stream.json");
    crate::output::write_bytes(
        &p,
        serde_json::to_string_pretty(&json(record)).unwrap_or_default(),
    )?;
    files.push(p);
    if !record.run.kept.is_empty() {
        let (w, h) = record.run.kept[0].1.dimensions();
        let gap = 4;
        let n = record.run.kept.len() as u32;
        let mut strip =
            image::RgbaImage::from_pixel(n * w + (n - 1) * gap, h, image::Rgba([255; 4]));
        for (k, (_, img)) in record.run.kept.iter().enumerate() {
            image::imageops::overlay(&mut strip, img, (k as u32 * (w + gap)) as i64, 0);
        }
        let p = out.join("strip.png");
        crate::output::write_png(&p, &strip).map_err(|e| crate::output::OutputError::Io {
            path: p.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        files.push(p);
    }
    Ok(files)
}
