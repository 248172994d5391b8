//! The live service's configuration: a TOML file (`harrier.example.toml` in the repository root
//! documents every key) whose values the command line may override.
//!
//! The deployment a track engine is built for (planar targets on a ground plane, motion models,
//! roads, the scan period) is described here and turned into a [`Deployment`] by
//! [`Config::deployment`], the form [`harrier_engine::registry::build_track_filter`] takes.

use std::net::SocketAddr;
use std::path::Path;

use harrier_core::detection::GeoPoint;
use harrier_core::scenario::{Motion, Road, Segment};
use harrier_link::bus::{BusConfig, Mode, TlsConfig};
use harrier_link::signing::{Signing, SigningKey, SigningMode};
use serde::{Deserialize, Serialize};

use harrier_engine::{Deployment, Params};

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
    pub clock: super::clock::ClockConfig,
}

/// The MAVLink GCS link and router ([`super::gcs`]).
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

/// The guidance loop ([`super::guidance`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct GuidanceConfig {
    /// Rate (Hz) at which assigned vehicles get a setpoint.
    pub rate_hz: f64,
    /// Flight envelope of the vehicles: `multirotor` or `fixed_wing`.
    pub airframe: String,
    /// Cruise speed (m/s) of the laws (their v₀).
    pub speed_m_s: f64,
    /// Takeoff height above home (m) of a vehicle assigned on the ground.
    pub takeoff_height_m: f64,
    /// Obstacles (ENU discs) the `formation` law steers around.
    pub obstacles: Vec<ObstacleConfig>,
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
            airframe: "multirotor".into(),
            speed_m_s: 10.0,
            takeoff_height_m: 30.0,
            obstacles: Vec::new(),
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
/// ([`Config::deployment`]) and the ordering of its input.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerConfig {
    /// The track filter (`ekf`, `cdkf`, `imm`, `cimm`; `GET /api/v1/estimators`). The key keeps
    /// the name `estimator`, as `PUT /api/v1/estimator` does: both select the track filter.
    pub estimator: String,
    /// Track filter parameters (`q`, `gate`, `m`, `n`, `misses`, …), name = value.
    pub params: std::collections::BTreeMap<String, f64>,
    /// Scans are held this long (s of scan time) so that scans of several vehicles arriving out
    /// of order are processed in time order; older ones are dropped as late.
    pub reorder_window_s: f64,
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
    /// Set-membership bounds beside the tracks ([`super::bound`]).
    pub bound: super::bound::BoundConfig,
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

