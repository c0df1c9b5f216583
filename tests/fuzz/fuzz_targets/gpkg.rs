#![no_main]
//! A GeoPackage file through the GeoPackage reader, every theme.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_gpkg(common::dir(), data);
});
