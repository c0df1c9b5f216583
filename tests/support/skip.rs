//! Skips that everyone sees, and one switch that turns them into failures.
//!
//! A test that needs something the machine may lack (a GPU adapter, the Node validators and
//! Chromium, the Astana data, the shared DEMs, the right to mount file systems, an X server, the
//! batch engines' tools) asks [`or_skip`];
//! `tests/fuzz/ci.sh` logs its own skip (no nightly toolchain or `cargo-fuzz`) the same way.
//! Without it, the skip is written straight to the process's standard error, which the test
//! harness does not capture (it captures only `print!` and `eprint!`), and appended to the skip
//! log, from which `tests/run` prints the count of skipped tests by reason at the end of the run.
//!
//! `BLOCKWALK_REQUIRE=gpu,validators,astana,...` (or `all`), or the variable of one need set to
//! `1` (`BLOCKWALK_REQUIRE_GPU=1`, ...), makes the need mandatory: a missing one fails the test.
//! `.ci/run` requires every need.

use std::fmt;
use std::io::Write;
use std::path::PathBuf;

/// What a test may find missing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// A wgpu adapter (lavapipe will do).
    Gpu,
    /// `node` with the npm tools of `tests/tools`, and Debian's `chromium`.
    Validators,
    /// The Astana data beside the repository (`../shared/data/astana`).
    Astana,
    /// The elevation grids beside the repository (`../shared/data/dem`).
    Dem,
    /// Mounting small file systems (a full disk, a read-only folder): root, or `sudo -n`.
    Mounts,
    /// An X server for a real window (`xvfb-run`).
    Display,
    /// The nightly toolchain and `cargo-fuzz`, for the brief fuzz runs of `tests/fuzz/ci.sh`
    /// (which `tests/run` starts after the tests).
    Fuzz,
    /// Slurm and munge (Debian's `slurm-wlm`, `munge`) and root or `sudo -n`, for a single-node
    /// cluster on the loopback.
    Slurm,
    /// A Python with PyYAML (`$BLOCKWALK_PYTHON`, else `python3`), to read Kubernetes manifests.
    Pyyaml,
    /// A Python with Dagster (`$BLOCKWALK_PYTHON`, else `python3`).
    Dagster,
}

impl Need {
    /// Every need, in the order the summary lists them.
    pub const ALL: [Need; 10] = [
        Need::Gpu,
        Need::Validators,
        Need::Astana,
        Need::Dem,
        Need::Mounts,
        Need::Display,
        Need::Fuzz,
        Need::Slurm,
        Need::Pyyaml,
        Need::Dagster,
    ];

    /// Its name in `BLOCKWALK_REQUIRE` and in the skip log.
    pub fn name(self) -> &'static str {
        match self {
            Need::Gpu => "gpu",
            Need::Validators => "validators",
            Need::Astana => "astana",
            Need::Dem => "dem",
            Need::Mounts => "mounts",
            Need::Display => "display",
            Need::Fuzz => "fuzz",
            Need::Slurm => "slurm",
            Need::Pyyaml => "pyyaml",
            Need::Dagster => "dagster",
        }
    }

    /// Its own variable: `BLOCKWALK_REQUIRE_GPU`, ...
    pub fn var(self) -> String {
        format!("BLOCKWALK_REQUIRE_{}", self.name().to_uppercase())
    }
}

impl fmt::Display for Need {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The needs that `list` (the value of `BLOCKWALK_REQUIRE`) names; an unknown name is an error,
/// so that a misspelt switch cannot pass silently.
pub fn parse_list(list: &str) -> Result<Vec<Need>, String> {
    let mut out = Vec::new();
    for word in list.split(',').map(str::trim).filter(|w| !w.is_empty()) {
        if word == "all" {
            out.extend(Need::ALL);
            continue;
        }
        match Need::ALL.iter().find(|n| n.name() == word) {
            Some(&n) => out.push(n),
            None => {
                let names: Vec<&str> = Need::ALL.iter().map(|n| n.name()).collect();
                return Err(format!(
                    "BLOCKWALK_REQUIRE names `{word}`; the needs are {} (or `all`)",
                    names.join(", ")
                ));
            }
        }
    }
    Ok(out)
}

/// Whether `need` is mandatory in this run. Panics on a switch that is set but means nothing
/// (an unknown name, or a variable set to anything but `1`).
pub fn required(need: Need) -> bool {
    if let Ok(list) = std::env::var("BLOCKWALK_REQUIRE") {
        match parse_list(&list) {
            Ok(needs) if needs.contains(&need) => return true,
            Ok(_) => {}
            Err(e) => panic!("{e}"),
        }
    }
    match std::env::var(need.var()) {
        Ok(v) if v == "1" => true,
        Ok(v) => panic!(
            "{}={v:?}: set it to 1 to require {need}, or unset it",
            need.var()
        ),
        Err(_) => false,
    }
}

/// Where skips are logged: `$BLOCKWALK_SKIP_LOG` (set by `tests/run`), else
/// `target/blockwalk-skips.log` in the repository.
pub fn log_path() -> PathBuf {
    std::env::var_os("BLOCKWALK_SKIP_LOG")
        .map(PathBuf::from)
        .unwrap_or_else(|| super::repo().join("target/blockwalk-skips.log"))
}

/// `found`'s value, or `None` after a loud skip of `test` for want of `need`; panics instead when
/// `need` is [`required`].
pub fn or_skip<T>(need: Need, test: &str, found: Result<T, String>) -> Option<T> {
    match found {
        Ok(t) => Some(t),
        Err(why) if required(need) => {
            panic!("{test}: {why}, and {need} is required (BLOCKWALK_REQUIRE)")
        }
        Err(why) => {
            skip(need, test, &why);
            None
        }
    }
}

/// Records a skip: one line on the real standard error and one in the skip log.
fn skip(need: Need, test: &str, why: &str) {
    skip_with(
        need,
        test,
        why,
        &format!("BLOCKWALK_REQUIRE={need} makes this a failure"),
    );
}

fn skip_with(need: Need, test: &str, why: &str, note: &str) {
    let why = why.replace(['\n', '\t'], " ");
    let line = format!("SKIPPED [{need}] {test}: {why} ({note})\n");
    // `std::io::stderr()` itself, not `eprintln!`: the harness captures only the macros.
    let _ = std::io::stderr().write_all(line.as_bytes());
    let path = log_path();
    if let Some(dir) = path.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    let logged = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .and_then(|mut f| f.write_all(format!("{need}\t{test}\t{why}\n").as_bytes()));
    if let Err(e) = logged {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED [{need}] {test}: could not log the skip to {}: {e}",
            path.display()
        );
    }
}
