//! Fuzz target `pack`: the body is `whitted::fuzzing::pack` (docs/reliability.md).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = whitted::fuzzing::pack(data);
});
