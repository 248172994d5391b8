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
//!   needed, stream setpoints, then OFFBOARD (PX4 refuses OFFBOARD before setpoints arrive), and
//!   OFFBOARD again whenever it is seen out of it. COMMAND_ACKs come from the link's ACK
//!   broadcast.
//! - A vehicle that is lost pauses (`lost`); when it speaks again its sequence restarts and it
//!   flies the assignment again. A vehicle whose sequence fails (a refused or unacknowledged
//!   command) goes to Hold and stays out (`failed`).
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
mod formation;
mod handle;
mod handoff;
pub mod plan;

pub use self::actor::start;
pub use self::handle::{AssignError, Guidance, GuidanceMetrics, GuidanceRequest};
pub use self::plan::{
    AssignmentRequest, AssignmentState, AssignmentView, ENDED_BY_OPERATOR, GuidanceSettings, Law,
    OrbitDirection, SlotState, SlotView,
};
