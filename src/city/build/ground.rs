//! Buildings on the ground: each building's base from the elevation model under its footprint.
//!
//! As 3dfier and the 3DBAG do for LoD1 models, a building's base is taken from the terrain under
//! its footprint: by default the lowest point of the terrain surface there ([`BaseRule::Min`]), so
//! that the lowest corner touches the ground and no wall floats; a percentile of the terrain
//! samples under the footprint is the other rule ([`BaseRule::Percentile`]). The walls go from
//! the base to the roof: on a slope the uphill side is buried by at most the terrain's relief
//! under the footprint, which the report lists where it exceeds a threshold. Heights stay heights
//! above the ground.
//!
//! A footprint partly over nodata (or over the grid's edge) takes its base from the samples that
//! exist and is reported with its counts; a footprint with no terrain under it at all is refused
//! (with the reason), never put at 0.

use std::path::PathBuf;

use serde::Serialize;

use crate::city::model::{Building, BuildingId, CityReport, RefusalNote};
use crate::importers::MetricTransform;
use crate::terrain::{
    BaseRule, FootprintGround, GroundError, Terrain, TerrainError, TerrainOptions, TerrainReport,
};

/// Default relief under a footprint above which a building is listed as standing on steep ground,
/// metres.
pub const DEFAULT_STEEP_M: f64 = 3.0;

/// Default terrain kept around the city's footprints, metres (streets, routes and views beyond
/// the last building stand on it too).
pub const DEFAULT_MARGIN_M: f64 = 3000.0;

/// Buildings listed by id in the report per kind (the counts are complete).
const LISTED: usize = 50;

/// Where a city's ground comes from and how bases are taken.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundOptions {
    /// The elevation model (GeoTIFF).
    pub dem: PathBuf,
    /// How a footprint's base is taken from the terrain under it.
    pub rule: BaseRule,
    /// Relief under a footprint above which the building is listed as on steep ground, metres.
    pub steep_m: f64,
    /// Terrain kept around the footprints' box, metres.
    pub margin_m: f64,
    /// Take a DEM without CRS information as being in the city's metric frame (otherwise it is
    /// refused when the city has a CRS).
    pub assume_city_frame: bool,
}

impl GroundOptions {
    /// Options for `dem` with the default rule (the minimum), threshold and margin.
    pub fn new(dem: impl Into<PathBuf>) -> Self {
        Self {
            dem: dem.into(),
            rule: BaseRule::Min,
            steep_m: DEFAULT_STEEP_M,
            margin_m: DEFAULT_MARGIN_M,
            assume_city_frame: false,
        }
    }

    /// Checks the numbers.
    ///
    /// # Errors
    /// A message naming the parameter.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.steep_m.is_finite() && self.steep_m >= 0.0) {
            return Err(format!(
                "steep-ground threshold {} m: need a finite value ≥ 0",
                self.steep_m
            ));
        }
        if !(self.margin_m.is_finite() && self.margin_m >= 0.0) {
            return Err(format!(
                "terrain margin {} m: need a finite value ≥ 0",
                self.margin_m
            ));
        }
        if let BaseRule::Percentile(p) = self.rule {
            if !(0.0..=100.0).contains(&p) {
                return Err(format!("base percentile {p}: need 0..=100"));
            }
        }
        Ok(())
    }
}

/// One building in a ground list.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct GroundNote {
    /// Source id.
    pub id: String,
    /// Relief of the terrain under the footprint, metres.
    pub relief_m: f64,
    /// Terrain samples under the footprint that were nodata or off the grid.
    pub missing_samples: usize,
    /// Terrain samples looked at.
    pub samples: usize,
}

/// Five numbers of a distribution.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Spread {
    /// Smallest.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Self {
            min: v[0],
            median: at(0.5),
            p90: at(0.9),
            max: v[v.len() - 1],
        }
    }
}

