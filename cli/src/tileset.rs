//! `blockwalk tileset`: the city as a 3D Tiles 1.1 tileset (the block quadtree; BlockMap height
//! fields inside, building meshes at the leaves), for CesiumJS and other 3D Tiles viewers.

use super::common::{load_scene, CityArgs};
use blockwalk::blockmap::Stop;
use blockwalk::scene::SceneOptions;
use blockwalk::tiles::{build_tileset, ContentEncoding, TilesetOptions};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub city: CityArgs,
    /// Height-map side K of the inner tiles' BlockMaps: 32, 64 or 128.
    #[arg(long, default_value_t = 64)]
    pub k: u32,
    /// Inner tiles for the first N levels of the quadtree (default: a map where it costs fewer
    /// bytes than the meshes, Cignoni et al., §4).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub levels: Option<u32>,
    /// Write a 3D Tiles 1.1 implicit quadtree (subtree files under subtrees/, contents at
    /// tiles/{level}/{x}/{y}.glb, each tile's own box and error as tile metadata) with the same
    /// tiles as the default explicit tileset.json. For viewers with implicit tiling (CesiumJS,
    /// 3d-tiles-tools); the terrain's tileset stays explicit.
    #[arg(long)]
    pub implicit: bool,
    /// Levels per subtree file of the implicit form.
    #[arg(long, default_value_t = blockwalk::tiles::implicit::DEFAULT_SUBTREE_LEVELS,
          value_parser = clap::value_parser!(u32).range(1..=16))]
    pub subtree_levels: u32,
    /// Write one file, a 3D Tiles archive (.3tz: a ZIP with an MD5 index), instead of a folder;
    /// implied when -o ends in .3tz. Works with the explicit and the implicit form. CesiumJS
    /// reads no .3tz itself: `blockwalk serve CITY.3tz` serves its entries, so a viewer loads
    /// http://ADDR/tileset.json.
    #[arg(long = "3tz")]
    pub archive: bool,
    /// Output directory (tileset.json and tiles/), or the .3tz file.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Print one JSON object instead of the human summary.
    #[arg(long)]
    pub json: bool,
    /// Write plain glTF contents (f32 positions and normals, no compression) instead of compact
    /// ones (positions within 1 mm, KHR_mesh_quantization, EXT_meshopt_compression): for viewers
    /// without EXT_meshopt_compression.
    #[arg(long)]
    pub plain: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    blockwalk::blockmap::BuildOptions {
        k: args.k,
        ..Default::default()
    }
    .validate()?;
    let t0 = std::time::Instant::now();
    let mut scene = load_scene(
        &args.city,
        0,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
    )?;
    // The tileset reads the buildings' own meshes, never the merged block meshes.
    scene.release_block_meshes();
    let bar = if args.json || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr())
    };
    bar.set_style(
        ProgressStyle::with_template("tileset [{bar:40}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let opts = TilesetOptions {
        k: args.k,
        stop: args.levels.map_or(Stop::Competitive, Stop::Levels),
        implicit: args.implicit,
        subtree_levels: args.subtree_levels,
        archive: args.archive
            || args
                .out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("3tz")),
        content: if args.plain {
            ContentEncoding::Plain
        } else {
            ContentEncoding::Compact
        },
        ..TilesetOptions::default()
    };
    let (_, summary) = build_tileset(
        &scene.city,
        &scene.layout,
        &scene.bounds,
        &scene.building_meshes,
        &args.out,
        &opts,
        &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    )?;
    bar.finish_and_clear();
    let total_s = t0.elapsed().as_secs_f64();
    if args.json {
        let mut v = serde_json::to_value(&summary)?;
        v["total_seconds"] = serde_json::json!(total_s);
        v["import"] = super::common::city_report_json(&scene.city);
        outln!("{}", serde_json::to_string(&v)?);
    } else {
        for line in super::common::city_report_lines(&scene.city) {
            outln!("{line}");
        }
        outln!(
            "{}: {} tiles ({} BlockMap height fields, {} building leaves), depth {}, {} buildings, {:.2} MiB, built in {:.1} s ({:.1} s with loading)",
            summary.city,
            summary.tiles,
            summary.map_tiles,
            summary.leaf_tiles,
            summary.depth,
            summary.buildings,
            summary.bytes as f64 / 1048576.0,
            summary.seconds,
            total_s
        );
        outln!("root geometric error {:.2} m", summary.root_geometric_error);
        outln!(
            "{} form{}{}",
            if summary.implicit {
                "implicit"
            } else {
                "explicit"
            },
            if summary.implicit {
                format!(" ({} subtree files)", summary.subtrees)
            } else {
                String::new()
            },
            if summary.archive {
                ", one .3tz archive"
            } else {
                ""
            }
        );
        match summary.content {
            ContentEncoding::Compact => outln!(
                "contents compact (KHR_mesh_quantization, EXT_meshopt_compression): positions within {:.2} mm of f32",
                summary.position_error_m * 1e3
            ),
            ContentEncoding::Plain => outln!("contents plain glTF (f32, uncompressed)"),
        }
        outln!("{}", summary.placement());
        outln!("wrote {}", summary.tileset_json.display());
    }
    Ok(())
}
