//! A headless GPU for the tests that draw, or a skip.

use blockwalk::render::{Gpu, RenderError};

/// A headless device, or `None` (with a SKIPPED line) when there is no adapter and
/// `BLOCKWALK_REQUIRE_GPU` is unset; with it set (as `.ci/run` does), no adapter fails the test.
pub fn gpu_or_skip(test: &str) -> Option<Gpu> {
    match Gpu::new_headless() {
        Ok(g) => {
            eprintln!("{test}: adapter {}", g.adapter_name());
            Some(g)
        }
        Err(RenderError::NoAdapter { source })
            if std::env::var_os("BLOCKWALK_REQUIRE_GPU").is_none() =>
        {
            eprintln!("{test}: SKIPPED, no GPU adapter ({source}); set BLOCKWALK_REQUIRE_GPU=1 to fail instead");
            None
        }
        Err(e) => panic!("{test}: no usable GPU: {e}"),
    }
}
