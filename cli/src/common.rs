//! Inputs shared by the commands that take a city.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

use blockwalk::city::build::BuildOptions;
use blockwalk::city::City;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::Choice;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The clap value parser of a library enum chosen by name ([`Choice`]): `--help` lists the
/// names with their help, and a wrong value is refused with the list.
pub fn choice<T: Choice + Send + Sync>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser as _};
    PossibleValuesParser::new(
        T::ALL
            .iter()
            .map(|c| PossibleValue::new(c.name()).help(c.help())),
    )
    .map(|s| T::from_name(&s).expect("clap accepted one of the listed names"))
}

/// A whole number of at least 1 (a count where 0 would do nothing, or mean something unsaid).
pub fn at_least_one(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("0 is not allowed: expected a whole number of at least 1".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("{e}: expected a whole number of at least 1")),
    }
}

/// A number in the closed range `lo..=hi` (`what` names the bound in the message).
pub fn f64_in(s: &str, lo: f64, hi: f64, what: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|e| format!("{e}: expected a number from {lo} to {hi}"))?;
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{v} is out of range: expected {lo} to {hi} ({what})"
        ))
    }
}

/// A city on the command line: footprints, optional streets and parcels, or a generated city's
/// directory.
#[derive(clap::Args, Debug, Clone)]
pub struct CityArgs {
    /// Footprint file (.shp, .geojson, .gpkg[:table], .osm.pbf), a generated city directory, or
    /// `synthetic:COLSxROWS` (a street grid of box buildings, about 27 per block).
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
    /// The city's name in summaries and reports (default: the footprint file's name, or its
    /// folder's when the file has a generic name such as buildings.shp).
    #[arg(long)]
    pub name: Option<String>,
    /// The footprint layer's CRS: `EPSG:NNNN`, a PROJ string, WKT, or a .prj / WKT file; states
    /// it for a file without one (otherwise taken as metres in a local frame) or replaces a
    /// wrong one.
    #[arg(long)]
    pub crs: Option<String>,
    /// Elevation model (GeoTIFF: strips or tiles, integer or float samples, nodata, the CRS
    /// from its GeoKeys) the buildings stand on; reprojected into the city's frame when its CRS
    /// differs. Without it the city is flat (z = 0).
    #[arg(long)]
    pub dem: Option<PathBuf>,
    /// How a building's base is taken from the terrain under its footprint: `min` (the lowest
    /// point, as 3dfier's LoD1 does) or `pNN`, a percentile of the terrain under it (e.g. `p10`).
    #[arg(long, default_value = "min", value_parser = blockwalk::city::build::ground::parse_rule)]
    pub base: blockwalk::terrain::BaseRule,
    /// List buildings whose footprint spans more terrain relief than this, metres.
    #[arg(long = "steep", default_value_t = blockwalk::city::build::ground::DEFAULT_STEEP_M)]
    pub steep_m: f64,
    /// Terrain kept around the footprints' box, metres.
    #[arg(long = "dem-margin", default_value_t = blockwalk::city::build::ground::DEFAULT_MARGIN_M)]
    pub dem_margin_m: f64,
    /// Take a DEM without CRS information as metres in the city's frame (otherwise refused).
    #[arg(long = "dem-in-city-frame")]
    pub dem_in_city_frame: bool,
    /// With --dem: the largest projected error of a drawn terrain tile, pixels.
    #[arg(long = "terrain-tau", default_value_t = blockwalk::scene::terrain::DEFAULT_TERRAIN_TAU_PX)]
    pub terrain_tau: f64,
    /// With --dem: whether the terrain's min-filtered cells take part in occlusion culling
    /// (`on`, `off`).
    #[arg(long = "terrain-occluder", default_value = "on", value_parser = parse_on_off, action = clap::ArgAction::Set)]
    pub terrain_occluder: bool,
}

fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("{s:?}: expected on or off")),
    }
}

/// The library's progress as a spinner (stages) and a bar (counts) on stderr, hidden with
/// `--json` or when stderr is not a terminal.
pub struct Progress {
    bar: ProgressBar,
    stage: std::sync::Mutex<String>,
}

