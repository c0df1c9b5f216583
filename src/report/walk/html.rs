//! The walk's self-contained HTML page: every picture is embedded (`data:` URLs, inline SVG), so
//! the page needs no other file; the files written beside it are named as text, not linked.

use super::context::ReportContext;
use super::{image_mode, kept_frame_rows};
use crate::walk::{CullMode, WalkRecord};
use std::fmt::Write as _;

/// Escapes text for HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The seed-003 Fig. 4 plots of one culling mode, as `data:` URLs.
#[derive(Clone, Debug)]
pub struct ModePlots {
    /// The culling mode.
    pub mode: CullMode,
    /// Frame time along the route, ms.
    pub frame_time: String,
    /// Triangles drawn along the route.
    pub triangles: String,
}

/// The pictures the page embeds.
#[derive(Clone, Debug, Default)]
pub struct Embedded {
    /// The route map (an `<svg>` element), when the city's plan was given.
    pub map_svg: Option<String>,
    /// Fig. 4 plots, one entry per culling mode.
    pub plots: Vec<ModePlots>,
    /// Mesh-only against hybrid frame time, when a far field ran (`data:` URL).
    pub far_plot: Option<String>,
    /// Thumbnails of the kept frames: frame number and `data:` URL.
    pub thumbs: Vec<(usize, String)>,
    /// Plots made beside the walk: caption and `data:` URL.
    pub extra: Vec<(String, String)>,
}

/// What the Table 1 rows mean, and the paper's figure to compare with.
const TABLE1_NOTE: &str = "<p>Seed 003 Table 1 (OpenGL Performer, Zaragoza, GeForce 6800): \
    BqR-tree / VAMSplit R-tree = <b>0.638</b> in seconds per frame. Here <code>vamsplit</code> is \
    the VAMSplit R-tree over the same blocks as the BqR-tree; <code>scenegraph</code> is the \
    paper's setting, a VAMSplit R-tree over buildings whose leaves (pages of up to 8 buildings) \
    are drawn whole; its <i>blocks</i> column counts pages. The <code>+buildings</code> modes \
    test each building of the surviving blocks against the frustum (and the cull map), Willmott et al. \
    §3.2.8; <i>buildings</i> counts those drawn.</p>";

/// `v` with `d` decimals, or a dash.
fn opt(v: Option<f64>, d: usize) -> String {
    v.filter(|v| v.is_finite())
        .map(|v| format!("{v:.d$}"))
        .unwrap_or("–".into())
}

