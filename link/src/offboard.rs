//! The launch of a vehicle under the ground station's control as a pure state machine, in the
//! sequence its autopilot documents:
//!
//! - **PX4** (multirotor and fixed wing): arm → take off (`NAV_TAKEOFF`, param7 AMSL) → stream
//!   velocity setpoints → switch to OFFBOARD (PX4 refuses the switch until setpoints arrive) →
//!   keep streaming. A multirotor is switched at once (its setpoints lift it off); a fixed wing
//!   only once its takeoff has climbed (OFFBOARD would end the launch on the ground).
//! - **ArduCopter**: GUIDED → arm → take off (`NAV_TAKEOFF`, param7 the height above home;
//!   "must be armed in GUIDED", Copter Commands in Guided Mode) → wait until it is up (a target
//!   sent during the takeoff would replace it) → stream velocity targets
//!   (SET_POSITION_TARGET_LOCAL_NED, the same type mask).
//! - **ArduPlane**: arm → TAKEOFF mode (it climbs to TKOFF_ALT, then loiters; a plain fixed
//!   wing takes off no other way, NAV_TAKEOFF being for QuadPlanes) → once up, GUIDED →
//!   steer with `MAV_CMD_GUIDED_CHANGE_HEADING` (course over ground), `_SPEED` (airspeed) and
//!   `_ALTITUDE` (ArduPlane reads only the altitude of a SET_POSITION_TARGET_*: "Plane Commands
//!   in Guided Mode", `GCS_MAVLINK_Plane::handle_set_position_target_global_int`), at most every
//!   [`OffboardConfig::plane_interval_s`].
//!
//! **Mode authority.** The sequence asks for its mode once; it never takes the vehicle back.
//! A change of mode or arming it did not command (a router client's command, the RC mode switch,
//! the autopilot's failsafe, a landing, a disarm) ends it with [`OffboardError::Overridden`]:
//! once its guided mode was acknowledged (or found in force), any HEARTBEAT newer than that in
//! another mode; during the launch, a mode outside the launch's own (the one the vehicle was
//! found in, the guided mode, the takeoff mode and the hold a PX4 takeoff ends in); and, once
//! armed, a disarm. This is PX4's own rule (a vehicle switched out of OFFBOARD stays out until
//! commanded again; MAVSDK's Offboard plugin stops) and ArduPilot's (the pilot's mode switch
//! always wins over GUIDED).
//!
//! No sockets and no clock inside: the caller passes its time, what it knows of the vehicle
//! ([`VehicleStatus`], from HEARTBEATs, and its height above home) and where to fly
//! ([`Steer`]) to [`OffboardSequence::next`], sends what comes back, and feeds the vehicle's
//! replies (COMMAND_ACKs) to [`OffboardSequence::handle`]. Commands wait for their
//! acknowledgement and are re-sent (with `confirmation` + 1) after
//! [`OffboardConfig::ack_timeout_s`]. A caller whose link answers at once (the simulator's
//! `record`) may call `next` again at the same time after feeding the replies: each command is
//! sent once per acknowledgement and at most one setpoint per distinct time, so the whole launch
//! can happen within one tick.

use mavlink::dialects::common::{MavCmd, MavMessage, MavResult};
use nalgebra::Vector3;

use crate::ardupilot::PlaneMode;
use crate::autopilot::{Autopilot, Frame, Mode, Personality, VehicleStatus};
use crate::command::{
    Setpoint, arm, guided_altitude, guided_heading, guided_speed, set_mode, takeoff,
    takeoff_relative,
};
use crate::px4::FlightMode;

/// Takeoff height above home (m) an ArduCopter is sent to when none is given (PX4's
/// MIS_TAKEOFF_ALT default; ArduCopter's NAV_TAKEOFF has no default of its own).
pub const DEFAULT_TAKEOFF_HEIGHT_M: f32 = 2.5;

