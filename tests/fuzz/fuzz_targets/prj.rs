#![no_main]
//! A .prj WKT through the CRS recogniser and the metric transform.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_prj(data);
});
