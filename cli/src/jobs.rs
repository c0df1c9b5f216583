//! `blockwalk jobs`: a city in tiles, each tile a job for any batch engine (see
//! `blockwalk::jobs`): `plan` cuts the city, `run` does one tile, `merge` checks them all and
//! writes the index.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use blockwalk::blockmap::{BuildOptions, CityMapsOptions, Stop, TreeOptions};
use blockwalk::jobs::{city_files, merge, plan, run_tile, write_plan, PlanOptions, TileOptions};
use blockwalk::tiles::TilesetOptions;
use serde_json::json;

use super::common::spinner;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    step: Step,
}

#[derive(clap::Subcommand, Debug)]
enum Step {
    /// Cut the city into tiles of whole blocks; write DIR/plan.json and print one command per tile.
    Plan {
        /// A generated city's folder (buildings.shp, streets.shp) or a footprint .shp.
        city: PathBuf,
        /// Street centre lines (when CITY is a file).
        #[arg(long)]
        streets: Option<PathBuf>,
        /// Output folder.
        #[arg(short, long)]
        output: PathBuf,
        /// At most this many buildings per tile (one block with more is a tile of its own).
        #[arg(long, default_value_t = 50_000)]
        max_buildings: usize,
        /// Elevation model (GeoTIFF) every tile puts its buildings on (see `import --dem`).
        #[arg(long)]
        dem: Option<PathBuf>,
        /// With --dem: `min` (default) or `pNN`, how a building's base is taken.
        #[arg(long, default_value = "min", value_parser = blockwalk::city::build::ground::parse_rule)]
        base: blockwalk::terrain::BaseRule,
        /// Print one JSON object instead of the summary and the commands.
        #[arg(long)]
        json: bool,
    },
    /// Run one tile of a plan (a job): writes tiles/tile_NNNNN.glb and its manifest beside it.
    Run {
        /// The plan (DIR/plan.json).
        plan: PathBuf,
        /// The tile (0-based; the index of a job array).
        #[arg(long)]
        tile: usize,
        /// Build the tile's BlockMaps too, at this height-map side K (32, 64 or 128); maps
        /// stop where a node's meshes take fewer bytes than a map.
        #[arg(long)]
        blockmaps: Option<u32>,
        /// Write the tile's own 3D Tiles tileset too (tiles/tile_NNNNN_tileset/, as `blockwalk
        /// tileset` writes a city's, at the --blockmaps K or 64); `merge` then writes a root
        /// tileset.json that references every tile's.
        #[arg(long)]
        tileset: bool,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
    },
    /// Check that every tile finished and write DIR/index.json (and DIR/tileset.json over the
    /// tiles' tilesets when their jobs wrote them).
    Merge {
        /// The plan's folder.
        dir: PathBuf,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
    },
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.step {
        Step::Plan {
            city,
            streets,
            output,
            max_buildings,
            dem,
            base,
            json,
        } => {
            let ground = dem.map(|d| blockwalk::city::build::GroundOptions {
                rule: base,
                ..blockwalk::city::build::GroundOptions::new(d)
            });
            let (fp, st) = city_files(&city, streets.as_deref())?;
            let t0 = Instant::now();
            let pb = spinner("planning");
            let p = plan(
                &fp,
                &st,
                &PlanOptions {
                    max_buildings,
                    build: blockwalk::city::build::BuildOptions {
                        ground,
                        ..Default::default()
                    },
                },
                &mut |m| pb.set_message(m.to_string()),
            );
            pb.finish_and_clear();
            let p = p?;
            let path = write_plan(&p, &output)?;
            let secs = t0.elapsed().as_secs_f64();
            let exe = std::env::args()
                .next()
                .unwrap_or_else(|| "blockwalk".into());
            if json {
                outln!(
                    "{}",
                    json!({
                        "plan": path,
                        "plan_id": p.plan_id,
                        "city": p.city,
                        "buildings": p.buildings,
                        "outskirts_buildings": p.outskirts_buildings,
                        "blocks": p.blocks.len(),
                        "tiles": p.tiles.len(),
                        "max_tile_buildings": p.tiles.iter().map(|t| t.buildings).max(),
                        "seconds": secs,
                        "peak_rss_bytes": blockwalk::process::peak_rss_bytes(),
                        "commands": (0..p.tiles.len()).map(|i| format!("{exe} jobs run {} --tile {i}", path.display())).collect::<Vec<_>>(),
                    })
                );
            } else {
                eprintln!(
                    "{}: {} buildings ({} in outskirts) in {} blocks, {} tiles of at most {} buildings (largest {}); plan {} in {:.1} s",
                    p.city,
                    p.buildings,
                    p.outskirts_buildings,
                    p.blocks.len(),
                    p.tiles.len(),
                    max_buildings,
                    p.tiles.iter().map(|t| t.buildings).max().unwrap_or(0),
                    path.display(),
                    secs
                );
                for i in 0..p.tiles.len() {
                    outln!("{exe} jobs run {} --tile {i}", path.display());
                }
            }
        }
        Step::Run {
            plan,
            tile,
            blockmaps,
            tileset,
            json,
        } => {
            if let Some(k) = blockmaps {
                BuildOptions {
                    k,
                    ..BuildOptions::default()
                }
                .validate()?;
            }
            let pb = spinner(format!("tile {tile}"));
            let maps = blockmaps.map(|k| CityMapsOptions {
                tree: TreeOptions {
                    build: BuildOptions {
                        k,
                        ..BuildOptions::default()
                    },
                    stop: Stop::Competitive,
                    ..TreeOptions::default()
                },
                checks: 0,
                ..CityMapsOptions::default()
            });
            let opts = TileOptions {
                maps,
                tileset: tileset.then(|| TilesetOptions {
                    k: blockmaps.unwrap_or(TilesetOptions::default().k),
                    ..TilesetOptions::default()
                }),
            };
            let r = run_tile(&plan, tile, &opts);
            pb.finish_and_clear();
            let r = r?;
            let m = &r.manifest;
            if json {
                outln!("{}", serde_json::to_string(m).context("manifest as JSON")?);
            } else {
                outln!(
                    "tile {} (key {}): {} blocks, {} buildings ({} read), {} triangles, {} BlockMaps, {} 3D Tiles, {} in {:.1} s, peak {} MiB",
                    m.tile,
                    m.key,
                    m.blocks.len(),
                    m.buildings,
                    m.buildings_read,
                    m.triangles,
                    m.blockmaps.as_ref().map_or(0, |b| b["maps"].as_u64().unwrap_or(0)),
                    m.tileset.as_ref().map_or(0, |t| t.tiles),
                    r.manifest_path.display(),
                    m.seconds,
                    m.peak_rss_bytes.unwrap_or(0) / (1 << 20)
                );
            }
        }
        Step::Merge { dir, json } => {
            let (index, path) = merge(&dir)?;
            if json {
                let mut v = serde_json::to_value(&index)?;
                if let Some(o) = v.as_object_mut() {
                    o.remove("tiles");
                    o.insert("tiles".into(), json!(index.tiles.len()));
                    o.insert("index".into(), json!(path));
                }
                outln!("{v}");
            } else {
                outln!(
                    "{}: {} tiles, {} blocks, {} buildings, {} triangles, {:.1} MiB; jobs {:.1} s in all, largest peak {} MiB; {}",
                    index.city,
                    index.tiles.len(),
                    index.blocks,
                    index.buildings,
                    index.triangles,
                    index.bytes as f64 / 1048576.0,
                    index.job_seconds,
                    index.max_peak_rss_bytes.unwrap_or(0) / (1 << 20),
                    path.display()
                );
                if let Some(t) = &index.tileset {
                    outln!(
                        "3D Tiles: {} over the tiles' tilesets",
                        dir.join(t).display()
                    );
                }
            }
        }
    }
    Ok(())
}
