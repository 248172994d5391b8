//! The MAVLink protocol a vehicle answers: COMMAND_LONG (arm, takeoff, land, mode, message
//! intervals and requests) with COMMAND_ACK, parameters, offboard setpoints.

use harrier_link::command::Setpoint;
use harrier_link::px4::{COMPONENT_ID, SetModeError};
use mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavMessage, MavResult,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use nalgebra::Vector3;

use super::{FlightMode, Vehicle};

impl Vehicle {
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
}
