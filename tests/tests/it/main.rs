//! Harrier's end-to-end and acceptance tests, one module per file, in a single test binary `it`
//! (`tests/it/main.rs`, found by Cargo's directory convention). Every test binary links the whole
//! workspace (zenoh, axum, rusqlite …); one binary instead of one per file links once and keeps
//! `target/` small. The shared helpers are the library `harrier_tests` (`tests/src/lib.rs`).
//!
//! Run one file's tests by its module path, or one test by a part of its name:
//!
//! ```sh
//! cargo test -p harrier-tests --test it live_server::              # every test of live_server.rs
//! cargo test -p harrier-tests --test it live_server::a_formation -- --nocapture
//! cargo test -p harrier-tests --test it -- --list                  # every test, module-qualified
//! ```
//!
//! The modules share one process, so a test must not change process-wide state (environment,
//! current directory, signal handlers, a global logger); each module's documentation says what it
//! starts. `allocation-counter`'s counting allocator (linked for `no_alloc` and `cimm`) is the
//! global allocator of the whole binary; it counts per thread, so the allocation checks see only
//! their own thread's allocations, whatever the other tests do meanwhile.
//!
//! A new test file goes here as a module (`mod name;` below), not as a new `tests/*.rs` binary.

mod api_clients;
mod association;
mod authority;
mod autopilots;
mod bearings;
mod cimm;
mod clock;
mod dashboard;
mod field_adsb;
mod field_asterix;
mod field_cot;
mod field_foxglove;
mod field_tak;
mod fuzz_regressions;
mod guidance;
mod handoff;
mod http_limits;
mod late_scans;
mod live_server;
mod mavlink_gcs;
mod mavproxy_client;
mod mavsdk_client;
mod mesh;
mod no_alloc;
mod pymavlink_client;
mod radar;
mod recording;
mod registration;
mod set_membership;
mod sim_missions;
mod sim_record;
mod tracker;
mod zenith;
mod zenoh_detections;
mod zenoh_router;
