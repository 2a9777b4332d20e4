//! Fuzz target `nff`: the body is `whitted::fuzzing::nff` (docs/reliability.md).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = whitted::fuzzing::nff(data);
});