impl Progress {
    /// Progress on stderr, hidden when `quiet`.
    pub fn new(quiet: bool) -> Self {
        let bar = spinner("");
        if quiet {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        Self {
            bar,
            stage: std::sync::Mutex::new(String::new()),
        }
    }

    /// Clears the line.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl blockwalk::walk::JobProgress for Progress {
    fn stage(&self, what: &str) {
        if let Ok(mut s) = self.stage.lock() {
            *s = what.to_string();
        }
        self.bar.set_message(what.to_string());
    }
    fn count(&self, done: usize, total: usize) {
        let stage = self.stage.lock().map(|s| s.clone()).unwrap_or_default();
        self.bar.set_message(format!("{stage}: {done}/{total}"));
    }
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

impl CityArgs {
    /// The city source these arguments name (`seed` is used by `synthetic:` inputs).
    pub fn source(&self, seed: u64) -> anyhow::Result<CitySource> {
        let [input] = self.inputs.as_slice() else {
            anyhow::bail!(
                "expected one footprint input (a file, a city directory or synthetic:COLSxROWS), got {}",
                self.inputs.len()
            );
        };
        let crs = self
            .crs
            .as_deref()
            .map(blockwalk::city::build::parse_crs)
            .transpose()?;
        Ok(CitySource::parse(
            input,
            self.streets.clone(),
            self.parcels.clone(),
            &self.exclude_tag,
            seed,
        )?
        .with_name_and_crs(self.name.clone(), crs)
        .with_ground(self.ground()?))
    }

    /// The ground options `--dem` and its companions ask for (`None` without `--dem`).
    pub fn ground(&self) -> anyhow::Result<Option<blockwalk::city::build::GroundOptions>> {
        let Some(dem) = &self.dem else {
            return Ok(None);
        };
        if self
            .inputs
            .iter()
            .any(|i| i.to_string_lossy().starts_with("synthetic:"))
        {
            anyhow::bail!(
                "--dem {}: a synthetic grid has no CRS to place an elevation model by; generate a city on it with `blockwalk generate --on-dem`",
                dem.display()
            );
        }
        let g = blockwalk::city::build::GroundOptions {
            dem: dem.clone(),
            rule: self.base,
            steep_m: self.steep_m,
            margin_m: self.dem_margin_m,
            assume_city_frame: self.dem_in_city_frame,
        };
        g.validate()
            .map_err(|e| anyhow::anyhow!("--dem {}: {e}", dem.display()))?;
        Ok(Some(g))
    }
}

/// Loads the city named by `args` with the default height rules.
pub fn load_city(args: &CityArgs) -> anyhow::Result<City> {
    load_city_with(args, &BuildOptions::default())
}

/// Loads the city named by `args` with `opts` (`--exclude-tag` is added to its exclusions).
pub fn load_city_with(args: &CityArgs, opts: &BuildOptions) -> anyhow::Result<City> {
    let source = args.source(0)?;
    let pb = spinner("loading the city");
    let loaded = source.load(opts, &mut |m| pb.set_message(m.to_string()));
    pb.finish_and_clear();
    Ok(loaded?.city)
}

/// Loads the city named by `args` and builds its scene, with a spinner.
pub fn load_scene(args: &CityArgs, seed: u64, opts: &SceneOptions) -> anyhow::Result<Scene> {
    let source = args.source(seed)?;
    if !(args.terrain_tau.is_finite() && args.terrain_tau > 0.0) {
        anyhow::bail!(
            "--terrain-tau {}: need a finite value > 0",
            args.terrain_tau
        );
    }
    let opts = &SceneOptions {
        terrain_tau_px: args.terrain_tau,
        terrain_occludes: args.terrain_occluder,
        ..opts.clone()
    };
    let pb = spinner("loading the city");
    let scene = Scene::load(&source, opts, &mut |m| pb.set_message(m.to_string()));
    pb.finish_and_clear();
    Ok(scene?)
}

/// An image size on the command line, `WIDTHxHEIGHT` (e.g. `1280x720`), each side 1..=8192.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
}

impl Size {
    /// As a pair.
    pub fn pair(self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Width / height.
    pub fn aspect(self) -> f64 {
        self.width as f64 / self.height as f64
    }
}

impl std::str::FromStr for Size {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| "expected WIDTHxHEIGHT, e.g. 1280x720".to_string())?;
        let side = |v: &str, what: &str| -> Result<u32, String> {
            let n: u32 = v
                .trim()
                .parse()
                .map_err(|_| format!("bad {what} {v:?}: expected a whole number"))?;
            if (1..=8192).contains(&n) {
                Ok(n)
            } else {
                Err(format!("{what} {n} is out of 1..=8192"))
            }
        };
        Ok(Size {
            width: side(w, "width")?,
            height: side(h, "height")?,
        })
    }
}

