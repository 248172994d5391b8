//! harrier-core's integration tests, one module per file, in a single test binary `it`
//! (`tests/it/main.rs`, found by Cargo's directory convention):
//!
//! ```sh
//! cargo test -p harrier-core --test it hostile::       # one file's tests
//! cargo test -p harrier-core --test it -- --list       # every test, module-qualified
//! ```
//!
//! proptest keeps the seeds of past failures in `tests/proptest-regressions/<module>.txt` (its
//! default place for a source file under a directory with a `main.rs`) and replays them first.

mod hostile;
mod properties;
