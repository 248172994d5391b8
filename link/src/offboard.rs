//! The offboard launch sequence of a PX4 vehicle as a pure state machine: arm → take off →
//! stream velocity setpoints → switch to OFFBOARD (PX4 refuses the switch until setpoints
//! arrive) → keep streaming, and ask for OFFBOARD again whenever the vehicle is seen out of it.
//!
//! No sockets and no clock inside: the caller passes its time and what it knows of the vehicle
//! ([`VehicleStatus`], from HEARTBEATs) to [`OffboardSequence::next`], sends what comes back, and
//! feeds the vehicle's replies (COMMAND_ACKs) to [`OffboardSequence::handle`]. Commands wait for
//! their acknowledgement and are re-sent (with `confirmation` + 1) after
//! [`OffboardConfig::ack_timeout_s`]. A caller whose link answers at once (the simulator's
//! `record`) may call `next` again at the same time after feeding the replies: each command is
//! sent once per acknowledgement and at most one setpoint per distinct time, so the whole launch
//! can happen within one tick.

use mavlink::dialects::common::{MavCmd, MavMessage, MavResult};
use nalgebra::Vector3;

use crate::command::{Setpoint, arm, set_mode, takeoff};
use crate::px4::{FlightMode, VehicleStatus};

/// Settings of an [`OffboardSequence`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffboardConfig {
    /// Takeoff altitude AMSL (m, NAV_TAKEOFF param7); `None`: the vehicle's `MIS_TAKEOFF_ALT`.
    pub takeoff_amsl_m: Option<f32>,
    /// Setpoints sent before OFFBOARD is requested (at least 1).
    pub setpoints_before_switch: u32,
    /// Time without a COMMAND_ACK after which a command is sent again (s, the caller's clock).
    pub ack_timeout_s: f64,
    /// Sends of one command before the sequence gives up.
    pub max_attempts: u32,
}

impl OffboardConfig {
    /// Takeoff to `takeoff_amsl_m`, OFFBOARD after the first setpoint, 1 s acknowledgement
    /// timeout, 3 attempts per command.
    pub fn new(takeoff_amsl_m: Option<f32>) -> Self {
        Self {
            takeoff_amsl_m,
            setpoints_before_switch: 1,
            ack_timeout_s: 1.0,
            max_attempts: 3,
        }
    }
}

/// Where the sequence is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for the arm command's acknowledgement (skipped if the vehicle is already armed).
    Arming,
    /// Waiting for the takeoff command's acknowledgement.
    TakingOff,
    /// Streaming setpoints; OFFBOARD requested whenever the vehicle is seen out of it.
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
    config: OffboardConfig,
    phase: Phase,
    pending: Option<Pending>,
    setpoints: u32,
    last_setpoint_at: Option<f64>,
    /// When the last OFFBOARD request was acknowledged: a status older than that predates it.
    switched_at: Option<f64>,
}

impl OffboardSequence {
    /// The sequence for vehicle (system id) `target`, not started.
    pub fn new(target: u8, config: OffboardConfig) -> Self {
        Self {
            target,
            config,
            phase: Phase::Arming,
            pending: None,
            setpoints: 0,
            last_setpoint_at: None,
            switched_at: None,
        }
    }

    /// The vehicle it flies.
    pub fn target(&self) -> u8 {
        self.target
    }

