//! The guidance loop (an actor): assignments tie vehicles to a track with a law, and at
//! `guidance.rate_hz` each assigned vehicle gets a velocity setpoint computed by harrier-core's
//! law from the track predicted to now and the vehicle's **measured** state (its
//! GLOBAL_POSITION_INT, in the server's ENU frame).
//!
//! - Laws: `togvf` (time-optimal guidance vector field, \[CIMM\] §4.1–4.2) and `lgvf` (the Lyapunov
//!   baseline), both with the phase coordination of \[CIMM\] §4.3 when several vehicles share the
//!   target (ring order from the current phases, spacing `spacing_deg`, default 360°/n); and
//!   `formation` (\[BOT\] §III): the track leads, the vehicles hold the LOS ranges of a shape (each
//!   at R from the leader, `spacing_deg` apart around it) with the range regulator of eqs.
//!   (5)–(6), steered around `guidance.obstacles` (§III.B).
//! - Each vehicle flies harrier-link's
//!   [`OffboardSequence`](harrier_link::offboard::OffboardSequence): arm and take off if
//!   needed, stream setpoints, then OFFBOARD (PX4 refuses OFFBOARD before setpoints arrive).
//!   COMMAND_ACKs come from the link's ACK broadcast.
//! - **The operator always wins over automation.** A vehicle whose mode or arming changes by
//!   no command of the guidance's (a router client's command, the RC switch, the autopilot's
//!   failsafe, a landing, a disarm; a hand-off's vehicle leaving its orbit or follow mode)
//!   leaves its slot at once: `overridden`, with what was seen and who sent the vehicle's last
//!   command through the router if anyone did shortly before, an assignment event, a log line
//!   and a counter. An operator's command through the API (`hold`, `land`, `set_mode`,
//!   `disarm`, `takeoff`) takes the vehicle out of its slot first. The guidance never commands
//!   an overridden vehicle again by itself; the operator takes it back with `resume` (or a new
//!   assignment). The rest of the ring re-spaces (360° over the vehicles still flying it, unless
//!   the request gave a spacing).
//! - A vehicle that is lost pauses (`lost`); when it speaks again in the mode it was lost in,
//!   its sequence restarts and it flies the assignment again; in another mode (its failsafe
//!   acted) it is `overridden`; from a new address it waits (`waiting`) until the operator
//!   accepts the address (gcs::identity). A vehicle whose sequence fails (a refused or
//!   unacknowledged command) goes to Hold and stays out (`failed`).
//! - When the track is deleted, or the assignment is ended through the API, every vehicle of it
//!   is sent to Hold (AUTO.LOITER) and the assignment is `ended` with the reason.
//!
//! The files: [`plan`] (the request, its checked [`plan::Plan`], the views and their enums:
//! [`Law`], [`OrbitDirection`], [`AssignmentState`], [`SlotState`]; pure),
//! `formation` (the \[BOT\] formation's commands; pure) and `actor` ([`start`]: the assignments
//! and the loop); `handle` holds the handle ([`Guidance`]), its requests, errors and counters;
//! this one only names them.
//!
//! \[CIMM\]: the constrained-IMM / TOGVF paper (`shared/papers/003_*.txt`).
//! \[BOT\]: Calise et al., *Estimation and Guidance Strategies for Vision-based Target Tracking*
//! (`shared/papers/002_*.txt`).

mod actor;
mod envelope;
mod formation;
mod handle;
mod handoff;
pub mod plan;

pub use self::actor::start;
pub use self::envelope::Envelope;
pub use self::handle::{AssignError, Guidance, GuidanceMetrics, GuidanceRequest};
pub use self::plan::{
    AssignmentRequest, AssignmentState, AssignmentView, ENDED_BY_OPERATOR, GuidanceSettings, Law,
    OrbitDirection, OverrideSource, OverrideView, SlotState, SlotView,
};
