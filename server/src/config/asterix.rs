//! `[asterix]`: the tracks as EUROCONTROL ASTERIX CAT062 system track messages over UDP
//! (`docs/asterix.md`).

use serde::{Deserialize, Serialize};

use super::error::ConfigError;

/// `[asterix]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct AsterixConfig {
    /// Send the tracks as CAT062.
    pub enabled: bool,
    /// Track updates per second (every track in each).
    pub hz: f64,
    /// Where the datagrams go, `host:port`: a unicast address or a multicast group.
    pub destination: String,
    /// System area code (I062/010).
    pub sac: u8,
    /// System identification code (I062/010).
    pub sic: u8,
    /// Service identification (I062/015).
    pub service_id: u8,
    /// Also send the tentative tracks (flagged CNF in I062/080); else only the confirmed ones.
    pub tentative: bool,
    /// Time to live of datagrams sent to an IPv4 multicast group (1: the local network).
    pub multicast_ttl: u32,
}

impl Default for AsterixConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            hz: 1.0,
            destination: "127.0.0.1:8600".into(),
            sac: 0,
            sic: 1,
            service_id: 1,
            tentative: false,
            multicast_ttl: 1,
        }
    }
}

impl AsterixConfig {
    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        if !self.enabled {
            return Ok(());
        }
        if !(self.hz.is_finite() && self.hz > 0.0 && self.hz <= 100.0) {
            return Err(ConfigError::Invalid(format!(
                "asterix.hz must be in (0, 100], got {}",
                self.hz
            )));
        }
        let port = self
            .destination
            .rsplit_once(':')
            .and_then(|(host, port)| (!host.is_empty()).then_some(port))
            .and_then(|p| p.parse::<u16>().ok());
        if !matches!(port, Some(p) if p != 0) {
            return Err(ConfigError::Invalid(format!(
                "asterix.destination must be host:port, got {:?}",
                self.destination
            )));
        }
        if !(1..=255).contains(&self.multicast_ttl) {
            return Err(ConfigError::Invalid(format!(
                "asterix.multicast_ttl must be in [1, 255], got {}",
                self.multicast_ttl
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::Config;

    #[test]
    fn bad_values_are_named() {
        for (toml, key) in [
            ("enabled = true\nhz = 0.0", "asterix.hz"),
            (
                "enabled = true\ndestination = \"nowhere\"",
                "asterix.destination",
            ),
            (
                "enabled = true\ndestination = \"host:0\"",
                "asterix.destination",
            ),
            ("enabled = true\nmulticast_ttl = 0", "asterix.multicast_ttl"),
        ] {
            let e = Config::parse(&format!("[asterix]\n{toml}\n"), "f").unwrap_err();
            assert!(e.to_string().contains(key), "{toml}: {e}");
        }
        let c = Config::parse("[asterix]\nenabled = true\nsac = 25\nsic = 201\n", "f").unwrap();
        assert_eq!((c.asterix.sac, c.asterix.sic, c.asterix.hz), (25, 201, 1.0));
        // Off, nothing is checked.
        assert!(Config::parse("[asterix]\nhz = -1.0\n", "f").is_ok());
    }
}