/// The far-field options `walk` and `view` share: the representation, τ, K, the relief
/// impostors' settings and the hysteresis.
#[derive(clap::Args, Debug, Clone)]
pub struct FarArgs {
    /// Far field: `blockmaps` draws far nodes of the block quadtree as ray-cast BlockMaps (Cignoni
    /// et al., §4–5), `relief` far nodes of the relief tree as multi-level relief impostors
    /// (Andujar et al., §3–5), near blocks as meshes; `none` draws meshes only.
    #[arg(long = "far", value_parser = choice::<blockwalk::walk::FarMode>(), default_value_t = blockwalk::walk::FarMode::None)]
    pub mode: blockwalk::walk::FarMode,
    #[command(flatten)]
    pub relief: ReliefArgs,
    /// Largest projected error of a drawn BlockMap, pixels (τ).
    #[arg(long, default_value_t = 1.0)]
    pub tau: f64,
    /// BlockMap height-map side K (32, 64 or 128).
    #[arg(long, default_value_t = 64)]
    pub k: u32,
    /// Hysteresis h: a node drawn finer in the previous frame becomes a map only when its error is at most τ/(1 + h) (a map stays one while its error is at most τ).
    #[arg(long, default_value_t = blockwalk::blockmap::select::DEFAULT_HYSTERESIS)]
    pub hysteresis: f64,
}

impl FarArgs {
    /// τ and the hysteresis as selection settings, with K and the relief settings checked too
    /// (the library refuses each with the reason).
    pub fn select(&self) -> anyhow::Result<blockwalk::blockmap::SelectOptions> {
        blockwalk::blockmap::BuildOptions {
            k: self.k,
            ..Default::default()
        }
        .validate()?;
        self.relief.options()?;
        Ok(blockwalk::blockmap::SelectOptions::new(
            self.tau,
            self.hysteresis,
        )?)
    }

    /// How BlockMaps are built.
    pub fn blockmaps(&self) -> blockwalk::walk::BlockMapsOptions {
        blockwalk::walk::BlockMapsOptions {
            build: blockwalk::blockmap::BuildOptions {
                k: self.k,
                ..Default::default()
            },
        }
    }
}

/// How relief impostors are built (Andujar et al., §3–4).
#[derive(clap::Args, Debug, Clone)]
pub struct ReliefArgs {
    /// Relief impostors: texel size asked for, metres (`ts`; the map side M follows from
    /// formula (9) with the city's largest block).
    #[arg(long = "relief-texel", default_value_t = blockwalk::relief::build::DEFAULT_TEXEL_M)]
    pub texel: f64,
    /// Relief impostors: map side M (a power of two), instead of formula (9).
    #[arg(long = "relief-map-size")]
    pub map_size: Option<u32>,
    /// Relief impostors: the largest M formula (9) may give (a power of two).
    #[arg(long = "relief-max-map-size", default_value_t = blockwalk::relief::build::DEFAULT_MAX_MAP_SIZE)]
    pub max_map_size: u32,
    /// Relief impostors: footprints at most this far apart (metres) are merged into one group.
    #[arg(long = "relief-gap", default_value_t = blockwalk::relief::tree::DEFAULT_GAP_M, allow_hyphen_values = true)]
    pub gap: f64,
    /// Relief impostors: share of the seeable wall area the oblique maps must see, in (0, 1].
    #[arg(long = "relief-coverage", default_value_t = blockwalk::relief::build::DEFAULT_COVERAGE, allow_hyphen_values = true)]
    pub coverage: f64,
    /// Relief impostors: most oblique maps per node.
    #[arg(long = "relief-max-obliques", default_value_t = blockwalk::relief::build::DEFAULT_MAX_OBLIQUES)]
    pub max_obliques: usize,
    /// Relief impostors: which nodes get maps: `all` (the paper's tree) or `competitive` (down
    /// to where a node's meshes take fewer bytes than its maps).
    #[arg(long = "relief-stop", value_parser = choice::<blockwalk::relief::Stop>(), default_value_t = blockwalk::relief::Stop::Competitive)]
    pub stop: blockwalk::relief::Stop,
    /// Relief impostors: a node whose height projects to fewer pixels than this is drawn as a
    /// flat quad (the paper's horizon nodes use 2; 0 draws every node by its walk).
    #[arg(long = "relief-flat-px", default_value_t = 0.0)]
    pub flat_px: f64,
    /// Relief impostors: frames over which a node's colours move from its previous oblique
    /// maps to a new choice (0: switch at once).
    #[arg(long = "relief-blend", default_value_t = blockwalk::relief::build::DEFAULT_BLEND_FRAMES)]
    pub blend_frames: u32,
}

