#![no_main]
//! Fuzz target `rest`: the body is `harness::rest`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::rest(data));
