//! Which autopilot flies a vehicle and which airframe it is (its [`Personality`], from the
//! HEARTBEAT's `autopilot` and `type`), the vehicle's flight [`Mode`] in that autopilot's
//! encoding, and what a ground station knows of it from a HEARTBEAT ([`VehicleStatus`]).
//!
//! The ground station and the simulator both go through here: the simulator announces a
//! personality and flies the modes of its table, the ground station decodes them and asks for
//! the mode that does what it needs ([`Personality::hold`], [`Personality::land`],
//! [`Personality::guided`]) in the vehicle's own encoding.
//!
//! | | PX4 | ArduCopter | ArduPlane |
//! |---|---|---|---|
//! | HEARTBEAT `autopilot` | `MAV_AUTOPILOT_PX4` | `MAV_AUTOPILOT_ARDUPILOTMEGA` | `MAV_AUTOPILOT_ARDUPILOTMEGA` |
//! | HEARTBEAT `type` | QUADROTOR / FIXED_WING | QUADROTOR | FIXED_WING |
//! | `custom_mode` | main << 16 \| sub << 24 ([`crate::px4`]) | mode number ([`crate::ardupilot`]) | mode number |
//! | hold | AUTO.LOITER | LOITER | LOITER |
//! | land | AUTO.LAND | LAND | RTL (it loiters at home; landing needs a mission) |
//! | external control | OFFBOARD | GUIDED | GUIDED |

use mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavModeFlag, MavType};

use crate::ardupilot::{CopterMode, PlaneMode};
use crate::px4::FlightMode;

/// The flight stack of a vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Autopilot {
    /// PX4 (and any autopilot the ground station does not know: it is decoded as PX4).
    Px4,
    /// ArduPilot (`MAV_AUTOPILOT_ARDUPILOTMEGA`): ArduCopter or ArduPlane by MAV_TYPE.
    ArduPilot,
}

impl Autopilot {
    /// `px4` or `ardupilot`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Px4 => "px4",
            Self::ArduPilot => "ardupilot",
        }
    }
}

/// The kind of airframe, as far as flying it goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Frame {
    /// Hovers: any rotorcraft MAV_TYPE (quad-, hexa-, octo-, tri-, coaxial, helicopter).
    Multirotor,
    /// Cannot hover (minimum airspeed, bank-limited turns): MAV_TYPE_FIXED_WING.
    FixedWing,
}

impl Frame {
    /// `multirotor` or `fixed_wing`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Multirotor => "multirotor",
            Self::FixedWing => "fixed_wing",
        }
    }

    /// The frame of a MAV_TYPE: fixed wing for `MAV_TYPE_FIXED_WING`, else a multirotor.
    pub fn of(mav_type: MavType) -> Self {
        if mav_type == MavType::MAV_TYPE_FIXED_WING {
            Self::FixedWing
        } else {
            Self::Multirotor
        }
    }

    /// The MAV_TYPE a vehicle of this frame announces.
    pub fn mav_type(self) -> MavType {
        match self {
            Self::Multirotor => MavType::MAV_TYPE_QUADROTOR,
            Self::FixedWing => MavType::MAV_TYPE_FIXED_WING,
        }
    }
}

/// Autopilot and airframe: what a vehicle's HEARTBEAT says it is, and which mode table it uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Personality {
    /// The flight stack.
    pub autopilot: Autopilot,
    /// The airframe.
    pub frame: Frame,
}

impl Personality {
    /// PX4 on a multirotor.
    pub const PX4_MULTIROTOR: Self = Self::new(Autopilot::Px4, Frame::Multirotor);

    /// A personality.
    pub const fn new(autopilot: Autopilot, frame: Frame) -> Self {
        Self { autopilot, frame }
    }

    /// What a HEARTBEAT announces.
    pub fn of(hb: &HEARTBEAT_DATA) -> Self {
        let autopilot = if hb.autopilot == MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA {
            Autopilot::ArduPilot
        } else {
            Autopilot::Px4
        };
        Self::new(autopilot, Frame::of(hb.mavtype))
    }

    /// The HEARTBEAT `autopilot` field.
    pub fn mav_autopilot(self) -> MavAutopilot {
        match self.autopilot {
            Autopilot::Px4 => MavAutopilot::MAV_AUTOPILOT_PX4,
            Autopilot::ArduPilot => MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        }
    }

