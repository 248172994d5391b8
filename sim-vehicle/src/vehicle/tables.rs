//! The vehicle's tables, data without behaviour: its parameters ([`Param`], the defaults of
//! each personality) and its telemetry streams ([`Stream`], [`STREAMS`] and their default
//! intervals, ArduPilot's data-stream groups).
//!
//! The parameters are the ones clients read and the simulation flies by, with the real
//! autopilots' names, types and defaults: PX4's (REAL32, sent bytewise) and ArduPilot's (their
//! own integer and float types, sent as C-cast floats): SYSID_THISMAV, ARMING_CHECK,
//! DISARM_DELAY, WPNAV_SPEED (cm/s), RTL_ALT (cm) … for ArduCopter; AIRSPEED_MIN,
//! AIRSPEED_CRUISE, AIRSPEED_MAX, ROLL_LIMIT_DEG, WP_LOITER_RAD, TKOFF_ALT, RTL_ALTITUDE …
//! for ArduPlane; FW_AIRSPD_MIN/TRIM/MAX/STALL, FW_R_LIM, NAV_LOITER_RAD for a PX4 fixed wing;
//! FLW_TGT_DST, FLW_TGT_HT (AUTO.FOLLOW_TARGET) for a PX4 multirotor; RTL_RETURN_ALT,
//! RTL_DESCEND_ALT and the battery failsafe's BAT_*_THR, COM_LOW_BAT_ACT (PX4) and BATT_*
//! (ArduPilot).

use harrier_link::autopilot::{Autopilot, Frame, Personality};
use mavlink::MessageData;
use mavlink::dialects::common::{
    ATTITUDE_DATA, BATTERY_STATUS_DATA, EXTENDED_SYS_STATE_DATA, GLOBAL_POSITION_INT_DATA,
    GPS_RAW_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, MavParamType, SYS_STATUS_DATA, VFR_HUD_DATA,
};

/// A tunable parameter.
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
    /// Its type on the wire.
    pub kind: MavParamType,
}

const fn real(name: &'static str, value: f32, min: f32, max: f32) -> Param {
    Param {
        name,
        value,
        min,
        max,
        kind: MavParamType::MAV_PARAM_TYPE_REAL32,
    }
}

const fn int(name: &'static str, kind: MavParamType, value: f32, min: f32, max: f32) -> Param {
    Param {
        name,
        value,
        min,
        max,
        kind,
    }
}

const I8: MavParamType = MavParamType::MAV_PARAM_TYPE_INT8;
const I16: MavParamType = MavParamType::MAV_PARAM_TYPE_INT16;
const I32: MavParamType = MavParamType::MAV_PARAM_TYPE_INT32;

