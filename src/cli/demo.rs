//! `blockwalk demo`: the whole pipeline on the bundled real data (Bubeneč, Prague and Helsinki
//! centre), step by step, through the same commands a user runs.

use std::path::{Path, PathBuf};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder with the bundled data (`bubenec/`, `helsinki/`).
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/data"))]
    pub data: PathBuf,
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

pub fn run(args: Args) -> anyhow::Result<()> {
    let d = &args.data;
    anyhow::ensure!(
        d.join("bubenec/buildings.shp").exists() && d.join("helsinki/buildings.shp").exists(),
        "{}: the bundled data is not there (expected bubenec/ and helsinki/; see --data)",
        d.display()
    );
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
        println!("\n== {}/{} {}", i + 1, steps.len(), s.title);
        println!("   $ {}", s.argv.join(" "));
        super::run_argv(&s.argv)?;
    }
    println!(
        "\ndemo done in {:.1} s; open {} (the walk report), and the maps and .glb files in {}",
        started.elapsed().as_secs_f64(),
        hel_walk.join("report.html").display(),
        args.out.display()
    );
    Ok(())
}
