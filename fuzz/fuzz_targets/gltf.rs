//! libFuzzer around `fuzz_cases::gltf` (what it checks is documented there).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| fuzz_cases::gltf::run(data));
