//! ArduPilot's flight modes as MAVLink carries them, for Copter and Plane, and ArduPilot's
//! reading of a guided target's type mask.
//!
//! **Modes.** An ArduPilot vehicle's HEARTBEAT `custom_mode` is its mode number
//! (`MAV_MODE_FLAG_CUSTOM_MODE_ENABLED` in `base_mode`): ArduCopter's `Mode::Number`
//! (`ArduCopter/mode.h`: STABILIZE 0, AUTO 3, GUIDED 4, LOITER 5, RTL 6, LAND 9, …) and
//! ArduPlane's (`ArduPlane/mode.h`: MANUAL 0, AUTO 10, RTL 11, LOITER 12, TAKEOFF 13, GUIDED 15,
//! …), told apart by the HEARTBEAT's MAV_TYPE. A ground station selects one with
//! `MAV_CMD_DO_SET_MODE` (param1 `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED`, param2 the number; what
//! pymavlink's `set_mode_apm` sends) or the SET_MODE message (`custom_mode` the number).
//! [`CopterMode`] and [`PlaneMode`] hold every number with the name pymavlink's
//! `mode_mapping_acm` / `mode_mapping_apm` give it, the names MAVProxy prints.
//!
//! **Guided targets** ([`TargetMask`]): ArduCopter reads SET_POSITION_TARGET_LOCAL_NED and
//! SET_POSITION_TARGET_GLOBAL_INT only in GUIDED, and a group of the type mask (position,
//! velocity, acceleration) counts as ignored when *any* of its three bits is set
//! (`GCS_MAVLink_Copter.cpp`, `handle_message_set_position_target_local_ned`: "When providing
//! Pos, Vel and/or Accel all 3 axis must be provided", the "Copter Commands in Guided Mode"
//! developer page).

use mavlink::dialects::common::PositionTargetTypemask;

/// Declares a mode table: the enum, its numbers and its names.
macro_rules! mode_table {
    (
        $(#[$meta:meta])*
        $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $number:literal, $text:literal; )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name {
            $( $(#[$vmeta])* $variant, )*
        }

        impl $name {
            /// Every mode of the table, in number order.
            pub const ALL: &'static [Self] = &[ $( Self::$variant, )* ];

            /// The mode number (HEARTBEAT `custom_mode`, DO_SET_MODE param2).
            pub fn number(self) -> u32 {
                match self {
                    $( Self::$variant => $number, )*
                }
            }

            /// The name MAVProxy prints (pymavlink's mode table).
            pub fn name(self) -> &'static str {
                match self {
                    $( Self::$variant => $text, )*
                }
            }

            /// The mode of a number, if the table has it.
            pub fn from_number(number: u32) -> Option<Self> {
                match number {
                    $( $number => Some(Self::$variant), )*
                    _ => None,
                }
            }

            /// The mode of a name (as [`Self::name`] spells it), if any.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.iter().copied().find(|m| m.name() == name)
            }
        }
    };
}

