//! The MAVLink GCS link and router (an actor): many vehicles on the GCS endpoints (PX4 sends to
//! UDP 14550), their telemetry decoded per vehicle, the ground station's own HEARTBEAT, commands
//! with COMMAND_ACK, retries and a timeout, and the vehicles' raw frames routed to client
//! endpoints (QGroundControl, MAVProxy, MAVSDK) and back by target system.
//!
//! ```text
//! vehicles ─UDP/TCP─▶ [gcs endpoints] ─Inbound─▶ [link actor] ─Outbound (raw bytes)─▶ [router endpoints] ─▶ clients
//!          ◀──────────────────────────Outbound─┘    │  ▲  ◀─Inbound (by target_system)─┘
//!                              vehicles watch, events,│  │ requests (commands with ACK, setpoints)
//!                              ACKs, .tlog ◀──────────┘  └── [API], [guidance]
//! ```
//!
//! - A vehicle is known from its first HEARTBEAT (any MAV_TYPE but GCS) on a GCS endpoint; it is
//!   its system id *and* the endpoint and peer it speaks from ([`identity`]): replies go there, a
//!   second source claiming the id while it is connected is a conflict (its frames refused,
//!   nothing sent to it), and a lost vehicle heard again from a new address moves there,
//!   unconfirmed until the operator accepts it. Silent for `mavlink.lost_after_s` it is marked
//!   lost; it recovers when it speaks again.
//! - A command is a COMMAND_LONG sent with confirmation 0, re-sent with confirmation + 1 after
//!   `command_timeout_ms` without its COMMAND_ACK, `command_attempts` times in all; the caller
//!   gets the final ACK's result, or `timeout`. `MAV_RESULT_IN_PROGRESS` restarts the wait.
//! - Router: every valid frame from a vehicle goes unchanged to every client endpoint (the
//!   ground station's own HEARTBEAT only with `mavlink.router_heartbeat`: a client script's
//!   `wait_heartbeat()` would otherwise take system 255 for its vehicle); a
//!   client's frame goes to the vehicle its `target_system` names, or to every vehicle when it
//!   names none (0 or no such field). Frames of other dialects fail their checksum and are not
//!   routed (counted as malformed).
//! - Router filters (`[[mavlink.router_filter]]`, [`filter`]): per client endpoint, allow or
//!   block lists of message ids and of source systems and a rate limit per message id and
//!   source, checked on the raw header of every frame going to that endpoint (the vehicles' and
//!   the ground station's own); a dropped frame is counted per endpoint and reason. Client
//!   frames to the vehicles are not filtered.
//! - Garbage datagrams and undecodable frames are counted per endpoint and skipped.
//! - MAVLink 2 signing (`[mavlink.signing]`, harrier-link's
//!   [`Signer`](harrier_link::signing::Signer), one for the whole link): the ground station signs
//!   its own frames; every frame received on any endpoint is checked
//!   before the actor sees it, and a refused one (`unsigned` in `signed_only` mode,
//!   `bad_signature`, `replay`) is counted by side and reason, logged at a bounded rate, and goes
//!   nowhere: not to the vehicle table, the ACKs, the guidance, the `.tlog` or the router.
//!   The router forwards accepted frames unchanged: a vehicle's frames keep the vehicle's
//!   signature, a client's keep the client's (so in `signed_only` mode clients must sign with the
//!   same key, and the vehicle checks the client's signature itself). It never re-signs: an
//!   unsigned client frame accepted in `sign` mode reaches the vehicle unsigned.

mod actor;
pub mod filter;
pub mod identity;
pub mod metrics;
pub mod timesync;
mod tlog;
pub mod transport;
pub mod vehicle;

mod handle;
mod messages;

pub use self::actor::start;
pub use self::handle::GcsLink;
pub use self::messages::{
    CommandError, CommandOutcome, CommandResult, GcsConfig, GcsError, LinkEvent, LinkEventKind,
    PUBLISH_HZ, Request, VehicleSample,
};
pub use self::metrics::LinkMetrics;
pub use self::vehicle::ClientCommand;
