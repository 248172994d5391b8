//! The MAVLink protocol a vehicle answers: commands (COMMAND_LONG and COMMAND_INT, each with a
//! COMMAND_ACK: arm, takeoff, land, RTL (PX4 and ArduPilot), loiter, mode, message intervals and requests, and
//! ArduPilot's guided commands, a target handed over: DO_ORBIT, DO_SET_ROI_LOCATION), SET_MODE,
//! FOLLOW_TARGET, parameters, data-stream requests, the mission protocol (`mission.rs`), and
//! the ground station's targets.

use harrier_link::ardupilot::CopterMode;
use harrier_link::autopilot::{Autopilot, Mode};
use harrier_link::px4::{COMPONENT_ID, FlightMode};
use mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA, MavCmd, MavFrame, MavMessage, MavResult,
};
use nalgebra::Vector3;

use super::modes::Behaviour;
use super::wire::{Incoming, Outgoing};
use super::{Target, Vehicle};

/// A command as either message carries it: params 1–4, then x, y, z (COMMAND_INT's latitude and
/// longitude in degrees, or COMMAND_LONG's params 5–7) and COMMAND_INT's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Cmd {
    pub(super) command: MavCmd,
    pub(super) p: [f32; 4],
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) z: f32,
    /// `None` for a COMMAND_LONG.
    pub(super) frame: Option<MavFrame>,
}

impl Cmd {
    fn long(c: &COMMAND_LONG_DATA) -> Self {
        Self {
            command: c.command,
            p: [c.param1, c.param2, c.param3, c.param4],
            x: f64::from(c.param5),
            y: f64::from(c.param6),
            z: c.param7,
            frame: None,
        }
    }

    fn int(c: &COMMAND_INT_DATA) -> Self {
        Self {
            command: c.command,
            p: [c.param1, c.param2, c.param3, c.param4],
            x: f64::from(c.x) * 1e-7,
            y: f64::from(c.y) * 1e-7,
            z: c.z,
            frame: Some(c.frame),
        }
    }
}

impl Vehicle {
    fn for_us(target_system: u8, target_component: u8, id: u8) -> bool {
        (target_system == 0 || target_system == id)
            && (target_component == 0 || target_component == COMPONENT_ID)
    }

    /// Handles one message received at wall time `now` from a ground station (system 255,
    /// component 190, no extension fields); returns the replies for its sender.
    pub fn handle(&mut self, now: f64, msg: &MavMessage) -> Vec<MavMessage> {
        self.handle_frame(now, Incoming::from_gcs(msg))
            .into_iter()
            .map(|o| o.message)
            .collect()
    }

    /// Handles one message received at wall time `now`, with its sender and `mission_type`;
    /// returns the replies for its sender, each with its component and extension fields.
    pub fn handle_frame(&mut self, now: f64, m: Incoming<'_>) -> Vec<Outgoing> {
        self.advance(now);
        if let Some(replies) = self.mission_message(now, &m) {
            return replies;
        }
        self.handle_message(now, m.message)
            .into_iter()
            .map(Outgoing::from)
            .collect()
    }

