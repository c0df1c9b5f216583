//! The `blockwalk` command line: one module per subcommand. The only place `anyhow` is used.
//!
//! Everything printed to standard output goes through [`outln!`] / [`out!`], which turn a closed
//! pipe (`blockwalk import … --json | head -c 10`) into [`StdoutClosed`]: the command stops, and
//! the process exits quietly with status 0, as when the reader has read all it wanted (the
//! conventional alternative, dying of SIGPIPE with status 141, would make `set -o pipefail`
//! scripts fail for a reader that stopped early on purpose). Other write errors on standard
//! output are reported as errors.

use std::io::Write;

use clap::{Parser, Subcommand};

/// `println!` that returns [`StdoutClosed`] (through `?`) instead of panicking when standard
/// output is a closed pipe.
macro_rules! outln {
    () => {
        out!("\n")
    };
    ($($arg:tt)*) => {
        out!("{}\n", ::std::format_args!($($arg)*))
    };
}

/// `print!` that returns [`StdoutClosed`] (through `?`) instead of panicking when standard
/// output is a closed pipe.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::stdout_written(::std::io::Write::write_fmt(
            &mut ::std::io::stdout().lock(),
            ::std::format_args!($($arg)*),
        ))?
    };
}

mod blockmaps;
mod blocks;
mod common;
mod cull_bench;
mod cull_proof;
mod demo;
mod farfield_sweep;
mod generate;
mod import;
mod jobs;
mod occlusion_bench;
mod relief;
mod relief_tree;
mod serve;
mod terrain;
mod tileset;
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
    /// The relief-impostor tree over the buildings: groups, levels, overlap ratio, formulas.
    ReliefTree(relief_tree::Args),
    /// Multi-level relief impostors: every node's maps, their cost and coverage error.
    Relief(relief::Args),
    /// A city on an elevation model: its terrain tree, the per-frame cut at τ px and its error
    /// against the full-resolution terrain along a route.
    Terrain(terrain::Args),
    /// The city as a 3D Tiles 1.1 tileset (block quadtree, BlockMap height fields, building meshes).
    Tileset(tileset::Args),
    /// Compare spatial structures on frustum culling.
    CullBench(cull_bench::Args),
    /// Check culling against the oracle on every frame of every route over the cities.
    CullProof(cull_proof::Args),
    /// A city in tiles: plan, run one tile (a batch job), merge.
    Jobs(jobs::Args),
    /// Occlusion culling with the cull map, checked against the visibility oracle.
    OcclusionBench(occlusion_bench::Args),
    /// Walk a camera route through the city with every structure; report and render.
    Walk(walk::Args),
    /// Far-field error against run time: τ × K × routes, hybrid against mesh-only frames.
    FarfieldSweep(farfield_sweep::Args),
    /// The main job on the bundled real data.
    Demo(demo::Args),
    /// Serve a tiled city's folder over HTTP (range requests) for streamed walks.
    Serve(serve::Args),
    /// Fly through the city in a window (feature `window`).
    #[command(after_help = view::KEYS)]
    View(view::Args),
}

/// Standard output was closed by its reader: the command stops, and the process exits with
/// status 0 without a message (see the module doc).
#[derive(Debug, thiserror::Error)]
#[error("standard output was closed")]
pub struct StdoutClosed;

/// The result of a write to standard output: a broken pipe becomes [`StdoutClosed`], other
/// errors say they happened on standard output.
pub fn stdout_written(r: std::io::Result<()>) -> anyhow::Result<()> {
    match r {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("writing to standard output")),
    }
}

/// When `XDG_RUNTIME_DIR` is unset, points it at a private folder (mode 0700) made for this
/// process, so that the graphics drivers (Mesa) find one instead of warning on standard error;
/// returns that folder, to be removed at exit.
fn private_runtime_dir() -> Option<std::path::PathBuf> {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("blockwalk-runtime-{}", std::process::id()));
    let mut b = std::fs::DirBuilder::new();
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut b, 0o700);
    b.create(&dir).ok()?;
    std::env::set_var("XDG_RUNTIME_DIR", &dir);
    Some(dir)
}

fn main() -> std::process::ExitCode {
    let runtime_dir = private_runtime_dir();
    let status = run_main();
    if let Some(d) = runtime_dir {
        let _ = std::fs::remove_dir_all(d);
    }
    status
}

fn run_main() -> std::process::ExitCode {
    // Not `Cli::parse`, which exits the process (leaving the runtime folder behind).
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return std::process::ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    match dispatch(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if e.chain().any(|c| c.is::<StdoutClosed>()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // Standard error may be closed too: the exit status still tells.
            let _ = writeln!(std::io::stderr(), "error: {}", error_text(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by `: `, as `{e:#}` prints them, except a cause that the
/// message before it already ends with (errors that print their source, such as
/// `"{file}: {source}"`, would otherwise show it twice).
fn error_text(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if !out.is_empty() && out.ends_with(&s) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&s);
    }
    out
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
        Command::ReliefTree(a) => relief_tree::run(a),
        Command::Terrain(a) => terrain::run(a),
        Command::Relief(a) => relief::run(a),
        Command::Tileset(a) => tileset::run(a),
        Command::CullBench(a) => cull_bench::run(a),
        Command::CullProof(a) => cull_proof::run(a),
        Command::Jobs(a) => jobs::run(a),
        Command::OcclusionBench(a) => occlusion_bench::run(a),
        Command::Walk(a) => walk::run(a),
        Command::FarfieldSweep(a) => farfield_sweep::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Serve(a) => serve::run(a),
        Command::View(a) => view::run(a),
    }
}
