//! PX4's flight modes as MAVLink carries them: HEARTBEAT `custom_mode` (main mode in bits 16–23,
//! sub-mode in bits 24–31, with `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED` in `base_mode`) and the
//! parameters of `MAV_CMD_DO_SET_MODE` (param1 base mode, param2 main mode, param3 sub-mode).
//!
//! [`FlightMode`] lists the modes Harrier flies (and its simulator implements); both directions
//! of the encoding live here, so the vehicle side and the ground-station side cannot disagree.

use mavlink::dialects::common::{HEARTBEAT_DATA, MavModeFlag};

/// MAVLink component id of a PX4 autopilot (`MAV_COMP_ID_AUTOPILOT1`).
pub const COMPONENT_ID: u8 = 1;

/// PX4 main modes (`custom_mode` bits 16–23) and AUTO sub-modes (bits 24–31).
const MAIN_POSCTL: u32 = 3;
const MAIN_AUTO: u32 = 4;
const MAIN_OFFBOARD: u32 = 6;
const SUB_AUTO_TAKEOFF: u32 = 2;
const SUB_AUTO_LOITER: u32 = 3;
const SUB_AUTO_LAND: u32 = 6;

/// The PX4 flight modes Harrier uses, with their encodings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlightMode {
    /// POSCTL: holds position (no RC in the simulator).
    Position,
    /// AUTO.LOITER ("Hold"): holds the position where it was entered (fixed wing: orbits it).
    Hold,
    /// AUTO.TAKEOFF: climbs to the takeoff altitude, then switches to Hold.
    Takeoff,
    /// AUTO.LAND: descends in place, disarms on touchdown.
    Land,
    /// OFFBOARD: flies SET_POSITION_TARGET_LOCAL_NED setpoints.
    Offboard,
}

impl FlightMode {
    /// PX4 (main mode, sub-mode).
    pub fn px4_main_sub(self) -> (u32, u32) {
        match self {
            Self::Position => (MAIN_POSCTL, 0),
            Self::Hold => (MAIN_AUTO, SUB_AUTO_LOITER),
            Self::Takeoff => (MAIN_AUTO, SUB_AUTO_TAKEOFF),
            Self::Land => (MAIN_AUTO, SUB_AUTO_LAND),
            Self::Offboard => (MAIN_OFFBOARD, 0),
        }
    }

    /// PX4 `custom_mode`: main mode in bits 16–23, sub-mode in bits 24–31.
    pub fn px4_custom_mode(self) -> u32 {
        let (main, sub) = self.px4_main_sub();
        (main << 16) | (sub << 24)
    }

    /// The mode of a PX4 (main, sub) pair, if it is one of ours.
    pub fn from_px4(main: u32, sub: u32) -> Option<Self> {
        match (main, sub) {
            (MAIN_POSCTL, _) => Some(Self::Position),
            (MAIN_OFFBOARD, _) => Some(Self::Offboard),
            (MAIN_AUTO, SUB_AUTO_LOITER) => Some(Self::Hold),
            (MAIN_AUTO, SUB_AUTO_TAKEOFF) => Some(Self::Takeoff),
            (MAIN_AUTO, SUB_AUTO_LAND) => Some(Self::Land),
            _ => None,
        }
    }

    /// The mode of a PX4 `custom_mode`, if it is one of ours.
    pub fn from_custom_mode(custom_mode: u32) -> Option<Self> {
        Self::from_px4((custom_mode >> 16) & 0xFF, custom_mode >> 24)
    }

    /// `MAV_CMD_DO_SET_MODE` param1–3 that select this mode: custom mode enabled, main, sub.
    pub fn set_mode_params(self) -> [f32; 3] {
        let (main, sub) = self.px4_main_sub();
        let base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits();
        [f32::from(base), main as f32, sub as f32]
    }

    /// The mode `MAV_CMD_DO_SET_MODE` param1–3 ask for.
    pub fn from_set_mode_params(p1: f32, p2: f32, p3: f32) -> Result<Self, SetModeError> {
        let byte = |x: f32| (0.0..=255.0).contains(&x) && x.fract() == 0.0;
        if !(byte(p1) && byte(p2) && byte(p3)) {
            return Err(SetModeError::Malformed);
        }
        if p1 as u8 & MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() == 0 {
            return Err(SetModeError::NotCustom);
        }
        Self::from_px4(p2 as u32, p3 as u32).ok_or(SetModeError::Unknown)
    }
}

