//! # harrier-server
//!
//! The Harrier ground-station service. For now it holds the offline tools; the live service
//! (Zenoh ingest, MAVLink links, REST/WebSocket) will be `live`, beside them on the same engine.
//!
//! * Estimation engine: [`engine`] (the traits and types every estimator is erased to,
//!   [`engine::ReplayEstimator`]; a leaf module), [`estimators`] (the drivers, which build
//!   harrier-core filters for a scenario and import only [`engine`]) and [`registry`] (every
//!   estimator by name, [`registry::build`]: the one place where a name becomes a
//!   `Box<dyn ReplayEstimator>`).
//! * Offline tools: [`replay`] (`harrier replay`) and [`guidance_sim`] (`harrier guidance-sim`),
//!   both getting their estimators from the registry.

pub mod engine;
pub mod estimators;
pub mod guidance_sim;
pub mod registry;
pub mod replay;
