//! Shared by the fuzz targets: the scratch folder every file-reading target writes its input into
//! (one per process), and the panic hook of the targets that reach an upstream panic blockwalk
//! catches.

use std::path::Path;
use std::sync::OnceLock;

#[allow(dead_code)]
pub fn dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("a temporary folder for the fuzz inputs"))
        .path()
}

/// Lets the upstream panics that blockwalk catches and turns into a refusal unwind to that
/// catch: an assertion in the polygon overlay of `i_overlay` (repair calls it under
/// `catch_unwind`) and the coordinate arithmetic of `osmpbf` overflowing on crafted input (the
/// OSM reader decodes under `catch_unwind`). libFuzzer's hook aborts on every panic, caught or
/// not, and still does on every other one; such a panic that nothing catches still ends the
/// run: the target's own guard aborts.
#[allow(dead_code)]
pub fn let_caught_upstream_panics_unwind() {
    let abort = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if info.location().is_some_and(|l| {
            l.file().contains("/i_overlay-") || l.file().contains("/osmpbf-")
        }) {
            return;
        }
        abort(info);
    }));
}
