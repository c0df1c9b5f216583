#![no_main]
//! A GeoPackage geometry blob and plain WKB through the WKB decoder.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk_importers::fuzzing::check_wkb(data);
});
