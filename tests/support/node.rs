//! The Node tools of `tests/tools` (the glTF validator, CesiumJS and puppeteer-core driving
//! Debian's `chromium`), shared by the tests that run them: finding them, skipping with the
//! reason when they are missing (a failure when the validators are required, as `.ci/run`
//! requires them; see [`super::skip`]), and running a script that prints one JSON report.

use super::repo;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// `tests/tools`.
pub fn tools() -> PathBuf {
    repo().join("tests/tools")
}

fn runs(cmd: &str) -> bool {
    Command::new(cmd)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// `node` (or `$BLOCKWALK_NODE`) when it runs and the npm `packages` are installed in
/// `tests/tools/node_modules`; else why not.
pub fn node_with(packages: &[&str]) -> Result<String, String> {
    let node = std::env::var("BLOCKWALK_NODE").unwrap_or_else(|_| "node".into());
    if !runs(&node) {
        return Err(format!("`{node}` cannot be run"));
    }
    let missing: Vec<&str> = packages
        .iter()
        .copied()
        .filter(|p| !tools().join("node_modules").join(p).is_dir())
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{} not installed (run `npm ci --prefix {}`)",
            missing.join(", "),
            tools().display()
        ));
    }
    Ok(node)
}

/// The path of `chromium` (or `$BLOCKWALK_CHROMIUM`), which puppeteer wants, when it runs;
/// else why not.
pub fn chromium() -> Result<String, String> {
    let chromium = std::env::var("BLOCKWALK_CHROMIUM").unwrap_or_else(|_| "chromium".into());
    if !runs(&chromium) {
        return Err(format!(
            "`{chromium}` cannot be run (apt-get install chromium)"
        ));
    }
    Ok(Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {chromium}"))
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .filter(|p| !p.is_empty())
        .unwrap_or(chromium))
}

/// `found`'s tool, or `None` after a loud skip of `test`; a failure when the validators are
/// required.
pub fn or_skip<T>(test: &str, found: Result<T, String>) -> Option<T> {
    super::skip::or_skip(super::skip::Need::Validators, test, found)
}

/// Runs `tests/tools/<script> <arg>` with `node`, asserts it succeeded, and parses the one JSON
/// object it prints.
pub fn run_json(node: &str, script: &str, arg: &Path) -> Value {
    let out = Command::new(node)
        .arg(tools().join(script))
        .arg(arg)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{script} {}: {}",
        arg.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Where screenshots go: `$BLOCKWALK_SCREENSHOT_DIR`, else `target/<sub>`; created.
pub fn screenshot_dir(sub: &str) -> PathBuf {
    let d = std::env::var_os("BLOCKWALK_SCREENSHOT_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("target").join(sub));
    std::fs::create_dir_all(&d).unwrap();
    d
}