/// Why `MAV_CMD_DO_SET_MODE` parameters name none of our modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SetModeError {
    /// A parameter is not an integer in 0–255.
    #[error("mode parameters must be integers in 0-255")]
    Malformed,
    /// The base mode does not enable custom (PX4) modes.
    #[error("base mode without MAV_MODE_FLAG_CUSTOM_MODE_ENABLED")]
    NotCustom,
    /// A PX4 mode Harrier does not use (MISSION, ACRO, …).
    #[error("unsupported PX4 mode")]
    Unknown,
}

/// HEARTBEAT `base_mode` of a PX4 vehicle: custom mode enabled, plus `SAFETY_ARMED` if armed.
pub fn base_mode(armed: bool) -> MavModeFlag {
    let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
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
    /// The flight mode, `None` when it is not one of [`FlightMode`]'s.
    pub mode: Option<FlightMode>,
    /// When the status was observed (s, the observer's clock).
    pub at: f64,
}

impl VehicleStatus {
    /// The status a HEARTBEAT received at `at` reports.
    pub fn from_heartbeat(hb: &HEARTBEAT_DATA, at: f64) -> Self {
        let custom = hb
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED);
        Self {
            armed: hb
                .base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
            mode: custom
                .then(|| FlightMode::from_custom_mode(hb.custom_mode))
                .flatten(),
            at,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [FlightMode; 5] = [
        FlightMode::Position,
        FlightMode::Hold,
        FlightMode::Takeoff,
        FlightMode::Land,
        FlightMode::Offboard,
    ];

    #[test]
    fn custom_mode_encoding_round_trips() {
        for m in ALL {
            let c = m.px4_custom_mode();
            assert_eq!(FlightMode::from_px4((c >> 16) & 0xFF, c >> 24), Some(m));
            assert_eq!(FlightMode::from_custom_mode(c), Some(m));
            let [p1, p2, p3] = m.set_mode_params();
            assert_eq!(FlightMode::from_set_mode_params(p1, p2, p3), Ok(m));
        }
        // pymavlink's px4_map: LOITER = main 4, sub 3; OFFBOARD = main 6.
        assert_eq!(FlightMode::Hold.px4_custom_mode(), (4 << 16) | (3 << 24));
        assert_eq!(FlightMode::Offboard.px4_custom_mode(), 6 << 16);
        assert_eq!(FlightMode::Offboard.set_mode_params(), [1.0, 6.0, 0.0]);
        assert_eq!(FlightMode::from_px4(4, 4), None); // MISSION
    }

    #[test]
    fn set_mode_parameters_are_checked() {
        use SetModeError as E;
        let p = FlightMode::from_set_mode_params;
        assert_eq!(p(1.0, 4.0, 4.0), Err(E::Unknown));
        assert_eq!(p(0.0, 4.0, 3.0), Err(E::NotCustom));
        assert_eq!(p(1.0, 4.5, 3.0), Err(E::Malformed));
        assert_eq!(p(f32::NAN, 4.0, 3.0), Err(E::Malformed));
        assert_eq!(p(1.0, 256.0, 0.0), Err(E::Malformed));
    }

    #[test]
    fn heartbeats_decode_to_a_status() {
        for (armed, m) in [(true, FlightMode::Offboard), (false, FlightMode::Hold)] {
            let hb = HEARTBEAT_DATA {
                custom_mode: m.px4_custom_mode(),
                base_mode: base_mode(armed),
                ..HEARTBEAT_DATA::DEFAULT
            };
            let s = VehicleStatus::from_heartbeat(&hb, 2.5);
            assert_eq!((s.armed, s.mode, s.at), (armed, Some(m), 2.5));
        }
        // Without the custom-mode flag, custom_mode means nothing.
        let hb = HEARTBEAT_DATA {
            custom_mode: FlightMode::Offboard.px4_custom_mode(),
            ..HEARTBEAT_DATA::DEFAULT
        };
        assert_eq!(VehicleStatus::from_heartbeat(&hb, 0.0).mode, None);
    }
}
