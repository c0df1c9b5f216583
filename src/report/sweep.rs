//! Writes a far-field sweep ([`crate::walk::sweep`]): the table of its rows (Markdown and
//! JSON), the plot of coverage error against frame time with the Pareto front (PNG and SVG), the
//! walk report of one configuration per route (embedding that plot), and the diagnoses when the
//! sweep made them. It only writes: the sweep itself is [`crate::walk::sweep::run_sweep`].

use super::plot::{write_plot, PlotKind, Series};
use super::walk::{write_with, ReportContext, ReportError};
use crate::walk::sweep::{pareto, Sweep, SweepBuild, SweepDiagnosis, SweepRow};
use crate::walk::FarMode;
use std::path::{Path, PathBuf};

/// The header of the table, one column per figure of a [`SweepRow`].
pub const HEADER: &str = "| city | route | far field | side | τ px | maps | far nodes | mesh tris | coverage err max | PSNR min dB | silhouette px max | ratio max | bound violations | sub-pixel | thin | popping px max | hybrid ms | mesh ms | ratio |";

/// Columns of [`HEADER`].
const COLUMNS: usize = 19;

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map(|v| format!("{v:.digits$}")).unwrap_or("–".into())
}

fn count(v: Option<u64>) -> String {
    v.map(|v| v.to_string()).unwrap_or("–".into())
}

/// One row of the table, as a Markdown line under [`HEADER`].
pub fn table_line(r: &SweepRow) -> String {
    format!(
        "| {} | {} | {} | {} | {} | {} | {:.1} | {:.0} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
        r.city,
        r.route,
        r.far,
        r.k,
        r.tau_px,
        r.maps,
        r.far_nodes,
        r.mesh_triangles,
        opt(r.coverage_error_max, 4),
        opt(r.psnr_min, 1),
        opt(r.silhouette_px_max, 1),
        opt(r.silhouette_ratio_max, 2),
        count(r.silhouette_bound_violations),
        count(r.silhouette_subpixel),
        count(r.silhouette_thin),
        opt(r.popping_px_max, 0),
        opt(r.hybrid_ms, 2),
        opt(r.mesh_ms, 2),
        opt(r.frame_time_ratio_vs_mesh, 3),
    )
}

/// The whole table in Markdown: [`HEADER`], the rule, one line per row.
pub fn table(rows: &[SweepRow]) -> String {
    let mut md = format!("{HEADER}\n|{}\n", "---|".repeat(COLUMNS));
    for r in rows {
        md.push_str(&table_line(r));
        md.push('\n');
    }
    md
}

/// The file stem of a configuration's files: `{prefix}_{route}_{far}{side}_tau{τ}` (`k64` for
/// BlockMaps at K = 64, `relief128` for relief impostors at M = 128).
fn stem(prefix: &str, route: &str, far: FarMode, k: u32, tau: f64) -> String {
    let f = match far {
        FarMode::Blockmaps => "k",
        _ => "relief",
    };
    format!("{prefix}_{route}_{f}{k}_tau{tau}")
}

/// The builds in Markdown: representation, side, nodes, bytes (MiB and per km²), build time.
pub fn builds_table(b: &[SweepBuild]) -> String {
    let mut md = String::from(
        "| far field | side | nodes | MiB | MiB/km² | build s |\n|---|---|---|---|---|---|\n",
    );
    for x in b {
        md.push_str(&format!(
            "| {} | {} | {} | {:.1} | {:.2} | {:.1} |\n",
            x.far,
            x.k,
            x.maps,
            x.bytes as f64 / (1024.0 * 1024.0),
            x.bytes_per_km2 / (1024.0 * 1024.0),
            x.seconds
        ));
    }
    md
}

/// A diagnosis in Markdown: a section with the table of each frame.
pub fn diagnosis_markdown(d: &SweepDiagnosis) -> String {
    d.frames
        .iter()
        .map(|f| format!("## frame {}\n\n{}\n", f.frame, f.diagnosis.table()))
        .collect()
}

fn put(path: PathBuf, text: String) -> Result<PathBuf, ReportError> {
    crate::output::write_bytes(&path, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| ReportError::Write {
            file: path.clone(),
            source,
        })?;
    Ok(path)
}

