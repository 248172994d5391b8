//! `[cot]`: the confirmed tracks as Cursor-on-Target events for TAK (ATAK, WinTAK, TAK Server),
//! over UDP (multicast or unicast), TCP and TLS (`docs/cot.md`).

use serde::{Deserialize, Serialize};

use super::error::ConfigError;

/// How the events are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CotEncoding {
    /// CoT 2.0 XML, one document per event.
    Xml,
    /// TAK protocol version 1 protobuf (mesh framing on UDP, stream framing on TCP).
    Protobuf,
}

/// The transport of a destination.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CotTransport {
    /// One datagram per event (to a multicast group or one host).
    Udp,
    /// A TCP client (a TAK server's input, e.g. port 8087), reconnected when lost.
    Tcp,
    /// A TLS client over TCP (a TAK server's TLS input, 8089), with `cot.tls_*`.
    Tls,
}

/// One parsed `cot.destinations` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CotDestination {
    /// `udp`, `tcp` or `tls`.
    pub transport: CotTransport,
    /// `host:port` (an IPv6 host in brackets), as written.
    pub address: String,
}

impl CotDestination {
    /// Parses `udp://host:port`, `tcp://host:port` or `tls://host:port`.
    pub fn parse(text: &str) -> Result<Self, String> {
        let (scheme, address) = text
            .split_once("://")
            .ok_or_else(|| format!("{text:?} is not scheme://host:port"))?;
        let transport = match scheme {
            "udp" => CotTransport::Udp,
            "tcp" => CotTransport::Tcp,
            "tls" => CotTransport::Tls,
            other => {
                return Err(format!(
                    "{text:?}: unknown scheme {other:?} (udp, tcp or tls)"
                ));
            }
        };
        let (host, port) = address
            .rsplit_once(':')
            .ok_or_else(|| format!("{text:?} has no port"))?;
        let host = host.trim_start_matches('[').trim_end_matches(']');
        if host.is_empty() || host.contains(char::is_whitespace) {
            return Err(format!("{text:?} has no host"));
        }
        match port.parse::<u16>() {
            Ok(p) if p > 0 => {}
            _ => return Err(format!("{text:?}: the port must be 1–65535")),
        }
        Ok(Self {
            transport,
            address: address.to_owned(),
        })
    }

    /// The host of `address` (without IPv6 brackets): the name a TLS server's certificate
    /// must carry.
    pub fn host(&self) -> &str {
        let host = self.address.rsplit_once(':').map_or("", |(h, _)| h);
        host.trim_start_matches('[').trim_end_matches(']')
    }
}

/// `[cot]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CotConfig {
    /// Send the confirmed tracks as CoT events.
    pub enabled: bool,
    /// Events per track and second.
    pub hz: f64,
    /// `xml` or `protobuf` (TAK protocol version 1).
    pub encoding: CotEncoding,
    /// Where to: `udp://239.2.3.1:6969` (TAK's mesh multicast group), `udp://host:port`,
    /// `tcp://host:port` (a TAK server's TCP input), `tls://host:port` (its TLS input, 8089,
    /// with `tls_ca`, `tls_cert`, `tls_key`).
    pub destinations: Vec<String>,
    /// The CoT type of a track (`a-u-G`: an unknown ground track; `a-h-G` hostile, …).
    #[serde(rename = "type")]
    pub cot_type: String,
    /// The CoT `how` (`m-f`: machine, fused).
    pub how: String,
    /// Send each vehicle too (where its platform was at its last scan).
    pub vehicles: bool,
    /// The CoT type of a vehicle (`a-f-A`: friendly air).
    pub vehicle_type: String,
    /// An event is stale this long after it is sent, s.
    pub stale_s: f64,
    /// The uids are `harrier.<uid_prefix>.track.<id>`; a distinct prefix per server keeps two
    /// servers' tracks apart.
    pub uid_prefix: String,
    /// The IP time-to-live of the multicast datagrams (1: this network only).
    pub multicast_ttl: u32,
    /// Longest wait between two TCP connection attempts, s (the waits double from 0.5 s).
    pub reconnect_max_s: f64,
    /// Events queued per TCP destination; when a slow peer lets it fill, events are dropped.
    pub queue: usize,
    /// For `tls://` destinations: the PEM file of the certificate authorities the server's
    /// certificate must chain to (a TAK server's `truststore` exported as PEM).
    pub tls_ca: String,
    /// For `tls://` destinations: this client's certificate chain, PEM (empty: no client
    /// certificate; a TAK server asks for one).
    pub tls_cert: String,
    /// The private key of `tls_cert`, PEM (PKCS#8, PKCS#1 or SEC1).
    pub tls_key: String,
}

impl Default for CotConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            hz: 1.0,
            encoding: CotEncoding::Xml,
            destinations: vec!["udp://239.2.3.1:6969".into()],
            cot_type: "a-u-G".into(),
            how: "m-f".into(),
            vehicles: false,
            vehicle_type: "a-f-A".into(),
            stale_s: 10.0,
            uid_prefix: "harrier".into(),
            multicast_ttl: 1,
            reconnect_max_s: 10.0,
            queue: 1024,
            tls_ca: String::new(),
            tls_cert: String::new(),
            tls_key: String::new(),
        }
    }
}

