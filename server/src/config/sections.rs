//! The sections of the configuration file (`[mavlink]`, `[guidance]`, `[frame]`, `[tracker]`,
//! `[api]`, `[recorder]`, `[zenoh]`): their types, their defaults, and the few values they
//! resolve themselves (the signing key, a token's expiry).

use std::net::SocketAddr;
use std::path::Path;

use harrier_core::detection::GeoPoint;
use harrier_core::scenario::{Motion, Road};
use harrier_link::signing::{Signing, SigningKey, SigningMode};
use serde::{Deserialize, Serialize};

use super::error::ConfigError;
use super::router_filter::RouterFilterConfig;

/// The MAVLink GCS link and router ([`crate::gcs`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MavlinkConfig {
    /// Endpoints the vehicles talk to (`udpin:`, `udpout:`, `tcpin:`, `tcpout:HOST:PORT`); PX4
    /// sends to UDP 14550. Empty: no MAVLink link (and no guidance).
    pub gcs: Vec<String>,
    /// Router endpoints for MAVLink clients (QGroundControl, MAVProxy, MAVSDK): they see every
    /// vehicle through Harrier. `udpin:` waits for the client to send first (pymavlink
    /// `udpout:`, MAVSDK `udpout://`), `udpout:` sends to a listening client (QGroundControl on
    /// UDP 14550 of another host), `tcpin:` serves TCP clients.
    pub router: Vec<String>,
    /// The ground station's MAVLink system id.
    pub system_id: u8,
    /// Its component id (190: MAV_COMP_ID_MISSIONPLANNER).
    pub component_id: u8,
    /// Silence (s) after which a vehicle is marked lost.
    pub lost_after_s: f64,
    /// Wait (ms) for a COMMAND_ACK before the command is sent again.
    pub command_timeout_ms: u64,
    /// Sends of one command before its result is `timeout`.
    pub command_attempts: u32,
    /// Raw MAVLink log (`.tlog`, read by pymavlink and MAVExplorer). Empty: beside the
    /// recording (`FILE.sqlite` → `FILE-session-N.tlog`) when recording, else none.
    pub tlog: String,
    /// MAVLink 2 message signing on every GCS and router endpoint.
    pub signing: SigningConfig,
    /// Rate (Hz) at which every confirmed track goes to the router's clients as an
    /// ADSB_VEHICLE message, callsign `T<id>` (the traffic message of MAVProxy's `adsb` module
    /// and QGroundControl's ADS-B display; never sent to the vehicles); 0: not sent.
    pub tracks_hz: f64,
    /// Send the ground station's own HEARTBEAT to the router's clients too. Off by default: a
    /// client script's `wait_heartbeat()` (pymavlink, MAVProxy) takes the first HEARTBEAT's
    /// system as its target, and Harrier's (system 255, as QGroundControl's and MAVProxy's own)
    /// would win over the vehicles'.
    pub router_heartbeat: bool,
    /// Per router endpoint: the messages and source systems it gets, and their rates
    /// (`[[mavlink.router_filter]]`; none: every frame to every client).
    pub router_filter: Vec<RouterFilterConfig>,
}

impl MavlinkConfig {
    /// Each router endpoint's filter, in the order of `router` (open where none is
    /// configured); refuses a filter that names no router endpoint, one of two equal endpoints,
    /// or an endpoint already filtered, and the values [`RouterFilterConfig`] cannot take.
    pub fn router_filters(&self) -> Result<Vec<crate::gcs::filter::FilterSpec>, ConfigError> {
        super::router_filter::resolve_all(&self.router, &self.router_filter)
    }
}

/// MAVLink 2 signing of the GCS link and router (`[mavlink.signing]`; docs/mavlink-signing.md).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SigningConfig {
    /// `off`; `sign` (sign every frame sent, accept unsigned frames but refuse wrongly signed
    /// and replayed ones); `signed_only` (accept only correctly signed, fresh frames).
    pub mode: String,
    /// File holding the 32-byte secret key: 64 hex characters, or exactly 32 raw bytes.
    pub key_file: String,
    /// The key as 64 hex characters, instead of `key_file`. Never written back out (the
    /// configuration recorded with a session leaves it out).
    #[serde(skip_serializing)]
    pub key: String,
    /// Link id in the ground station's signatures.
    pub link_id: u8,
}

impl Default for SigningConfig {
    fn default() -> Self {
        Self {
            mode: "off".into(),
            key_file: String::new(),
            key: String::new(),
            link_id: 0,
        }
    }
}