    // Superseded messages clients still send: MAVProxy's SET_MODE and REQUEST_DATA_STREAM.
    #[allow(deprecated)]
    fn handle_message(&mut self, now: f64, msg: &MavMessage) -> Vec<MavMessage> {
        let id = self.config.id;
        match msg {
            MavMessage::COMMAND_LONG(c)
                if Self::for_us(c.target_system, c.target_component, id) =>
            {
                self.command(now, &Cmd::long(c))
            }
            MavMessage::COMMAND_INT(c) if Self::for_us(c.target_system, c.target_component, id) => {
                self.command(now, &Cmd::int(c))
            }
            MavMessage::SET_MODE(s) if s.target_system == id => {
                // ArduPilot answers SET_MODE with the COMMAND_ACK of a DO_SET_MODE.
                let base = f32::from(s.base_mode.bits());
                let result = self.set_mode_command(now, base, s.custom_mode, 0);
                vec![self.ack(MavCmd::MAV_CMD_DO_SET_MODE, result)]
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
            MavMessage::REQUEST_DATA_STREAM(r)
                if Self::for_us(r.target_system, r.target_component, id) =>
            {
                self.request_data_stream(now, r);
                Vec::new()
            }
            MavMessage::FOLLOW_TARGET(f) => {
                self.follow_target(f);
                Vec::new()
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(s)
                if Self::for_us(s.target_system, s.target_component, id) =>
            {
                self.local_target(now, s);
                Vec::new()
            }
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(s)
                if Self::for_us(s.target_system, s.target_component, id) =>
            {
                self.global_target(now, s);
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    pub(super) fn ack(&mut self, command: MavCmd, result: MavResult) -> MavMessage {
        if result != MavResult::MAV_RESULT_ACCEPTED {
            self.counters.refused_commands += 1;
        }
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA { command, result })
    }

    // MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, superseded, is still sent by ground stations.
    #[allow(deprecated)]
    fn command(&mut self, now: f64, c: &Cmd) -> Vec<MavMessage> {
        use MavResult::{MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED};
        let ardupilot = self.personality.autopilot == Autopilot::ArduPilot;
        let mut extra = Vec::new();
        let result = match c.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => self.arm_disarm(now, c.p[0], c.p[1]),
            MavCmd::MAV_CMD_NAV_TAKEOFF if ardupilot => self.ardupilot_takeoff(now, c),
            MavCmd::MAV_CMD_NAV_TAKEOFF => self.px4_takeoff(now, c.z),
            MavCmd::MAV_CMD_NAV_LAND if self.is_plane() => MAV_RESULT_UNSUPPORTED,
            MavCmd::MAV_CMD_NAV_LAND if !self.armed => MAV_RESULT_DENIED,
            MavCmd::MAV_CMD_NAV_LAND => {
                let land = self.personality.land();
                self.mode_result(now, land)
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH | MavCmd::MAV_CMD_NAV_LOITER_UNLIM
                if ardupilot =>
            {
                let mode = if c.command == MavCmd::MAV_CMD_NAV_LOITER_UNLIM {
                    self.personality.hold()
                } else {
                    self.personality
                        .mode_named("RTL")
                        .unwrap_or(self.personality.hold())
                };
                self.mode_result(now, mode)
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                self.mode_result(now, Mode::Px4(FlightMode::Rtl))
            }
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let byte = |x: f32| (0.0..=255.0).contains(&x) && x.fract() == 0.0;
                if byte(c.p[1]) && byte(c.p[2]) {
                    self.set_mode_command(now, c.p[0], c.p[1] as u32, c.p[2] as u32)
                } else {
                    self.refusal(MAV_RESULT_DENIED)
                }
            }
            MavCmd::MAV_CMD_DO_REPOSITION if ardupilot => self.reposition(now, c),
            MavCmd::MAV_CMD_DO_REPOSITION => self.px4_reposition(now, c),
            MavCmd::MAV_CMD_DO_ORBIT if !ardupilot => self.do_orbit(now, c),
            MavCmd::MAV_CMD_DO_SET_ROI_LOCATION => self.set_roi(c),
            MavCmd::MAV_CMD_DO_SET_ROI_NONE => self.clear_roi(),
            MavCmd::MAV_CMD_DO_CHANGE_SPEED if ardupilot => self.change_speed(c),
            MavCmd::MAV_CMD_GUIDED_CHANGE_HEADING
            | MavCmd::MAV_CMD_GUIDED_CHANGE_SPEED
            | MavCmd::MAV_CMD_GUIDED_CHANGE_ALTITUDE
                if self.is_plane() =>
            {
                self.plane_guided_command(c)
            }
            MavCmd::MAV_CMD_MISSION_START | MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT => {
                let r = self.mission_command(now, c);
                self.refusal_of(r)
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => self.set_message_interval(now, c.p[0], c.p[1]),
            MavCmd::MAV_CMD_REQUEST_MESSAGE | MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                let id = if c.command == MavCmd::MAV_CMD_REQUEST_MESSAGE {
                    c.p[0]
                } else {
                    // AUTOPILOT_VERSION.
                    148.0
                };
                match (id.is_finite() && id >= 0.0)
                    .then(|| self.message(id as u32))
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

    /// ArduPilot's answer to a refused command: MAV_RESULT_FAILED (its `set_mode` and
    /// `do_user_takeoff` returning false), PX4's the given one.
    fn refusal(&self, px4: MavResult) -> MavResult {
        match self.personality.autopilot {
            Autopilot::Px4 => px4,
            Autopilot::ArduPilot => MavResult::MAV_RESULT_FAILED,
        }
    }

    /// A refusal in the autopilot's terms: ArduPilot's DENIED is FAILED.
    fn refusal_of(&self, r: MavResult) -> MavResult {
        match r {
            MavResult::MAV_RESULT_DENIED => self.refusal(MavResult::MAV_RESULT_DENIED),
            r => r,
        }
    }

    /// Switches to `mode`, ArduPilot's refusals as FAILED.
    fn mode_result(&mut self, now: f64, mode: Mode) -> MavResult {
        let r = self.request_mode(now, mode);
        self.refusal_of(r)
    }

    /// DO_SET_MODE (or SET_MODE): base mode with the custom flag, then the autopilot's mode.
    fn set_mode_command(&mut self, now: f64, base: f32, main: u32, sub: u32) -> MavResult {
        use harrier_link::autopilot::SetModeError;
        match self
            .personality
            .requested_mode(base, main as f32, sub as f32)
        {
            Ok(mode) => self.mode_result(now, mode),
            Err(SetModeError::Malformed) => self.refusal(MavResult::MAV_RESULT_DENIED),
            Err(SetModeError::NotCustom | SetModeError::Unknown) => {
                MavResult::MAV_RESULT_UNSUPPORTED
            }
        }
    }

    /// PX4's NAV_TAKEOFF: param7 is the altitude AMSL (NaN: MIS_TAKEOFF_ALT above home); armed.
    fn px4_takeoff(&mut self, now: f64, param7: f32) -> MavResult {
        let alt = if param7.is_nan() {
            self.param("MIS_TAKEOFF_ALT").map(f64::from)
        } else if param7.is_finite() {
            Some(f64::from(param7) - self.config.origin.alt_m)
        } else {
            None
        };
        match alt {
            Some(a) if self.armed && a > 0.0 && a < 10_000.0 => {
                self.set_mode(now, Mode::Px4(FlightMode::Takeoff));
                self.takeoff_alt = a;
                MavResult::MAV_RESULT_ACCEPTED
            }
            _ => MavResult::MAV_RESULT_DENIED,
        }
    }

    /// ArduPilot's NAV_TAKEOFF. ArduCopter: param7 (or a COMMAND_INT's z in
    /// `MAV_FRAME_GLOBAL_RELATIVE_ALT`) is the height above home; it must be armed, on the
    /// ground, in a mode with a user takeoff (GUIDED, LOITER, POSHOLD, ALT_HOLD, SPORT), and climb
    /// (`Mode::do_user_takeoff`), else FAILED; another COMMAND_INT frame is DENIED. ArduPlane:
    /// NAV_TAKEOFF is a QuadPlane's; a plane takes off in TAKEOFF mode (FAILED).
    #[allow(deprecated)]
    fn ardupilot_takeoff(&mut self, now: f64, c: &Cmd) -> MavResult {
        if self.is_plane() {
            return MavResult::MAV_RESULT_FAILED;
        }
        if c.frame.is_some_and(|f| {
            !matches!(
                f,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            )
        }) {
            return MavResult::MAV_RESULT_DENIED;
        }
        let height = f64::from(c.z);
        // `Mode::has_user_takeoff`: the modes that control the climb.
        let user_takeoff = matches!(
            self.mode,
            Mode::Copter(
                CopterMode::Guided
                    | CopterMode::Loiter
                    | CopterMode::PosHold
                    | CopterMode::AltHold
                    | CopterMode::Sport
            )
        );
        if !(self.armed
            && self.on_ground()
            && user_takeoff
            && height.is_finite()
            && height > self.state.position.z
            && height < 10_000.0)
        {
            return MavResult::MAV_RESULT_FAILED;
        }
        self.start_takeoff(height);
        if self.behaviour() == Behaviour::External {
            self.target = None;
            self.last_target = Some(now);
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    fn arm_disarm(&mut self, now: f64, p1: f32, p2: f32) -> MavResult {
        const FORCE: f32 = 21196.0;
        if p1 == 1.0 {
            if self.armed {
                MavResult::MAV_RESULT_ACCEPTED
            } else if self.may_arm() {
                self.armed = true;
                self.on_armed(now);
                MavResult::MAV_RESULT_ACCEPTED
            } else {
                self.refusal(MavResult::MAV_RESULT_DENIED)
            }
        } else if p1 == 0.0 {
            if !self.armed || self.on_ground() || p2 == FORCE {
                self.armed = false;
                self.taking_off = false;
                if !self.on_ground() {
                    // Forced disarm in the air: the point mass falls to the ground.
                    self.state.position.z = 0.0;
                }
                self.state.velocity = Vector3::zeros();
                if matches!(
                    self.mode,
                    Mode::Px4(FlightMode::Offboard | FlightMode::Takeoff)
                ) {
                    self.set_mode(now, Mode::Px4(FlightMode::Hold));
                }
                MavResult::MAV_RESULT_ACCEPTED
            } else {
                self.refusal(MavResult::MAV_RESULT_DENIED)
            }
        } else {
            MavResult::MAV_RESULT_DENIED
        }
    }

    /// Keeps a GUIDED target's time (a velocity target lapses after GUID_TIMEOUT; PX4's
    /// OFFBOARD needs them fresh).
    pub(super) fn take_target(&mut self, now: f64, target: Target) {
        self.target = Some(target);
        self.last_target = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_read_the_same_from_both_messages() {
        let long = COMMAND_LONG_DATA {
            param1: 1.0,
            param5: 47.5,
            param6: 8.25,
            param7: 30.0,
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            ..COMMAND_LONG_DATA::DEFAULT
        };
        let int = COMMAND_INT_DATA {
            param1: 1.0,
            x: 475_000_000,
            y: 82_500_000,
            z: 30.0,
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            ..COMMAND_INT_DATA::DEFAULT
        };
        let (a, b) = (Cmd::long(&long), Cmd::int(&int));
        assert_eq!((a.command, a.p, a.z), (b.command, b.p, b.z));
        assert!((a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9);
        assert_eq!((a.frame, b.frame), (None, Some(MavFrame::MAV_FRAME_GLOBAL)));
    }
}
