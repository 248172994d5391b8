//! How a Harrier process joins the Zenoh network: peer or client mode, explicit endpoints,
//! multicast scouting off unless asked for (so nothing leaks onto the LAN), and only the TCP and
//! TLS transports compiled in (the workspace's `zenoh` dependency enables `transport_tcp` and
//! `transport_tls`). [`TlsConfig`] holds the certificates of `tls/HOST:PORT` endpoints, under
//! Zenoh's own names (`transport/link/tls/*`); with `enable_mtls` the process also presents its
//! certificate, whose common name a router's access control can name (`docs/deploy.md`).
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
    /// Certificates for `tls/…` endpoints.
    pub tls: TlsConfig,
}

/// Certificates and keys of the TLS transport (PEM files), Zenoh's `transport/link/tls/*`.
/// `None`: not set (Zenoh's default).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct TlsConfig {
    /// The certificate authority that signs the other side's certificate (`root_ca_certificate`).
    pub root_ca_certificate: Option<String>,
    /// This process's certificate when it listens on a `tls/` endpoint (`listen_certificate`).
    pub listen_certificate: Option<String>,
    /// Its private key (`listen_private_key`).
    pub listen_private_key: Option<String>,
    /// This process's certificate when it connects to a `tls/` endpoint, presented with
    /// `enable_mtls` (`connect_certificate`).
    pub connect_certificate: Option<String>,
    /// Its private key (`connect_private_key`).
    pub connect_private_key: Option<String>,
    /// Mutual TLS: a listener asks for the client's certificate, a client presents its own
    /// (`enable_mtls`).
    pub enable_mtls: bool,
}

impl TlsConfig {
    /// The settings as (Zenoh key, JSON value) pairs, unset paths left out.
    fn entries(&self) -> Vec<(&'static str, String)> {
        let paths = [
            (
                "transport/link/tls/root_ca_certificate",
                &self.root_ca_certificate,
            ),
            (
                "transport/link/tls/listen_certificate",
                &self.listen_certificate,
            ),
            (
                "transport/link/tls/listen_private_key",
                &self.listen_private_key,
            ),
            (
                "transport/link/tls/connect_certificate",
                &self.connect_certificate,
            ),
            (
                "transport/link/tls/connect_private_key",
                &self.connect_private_key,
            ),
        ];
        let mut out: Vec<(&'static str, String)> = paths
            .into_iter()
            .filter_map(|(k, v)| {
                v.as_ref()
                    .map(|p| (k, serde_json::Value::from(p.as_str()).to_string()))
            })
            .collect();
        out.push((
            "transport/link/tls/enable_mtls",
            self.enable_mtls.to_string(),
        ));
        out
    }
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
        for (key, value) in self.tls.entries() {
            set(key, value)?;
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
            tls: TlsConfig {
                root_ca_certificate: Some("/etc/harrier/ca.pem".into()),
                connect_certificate: Some("/etc/harrier/gcs.pem".into()),
                connect_private_key: Some("/etc/harrier/gcs.key".into()),
                enable_mtls: true,
                ..TlsConfig::default()
            },
        }
        .to_zenoh()
        .expect("config");
        let get = |k: &str| c.get_json(k).expect(k);
        assert_eq!(get("mode"), "\"client\"");
        assert_eq!(get("scouting/multicast/enabled"), "false");
        assert_eq!(get("connect/endpoints"), r#"["tcp/127.0.0.1:7447"]"#);
        assert_eq!(get("listen/endpoints"), r#"["tcp/127.0.0.1:0"]"#);
        let tls = |k: &str| get(&format!("transport/link/tls/{k}"));
        assert_eq!(tls("root_ca_certificate"), r#""/etc/harrier/ca.pem""#);
        assert_eq!(tls("connect_certificate"), r#""/etc/harrier/gcs.pem""#);
        assert_eq!(tls("connect_private_key"), r#""/etc/harrier/gcs.key""#);
        assert_eq!(tls("listen_certificate"), "null");
        assert_eq!(tls("enable_mtls"), "true");
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