    /// `px4-mc`, `px4-fw`, `ardupilot-mc` (ArduCopter) or `ardupilot-fw` (ArduPlane).
    pub fn label(self) -> &'static str {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, Frame::Multirotor) => "px4-mc",
            (Autopilot::Px4, Frame::FixedWing) => "px4-fw",
            (Autopilot::ArduPilot, Frame::Multirotor) => "ardupilot-mc",
            (Autopilot::ArduPilot, Frame::FixedWing) => "ardupilot-fw",
        }
    }

    /// The personality of a [`Self::label`].
    pub fn from_label(label: &str) -> Option<Self> {
        [
            (Autopilot::Px4, Frame::Multirotor),
            (Autopilot::Px4, Frame::FixedWing),
            (Autopilot::ArduPilot, Frame::Multirotor),
            (Autopilot::ArduPilot, Frame::FixedWing),
        ]
        .into_iter()
        .map(|(a, f)| Self::new(a, f))
        .find(|p| p.label() == label)
    }

    /// The mode a `custom_mode` means to this vehicle, if its table has it.
    pub fn decode(self, custom_mode: u32) -> Option<Mode> {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => FlightMode::from_custom_mode(custom_mode).map(Mode::Px4),
            (Autopilot::ArduPilot, Frame::Multirotor) => {
                CopterMode::from_number(custom_mode).map(Mode::Copter)
            }
            (Autopilot::ArduPilot, Frame::FixedWing) => {
                PlaneMode::from_number(custom_mode).map(Mode::Plane)
            }
        }
    }

    /// The mode of a name in this vehicle's table ([`Mode::name`]).
    pub fn mode_named(self, name: &str) -> Option<Mode> {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => FlightMode::ALL
                .into_iter()
                .find(|m| m.name() == name)
                .map(Mode::Px4),
            (Autopilot::ArduPilot, Frame::Multirotor) => {
                CopterMode::from_name(name).map(Mode::Copter)
            }
            (Autopilot::ArduPilot, Frame::FixedWing) => PlaneMode::from_name(name).map(Mode::Plane),
        }
    }

    /// Where a `custom_mode` this vehicle's table lacks is shown: `PX4 main M sub S` or
    /// `Mode(N)` (pymavlink's spelling).
    pub fn unknown_mode_name(self, custom_mode: u32) -> String {
        match self.autopilot {
            Autopilot::Px4 => format!(
                "PX4 main {} sub {}",
                (custom_mode >> 16) & 0xFF,
                custom_mode >> 24
            ),
            Autopilot::ArduPilot => format!("Mode({custom_mode})"),
        }
    }

    /// The mode it boots in: PX4 Hold; ArduCopter STABILIZE (no RC: the first flight-mode
    /// slot); ArduPlane MANUAL (`INITIAL_MODE`'s default).
    pub fn initial(self) -> Mode {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => Mode::Px4(FlightMode::Hold),
            (Autopilot::ArduPilot, Frame::Multirotor) => Mode::Copter(CopterMode::Stabilize),
            (Autopilot::ArduPilot, Frame::FixedWing) => Mode::Plane(PlaneMode::Manual),
        }
    }

    /// The mode `MAV_CMD_DO_SET_MODE` param1–3 (or SET_MODE's `base_mode` and `custom_mode`,
    /// param3 0) ask this vehicle for: custom mode enabled in param1, then PX4's main and sub
    /// mode, or ArduPilot's mode number.
    pub fn requested_mode(self, p1: f32, p2: f32, p3: f32) -> Result<Mode, SetModeError> {
        let byte = |x: f32| (0.0..=255.0).contains(&x) && x.fract() == 0.0;
        if !(byte(p1) && byte(p2) && byte(p3)) {
            return Err(SetModeError::Malformed);
        }
        if p1 as u8 & MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() == 0 {
            return Err(SetModeError::NotCustom);
        }
        let mode = match self.autopilot {
            Autopilot::Px4 => FlightMode::from_px4(p2 as u32, p3 as u32).map(Mode::Px4),
            Autopilot::ArduPilot => self.decode(p2 as u32),
        };
        mode.ok_or(SetModeError::Unknown)
    }

    /// The mode that keeps the vehicle where it is: PX4 Hold (AUTO.LOITER), ArduCopter LOITER,
    /// ArduPlane LOITER (it circles the point at WP_LOITER_RAD).
    pub fn hold(self) -> Mode {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => Mode::Px4(FlightMode::Hold),
            (Autopilot::ArduPilot, Frame::Multirotor) => Mode::Copter(CopterMode::Loiter),
            (Autopilot::ArduPilot, Frame::FixedWing) => Mode::Plane(PlaneMode::Loiter),
        }
    }

    /// The mode that brings it down: PX4 AUTO.LAND, ArduCopter LAND; ArduPlane RTL (it returns
    /// and loiters over home: a fixed-wing landing is a mission's landing sequence).
    pub fn land(self) -> Mode {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => Mode::Px4(FlightMode::Land),
            (Autopilot::ArduPilot, Frame::Multirotor) => Mode::Copter(CopterMode::Land),
            (Autopilot::ArduPilot, Frame::FixedWing) => Mode::Plane(PlaneMode::Rtl),
        }
    }

    /// The mode in which it follows the FOLLOW_TARGET messages it is sent: PX4 AUTO.FOLLOW_TARGET
    /// ("Follow Me"), ArduCopter FOLLOW (AP_Follow reads FOLLOW_TARGET); ArduPlane has none.
    pub fn follow(self) -> Option<Mode> {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, Frame::Multirotor) => Some(Mode::Px4(FlightMode::FollowTarget)),
            (Autopilot::ArduPilot, Frame::Multirotor) => Some(Mode::Copter(CopterMode::Follow)),
            (_, Frame::FixedWing) => None,
        }
    }

    /// The mode in which it flies the ground station's targets: PX4 OFFBOARD, ArduPilot GUIDED.
    pub fn guided(self) -> Mode {
        match (self.autopilot, self.frame) {
            (Autopilot::Px4, _) => Mode::Px4(FlightMode::Offboard),
            (Autopilot::ArduPilot, Frame::Multirotor) => Mode::Copter(CopterMode::Guided),
            (Autopilot::ArduPilot, Frame::FixedWing) => Mode::Plane(PlaneMode::Guided),
        }
    }
}

