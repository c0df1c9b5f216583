//! What a walk report needs beyond the [`WalkRecord`](crate::walk::WalkRecord): the plan of the
//! city for the route map, the machine that ran the walk and the command line that started it.

use crate::scene::Scene;
use glam::DVec2;
use serde::Serialize;

/// The city in plan view, local frame (metres from the local origin, x east, y north): the
/// frame the cameras are in, so the route can be drawn over it.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    /// Outer rings of the blocks (outskirts groups included).
    pub blocks: Vec<Vec<DVec2>>,
    /// Outer rings of the building footprints.
    pub footprints: Vec<Vec<DVec2>>,
}

impl Plan {
    /// The blocks and footprints of `scene`, moved from world coordinates into its local frame.
    pub fn from_scene(scene: &Scene) -> Plan {
        let frame = &scene.city.frame;
        let ring = |r: &geo_types::LineString<f64>| -> Vec<DVec2> {
            r.0.iter().map(|c| frame.to_local_xy(*c)).collect()
        };
        Plan {
            blocks: scene
                .layout
                .blocks
                .iter()
                .map(|b| ring(b.polygon.exterior()))
                .collect(),
            footprints: scene
                .city
                .buildings
                .iter()
                .map(|b| ring(b.footprint.exterior()))
                .collect(),
        }
    }
}

/// The machine and build that produced a report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Machine {
    /// CPU model (`/proc/cpuinfo`'s `model name`), when known.
    pub cpu: Option<String>,
    /// Hardware threads available to the process.
    pub cores: usize,
    /// Operating system (`/etc/os-release`'s `PRETTY_NAME`, else Rust's OS name) and architecture.
    pub os: String,
    /// blockwalk's version.
    pub version: String,
    /// The git commit blockwalk was built from, when `BLOCKWALK_GIT_COMMIT` was set at build time
    /// (no build script asks git for it).
    pub commit: Option<String>,
}

impl Machine {
    /// This machine and this build.
    pub fn detect() -> Machine {
        let cpu = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        });
        let os = std::fs::read_to_string("/etc/os-release")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find_map(|l| l.strip_prefix("PRETTY_NAME="))
                    .map(|v| v.trim_matches('"').to_string())
            })
            .unwrap_or_else(|| std::env::consts::OS.to_string());
        Machine {
            cpu,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            os: format!("{os} ({})", std::env::consts::ARCH),
            version: env!("CARGO_PKG_VERSION").to_string(),
            commit: option_env!("BLOCKWALK_GIT_COMMIT").map(str::to_string),
        }
    }
}

/// Everything the report receives besides the record. `Default` gives an empty plan (no map), no
/// machine and no command: the report says so instead of drawing them.
#[derive(Clone, Debug, Default)]
pub struct ReportContext {
    /// The city for the route map.
    pub plan: Plan,
    /// The machine, when known.
    pub machine: Option<Machine>,
    /// The command line that produced the walk (`std::env::args`), empty when unknown.
    pub command: Vec<String>,
    /// Plots made beside the walk, embedded in the page under their caption: PNG files, e.g. a
    /// far-field sweep's error against frame time (`blockwalk farfield-sweep`).
    pub extra_plots: Vec<(String, std::path::PathBuf)>,
}
