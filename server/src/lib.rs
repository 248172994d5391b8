//! # harrier-server
//!
//! The Harrier ground-station service. For now it holds the offline side: `harrier replay` runs an
//! estimator over a `gcs-scenario/1` directory and writes `estimates.jsonl`.
//!
//! [`engine`] is the one place where harrier-core's generic filters are erased into trait objects
//! ([`engine::ReplayEstimator`]), chosen by name at run time.

pub mod engine;
pub mod estimators;
pub mod guidance_sim;
pub mod replay;
