//! One simulated vehicle: point-mass flight (harrier-core's guidance kinematics), PX4 flight modes
//! and the MAVLink protocol it speaks, independent of sockets and of the clock.
//!
//! Time is passed in explicitly (`now`, wall-clock seconds since start), so the protocol and mode
//! logic are unit-tested deterministically; [`crate::net`] drives a [`Vehicle`] over real links.

use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::{Command, Limits, UavState};
use mavlink::MessageData;
use mavlink::dialects::common::{
    ATTITUDE_DATA, AUTOPILOT_VERSION_DATA, BATTERY_STATUS_DATA, COMMAND_ACK_DATA,
    COMMAND_LONG_DATA, EXTENDED_SYS_STATE_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA,
    GpsFixType, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA, MavAutopilot,
    MavBatteryFunction, MavBatteryType, MavCmd, MavLandedState, MavMessage, MavParamType,
    MavProtocolCapability, MavResult, MavState, MavSysStatusSensor, MavType, MavVtolState,
    PARAM_SET_DATA, PARAM_VALUE_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA, SYS_STATUS_DATA,
};
use nalgebra::{Vector2, Vector3};

use harrier_link::command::Setpoint;
use harrier_link::geo::{Geodetic, LocalFrame, enu_to_ned};
use harrier_link::px4::{COMPONENT_ID, SetModeError, base_mode};

/// The flight modes the vehicle flies (harrier-link's PX4 codec).
pub use harrier_link::px4::FlightMode;

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
    fn mav_type(self) -> MavType {
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
}

/// A tunable parameter (all REAL32).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Param {
    /// Name (at most 16 characters).
    pub name: &'static str,
    /// Value.
    pub value: f32,
    /// Smallest accepted value.
    pub min: f32,
    /// Largest accepted value.
    pub max: f32,
}

fn default_params() -> Vec<Param> {
    vec![
        Param {
            name: "MIS_TAKEOFF_ALT",
            value: 2.5,
            min: 0.5,
            max: 500.0,
        },
        Param {
            name: "COM_OF_LOSS_T",
            value: 0.5,
            min: 0.1,
            max: 60.0,
        },
        Param {
            name: "MPC_LAND_SPEED",
            value: 0.7,
            min: 0.1,
            max: 5.0,
        },
    ]
}

/// Telemetry streams and their default intervals (s).
const STREAMS: [(u32, f64); 9] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 1.0),
    (EXTENDED_SYS_STATE_DATA::ID, 1.0),
    (BATTERY_STATUS_DATA::ID, 1.0),
    (HOME_POSITION_DATA::ID, 2.0),
    (GPS_RAW_INT_DATA::ID, 0.2),
    (GLOBAL_POSITION_INT_DATA::ID, 0.1),
    (LOCAL_POSITION_NED_DATA::ID, 0.1),
    (ATTITUDE_DATA::ID, 0.1),
];

#[derive(Debug, Clone, Copy)]
struct Stream {
    id: u32,
    default_interval: f64,
    /// Interval (s); `None` when disabled.
    interval: Option<f64>,
    next_due: f64,
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
}

