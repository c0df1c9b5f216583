#![no_main]
//! A route file (TOML, or JSON when it starts with {) resolved as a walk does.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_route(common::dir(), data);
});