mode_table! {
    /// ArduCopter's flight modes (`ArduCopter/mode.h`, `Mode::Number`).
    CopterMode {
        /// Manual angle, manual throttle (the mode a Copter boots in without RC).
        Stabilize = 0, "STABILIZE";
        /// Manual body rates.
        Acro = 1, "ACRO";
        /// Manual angle, automatic throttle.
        AltHold = 2, "ALT_HOLD";
        /// The mission.
        Auto = 3, "AUTO";
        /// Fly to a point, a velocity or an attitude from the ground station.
        Guided = 4, "GUIDED";
        /// Hold position and altitude.
        Loiter = 5, "LOITER";
        /// Return to launch, then land.
        Rtl = 6, "RTL";
        /// Circle a point at CIRCLE_RADIUS.
        Circle = 7, "CIRCLE";
        /// Legacy position mode.
        Position = 8, "POSITION";
        /// Land where it is, then disarm.
        Land = 9, "LAND";
        /// Legacy optical-flow loiter.
        OfLoiter = 10, "OF_LOITER";
        /// Drift.
        Drift = 11, "DRIFT";
        /// Sport.
        Sport = 13, "SPORT";
        /// Flip.
        Flip = 14, "FLIP";
        /// Autotune.
        AutoTune = 15, "AUTOTUNE";
        /// Position hold with manual override.
        PosHold = 16, "POSHOLD";
        /// Stop at once and hold.
        Brake = 17, "BRAKE";
        /// Throw to launch.
        Throw = 18, "THROW";
        /// Avoid ADS-B traffic.
        AvoidAdsb = 19, "AVOID_ADSB";
        /// Guided without GPS (attitude and altitude only).
        GuidedNoGps = 20, "GUIDED_NOGPS";
        /// Return along the path flown.
        SmartRtl = 21, "SMART_RTL";
        /// Optical-flow hold.
        FlowHold = 22, "FLOWHOLD";
        /// Follow another vehicle.
        Follow = 23, "FOLLOW";
        /// Zigzag.
        ZigZag = 24, "ZIGZAG";
        /// System identification.
        SystemId = 25, "SYSTEMID";
        /// Helicopter autorotation.
        Autorotate = 26, "AUTOROTATE";
        /// RTL by the mission's landing sequence.
        AutoRtl = 27, "AUTO_RTL";
        /// Turtle.
        Turtle = 28, "TURTLE";
        /// Rate acro.
        RateAcro = 29, "RATE_ACRO";
    }
}

mode_table! {
    /// ArduPlane's flight modes (`ArduPlane/mode.h`, `Mode::Number`).
    PlaneMode {
        /// Manual surfaces (the default INITIAL_MODE).
        Manual = 0, "MANUAL";
        /// Gentle circles (failsafe).
        Circle = 1, "CIRCLE";
        /// Stabilise.
        Stabilize = 2, "STABILIZE";
        /// Training.
        Training = 3, "TRAINING";
        /// Acro.
        Acro = 4, "ACRO";
        /// Fly-by-wire A.
        Fbwa = 5, "FBWA";
        /// Fly-by-wire B.
        Fbwb = 6, "FBWB";
        /// Cruise.
        Cruise = 7, "CRUISE";
        /// Autotune.
        Autotune = 8, "AUTOTUNE";
        /// The mission.
        Auto = 10, "AUTO";
        /// Return home, then loiter there.
        Rtl = 11, "RTL";
        /// Circle where the mode was entered at WP_LOITER_RAD.
        Loiter = 12, "LOITER";
        /// Climb to TKOFF_ALT, then loiter.
        Takeoff = 13, "TAKEOFF";
        /// Avoid ADS-B traffic.
        AvoidAdsb = 14, "AVOID_ADSB";
        /// Loiter around a point (or fly a heading) the ground station gives.
        Guided = 15, "GUIDED";
        /// Booting.
        Initialising = 16, "INITIALISING";
        /// QuadPlane stabilise.
        QStabilize = 17, "QSTABILIZE";
        /// QuadPlane hover.
        QHover = 18, "QHOVER";
        /// QuadPlane loiter.
        QLoiter = 19, "QLOITER";
        /// QuadPlane land.
        QLand = 20, "QLAND";
        /// QuadPlane RTL.
        QRtl = 21, "QRTL";
        /// QuadPlane autotune.
        QAutotune = 22, "QAUTOTUNE";
        /// QuadPlane acro.
        QAcro = 23, "QACRO";
        /// Thermalling.
        Thermal = 24, "THERMAL";
        /// Loiter down, then QLAND.
        LoiterAltQLand = 25, "LOITERALTQLAND";
        /// Automatic landing.
        Autoland = 26, "AUTOLAND";
    }
}

/// Position ignored (x, y, z).
const POSITION_BITS: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_X_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Y_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE);
/// Velocity ignored (vx, vy, vz).
const VELOCITY_BITS: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE);
/// Acceleration ignored (ax, ay, az).
const ACCEL_BITS: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE);

/// Which parts of a SET_POSITION_TARGET_* an ArduCopter flies, read from its type mask as
/// `handle_message_set_position_target_local_ned` reads it: a group is ignored when any of its
/// bits is set; position and velocity → position with a velocity feed-forward, velocity alone
/// (with or without acceleration) → velocity, acceleration alone → acceleration, position alone
/// → position; anything else, or a force flag with an acceleration, is refused (the vehicle
/// then stops and holds where it is).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TargetMask {
    /// Position and velocity.
    PositionVelocity,
    /// Velocity (and acceleration when given).
    Velocity,
    /// Acceleration only.
    Acceleration,
    /// Position only.
    Position,
}