impl VehicleConfig {
    /// A multirotor with the given id at PX4 SITL's default home (Zurich), real time.
    pub fn new(id: u8) -> Self {
        Self {
            id,
            airframe: Airframe::Multirotor,
            origin: Geodetic::new(47.397_742, 8.545_594, 488.0),
            speedup: 1.0,
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
        let streams = STREAMS
            .iter()
            .map(|&(id, dt)| Stream {
                id,
                default_interval: dt,
                interval: Some(dt),
                next_due: now,
            })
            .collect();
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

    /// Advances the flight to wall time `now` (simulated time runs `speedup` times faster).
    pub fn advance(&mut self, now: f64) {
        let wall_dt = now - self.last_advance;
        if !wall_dt.is_finite() || wall_dt <= 0.0 {
            return;
        }
        self.last_advance = now;
        // Offboard loss: back to Hold when setpoints stop (wall time, as a client streams them).
        if self.mode == FlightMode::Offboard && !self.setpoints_fresh(now) {
            self.setpoint = None;
            self.set_mode(FlightMode::Hold);
        }
        let mut remaining = (wall_dt * self.config.speedup).min(10.0);
        while remaining > 1e-9 {
            let dt = remaining.min(MAX_STEP);
            self.physics_step(dt);
            remaining -= dt;
        }
    }

    fn setpoints_fresh(&self, now: f64) -> bool {
        let timeout = f64::from(self.param("COM_OF_LOSS_T").unwrap_or(0.5));
        self.last_setpoint.is_some_and(|t| now - t <= timeout)
    }

    fn hold_command(&self, target: Vector3<f64>) -> Vector3<f64> {
        let err = target - self.state.position;
        if self.limits.can_hover() {
            err * POS_GAIN
        } else {
            // Fixed wing: orbit the target point at the cruise speed.
            let r = Vector2::new(-err.x, -err.y);
            let d = r.norm().max(1e-6);
            let radial = r / d;
            let tangent = Vector2::new(-radial.y, radial.x);
            let v = tangent * FW_CRUISE - radial * ((d - FW_ORBIT_RADIUS) * 0.1).clamp(-8.0, 8.0);
            Vector3::new(v.x, v.y, err.z * POS_GAIN)
        }
    }

    fn physics_step(&mut self, dt: f64) {
        self.sim_time += dt;
        if self.armed {
            self.battery = (self.battery - dt / 1800.0).max(0.0);
        }
        if !self.armed {
            self.state.velocity = Vector3::zeros();
            self.accel = Vector3::zeros();
            return;
        }
        let grounded = self.on_ground();
        let cmd = match self.mode {
            FlightMode::Takeoff => {
                let mut c = self.hold_command(Vector3::new(
                    self.hold_point.x,
                    self.hold_point.y,
                    self.takeoff_alt,
                ));
                c.z = ((self.takeoff_alt - self.state.position.z) * POS_GAIN * 2.0)
                    .clamp(-CLIMB_SPEED, CLIMB_SPEED);
                if grounded {
                    c.x = 0.0;
                    c.y = 0.0;
                }
                c
            }
            FlightMode::Land => {
                let mut c = self.hold_command(self.hold_point);
                c.z = -f64::from(self.param("MPC_LAND_SPEED").unwrap_or(0.7));
                c
            }
            FlightMode::Hold | FlightMode::Position => self.hold_command(self.hold_point),
            FlightMode::Offboard => match self.setpoint {
                Some(Setpoint::Velocity(v)) => v,
                Some(Setpoint::Position(p)) => self.hold_command(p),
                None => self.hold_command(self.hold_point),
            },
        };
        if grounded && cmd.z <= 0.0 {
            // Sitting on the ground: nothing moves until a climb is commanded.
            self.state.position.z = 0.0;
            self.state.velocity = Vector3::zeros();
            self.accel = Vector3::zeros();
            if self.mode == FlightMode::Land {
                self.armed = false;
                self.set_mode(FlightMode::Hold);
            }
            return;
        }
        let mut limits = self.limits;
        if grounded {
            // A fixed wing leaves the ground like a multirotor (catapult launch).
            limits.v_min = 0.0;
        }
        let prev = self.state;
        let mut next = step(&prev, &Command { velocity: cmd }, &limits, dt);
        if next.position.z < 0.0 {
            next.position.z = 0.0;
            next.velocity.z = next.velocity.z.max(0.0);
        }
        self.accel = (next.velocity - prev.velocity) / dt;
        let vh = next.horizontal_velocity();
        if vh.norm() > 0.3 {
            // NED yaw: clockwise from north.
            self.yaw = vh.x.atan2(vh.y);
        }
        self.state = next;
        if self.mode == FlightMode::Takeoff && self.state.position.z >= self.takeoff_alt - 0.1 {
            self.set_mode(FlightMode::Hold);
        }
    }

    fn for_us(target_system: u8, target_component: u8, id: u8) -> bool {
        (target_system == 0 || target_system == id)
            && (target_component == 0 || target_component == COMPONENT_ID)
    }

    /// Handles one message received at wall time `now`; returns the replies for its sender.
    pub fn handle(&mut self, now: f64, msg: &MavMessage) -> Vec<MavMessage> {
        self.advance(now);
        let id = self.config.id;
        match msg {
            MavMessage::COMMAND_LONG(c)
                if Self::for_us(c.target_system, c.target_component, id) =>
            {
                self.command(now, c)
            }
            MavMessage::PARAM_REQUEST_LIST(p)
                if Self::for_us(p.target_system, p.target_component, id) =>
            {
                (0..self.params.len())
                    .map(|i| self.param_value(i))
                    .collect()
            }
            MavMessage::PARAM_REQUEST_READ(p)
                if Self::for_us(p.target_system, p.target_component, id) =>
            {
                let index = if p.param_index >= 0 {
                    usize::try_from(p.param_index)
                        .ok()
                        .filter(|&i| i < self.params.len())
                } else {
                    let name = p.param_id.to_str().unwrap_or("");
                    self.params.iter().position(|q| q.name == name)
                };
                index.map(|i| self.param_value(i)).into_iter().collect()
            }
            MavMessage::PARAM_SET(p) if Self::for_us(p.target_system, p.target_component, id) => {
                self.param_set(p)
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(s)
                if Self::for_us(s.target_system, s.target_component, id) =>
            {
                self.setpoint(now, s);
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    fn param_value(&self, index: usize) -> MavMessage {
        let p = self.params[index];
        MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: p.value,
            param_count: self.params.len() as u16,
            param_index: index as u16,
            param_id: p.name.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })
    }

    fn param_set(&mut self, p: &PARAM_SET_DATA) -> Vec<MavMessage> {
        let name = p.param_id.to_str().unwrap_or("");
        let Some(i) = self.params.iter().position(|q| q.name == name) else {
            self.counters.rejected_params += 1;
            return Vec::new();
        };
        let q = &mut self.params[i];
        if p.param_value.is_finite() && (q.min..=q.max).contains(&p.param_value) {
            q.value = p.param_value;
        } else {
            self.counters.rejected_params += 1;
        }
        // PX4 answers with the value in force, changed or not.
        vec![self.param_value(i)]
    }

    fn setpoint(&mut self, now: f64, s: &SET_POSITION_TARGET_LOCAL_NED_DATA) {
        match Setpoint::from_message(s) {
            Some(sp) => {
                self.setpoint = Some(sp);
                self.last_setpoint = Some(now);
            }
            None => self.counters.rejected_setpoints += 1,
        }
    }

    fn ack(&mut self, command: MavCmd, result: MavResult) -> MavMessage {
        if result != MavResult::MAV_RESULT_ACCEPTED {
            self.counters.refused_commands += 1;
        }
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA { command, result })
    }

    fn command(&mut self, now: f64, c: &COMMAND_LONG_DATA) -> Vec<MavMessage> {
        use MavResult::{MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED};
        let mut extra = Vec::new();
        let result = match c.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => self.arm_disarm(c.param1, c.param2),
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                let alt = if c.param7.is_nan() {
                    self.param("MIS_TAKEOFF_ALT").map(f64::from)
                } else if c.param7.is_finite() {
                    // PX4: param7 is the altitude AMSL.
                    Some(f64::from(c.param7) - self.config.origin.alt_m)
                } else {
                    None
                };
                match alt {
                    Some(a) if self.armed && a > 0.0 && a < 10_000.0 => {
                        self.set_mode(FlightMode::Takeoff);
                        self.takeoff_alt = a;
                        MAV_RESULT_ACCEPTED
                    }
                    _ => MAV_RESULT_DENIED,
                }
            }
            MavCmd::MAV_CMD_NAV_LAND => {
                if self.armed {
                    self.set_mode(FlightMode::Land);
                    MAV_RESULT_ACCEPTED
                } else {
                    MAV_RESULT_DENIED
                }
            }
            MavCmd::MAV_CMD_DO_SET_MODE => self.do_set_mode(now, c),
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                self.set_message_interval(now, c.param1, c.param2)
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                match (c.param1.is_finite() && c.param1 >= 0.0)
                    .then(|| self.message(c.param1 as u32))
                    .flatten()
                {
                    Some(m) => {
                        extra.push(m);
                        MAV_RESULT_ACCEPTED
                    }
                    None => MAV_RESULT_DENIED,
                }
            }
            _ => MAV_RESULT_UNSUPPORTED,
        };
        let mut out = vec![self.ack(c.command, result)];
        out.extend(extra);
        out
    }