/// The page: the machine and command, Table 1 (ms), the notes, the route map, the strip of kept
/// frames with their figures, the far field's figures and plot, and the Fig. 4 plots.
pub fn page(record: &WalkRecord, ctx: &ReportContext, e: &Embedded) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>blockwalk walk: {city}</title>\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         td:first-child,td:nth-child(2){{text-align:left}}img{{max-width:100%}}\
         .strip{{display:flex;gap:12px;overflow-x:auto;padding-bottom:8px}}\
         .strip figure{{margin:0;flex:0 0 auto;width:330px}}.strip img{{width:100%}}.strip table{{font-size:12px;width:100%}}\
         .strip figcaption{{font-size:12px}}dl.machine dt{{font-weight:bold;float:left;clear:left;width:9em}}\
         dl.machine dd{{margin-left:10em}}code{{word-break:break-all}}</style></head><body>\
         <h1>Walk through {city}</h1><p>Route <b>{route}</b>, {n} frames; total {t:.0} ms.</p>",
        city = escape(&record.city),
        route = escape(&record.route),
        n = record.cameras.len(),
        t = record.total_s * 1e3
    );
    for line in super::verdict::conclusion(record) {
        let _ = write!(h, "<p><b>{}</b></p>", escape(&line));
    }
    machine_section(&mut h, record, ctx);
    h.push_str("<h2>Average per frame (Pina, Serón and Cerezo, Table 1)</h2><table><tr><th>structure</th><th>culling</th><th>ms/frame</th><th>ratio BqR/structure</th><th>cull ms</th><th>render ms</th><th>triangles</th><th>blocks</th><th>buildings</th><th>nodes</th><th>false culls</th></tr>");
    for r in &record.summary {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.4}</td><td>{}</td><td>{:.0}</td><td>{:.1}</td><td>{}</td><td>{:.1}</td><td>{}</td></tr>",
            r.structure,
            escape(r.mode.name()),
            r.seconds_per_frame * 1e3,
            r.ratio,
            r.cull_s * 1e3,
            opt(r.render_s.map(|v| v * 1e3), 3),
            r.triangles,
            r.blocks,
            opt(r.buildings, 1),
            r.nodes_visited,
            r.false_culls.map(|v| v.to_string()).unwrap_or("–".into())
        );
    }
    h.push_str("</table>");
    h.push_str(TABLE1_NOTE);
    for d in &record.buildings_decision {
        let _ = write!(h, "<p>{}</p>", escape(&d.note));
    }
    if !record.notes.is_empty() {
        h.push_str("<h2>Notes</h2><ul>");
        for n in &record.notes {
            let _ = write!(h, "<li>{}</li>", escape(n));
        }
        h.push_str("</ul>");
    }
    h.push_str("<h2>The route</h2>");
    match &e.map_svg {
        Some(svg) => {
            h.push_str("<p>Blocks (blue), buildings (grey), the camera path (red, from the green dot) and the numbered frames below.</p><div class=\"mapbox\">");
            h.push_str(svg);
            h.push_str("</div>");
        }
        None => h.push_str("<p>No map: the report was not given the city's plan.</p>"),
    }
    strip(&mut h, record, e);
    far_section(&mut h, record, e);
    extra_section(&mut h, e);
    for p in &e.plots {
        let _ = write!(
            h,
            "<h2>Along the route ({m}; Pina, Serón and Cerezo, Fig. 4)</h2><p><img src=\"{ft}\" alt=\"time per frame, {m}\"></p><p><img src=\"{tr}\" alt=\"triangles drawn, {m}\"></p>",
            m = escape(p.mode.name()),
            ft = p.frame_time,
            tr = p.triangles,
        );
    }
    h.push_str("<p>Written beside this page: <code>frames.csv</code> (per frame), <code>summary.md</code> (Table 1), <code>report.json</code> (all the figures here), the plots as PNG and SVG, and the full-size frames.</p></body></html>\n");
    h
}

/// The machine, the build and the command line.
fn machine_section(h: &mut String, record: &WalkRecord, ctx: &ReportContext) {
    h.push_str("<h2>Machine and command</h2><dl class=\"machine\">");
    let mut item = |k: &str, v: &str| {
        let _ = write!(h, "<dt>{k}</dt><dd>{v}</dd>");
    };
    match &ctx.machine {
        Some(m) => {
            item(
                "CPU",
                &escape(&format!(
                    "{} ({} hardware threads)",
                    m.cpu.as_deref().unwrap_or("unknown model"),
                    m.cores
                )),
            );
            item("OS", &escape(&m.os));
            item(
                "blockwalk",
                &escape(&match &m.commit {
                    Some(c) => format!("{} (commit {c})", m.version),
                    None => m.version.clone(),
                }),
            );
        }
        None => item("machine", "not recorded"),
    }
    item("renderer", &escape(&record.renderer));
    let cmd = if ctx.command.is_empty() {
        "not recorded".to_string()
    } else {
        format!(
            "<code class=\"command\">{}</code>",
            escape(&shell_words(&ctx.command))
        )
    };
    item("command", &cmd);
    h.push_str("</dl>");
}