impl CotConfig {
    /// The parsed destinations.
    pub fn parsed_destinations(&self) -> Result<Vec<CotDestination>, ConfigError> {
        self.destinations
            .iter()
            .map(|d| {
                CotDestination::parse(d)
                    .map_err(|e| ConfigError::Invalid(format!("cot.destinations: {e}")))
            })
            .collect()
    }

    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        if !self.enabled {
            return Ok(());
        }
        let bad = |m: String| Err(ConfigError::Invalid(m));
        if !(self.hz.is_finite() && self.hz > 0.0 && self.hz <= 50.0) {
            return bad(format!("cot.hz must be in (0, 50], got {}", self.hz));
        }
        if !(self.stale_s.is_finite() && self.stale_s > 0.0 && self.stale_s <= 86_400.0) {
            return bad(format!(
                "cot.stale_s must be in (0, 86400], got {}",
                self.stale_s
            ));
        }
        if self.destinations.is_empty() {
            return bad("cot.destinations must name at least one destination".into());
        }
        let destinations = self.parsed_destinations()?;
        if destinations
            .iter()
            .any(|d| d.transport == CotTransport::Tls)
            && self.tls_ca.is_empty()
        {
            return bad("cot.tls_ca must name a PEM file for a tls:// destination".into());
        }
        if self.tls_cert.is_empty() != self.tls_key.is_empty() {
            return bad("cot.tls_cert and cot.tls_key go together".into());
        }
        for (key, v) in [
            ("type", &self.cot_type),
            ("how", &self.how),
            ("vehicle_type", &self.vehicle_type),
            ("uid_prefix", &self.uid_prefix),
        ] {
            if v.is_empty() || !v.chars().all(|c| c.is_ascii_graphic()) {
                return bad(format!(
                    "cot.{key} must be non-empty printable ASCII without spaces, got {v:?}"
                ));
            }
        }
        if !(1..=255).contains(&self.multicast_ttl) {
            return bad(format!(
                "cot.multicast_ttl must be 1–255, got {}",
                self.multicast_ttl
            ));
        }
        if !(self.reconnect_max_s.is_finite() && self.reconnect_max_s >= 0.5) {
            return bad(format!(
                "cot.reconnect_max_s must be at least 0.5, got {}",
                self.reconnect_max_s
            ));
        }
        if !(1..=65_536).contains(&self.queue) {
            return bad(format!("cot.queue must be 1–65536, got {}", self.queue));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn destinations_parse_and_bad_values_name_their_key() {
        let d = CotDestination::parse("udp://239.2.3.1:6969").expect("udp");
        assert_eq!(d.transport, CotTransport::Udp);
        assert_eq!(d.address, "239.2.3.1:6969");
        let d = CotDestination::parse("tcp://[::1]:8087").expect("tcp");
        assert_eq!(
            (d.transport, d.address.as_str()),
            (CotTransport::Tcp, "[::1]:8087")
        );
        for bad in [
            "239.2.3.1:6969",
            "http://a:1",
            "udp://a",
            "udp://:1",
            "tcp://a:0",
            "ftp://a:21",
        ] {
            assert!(CotDestination::parse(bad).is_err(), "{bad}");
        }
        let on = CotConfig {
            enabled: true,
            ..CotConfig::default()
        };
        assert!(on.check().is_ok());
        let tls = CotConfig {
            destinations: vec!["tls://tak.example:8089".into()],
            ..on.clone()
        };
        assert_eq!(
            CotDestination::parse("tls://[::1]:8089")
                .expect("tls")
                .host(),
            "::1"
        );
        assert!(
            tls.check()
                .expect_err("no CA")
                .to_string()
                .contains("cot.tls_ca")
        );
        let half = CotConfig {
            tls_ca: "ca.pem".into(),
            tls_cert: "c.pem".into(),
            ..tls
        };
        assert!(
            half.check()
                .expect_err("no key")
                .to_string()
                .contains("cot.tls_key")
        );
        let cases: [(&str, CotConfig); 5] = [
            (
                "cot.hz",
                CotConfig {
                    hz: 0.0,
                    ..on.clone()
                },
            ),
            (
                "cot.stale_s",
                CotConfig {
                    stale_s: f64::NAN,
                    ..on.clone()
                },
            ),
            (
                "cot.destinations",
                CotConfig {
                    destinations: vec!["udp://x".into()],
                    ..on.clone()
                },
            ),
            (
                "cot.type",
                CotConfig {
                    cot_type: "a u G".into(),
                    ..on.clone()
                },
            ),
            (
                "cot.queue",
                CotConfig {
                    queue: 0,
                    ..on.clone()
                },
            ),
        ];
        for (key, c) in cases {
            let e = c.check().expect_err(key).to_string();
            assert!(e.contains(key), "{e}");
        }
    }
}