    fn arm_disarm(&mut self, p1: f32, p2: f32) -> MavResult {
        const FORCE: f32 = 21196.0;
        if p1 == 1.0 {
            if self.armed || self.on_ground() {
                if !self.armed {
                    self.armed = true;
                    self.set_mode(self.mode);
                }
                MavResult::MAV_RESULT_ACCEPTED
            } else {
                MavResult::MAV_RESULT_DENIED
            }
        } else if p1 == 0.0 {
            if !self.armed || self.on_ground() || p2 == FORCE {
                self.armed = false;
                if !self.on_ground() {
                    // Forced disarm in the air: the point mass falls to the ground.
                    self.state.position.z = 0.0;
                }
                self.state.velocity = Vector3::zeros();
                if matches!(self.mode, FlightMode::Offboard | FlightMode::Takeoff) {
                    self.set_mode(FlightMode::Hold);
                }
                MavResult::MAV_RESULT_ACCEPTED
            } else {
                MavResult::MAV_RESULT_DENIED
            }
        } else {
            MavResult::MAV_RESULT_DENIED
        }
    }

    fn do_set_mode(&mut self, now: f64, c: &COMMAND_LONG_DATA) -> MavResult {
        let mode = match FlightMode::from_set_mode_params(c.param1, c.param2, c.param3) {
            Ok(mode) => mode,
            Err(SetModeError::Malformed) => return MavResult::MAV_RESULT_DENIED,
            Err(SetModeError::NotCustom | SetModeError::Unknown) => {
                return MavResult::MAV_RESULT_UNSUPPORTED;
            }
        };
        match mode {
            FlightMode::Offboard if !self.setpoints_fresh(now) => MavResult::MAV_RESULT_DENIED,
            FlightMode::Takeoff if !self.armed => MavResult::MAV_RESULT_DENIED,
            FlightMode::Takeoff => {
                self.takeoff_alt = f64::from(self.param("MIS_TAKEOFF_ALT").unwrap_or(2.5));
                self.set_mode(mode);
                MavResult::MAV_RESULT_ACCEPTED
            }
            _ => {
                self.set_mode(mode);
                MavResult::MAV_RESULT_ACCEPTED
            }
        }
    }