/// A vehicle's flight mode in its autopilot's table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// A PX4 mode.
    Px4(FlightMode),
    /// An ArduCopter mode.
    Copter(CopterMode),
    /// An ArduPlane mode.
    Plane(PlaneMode),
}

impl Mode {
    /// HEARTBEAT `custom_mode`.
    pub fn custom_mode(self) -> u32 {
        match self {
            Self::Px4(m) => m.px4_custom_mode(),
            Self::Copter(m) => m.number(),
            Self::Plane(m) => m.number(),
        }
    }

    /// The name a ground station shows (QGroundControl's for PX4, MAVProxy's for ArduPilot).
    pub fn name(self) -> &'static str {
        match self {
            Self::Px4(m) => m.name(),
            Self::Copter(m) => m.name(),
            Self::Plane(m) => m.name(),
        }
    }

    /// `MAV_CMD_DO_SET_MODE` param1–3: custom mode enabled, then PX4's main and sub mode or
    /// ArduPilot's mode number and 0.
    pub fn set_mode_params(self) -> [f32; 3] {
        match self {
            Self::Px4(m) => m.set_mode_params(),
            Self::Copter(_) | Self::Plane(_) => {
                let base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits();
                [f32::from(base), self.custom_mode() as f32, 0.0]
            }
        }
    }

    /// Whether it is the mode in which the vehicle flies the ground station's targets.
    pub fn is_guided(self) -> bool {
        matches!(
            self,
            Self::Px4(FlightMode::Offboard)
                | Self::Copter(CopterMode::Guided)
                | Self::Plane(PlaneMode::Guided)
        )
    }
}

/// Why mode-switch parameters name none of the vehicle's modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SetModeError {
    /// A parameter is not an integer in 0–255.
    #[error("mode parameters must be integers in 0-255")]
    Malformed,
    /// The base mode does not enable custom (autopilot) modes.
    #[error("base mode without MAV_MODE_FLAG_CUSTOM_MODE_ENABLED")]
    NotCustom,
    /// A mode the vehicle's table lacks (a PX4 MISSION, an ArduCopter mode 12, …).
    #[error("a mode this vehicle does not have")]
    Unknown,
}

/// HEARTBEAT `base_mode` of an ArduPilot vehicle: stabilised, manual input and custom mode
/// enabled, guided while the position controller runs, plus `SAFETY_ARMED` if armed
/// (`GCS_MAVLINK_Copter::base_mode`).
pub fn ardupilot_base_mode(armed: bool, position_control: bool) -> MavModeFlag {
    let mut base = MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
        | MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    if position_control {
        base |= MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED;
    }
    if armed {
        base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    base
}

/// What a ground station knows of a vehicle from its HEARTBEAT, and when it learnt it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleStatus {
    /// Motors armed.
    pub armed: bool,
    /// Autopilot and airframe.
    pub personality: Personality,
    /// The flight mode, `None` when its table lacks the `custom_mode` (or custom modes are off).
    pub mode: Option<Mode>,
    /// When the status was observed (s, the observer's clock).
    pub at: f64,
}

