//! The walk's self-contained HTML page.

use super::mode_tag;
use crate::walk::{CullMode, WalkRecord};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Escapes text for HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The page: Table 1, the notes, one pair of plots per culling mode (files written beside it by
/// [`super::write`]) and the kept frames (`frames`: frame number and file).
pub fn page(
    record: &WalkRecord,
    dir: &Path,
    modes: &[CullMode],
    frames: &[(usize, PathBuf)],
) -> String {
    let rel = |p: &Path| {
        p.strip_prefix(dir)
            .map(|r| r.to_string_lossy().into_owned())
            .unwrap_or_else(|_| p.to_string_lossy().into_owned())
    };
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>blockwalk walk: {city}</title>\
         <style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         td:first-child,td:nth-child(2){{text-align:left}}img{{max-width:100%}}</style></head><body>\
         <h1>Walk through {city}</h1><p>Route <b>{route}</b>, {n} frames; renderer: {r}; total {t:.2} s.</p>",
        city = escape(&record.city),
        route = escape(&record.route),
        n = record.cameras.len(),
        r = escape(&record.renderer),
        t = record.total_s
    );
    h.push_str("<h2>Average per frame (seed 003 Table 1)</h2><table><tr><th>structure</th><th>culling</th><th>ms/frame</th><th>ratio BqR/structure</th><th>cull ms</th><th>render ms</th><th>triangles</th><th>blocks</th><th>nodes</th><th>false culls</th></tr>");
    for r in &record.summary {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.4}</td><td>{}</td><td>{:.0}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td></tr>",
            r.structure,
            escape(r.mode.name()),
            r.seconds_per_frame * 1e3,
            r.ratio,
            r.cull_s * 1e3,
            r.render_s
                .map(|v| format!("{:.3}", v * 1e3))
                .unwrap_or("–".into()),
            r.triangles,
            r.blocks,
            r.nodes_visited,
            r.false_culls.map(|v| v.to_string()).unwrap_or("–".into())
        );
    }
    h.push_str("</table>");
    if !record.notes.is_empty() {
        h.push_str("<h2>Notes</h2><ul>");
        for n in &record.notes {
            let _ = write!(h, "<li>{}</li>", escape(n));
        }
        h.push_str("</ul>");
    }
    if let (Some(d), Some(o)) = (&record.far_decision, &record.far_options) {
        let f = crate::walk::far_json(&record.far, d, o);
        let num = |k: &str, scale: f64, digits: usize| {
            f[k].as_f64()
                .map(|v| format!("{:.*}", digits, v * scale))
                .unwrap_or("–".into())
        };
        let _ = write!(
            h,
            "<h2>Far field (BlockMaps, τ = {tau} px)</h2><p>{used}</p><table><tr><th>far nodes</th><th>mesh triangles</th><th>hybrid ms</th><th>mesh-only ms</th><th>ratio</th><th>coverage error max</th><th>PSNR min dB</th><th>silhouette px max</th><th>popping px max</th></tr>             <tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr></table>",
            num("far_nodes", 1.0, 1),
            num("mesh_triangles", 1.0, 0),
            num("frame_s", 1e3, 3),
            num("mesh_frame_s", 1e3, 3),
            num("frame_time_ratio_vs_mesh", 1.0, 3),
            num("coverage_error_max", 1.0, 4),
            num("psnr_min", 1.0, 1),
            num("silhouette_px_max", 1.0, 1),
            num("popping_px_max", 1.0, 0),
            tau = o.tau_px,
            used = escape(&match (&d.used, &d.reason) {
                (true, _) => "Drawn on every frame.".to_string(),
                (false, Some(r)) => format!("Left out: {r}"),
                (false, None) => "Left out.".to_string(),
            }),
        );
        if !record.far.is_empty() {
            h.push_str("<p><img src=\"far_frame_time.svg\" alt=\"far frame time\"></p><p>Per frame: <a href=\"far_frames.csv\">far_frames.csv</a>.</p>");
        }
    }
    for &mode in modes {
        let _ = write!(
            h,
            "<h2>Along the route ({m}; seed 003 Fig. 4)</h2><p><img src=\"frame_time_{t}.svg\" alt=\"frame time\"></p><p><img src=\"triangles_{t}.svg\" alt=\"triangles\"></p>",
            m = escape(mode.name()),
            t = mode_tag(mode)
        );
    }
    if !frames.is_empty() {
        h.push_str("<h2>Frames</h2>");
        for (f, p) in frames {
            let _ = write!(
                h,
                "<figure style=\"display:inline-block;width:48%\"><img src=\"{}\" alt=\"frame {f}\"><figcaption>frame {f}</figcaption></figure>",
                escape(&rel(p))
            );
        }
    }
    h.push_str("<p>Per-frame data: <a href=\"frames.csv\">frames.csv</a>; summary: <a href=\"summary.md\">summary.md</a>; <a href=\"report.json\">report.json</a>.</p></body></html>\n");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_text_and_links_plots_and_frames() {
        let r = crate::report::walk::tests::record();
        let dir = Path::new("/out");
        let h = page(
            &r,
            dir,
            &[CullMode::Frustum, CullMode::FrustumOcclusion],
            &[(0, dir.join("frames/frame_0000.png"))],
        );
        assert!(h.contains("Walk through Test &lt;city&gt;"));
        assert!(h.contains("a note &amp; more"));
        assert!(h.contains("frame_time_frustum_occlusion.svg"));
        assert!(h.contains("src=\"frames/frame_0000.png\""));
        assert_eq!(h.matches("<tr><td>").count(), r.summary.len());
    }
}
