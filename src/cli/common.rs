//! Inputs shared by the commands that take a city.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use blockwalk::city::build::{build_city, BuildOptions};
use blockwalk::city::City;
use blockwalk::importers::{read_layer, Layer, Theme};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A city on the command line: footprints, optional streets and parcels, or a generated city's
/// directory.
#[derive(clap::Args, Debug, Clone)]
pub struct CityArgs {
    /// Footprint file(s) (.shp, .geojson, .gpkg[:table], .osm.pbf) or a generated city directory.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Street centre lines.
    #[arg(long)]
    pub streets: Option<PathBuf>,
    /// Cadastral parcels.
    #[arg(long)]
    pub parcels: Option<PathBuf>,
    /// Leave out street features with this attribute value (k=v), e.g. `tunnel=1`.
    #[arg(long = "exclude-tag")]
    pub exclude_tag: Vec<String>,
}

/// A spinner on stderr, hidden when stderr is not a terminal.
pub fn spinner(msg: impl Into<String>) -> ProgressBar {
    let pb = if std::io::stderr().is_terminal() {
        ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_message(msg.into());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

fn read(path: &Path, theme: &Theme) -> anyhow::Result<Layer> {
    let pb = spinner(format!("reading {}", path.display()));
    let l = read_layer(path, theme).with_context(|| format!("reading {}", path.display()));
    pb.finish_and_clear();
    l
}

fn parse_tags(tags: &[String]) -> anyhow::Result<Vec<(String, String)>> {
    tags.iter()
        .map(|t| {
            t.split_once('=')
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .with_context(|| format!("--exclude-tag {t:?}: expected k=v"))
        })
        .collect()
}

/// The layers named by `args`: footprints, streets, parcels. A directory input stands for its
/// `buildings.shp` (+ `streets.shp`, `parcels.shp` when present), as `blockwalk generate` writes.
pub fn load_layers(args: &CityArgs) -> anyhow::Result<(Layer, Option<Layer>, Option<Layer>)> {
    if args.inputs.len() != 1 {
        anyhow::bail!(
            "expected one footprint input (a file or a city directory), got {}",
            args.inputs.len()
        );
    }
    let input = &args.inputs[0];
    let (fp, mut st, mut pa) = if input.is_dir() {
        let b = input.join("buildings.shp");
        if !b.exists() {
            anyhow::bail!("{}: directory has no buildings.shp", input.display());
        }
        let s = input.join("streets.shp");
        let p = input.join("parcels.shp");
        (b, s.exists().then_some(s), p.exists().then_some(p))
    } else {
        (input.clone(), None, None)
    };
    if args.streets.is_some() {
        st = args.streets.clone();
    }
    if args.parcels.is_some() {
        pa = args.parcels.clone();
    }
    let footprints = read(&fp, &Theme::Buildings)?;
    let streets = st.map(|s| read(&s, &Theme::Streets)).transpose()?;
    let parcels = pa.map(|p| read(&p, &Theme::Parcels)).transpose()?;
    Ok((footprints, streets, parcels))
}

/// Loads the city named by `args` with the default height rules.
#[allow(dead_code)]
pub fn load_city(args: &CityArgs) -> anyhow::Result<City> {
    load_city_with(args, &BuildOptions::default())
}

/// Loads the city named by `args`; `opts.exclude_street_tags` is extended by `--exclude-tag`.
pub fn load_city_with(args: &CityArgs, opts: &BuildOptions) -> anyhow::Result<City> {
    let (f, s, p) = load_layers(args)?;
    let mut opts = opts.clone();
    opts.exclude_street_tags
        .extend(parse_tags(&args.exclude_tag)?);
    let pb = spinner(format!(
        "building city from {} footprints",
        f.features.len()
    ));
    let city = build_city(&f, s.as_ref(), p.as_ref(), &opts)
        .with_context(|| format!("building the city from {}", f.source.display()));
    pb.finish_and_clear();
    city
}

/// Peak resident memory of this process in bytes (`VmHWM` from `/proc/self/status`), where the
/// system has it.
pub fn peak_memory_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
