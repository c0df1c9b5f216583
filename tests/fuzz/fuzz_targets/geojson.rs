#![no_main]
//! A GeoJSON file through the GeoJSON reader.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_geojson(common::dir(), data);
});
