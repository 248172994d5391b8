#![no_main]
//! Fuzz target `link`: the body is `harness::link`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::link(data));
