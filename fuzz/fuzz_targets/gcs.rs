#![no_main]
//! Fuzz target `gcs`: the body is `harness::gcs`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::gcs(data));
