#![no_main]
//! A Shapefile (.shp, .shx, .dbf, .prj split from one input) through both Shapefile readers.
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_shapefile(common::dir(), data);
});
