//! libFuzzer around `fuzz_cases::shards` (what it checks is documented there).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| fuzz_cases::shards::run(data));
