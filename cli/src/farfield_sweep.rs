//! `blockwalk farfield-sweep`: error against run time of the far field (issue 12). For every K,
//! route and τ, a hybrid walk with the reference (coverage error, PSNR, silhouette distance,
//! popping) and the mesh-only frames beside it; a table (Markdown, CSV, JSON), the Pareto plot of
//! error against milliseconds, frame time along each route (mesh-only vs hybrid), and the walk
//! report of one configuration per route. Not run in CI: it draws about four frames per camera.

use super::common::{load_scene, CityArgs, Size};
use anyhow::Context;
use blockwalk::blockmap::SelectOptions;
use blockwalk::report::plot::{write_plot, PlotKind, Series};
use blockwalk::route::{flyover_route_with_near, CameraRoute, RouteChoice, FLYOVER_NEAR_SHARE};
use blockwalk::scene::{Scene, SceneOptions};
use blockwalk::walk::{
    run_walk_with_far, Drawing, FarSetup, FarSummary, OcclusionMode, WalkParams,
};
use serde::Serialize;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Error thresholds τ, pixels.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8,16")]
    pub taus: Vec<f64>,
    /// Height-map sides K.
    #[arg(long, value_delimiter = ',', default_value = "32,64,128")]
    pub ks: Vec<u32>,
    /// Routes: `paper`, `orbit`, `flyover` (high, the whole city in view), `street`, or files.
    #[arg(long, value_delimiter = ',', default_value = "paper,orbit,flyover")]
    pub routes: Vec<RouteChoice>,
    /// Frames per route.
    #[arg(long, default_value_t = 12)]
    pub frames: usize,
    /// Image size.
    #[arg(long, default_value = "160x90")]
    pub size: Size,
    /// Draw with the GPU renderer when there is one (else the CPU hybrid renderer).
    #[arg(long)]
    pub gpu: bool,
    /// Output directory.
    #[arg(long, default_value = "farfield-sweep")]
    pub out: PathBuf,
    /// Seed of a `synthetic:` city.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Classify the coverage-mismatched pixels of each configuration's worst frames (largest
    /// coverage error, largest silhouette distance) by cause (`blockmap::diagnose`), into
    /// `OUT/diagnose_ROUTE_kK_tauT.{json,md}`.
    #[arg(long)]
    pub diagnose: bool,
    /// Half-planes per texel the maps store: 0 (whole texels), 1 (one footprint edge) or 2
    /// (a second where it fits the footprint more closely; the default), to measure each.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=2))]
    pub edges: u8,
    /// The fly-over's near plane as a share of its height above the highest roof (0: the
    /// lens's default, 0.5 m).
    #[arg(long, default_value_t = FLYOVER_NEAR_SHARE)]
    pub flyover_near_share: f64,
}

/// One configuration's figures.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub city: String,
    pub route: String,
    pub k: u32,
    pub tau_px: f64,
    pub maps: usize,
    pub frames: usize,
    pub far_nodes: f64,
    pub mesh_triangles: f64,
    pub coverage_error_max: Option<f64>,
    pub coverage_error_mean: Option<f64>,
    pub psnr_min: Option<f64>,
    pub silhouette_px_max: Option<f64>,
    /// Largest distance over allowed distance after the second look (≤ 1: the bound holds).
    pub silhouette_ratio_max: Option<f64>,
    /// Pixels beyond the bound after the second look, summed over the frames.
    pub silhouette_bound_violations: Option<u64>,
    /// Pixels beyond the bound at pixel spacing settled as sub-pixel features.
    pub silhouette_subpixel: Option<u64>,
    /// Pixels of buildings the maps declare thin or dropped, within the bound of their own
    /// mesh silhouette.
    pub silhouette_thin: Option<u64>,
    pub popping_px_max: Option<f64>,
    pub hybrid_ms: Option<f64>,
    pub mesh_ms: Option<f64>,
    pub frame_time_ratio_vs_mesh: Option<f64>,
}

