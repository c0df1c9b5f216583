#![no_main]
//! An OSM PBF file through the OSM reader, buildings and streets.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(init: common::let_caught_upstream_panics_unwind(), |data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_osm(common::dir(), data);
});