impl ReliefArgs {
    /// The settings, checked by the library.
    pub fn options(&self) -> anyhow::Result<blockwalk::relief::ReliefOptions> {
        let o = blockwalk::relief::ReliefOptions {
            tree: blockwalk::relief::TreeParams {
                gap_m: self.gap,
                ..Default::default()
            },
            texel_m: self.texel,
            map_size: self.map_size,
            max_map_size: self.max_map_size,
            coverage_target: self.coverage,
            max_obliques: self.max_obliques,
            stop: self.stop,
            flat_px: self.flat_px,
            blend_frames: self.blend_frames,
        };
        o.validate()?;
        Ok(o)
    }
}

/// The import report of a city as `import --json` gives it (counts, refusals with reasons,
/// warnings and notes), for the commands that read a city.
pub fn city_report_json(city: &City) -> serde_json::Value {
    let r = &city.report;
    serde_json::json!({
        "crs": r.crs,
        "buildings_read": r.buildings_read,
        "buildings_imported": r.buildings_imported,
        "buildings_repaired": r.buildings_repaired.len(),
        "buildings_refused": r.buildings_refused,
        "refused_by_reason": r.refused_by_reason,
        "implausible_heights": r.implausible_heights.len(),
        "streets_read": r.streets_read,
        "streets_refused": r.streets_refused,
        "parcels_read": r.parcels_read,
        "parcels_refused": r.parcels_refused,
        "street_layer_unusable": r.street_layer_unusable,
        "parcel_layer_unusable": r.parcel_layer_unusable,
        "warnings": r.notes.iter().filter(|n| n.starts_with("warning:")).collect::<Vec<_>>(),
        "notes": r.notes,
        "ground": r.ground,
    })
}

/// The import report's lines a command that reads a city prints before its own summary: what
/// was refused (footprints, street and parcel features, with reasons) and every warning.
pub fn city_report_lines(city: &City) -> Vec<String> {
    let r = &city.report;
    let mut out = Vec::new();
    if !r.buildings_refused.is_empty() || !r.buildings_repaired.is_empty() {
        out.push(format!(
            "footprints: {} read, {} imported, {} repaired, {} refused",
            r.buildings_read,
            r.buildings_imported,
            r.buildings_repaired.len(),
            r.buildings_refused.len()
        ));
        for g in &r.refused_by_reason {
            out.push(format!(
                "  refused {} × {} (e.g. {})",
                g.count,
                g.reason,
                g.examples.join(", ")
            ));
        }
    }
    for (what, read, refused) in [
        ("street", r.streets_read, &r.streets_refused),
        ("parcel", r.parcels_read, &r.parcels_refused),
    ] {
        if refused.is_empty() {
            continue;
        }
        let groups = blockwalk::importers::group_reasons(
            refused.iter().map(|n| (n.id.clone(), n.reason.as_str())),
        );
        out.push(format!(
            "{what} features: {read} read, {} refused",
            refused.len()
        ));
        for g in &groups {
            out.push(format!(
                "  refused {} × {} (e.g. {})",
                g.count,
                g.reason,
                g.examples.join(", ")
            ));
        }
    }
    if let Some(g) = &r.ground {
        out.extend(ground_lines(g));
    }
    out.extend(
        r.notes
            .iter()
            .filter(|n| n.starts_with("warning:"))
            .cloned(),
    );
    out
}