fn json_text(path: &Path, v: &impl serde::Serialize) -> Result<String, ReportError> {
    serde_json::to_string_pretty(v).map_err(|e| ReportError::Write {
        file: path.to_path_buf(),
        source: std::io::Error::other(e),
    })
}

/// Writes `sweep` into `out_dir` (made when missing): `diagnose_ROUTE_kK_tauT.{md,json}` per
/// diagnosed configuration, `sweep.md`, `sweep.json`, `pareto.{png,svg}`, and the walk report of
/// each kept walk in `walk_ROUTE_kK_tauT/`, written last with `ctx` (the plan, machine and
/// command line) and the Pareto plot embedded. Returns the paths written.
///
/// # Errors
/// [`ReportError`] naming the file that could not be written.
pub fn write(
    sweep: &Sweep,
    out_dir: &Path,
    ctx: &ReportContext,
) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(out_dir).map_err(|source| ReportError::Write {
        file: out_dir.to_path_buf(),
        source,
    })?;
    let mut files = Vec::new();
    for d in &sweep.diagnoses {
        let base = out_dir.join(stem(
            "diagnose",
            &d.route,
            FarMode::Blockmaps,
            d.k,
            d.tau_px,
        ));
        files.push(put(base.with_extension("md"), diagnosis_markdown(d))?);
        let p = base.with_extension("json");
        // Through a JSON value: the keys of every object in alphabetical order.
        let value = serde_json::to_value(&d.frames).map_err(|e| ReportError::Write {
            file: p.clone(),
            source: std::io::Error::other(e),
        })?;
        let text = json_text(&p, &value)?;
        files.push(put(p, text)?);
    }
    files.push(put(
        out_dir.join("sweep.md"),
        format!("{}\n{}", builds_table(&sweep.builds), table(&sweep.rows)),
    )?);
    let p = out_dir.join("sweep.json");
    let text = json_text(
        &p,
        &serde_json::json!({ "builds": sweep.builds, "rows": sweep.rows }),
    )?;
    files.push(put(p, text)?);
    files.extend(write_pareto(out_dir, &sweep.city, &sweep.rows)?);
    let ctx = ReportContext {
        extra_plots: ctx
            .extra_plots
            .iter()
            .cloned()
            .chain([(
                "Coverage error against frame time over the whole sweep (every route, τ and K), \
                 with the Pareto front"
                    .into(),
                out_dir.join("pareto.png"),
            )])
            .collect(),
        ..ctx.clone()
    };
    for w in &sweep.walks {
        let dir = out_dir.join(stem("walk", &w.route, w.far, w.k, w.tau_px));
        files.extend(write_with(&w.record, &dir, None, &ctx)?);
    }
    Ok(files)
}

/// Error against milliseconds: one series per representation and side, the mesh-only frames at
/// zero error, and the Pareto front over all of them, to `pareto.{png,svg}`.
fn write_pareto(dir: &Path, city: &str, rows: &[SweepRow]) -> Result<Vec<PathBuf>, ReportError> {
    let mut ks: Vec<(FarMode, u32)> = Vec::new();
    for r in rows {
        if !ks.contains(&(r.far, r.k)) {
            ks.push((r.far, r.k));
        }
    }
    let mut series: Vec<Series> = ks
        .iter()
        .map(|&(far, k)| Series {
            name: match far {
                FarMode::Blockmaps => format!("BlockMaps K = {k}"),
                _ => format!("relief impostors M = {k}"),
            },
            points: rows
                .iter()
                .filter(|r| r.far == far && r.k == k)
                .filter_map(|r| Some((r.hybrid_ms?, r.coverage_error_max? * 100.0)))
                .collect(),
        })
        .collect();
    series.push(Series {
        name: "mesh only".into(),
        points: rows
            .iter()
            .filter_map(|r| Some((r.mesh_ms?, 0.0)))
            .collect(),
    });
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.points.clone()).collect();
    series.push(Series {
        name: "Pareto front".into(),
        points: pareto(all),
    });
    let mut files = Vec::new();
    for ext in ["png", "svg"] {
        let p = dir.join(format!("pareto.{ext}"));
        write_plot(
            &p,
            &format!("{city}: coverage error against frame time (all routes, τ, far fields)"),
            "ms per frame",
            "coverage error max, %",
            &series,
            PlotKind::Points,
        )?;
        files.push(p);
    }
    Ok(files)
}
