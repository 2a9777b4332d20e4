//! Fuzz target `obj`: the body is `whitted::fuzzing::obj` (docs/reliability.md).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = whitted::fuzzing::obj(data);
});
