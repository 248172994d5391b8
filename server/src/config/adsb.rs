//! `[adsb]`: manned traffic from an ADS-B receiver's BaseStation (SBS-1) output (dump1090,
//! readsb: TCP port 30003) or its Beast binary output (port 30005), tracked per aircraft
//! (`docs/adsb.md`).

use serde::{Deserialize, Serialize};

use super::error::ConfigError;
use harrier_core::tracker::identified::IdentifiedConfig;

/// What the receiver's output is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AdsbFormat {
    /// BaseStation SBS-1 text, one decoded message per line (port 30003).
    #[default]
    Sbs,
    /// Beast binary, the raw Mode S messages (port 30005), decoded here.
    Beast,
}

impl std::str::FromStr for AdsbFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sbs" => Ok(Self::Sbs),
            "beast" => Ok(Self::Beast),
            _ => Err(format!(
                "adsb.format must be \"sbs\" or \"beast\", got {s:?}"
            )),
        }
    }
}

/// `[adsb]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdsbConfig {
    /// Connect to the receiver and track its aircraft.
    pub enabled: bool,
    /// The receiver's output, `host:port`.
    pub address: String,
    /// What that output is: `sbs` (port 30003) or `beast` (port 30005).
    pub format: AdsbFormat,
    /// An aircraft without a report for this long is dropped, s.
    pub stale_s: f64,
    /// Standard deviation of a reported horizontal position, m (SBS-1 does not carry the
    /// position's accuracy category, nor is it read from Beast; 10 m is NACp 9's bound).
    pub position_std_m: f64,
    /// Standard deviation of a reported altitude, m (Mode C altitudes come in 25 ft steps).
    pub altitude_std_m: f64,
    /// Standard deviation of a reported ground velocity, m/s (per axis).
    pub velocity_std_mps: f64,
    /// Acceleration noise spectral density of the aircraft's constant-velocity model, m²/s³.
    pub q: f64,
    /// Longest wait between two connection attempts, s (the waits double from 0.5 s).
    pub reconnect_max_s: f64,
}

impl Default for AdsbConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            address: "127.0.0.1:30003".into(),
            format: AdsbFormat::Sbs,
            stale_s: 60.0,
            position_std_m: 10.0,
            altitude_std_m: 10.0,
            velocity_std_mps: 2.0,
            q: 2.0,
            reconnect_max_s: 10.0,
        }
    }
}

impl AdsbConfig {
    /// The per-aircraft filter's settings.
    pub fn filter(&self) -> IdentifiedConfig {
        let (h, v) = (self.position_std_m, self.velocity_std_mps);
        IdentifiedConfig {
            q: self.q,
            position_std: [h, h, self.altitude_std_m],
            velocity_std: [v, v, v],
            initial_velocity_std: 300.0,
            // χ²₃ at 1 − 10⁻⁶: only a report that cannot be the same aircraft is refused.
            gate_nis: 30.7,
            max_rejects: 3,
            stale_s: self.stale_s,
            late_tolerance_s: 2.0,
        }
    }

    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        if !self.enabled {
            return Ok(());
        }
        if self.address.trim().is_empty() || !self.address.contains(':') {
            return Err(ConfigError::Invalid(format!(
                "adsb.address must be host:port, got {:?}",
                self.address
            )));
        }
        let positive = [
            ("stale_s", self.stale_s),
            ("position_std_m", self.position_std_m),
            ("altitude_std_m", self.altitude_std_m),
            ("velocity_std_mps", self.velocity_std_mps),
            ("q", self.q),
        ];
        for (key, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::Invalid(format!(
                    "adsb.{key} must be positive and finite, got {v}"
                )));
            }
        }
        if !(self.reconnect_max_s.is_finite() && self.reconnect_max_s >= 0.5) {
            return Err(ConfigError::Invalid(format!(
                "adsb.reconnect_max_s must be at least 0.5, got {}",
                self.reconnect_max_s
            )));
        }
        Ok(())
    }
}