/// The ground report in a few lines: the terrain, the bases, the slopes, the lists.
pub fn ground_lines(g: &blockwalk::city::build::GroundReport) -> Vec<String> {
    let t = &g.terrain;
    let mut out = vec![
        format!(
            "terrain: {} ({}), {}×{} nodes at {:.1}×{:.1} m{}, {:.1}–{:.1} m, {} nodata",
            t.source,
            t.crs,
            t.size[0],
            t.size[1],
            t.spacing_m[0],
            t.spacing_m[1],
            if t.resampled { ", resampled" } else { "" },
            t.min_m,
            t.max_m,
            t.nodata_count
        ),
        format!(
            "ground: {} buildings on it (base rule {}; terrain {:.0} ms, bases {:.0} ms): base {:.1}–{:.1} m (median {:.1}); slope under footprints median {:.1}°, p90 {:.1}°, max {:.1}°; relief under footprints median {:.2} m, max {:.2} m",
            g.placed,
            g.rule,
            g.terrain_ms,
            g.place_ms,
            g.base_m.min,
            g.base_m.max,
            g.base_m.median,
            g.slope_deg.median,
            g.slope_deg.p90,
            g.slope_deg.max,
            g.relief_m.median,
            g.relief_m.max
        ),
    ];
    if g.steep_count > 0 {
        out.push(format!(
            "  {} buildings span more than {} m of terrain (e.g. {})",
            g.steep_count,
            g.steep_threshold_m,
            g.steep
                .iter()
                .take(5)
                .map(|n| format!("{} {:.1} m", n.id, n.relief_m))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if g.partial_count > 0 {
        out.push(format!(
            "  {} buildings stand partly over nodata or off the grid (e.g. {})",
            g.partial_count,
            g.partial
                .iter()
                .take(5)
                .map(|n| format!(
                    "{} {}/{} samples missing",
                    n.id, n.missing_samples, n.samples
                ))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if g.refused_count > 0 {
        out.push(format!(
            "  {} buildings refused: no terrain under them",
            g.refused_count
        ));
    }
    out
}

/// How a tiled city (`jobs merge`'s folder, its `index.json`, or a URL of either) is streamed.
#[derive(clap::Args, Debug)]
#[command(next_help_heading = "Streaming a tiled city")]
pub struct StreamArgs {
    /// Memory for resident tiles' content (decoded meshes and maps), e.g. 768MiB, 1GiB.
    #[arg(long, default_value = "768MiB", value_parser = blockwalk::stream::parse_bytes)]
    pub budget: u64,
    /// Limit the link to this bandwidth, e.g. 100Mbps, 4Mbps (default: unlimited).
    #[arg(long, value_parser = blockwalk::stream::LinkSpec::parse_bandwidth)]
    pub bandwidth: Option<f64>,
    /// Latency of every request on the link, milliseconds.
    #[arg(long, default_value_t = 0.0)]
    pub latency_ms: f64,
    /// Loader threads (concurrent requests).
    #[arg(long, default_value_t = 4)]
    pub workers: usize,
    /// Frames complete their loads before they are drawn (images then depend on the input
    /// alone); otherwise the render thread never waits and draws stand-ins.
    #[arg(long)]
    pub deterministic: bool,
    /// Frames of the route ahead whose content is prefetched.
    #[arg(long, default_value_t = 30)]
    pub prefetch: usize,
    /// Pace the walk at this many frames per second (default: as fast as frames are drawn).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Compare every frame with the same frame drawn from fully resident content (pixels
    /// differing, PSNR); loads that content outside the budget.
    #[arg(long)]
    pub check: bool,
    /// Request what a frame needs before the coarser maps that stand in for it meanwhile (the
    /// order of Di Benedetto's thesis, §4.4); by default the stand-ins come first.
    #[arg(long)]
    pub needed_first: bool,
}

impl StreamArgs {
    /// The streamed walk's options these arguments and `far` (τ, BlockMaps or none) ask for,
    /// at `size` pixels.
    pub fn options(
        &self,
        far: &FarArgs,
        size: (u32, u32),
    ) -> anyhow::Result<blockwalk::stream::StreamOptions> {
        use blockwalk::stream::{LinkSpec, Mode, StreamOptions};
        use blockwalk::walk::FarMode;
        let use_far = match far.mode {
            FarMode::None => false,
            FarMode::Blockmaps => true,
            FarMode::Relief => anyhow::bail!(
                "--far relief: a tiled city carries BlockMaps (jobs run --blockmaps K), not relief impostors"
            ),
        };
        let mut o = StreamOptions::new(
            self.budget,
            self.workers,
            LinkSpec::new(self.bandwidth, self.latency_ms / 1e3).map_err(anyhow::Error::msg)?,
            if self.deterministic {
                Mode::Deterministic
            } else {
                Mode::Realtime
            },
            far.tau,
            size,
            self.prefetch,
            self.fps,
        )?;
        o.far = use_far;
        o.needed_first = self.needed_first;
        Ok(o)
    }
}