/// Settings of an [`OffboardSequence`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffboardConfig {
    /// Takeoff height above home (m); `None`: the vehicle's own (PX4 `MIS_TAKEOFF_ALT`,
    /// ArduPlane `TKOFF_ALT`; ArduCopter [`DEFAULT_TAKEOFF_HEIGHT_M`]). An ArduPlane is switched
    /// to GUIDED once at 90 % of it: keep it at or below its TKOFF_ALT (50 m by default).
    pub takeoff_height_m: Option<f32>,
    /// Home altitude AMSL (m), for PX4's NAV_TAKEOFF (param7 is AMSL); unknown: the vehicle's
    /// MIS_TAKEOFF_ALT.
    pub home_amsl_m: Option<f32>,
    /// Setpoints sent before OFFBOARD is requested (at least 1; PX4).
    pub setpoints_before_switch: u32,
    /// Time without a COMMAND_ACK after which a command is sent again (s, the caller's clock).
    pub ack_timeout_s: f64,
    /// Sends of one command before the sequence gives up.
    pub max_attempts: u32,
    /// Shortest time between two ArduPlane steering updates (s).
    pub plane_interval_s: f64,
    /// Largest lateral acceleration an ArduPlane turns with (m/s²; its bank angle is
    /// `atan(a / g)`, within ROLL_LIMIT_DEG).
    pub plane_lateral_accel_m_s2: f32,
}

impl OffboardConfig {
    /// Takeoff to `takeoff_height_m` above a home at `home_amsl_m`, OFFBOARD after the first
    /// setpoint, 1 s acknowledgement timeout, 3 attempts per command, ArduPlane steered at 4 Hz
    /// with up to 1 g (45° of bank).
    pub fn new(takeoff_height_m: Option<f32>, home_amsl_m: Option<f32>) -> Self {
        Self {
            takeoff_height_m,
            home_amsl_m,
            setpoints_before_switch: 1,
            ack_timeout_s: 1.0,
            max_attempts: 3,
            plane_interval_s: 0.25,
            plane_lateral_accel_m_s2: 9.81,
        }
    }
}

/// Where to fly, once airborne.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steer {
    /// Velocity (ENU, m/s). PX4 and ArduCopter fly it; an ArduPlane its horizontal course and
    /// speed.
    pub velocity: Vector3<f64>,
    /// Altitude AMSL (m) an ArduPlane holds (it takes no vertical speed); `None`: its own.
    pub altitude_amsl_m: Option<f64>,
}

impl Steer {
    /// Fly `velocity`, no altitude goal.
    pub fn velocity(velocity: Vector3<f64>) -> Self {
        Self {
            velocity,
            altitude_amsl_m: None,
        }
    }

    fn is_finite(&self) -> bool {
        self.velocity.iter().all(|x| x.is_finite())
            && self.altitude_amsl_m.is_none_or(f64::is_finite)
    }
}

/// Where the sequence is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Switching to GUIDED (ArduCopter) and arming (skipped if the vehicle is already flying).
    Arming,
    /// Waiting for the takeoff command's (or ArduPlane's TAKEOFF mode's) acknowledgement.
    TakingOff,
    /// ArduPilot, and a PX4 fixed wing: climbing, waiting to be up before the first target.
    Climbing,
    /// Streaming setpoints (PX4 OFFBOARD) or targets (ArduPilot GUIDED); the mode requested
    /// until acknowledged, never again after.
    Offboard,
}

/// Why the sequence stopped.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum OffboardError {
    /// The vehicle refused a command.
    #[error("{command:?} refused: {result:?}")]
    Refused {
        /// The command.
        command: MavCmd,
        /// The vehicle's answer.
        result: MavResult,
    },
    /// A command went unacknowledged.
    #[error("{command:?} not acknowledged after {attempts} attempts")]
    NoAck {
        /// The command.
        command: MavCmd,
        /// How often it was sent.
        attempts: u32,
    },
    /// Someone else took the vehicle: a change of mode or arming the sequence did not command.
    #[error("{0}")]
    Overridden(Override),
}