fn route_of(
    choice: &RouteChoice,
    scene: &Scene,
    size: Size,
    near_share: f64,
) -> anyhow::Result<CameraRoute> {
    if *choice == RouteChoice::Flyover {
        return Ok(flyover_route_with_near(
            scene.city_bounds(),
            size.aspect(),
            near_share,
        )?);
    }
    Ok(blockwalk::walk::job::resolve_route(choice, scene, size.aspect())?.0)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.frames >= 2, "--frames {}: at least 2", args.frames);
    for &tau in &args.taus {
        SelectOptions::new(tau, SelectOptions::default().hysteresis)?;
    }
    for &k in &args.ks {
        blockwalk::blockmap::BuildOptions {
            k,
            ..Default::default()
        }
        .validate()?;
    }
    let opts = SceneOptions {
        structures: vec![blockwalk::index::Structure::Bqr],
        occlusion: None,
        ..SceneOptions::default()
    };
    let scene = load_scene(&args.city, args.seed, &opts)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let routes: Vec<(String, CameraRoute)> = args
        .routes
        .iter()
        .map(|r| {
            Ok((
                r.to_string(),
                route_of(r, &scene, args.size, args.flyover_near_share)?,
            ))
        })
        .collect::<anyhow::Result<_>>()?;
    // The exact prisms: the walk checks the silhouette bound with them, and `--diagnose`
    // classifies pixels with them.
    let source =
        blockwalk::blockmap::Source::new(&scene.city, &scene.layout, &scene.building_meshes)
            .with_context(|| format!("preparing the buildings of {}", scene.name))?;
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    let mut files = Vec::new();
    let mut reports = Vec::new();
    for &k in &args.ks {
        let t0 = std::time::Instant::now();
        let build = blockwalk::blockmap::BuildOptions {
            k,
            edges: args.edges > 0,
            two_edges: args.edges > 1,
            ..Default::default()
        };
        let progress = super::common::Progress::new(args.json);
        use blockwalk::walk::{BuildFar, JobProgress};
        progress.stage(&format!(
            "building the BlockMaps of {} (K = {k})",
            scene.name
        ));
        let maps = blockwalk::blockmap::MapTree::build(
            &scene,
            &blockwalk::walk::BlockMapsOptions { build },
            &|d, t| progress.count(d, t),
        )
        .with_context(|| format!("building the BlockMaps of {}", scene.name))?;
        progress.finish();
        let build_s = t0.elapsed().as_secs_f64();
        if !args.json {
            outln!(
                "{}: K = {k}: {} maps in {build_s:.1} s",
                scene.name,
                maps.maps.len()
            );
        }
        let gpu = args
            .gpu
            .then(|| super::walk::gpu().renderer(&scene, args.size.pair(), Some(&maps)));
        if let Some(Err(e)) = &gpu {
            notes.push(format!(
                "K = {k}: no GPU renderer ({e}); CPU hybrid renderer"
            ));
        }
        for (rname, route) in &routes {
            for &tau in &args.taus {
                let params = WalkParams {
                    route: route.clone(),
                    frames: args.frames,
                    occlusion: OcclusionMode::Off,
                    image_every: 0,
                    oracle: false,
                    size: args.size.pair(),
                };
                let drawing = match &gpu {
                    Some(Ok(r)) => Drawing::With(r.as_ref()),
                    _ => Drawing::CpuFallback {
                        reason: "farfield-sweep".into(),
                    },
                };
                let far = FarSetup {
                    select: SelectOptions {
                        tau_px: tau,
                        ..SelectOptions::default()
                    },
                    reference: true,
                    leave_out: false,
                    source: Some(&source),
                    ..FarSetup::new(&maps)
                };
                let rec = run_walk_with_far(&scene, &params, drawing, Some(far), &mut |_, _| {})?;
                let d = rec
                    .far_decision
                    .clone()
                    .unwrap_or(blockwalk::walk::FarDecision {
                        used: false,
                        reason: None,
                        left_out_after: None,
                    });
                let j = FarSummary::new(&rec.far, &d, &far.select);
                if args.diagnose {
                    let p = args.out.join(format!("diagnose_{rname}_k{k}_tau{tau}"));
                    diagnose(
                        &scene, &source, &maps, route, &args, &rec.far, far.select, &p,
                    )?;
                    files.push(p.with_extension("md"));
                }
                let row = Row {
                    city: scene.name.clone(),
                    route: rname.clone(),
                    k,
                    tau_px: tau,
                    maps: maps.maps.len(),
                    frames: args.frames,
                    far_nodes: j.far_nodes.unwrap_or(0.0),
                    mesh_triangles: j.mesh_triangles.unwrap_or(0.0),
                    coverage_error_max: j.coverage_error_max,
                    coverage_error_mean: j.coverage_error_mean,
                    psnr_min: j.psnr_min,
                    silhouette_px_max: j.silhouette_px_max,
                    silhouette_ratio_max: j.silhouette_ratio_max,
                    silhouette_bound_violations: j.silhouette_bound_violations,
                    silhouette_subpixel: j.silhouette_subpixel,
                    silhouette_thin: j.silhouette_thin,
                    popping_px_max: j.popping_px_max,
                    hybrid_ms: j.frame_s.map(|s| s * 1e3),
                    mesh_ms: j.mesh_frame_s.map(|s| s * 1e3),
                    frame_time_ratio_vs_mesh: j.frame_time_ratio_vs_mesh,
                };
                if !args.json {
                    outln!("{}", table_line(&row));
                }
                // The walk report of one configuration per route: τ = 1 at K = 64 when swept,
                // else the first.
                let show_k = if args.ks.contains(&64) {
                    64
                } else {
                    args.ks[0]
                };
                let show_t = if args.taus.contains(&1.0) {
                    1.0
                } else {
                    args.taus[0]
                };
                if k == show_k && tau == show_t {
                    let dir = args.out.join(format!("walk_{rname}_k{k}_tau{tau}"));
                    reports.push((rec, dir));
                }
                rows.push(row);
            }
        }
    }
    files.extend(write_outputs(&args.out, &scene.name, &rows)?);
    // The walk reports, written last so that each embeds the sweep's error against time.
    let ctx = blockwalk::report::walk::ReportContext {
        plan: blockwalk::report::walk::Plan::from_scene(&scene),
        machine: Some(blockwalk::report::walk::Machine::detect()),
        command: std::env::args().collect(),
        extra_plots: vec![(
            "Coverage error against frame time over the whole sweep (every route, τ and K), with \
             the Pareto front"
                .into(),
            args.out.join("pareto.png"),
        )],
    };
    for (rec, dir) in &reports {
        files.extend(
            blockwalk::report::walk::write_with(rec, dir, None, &ctx)
                .with_context(|| format!("writing {}", dir.display()))?,
        );
    }
    if args.json {
        outln!(
            "{}",
            serde_json::to_string(&serde_json::json!({
                "city": scene.name, "size": [args.size.width, args.size.height],
                "frames": args.frames, "rows": rows, "notes": notes, "files": files,
            }))?
        );
    } else {
        for n in &notes {
            outln!("note: {n}");
        }
        outln!("table: {}", args.out.join("sweep.md").display());
    }
    Ok(())
}