impl SigningConfig {
    /// The settings, `None` when the mode is `off`; reads the key file.
    pub fn resolve(&self) -> Result<Option<Signing>, ConfigError> {
        let bad = |m: String| ConfigError::Invalid(format!("mavlink.signing: {m}"));
        let mode: SigningMode = self.mode.parse().map_err(bad)?;
        if mode == SigningMode::Off {
            return Ok(None);
        }
        let key = match (self.key.is_empty(), self.key_file.is_empty()) {
            (false, true) => SigningKey::from_hex(&self.key),
            (true, false) => SigningKey::from_file(Path::new(&self.key_file)),
            _ => {
                return Err(bad(format!(
                    "mode {mode} needs exactly one of key_file and key"
                )));
            }
        }
        .map_err(|e| bad(e.to_string()))?;
        Ok(Some(Signing {
            key,
            mode,
            link_id: self.link_id,
        }))
    }
}

impl Default for MavlinkConfig {
    fn default() -> Self {
        Self {
            gcs: vec!["udpin:0.0.0.0:14550".into()],
            router: vec!["udpin:0.0.0.0:14551".into(), "tcpin:0.0.0.0:5760".into()],
            system_id: 255,
            component_id: 190,
            lost_after_s: 3.0,
            command_timeout_ms: 1000,
            command_attempts: 3,
            tlog: String::new(),
            signing: SigningConfig::default(),
            tracks_hz: 1.0,
            router_heartbeat: false,
            router_filter: Vec::new(),
        }
    }
}

impl MavlinkConfig {
    /// A GCS link on a free loopback UDP port and no router: for tests and embedded use, where
    /// the well-known ports may be taken.
    pub fn ephemeral() -> Self {
        Self {
            gcs: vec!["udpin:127.0.0.1:0".into()],
            router: Vec::new(),
            ..Self::default()
        }
    }
}

/// The guidance loop ([`crate::guidance`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct GuidanceConfig {
    /// Rate (Hz) at which assigned vehicles get a setpoint.
    pub rate_hz: f64,
    /// A fixed wing's (MAV_TYPE_FIXED_WING's) airspeed band `[min, max]` (m/s): the laws keep it
    /// above the minimum (its stall margin) and below the maximum.
    pub fixed_wing_speed_m_s: [f64; 2],
    /// A fixed wing's bank-angle limit (degrees): its turn rate at speed V is g·tan(φ)/V.
    pub fixed_wing_bank_deg: f64,
    /// Cruise speed (m/s) of the laws (their v₀).
    pub speed_m_s: f64,
    /// Takeoff height above home (m) of a vehicle assigned on the ground.
    pub takeoff_height_m: f64,
    /// Obstacles (ENU discs) the `formation` law steers around; the safety envelope keeps every
    /// setpoint out of them (`safety.no_fly`).
    pub obstacles: Vec<ObstacleConfig>,
    /// The safety envelope on every setpoint (`[guidance.safety]`).
    pub safety: SafetyConfig,
}

/// The safety envelope on every setpoint the guidance sends (`[guidance.safety]`; the
/// guidance's `envelope` module).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyConfig {
    /// Keep setpoints out of the no-fly discs (`guidance.obstacles`).
    pub no_fly: bool,
    /// Largest horizontal distance (m) from the frame's origin; 0: none.
    pub max_distance_m: f64,
    /// Lowest height (m, up in the server's frame) a setpoint may lead to.
    pub floor_m: f64,
    /// Highest height (m, up in the server's frame).
    pub ceiling_m: f64,
    /// How far ahead (s) a setpoint is judged.
    pub lookahead_s: f64,
    /// Remaining battery (%) below which a vehicle leaves its slot and returns home; 0: none.
    pub battery_floor_pct: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            no_fly: true,
            max_distance_m: 5000.0,
            floor_m: 5.0,
            ceiling_m: 500.0,
            lookahead_s: 2.0,
            battery_floor_pct: 25.0,
        }
    }
}

/// A disc to keep out of.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleConfig {
    /// Centre east (m, the server's ENU frame).
    pub x_m: f64,
    /// Centre north (m).
    pub y_m: f64,
    /// Radius (m).
    pub radius_m: f64,
}

