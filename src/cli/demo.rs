//! `blockwalk demo`: the whole pipeline on the bundled real data (Bubeneč, Prague and Helsinki
//! centre), step by step, through the same commands a user runs.

use std::path::{Path, PathBuf};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder with the bundled data (`bubenec/`, `helsinki/`). Default: the first `data/` that
    /// holds them in the working directory or one of its parents, else beside the executable or
    /// one of its parents.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Frames along the paper route.
    #[arg(long, default_value_t = 150)]
    pub frames: usize,
    /// Image size of rendered frames and of the visibility oracle.
    #[arg(long, default_value = "960x540")]
    pub size: String,
    /// Fewer views and frames, for a quick look.
    #[arg(long)]
    pub quick: bool,
}

/// One step of the demo: a heading and the command line that runs it.
struct Step {
    title: String,
    argv: Vec<String>,
}

fn step(title: &str, argv: &[&str]) -> Step {
    Step {
        title: title.to_string(),
        argv: std::iter::once("blockwalk")
            .chain(argv.iter().copied())
            .map(String::from)
            .collect(),
    }
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap_or_default()
}

/// True when `d` holds the bundled data the demo reads.
fn has_data(d: &Path) -> bool {
    d.join("bubenec/buildings.shp").is_file() && d.join("helsinki/buildings.shp").is_file()
}

/// The candidate data folders, in order: `data/` in the working directory and each parent, then
/// beside the executable and each of its parents.
fn data_candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let roots = [
        std::env::current_dir().ok(),
        std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(Path::to_path_buf)),
    ];
    for root in roots.into_iter().flatten() {
        for dir in root.ancestors() {
            let c = dir.join("data");
            if !out.contains(&c) {
                out.push(c);
            }
        }
    }
    out
}

/// The data folder: `--data` when given, else the first candidate that holds the data.
fn find_data(given: Option<&Path>) -> anyhow::Result<PathBuf> {
    if let Some(d) = given {
        anyhow::ensure!(
            has_data(d),
            "{}: the bundled data is not there (expected bubenec/buildings.shp and \
             helsinki/buildings.shp)",
            d.display()
        );
        return Ok(d.to_path_buf());
    }
    let candidates = data_candidates();
    candidates
        .iter()
        .find(|d| has_data(d))
        .cloned()
        .ok_or_else(|| {
            let looked: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
            anyhow::anyhow!(
                "the bundled data (bubenec/buildings.shp, helsinki/buildings.shp) was not found; \
             looked in: {}; run from the repository or pass --data DIR",
                looked.join(", ")
            )
        })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let data = find_data(args.data.as_deref())?;
    let d = &data;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.out.display()))?;
    let o = |name: &str| args.out.join(name);
    let (bub, bub_streets) = (
        d.join("bubenec/buildings.shp"),
        d.join("bubenec/streets.shp"),
    );
    let (hel, hel_streets) = (
        d.join("helsinki/buildings.shp"),
        d.join("helsinki/streets_blockclass.shp"),
    );
    let frames = if args.quick { 40 } else { args.frames }.to_string();
    let views = if args.quick { "40" } else { "200" };
    let (bub_glb, bub_fp, bub_blocks, bub_png) = (
        o("bubenec.glb"),
        o("bubenec_footprints.geojson"),
        o("bubenec_blocks.geojson"),
        o("bubenec_blocks.png"),
    );
    let (hel_glb, hel_blocks, hel_png, hel_plot, hel_walk) = (
        o("helsinki.glb"),
        o("helsinki_blocks.geojson"),
        o("helsinki_blocks.png"),
        o("helsinki_occlusion.png"),
        o("helsinki_walk"),
    );
    let steps = [
        step(
            "Bubeneč, Prague (EPSG:3857): import, repair, extrude, export",
            &[
                "import",
                p(&bub),
                "--streets",
                p(&bub_streets),
                "-o",
                p(&bub_glb),
                "--geojson",
                p(&bub_fp),
            ],
        ),
        step(
            "Bubeneč: urban blocks from the street layer",
            &[
                "blocks",
                p(&bub),
                "--streets",
                p(&bub_streets),
                "-o",
                p(&bub_blocks),
                "--png",
                p(&bub_png),
            ],
        ),
        step(
            "Helsinki centre (EPSG:3067, OpenStreetMap): import, repair, extrude, export",
            &[
                "import",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "-o",
                p(&hel_glb),
            ],
        ),
        step(
            "Helsinki: urban blocks from the street layer",
            &[
                "blocks",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "-o",
                p(&hel_blocks),
                "--png",
                p(&hel_png),
            ],
        ),
        step(
            "Helsinki: frustum culling with every structure (checked against brute force)",
            &[
                "cull-bench",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "--views",
                views,
            ],
        ),
        step(
            "Helsinki: occlusion culling with the cull map (checked against the visibility oracle)",
            &[
                "occlusion-bench",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "--views",
                views,
                "--resolution",
                "64,256,1024",
                "--plot",
                p(&hel_plot),
            ],
        ),
        step(
            "Helsinki: the paper's camera route with every structure, rendered",
            &[
                "walk",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "--route",
                "paper",
                "--frames",
                &frames,
                "--render",
                "--oracle",
                "--size",
                &args.size,
                "--image-every",
                "15",
                "--out",
                p(&hel_walk),
            ],
        ),
    ];
    let started = std::time::Instant::now();
    for (i, s) in steps.iter().enumerate() {
        outln!("\n== {}/{} {}", i + 1, steps.len(), s.title);
        outln!("   $ {}", s.argv.join(" "));
        super::run_argv(&s.argv)?;
    }
    outln!(
        "\ndemo done in {:.1} s; open {} (the walk report), and the maps and .glb files in {}",
        started.elapsed().as_secs_f64(),
        hel_walk.join("report.html").display(),
        args.out.display()
    );
    Ok(())
}