/// The Zenoh session (harrier-link's [`BusConfig`]).
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
            params: Default::default(),
            reorder_window_s: 0.1,
            scan_period_s: 1.0,
            motion: Motion::cv(1.0),
            roads: Vec::new(),
            queue: 1024,
            sensors: Vec::new(),
            target_size_m: None,
            bound: super::bound::BoundConfig::default(),
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

    /// Checks the values a TOML parser cannot.
    pub fn check(&self) -> Result<(), ConfigError> {
        let bad = |m: String| Err(ConfigError::Invalid(m));
        if let Some(p) = self.clock.problem() {
            return bad(p);
        }
        let o = self.frame.origin;
        if !(o.lat_deg.abs() <= 90.0 && o.lon_deg.abs() <= 180.0 && o.alt_m.is_finite()) {
            return bad(format!("frame.origin {o:?} is not a WGS-84 position"));
        }
        if !self.frame.plane_z.is_finite() {
            return bad("frame.plane_z must be finite".into());
        }
        let mut names = std::collections::HashSet::new();
        for tok in &self.api.tokens {
            if tok.name.is_empty() || !names.insert(tok.name.as_str()) {
                return bad(format!(
                    "api.tokens: every token needs a distinct, non-empty name, got {:?}",
                    tok.name
                ));
            }
            if tok.token.chars().count() < 16 {
                return bad(format!(
                    "api.tokens {:?}: the token must have at least 16 characters",
                    tok.name
                ));
            }
            tok.expiry().map_err(ConfigError::Invalid)?;
        }
        let t = &self.tracker;
        if !(t.reorder_window_s.is_finite() && (0.0..=60.0).contains(&t.reorder_window_s)) {
            return bad(format!(
                "tracker.reorder_window_s must be in [0, 60] s, got {}",
                t.reorder_window_s
            ));
        }
        if !(t.scan_period_s.is_finite() && t.scan_period_s > 0.0) {
            return bad(format!(
                "tracker.scan_period_s must be > 0, got {}",
                t.scan_period_s
            ));
        }
        if t.queue == 0 {
            return bad("tracker.queue must be ≥ 1".into());
        }
        if let Some(p) = deployment_problem(&t.motion, &t.roads) {
            return bad(p);
        }
        if let Some(size) = t.target_size_m
            && !(size.is_finite() && size > 0.0)
        {
            return bad(format!("tracker.target_size_m must be > 0, got {size}"));
        }
        t.bound.check().map_err(ConfigError::Invalid)?;
        if self.api.ws_queue == 0 {
            return bad("api.ws_queue must be ≥ 1".into());
        }
        for (key, s) in [
            ("header_timeout_s", self.api.header_timeout_s),
            ("body_timeout_s", self.api.body_timeout_s),
        ] {
            if !(s.is_finite() && s > 0.0 && s <= 3600.0) {
                return bad(format!("api.{key} must be in (0, 3600] s, got {s}"));
            }
        }
        if self.api.max_connections == 0 {
            return bad("api.max_connections must be ≥ 1".into());
        }
        let r = &self.recorder;
        if !(1..=1000).contains(&r.flush_ms) {
            return bad(format!(
                "recorder.flush_ms must be in [1, 1000] ms, got {}",
                r.flush_ms
            ));
        }
        if r.queue == 0 {
            return bad("recorder.queue must be ≥ 1".into());
        }
        let z = &self.zenoh;
        if !(z.tracks_hz.is_finite() && z.tracks_hz > 0.0 && z.tracks_hz <= 1000.0) {
            return bad(format!(
                "zenoh.tracks_hz must be in (0, 1000], got {}",
                z.tracks_hz
            ));
        }
        if !z.tracks_key.is_empty() {
            if let Err(e) = zenoh::key_expr::KeyExpr::try_from(z.tracks_key.as_str()) {
                return bad(format!("zenoh.tracks_key {:?}: {e}", z.tracks_key));
            }
        }
        self.bus()?;
        let m = &self.mavlink;
        for e in m.gcs.iter().chain(&m.router) {
            harrier_link::frame::Endpoint::parse(e)
                .map_err(|e| ConfigError::Invalid(format!("mavlink: {e}")))?;
        }
        if m.system_id == 0 {
            return bad("mavlink.system_id must be 1-255".into());
        }
        if !(m.lost_after_s.is_finite() && m.lost_after_s > 0.0) {
            return bad(format!(
                "mavlink.lost_after_s must be > 0, got {}",
                m.lost_after_s
            ));
        }
        if !(1..=60_000).contains(&m.command_timeout_ms) || m.command_attempts == 0 {
            return bad(
                "mavlink.command_timeout_ms must be in [1, 60000] and mavlink.command_attempts ≥ 1"
                    .into(),
            );
        }
        if !(m.tracks_hz.is_finite() && (0.0..=50.0).contains(&m.tracks_hz)) {
            return bad(format!(
                "mavlink.tracks_hz must be in [0, 50] (0: tracks not sent), got {}",
                m.tracks_hz
            ));
        }
        m.signing.resolve()?;
        let g = &self.guidance;
        if !(g.rate_hz.is_finite() && g.rate_hz > 0.0 && g.rate_hz <= 100.0) {
            return bad(format!(
                "guidance.rate_hz must be in (0, 100], got {}",
                g.rate_hz
            ));
        }
        if !matches!(g.airframe.as_str(), "multirotor" | "fixed_wing") {
            return bad(format!(
                "guidance.airframe must be multirotor or fixed_wing, got {:?}",
                g.airframe
            ));
        }
        if !(g.speed_m_s.is_finite() && g.speed_m_s > 0.0) {
            return bad(format!(
                "guidance.speed_m_s must be > 0, got {}",
                g.speed_m_s
            ));
        }
        if let Some(o) = g.obstacles.iter().find(|o| {
            !(o.x_m.is_finite() && o.y_m.is_finite() && o.radius_m.is_finite() && o.radius_m > 0.0)
        }) {
            return bad(format!(
                "guidance.obstacles: {o:?} needs finite x_m, y_m and radius_m > 0"
            ));
        }
        if !(g.takeoff_height_m.is_finite() && g.takeoff_height_m > 0.0) {
            return bad(format!(
                "guidance.takeoff_height_m must be > 0, got {}",
                g.takeoff_height_m
            ));
        }
        Ok(())
    }

    /// The MAVLink link's settings, or `None` when `mavlink.gcs` is empty. `session` names the
    /// default `.tlog` beside the recording.
    pub fn gcs(&self, session: Option<i64>) -> Result<Option<super::gcs::GcsConfig>, ConfigError> {
        let m = &self.mavlink;
        if m.gcs.is_empty() {
            return Ok(None);
        }
        let parse = |v: &[String]| {
            v.iter()
                .map(|e| harrier_link::frame::Endpoint::parse(e))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| ConfigError::Invalid(format!("mavlink: {e}")))
        };
        let tlog = if !m.tlog.is_empty() {
            Some(std::path::PathBuf::from(&m.tlog))
        } else if let (false, Some(id)) = (self.recorder.path.is_empty(), session) {
            let p = Path::new(&self.recorder.path);
            let stem = p
                .file_stem()
                .map_or_else(|| "harrier".into(), |s| s.to_string_lossy());
            Some(p.with_file_name(format!("{stem}-session-{id}.tlog")))
        } else {
            None
        };
        Ok(Some(super::gcs::GcsConfig {
            gcs: parse(&m.gcs)?,
            router: parse(&m.router)?,
            system_id: m.system_id,
            component_id: m.component_id,
            lost_after: std::time::Duration::from_secs_f64(m.lost_after_s),
            command_timeout: std::time::Duration::from_millis(m.command_timeout_ms),
            command_attempts: m.command_attempts,
            frame: harrier_link::geo::LocalFrame::new(self.frame.origin),
            tlog,
            signing: m.signing.resolve()?,
            router_heartbeat: m.router_heartbeat,
        }))
    }

    /// The Zenoh session configuration.
    pub fn bus(&self) -> Result<BusConfig, ConfigError> {
        let z = &self.zenoh;
        let mode: Mode = z.mode.parse().map_err(ConfigError::Invalid)?;
        let path = |p: &String| (!p.is_empty()).then(|| p.clone());
        if z.enable_mtls
            && z.connect.iter().any(|e| e.starts_with("tls/"))
            && (z.connect_certificate.is_empty() || z.connect_private_key.is_empty())
        {
            return Err(ConfigError::Invalid(
                "zenoh.enable_mtls with a tls/ connect endpoint needs zenoh.connect_certificate \
                 and zenoh.connect_private_key"
                    .into(),
            ));
        }
        Ok(BusConfig {
            mode,
            connect: z.connect.clone(),
            listen: z.listen.clone(),
            multicast_scouting: z.multicast_scouting,
            tls: TlsConfig {
                root_ca_certificate: path(&z.root_ca_certificate),
                listen_certificate: path(&z.listen_certificate),
                listen_private_key: path(&z.listen_private_key),
                connect_certificate: path(&z.connect_certificate),
                connect_private_key: path(&z.connect_private_key),
                enable_mtls: z.enable_mtls,
            },
        })
    }

    /// The engine parameters.
    pub fn params(&self) -> Params {
        Params::from(&self.tracker.params)
    }

    /// The deployment: planar targets on the ground plane `frame.plane_z`, the motion models,
    /// roads and scan period of `[tracker]`, one sensor (scans bring their own models).
    pub fn deployment(&self) -> Deployment {
        let t = &self.tracker;
        Deployment {
            dims: 2,
            plane_z: self.frame.plane_z,
            motion: Some(t.motion.clone()),
            roads: t.roads.clone(),
            scan_period_s: t.scan_period_s,
            sensors: 1,
        }
    }
}