/// Classifies the mismatched pixels of the frames with the largest coverage error and the
/// largest silhouette distance, replaying the walk's selection up to them (the selector's
/// hysteresis depends on the frames before).
#[allow(clippy::too_many_arguments)]
fn diagnose(
    scene: &Scene,
    source: &blockwalk::blockmap::Source,
    maps: &blockwalk::blockmap::MapTree,
    route: &CameraRoute,
    args: &Args,
    records: &[blockwalk::walk::FarRecord],
    opts: SelectOptions,
    path: &std::path::Path,
) -> anyhow::Result<()> {
    use blockwalk::blockmap::diagnose::{diagnose_frame, FrameInput};
    let key = |f: &dyn Fn(&blockwalk::walk::ImageError) -> f64| {
        records
            .iter()
            .filter_map(|r| r.image.as_ref().map(|i| (r.frame, f(i))))
            .fold(None, |a: Option<(usize, f64)>, (fr, v)| match a {
                Some((_, b)) if b >= v => a,
                _ => Some((fr, v)),
            })
            .map(|x| x.0)
    };
    let mut frames: Vec<usize> = [
        key(&|i| i.coverage_error),
        // The frame farthest beyond the bound after the second look, else the raw distance.
        key(&|i| i.silhouette_ratio_max.unwrap_or(i.silhouette_px)),
    ]
    .into_iter()
    .flatten()
    .collect();
    frames.dedup();
    let cameras = route.sample(args.frames);
    let mut sel = blockwalk::blockmap::Selector::new(maps, &scene.bounds, opts)?;
    let mut md = String::new();
    let mut js = Vec::new();
    let (w, h) = args.size.pair();
    for (f, cam) in cameras.iter().enumerate() {
        let s = sel.select(cam, h, None);
        if !frames.contains(&f) {
            continue;
        }
        let d = diagnose_frame(&FrameInput {
            source,
            ground: Some(&scene.ground),
            tree: maps,
            selection: &s,
            camera: cam,
            width: w,
            height: h,
            tau_px: opts.tau_px,
        });
        md.push_str(&format!("## frame {f}\n\n{}\n", d.table()));
        if !args.json {
            outln!("frame {f}:\n{}", d.table());
        }
        js.push(serde_json::json!({"frame": f, "diagnosis": d}));
    }
    let p = path.with_extension("md");
    std::fs::write(&p, md).with_context(|| format!("writing {}", p.display()))?;
    let p = path.with_extension("json");
    std::fs::write(&p, serde_json::to_string_pretty(&js)?)
        .with_context(|| format!("writing {}", p.display()))?;
    Ok(())
}

