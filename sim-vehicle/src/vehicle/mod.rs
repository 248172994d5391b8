//! One simulated vehicle: point-mass flight (harrier-core's guidance kinematics), PX4 flight modes
//! and the MAVLink protocol it speaks, independent of sockets and of the clock.
//!
//! Time is passed in explicitly (`now`, wall-clock seconds since start), so the protocol and mode
//! logic are unit-tested deterministically; [`crate::net`] drives a [`Vehicle`] over real links.
//!
//! Split by concern: the vehicle's state and mode changes are here; `physics.rs` flies it,
//! `protocol.rs` answers commands and setpoints, `params.rs` holds its parameters and
//! `telemetry.rs` its streamed messages.

use harrier_core::guidance::{Limits, UavState};
use harrier_link::command::Setpoint;
use harrier_link::geo::{Geodetic, LocalFrame, enu_to_ned};
use mavlink::dialects::common::{MavLandedState, MavType};
use nalgebra::Vector3;

/// The flight modes the vehicle flies (harrier-link's PX4 codec).
pub use harrier_link::px4::FlightMode;
pub use tables::Param;

mod params;
mod physics;
mod protocol;
mod tables;
mod telemetry;
#[cfg(test)]
mod tests;

use tables::{Stream, default_params, default_streams};

/// Airframe: which kinematic limits apply and which MAV_TYPE is reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Airframe {
    /// Multirotor (hovers): [`Limits::multirotor`], MAV_TYPE_QUADROTOR.
    Multirotor,
    /// Fixed wing (minimum speed, turn-rate limit): [`Limits::fixed_wing`], MAV_TYPE_FIXED_WING.
    FixedWing,
}

impl Airframe {
    /// Kinematic limits of the airframe.
    pub fn limits(self) -> Limits {
        match self {
            Self::Multirotor => Limits::multirotor(),
            Self::FixedWing => Limits::fixed_wing(),
        }
    }
    pub(super) fn mav_type(self) -> MavType {
        match self {
            Self::Multirotor => MavType::MAV_TYPE_QUADROTOR,
            Self::FixedWing => MavType::MAV_TYPE_FIXED_WING,
        }
    }
}

/// Counters of bad or refused input (the vehicle keeps flying).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Input that held no valid MAVLink frame (bad CRC, truncated, unknown message or enum
    /// value): UDP datagrams, stretches of a TCP stream between two valid frames, and frames
    /// with a valid checksum that do not decode.
    pub malformed: u64,
    /// Setpoints ignored: non-finite values, unsupported frame or type mask.
    pub rejected_setpoints: u64,
    /// PARAM_SET refused: unknown name, non-finite or out-of-range value.
    pub rejected_params: u64,
    /// Commands answered with anything but MAV_RESULT_ACCEPTED.
    pub refused_commands: u64,
    /// Frames refused by MAVLink 2 signing, by reason (never handled).
    pub rejected: harrier_link::signing::Rejections,
}

/// Configuration of one vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleConfig {
    /// MAVLink system id (1–255).
    pub id: u8,
    /// Airframe.
    pub airframe: Airframe,
    /// Geodetic origin of the local frame, also the home position.
    pub origin: Geodetic,
    /// Simulation seconds per wall-clock second.
    pub speedup: f64,
    /// How wrong its clock is: the TIMESYNC answers (and the detections' `time_unix`) read it.
    pub clock: ClockSkew,
}

/// A wrong clock: `time_unix` = the true instant + `offset_s` + `drift_ppm`·10⁻⁶ · seconds
/// since the start.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClockSkew {
    /// Offset (s); positive: the clock is ahead.
    pub offset_s: f64,
    /// Drift (µs per s; parts per million).
    pub drift_ppm: f64,
}

impl ClockSkew {
    /// The reading of this clock `elapsed` s after a start the true clock read `start_unix`.
    pub fn read(&self, start_unix: f64, elapsed: f64) -> f64 {
        start_unix + elapsed + self.offset_s + self.drift_ppm * 1e-6 * elapsed
    }
}

impl VehicleConfig {
    /// A multirotor with the given id at PX4 SITL's default home (Zurich), real time.
    pub fn new(id: u8) -> Self {
        Self {
            id,
            airframe: Airframe::Multirotor,
            origin: Geodetic::new(47.397_742, 8.545_594, 488.0),
            speedup: 1.0,
            clock: ClockSkew::default(),
        }
    }
}

/// Largest physics step (simulated seconds).
const MAX_STEP: f64 = 0.02;
/// Vertical speed of an automatic climb (m/s).
const CLIMB_SPEED: f64 = 2.5;
/// Position-hold gain (1/s).
const POS_GAIN: f64 = 1.0;
/// Cruise speed of a fixed wing in Hold and its orbit radius.
const FW_CRUISE: f64 = 18.0;
const FW_ORBIT_RADIUS: f64 = 80.0;

