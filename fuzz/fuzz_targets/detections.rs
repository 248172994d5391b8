#![no_main]
//! Fuzz target `detections`: the body is `harness::detections`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::detections(data));