impl TargetMask {
    /// The reading of `mask`, `None` when ArduCopter refuses it.
    pub fn of(mask: PositionTargetTypemask) -> Option<Self> {
        let pos = !mask.intersects(POSITION_BITS);
        let vel = !mask.intersects(VELOCITY_BITS);
        let acc = !mask.intersects(ACCEL_BITS);
        if mask.contains(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_FORCE_SET) && acc {
            return None;
        }
        match (pos, vel, acc) {
            (true, true, _) => Some(Self::PositionVelocity),
            (false, true, _) => Some(Self::Velocity),
            (false, false, true) => Some(Self::Acceleration),
            (true, false, false) => Some(Self::Position),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The numbers of ArduCopter's and ArduPlane's mode.h, and pymavlink's names.
    #[test]
    fn mode_numbers_and_names_are_ardupilots() {
        for (m, n, s) in [
            (CopterMode::Stabilize, 0, "STABILIZE"),
            (CopterMode::Auto, 3, "AUTO"),
            (CopterMode::Guided, 4, "GUIDED"),
            (CopterMode::Loiter, 5, "LOITER"),
            (CopterMode::Rtl, 6, "RTL"),
            (CopterMode::Land, 9, "LAND"),
            (CopterMode::Brake, 17, "BRAKE"),
        ] {
            assert_eq!((m.number(), m.name()), (n, s));
            assert_eq!(CopterMode::from_number(n), Some(m));
            assert_eq!(CopterMode::from_name(s), Some(m));
        }
        for (m, n, s) in [
            (PlaneMode::Manual, 0, "MANUAL"),
            (PlaneMode::Auto, 10, "AUTO"),
            (PlaneMode::Rtl, 11, "RTL"),
            (PlaneMode::Loiter, 12, "LOITER"),
            (PlaneMode::Takeoff, 13, "TAKEOFF"),
            (PlaneMode::Guided, 15, "GUIDED"),
        ] {
            assert_eq!((m.number(), m.name()), (n, s));
            assert_eq!(PlaneMode::from_number(n), Some(m));
            assert_eq!(PlaneMode::from_name(s), Some(m));
        }
        // Gaps in the tables, and every entry round-trips.
        assert_eq!(CopterMode::from_number(12), None);
        assert_eq!(PlaneMode::from_number(9), None);
        for m in CopterMode::ALL {
            assert_eq!(CopterMode::from_number(m.number()), Some(*m));
        }
        for m in PlaneMode::ALL {
            assert_eq!(PlaneMode::from_name(m.name()), Some(*m));
        }
    }

    /// The developer page's masks: position 0x0DF8, velocity 0x0DC7, acceleration 0x0C3F,
    /// position and velocity 0x0DC0; a partly given group counts as ignored.
    #[test]
    fn type_masks_are_read_as_ardupilot_reads_them() {
        let m = |bits: u16| TargetMask::of(PositionTargetTypemask::from_bits_truncate(bits));
        assert_eq!(m(0x0DF8), Some(TargetMask::Position));
        assert_eq!(m(0x0DC7), Some(TargetMask::Velocity));
        assert_eq!(m(0x0C3F), Some(TargetMask::Acceleration));
        assert_eq!(m(0x0DC0), Some(TargetMask::PositionVelocity));
        assert_eq!(m(0x0C07), Some(TargetMask::Velocity)); // velocity and acceleration
        // x ignored only: the position group is ignored, velocity too: nothing left.
        assert_eq!(m(0x0DF9), None);
        // Only vx ignored among velocity, position ignored: velocity group ignored → acceleration
        // group ignored as well → refused.
        assert_eq!(m(0x0DCF), None);
        assert_eq!(m(0x0FFF), None);
        // Force with an acceleration is refused.
        assert_eq!(m(0x0C3F | 0x0200), None);
    }
}