/// The parameters a vehicle of `personality` with system id `id` starts with.
pub(super) fn default_params(personality: Personality, id: u8) -> Vec<Param> {
    let id = f32::from(id);
    match (personality.autopilot, personality.frame) {
        (Autopilot::Px4, frame) => {
            let mut p = vec![
                real("MIS_TAKEOFF_ALT", 2.5, 0.5, 500.0),
                real("COM_OF_LOSS_T", 0.5, 0.1, 60.0),
                real("MPC_LAND_SPEED", 0.7, 0.1, 5.0),
                // RTL: the return altitude (climbed to if lower) and, for a fixed wing, the
                // loiter altitude over home.
                real("RTL_RETURN_ALT", 60.0, 0.0, 1000.0),
                real("RTL_DESCEND_ALT", 30.0, 2.0, 500.0),
                // The battery's warning levels (remaining charge) and the low-battery
                // failsafe: 0 warning, 2 Land at critical, 3 Return at critical and Land at
                // emergency.
                real("BAT_LOW_THR", 0.15, 0.12, 0.5),
                real("BAT_CRIT_THR", 0.07, 0.05, 0.25),
                real("BAT_EMERGEN_THR", 0.05, 0.03, 0.1),
                int("COM_LOW_BAT_ACT", I32, 0.0, 0.0, 3.0),
                // A mission waypoint's default acceptance radius (rc.mc_defaults: 2 m).
                real(
                    "NAV_ACC_RAD",
                    if frame == Frame::Multirotor {
                        2.0
                    } else {
                        10.0
                    },
                    0.05,
                    200.0,
                ),
            ];
            if frame == Frame::Multirotor {
                // Auto modes' horizontal cruise speed, descent speed, and the height below
                // which a landing slows to MPC_LAND_SPEED.
                p.extend([
                    real("MPC_XY_CRUISE", 5.0, 3.0, 20.0),
                    real("MPC_Z_V_AUTO_DN", 1.5, 0.5, 4.0),
                    real("MPC_LAND_ALT1", 10.0, 0.0, 122.0),
                ]);
            }
            if frame == Frame::Multirotor {
                // AUTO.FOLLOW_TARGET: distance from and height above the target, the angle
                // around it (0 in front, 180 behind, positive clockwise), responsiveness,
                // altitude mode (0 2-D, 1 2-D with terrain, 2 3-D) and top speed.
                p.extend([
                    real("FLW_TGT_DST", 8.0, 1.0, 100.0),
                    real("FLW_TGT_HT", 8.0, 8.0, 100.0),
                    real("FLW_TGT_FA", 180.0, -180.0, 180.0),
                    real("FLW_TGT_RS", 0.1, 0.0, 1.0),
                    int("FLW_TGT_ALT_M", I32, 0.0, 0.0, 2.0),
                    real("FLW_TGT_MAX_VEL", 5.0, 0.0, 20.0),
                ]);
            }
            if frame == Frame::FixedWing {
                p.extend([
                    real("FW_AIRSPD_STALL", 7.0, 0.5, 40.0),
                    real("FW_AIRSPD_MIN", 10.0, 0.5, 40.0),
                    real("FW_AIRSPD_TRIM", 15.0, 0.5, 40.0),
                    real("FW_AIRSPD_MAX", 20.0, 0.5, 40.0),
                    real("FW_R_LIM", 50.0, 35.0, 65.0),
                    real("FW_T_CLMB_MAX", 5.0, 1.0, 15.0),
                    real("NAV_LOITER_RAD", 80.0, 25.0, 1000.0),
                ]);
            }
            p
        }
        (Autopilot::ArduPilot, Frame::Multirotor) => vec![
            int("SYSID_THISMAV", I16, id, 1.0, 255.0),
            int("SYSID_MYGCS", I16, 255.0, 1.0, 255.0),
            int("FRAME_CLASS", I8, 1.0, 0.0, 15.0),
            int("ARMING_CHECK", I32, 1.0, 0.0, 1_048_575.0),
            int("DISARM_DELAY", I8, 10.0, 0.0, 127.0),
            real("WPNAV_SPEED", 1000.0, 10.0, 2000.0),
            real("WPNAV_SPEED_UP", 250.0, 10.0, 1000.0),
            real("WPNAV_SPEED_DN", 150.0, 10.0, 500.0),
            int("LAND_SPEED", I16, 50.0, 30.0, 200.0),
            int("RTL_ALT", I32, 1500.0, 200.0, 300_000.0),
            real("PILOT_TKOFF_ALT", 0.0, 0.0, 1000.0),
            real("GUID_TIMEOUT", 3.0, 0.1, 5.0),
            real("WPNAV_RADIUS", 200.0, 5.0, 1000.0),
            int("BATT_CAPACITY", I32, 3300.0, 0.0, 1_000_000.0),
            real("BATT_LOW_VOLT", 10.5, 0.0, 100.0),
            real("BATT_LOW_MAH", 0.0, 0.0, 1_000_000.0),
            real("BATT_CRT_VOLT", 0.0, 0.0, 100.0),
            real("BATT_CRT_MAH", 0.0, 0.0, 1_000_000.0),
            int("BATT_FS_LOW_ACT", I8, 0.0, 0.0, 7.0),
            int("BATT_FS_CRT_ACT", I8, 0.0, 0.0, 7.0),
        ],
        (Autopilot::ArduPilot, Frame::FixedWing) => vec![
            int("SYSID_THISMAV", I16, id, 1.0, 255.0),
            int("SYSID_MYGCS", I16, 255.0, 1.0, 255.0),
            int("ARMING_CHECK", I32, 1.0, 0.0, 1_048_575.0),
            int("AIRSPEED_MIN", I16, 9.0, 5.0, 100.0),
            real("AIRSPEED_CRUISE", 15.0, 5.0, 100.0),
            int("AIRSPEED_MAX", I16, 22.0, 5.0, 100.0),
            real("ROLL_LIMIT_DEG", 45.0, 0.0, 90.0),
            int("WP_LOITER_RAD", I16, 60.0, -32767.0, 32767.0),
            int("TKOFF_ALT", I16, 50.0, 0.0, 300.0),
            real("RTL_ALTITUDE", 100.0, -1.0, 5000.0),
            real("TECS_CLMB_MAX", 5.0, 0.1, 20.0),
            int("WP_RADIUS", I16, 90.0, 1.0, 32767.0),
            int("BATT_CAPACITY", I32, 3300.0, 0.0, 1_000_000.0),
            real("BATT_LOW_VOLT", 0.0, 0.0, 100.0),
            real("BATT_LOW_MAH", 0.0, 0.0, 1_000_000.0),
            real("BATT_CRT_VOLT", 0.0, 0.0, 100.0),
            real("BATT_CRT_MAH", 0.0, 0.0, 1_000_000.0),
            int("BATT_FS_LOW_ACT", I8, 0.0, 0.0, 7.0),
            int("BATT_FS_CRT_ACT", I8, 0.0, 0.0, 7.0),
        ],
    }
}

