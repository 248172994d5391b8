//! One simulated vehicle: point-mass flight (harrier-core's guidance kinematics), the flight
//! modes and MAVLink protocol of its autopilot personality (PX4, or ArduPilot: ArduCopter or
//! ArduPlane), independent of sockets and of the clock.
//!
//! Time is passed in explicitly (`now`, wall-clock seconds since start), so the protocol and mode
//! logic are unit-tested deterministically; [`crate::net`] drives a [`Vehicle`] over real links.
//!
//! Split by concern: the vehicle's state and mode changes are here; `modes.rs` says what each
//! mode of each autopilot does and when it may be entered, `physics.rs` flies it, `protocol.rs`
//! answers commands and setpoints, `guided.rs` ArduPilot's GUIDED targets, `battery.rs` the
//! battery and its failsafes, `params.rs` holds
//! its parameters (`tables.rs` the defaults of each personality) and `telemetry.rs` its streamed
//! messages.

use harrier_core::guidance::{Limits, UavState};
use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
use harrier_link::geo::{Geodetic, LocalFrame, enu_to_ned};
use mavlink::dialects::common::MavLandedState;
use nalgebra::Vector3;

pub use battery::BatteryLevel;
pub use handoff::GIMBAL_DEVICE_ID;
pub use harrier_link::ardupilot::{CopterMode, PlaneMode};
/// The PX4 flight modes the vehicle flies (harrier-link's PX4 codec).
pub use harrier_link::px4::FlightMode;
pub use tables::Param;
pub use wire::{Framed, Incoming, Outgoing};

mod auto;
mod battery;
mod guided;
mod handoff;
mod mission;
mod modes;
mod params;
mod physics;
mod protocol;
mod tables;
mod telemetry;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_ardupilot;
#[cfg(test)]
mod tests_failsafe;
#[cfg(test)]
mod tests_handoff;
#[cfg(test)]
mod tests_mission;
mod wire;

use modes::Behaviour;
use tables::{Stream, default_params, default_streams};

/// Airframe: which kinematic limits apply and which MAV_TYPE is reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Airframe {
    /// Multirotor (hovers): [`Limits::multirotor`], MAV_TYPE_QUADROTOR.
    Multirotor,
    /// Fixed wing: minimum airspeed (stall margin), bank-angle-limited turns, loiters instead of
    /// hovering; [`Limits::bank_limited`] from its parameters; MAV_TYPE_FIXED_WING.
    FixedWing,
}

impl Airframe {
    /// The airframe's frame kind (harrier-link's).
    pub fn frame(self) -> Frame {
        match self {
            Self::Multirotor => Frame::Multirotor,
            Self::FixedWing => Frame::FixedWing,
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
    /// Setpoints ignored: non-finite values, unsupported frame or type mask, or (ArduPilot) sent
    /// outside GUIDED.
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
    /// The autopilot it behaves as (HEARTBEAT, modes, commands, parameters).
    pub autopilot: Autopilot,
    /// Geodetic origin of the local frame, also the home position.
    pub origin: Geodetic,
    /// Simulation seconds per wall-clock second.
    pub speedup: f64,
    /// How wrong its clock is: the TIMESYNC answers (and the detections' `time_unix`) read it.
    pub clock: ClockSkew,
    /// How fast the battery drains while armed (percent of its charge per simulated minute;
    /// [`DEFAULT_BATTERY_DRAIN_PCT_MIN`]: empty after 30 minutes).
    pub battery_drain_pct_min: f64,
}

/// The default battery drain: a full battery lasts 30 simulated minutes armed.
pub const DEFAULT_BATTERY_DRAIN_PCT_MIN: f64 = 100.0 / 30.0;

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
    /// A PX4 multirotor with the given id at PX4 SITL's default home (Zurich), real time.
    pub fn new(id: u8) -> Self {
        Self {
            id,
            airframe: Airframe::Multirotor,
            autopilot: Autopilot::Px4,
            origin: Geodetic::new(47.397_742, 8.545_594, 488.0),
            speedup: 1.0,
            clock: ClockSkew::default(),
            battery_drain_pct_min: DEFAULT_BATTERY_DRAIN_PCT_MIN,
        }
    }

    /// This configuration as another personality (autopilot and airframe).
    pub fn with_personality(self, p: Personality) -> Self {
        Self {
            autopilot: p.autopilot,
            airframe: match p.frame {
                Frame::Multirotor => Airframe::Multirotor,
                Frame::FixedWing => Airframe::FixedWing,
            },
            ..self
        }
    }

    /// Autopilot and airframe.
    pub fn personality(&self) -> Personality {
        Personality::new(self.autopilot, self.airframe.frame())
    }
}

/// Largest physics step (simulated seconds).
const MAX_STEP: f64 = 0.02;
/// Vertical speed of an automatic climb (m/s).
const CLIMB_SPEED: f64 = 2.5;
/// Position-hold gain (1/s).
const POS_GAIN: f64 = 1.0;

/// A target of the ground station's in PX4's OFFBOARD or ArduCopter's GUIDED (ENU, m and m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    /// Fly this velocity.
    Velocity(Vector3<f64>),
    /// Go to and hold this position.
    Position(Vector3<f64>),
    /// Track this position with this velocity feed-forward.
    PositionVelocity(Vector3<f64>, Vector3<f64>),
}