/// A simulated vehicle: state, modes, parameters and protocol handling.
#[derive(Debug, Clone)]
pub struct Vehicle {
    config: VehicleConfig,
    limits: Limits,
    frame: LocalFrame,
    /// ENU position relative to the origin (m) and velocity (m/s).
    state: UavState,
    yaw: f64,
    accel: Vector3<f64>,
    armed: bool,
    mode: FlightMode,
    hold_point: Vector3<f64>,
    takeoff_alt: f64,
    setpoint: Option<Setpoint>,
    last_setpoint: Option<f64>,
    params: Vec<Param>,
    streams: Vec<Stream>,
    last_advance: f64,
    sim_time: f64,
    battery: f64,
    counters: Counters,
}

/// Height below which the vehicle counts as on the ground (m); the ground is the plane `z = 0`
/// of the local frame.
const GROUND_EPS: f64 = 0.05;

impl Vehicle {
    /// A disarmed vehicle on the ground at the origin, in Hold, at wall time `now`.
    pub fn new(config: VehicleConfig, now: f64) -> Self {
        let streams = default_streams(now);
        Self {
            config,
            limits: config.airframe.limits(),
            frame: LocalFrame::new(config.origin),
            state: UavState::new(Vector3::zeros(), Vector3::zeros()),
            yaw: 0.0,
            accel: Vector3::zeros(),
            armed: false,
            mode: FlightMode::Hold,
            hold_point: Vector3::zeros(),
            takeoff_alt: 0.0,
            setpoint: None,
            last_setpoint: None,
            params: default_params(),
            streams,
            last_advance: now,
            sim_time: 0.0,
            battery: 1.0,
            counters: Counters::default(),
        }
    }

    /// MAVLink system id.
    pub fn id(&self) -> u8 {
        self.config.id
    }
    /// Configuration.
    pub fn config(&self) -> &VehicleConfig {
        &self.config
    }
    /// Whether the motors are armed.
    pub fn armed(&self) -> bool {
        self.armed
    }
    /// The flight mode in force.
    pub fn mode(&self) -> FlightMode {
        self.mode
    }
    /// Position (ENU, m, relative to the origin) and velocity (m/s).
    pub fn state(&self) -> UavState {
        self.state
    }
    /// Attitude `[roll, pitch, yaw]` (rad, MAVLink ATTITUDE convention: yaw clockwise from North
    /// in `[-π, π)`): the tilt that produces the current acceleration, body x along the yaw.
    pub fn attitude(&self) -> [f64; 3] {
        let a = enu_to_ned(&self.accel);
        let (sy, cy) = self.yaw.sin_cos();
        let fwd = a.x * cy + a.y * sy;
        let right = -a.x * sy + a.y * cy;
        let g0 = 9.81;
        let yaw = (self.yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        [(right / g0).atan(), (-fwd / g0).atan(), yaw]
    }
    /// Geodetic position.
    pub fn position(&self) -> Geodetic {
        self.frame.from_enu(&self.state.position)
    }
    /// Bad-input counters.
    pub fn counters(&self) -> Counters {
        self.counters
    }
    /// Counts malformed input (see [`Counters::malformed`]).
    pub fn count_malformed(&mut self) {
        self.counters.malformed += 1;
    }
    /// Counts a frame refused by signing (see [`Counters::rejected`]).
    pub fn count_rejected(&mut self, reason: harrier_link::signing::Rejection) {
        self.counters.rejected.count(reason);
    }
    /// A parameter's value.
    pub fn param(&self, name: &str) -> Option<f32> {
        self.params.iter().find(|p| p.name == name).map(|p| p.value)
    }
    /// Simulated seconds since start.
    pub fn sim_time(&self) -> f64 {
        self.sim_time
    }

    fn on_ground(&self) -> bool {
        self.state.position.z <= GROUND_EPS && self.state.velocity.z <= 0.0
    }

    fn landed_state(&self) -> MavLandedState {
        if !self.armed || (self.on_ground() && self.mode != FlightMode::Takeoff) {
            MavLandedState::MAV_LANDED_STATE_ON_GROUND
        } else {
            match self.mode {
                FlightMode::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                FlightMode::Land => MavLandedState::MAV_LANDED_STATE_LANDING,
                _ => MavLandedState::MAV_LANDED_STATE_IN_AIR,
            }
        }
    }

    fn set_mode(&mut self, mode: FlightMode) {
        if matches!(
            mode,
            FlightMode::Hold | FlightMode::Position | FlightMode::Land
        ) {
            self.hold_point = self.state.position;
            if self.limits.can_hover() {
                // Brake first (PX4): hold where a maximum deceleration stops the vehicle.
                let vh = self.state.horizontal_velocity();
                let d = vh * (vh.norm() / (2.0 * self.limits.accel_max.max(1e-9)));
                self.hold_point.x += d.x;
                self.hold_point.y += d.y;
            }
        }
        self.mode = mode;
    }

    fn setpoints_fresh(&self, now: f64) -> bool {
        let timeout = f64::from(self.param("COM_OF_LOSS_T").unwrap_or(0.5));
        self.last_setpoint.is_some_and(|t| now - t <= timeout)
    }
}