/// Telemetry streams and their default intervals (s).
pub(super) const STREAMS: [(u32, f64); 10] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 1.0),
    (EXTENDED_SYS_STATE_DATA::ID, 1.0),
    (BATTERY_STATUS_DATA::ID, 1.0),
    (HOME_POSITION_DATA::ID, 2.0),
    (GPS_RAW_INT_DATA::ID, 0.2),
    (GLOBAL_POSITION_INT_DATA::ID, 0.1),
    (LOCAL_POSITION_NED_DATA::ID, 0.1),
    (ATTITUDE_DATA::ID, 0.1),
    (MISSION_CURRENT_DATA::ID, 1.0),
];

/// ArduPilot's extra stream: VFR_HUD (its SRn_EXTRA2 group), 4 Hz.
const ARDUPILOT_STREAMS: [(u32, f64); 1] = [(VFR_HUD_DATA::ID, 0.25)];

/// The messages of an ArduPilot data stream (REQUEST_DATA_STREAM `req_stream_id`,
/// `MAV_DATA_STREAM`, GCS_Common's `STREAM_*` groups) among those the simulator sends; 0 is
/// every stream but the HEARTBEAT.
pub(super) fn data_stream(id: u8) -> &'static [u32] {
    match id {
        0 => &[
            SYS_STATUS_DATA::ID,
            EXTENDED_SYS_STATE_DATA::ID,
            BATTERY_STATUS_DATA::ID,
            GPS_RAW_INT_DATA::ID,
            GLOBAL_POSITION_INT_DATA::ID,
            LOCAL_POSITION_NED_DATA::ID,
            ATTITUDE_DATA::ID,
            VFR_HUD_DATA::ID,
            MISSION_CURRENT_DATA::ID,
        ],
        // EXTENDED_STATUS
        2 => &[
            SYS_STATUS_DATA::ID,
            GPS_RAW_INT_DATA::ID,
            EXTENDED_SYS_STATE_DATA::ID,
            MISSION_CURRENT_DATA::ID,
        ],
        // POSITION
        6 => &[GLOBAL_POSITION_INT_DATA::ID, LOCAL_POSITION_NED_DATA::ID],
        // EXTRA1
        10 => &[ATTITUDE_DATA::ID],
        // EXTRA2
        11 => &[VFR_HUD_DATA::ID],
        // EXTRA3
        12 => &[BATTERY_STATUS_DATA::ID],
        _ => &[],
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Stream {
    /// Message id.
    pub(super) id: u32,
    /// Interval at start and after a reset (s).
    pub(super) default_interval: f64,
    /// Interval (s); `None` when disabled.
    pub(super) interval: Option<f64>,
    /// Wall time it is next due.
    pub(super) next_due: f64,
}

/// The streams of `personality` at their default intervals, all due at wall time `now`.
pub(super) fn default_streams(personality: Personality, now: f64) -> Vec<Stream> {
    let extra: &[(u32, f64)] = match personality.autopilot {
        Autopilot::Px4 => &[],
        Autopilot::ArduPilot => &ARDUPILOT_STREAMS,
    };
    STREAMS
        .iter()
        .chain(extra)
        .map(|&(id, dt)| Stream {
            id,
            default_interval: dt,
            interval: Some(dt),
            next_due: now,
        })
        .collect()
}