/// ArduPlane's GUIDED state: the point it loiters around, the radius and direction, and the
/// offboard course, airspeed and altitude its guided commands set.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PlaneGuided {
    /// Loiter radius (m); 0: WP_LOITER_RAD.
    radius: f64,
    /// Loiter counter-clockwise.
    ccw: bool,
    /// Course over ground (rad, clockwise from north) and the lateral acceleration to turn
    /// with (m/s²), set by MAV_CMD_GUIDED_CHANGE_HEADING.
    course: Option<(f64, f64)>,
    /// Airspeed (m/s): GUIDED_CHANGE_SPEED / DO_CHANGE_SPEED; `None`: AIRSPEED_CRUISE.
    airspeed: Option<f64>,
}

/// A PX4 MAV_CMD_DO_ORBIT: its centre (ENU), radius, sense and tangential speed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OrbitTarget {
    centre: Vector3<f64>,
    radius: f64,
    ccw: bool,
    speed: f64,
}

/// The last FOLLOW_TARGET: the target's position and velocity (ENU).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Followed {
    position: Vector3<f64>,
    velocity: Vector3<f64>,
}

impl PlaneGuided {
    const NONE: Self = Self {
        radius: 0.0,
        ccw: false,
        course: None,
        airspeed: None,
    };
}

/// A simulated vehicle: state, modes, parameters and protocol handling.
#[derive(Debug, Clone)]
pub struct Vehicle {
    config: VehicleConfig,
    personality: Personality,
    frame: LocalFrame,
    /// ENU position relative to the origin (m) and velocity (m/s).
    state: UavState,
    yaw: f64,
    accel: Vector3<f64>,
    armed: bool,
    mode: Mode,
    /// Where Hold, Land, RTL and a fixed wing's loiter are centred (ENU, m); `z` the altitude
    /// a fixed wing holds there.
    hold_point: Vector3<f64>,
    /// Height a takeoff climbs to (m above the origin).
    takeoff_alt: f64,
    /// A takeoff (PX4 AUTO.TAKEOFF, ArduCopter's user takeoff, a fixed wing's launch) is climbing.
    taking_off: bool,
    /// The ground station's target (PX4 OFFBOARD, ArduCopter GUIDED).
    target: Option<Target>,
    /// Wall time of the last target.
    last_target: Option<f64>,
    /// ArduPlane's GUIDED state.
    plane: PlaneGuided,
    /// Guided position targets' horizontal speed (m/s; ArduCopter WPNAV_SPEED, DO_CHANGE_SPEED).
    guided_speed: Option<f64>,
    /// Since when an armed ArduCopter sits on the ground (sim time, s).
    landed_since: Option<f64>,
    /// The lowest horizontal speed flown off the ground (m/s).
    slowest_airborne: Option<f64>,
    /// A PX4 DO_REPOSITION's speed (m/s) while Hold flies to its point.
    reposition: Option<f64>,
    /// The orbit of PX4's POSCTL.ORBIT.
    orbit: Option<OrbitTarget>,
    /// The target a follow mode follows.
    followed: Option<Followed>,
    /// ArduCopter FOLLOW's offset from the target, kept from when it was engaged (AP_Follow with
    /// zero FOLL_OFS_*).
    follow_offset: Option<Vector3<f64>>,
    /// The gimbal's region of interest (ENU), from MAV_CMD_DO_SET_ROI_LOCATION.
    roi: Option<Vector3<f64>>,
    params: Vec<Param>,
    streams: Vec<Stream>,
    last_advance: f64,
    sim_time: f64,
    /// Remaining charge (0–1).
    battery: f64,
    /// The battery failsafe levels reached and acted on.
    battery_state: battery::BatteryState,
    /// The mission, fence and rally lists and the transfer in progress.
    missions: mission::Missions,
    /// Where the mission's execution is.
    mission_exec: auto::Exec,
    /// Messages for the next telemetry pass (MISSION_ITEM_REACHED, MISSION_CURRENT, …).
    outbox: Vec<Outgoing>,
    counters: Counters,
}

