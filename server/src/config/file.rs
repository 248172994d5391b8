//! The whole configuration ([`Config`]) and its reading from TOML.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::adsb::AdsbConfig;
use super::asterix::AsterixConfig;
use super::cot::CotConfig;
use super::error::ConfigError;
use super::foxglove::FoxgloveConfig;
use super::map::MapConfig;
use super::registration::RegistrationConfig;
use super::sections::{
    ApiConfig, FrameConfig, GuidanceConfig, MavlinkConfig, RecorderConfig, TrackerConfig,
    ZenohConfig,
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
    /// Manned traffic from an ADS-B receiver (SBS-1).
    pub adsb: AdsbConfig,
    /// The Foxglove WebSocket server.
    pub foxglove: FoxgloveConfig,
    /// The tracks as ASTERIX CAT062 over UDP.
    pub asterix: AsterixConfig,
    /// The confirmed tracks as Cursor-on-Target events for TAK.
    pub cot: CotConfig,
    /// The dashboard's geographic map: its tiles.
    pub map: MapConfig,
    /// Live sensor registration: the sensors whose biases the tracker estimates.
    pub registration: RegistrationConfig,
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
