//! Command-line interface: one module per subcommand. The only place `anyhow` is used.

use clap::{Parser, Subcommand};

mod blockmaps;
mod blocks;
mod common;
mod cull_bench;
mod demo;
mod generate;
mod import;
mod occlusion_bench;
mod view;
mod walk;

/// Cadastral maps to navigable 3D cities.
#[derive(Parser, Debug)]
#[command(name = "blockwalk", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Import footprints (and streets, parcels), extrude, export glTF / GeoJSON, report.
    Import(import::Args),
    /// Generate a procedural city as Shapefiles.
    Generate(generate::Args),
    /// Detect streets and urban blocks; assign buildings.
    Blocks(blocks::Args),
    /// BlockMaps for the block quadtree's nodes, with their measured error.
    Blockmaps(blockmaps::Args),
    /// Compare spatial structures on frustum culling.
    CullBench(cull_bench::Args),
    /// Occlusion culling with the cull map, checked against the visibility oracle.
    OcclusionBench(occlusion_bench::Args),
    /// Walk a camera route through the city with every structure; report and render.
    Walk(walk::Args),
    /// The main job on the bundled real data.
    Demo(demo::Args),
    /// Fly through the city in a window (feature `window`).
    View(view::Args),
}

pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match dispatch(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Runs a command line as if it had been typed (used by `demo`).
fn run_argv(argv: &[String]) -> anyhow::Result<()> {
    let cli = Cli::try_parse_from(argv)?;
    dispatch(cli.command)
}

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Import(a) => import::run(a),
        Command::Generate(a) => generate::run(a),
        Command::Blocks(a) => blocks::run(a),
        Command::Blockmaps(a) => blockmaps::run(a),
        Command::CullBench(a) => cull_bench::run(a),
        Command::OcclusionBench(a) => occlusion_bench::run(a),
        Command::Walk(a) => walk::run(a),
        Command::Demo(a) => demo::run(a),
        Command::View(a) => view::run(a),
    }
}