/// A change of a vehicle's mode or arming that its ground station did not command (see the
/// module documentation): the vehicle is someone else's now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Override {
    /// The mode it was last seen in (`None`: not in its table, or not seen yet).
    pub from: Option<Mode>,
    /// The mode it is in now (`None`: not in its table).
    pub to: Option<Mode>,
    /// Whether it was disarmed.
    pub disarmed: bool,
    /// When the HEARTBEAT that showed it was observed (the caller's clock).
    pub at: f64,
}

impl std::fmt::Display for Override {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = |m: Option<Mode>| m.map_or("an unknown mode", Mode::name);
        if self.disarmed {
            write!(f, "disarmed by no command of ours (in {})", name(self.to))
        } else {
            write!(
                f,
                "mode changed by no command of ours: {} -> {}",
                name(self.from),
                name(self.to)
            )
        }
    }
}

impl Override {
    /// The override `status` shows, if any, for a vehicle last seen in `from`: a mode `allowed`
    /// rejects, or a disarm when `armed_since` says it was armed before `status` was observed.
    pub fn of(
        status: &VehicleStatus,
        from: Option<Mode>,
        armed_since: Option<f64>,
        allowed: impl Fn(Option<Mode>) -> bool,
    ) -> Option<Self> {
        let disarmed = !status.armed && armed_since.is_some_and(|t| status.at > t);
        (disarmed || !allowed(status.mode)).then_some(Self {
            from,
            to: status.mode,
            disarmed,
            at: status.at,
        })
    }
}

/// A command waiting for its acknowledgement.
#[derive(Debug, Clone, PartialEq)]
struct Pending {
    message: MavMessage,
    command: MavCmd,
    sent_at: f64,
    attempts: u32,
}

/// The launch-and-offboard sequence of one vehicle (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct OffboardSequence {
    target: u8,
    personality: Personality,
    config: OffboardConfig,
    phase: Phase,
    pending: Option<Pending>,
    setpoints: u32,
    last_setpoint_at: Option<f64>,
    /// When the guided mode was acknowledged (or found in force): from then on, every newer
    /// status must show it.
    switched_at: Option<f64>,
    /// ArduCopter: GUIDED was acknowledged before arming.
    guided_before_arming: bool,
    /// When the vehicle was known armed (the arming acknowledged, or found armed): a newer
    /// disarmed status is an override.
    armed_at: Option<f64>,
    /// The mode the vehicle was in when the sequence first saw it (`Some(None)`: one its
    /// table lacks).
    initial: Option<Option<Mode>>,
    /// The mode of the last status seen.
    last_mode: Option<Mode>,
}

impl OffboardSequence {
    /// The sequence for vehicle (system id) `target` of `personality`, not started.
    pub fn new(target: u8, personality: Personality, config: OffboardConfig) -> Self {
        Self {
            target,
            personality,
            config,
            phase: Phase::Arming,
            pending: None,
            setpoints: 0,
            last_setpoint_at: None,
            switched_at: None,
            guided_before_arming: false,
            armed_at: None,
            initial: None,
            last_mode: None,
        }
    }

    /// The vehicle it flies.
    pub fn target(&self) -> u8 {
        self.target
    }

    /// The personality it flies it as.
    pub fn personality(&self) -> Personality {
        self.personality
    }

