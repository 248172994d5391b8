//! What the service and the link actor exchange: the link's configuration, its requests
//! (commands with their outcome, messages to send), the link events, the vehicles' samples and
//! why the link could not start.

use std::path::PathBuf;
use std::time::Duration;

use harrier_link::autopilot::VehicleStatus;
use harrier_link::frame::{Endpoint, EndpointError};
use harrier_link::geo::LocalFrame;
use harrier_link::mavlink::dialects::common::{MavMessage, MavResult};
use harrier_link::signing::Signing;
use serde::{Deserialize, Serialize};
use tokio::sync::oneshot;
use utoipa::ToSchema;

use super::filter::FilterSpec;
use super::vehicle::{ClientCommand, VehicleLinkView};
use crate::config::{Config, ConfigError};

/// Settings of the link (the `[mavlink]` section, checked).
#[derive(Debug, Clone, PartialEq)]
pub struct GcsConfig {
    /// Endpoints the vehicles talk to.
    pub gcs: Vec<Endpoint>,
    /// Client endpoints of the router.
    pub router: Vec<Endpoint>,
    /// The ground station's system id.
    pub system_id: u8,
    /// Its component id.
    pub component_id: u8,
    /// Silence after which a vehicle is lost.
    pub lost_after: Duration,
    /// Wait for a COMMAND_ACK before re-sending.
    pub command_timeout: Duration,
    /// Sends of one command before `timeout`.
    pub command_attempts: u32,
    /// The server's ENU frame (vehicle positions are given in it).
    pub frame: LocalFrame,
    /// Raw MAVLink log (`.tlog`: each frame after its 8-byte big-endian UNIX time in µs).
    pub tlog: Option<PathBuf>,
    /// MAVLink 2 signing (`None`: off).
    pub signing: Option<Signing>,
    /// The ground station's HEARTBEAT goes to the router's clients too.
    pub router_heartbeat: bool,
    /// What each router endpoint lets through, in the order of `router` (an endpoint without
    /// one lets everything through).
    pub router_filters: Vec<FilterSpec>,
}

impl GcsConfig {
    /// The link's settings from the configuration (`[mavlink]`, `[frame]`, `[recorder]`), or
    /// `None` when `mavlink.gcs` is empty. `session` names the
    /// default `.tlog` beside the recording.
    pub fn from_config(c: &Config, session: Option<i64>) -> Result<Option<Self>, ConfigError> {
        let m = &c.mavlink;
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
        } else if let (false, Some(id)) = (c.recorder.path.is_empty(), session) {
            let p = std::path::Path::new(&c.recorder.path);
            let stem = p
                .file_stem()
                .map_or_else(|| "harrier".into(), |s| s.to_string_lossy());
            Some(p.with_file_name(format!("{stem}-session-{id}.tlog")))
        } else {
            None
        };
        Ok(Some(Self {
            gcs: parse(&m.gcs)?,
            router: parse(&m.router)?,
            system_id: m.system_id,
            component_id: m.component_id,
            lost_after: std::time::Duration::from_secs_f64(m.lost_after_s),
            command_timeout: std::time::Duration::from_millis(m.command_timeout_ms),
            command_attempts: m.command_attempts,
            frame: harrier_link::geo::LocalFrame::new(c.frame.origin),
            tlog,
            signing: m.signing.resolve()?,
            router_heartbeat: m.router_heartbeat,
            router_filters: m.router_filters()?,
        }))
    }
}

