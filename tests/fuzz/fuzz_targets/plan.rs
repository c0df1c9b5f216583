#![no_main]
//! A jobs plan.json read, checked for use and written back.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_plan(common::dir(), data);
});
