#![no_main]
//! A decoded polygon repaired and extruded.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_extrude(data);
});
