#![no_main]
//! A decoded polygon through ring repair.

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(init: common::let_caught_upstream_panics_unwind(), |data: &[u8]| {
    let _ = blockwalk::fuzzing::check_repair(data);
});