/// What putting the buildings on the ground did.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct GroundReport {
    /// The terrain: source, CRS, grid, what was resampled.
    pub terrain: TerrainReport,
    /// The base rule (`min` or `pNN`).
    pub rule: String,
    /// Buildings put on the ground.
    pub placed: usize,
    /// Base heights, metres.
    pub base_m: Spread,
    /// Steepest terrain slope under each footprint, degrees.
    pub slope_deg: Spread,
    /// Relief of the terrain under each footprint, metres.
    pub relief_m: Spread,
    /// The threshold of `steep`, metres.
    pub steep_threshold_m: f64,
    /// Buildings whose footprint spans more relief than the threshold.
    pub steep_count: usize,
    /// The first of them (by relief, largest first).
    pub steep: Vec<GroundNote>,
    /// Buildings partly over nodata or off the grid (base from the samples that exist).
    pub partial_count: usize,
    /// The first of them.
    pub partial: Vec<GroundNote>,
    /// Buildings refused for having no terrain under them.
    pub refused_count: usize,
    /// Milliseconds to read the DEM and make the terrain.
    pub terrain_ms: f64,
    /// Milliseconds to put the buildings on it.
    pub place_ms: f64,
}

/// Why the ground could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum GroundSetupError {
    /// The DEM could not be read.
    #[error(transparent)]
    Read(#[from] crate::importers::DemError),
    /// The DEM could not be made a terrain in the city's frame.
    #[error(transparent)]
    Terrain(#[from] TerrainError),
    /// The options are not usable.
    #[error("{0}")]
    Options(String),
}

/// The terrain of `opts.dem` in the city's metric frame (`transform`), over the footprints' box
/// plus the margin.
///
/// # Errors
/// [`GroundSetupError`] naming the file and problem.
pub fn load_terrain(
    opts: &GroundOptions,
    transform: &MetricTransform,
    buildings: &[Building],
) -> Result<Terrain, GroundSetupError> {
    opts.validate().map_err(GroundSetupError::Options)?;
    let dem = crate::importers::read_dem(&opts.dem)?;
    // A city without a CRS has no place to put a georeferenced DEM: its coordinates would be
    // read as the DEM's and the buildings silently misplaced if the two happened to overlap.
    if transform.crs == crate::importers::Crs::Unknown
        && dem.crs != crate::importers::Crs::Unknown
        && !opts.assume_city_frame
    {
        return Err(GroundSetupError::Options(format!(
            "{}: the DEM is in {}, but the city has no CRS; state the city's with --crs, or take              the DEM's coordinates as the city's with --dem-in-city-frame",
            opts.dem.display(),
            dem.crs.describe()
        )));
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for b in buildings {
        for c in b.footprint.exterior().coords() {
            lo = [lo[0].min(c.x), lo[1].min(c.y)];
            hi = [hi[0].max(c.x), hi[1].max(c.y)];
        }
    }
    let m = opts.margin_m;
    let region = (lo[0] <= hi[0]).then(|| [lo[0] - m, lo[1] - m, hi[0] + m, hi[1] + m]);
    let to_metric = match transform.for_layer(&dem.crs) {
        Ok(t) => t,
        Err(e) => {
            return Err(GroundSetupError::Options(format!(
                "{}: its CRS cannot be mapped into the city's frame: {e}",
                opts.dem.display()
            )))
        }
    };
    Ok(Terrain::from_dem_with(
        &dem,
        &to_metric,
        &TerrainOptions {
            region,
            assume_city_frame: opts.assume_city_frame,
        },
    )?)
}

/// Puts every building on `terrain` by `opts.rule`: sets `base_m`, refuses (and removes, into
/// `report`) buildings with no terrain under them, renumbers the rest, and returns what was done.
pub fn place_buildings(
    buildings: &mut Vec<Building>,
    terrain: &Terrain,
    opts: &GroundOptions,
    report: &mut CityReport,
) -> GroundReport {
    use rayon::prelude::*;
    let t0 = std::time::Instant::now();
    // A footprint partly over nodata keeps the ground of the points that have a height.
    let grounds: Vec<Result<FootprintGround, GroundError>> = buildings
        .par_iter()
        .map(|b| match terrain.ground_under(&b.footprint, opts.rule) {
            Err(GroundError::Nodata {
                partial: Some(g), ..
            }) => Ok(*g),
            other => other,
        })
        .collect();
    let (mut bases, mut slopes, mut reliefs) = (Vec::new(), Vec::new(), Vec::new());
    let (mut steep, mut partial) = (Vec::new(), Vec::new());
    let mut refused = 0;
    let mut kept = Vec::with_capacity(buildings.len());
    for (mut b, g) in std::mem::take(buildings).into_iter().zip(grounds) {
        match g {
            Ok(g) => {
                b.base_m = g.base_m;
                bases.push(g.base_m);
                slopes.push(g.slope_deg);
                reliefs.push(g.relief_m);
                let note = GroundNote {
                    id: b.source_id.clone(),
                    relief_m: g.relief_m,
                    missing_samples: g.nodata_samples,
                    samples: g.samples,
                };
                if g.nodata_samples > 0 {
                    partial.push(note.clone());
                }
                if g.relief_m > opts.steep_m {
                    steep.push(note);
                }
                b.id = BuildingId(kept.len() as u32);
                kept.push(b);
            }
            Err(e) => {
                refused += 1;
                report.buildings_refused.push(RefusalNote {
                    id: b.source_id.clone(),
                    reason: format!("no terrain under the footprint: {e}"),
                });
            }
        }
    }
    *buildings = kept;
    if refused > 0 {
        report.refused_by_reason = crate::importers::group_reasons(
            report
                .buildings_refused
                .iter()
                .map(|r| (r.id.clone(), r.reason.as_str())),
        );
        report.notes.push(format!(
            "warning: {refused} buildings have no terrain under them in {} and were refused",
            opts.dem.display()
        ));
    }
    steep.sort_by(|a, b| b.relief_m.total_cmp(&a.relief_m).then(a.id.cmp(&b.id)));
    let (steep_count, partial_count) = (steep.len(), partial.len());
    steep.truncate(LISTED);
    partial.truncate(LISTED);
    if partial_count > 0 {
        report.notes.push(format!(
            "{partial_count} buildings stand partly over nodata or off the grid of {}: bases from the samples that exist",
            opts.dem.display()
        ));
    }
    GroundReport {
        terrain: terrain.report().clone(),
        rule: rule_name(opts.rule),
        placed: bases.len(),
        base_m: Spread::of(bases),
        slope_deg: Spread::of(slopes),
        relief_m: Spread::of(reliefs),
        steep_threshold_m: opts.steep_m,
        steep_count,
        steep,
        partial_count,
        partial,
        refused_count: refused,
        terrain_ms: 0.0,
        place_ms: t0.elapsed().as_secs_f64() * 1e3,
    }
}

/// `min`, or `pNN` for a percentile.
pub fn rule_name(rule: BaseRule) -> String {
    match rule {
        BaseRule::Min => "min".into(),
        BaseRule::Percentile(p) => format!("p{p}"),
    }
}

/// Reads a base rule: `min`, or `pNN` / `percentile:NN` (0 … 100).
///
/// # Errors
/// A message saying what is expected.
pub fn parse_rule(s: &str) -> Result<BaseRule, String> {
    let t = s.trim().to_ascii_lowercase();
    if t == "min" || t == "minimum" {
        return Ok(BaseRule::Min);
    }
    let n = t
        .strip_prefix("percentile:")
        .or_else(|| t.strip_prefix('p'))
        .and_then(|n| n.parse::<f64>().ok())
        .filter(|p| (0.0..=100.0).contains(p))
        .ok_or_else(|| format!("{s:?}: expected min or pNN (a percentile 0..=100, e.g. p10)"))?;
    Ok(if n == 0.0 {
        BaseRule::Min
    } else {
        BaseRule::Percentile(n)
    })
}
