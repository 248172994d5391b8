//! `[foxglove]`: a Foxglove WebSocket server (the official `foxglove` SDK's) publishing the tracks,
//! the vehicles and the frame transforms for Foxglove's (or Lichtblick's) 3-D and Map panels, and
//! the same channels recorded into an MCAP file (`docs/foxglove.md`).

use std::net::SocketAddr;

use serde::{Deserialize, Serialize};

use super::error::ConfigError;

/// `[foxglove]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FoxgloveConfig {
    /// Serve the Foxglove WebSocket protocol.
    pub enabled: bool,
    /// Address of the WebSocket server (Foxglove's default port is 8765; port 0: any free port).
    pub listen: SocketAddr,
    /// Rate (Hz) at which the tracker's latest state is published.
    pub hz: f64,
    /// Also record the same channels into this MCAP file (created; it must not exist yet),
    /// closed when the service stops; empty: none. Works with `enabled = false` too (a
    /// recording without a WebSocket server).
    pub mcap: String,
}

impl Default for FoxgloveConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            listen: SocketAddr::from(([127, 0, 0, 1], 8765)),
            hz: 10.0,
            mcap: String::new(),
        }
    }
}

impl FoxgloveConfig {
    /// The feed runs: a WebSocket server, an MCAP recording or both.
    pub fn on(&self) -> bool {
        self.enabled || !self.mcap.is_empty()
    }

    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        if self.on() && !(self.hz.is_finite() && self.hz > 0.0 && self.hz <= 100.0) {
            return Err(ConfigError::Invalid(format!(
                "foxglove.hz must be in (0, 100], got {}",
                self.hz
            )));
        }
        Ok(())
    }
}
