//! `blockwalk demo`: the whole pipeline on the bundled real data (Bubeneč, Prague and Helsinki
//! centre), step by step, through the same commands a user runs; `--astana` runs it end to end
//! on Astana (32,056 buildings, 10,176 streets), which is not in the repository.

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
    /// Run the pipeline end to end on Astana (32,056 buildings, 10,176 streets) instead of the
    /// bundled data: import, blocks, extrusion, `.glb` and CityJSON, BlockMaps, occlusion, and
    /// the rendered walk. The data is too big for the repository: DIR, or by default the first
    /// `../shared/data/astana` or `shared/data/astana` found from the working directory upwards.
    #[arg(long, num_args = 0..=1, default_missing_value = "auto", value_name = "DIR")]
    pub astana: Option<PathBuf>,
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

/// True when `d` holds the Astana layers the demo reads.
fn has_astana(d: &Path) -> bool {
    d.join("buildings.shp").is_file() && d.join("streets_blockclass.shp").is_file()
}

/// Footprints in the Astana data, as the demo's headings and figures state.
const ASTANA_BUILDINGS: u64 = 32_056;

/// Records in a Shapefile, from its `.shx` index (100-byte header, 8 bytes a record).
fn shx_records(shp: &Path) -> Option<u64> {
    let len = std::fs::metadata(shp.with_extension("shx")).ok()?.len();
    (len >= 100 && (len - 100).is_multiple_of(8)).then_some((len - 100) / 8)
}

/// `d` holds Astana's layers and its footprint count: another city's folder is refused rather
/// than run under Astana's headings.
fn check_astana(d: &Path) -> anyhow::Result<()> {
    let fp = d.join("buildings.shp");
    match shx_records(&fp) {
        Some(ASTANA_BUILDINGS) => Ok(()),
        Some(n) => anyhow::bail!(
            "{}: {n} footprints, not Astana's {ASTANA_BUILDINGS}: this folder is not the Astana \
             data, and `demo --astana` would run it under Astana's headings and figures; for \
             another city run the commands of the README's \"Your own city\" on it",
            fp.display()
        ),
        None => anyhow::bail!(
            "{}: no readable .shx index beside it to count the footprints (Astana has \
             {ASTANA_BUILDINGS})",
            fp.display()
        ),
    }
}

/// The Astana folder: `given`, or for `auto` the first `../shared/data/astana` or
/// `shared/data/astana` from the working directory upwards.
fn find_astana(given: &Path) -> anyhow::Result<PathBuf> {
    if given != Path::new("auto") {
        anyhow::ensure!(
            has_astana(given),
            "{}: the Astana data is not there (expected buildings.shp and streets_blockclass.shp)",
            given.display()
        );
        check_astana(given)?;
        return Ok(given.to_path_buf());
    }
    let mut looked = Vec::new();
    if let Ok(cwd) = std::env::current_dir() {
        for dir in cwd.ancestors() {
            for rel in ["../shared/data/astana", "shared/data/astana"] {
                let c = dir.join(rel);
                if has_astana(&c) {
                    check_astana(&c)?;
                    return Ok(c);
                }
                looked.push(c.display().to_string());
            }
        }
    }
    anyhow::bail!(
        "the Astana data (buildings.shp, streets_blockclass.shp) is not in the repository (too \
         big) and was not found beside it; looked in: {}; pass --astana DIR",
        looked.join(", ")
    )
}

/// The Astana steps.
fn astana_steps(d: &Path, out: &Path, args: &Args) -> Vec<Step> {
    let o = |name: &str| out.join(name);
    let (fp, st) = (d.join("buildings.shp"), d.join("streets_blockclass.shp"));
    let (glb, cj, blocks, png, maps, plot, walk) = (
        o("astana.glb"),
        o("astana.city.jsonl"),
        o("astana_blocks.geojson"),
        o("astana_blocks.png"),
        o("astana_maps"),
        o("astana_occlusion.png"),
        o("astana_walk"),
    );
    let frames = if args.quick { 40 } else { args.frames }.to_string();
    let views = if args.quick { "40" } else { "200" };
    vec![
        step(
            "Astana (32,056 buildings): import, repair, extrude, export .glb and CityJSONSeq",
            &[
                "import",
                p(&fp),
                "--streets",
                p(&st),
                "-o",
                p(&glb),
                "--cityjson",
                p(&cj),
            ],
        ),
        step(
            "Astana: urban blocks from the street layer",
            &[
                "blocks",
                p(&fp),
                "--streets",
                p(&st),
                "-o",
                p(&blocks),
                "--png",
                p(&png),
            ],
        ),
        step(
            "Astana: BlockMaps for the block quadtree, with their measured error",
            &["blockmaps", p(&fp), "--streets", p(&st), "-o", p(&maps)],
        ),
        step(
            "Astana: occlusion culling with the cull map (checked against the visibility oracle)",
            &[
                "occlusion-bench",
                p(&fp),
                "--streets",
                p(&st),
                "--views",
                views,
                "--resolution",
                "256",
                "--plot",
                p(&plot),
            ],
        ),
        step(
            "Astana: the paper's camera route, BqR-tree and VAMSplit R-tree, rendered, BlockMaps far away",
            &[
                "walk",
                p(&fp),
                "--streets",
                p(&st),
                "--route",
                "paper",
                "--structures",
                "vamsplit,bqr",
                "--far",
                "blockmaps",
                "--frames",
                &frames,
                "--render",
                "--size",
                &args.size,
                "--image-every",
                "15",
                "--out",
                p(&walk),
            ],
        ),
    ]
}

/// Runs the steps in order, each echoed with its command line.
fn run_steps(steps: &[Step]) -> anyhow::Result<f64> {
    let started = std::time::Instant::now();
    for (i, s) in steps.iter().enumerate() {
        outln!("\n== {}/{} {}", i + 1, steps.len(), s.title);
        outln!("   $ {}", s.argv.join(" "));
        super::run_argv(&s.argv)?;
    }
    Ok(started.elapsed().as_secs_f64())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(dir) = &args.astana {
        let d = find_astana(dir)?;
        std::fs::create_dir_all(&args.out)
            .map_err(|e| anyhow::anyhow!("{}: {e}", args.out.display()))?;
        let steps = astana_steps(&d, &args.out, &args);
        let s = run_steps(&steps)?;
        outln!(
            "\nAstana done in {s:.1} s; open {} (the walk report), and the maps and models in {}",
            args.out.join("astana_walk/report.html").display(),
            args.out.display()
        );
        return Ok(());
    }
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
    let hel_maps = o("helsinki_maps");
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
            "Helsinki: BlockMaps for the block quadtree, every map checked against the meshes",
            &[
                "blockmaps",
                p(&hel),
                "--streets",
                p(&hel_streets),
                "--check",
                "1000",
                "-o",
                p(&hel_maps),
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
    let s = run_steps(&steps)?;
    outln!(
        "\ndemo done in {s:.1} s; open {} (the walk report), and the maps and .glb files in {}",
        hel_walk.join("report.html").display(),
        args.out.display()
    );
    Ok(())
}
