#![no_main]
//! Fuzz target `stream`: the body is `harness::stream`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::stream(data));