/// What is wrong with the motion models and roads of `[tracker]`, if anything: a negative
/// `accel_std`, a number that is not finite.
fn deployment_problem(motion: &Motion, roads: &[Road]) -> Option<String> {
    if let Some(a) = motion.accel_std
        && !(a.is_finite() && a >= 0.0)
    {
        return Some(format!("tracker.motion.accel_std must be ≥ 0, got {a}"));
    }
    let mut motion_numbers = motion
        .accel_bound
        .iter()
        .chain(motion.models.iter().filter_map(|m| m.turn_rate.as_ref()))
        .chain(motion.initial_probs.iter().flatten())
        .chain(motion.transition_matrix.iter().flatten().flatten());
    if let Some(bad) = motion_numbers.find(|v| !v.is_finite()) {
        return Some(format!("tracker.motion: {bad} is not a finite number"));
    }
    for road in roads {
        let mut numbers: Vec<f64> = road.width_m.into_iter().chain(road.sigma_m).collect();
        for segment in &road.segments {
            match segment {
                Segment::Line { start, end } => numbers.extend(start.iter().chain(end)),
                Segment::Arc {
                    center,
                    radius,
                    start,
                    end,
                    sweep_rad,
                } => {
                    numbers.extend(center.iter().chain(start).chain(end));
                    numbers.extend([*radius, *sweep_rad]);
                }
            }
        }
        if let Some(bad) = numbers.iter().find(|v| !v.is_finite()) {
            return Some(format!(
                "tracker.roads {:?}: {bad} is not a finite number",
                road.id
            ));
        }
    }
    None
}

