//! Fuzz target `toml`: the body is `whitted::fuzzing::toml` (docs/reliability.md).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = whitted::fuzzing::toml(data);
});
