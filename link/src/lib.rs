//! harrier-link: what Harrier's ground station and its simulator both need to talk to vehicles
//! and to each other, with no simulator inside (the live server depends on this crate, never on
//! harrier-sim).
//!
//! - [`geo`]: WGS-84 geodetic ↔ ECEF ↔ local ENU/NED, and points and directions between two
//!   local frames.
//! - [`bus`]: the Zenoh session configuration ([`bus::BusConfig`]: peer/client, explicit
//!   endpoints, multicast scouting off by default, TCP and TLS transports only,
//!   [`bus::TlsConfig`]).
//! - [`autopilot`]: which autopilot and airframe a vehicle is ([`autopilot::Personality`], from
//!   the HEARTBEAT), its [`autopilot::Mode`] in that autopilot's table, the modes that hold,
//!   land or take the ground station's targets, and [`autopilot::VehicleStatus`] from a
//!   HEARTBEAT.
//! - [`px4`]: PX4 flight modes and their MAVLink encodings (HEARTBEAT `custom_mode`,
//!   DO_SET_MODE parameters).
//! - [`ardupilot`]: ArduCopter's and ArduPlane's mode tables, and ArduPilot's reading of a
//!   guided target's type mask.
//! - [`command`]: COMMAND_LONG / COMMAND_INT builders (arm, takeoff, land, mode, ArduPlane's
//!   guided heading, speed and altitude) and offboard setpoints (SET_POSITION_TARGET_LOCAL_NED,
//!   ENU in, NED on the wire), encoded and decoded.
//! - [`offboard`]: the launch under the ground station's control (PX4: arm → takeoff →
//!   setpoints → OFFBOARD; ArduPilot: GUIDED, arm, takeoff, targets) as a pure state machine
//!   driven by the caller's clock and transport.
//! - [`handoff`]: handing a target to the autopilot: PX4's DO_ORBIT, ArduPlane's guided loiter
//!   (DO_REPOSITION with a radius), FOLLOW_TARGET with the track's covariance,
//!   DO_SET_ROI_LOCATION for a camera.
//! - [`frame`]: connection strings ([`frame::Endpoint`]) and MAVLink frames reassembled from
//!   bytes with their headers and raw bytes ([`frame::StreamParser`], [`frame::parse_datagram`]).
//! - [`signing`]: MAVLink 2 message signing ([`signing::Signer`]: sign outgoing frames, refuse
//!   unsigned, wrongly signed and replayed incoming ones by mode, each refusal with its reason).
//! - [`detections`]: a `DetectionScan` re-expressed in a consumer's ENU frame, and the
//!   harrier-core measurement model for it.
//! - [`scenario_out`]: writing `gcs-scenario/1` directories from scans (sensor and platform ids,
//!   measurement lines, truth rows, the atomic directory write), shared by harrier-sim's `record`
//!   and the server's session export.
//!
//! ```
//! use harrier_link::autopilot::{Mode, Personality, VehicleStatus};
//! use harrier_link::offboard::{OffboardConfig, OffboardSequence, Steer};
//! use harrier_link::px4::FlightMode;
//! use nalgebra::Vector3;
//!
//! let p = Personality::PX4_MULTIROTOR;
//! let mut seq = OffboardSequence::new(1, p, OffboardConfig::new(None, None));
//! let status = VehicleStatus {
//!     armed: false,
//!     personality: p,
//!     mode: Some(Mode::Px4(FlightMode::Hold)),
//!     at: 0.0,
//! };
//! let steer = Steer::velocity(Vector3::new(5.0, 0.0, 0.0));
//! let to_send = seq.next(0.0, &status, Some(0.0), Some(steer))?;
//! assert_eq!(to_send.len(), 1); // the arm command; takeoff follows its COMMAND_ACK
//! # Ok::<(), harrier_link::offboard::OffboardError>(())
//! ```
#![deny(missing_docs)]

pub mod ardupilot;
pub mod autopilot;
pub mod bus;
pub mod clock;
pub mod command;
pub mod detections;
pub mod frame;
pub mod geo;
pub mod handoff;
pub mod offboard;
pub mod px4;
pub mod scenario_out;
pub mod signing;

pub use mavlink;
