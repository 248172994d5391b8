//! # harrier-server
//!
//! The Harrier ground-station service: the live tracking service and the offline tools, on the
//! same engine.
//!
//! * Estimation engine: [`engine`] (the traits and types every estimator is erased to,
//!   [`engine::ReplayEstimator`]; a leaf module), [`estimators`] (the drivers, which build
//!   harrier-core filters for a scenario and import only [`engine`]) and [`registry`] (every
//!   replay estimator by name, [`registry::build`]: the one place where a name becomes a
//!   `Box<dyn ReplayEstimator>`; every track filter by name, [`registry::build_track_filter`]:
//!   the one place where a name becomes a `Box<dyn TrackEngine>`).
//! * Live service: [`live`] (`harrier serve`): Zenoh detections in ([`live::ingest`]), a track
//!   engine from the registry fed in time order ([`live::tracker`]), tracks, health and
//!   Prometheus metrics over HTTP ([`live::http`]), the WebSocket stream ([`live::http::ws`]), the
//!   MAVLink GCS link and router ([`live::gcs`]) and the guidance loop ([`live::guidance`]);
//!   configured by a TOML file ([`live::config`]). [`demo`] runs it with harrier-sim's world
//!   in-process; [`bench`](mod@bench) loads it.
//! * Recording: [`recording`], the session file: written by the live service
//!   ([`recording::writer`]), read offline by `harrier sessions` and the `/sessions` routes
//!   ([`recording::reader`], [`recording::export`]).
//! * Offline tools: [`replay`] (`harrier replay`) and [`guidance_sim`] (`harrier guidance-sim`),
//!   both getting their estimators from the registry; [`gen_multi`] (`harrier gen-multi`).

pub mod bench;
pub mod clock;
pub mod demo;
pub mod engine;
pub mod estimators;
pub mod gen_multi;
pub mod guidance_sim;
pub mod live;
pub mod prom;
pub mod recording;
pub mod registry;
pub mod replay;

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
