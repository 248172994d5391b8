#![no_main]
//! Fuzz target `sim_scenario`: the body is `harness::sim_scenario`, shared with `tests/tests/it/fuzz_regressions.rs`.

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::sim_scenario(data));