/// Why the link cannot start.
#[derive(Debug, thiserror::Error)]
pub enum GcsError {
    /// A connection string is malformed.
    #[error("mavlink: {0}")]
    Endpoint(#[from] EndpointError),
    /// An endpoint cannot be opened.
    #[error("mavlink: cannot open {endpoint}: {source}")]
    Open {
        /// The endpoint.
        endpoint: Endpoint,
        /// Why.
        source: std::io::Error,
    },
    /// The `.tlog` file cannot be created.
    #[error("mavlink: cannot create the tlog {path}: {source}")]
    Tlog {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The answer to a command.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct CommandOutcome {
    /// The vehicle.
    pub vehicle: u8,
    /// The MAV_CMD sent.
    pub command: String,
    /// `accepted`, `temporarily_rejected`, `denied`, `unsupported`, `failed`, `cancelled`… (the
    /// vehicle's COMMAND_ACK), or `timeout` (no final ACK after every attempt).
    pub result: CommandResult,
    /// Whether the vehicle accepted it.
    pub ok: bool,
    /// Times it was sent.
    pub attempts: u32,
    /// From the first send to the answer (ms).
    pub elapsed_ms: f64,
}

/// How a command ended: the MAV_RESULT of the vehicle's final COMMAND_ACK (its name without
/// `MAV_RESULT_`, in lower case), or `timeout`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum CommandResult {
    /// `MAV_RESULT_ACCEPTED`: accepted and executed (`ok`).
    Accepted,
    /// `MAV_RESULT_TEMPORARILY_REJECTED`: valid, but not now; it may be tried again later.
    TemporarilyRejected,
    /// `MAV_RESULT_DENIED`: invalid (parameters out of range, or not allowed in this state).
    Denied,
    /// `MAV_RESULT_UNSUPPORTED`: the vehicle does not know this command.
    Unsupported,
    /// `MAV_RESULT_FAILED`: valid, but its execution failed.
    Failed,
    /// `MAV_RESULT_IN_PROGRESS`: still running. Never the final answer here: it restarts the
    /// wait for the ACK.
    InProgress,
    /// `MAV_RESULT_CANCELLED`: cancelled by a COMMAND_CANCEL.
    Cancelled,
    /// `MAV_RESULT_COMMAND_LONG_ONLY`: to be sent as a COMMAND_LONG.
    CommandLongOnly,
    /// `MAV_RESULT_COMMAND_INT_ONLY`: to be sent as a COMMAND_INT.
    CommandIntOnly,
    /// `MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME`: its frame is not supported.
    CommandUnsupportedMavFrame,
    /// `MAV_RESULT_NOT_IN_CONTROL`: another ground station controls the vehicle.
    NotInControl,
    /// No final COMMAND_ACK after every attempt (answered with 504).
    Timeout,
}

impl CommandResult {
    /// The name on the wire (and the `result` label of `harrier_mavlink_command_results_total`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Accepted => "accepted",
            Self::TemporarilyRejected => "temporarily_rejected",
            Self::Denied => "denied",
            Self::Unsupported => "unsupported",
            Self::Failed => "failed",
            Self::InProgress => "in_progress",
            Self::Cancelled => "cancelled",
            Self::CommandLongOnly => "command_long_only",
            Self::CommandIntOnly => "command_int_only",
            Self::CommandUnsupportedMavFrame => "command_unsupported_mav_frame",
            Self::NotInControl => "not_in_control",
            Self::Timeout => "timeout",
        }
    }
}

impl From<MavResult> for CommandResult {
    fn from(r: MavResult) -> Self {
        match r {
            MavResult::MAV_RESULT_ACCEPTED => Self::Accepted,
            MavResult::MAV_RESULT_TEMPORARILY_REJECTED => Self::TemporarilyRejected,
            MavResult::MAV_RESULT_DENIED => Self::Denied,
            MavResult::MAV_RESULT_UNSUPPORTED => Self::Unsupported,
            MavResult::MAV_RESULT_FAILED => Self::Failed,
            MavResult::MAV_RESULT_IN_PROGRESS => Self::InProgress,
            MavResult::MAV_RESULT_CANCELLED => Self::Cancelled,
            MavResult::MAV_RESULT_COMMAND_LONG_ONLY => Self::CommandLongOnly,
            MavResult::MAV_RESULT_COMMAND_INT_ONLY => Self::CommandIntOnly,
            MavResult::MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME => Self::CommandUnsupportedMavFrame,
            MavResult::MAV_RESULT_NOT_IN_CONTROL => Self::NotInControl,
        }
    }
}

/// Why a command was not sent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommandError {
    /// No vehicle with this system id was heard.
    #[error("no vehicle {0}")]
    UnknownVehicle(u8),
    /// The vehicle is silent.
    #[error("vehicle {0} is lost (silent {1:.1} s)")]
    Lost(u8, f64),
    /// The same command to the same vehicle is waiting for its ACK.
    #[error("a {1} to vehicle {0} is already waiting for its acknowledgement")]
    Busy(u8, String),
    /// Not a COMMAND_LONG.
    #[error("not a COMMAND_LONG")]
    NotACommand,
    /// The link is shutting down.
    #[error("the MAVLink link is not running")]
    Stopped,
}

/// A request to the link actor.
#[derive(Debug)]
pub enum Request {
    /// Send a COMMAND_LONG and answer with its outcome.
    Command {
        /// The vehicle.
        vehicle: u8,
        /// The COMMAND_LONG.
        message: MavMessage,
        /// Where the outcome goes.
        reply: oneshot::Sender<Result<CommandOutcome, CommandError>>,
    },
    /// Send a message once, no answer awaited (setpoints; the guidance's own commands, whose ACKs
    /// it reads from `GcsLink::acks`).
    Send {
        /// The vehicle.
        vehicle: u8,
        /// The message.
        message: MavMessage,
    },
    /// Send messages from the ground station to every router client, none to the vehicles
    /// (Harrier's tracks as traffic: the `adsb_out` feed).
    ToClients(Vec<MavMessage>),
    /// The operator accepts a vehicle's new address (gcs::identity); the answer says whether
    /// there was one to accept.
    Accept {
        /// The vehicle.
        vehicle: u8,
        /// `Ok(true)`: accepted; `Ok(false)`: its address was already confirmed.
        reply: oneshot::Sender<Result<bool, CommandError>>,
    },
}

