//! Helpers shared by the integration tests: the bundled data and the scenes built from it
//! ([`data`]), a headless GPU or a skip ([`gpu`], with the `render` feature) and the Node tools of
//! `tests/tools` ([`node`]), and the loud skips of tests whose needs are missing ([`skip`]).
//!
//! Tile contents (`.glb`, plain or compressed) are read back by [`glb`].
//!
//! A test file of the library includes it as `mod support;`, one of the command line (`cli/tests`)
//! as `#[path = "../../tests/support/mod.rs"] mod support;`.

// Each test binary compiles this whole module and uses only a part of it.
#![allow(dead_code)]

pub mod data;
pub mod glb;
#[cfg(feature = "render")]
pub mod gpu;
pub mod node;
pub mod skip;
pub mod terrain;

use std::path::{Path, PathBuf};

/// The repository's root: the including crate's folder (the library's tests) or the first folder
/// above it that holds `tests/tools` (the command line's tests, in `cli/`).
pub fn repo() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.ancestors()
        .find(|d| d.join("tests/tools").is_dir())
        .unwrap_or(here)
        .to_path_buf()
}
