//! A headless GPU for the tests that draw, or a loud skip.

use super::skip::{or_skip, Need};
use blockwalk::render::{Gpu, RenderError};

/// A headless device, or `None` after a loud skip when there is no adapter; when the GPU is
/// required (`BLOCKWALK_REQUIRE=gpu`, as `.ci/run` sets), no adapter fails the test.
pub fn gpu_or_skip(test: &str) -> Option<Gpu> {
    let found = match Gpu::new_headless() {
        Ok(g) => Ok(g),
        Err(RenderError::NoAdapter { source }) => Err(format!("no GPU adapter ({source})")),
        Err(e @ RenderError::Unsupported { .. }) => Err(e.to_string()),
        Err(e) => panic!("{test}: no usable GPU: {e}"),
    };
    let gpu = or_skip(Need::Gpu, test, found)?;
    eprintln!("{test}: adapter {}", gpu.adapter_name());
    Some(gpu)
}
