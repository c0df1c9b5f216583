#![no_main]
//! Decoded street lines through noding and faces.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = blockwalk::fuzzing::check_faces(data);
});
