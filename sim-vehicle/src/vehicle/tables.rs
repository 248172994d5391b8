//! The vehicle's tables, data without behaviour: its parameters ([`Param`], the defaults) and
//! its telemetry streams ([`Stream`], [`STREAMS`] and their default intervals).

use mavlink::MessageData;
use mavlink::dialects::common::{
    ATTITUDE_DATA, BATTERY_STATUS_DATA, EXTENDED_SYS_STATE_DATA, GLOBAL_POSITION_INT_DATA,
    GPS_RAW_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA, SYS_STATUS_DATA,
};

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

/// The parameters a vehicle starts with.
pub(super) fn default_params() -> Vec<Param> {
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
pub(super) const STREAMS: [(u32, f64); 9] = [
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

/// The streams at their default intervals, all due at wall time `now`.
pub(super) fn default_streams(now: f64) -> Vec<Stream> {
    STREAMS
        .iter()
        .map(|&(id, dt)| Stream {
            id,
            default_interval: dt,
            interval: Some(dt),
            next_due: now,
        })
        .collect()
}