impl VehicleStatus {
    /// The status a HEARTBEAT received at `at` reports.
    pub fn from_heartbeat(hb: &HEARTBEAT_DATA, at: f64) -> Self {
        let personality = Personality::of(hb);
        let custom = hb
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED);
        Self {
            armed: hb
                .base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
            personality,
            mode: custom.then(|| personality.decode(hb.custom_mode)).flatten(),
            at,
        }
    }

    /// A disarmed PX4 multirotor in an unknown mode, seen at time 0: what to assume before the
    /// first HEARTBEAT.
    pub fn unknown() -> Self {
        Self {
            armed: false,
            personality: Personality::PX4_MULTIROTOR,
            mode: None,
            at: 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::px4::base_mode;

    fn heartbeat(p: Personality, mode: Mode, armed: bool) -> HEARTBEAT_DATA {
        HEARTBEAT_DATA {
            custom_mode: mode.custom_mode(),
            mavtype: p.frame.mav_type(),
            autopilot: p.mav_autopilot(),
            base_mode: match p.autopilot {
                Autopilot::Px4 => base_mode(armed),
                Autopilot::ArduPilot => ardupilot_base_mode(armed, false),
            },
            ..HEARTBEAT_DATA::DEFAULT
        }
    }

    /// Each personality's HEARTBEAT decodes to itself and its mode, whichever table it uses.
    #[test]
    fn heartbeats_decode_by_autopilot_and_type() {
        for label in ["px4-mc", "px4-fw", "ardupilot-mc", "ardupilot-fw"] {
            let p = Personality::from_label(label).expect("label");
            assert_eq!(p.label(), label);
            for (mode, armed) in [(p.hold(), true), (p.guided(), false), (p.land(), true)] {
                let s = VehicleStatus::from_heartbeat(&heartbeat(p, mode, armed), 1.5);
                assert_eq!(
                    (s.personality, s.mode, s.armed, s.at),
                    (p, Some(mode), armed, 1.5)
                );
                assert_eq!(p.mode_named(mode.name()), Some(mode));
            }
        }
        // The same number means another mode to a Copter and to a Plane: 4 is GUIDED and ACRO.
        let copter = Personality::from_label("ardupilot-mc").expect("label");
        let plane = Personality::from_label("ardupilot-fw").expect("label");
        assert_eq!(copter.decode(4).map(Mode::name), Some("GUIDED"));
        assert_eq!(plane.decode(4).map(Mode::name), Some("ACRO"));
        assert_eq!(plane.decode(15).map(Mode::name), Some("GUIDED"));
        assert_eq!(copter.decode(12), None);
        assert_eq!(copter.unknown_mode_name(12), "Mode(12)");
        // Without the custom-mode flag custom_mode means nothing.
        let mut hb = heartbeat(copter, copter.guided(), true);
        hb.base_mode = MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        assert_eq!(VehicleStatus::from_heartbeat(&hb, 0.0).mode, None);
    }

    /// DO_SET_MODE carries PX4's main and sub mode, or ArduPilot's number in param2.
    #[test]
    fn set_mode_parameters_follow_the_autopilot() {
        assert_eq!(
            Mode::Px4(FlightMode::Offboard).set_mode_params(),
            [1.0, 6.0, 0.0]
        );
        assert_eq!(
            Mode::Copter(CopterMode::Guided).set_mode_params(),
            [1.0, 4.0, 0.0]
        );
        assert_eq!(
            Mode::Plane(PlaneMode::Guided).set_mode_params(),
            [1.0, 15.0, 0.0]
        );
        assert!(Mode::Plane(PlaneMode::Guided).is_guided());
        assert!(!Mode::Copter(CopterMode::Loiter).is_guided());
        assert_eq!(Personality::from_label("px4-vtol"), None);
        let copter = Personality::from_label("ardupilot-mc").expect("label");
        assert_eq!(
            copter.requested_mode(1.0, 4.0, 0.0),
            Ok(Mode::Copter(CopterMode::Guided))
        );
        assert_eq!(
            copter.requested_mode(1.0, 12.0, 0.0),
            Err(SetModeError::Unknown)
        );
        assert_eq!(
            copter.requested_mode(0.0, 4.0, 0.0),
            Err(SetModeError::NotCustom)
        );
        assert_eq!(
            copter.requested_mode(1.0, 4.5, 0.0),
            Err(SetModeError::Malformed)
        );
        assert_eq!(
            Personality::PX4_MULTIROTOR.requested_mode(1.0, 6.0, 0.0),
            Ok(Mode::Px4(FlightMode::Offboard))
        );
    }
}
