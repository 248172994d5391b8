//! # harrier-server
//!
//! The Harrier ground-station service: the live tracking service and the offline tools, on the
//! same engine.
//!
//! * Estimation engine: [`engine`] (the traits and types every estimator is erased to,
//!   [`engine::ReplayEstimator`]; a leaf module), [`estimators`] (the drivers, which build
//!   harrier-core filters for a scenario and import only [`engine`]) and [`registry`] (every
//!   estimator by name, [`registry::build`]: the one place where a name becomes a
//!   `Box<dyn ReplayEstimator>`).
//! * Live service: [`live`] (`harrier serve`): Zenoh detections in ([`live::ingest`]), a track
//!   engine from the registry fed in time order ([`live::tracker`]), tracks, health and
//!   Prometheus metrics over HTTP ([`live::api`]); configured by a TOML file ([`live::config`]).
//!   MAVLink links and WebSocket streams come later.
//! * Offline tools: [`replay`] (`harrier replay`) and [`guidance_sim`] (`harrier guidance-sim`),
//!   both getting their estimators from the registry.

pub mod bench;
pub mod demo;
pub mod engine;
pub mod estimators;
pub mod guidance_sim;
pub mod live;
pub mod registry;
pub mod replay;
pub mod sessions;
