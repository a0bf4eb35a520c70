#![no_main]
// What this target does with an input: relit_fuzz::harness::transforms (src/harness.rs).
libfuzzer_sys::fuzz_target!(|data: &[u8]| relit_fuzz::harness::transforms(data));
