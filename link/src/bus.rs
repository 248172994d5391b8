//! How a Harrier process joins the Zenoh network: peer or client mode, explicit endpoints,
//! multicast scouting off unless asked for (so nothing leaks onto the LAN), and only the TCP
//! transport compiled in (the workspace's `zenoh` dependency enables `transport_tcp` alone).
//!
//! The simulator publishes detections with a session opened from a [`BusConfig`]; the ground
//! station subscribes with one. Keys and payloads are [`harrier_core::detection`]'s.

use std::fmt;
use std::str::FromStr;

/// Zenoh session mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Peer: talks directly to other peers (and routers).
    #[default]
    Peer,
    /// Client: talks through the router(s) it connects to.
    Client,
}

impl Mode {
    /// Zenoh's name of the mode.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Peer => "peer",
            Self::Client => "client",
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "peer" => Ok(Self::Peer),
            "client" => Ok(Self::Client),
            _ => Err(format!("zenoh mode {s:?}: expected peer or client")),
        }
    }
}

/// How to reach the Zenoh network.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BusConfig {
    /// Session mode.
    pub mode: Mode,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447` (retried in the background while
    /// nobody listens there).
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0` (port 0: any free port).
    pub listen: Vec<String>,
    /// Multicast scouting (off by default).
    pub multicast_scouting: bool,
}

/// Errors from opening a Zenoh session or declaring publishers and subscribers on it.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The configuration was refused (bad endpoint syntax, …).
    #[error("zenoh configuration {key}: {message}")]
    Config {
        /// The configuration key.
        key: &'static str,
        /// Zenoh's message.
        message: String,
    },
    /// The session could not be opened, or a publisher or subscriber declared.
    #[error("zenoh: {0}")]
    Session(String),
}

impl BusConfig {
    /// The Zenoh configuration.
    pub fn to_zenoh(&self) -> Result<zenoh::Config, BusError> {
        let mut c = zenoh::Config::default();
        let mut set = |key: &'static str, value: String| {
            c.insert_json5(key, &value).map_err(|e| BusError::Config {
                key,
                message: e.to_string(),
            })
        };
        set("mode", format!("{:?}", self.mode.as_str()))?;
        set(
            "scouting/multicast/enabled",
            self.multicast_scouting.to_string(),
        )?;
        let list = |v: &[String]| serde_json::to_string(v).unwrap_or_default();
        if !self.connect.is_empty() {
            set("connect/endpoints", list(&self.connect))?;
        }
        if !self.listen.is_empty() {
            set("listen/endpoints", list(&self.listen))?;
        }
        Ok(c)
    }

    /// Opens a session with this configuration (blocking; async callers can
    /// `zenoh::open(config.to_zenoh()?).await` instead).
    pub fn open(&self) -> Result<zenoh::Session, BusError> {
        use zenoh::Wait;
        zenoh::open(self.to_zenoh()?)
            .wait()
            .map_err(|e| BusError::Session(format!("cannot open a session: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse_and_print() {
        for m in [Mode::Peer, Mode::Client] {
            assert_eq!(m.to_string().parse::<Mode>(), Ok(m));
        }
        assert!("router".parse::<Mode>().is_err());
    }

    #[test]
    fn the_config_has_what_was_asked_and_scouting_off() {
        let c = BusConfig {
            mode: Mode::Client,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            listen: vec!["tcp/127.0.0.1:0".into()],
            multicast_scouting: false,
        }
        .to_zenoh()
        .expect("config");
        let get = |k: &str| c.get_json(k).expect(k);
        assert_eq!(get("mode"), "\"client\"");
        assert_eq!(get("scouting/multicast/enabled"), "false");
        assert_eq!(get("connect/endpoints"), r#"["tcp/127.0.0.1:7447"]"#);
        assert_eq!(get("listen/endpoints"), r#"["tcp/127.0.0.1:0"]"#);
    }

    #[test]
    fn bad_endpoints_are_reported() {
        let config = BusConfig {
            listen: vec!["nonsense".into()],
            ..BusConfig::default()
        };
        let e = config.open().expect_err("bad endpoint");
        assert!(e.to_string().contains("listen/endpoints"), "{e}");
    }
}