/// Height below which the vehicle counts as on the ground (m); the ground is the plane `z = 0`
/// of the local frame.
const GROUND_EPS: f64 = 0.05;

impl Vehicle {
    /// A disarmed vehicle on the ground at the origin, in its autopilot's boot mode (PX4 Hold,
    /// ArduCopter STABILIZE, ArduPlane MANUAL), at wall time `now`.
    pub fn new(config: VehicleConfig, now: f64) -> Self {
        let personality = config.personality();
        let streams = default_streams(personality, now);
        Self {
            config,
            personality,
            frame: LocalFrame::new(config.origin),
            state: UavState::new(Vector3::zeros(), Vector3::zeros()),
            yaw: 0.0,
            accel: Vector3::zeros(),
            armed: false,
            mode: personality.initial(),
            hold_point: Vector3::zeros(),
            takeoff_alt: 0.0,
            taking_off: false,
            target: None,
            last_target: None,
            plane: PlaneGuided::NONE,
            guided_speed: None,
            landed_since: None,
            slowest_airborne: None,
            reposition: None,
            orbit: None,
            followed: None,
            follow_offset: None,
            roi: None,
            params: default_params(personality, config.id),
            streams,
            last_advance: now,
            sim_time: 0.0,
            battery: 1.0,
            battery_state: battery::BatteryState::default(),
            missions: mission::Missions::default(),
            mission_exec: auto::Exec::default(),
            outbox: Vec::new(),
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
    /// Autopilot and airframe.
    pub fn personality(&self) -> Personality {
        self.personality
    }
    /// Whether the motors are armed.
    pub fn armed(&self) -> bool {
        self.armed
    }
    /// The flight mode in force, in its autopilot's table.
    pub fn mode(&self) -> Mode {
        self.mode
    }
    /// Position (ENU, m, relative to the origin) and velocity (m/s).
    pub fn state(&self) -> UavState {
        self.state
    }
    /// Heading (rad, clockwise from north in `[-π, π)`): where the nose points.
    pub fn yaw(&self) -> f64 {
        (self.yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
    }
    /// Attitude `[roll, pitch, yaw]` (rad, MAVLink ATTITUDE convention: yaw clockwise from North
    /// in `[-π, π)`): the tilt that produces the current acceleration, body x along the yaw.
    pub fn attitude(&self) -> [f64; 3] {
        let a = enu_to_ned(&self.accel);
        let (sy, cy) = self.yaw.sin_cos();
        let fwd = a.x * cy + a.y * sy;
        let right = -a.x * sy + a.y * cy;
        let g0 = 9.81;
        [(right / g0).atan(), (-fwd / g0).atan(), self.yaw()]
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

    /// A pilot's mode switch: the vehicle changes to `mode` by itself, as when its RC
    /// flight-mode switch is flipped — no command, no COMMAND_ACK; the next HEARTBEAT shows it.
    /// The autopilot's own rules still apply (PX4 enters OFFBOARD only with fresh setpoints and
    /// AUTO.TAKEOFF only armed; a mode the simulator does not fly is refused): whether it
    /// switched.
    pub fn pilot_switch(&mut self, mode: Mode) -> bool {
        let now = self.last_advance;
        self.request_mode(now, mode) == mavlink::dialects::common::MavResult::MAV_RESULT_ACCEPTED
    }

    fn param_f64(&self, name: &str, default: f64) -> f64 {
        self.param(name).map_or(default, f64::from)
    }

    /// The flight envelope: a multirotor's, or a fixed wing's from its airspeed, bank and climb
    /// parameters (ArduPlane AIRSPEED_MIN/MAX, ROLL_LIMIT_DEG, TECS_CLMB_MAX; PX4
    /// FW_AIRSPD_MIN/MAX, FW_R_LIM, FW_T_CLMB_MAX).
    pub fn limits(&self) -> Limits {
        match (self.personality.frame, self.personality.autopilot) {
            (Frame::Multirotor, _) => Limits::multirotor(),
            (Frame::FixedWing, Autopilot::ArduPilot) => Limits::bank_limited(
                self.param_f64("AIRSPEED_MIN", 9.0),
                self.param_f64("AIRSPEED_MAX", 22.0),
                self.param_f64("ROLL_LIMIT_DEG", 45.0).to_radians(),
                self.param_f64("TECS_CLMB_MAX", 5.0),
            ),
            (Frame::FixedWing, Autopilot::Px4) => Limits::bank_limited(
                self.param_f64("FW_AIRSPD_MIN", 10.0),
                self.param_f64("FW_AIRSPD_MAX", 20.0),
                self.param_f64("FW_R_LIM", 50.0).to_radians(),
                self.param_f64("FW_T_CLMB_MAX", 5.0),
            ),
        }
    }

    /// The lowest horizontal speed it has flown off the ground, at every physics step (m/s;
    /// with no wind a fixed wing's lowest airspeed), `None` before it flew.
    pub fn slowest_airborne_speed(&self) -> Option<f64> {
        self.slowest_airborne
    }

    /// The region of interest its gimbal points at (ENU, m), `None` without one.
    pub fn roi(&self) -> Option<Vector3<f64>> {
        self.roi
    }

    /// The gimbal's pointing: the unit vector (ENU) from the vehicle to its region of interest,
    /// `None` without one (a camera slaved to the ROI then looks straight down).
    pub fn gimbal_direction(&self) -> Option<Vector3<f64>> {
        self.roi
            .and_then(|r| (r - self.state.position).try_normalize(1e-9))
    }

    /// A fixed wing's stall speed (m/s): PX4's FW_AIRSPD_STALL; ArduPlane's AIRSPEED_MIN (it has
    /// no separate one). `None` for a multirotor.
    pub fn stall_speed(&self) -> Option<f64> {
        match (self.personality.frame, self.personality.autopilot) {
            (Frame::Multirotor, _) => None,
            (Frame::FixedWing, Autopilot::ArduPilot) => Some(self.param_f64("AIRSPEED_MIN", 9.0)),
            (Frame::FixedWing, Autopilot::Px4) => Some(self.param_f64("FW_AIRSPD_STALL", 7.0)),
        }
    }

    fn behaviour(&self) -> Behaviour {
        modes::behaviour(self.mode).unwrap_or(Behaviour::Hold)
    }

    fn on_ground(&self) -> bool {
        self.state.position.z <= GROUND_EPS && self.state.velocity.z <= 0.0
    }

    fn landed_state(&self) -> MavLandedState {
        let behaviour = self.behaviour();
        if !self.armed || (self.on_ground() && !self.taking_off) {
            MavLandedState::MAV_LANDED_STATE_ON_GROUND
        } else if self.taking_off {
            MavLandedState::MAV_LANDED_STATE_TAKEOFF
        } else if behaviour == Behaviour::Land {
            MavLandedState::MAV_LANDED_STATE_LANDING
        } else {
            MavLandedState::MAV_LANDED_STATE_IN_AIR
        }
    }

    fn setpoints_fresh(&self, now: f64) -> bool {
        let timeout = f64::from(self.param("COM_OF_LOSS_T").unwrap_or(0.5));
        self.last_target.is_some_and(|t| now - t <= timeout)
    }
}
