//! libFuzzer around `fuzz_cases::pipeline` (what it checks is documented there).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| fuzz_cases::pipeline::run(data));
