//! Shared by the fuzz targets: the scratch folder every file-reading target writes its input into
//! (one per process), and the panic hook of the targets that reach the polygon overlay.

use std::path::Path;
use std::sync::OnceLock;

#[allow(dead_code)]
pub fn dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("a temporary folder for the fuzz inputs"))
        .path()
}

/// Lets the one upstream assertion that blockwalk catches and turns into a refusal (in the
/// polygon overlay of `i_overlay`, which repair calls under `catch_unwind`) unwind to that catch;
/// libFuzzer's hook aborts on every panic, caught or not, and still does on every other one. A
/// panic of the overlay that nothing catches still ends the run: the target's own guard aborts.
#[allow(dead_code)]
pub fn let_caught_overlay_panics_unwind() {
    let abort = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if info
            .location()
            .is_some_and(|l| l.file().contains("/i_overlay-"))
        {
            return;
        }
        abort(info);
    }));
}
