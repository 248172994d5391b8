//! The live service's configuration: a TOML file (`harrier.example.toml` in the repository root
//! documents every key) whose values the command line may override.
//!
//! The deployment a track engine is built for (planar targets on a ground plane, motion models,
//! roads, the scan period) is described here and turned into a
//! [`Deployment`](harrier_engine::Deployment) by [`Config::deployment`], the form
//! [`harrier_engine::registry::build_track_filter`] takes.
//!
//! Split by concern: [`Config`] and its reading in `file.rs`, [`ConfigError`] in `error.rs`; the sections' types and
//! defaults in `sections.rs`, the checks a TOML parser cannot make ([`Config::check`]) in
//! `check.rs`, and the conversions into what the lower crates take ([`Config::bus`],
//! [`Config::deployment`]) in `convert.rs`. The actors read their own sections
//! ([`crate::gcs::GcsConfig::from_config`], `GuidanceSettings::from`).

mod adsb;
mod asterix;
mod check;
mod convert;
mod cot;
mod error;
mod file;
mod foxglove;
mod map;
mod registration;
mod router_filter;
mod sections;
#[cfg(test)]
mod tests;

pub use adsb::{AdsbConfig, AdsbFormat};
pub use asterix::AsterixConfig;
pub use cot::{CotConfig, CotDestination, CotEncoding, CotTransport};
pub use error::ConfigError;
pub use file::Config;
pub use foxglove::FoxgloveConfig;
pub use map::{MapConfig, OSM_ATTRIBUTION};
pub use registration::{RegistrationConfig, RegistrationSensor};
pub use router_filter::{MessageRef, RouterFilterConfig};
pub use sections::{
    ApiConfig, DEFAULT_ORIGIN, FrameConfig, GuidanceConfig, MavlinkConfig, ObstacleConfig,
    RecorderConfig, SigningConfig, TokenConfig, TrackerConfig, ZenohConfig,
};