impl From<&GuidanceConfig> for super::guidance::GuidanceSettings {
    /// The guidance loop's settings: `airframe` as its flight envelope, the obstacles as discs.
    fn from(g: &GuidanceConfig) -> Self {
        use harrier_core::guidance::{Limits, obstacle::Obstacle};
        Self {
            rate_hz: g.rate_hz,
            limits: if g.airframe == "fixed_wing" {
                Limits::fixed_wing()
            } else {
                Limits::multirotor()
            },
            speed: g.speed_m_s,
            takeoff_height: g.takeoff_height_m,
            obstacles: g
                .obstacles
                .iter()
                .map(|o| Obstacle {
                    center: nalgebra::Vector2::new(o.x_m, o.y_m),
                    radius: o.radius_m,
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_example_parses_and_builds_its_engine() {
        let text = include_str!("../../harrier.example.toml");
        let c = Config::parse(text, "harrier.example.toml").expect("example config");
        harrier_engine::registry::build_track_filter(
            &c.tracker.estimator,
            &c.deployment(),
            &c.params(),
        )
        .expect("engine");
    }

    #[test]
    fn defaults_build_and_bad_values_are_named() {
        let c = Config::parse("", "empty").expect("defaults");
        assert_eq!(c, Config::default());
        harrier_engine::registry::build_track_filter("ekf", &c.deployment(), &c.params())
            .expect("engine");
        let e = Config::parse("[tracker]\nreorder_window_s = -1\n", "f").unwrap_err();
        assert!(e.to_string().contains("reorder_window_s"), "{e}");
        let e = Config::parse("[zenoh]\nmode = \"router\"\n", "f").unwrap_err();
        assert!(e.to_string().contains("router"), "{e}");
        let e = Config::parse(
            "[zenoh]\nconnect = [\"tls/10.0.0.1:7447\"]\nenable_mtls = true\n",
            "f",
        )
        .unwrap_err();
        assert!(e.to_string().contains("connect_certificate"), "{e}");
        let e = Config::parse("[api]\nlisten = 3\n", "f").unwrap_err();
        assert!(e.to_string().starts_with("f: "), "{e}");
        let e = Config::parse("[nonsense]\n", "f").unwrap_err();
        assert!(e.to_string().contains("nonsense"), "{e}");
    }

    #[test]
    fn the_deployment_is_the_tracker_section_and_its_numbers_are_checked() {
        let c = Config::parse(
            "[frame]\nplane_z = 12.5\n[tracker]\nscan_period_s = 0.5\n\
             [[tracker.roads]]\nid = \"r\"\nsigma_m = 2.0\n\
             segments = [{type = \"line\", start = [0.0, 0.0], end = [100.0, 0.0]}]\n",
            "f",
        )
        .expect("config");
        let d = c.deployment();
        assert_eq!(
            (d.dims, d.plane_z, d.scan_period_s, d.sensors),
            (2, 12.5, 0.5, 1)
        );
        assert_eq!(d.motion.as_ref(), Some(&c.tracker.motion));
        assert_eq!(d.roads, c.tracker.roads);
        harrier_engine::registry::build_track_filter("cimm", &d, &c.params()).expect("cimm engine");
        let e = Config::parse("[tracker.motion]\naccel_std = -1.0\n", "f").unwrap_err();
        assert!(e.to_string().contains("tracker.motion.accel_std"), "{e}");
        let e = Config::parse("[tracker.motion]\ntransition_matrix = [[nan]]\n", "f").unwrap_err();
        assert!(e.to_string().contains("tracker.motion: NaN"), "{e}");
        let e = Config::parse(
            "[[tracker.roads]]\nid = \"r\"\nsigma_m = 2.0\n\
             segments = [{type = \"line\", start = [0.0, inf], end = [1.0, 0.0]}]\n",
            "f",
        )
        .unwrap_err();
        assert!(e.to_string().contains("tracker.roads \"r\": inf"), "{e}");
    }

    #[test]
    fn named_tokens_need_a_long_secret_and_a_real_expiry() {
        let tokens = |entry: &str| format!("[[api.tokens]]\n{entry}\n");
        let c = Config::parse(
            &tokens(
                "name = \"ci\"\ntoken = \"0123456789abcdef\"\nexpires = \"2026-12-31T23:59:59Z\"",
            ),
            "f",
        )
        .expect("valid token");
        let at = c.api.tokens[0].expiry().expect("expiry").expect("some");
        let unix = at
            .duration_since(std::time::UNIX_EPOCH)
            .expect("after 1970");
        assert_eq!(unix.as_secs(), 1_798_761_599);
        let e = Config::parse(&tokens("name = \"ci\"\ntoken = \"short\""), "f").unwrap_err();
        assert!(e.to_string().contains("16 characters"), "{e}");
        let e = Config::parse(
            &tokens("name = \"ci\"\ntoken = \"0123456789abcdef\"\nexpires = \"next week\""),
            "f",
        )
        .unwrap_err();
        assert!(e.to_string().contains("RFC 3339"), "{e}");
        let twice = tokens("name = \"a\"\ntoken = \"0123456789abcdef\"").repeat(2);
        let e = Config::parse(&twice, "f").unwrap_err();
        assert!(e.to_string().contains("distinct"), "{e}");
    }

    #[test]
    fn signing_keys_from_hex_or_file_and_never_written_out() {
        let hex = "ab".repeat(32);
        let c = Config::parse(
            &format!("[mavlink.signing]\nmode = \"signed_only\"\nkey = \"{hex}\"\nlink_id = 4\n"),
            "f",
        )
        .expect("hex key");
        let s = c.mavlink.signing.resolve().expect("valid").expect("on");
        assert_eq!(
            (s.mode, s.link_id, *s.key.bytes()),
            (SigningMode::SignedOnly, 4, [0xAB; 32])
        );
        assert!(c.gcs(None).expect("gcs").expect("on").signing.is_some());
        // The configuration recorded with a session does not hold the key.
        let json = serde_json::to_string(&c).expect("json");
        assert!(!json.contains(&hex), "{json}");
        let dir = tempfile::tempdir().expect("temporary directory");
        let file = dir.path().join("key");
        std::fs::write(&file, [7u8; 32]).expect("write");
        let text = format!(
            "[mavlink.signing]\nmode = \"sign\"\nkey_file = {:?}\n",
            file.display().to_string()
        );
        let s = Config::parse(&text, "f")
            .expect("key file")
            .mavlink
            .signing
            .resolve()
            .expect("valid")
            .expect("on");
        assert_eq!((s.mode, *s.key.bytes()), (SigningMode::Sign, [7; 32]));
        assert_eq!(
            Config::default().mavlink.signing.resolve().expect("off"),
            None
        );
        for (bad, says) in [
            ("mode = \"on\"", "off, sign or signed_only"),
            ("mode = \"signed_only\"", "exactly one of key_file and key"),
            ("mode = \"sign\"\nkey = \"abcd\"", "64 hex characters"),
            (
                "mode = \"sign\"\nkey_file = \"/nonexistent/key\"",
                "/nonexistent/key",
            ),
        ] {
            let e = Config::parse(&format!("[mavlink.signing]\n{bad}\n"), "f").unwrap_err();
            assert!(e.to_string().contains(says), "{bad}: {e}");
        }
    }
}