/// A change of a vehicle's link or flight state, on the WebSocket and in the recording.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct LinkEvent {
    /// The vehicle.
    pub vehicle: u8,
    /// `connected` (first heard), `lost`, `recovered`, `mode` (the PX4 mode changed), `armed`,
    /// `disarmed`, `conflict` (a second source claims its id), `moved` (back from a new
    /// address), `accepted` (the operator accepted it).
    pub event: LinkEventKind,
    /// The mode after the change.
    pub mode: Option<String>,
    /// When (UNIX s).
    pub time_unix: f64,
    /// What was seen, in words (`conflict`, `moved`: the addresses).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

/// What happened to a vehicle's link or flight state (a [`LinkEvent`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum LinkEventKind {
    /// First heard (its first HEARTBEAT on a GCS endpoint).
    Connected,
    /// Silent for `mavlink.lost_after_s`.
    Lost,
    /// Heard again after it was lost.
    Recovered,
    /// Its PX4 mode changed (`mode` is the new one).
    Mode,
    /// Its motors were armed.
    Armed,
    /// Its motors were disarmed.
    Disarmed,
    /// A second source claims the vehicle's system id (`detail` names it): its frames are
    /// refused.
    Conflict,
    /// The vehicle speaks again from a new address after it was lost (`detail`): not commanded
    /// by the guidance until the operator accepts it.
    Moved,
    /// The operator accepted the vehicle's new address.
    Accepted,
}

/// A vehicle's state for the guidance: its API view and its status (times on the link's clock,
/// seconds since `GcsLink::epoch`).
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSample {
    /// The API view.
    pub view: VehicleLinkView,
    /// Mode and armed state from its last HEARTBEAT.
    pub status: Option<VehicleStatus>,
    /// Home altitude AMSL (m), once known.
    pub home_amsl: Option<f64>,
    /// Its gimbal manager, once it announced one (GIMBAL_MANAGER_INFORMATION): the manager's
    /// component id and the gimbal device it manages.
    pub gimbal_manager: Option<(u8, u8)>,
    /// When its position (`view.position`, `view.velocity`) arrived: UNIX seconds on the
    /// server's clock, once a GLOBAL_POSITION_INT was heard.
    pub position_unix: Option<f64>,
    /// Whether the guidance may command it: `false` while its new address awaits the operator's
    /// acceptance (gcs::identity).
    pub confirmed: bool,
    /// The last command a router client sent it.
    pub client_command: Option<ClientCommand>,
}

/// Rate of the vehicles watch and of the timeout checks.
pub const PUBLISH_HZ: f64 = 20.0;

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    /// A command's `result` is the MAV_RESULT's name without its prefix, in lower case (as it was
    /// when it was a string), or `timeout`; the metrics label is the same name.
    #[test]
    fn a_command_result_is_named_after_its_mav_result() {
        use MavResult as R;
        for r in [
            R::MAV_RESULT_ACCEPTED,
            R::MAV_RESULT_TEMPORARILY_REJECTED,
            R::MAV_RESULT_DENIED,
            R::MAV_RESULT_UNSUPPORTED,
            R::MAV_RESULT_FAILED,
            R::MAV_RESULT_IN_PROGRESS,
            R::MAV_RESULT_CANCELLED,
            R::MAV_RESULT_COMMAND_LONG_ONLY,
            R::MAV_RESULT_COMMAND_INT_ONLY,
            R::MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME,
            R::MAV_RESULT_NOT_IN_CONTROL,
        ] {
            let former = format!("{r:?}")
                .trim_start_matches("MAV_RESULT_")
                .to_ascii_lowercase();
            let result = CommandResult::from(r);
            assert_eq!(json!(result), json!(former));
            assert_eq!(result.as_str(), former);
        }
        assert_eq!(json!(CommandResult::Timeout), json!("timeout"));
        assert_eq!(CommandResult::Timeout.as_str(), "timeout");
    }

    #[test]
    fn a_link_event_is_sent_by_its_former_name() {
        use LinkEventKind as E;
        let kinds = [
            E::Connected,
            E::Lost,
            E::Recovered,
            E::Mode,
            E::Armed,
            E::Disarmed,
        ];
        assert_eq!(
            json!(kinds),
            json!([
                "connected",
                "lost",
                "recovered",
                "mode",
                "armed",
                "disarmed"
            ])
        );
        let e = LinkEvent {
            vehicle: 3,
            event: E::Mode,
            mode: Some("HOLD".into()),
            time_unix: 1.5,
            detail: None,
        };
        assert_eq!(
            json!(e),
            json!({"vehicle": 3, "event": "mode", "mode": "HOLD", "time_unix": 1.5})
        );
    }
}