    fn set_message_interval(&mut self, now: f64, id: f32, interval_us: f32) -> MavResult {
        if !(id.is_finite() && interval_us.is_finite() && id >= 0.0) {
            return MavResult::MAV_RESULT_DENIED;
        }
        let Some(s) = self.streams.iter_mut().find(|s| s.id == id as u32) else {
            return MavResult::MAV_RESULT_DENIED;
        };
        s.interval = if interval_us == -1.0 {
            None
        } else if interval_us == 0.0 {
            Some(s.default_interval)
        } else if interval_us >= 1_000.0 {
            Some(f64::from(interval_us) * 1e-6)
        } else {
            return MavResult::MAV_RESULT_DENIED;
        };
        s.next_due = now;
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// Stream interval of a message id (s), `None` when disabled or not streamed.
    pub fn stream_interval(&self, id: u32) -> Option<f64> {
        self.streams
            .iter()
            .find(|s| s.id == id)
            .and_then(|s| s.interval)
    }

    /// Telemetry due at wall time `now` (advances the flight first).
    pub fn telemetry(&mut self, now: f64) -> Vec<MavMessage> {
        self.advance(now);
        let mut due = Vec::new();
        for s in &mut self.streams {
            if let Some(iv) = s.interval {
                if now >= s.next_due {
                    due.push(s.id);
                    // Keep the cadence, but never burst after a stall.
                    s.next_due = (s.next_due + iv).max(now);
                }
            }
        }
        due.into_iter().filter_map(|id| self.message(id)).collect()
    }

    fn time_boot_ms(&self) -> u32 {
        (self.sim_time * 1000.0) as u32
    }

    /// The current value of a message the vehicle can send, by id.
    pub fn message(&self, id: u32) -> Option<MavMessage> {
        let ned = enu_to_ned(&self.state.position);
        let vned = enu_to_ned(&self.state.velocity);
        let g = self.position();
        let home = self.config.origin;
        let deg7 = |d: f64| (d * 1e7).round() as i32;
        let mm = |m: f64| (m * 1000.0).round() as i32;
        let cms = |v: f64| (v * 100.0).round().clamp(-32768.0, 32767.0) as i16;
        let hdg_cdeg = (self.yaw.to_degrees().rem_euclid(360.0) * 100.0) as u16 % 36000;
        Some(match id {
            HEARTBEAT_DATA::ID => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: self.mode.px4_custom_mode(),
                mavtype: self.config.airframe.mav_type(),
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                base_mode: base_mode(self.armed),
                system_status: if self.armed {
                    MavState::MAV_STATE_ACTIVE
                } else {
                    MavState::MAV_STATE_STANDBY
                },
                mavlink_version: 3,
            }),
            GLOBAL_POSITION_INT_DATA::ID => {
                MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    lat: deg7(g.lat_deg),
                    lon: deg7(g.lon_deg),
                    alt: mm(g.alt_m),
                    relative_alt: mm(self.state.position.z),
                    vx: cms(vned.x),
                    vy: cms(vned.y),
                    vz: cms(vned.z),
                    hdg: hdg_cdeg,
                })
            }
            LOCAL_POSITION_NED_DATA::ID => {
                MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    x: ned.x as f32,
                    y: ned.y as f32,
                    z: ned.z as f32,
                    vx: vned.x as f32,
                    vy: vned.y as f32,
                    vz: vned.z as f32,
                })
            }
            ATTITUDE_DATA::ID => {
                let [roll, pitch, yaw] = self.attitude();
                MavMessage::ATTITUDE(ATTITUDE_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    roll: roll as f32,
                    pitch: pitch as f32,
                    yaw: yaw as f32,
                    rollspeed: 0.0,
                    pitchspeed: 0.0,
                    yawspeed: 0.0,
                })
            }
            SYS_STATUS_DATA::ID => {
                use MavSysStatusSensor as S;
                let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
                    | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
                    | S::MAV_SYS_STATUS_SENSOR_3D_MAG
                    | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                    | S::MAV_SYS_STATUS_SENSOR_GPS
                    | S::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
                    | S::MAV_SYS_STATUS_SENSOR_YAW_POSITION
                    | S::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                    | S::MAV_SYS_STATUS_AHRS
                    | S::MAV_SYS_STATUS_SENSOR_BATTERY
                    | S::MAV_SYS_STATUS_PREARM_CHECK;
                MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                    onboard_control_sensors_present: sensors,
                    onboard_control_sensors_enabled: sensors,
                    onboard_control_sensors_health: sensors,
                    load: 100,
                    voltage_battery: self.voltage_mv(),
                    current_battery: if self.armed { 1000 } else { 50 },
                    drop_rate_comm: 0,
                    errors_comm: 0,
                    errors_count1: 0,
                    errors_count2: 0,
                    errors_count3: 0,
                    errors_count4: 0,
                    battery_remaining: self.battery_percent(),
                })
            }
            EXTENDED_SYS_STATE_DATA::ID => {
                MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                    vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                    landed_state: self.landed_state(),
                })
            }
            GPS_RAW_INT_DATA::ID => MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: (self.sim_time * 1e6) as u64,
                lat: deg7(g.lat_deg),
                lon: deg7(g.lon_deg),
                alt: mm(g.alt_m),
                eph: 80,
                epv: 120,
                vel: (self.state.horizontal_velocity().norm() * 100.0).round() as u16,
                cog: hdg_cdeg,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 12,
            }),
            HOME_POSITION_DATA::ID => MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: deg7(home.lat_deg),
                longitude: deg7(home.lon_deg),
                altitude: mm(home.alt_m),
                x: 0.0,
                y: 0.0,
                z: 0.0,
                q: [1.0, 0.0, 0.0, 0.0],
                approach_x: 0.0,
                approach_y: 0.0,
                approach_z: 0.0,
            }),
            BATTERY_STATUS_DATA::ID => {
                let mut voltages = [u16::MAX; 10];
                voltages[0] = self.voltage_mv();
                MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                    current_consumed: ((1.0 - self.battery) * 5000.0) as i32,
                    energy_consumed: -1,
                    temperature: i16::MAX,
                    voltages,
                    current_battery: if self.armed { 1000 } else { 50 },
                    id: 0,
                    battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                    mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                    battery_remaining: self.battery_percent(),
                })
            }
            AUTOPILOT_VERSION_DATA::ID => MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
                capabilities: MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED,
                uid: u64::from(self.config.id),
                // PX4 encoding: major.minor.patch.type (0xFF = release).
                flight_sw_version: (1 << 24) | (15 << 16) | 0xFF,
                middleware_sw_version: 0,
                os_sw_version: 0,
                board_version: 0,
                vendor_id: 0,
                product_id: 0,
                flight_custom_version: [0; 8],
                middleware_custom_version: [0; 8],
                os_custom_version: [0; 8],
            }),
            _ => return None,
        })
    }

    fn battery_percent(&self) -> i8 {
        (self.battery * 100.0).round() as i8
    }

    fn voltage_mv(&self) -> u16 {
        (14_800.0 + 2_000.0 * self.battery) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::command::command_long;
    use mavlink::dialects::common::{
        MavFrame, MavModeFlag, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA,
        PositionTargetTypemask,
    };

    fn cmd(command: MavCmd, p: [f32; 7]) -> MavMessage {
        command_long(1, command, p)
    }

    fn ack_of(replies: &[MavMessage]) -> MavResult {
        match replies.first() {
            Some(MavMessage::COMMAND_ACK(a)) => a.result,
            other => panic!("no COMMAND_ACK: {other:?}"),
        }
    }

    fn velocity_sp(vn: f32, ve: f32, vd: f32) -> MavMessage {
        use PositionTargetTypemask as M;
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            vx: vn,
            vy: ve,
            vz: vd,
            type_mask: M::from_bits_truncate(0b0000_1101_1100_0111),
            target_system: 1,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
        })
    }

    const CUSTOM: f32 = 1.0; // MAV_MODE_FLAG_CUSTOM_MODE_ENABLED

    fn run(v: &mut Vehicle, from: f64, to: f64) {
        let mut t = from;
        while t < to {
            t += 0.05;
            v.advance(t);
        }
    }

    fn airborne(airframe: Airframe) -> Vehicle {
        let mut v = Vehicle::new(
            VehicleConfig {
                airframe,
                ..VehicleConfig::new(1)
            },
            0.0,
        );
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                [1.0, 0., 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_NAV_TAKEOFF,
                [0., 0., 0., f32::NAN, f32::NAN, f32::NAN, f32::NAN],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(v.mode(), FlightMode::Takeoff);
        run(&mut v, 0.0, 10.0);
        v
    }

    #[test]
    fn arm_takeoff_to_mis_takeoff_alt_then_hold() {
        let v = airborne(Airframe::Multirotor);
        assert_eq!(v.mode(), FlightMode::Hold);
        assert!((v.state().position.z - 2.5).abs() < 0.2, "{:?}", v.state());
        assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_IN_AIR);
    }

    #[test]
    fn commands_are_refused_when_they_do_not_apply() {
        let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
        let nan = [f32::NAN; 7];
        // Takeoff and land need the motors armed.
        assert_eq!(
            ack_of(&v.handle(0.0, &cmd(MavCmd::MAV_CMD_NAV_TAKEOFF, nan))),
            MavResult::MAV_RESULT_DENIED
        );
        assert_eq!(
            ack_of(&v.handle(0.0, &cmd(MavCmd::MAV_CMD_NAV_LAND, nan))),
            MavResult::MAV_RESULT_DENIED
        );
        // Commands the simulator does not implement.
        let r = v.handle(0.0, &cmd(MavCmd::MAV_CMD_DO_REPOSITION, [0.0; 7]));
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_UNSUPPORTED);
        // Arm with a NaN parameter.
        let r = v.handle(0.0, &cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, nan));
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
        assert!(!v.armed());
        assert_eq!(v.counters().refused_commands, 4);
        // Commands for another system are ignored.
        let mut other = cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7]);
        if let MavMessage::COMMAND_LONG(c) = &mut other {
            c.target_system = 9;
        }
        assert!(v.handle(0.0, &other).is_empty());
    }

    #[test]
    fn disarm_in_flight_needs_force() {
        let mut v = airborne(Airframe::Multirotor);
        let r = v.handle(10.0, &cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]));
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
        assert!(v.armed());
        let r = v.handle(
            10.0,
            &cmd(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                [0.0, 21196.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert!(!v.armed());
    }

    #[test]
    fn do_set_mode_follows_px4_modes() {
        let mut v = airborne(Airframe::Multirotor);
        let r = v.handle(
            10.0,
            &cmd(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [CUSTOM, 3.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(v.mode(), FlightMode::Position);
        let hb = v.message(HEARTBEAT_DATA::ID);
        let Some(MavMessage::HEARTBEAT(hb)) = hb else {
            panic!()
        };
        assert_eq!(hb.custom_mode, 3 << 16);
        assert!(hb.base_mode.contains(
            MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        ));
        // MISSION is not simulated; a mode without the custom flag is not understood.
        let r = v.handle(
            10.0,
            &cmd(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [CUSTOM, 4.0, 4.0, 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_UNSUPPORTED);
        let r = v.handle(
            10.0,
            &cmd(MavCmd::MAV_CMD_DO_SET_MODE, [0.0, 4.0, 3.0, 0., 0., 0., 0.]),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_UNSUPPORTED);
        assert_eq!(v.mode(), FlightMode::Position);
        // Land: descends, touches down, disarms.
        let r = v.handle(
            10.0,
            &cmd(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [CUSTOM, 4.0, 6.0, 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_LANDING);
        run(&mut v, 10.0, 20.0);
        assert!(!v.armed());
        assert_eq!(v.state().position.z, 0.0);
        assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_ON_GROUND);
    }

    #[test]
    fn offboard_needs_setpoints_and_times_out_to_hold() {
        let mut v = airborne(Airframe::Multirotor);
        let offboard = cmd(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [CUSTOM, 6.0, 0., 0., 0., 0., 0.],
        );
        assert_eq!(
            ack_of(&v.handle(10.0, &offboard)),
            MavResult::MAV_RESULT_DENIED
        );
        assert_eq!(v.mode(), FlightMode::Hold);
        // Stream 2 m/s north.
        v.handle(10.0, &velocity_sp(2.0, 0.0, 0.0));
        assert_eq!(
            ack_of(&v.handle(10.1, &offboard)),
            MavResult::MAV_RESULT_ACCEPTED
        );
        assert_eq!(v.mode(), FlightMode::Offboard);
        let x0 = v.state().position;
        let mut t = 10.1;
        while t < 15.0 {
            t += 0.1;
            v.handle(t, &velocity_sp(2.0, 0.0, 0.0));
        }
        let d = v.state().position - x0;
        assert!(d.y > 7.0 && d.x.abs() < 0.1 && d.z.abs() < 0.1, "{d:?}"); // ENU: north is y
        // NaN setpoints are ignored and counted; they do not keep offboard alive.
        v.handle(15.2, &velocity_sp(f32::NAN, 0.0, 0.0));
        assert_eq!(v.counters().rejected_setpoints, 1);
        v.advance(15.45);
        assert_eq!(v.mode(), FlightMode::Offboard);
        v.advance(15.7);
        assert_eq!(v.mode(), FlightMode::Hold);
        // Hold brakes to a stop.
        let p0 = v.state().position;
        run(&mut v, 15.7, 19.7);
        assert!(v.state().velocity.norm() < 0.2, "{:?}", v.state());
        assert!((v.state().position - p0).norm() < 2.0, "{:?}", v.state());
    }

    #[test]
    fn position_setpoints_are_flown() {
        use PositionTargetTypemask as M;
        let mut v = airborne(Airframe::Multirotor);
        let sp = MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: 10.0,
            y: -5.0,
            z: -8.0,
            type_mask: M::from_bits_truncate(0b0000_1101_1111_1000),
            target_system: 1,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
        });
        v.handle(10.0, &sp);
        let r = v.handle(
            10.0,
            &cmd(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [CUSTOM, 6.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        let mut t = 10.0;
        while t < 30.0 {
            t += 0.1;
            v.handle(t, &sp);
        }
        let p = v.state().position;
        assert!((p - Vector3::new(-5.0, 10.0, 8.0)).norm() < 0.3, "{p:?}");
    }

    #[test]
    fn fixed_wing_keeps_flying_in_hold() {
        let mut v = airborne(Airframe::FixedWing);
        run(&mut v, 10.0, 60.0);
        let s = v.state();
        assert!(s.horizontal_velocity().norm() >= 12.0 - 1e-9);
        assert!(s.horizontal_position().norm() < 200.0, "{s:?}");
        assert!((s.position.z - 2.5).abs() < 1.0);
        let Some(MavMessage::HEARTBEAT(hb)) = v.message(HEARTBEAT_DATA::ID) else {
            panic!()
        };
        assert_eq!(hb.mavtype, MavType::MAV_TYPE_FIXED_WING);
    }

    #[test]
    fn parameters_list_read_set() {
        let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
        let list = v.handle(
            0.0,
            &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
            }),
        );
        assert_eq!(list.len(), 3);
        let read = |v: &mut Vehicle, name: &str| {
            v.handle(
                0.0,
                &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                    param_index: -1,
                    target_system: 1,
                    target_component: 1,
                    param_id: name.into(),
                }),
            )
        };
        let r = read(&mut v, "MIS_TAKEOFF_ALT");
        let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
            panic!("{r:?}")
        };
        assert_eq!(p.param_value, 2.5);
        assert!(read(&mut v, "NO_SUCH").is_empty());
        let set = |v: &mut Vehicle, name: &str, value: f32| {
            v.handle(
                0.0,
                &MavMessage::PARAM_SET(PARAM_SET_DATA {
                    param_value: value,
                    target_system: 1,
                    target_component: 1,
                    param_id: name.into(),
                    param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
                }),
            )
        };
        let r = set(&mut v, "MIS_TAKEOFF_ALT", 5.0);
        let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
            panic!("{r:?}")
        };
        assert_eq!(p.param_value, 5.0);
        for bad in [f32::NAN, -1.0, 1e6] {
            let r = set(&mut v, "MIS_TAKEOFF_ALT", bad);
            let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
                panic!("{r:?}")
            };
            assert_eq!(p.param_value, 5.0);
        }
        assert!(set(&mut v, "NO_SUCH", 1.0).is_empty());
        assert_eq!(v.counters().rejected_params, 4);
        assert_eq!(v.param("MIS_TAKEOFF_ALT"), Some(5.0));
    }

    #[test]
    fn message_intervals_and_requests() {
        let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
        let all = v.telemetry(0.0);
        assert_eq!(all.len(), STREAMS.len());
        let id = GLOBAL_POSITION_INT_DATA::ID as f32;
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                [id, 50_000.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        let iv = v.stream_interval(GLOBAL_POSITION_INT_DATA::ID);
        assert!(iv.is_some_and(|iv| (iv - 0.05).abs() < 1e-9), "{iv:?}");
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                [id, -1.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(v.stream_interval(GLOBAL_POSITION_INT_DATA::ID), None);
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                [id, 0.0, 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(v.stream_interval(GLOBAL_POSITION_INT_DATA::ID), Some(0.1));
        for bad in [[id, 10.0], [id, f32::NAN], [9999.0, 1e5], [f32::NAN, 1e5]] {
            let r = v.handle(
                0.0,
                &cmd(
                    MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                    [bad[0], bad[1], 0., 0., 0., 0., 0.],
                ),
            );
            assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
        }
        // 0.95 s of telemetry at the default rates: 10 Hz position, 1 Hz heartbeat.
        let mut count = std::collections::HashMap::<u32, usize>::new();
        let mut t = 0.0;
        while t < 0.95 {
            t += 0.01;
            for m in v.telemetry(t) {
                *count.entry(mavlink::Message::message_id(&m)).or_default() += 1;
            }
        }
        assert_eq!(count.get(&LOCAL_POSITION_NED_DATA::ID), Some(&9));
        assert_eq!(count.get(&HEARTBEAT_DATA::ID), None);
        for (msg, expect) in [
            (AUTOPILOT_VERSION_DATA::ID, true),
            (HOME_POSITION_DATA::ID, true),
            (12_345, false),
        ] {
            let r = v.handle(
                1.0,
                &cmd(
                    MavCmd::MAV_CMD_REQUEST_MESSAGE,
                    [msg as f32, 0., 0., 0., 0., 0., 0.],
                ),
            );
            assert_eq!(r.len(), if expect { 2 } else { 1 });
            assert_eq!(ack_of(&r) == MavResult::MAV_RESULT_ACCEPTED, expect);
        }
    }

    #[test]
    fn telemetry_is_consistent_with_the_state() {
        let mut v = airborne(Airframe::Multirotor);
        let Some(MavMessage::GLOBAL_POSITION_INT(g)) = v.message(GLOBAL_POSITION_INT_DATA::ID)
        else {
            panic!()
        };
        assert!((g.relative_alt - 2500).abs() < 200);
        assert!((f64::from(g.alt) - 490_500.0).abs() < 200.0);
        let Some(MavMessage::LOCAL_POSITION_NED(l)) = v.message(LOCAL_POSITION_NED_DATA::ID) else {
            panic!()
        };
        assert!((l.z + 2.5).abs() < 0.2);
        assert!(v.handle(10.0, &velocity_sp(0.0, 0.0, 0.0)).is_empty());
    }
}