impl Default for GuidanceConfig {
    fn default() -> Self {
        Self {
            rate_hz: 20.0,
            fixed_wing_speed_m_s: [10.0, 20.0],
            fixed_wing_bank_deg: 45.0,
            speed_m_s: 10.0,
            takeoff_height_m: 30.0,
            obstacles: Vec::new(),
            safety: SafetyConfig::default(),
        }
    }
}

/// The ENU frame tracks are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrameConfig {
    /// WGS-84 origin of the frame.
    pub origin: GeoPoint,
    /// Up coordinate (m) of the ground plane the targets move on.
    pub plane_z: f64,
}

/// The live tracker (`[tracker]`): its track filter, the deployment it tracks in
/// (`Config::deployment`) and the ordering of its input.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerConfig {
    /// The track filter (`ekf`, `cdkf`, `imm`, `cimm`; `GET /api/v1/estimators`). The key keeps
    /// the name `estimator`, as `PUT /api/v1/estimator` does: both select the track filter.
    pub estimator: String,
    /// The associator (`gnn`, `jipda`, `mht`; `GET /api/v1/estimators`), with any track filter;
    /// `PUT /api/v1/estimator` changes it too.
    pub associator: String,
    /// Track filter parameters (`q`, `gate`, `m`, `n`, `misses`, …), name = value.
    pub params: std::collections::BTreeMap<String, f64>,
    /// Scans are held this long (s of scan time) so that scans of several vehicles arriving out
    /// of order are processed in time order.
    pub reorder_window_s: f64,
    /// A scan older than the last processed one by at most this (s of scan time) updates the
    /// tracks by retrodiction (harrier-core's `tracker::retrodict`); older ones are dropped as
    /// late. 0: every scan older than the last processed one is dropped.
    pub late_lag_s: f64,
    /// Nominal scan period (s): the scenario's `time.dt` (CIMM's road velocity noise).
    pub scan_period_s: f64,
    /// Motion models (`gcs-scenario/1` `motion` block: `accel_std`, `models`, …).
    pub motion: Motion,
    /// Road network (`gcs-scenario/1` `roads`), needed by `cimm`.
    pub roads: Vec<Road>,
    /// Bounded queue lengths between the actors (payloads, scans).
    pub queue: usize,
    /// Sensor ids to track from (a scan's `sensor`); empty: every sensor.
    pub sensors: Vec<String>,
    /// Characteristic size of the targets (m), which `bearing_size` detections need (their
    /// subtended angle gives the range); unset: `bearing_size` scans are dropped as `frame`.
    pub target_size_m: Option<f64>,
    /// Set-membership bounds beside the tracks ([`crate::bound`]).
    pub bound: crate::bound::BoundConfig,
}

/// The HTTP API.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ApiConfig {
    /// Address to bind (port 0: any free port).
    pub listen: SocketAddr,
    /// Bearer token every mutating request must carry (`Authorization: Bearer …`). The
    /// environment variable `HARRIER_TOKEN` overrides it; when both are empty a random token is
    /// generated and printed at start. Never recorded.
    #[serde(skip_serializing)]
    pub token: String,
    /// More tokens, each with a name and an optional expiry (`[[api.tokens]]`): for a script, a
    /// second operator, a CI job. Accepted like `token` until they expire. Never recorded.
    #[serde(skip_serializing)]
    pub tokens: Vec<TokenConfig>,
    /// Require the token for reads too (GET routes and the WebSocket).
    pub auth_reads: bool,
    /// Origins other than the server's own allowed to call the API from a browser (CORS);
    /// empty: same-origin only.
    pub cors_origins: Vec<String>,
    /// Directory of the web dashboard served at `/`; empty: the repository's `web/`.
    pub web_dir: String,
    /// Messages queued per WebSocket client before it is dropped to the latest state.
    pub ws_queue: usize,
    /// Longest wait (s) for a request's head (request line and headers) on a connection, from
    /// its opening or its last response; the connection is then closed.
    pub header_timeout_s: f64,
    /// Longest time (s) from a request's head to the end of its body; then 408.
    pub body_timeout_s: f64,
    /// Most connections open at once, WebSockets included (lowered at start to fit the
    /// open-file limit). At the cap a new connection replaces the oldest one that has not sent
    /// a whole request head yet, or is closed at once when every connection has.
    pub max_connections: usize,
}

/// One `[[api.tokens]]` entry.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TokenConfig {
    /// Who holds it (logs, refusals).
    pub name: String,
    /// The secret (at least 16 characters).
    pub token: String,
    /// When it stops being accepted: RFC 3339 UTC, e.g. `"2026-12-31T23:59:59Z"`; absent: never.
    #[serde(default)]
    pub expires: Option<String>,
}

