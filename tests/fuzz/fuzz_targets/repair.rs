#![no_main]
//! A decoded polygon through ring repair.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_repair(data);
});