/// The arguments as one shell line (quoted where needed).
fn shell_words(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            if !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c))
            {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', "'\\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The strip of kept frames, each with its figures.
fn strip(h: &mut String, record: &WalkRecord, e: &Embedded) {
    if e.thumbs.is_empty() {
        h.push_str("<p>No frames were kept (walk with <code>--render</code> to keep some).</p>");
        return;
    }
    let _ = write!(
        h,
        "<h2>Frames along the route ({})</h2><div class=\"strip\">",
        escape(image_mode(record).map_or("", |m| m.name()))
    );
    for (f, url) in &e.thumbs {
        let (rows, far) = kept_frame_rows(record, *f);
        let _ = write!(
            h,
            "<figure class=\"frame\"><img src=\"{url}\" alt=\"frame {f}\"><figcaption><b>frame {f}</b>\
             <table><tr><th>structure</th><th>blocks</th><th>triangles</th><th>cull ms</th><th>frame ms</th></tr>"
        );
        for r in rows {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td></tr>",
                r.structure,
                r.blocks,
                r.triangles,
                r.cull_s * 1e3,
                r.frame_s * 1e3
            );
        }
        h.push_str("</table>");
        if let Some(r) = far {
            let _ = write!(
                h,
                "far field: {} nodes, {} mesh triangles, hybrid {:.3} ms (meshes only {:.3} ms), coverage error {}, PSNR {} dB",
                r.far_nodes,
                r.mesh_triangles,
                r.frame_s * 1e3,
                r.mesh_frame_s * 1e3,
                opt(r.image.map(|i| i.coverage_error), 4),
                opt(r.image.map(|i| i.psnr_db), 1),
            );
        }
        h.push_str("</figcaption></figure>");
    }
    h.push_str("</div>");
}

/// The far field's figures and its error-against-time plot.
/// The plots made beside the walk, each under its caption.
fn extra_section(h: &mut String, e: &Embedded) {
    for (caption, url) in &e.extra {
        let c = escape(caption);
        let _ = write!(
            h,
            "<figure><img src=\"{url}\" alt=\"{c}\"><figcaption>{c}</figcaption></figure>"
        );
    }
}

fn far_section(h: &mut String, record: &WalkRecord, e: &Embedded) {
    let Some(f) = record.far_summary() else {
        return;
    };
    let num = |v: Option<f64>, scale: f64, digits: usize| opt(v.map(|v| v * scale), digits);
    let count = |v: Option<u64>| opt(v.map(|v| v as f64), 0);
    let _ = write!(
        h,
        "<h2>Far field ({far}, τ = {tau} px)</h2><p>{used}</p><table><tr><th>far nodes</th><th>mesh triangles</th><th>hybrid ms</th><th>mesh-only ms</th><th>ratio</th><th>coverage error max</th><th>PSNR min dB</th><th>silhouette px max (raw)</th><th>ratio max</th><th>bound violations</th><th>sub-pixel</th><th>thin</th><th>popping px max</th></tr><tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr></table><p>{bound}</p>",
        num(f.far_nodes, 1.0, 1),
        num(f.mesh_triangles, 1.0, 0),
        num(f.frame_s, 1e3, 3),
        num(f.mesh_frame_s, 1e3, 3),
        num(f.frame_time_ratio_vs_mesh, 1.0, 3),
        num(f.coverage_error_max, 1.0, 4),
        num(f.psnr_min, 1.0, 1),
        num(f.silhouette_px_max, 1.0, 1),
        num(f.silhouette_ratio_max, 1.0, 2),
        count(f.silhouette_bound_violations),
        count(f.silhouette_subpixel),
        count(f.silhouette_thin),
        num(f.popping_px_max, 1.0, 0),
        bound = if f.silhouette_ratio_max.is_none() {
            "The silhouette bound 1 px + τ/cos²θ was not checked with the exact geometry (no \
             buildings were given): only the raw image distance is shown."
        } else {
            "Bound 1 px + τ/cos²θ per mismatched pixel: ratio max is the largest distance over \
             allowed distance after a second look at quarter-pixel spacing with the exact \
             geometry (≤ 1 where the bound holds); sub-pixel: pixels beyond the bound at pixel \
             spacing that the second look settled; thin: pixels of buildings the maps declare \
             thin or dropped; bound violations: the rest."
        },
        tau = f.tau_px,
        far = escape(&f.representation),
        used = escape(&match (&f.used, &f.reason) {
            (true, _) => "Drawn on every frame.".to_string(),
            (false, Some(r)) => format!("Left out: {r}"),
            (false, None) => "Left out.".to_string(),
        }),
    );
    if let Some(url) = &e.far_plot {
        let _ = write!(
            h,
            "<p><img src=\"{url}\" alt=\"mesh-only against hybrid frame time\"></p>"
        );
    }
}
