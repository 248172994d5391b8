//! PX4's flight modes as MAVLink carries them: HEARTBEAT `custom_mode` (main mode in bits 16–23,
//! sub-mode in bits 24–31, with `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED` in `base_mode`) and the
//! parameters of `MAV_CMD_DO_SET_MODE` (param1 base mode, param2 main mode, param3 sub-mode).
//!
//! [`FlightMode`] lists the modes Harrier flies (and its simulator implements); both directions
//! of the encoding live here, so the vehicle side and the ground-station side cannot disagree.
//! What a HEARTBEAT says, whichever the autopilot, is [`crate::autopilot::VehicleStatus`].

use mavlink::dialects::common::MavModeFlag;

/// MAVLink component id of a PX4 autopilot (`MAV_COMP_ID_AUTOPILOT1`).
pub const COMPONENT_ID: u8 = 1;

/// PX4 main modes (`custom_mode` bits 16–23) and AUTO sub-modes (bits 24–31).
const MAIN_POSCTL: u32 = 3;
const MAIN_AUTO: u32 = 4;
const MAIN_OFFBOARD: u32 = 6;
const SUB_AUTO_TAKEOFF: u32 = 2;
const SUB_AUTO_LOITER: u32 = 3;
const SUB_AUTO_MISSION: u32 = 4;
const SUB_AUTO_RTL: u32 = 5;
const SUB_AUTO_LAND: u32 = 6;
const SUB_AUTO_FOLLOW_TARGET: u32 = 8;
const SUB_POSCTL_ORBIT: u32 = 1;

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
    /// POSCTL.ORBIT: circles the centre of a MAV_CMD_DO_ORBIT.
    Orbit,
    /// AUTO.FOLLOW_TARGET ("Follow Me"): follows the FOLLOW_TARGET messages it receives.
    FollowTarget,
    /// AUTO.RTL ("Return"): climbs to RTL_RETURN_ALT if lower, flies home, lands (a fixed wing
    /// loiters over home).
    Rtl,
    /// AUTO.MISSION: flies the uploaded mission.
    Mission,
}

impl FlightMode {
    /// Every mode Harrier uses.
    pub const ALL: [Self; 9] = [
        Self::Position,
        Self::Hold,
        Self::Takeoff,
        Self::Land,
        Self::Offboard,
        Self::Orbit,
        Self::FollowTarget,
        Self::Rtl,
        Self::Mission,
    ];

    /// The mode's name as QGroundControl shows it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Position => "POSCTL",
            Self::Hold => "HOLD",
            Self::Takeoff => "TAKEOFF",
            Self::Land => "LAND",
            Self::Offboard => "OFFBOARD",
            Self::Orbit => "ORBIT",
            Self::FollowTarget => "FOLLOW_TARGET",
            Self::Rtl => "RTL",
            Self::Mission => "MISSION",
        }
    }

    /// PX4 (main mode, sub-mode).
    pub fn px4_main_sub(self) -> (u32, u32) {
        match self {
            Self::Position => (MAIN_POSCTL, 0),
            Self::Hold => (MAIN_AUTO, SUB_AUTO_LOITER),
            Self::Takeoff => (MAIN_AUTO, SUB_AUTO_TAKEOFF),
            Self::Land => (MAIN_AUTO, SUB_AUTO_LAND),
            Self::Offboard => (MAIN_OFFBOARD, 0),
            Self::Orbit => (MAIN_POSCTL, SUB_POSCTL_ORBIT),
            Self::FollowTarget => (MAIN_AUTO, SUB_AUTO_FOLLOW_TARGET),
            Self::Rtl => (MAIN_AUTO, SUB_AUTO_RTL),
            Self::Mission => (MAIN_AUTO, SUB_AUTO_MISSION),
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
            (MAIN_POSCTL, SUB_POSCTL_ORBIT) => Some(Self::Orbit),
            (MAIN_POSCTL, _) => Some(Self::Position),
            (MAIN_OFFBOARD, _) => Some(Self::Offboard),
            (MAIN_AUTO, SUB_AUTO_LOITER) => Some(Self::Hold),
            (MAIN_AUTO, SUB_AUTO_TAKEOFF) => Some(Self::Takeoff),
            (MAIN_AUTO, SUB_AUTO_LAND) => Some(Self::Land),
            (MAIN_AUTO, SUB_AUTO_FOLLOW_TARGET) => Some(Self::FollowTarget),
            (MAIN_AUTO, SUB_AUTO_RTL) => Some(Self::Rtl),
            (MAIN_AUTO, SUB_AUTO_MISSION) => Some(Self::Mission),
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
}

/// HEARTBEAT `base_mode` of a PX4 vehicle: custom mode enabled, plus `SAFETY_ARMED` if armed.
pub fn base_mode(armed: bool) -> MavModeFlag {
    let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    if armed {
        base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    base
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn custom_mode_encoding_round_trips() {
        for m in FlightMode::ALL {
            let c = m.px4_custom_mode();
            assert_eq!(FlightMode::from_px4((c >> 16) & 0xFF, c >> 24), Some(m));
            assert_eq!(FlightMode::from_custom_mode(c), Some(m));
        }
        // pymavlink's px4_map: LOITER = main 4, sub 3; OFFBOARD = main 6.
        assert_eq!(FlightMode::Hold.px4_custom_mode(), (4 << 16) | (3 << 24));
        assert_eq!(FlightMode::Offboard.px4_custom_mode(), 6 << 16);
        assert_eq!(FlightMode::Offboard.set_mode_params(), [1.0, 6.0, 0.0]);
        // pymavlink's px4_map: MISSION = main 4, sub 4; RTL = main 4, sub 5.
        assert_eq!(FlightMode::from_px4(4, 4), Some(FlightMode::Mission));
        assert_eq!(FlightMode::Rtl.px4_custom_mode(), (4 << 16) | (5 << 24));
        assert_eq!(FlightMode::from_px4(4, 7), None); // RTGS
    }
}