    /// Where the sequence is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The messages to send at `now`, given the vehicle's `status` and the velocity (ENU, m/s) to
    /// fly once airborne (`None` or non-finite: no setpoint, and no OFFBOARD request).
    pub fn next(
        &mut self,
        now: f64,
        status: &VehicleStatus,
        velocity: Option<Vector3<f64>>,
    ) -> Result<Vec<MavMessage>, OffboardError> {
        let mut out = Vec::new();
        if let Some(p) = &mut self.pending {
            if now - p.sent_at >= self.config.ack_timeout_s {
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
            }
        }
        let idle = self.pending.is_none();
        match self.phase {
            Phase::Arming if idle && status.armed => self.phase = Phase::Offboard,
            Phase::Arming if idle => self.send(now, arm(self.target), &mut out),
            Phase::TakingOff if idle => {
                let m = takeoff(self.target, self.config.takeoff_amsl_m);
                self.send(now, m, &mut out);
            }
            _ => {}
        }
        if self.phase != Phase::Offboard {
            return Ok(out);
        }
        let Some(v) = velocity.filter(|v| v.iter().all(|x| x.is_finite())) else {
            return Ok(out);
        };
        if self.last_setpoint_at != Some(now) {
            out.push(Setpoint::Velocity(v).to_message(self.target));
            self.setpoints = self.setpoints.saturating_add(1);
            self.last_setpoint_at = Some(now);
        }
        let out_of_offboard = status.mode != Some(FlightMode::Offboard)
            && self.switched_at.is_none_or(|t| status.at > t);
        if idle && out_of_offboard && self.setpoints >= self.config.setpoints_before_switch.max(1) {
            self.send(now, set_mode(self.target, FlightMode::Offboard), &mut out);
        }
        Ok(out)
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
        match p.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => self.phase = Phase::TakingOff,
            MavCmd::MAV_CMD_NAV_TAKEOFF => self.phase = Phase::Offboard,
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
mod tests {
    use super::*;
    use mavlink::dialects::common::COMMAND_ACK_DATA;

    fn ack(command: MavCmd, result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA { command, result })
    }

    fn commands(out: &[MavMessage]) -> Vec<MavCmd> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_LONG(c) => Some(c.command),
                _ => None,
            })
            .collect()
    }

    fn setpoints(out: &[MavMessage]) -> usize {
        out.iter()
            .filter(|m| matches!(m, MavMessage::SET_POSITION_TARGET_LOCAL_NED(_)))
            .count()
    }

    fn status(armed: bool, mode: FlightMode, at: f64) -> VehicleStatus {
        VehicleStatus {
            armed,
            mode: Some(mode),
            at,
        }
    }

    const V: Option<Vector3<f64>> = Some(Vector3::new(1.0, 2.0, 0.0));

    /// Over a slow link: one command per acknowledgement, setpoints before the switch, the
    /// switch repeated only when a status newer than its acknowledgement shows another mode.
    #[test]
    fn launch_waits_for_each_acknowledgement() {
        use MavCmd::*;
        let mut s = OffboardSequence::new(1, OffboardConfig::new(Some(500.0)));
        let hold = status(false, FlightMode::Hold, 0.0);
        let out = s.next(0.0, &hold, V).expect("next");
        assert_eq!(commands(&out), [MAV_CMD_COMPONENT_ARM_DISARM]);
        assert_eq!(setpoints(&out), 0);
        // Nothing new until the acknowledgement.
        assert!(s.next(0.1, &hold, V).expect("next").is_empty());
        s.handle(
            0.2,
            &ack(MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_ACCEPTED),
        )
        .expect("ack");
        let out = s
            .next(0.2, &status(true, FlightMode::Hold, 0.2), V)
            .expect("next");
        assert_eq!(commands(&out), [MAV_CMD_NAV_TAKEOFF]);
        s.handle(
            0.3,
            &ack(MAV_CMD_NAV_TAKEOFF, MavResult::MAV_RESULT_ACCEPTED),
        )
        .expect("ack");
        assert_eq!(s.phase(), Phase::Offboard);
        let climbing = status(true, FlightMode::Takeoff, 0.3);
        let out = s.next(0.4, &climbing, V).expect("next");
        assert_eq!(commands(&out), [MAV_CMD_DO_SET_MODE]);
        assert_eq!(setpoints(&out), 1);
        // One setpoint per time, not per call.
        assert!(s.next(0.4, &climbing, V).expect("next").is_empty());
        s.handle(
            0.5,
            &ack(MAV_CMD_DO_SET_MODE, MavResult::MAV_RESULT_ACCEPTED),
        )
        .expect("ack");
        // A heartbeat from before the switch does not trigger another request…
        let out = s.next(0.6, &climbing, V).expect("next");
        assert_eq!((commands(&out).len(), setpoints(&out)), (0, 1));
        // …a later one still out of OFFBOARD does; no velocity, no setpoint and no request.
        let fell_back = status(true, FlightMode::Hold, 0.7);
        assert!(s.next(0.8, &fell_back, None).expect("next").is_empty());
        let out = s.next(0.9, &fell_back, V).expect("next");
        assert_eq!(commands(&out), [MAV_CMD_DO_SET_MODE]);
    }

    #[test]
    fn unanswered_commands_are_retried_then_given_up() {
        let mut s = OffboardSequence::new(4, OffboardConfig::new(None));
        let st = status(false, FlightMode::Hold, 0.0);
        let first = s.next(0.0, &st, V).expect("next");
        let again = s.next(1.0, &st, V).expect("next");
        let (MavMessage::COMMAND_LONG(a), MavMessage::COMMAND_LONG(b)) = (&first[0], &again[0])
        else {
            panic!("{first:?} {again:?}");
        };
        assert_eq!((a.confirmation, b.confirmation), (0, 1));
        assert_eq!(s.next(2.0, &st, V).expect("next").len(), 1);
        let e = s.next(3.0, &st, V).expect_err("gives up");
        assert_eq!(
            e,
            OffboardError::NoAck {
                command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                attempts: 3
            }
        );
    }

    #[test]
    fn refusals_stop_the_sequence_and_armed_vehicles_skip_the_launch() {
        let mut s = OffboardSequence::new(1, OffboardConfig::new(None));
        s.next(0.0, &status(false, FlightMode::Hold, 0.0), V)
            .expect("next");
        let e = s.handle(
            0.0,
            &ack(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                MavResult::MAV_RESULT_DENIED,
            ),
        );
        assert!(e.is_err_and(|e| e.to_string().contains("MAV_RESULT_DENIED")));
        // An acknowledgement of some other command is not ours.
        let mut s = OffboardSequence::new(1, OffboardConfig::new(None));
        let flying = status(true, FlightMode::Hold, 0.0);
        let out = s.next(0.0, &flying, V).expect("next");
        assert_eq!(commands(&out), [MavCmd::MAV_CMD_DO_SET_MODE]);
        s.handle(
            0.0,
            &ack(MavCmd::MAV_CMD_NAV_LAND, MavResult::MAV_RESULT_DENIED),
        )
        .expect("not ours");
        assert_eq!(s.phase(), Phase::Offboard);
    }
}