const HEADER: &str = "| city | route | K | τ px | maps | far nodes | mesh tris | coverage err max | PSNR min dB | silhouette px max | ratio max | bound violations | sub-pixel | thin | popping px max | hybrid ms | mesh ms | ratio |";

/// Columns of [`HEADER`].
const COLUMNS: usize = 18;

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map(|v| format!("{v:.digits$}")).unwrap_or("–".into())
}

fn count(v: Option<u64>) -> String {
    v.map(|v| v.to_string()).unwrap_or("–".into())
}

fn table_line(r: &Row) -> String {
    format!(
        "| {} | {} | {} | {} | {} | {:.1} | {:.0} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
        r.city,
        r.route,
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

/// Points of `pts` (ms, error) no other point beats in both, by ms.
fn pareto(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.retain(|p| p.0.is_finite() && p.1.is_finite());
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for p in pts {
        if out.last().is_none_or(|l| p.1 < l.1) {
            out.push(p);
        }
    }
    out
}

fn write_outputs(dir: &std::path::Path, city: &str, rows: &[Row]) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let mut md = format!("{HEADER}\n|{}\n", "---|".repeat(COLUMNS));
    for r in rows {
        md.push_str(&table_line(r));
        md.push('\n');
    }
    let p = dir.join("sweep.md");
    std::fs::write(&p, md).with_context(|| format!("writing {}", p.display()))?;
    files.push(p);
    let p = dir.join("sweep.json");
    std::fs::write(&p, serde_json::to_string_pretty(rows)?)
        .with_context(|| format!("writing {}", p.display()))?;
    files.push(p);
    // Error against milliseconds: one series per K, the mesh-only frames at zero error, and the
    // Pareto front over all configurations.
    let mut ks: Vec<u32> = rows.iter().map(|r| r.k).collect();
    ks.dedup();
    let mut series: Vec<Series> = ks
        .iter()
        .map(|&k| Series {
            name: format!("K = {k}"),
            points: rows
                .iter()
                .filter(|r| r.k == k)
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
    for ext in ["png", "svg"] {
        let p = dir.join(format!("pareto.{ext}"));
        write_plot(
            &p,
            &format!("{city}: coverage error against frame time (all routes, τ, K)"),
            "ms per frame",
            "coverage error max, %",
            &series,
            PlotKind::Points,
        )?;
        files.push(p);
    }
    Ok(files)
}
