#![no_main]
//! Fuzz target `vehicle`: the body is `harness::vehicle`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::vehicle(data));
