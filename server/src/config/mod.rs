//! The live service's configuration: a TOML file (`harrier.example.toml` in the repository root
//! documents every key) whose values the command line may override.
//!
//! The deployment a track engine is built for (planar targets on a ground plane, motion models,
//! roads, the scan period) is described here and turned into a
//! [`Deployment`](harrier_engine::Deployment) by [`Config::deployment`], the form
//! [`harrier_engine::registry::build_track_filter`] takes.
//!
//! Split by concern: [`Config`], its errors and reading are here; the sections' types and
//! defaults in `sections.rs`, the checks a TOML parser cannot make ([`Config::check`]) in
//! `check.rs`, and the conversions into the actors' settings ([`Config::gcs`],
//! [`Config::bus`], [`Config::deployment`], the guidance's) in `convert.rs`.

mod check;
mod convert;
mod sections;
#[cfg(test)]
mod tests;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use sections::{
    ApiConfig, DEFAULT_ORIGIN, FrameConfig, GuidanceConfig, MavlinkConfig, ObstacleConfig,
    RecorderConfig, SigningConfig, TokenConfig, TrackerConfig, ZenohConfig,
};

/// The whole configuration.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// The server's ENU frame.
    pub frame: FrameConfig,
    /// The live tracker: its track filter, deployment and input ordering.
    pub tracker: TrackerConfig,
    /// The HTTP API.
    pub api: ApiConfig,
    /// The Zenoh session.
    pub zenoh: ZenohConfig,
    /// The SQLite session recording.
    pub recorder: RecorderConfig,
    /// The MAVLink GCS link and router.
    pub mavlink: MavlinkConfig,
    /// The guidance loop.
    pub guidance: GuidanceConfig,
    /// How far the sources' clocks are trusted.
    pub clock: crate::clock::ClockConfig,
}

/// A configuration that cannot be read or used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not valid TOML or has unknown or mistyped keys.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// toml's message (with line and column).
        message: String,
    },
    /// A value is out of range or inconsistent.
    #[error("{0}")]
    Invalid(String),
}

impl Config {
    /// Parses TOML text (`path` names it in errors).
    pub fn parse(text: &str, path: &str) -> Result<Self, ConfigError> {
        let c: Self = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.into(),
            message: e.to_string(),
        })?;
        c.check()?;
        Ok(c)
    }

    /// Reads a TOML file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }
}