    /// Where the sequence is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    fn takeoff_height(&self) -> f32 {
        self.config
            .takeoff_height_m
            .unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M)
    }

    /// The messages to send at `now`, given the vehicle's `status`, its height above home
    /// (`None`: unknown) and where to fly once airborne (`None` or non-finite: nothing sent
    /// beyond the launch, and no mode request).
    pub fn next(
        &mut self,
        now: f64,
        status: &VehicleStatus,
        height_m: Option<f64>,
        steer: Option<Steer>,
    ) -> Result<Vec<MavMessage>, OffboardError> {
        self.authority(status)?;
        let mut out = Vec::new();
        self.resend(now, &mut out)?;
        let idle = self.pending.is_none();
        let ardupilot = self.personality.autopilot == Autopilot::ArduPilot;
        let airborne = height_m.is_none_or(|h| h > 1.0);
        let px4_multirotor = self.personality == Personality::PX4_MULTIROTOR;
        match self.phase {
            Phase::Arming if idle && status.armed && (px4_multirotor || airborne) => {
                self.phase = Phase::Offboard;
                self.armed_at = Some(status.at);
            }
            Phase::Arming if idle => self.arm_step(now, status, &mut out),
            Phase::TakingOff if idle => {
                let m = match (self.personality.autopilot, self.personality.frame) {
                    (Autopilot::Px4, _) => {
                        let amsl = self
                            .config
                            .home_amsl_m
                            .zip(self.config.takeoff_height_m)
                            .map(|(home, h)| home + h);
                        takeoff(self.target, amsl)
                    }
                    (Autopilot::ArduPilot, Frame::Multirotor) => {
                        takeoff_relative(self.target, self.takeoff_height())
                    }
                    (Autopilot::ArduPilot, Frame::FixedWing) => {
                        set_mode(self.target, Mode::Plane(PlaneMode::Takeoff))
                    }
                };
                self.send(now, m, &mut out);
            }
            Phase::Climbing => {
                let goal = self.config.takeoff_height_m.map_or(
                    if ardupilot && self.personality.frame == Frame::FixedWing {
                        // ArduPlane's TKOFF_ALT default.
                        50.0
                    } else {
                        // ArduCopter's takeoff default, PX4's MIS_TAKEOFF_ALT default.
                        f64::from(DEFAULT_TAKEOFF_HEIGHT_M)
                    },
                    f64::from,
                );
                if height_m.is_some_and(|h| h >= 0.9 * goal) {
                    self.phase = Phase::Offboard;
                }
            }
            _ => {}
        }
        if self.phase != Phase::Offboard {
            return Ok(out);
        }
        let Some(steer) = steer.filter(Steer::is_finite) else {
            return Ok(out);
        };
        let guided = self.personality.guided();
        let in_guided = status.mode == Some(guided);
        if in_guided && self.switched_at.is_none() {
            // Found in the guided mode (flying already): held to it from now on.
            self.switched_at = Some(status.at);
        }
        match (self.personality.autopilot, self.personality.frame) {
            (_, Frame::Multirotor) | (Autopilot::Px4, Frame::FixedWing) => {
                if self.last_setpoint_at != Some(now) {
                    out.push(Setpoint::Velocity(steer.velocity).to_message(self.target));
                    self.setpoints = self.setpoints.saturating_add(1);
                    self.last_setpoint_at = Some(now);
                }
            }
            (Autopilot::ArduPilot, Frame::FixedWing) => {
                let due = self
                    .last_setpoint_at
                    .is_none_or(|t| now - t >= self.config.plane_interval_s);
                if in_guided && due {
                    out.extend(self.plane_steering(&steer));
                    self.setpoints = self.setpoints.saturating_add(1);
                    self.last_setpoint_at = Some(now);
                }
            }
        }
        // Asked for until acknowledged, never after: a vehicle seen out of it since is someone
        // else's (`authority`).
        let ready = ardupilot || self.setpoints >= self.config.setpoints_before_switch.max(1);
        if self.pending.is_none() && self.switched_at.is_none() && ready {
            self.send(now, set_mode(self.target, guided), &mut out);
        }
        Ok(out)
    }

    /// Whether `status` shows someone else's change (see the module documentation): once the
    /// guided mode was acknowledged, another mode in a newer status; before, a mode outside the
    /// launch's; once armed, a disarm. Remembers the mode seen.
    fn authority(&mut self, status: &VehicleStatus) -> Result<(), OffboardError> {
        let initial = *self.initial.get_or_insert(status.mode);
        let guided = self.personality.guided();
        let launch = [
            initial,
            Some(guided),
            Some(self.personality.hold()),
            Some(Mode::Px4(FlightMode::Takeoff)),
            Some(Mode::Plane(PlaneMode::Takeoff)),
        ];
        let switched_at = self.switched_at;
        let allowed = |m: Option<Mode>| match switched_at {
            Some(t) if status.at > t => m == Some(guided),
            _ => launch.contains(&m),
        };
        let found = Override::of(status, self.last_mode, self.armed_at, allowed);
        self.last_mode = status.mode;
        found.map_or(Ok(()), |o| Err(OffboardError::Overridden(o)))
    }

    /// Re-sends the pending command once its acknowledgement is late; gives up after the last
    /// attempt.
    fn resend(&mut self, now: f64, out: &mut Vec<MavMessage>) -> Result<(), OffboardError> {
        let Some(p) = &mut self.pending else {
            return Ok(());
        };
        if now - p.sent_at < self.config.ack_timeout_s {
            return Ok(());
        }
        if p.attempts >= self.config.max_attempts {
            return Err(OffboardError::NoAck {
                command: p.command,
                attempts: p.attempts,
            });
        }
        if let MavMessage::COMMAND_LONG(c) = &mut p.message {
            c.confirmation = c.confirmation.saturating_add(1);
        }
        p.attempts += 1;
        p.sent_at = now;
        out.push(p.message.clone());
        Ok(())
    }

    /// The arming phase's next command: ArduCopter switches to GUIDED first (it takes off only
    /// there), then every autopilot arms.
    fn arm_step(&mut self, now: f64, status: &VehicleStatus, out: &mut Vec<MavMessage>) {
        let copter = self.personality == Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
        let guided = self.personality.guided();
        if copter && !self.guided_before_arming && status.mode != Some(guided) {
            self.send(now, set_mode(self.target, guided), out);
        } else {
            self.send(now, arm(self.target), out);
        }
    }

    /// ArduPlane's steering commands for `steer`: course and airspeed from the horizontal
    /// velocity, the altitude goal when there is one.
    fn plane_steering(&self, steer: &Steer) -> Vec<MavMessage> {
        let v = steer.velocity;
        // Course over ground, clockwise from north: ENU east is x, north y.
        let course = v.x.atan2(v.y).to_degrees().rem_euclid(360.0) as f32;
        let mut out = vec![
            guided_heading(self.target, course, self.config.plane_lateral_accel_m_s2),
            guided_speed(self.target, v.xy().norm() as f32),
        ];
        if let Some(alt) = steer.altitude_amsl_m {
            out.push(guided_altitude(self.target, alt as f32, 0.0));
        }
        out
    }

    /// Takes a message from the vehicle: a COMMAND_ACK of the pending command advances the
    /// sequence (or stops it, when the command was refused); anything else is ignored.
    pub fn handle(&mut self, now: f64, msg: &MavMessage) -> Result<(), OffboardError> {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return Ok(());
        };
        let Some(p) = self.pending.as_ref().filter(|p| p.command == ack.command) else {
            return Ok(());
        };
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => {}
            // Still working on it: wait for the final answer.
            MavResult::MAV_RESULT_IN_PROGRESS => return Ok(()),
            result => {
                return Err(OffboardError::Refused {
                    command: p.command,
                    result,
                });
            }
        }
        let switch_at_once = self.personality == Personality::PX4_MULTIROTOR;
        match (self.phase, p.command) {
            (Phase::Arming, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM) => {
                self.phase = Phase::TakingOff;
                self.armed_at = Some(now);
            }
            (Phase::Arming, _) => {
                // ArduCopter's GUIDED before arming: held to it from now on.
                self.guided_before_arming = true;
                self.switched_at = Some(now);
            }
            (Phase::TakingOff, _) if switch_at_once => self.phase = Phase::Offboard,
            (Phase::TakingOff, _) => self.phase = Phase::Climbing,
            _ => self.switched_at = Some(now),
        }
        self.pending = None;
        Ok(())
    }

    fn send(&mut self, now: f64, message: MavMessage, out: &mut Vec<MavMessage>) {
        let MavMessage::COMMAND_LONG(c) = &message else {
            return;
        };
        self.pending = Some(Pending {
            command: c.command,
            message: message.clone(),
            sent_at: now,
            attempts: 1,
        });
        out.push(message);
    }
}

#[cfg(test)]
mod tests;
