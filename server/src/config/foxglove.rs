//! `[foxglove]`: a Foxglove WebSocket server (the official `foxglove` SDK's) publishing the tracks,
//! the vehicles and the frame transforms for Foxglove's (or Lichtblick's) 3-D and Map panels
//! (`docs/foxglove.md`).

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
}

impl Default for FoxgloveConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            listen: SocketAddr::from(([127, 0, 0, 1], 8765)),
            hz: 10.0,
        }
    }
}

impl FoxgloveConfig {
    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        if self.enabled && !(self.hz.is_finite() && self.hz > 0.0 && self.hz <= 100.0) {
            return Err(ConfigError::Invalid(format!(
                "foxglove.hz must be in (0, 100], got {}",
                self.hz
            )));
        }
        Ok(())
    }
}
