//! # harrier-cli
//!
//! The `harrier` command (`src/main.rs`): one subcommand per program of the workspace, each a
//! library of its own. This crate's library holds only what joins them:
//!
//! * [`demo`] (`harrier demo`): the live service ([`harrier_server`]) with harrier-sim's world
//!   in-process; the one place outside the tests where the service and the simulator meet.
//! * [`tiles`] (`harrier tiles`): MBTiles files for the dashboard's map, rendered from a
//!   deployment's roads and obstacles.
//! * [`offline_map`]: a deployment's world for the tile renderer, and the demo's offline map
//!   (rendered once, cached), which both of the above use.
//! * [`init_logging`]: the structured logs every subcommand writes.
//!
//! The others: `harrier serve` is [`harrier_server::start`], `harrier replay`, `guidance-sim`,
//! `gen-multi` and `sessions` are the offline tools of `harrier_tools`, `harrier bench` is
//! `harrier_bench`, and `harrier estimators` lists [`harrier_engine::registry`].

pub mod demo;
pub mod offline_map;
pub mod tiles;

/// Structured logs on stderr for the `harrier` commands: the `RUST_LOG` filter if set, else
/// `default`; colours only when stderr is a terminal (a redirected log gets no escape codes).
/// A second call keeps the first subscriber.
pub fn init_logging(default: &str) {
    use std::io::IsTerminal as _;
    use tracing_subscriber::EnvFilter;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default)),
        )
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}