impl TokenConfig {
    /// The expiry as a time, if any.
    pub fn expiry(&self) -> Result<Option<std::time::SystemTime>, String> {
        self.expires
            .as_deref()
            .map(|e| {
                humantime::parse_rfc3339_weak(e).map_err(|err| {
                    format!(
                        "api.tokens {:?}: expires {e:?} is not an RFC 3339 UTC time \
                         (e.g. \"2026-12-31T23:59:59Z\"): {err}",
                        self.name
                    )
                })
            })
            .transpose()
    }
}

/// The SQLite recording of the session.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecorderConfig {
    /// SQLite file (created if missing; one file holds many sessions); empty: no recording. If
    /// it cannot be opened the service runs without a recording (RECORDING.md).
    pub path: String,
    /// Longest time (ms) between two commits: what a crash can lose.
    pub flush_ms: u64,
    /// Records queued for the writer before new ones are dropped (and counted).
    pub queue: usize,
    /// Also record the simulator's truth (`harrier/v1/sim/truth`) when it is published.
    pub truth: bool,
}

/// The Zenoh session (harrier-link's [`BusConfig`](harrier_link::bus::BusConfig)).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohConfig {
    /// `peer` or `client`.
    pub mode: String,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// Endpoints to connect to (a router in client mode).
    pub connect: Vec<String>,
    /// Multicast scouting.
    pub multicast_scouting: bool,
    /// TLS (`tls/HOST:PORT` endpoints): the certificate authority's certificate (PEM file) that
    /// signed the router's; empty: not set. The names are Zenoh's (`transport/link/tls/*`).
    pub root_ca_certificate: String,
    /// This server's certificate (PEM), presented to the router with `enable_mtls`.
    pub connect_certificate: String,
    /// Its private key (PEM).
    pub connect_private_key: String,
    /// This server's certificate (PEM) on its own `tls/` listen endpoints.
    pub listen_certificate: String,
    /// Its private key (PEM).
    pub listen_private_key: String,
    /// Mutual TLS: present `connect_certificate` when connecting, ask clients for theirs when
    /// listening (a router's access control names them by certificate common name).
    pub enable_mtls: bool,
    /// Key the confirmed tracks are published on (TRACKS.md); empty: not published.
    pub tracks_key: String,
    /// Rate (Hz) of the track publication.
    pub tracks_hz: f64,
}

/// PX4 SITL's default home (Zurich), harrier-sim's default origin.
pub const DEFAULT_ORIGIN: GeoPoint = GeoPoint {
    lat_deg: 47.397_742,
    lon_deg: 8.545_594,
    alt_m: 488.0,
};

impl Default for FrameConfig {
    fn default() -> Self {
        Self {
            origin: DEFAULT_ORIGIN,
            plane_z: 0.0,
        }
    }
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            estimator: "ekf".into(),
            associator: "gnn".into(),
            params: Default::default(),
            reorder_window_s: 0.1,
            late_lag_s: 2.0,
            scan_period_s: 1.0,
            motion: Motion::cv(1.0),
            roads: Vec::new(),
            queue: 1024,
            sensors: Vec::new(),
            target_size_m: None,
            bound: crate::bound::BoundConfig::default(),
        }
    }
}

impl Default for ApiConfig {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            token: String::new(),
            tokens: Vec::new(),
            auth_reads: false,
            cors_origins: Vec::new(),
            web_dir: String::new(),
            ws_queue: 256,
            header_timeout_s: 10.0,
            body_timeout_s: 10.0,
            max_connections: 512,
        }
    }
}

impl Default for RecorderConfig {
    fn default() -> Self {
        Self {
            path: String::new(),
            flush_ms: 200,
            queue: 16_384,
            truth: true,
        }
    }
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            mode: "peer".into(),
            listen: vec!["tcp/127.0.0.1:7447".into()],
            connect: Vec::new(),
            multicast_scouting: false,
            root_ca_certificate: String::new(),
            connect_certificate: String::new(),
            connect_private_key: String::new(),
            listen_certificate: String::new(),
            listen_private_key: String::new(),
            enable_mtls: false,
            tracks_key: harrier_core::detection::TRACKS_KEY.into(),
            tracks_hz: 10.0,
        }
    }
}
