#![no_main]
//! A tile's streaming content: a block mesh record (zlib or raw) or a tile hierarchy.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_tile(common::dir(), data);
});
