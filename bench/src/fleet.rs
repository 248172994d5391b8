//! The vehicles' MAVLink side (`--mavlink`): one PX4-like harrier-sim vehicle per simulated
//! vehicle, all on a few fleet threads of this process ([`harrier_sim::net::spawn_fleet`]), each
//! on its own UDP socket sending to the server's GCS link, as PX4 SITL instances do. They stream
//! telemetry (GLOBAL_POSITION_INT, LOCAL_POSITION_NED and ATTITUDE at `--telemetry-hz`, the
//! other streams at their PX4 rates), answer commands and fly offboard setpoints, so the
//! guidance can fly them.
//!
//! Their homes are a grid 20 m apart south of the targets, on the server's frame.

use std::net::SocketAddr;
use std::time::Duration;

use anyhow::Context as _;
use harrier_core::detection::GeoPoint;
use harrier_link::geo::LocalFrame;
use harrier_link::mavlink::MessageData as _;
use harrier_link::mavlink::dialects::common::{
    ATTITUDE_DATA, COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, LOCAL_POSITION_NED_DATA, MavCmd,
    MavMessage,
};
use harrier_sim::net::{FleetHandle, LinkConfig, spawn_fleet};
use harrier_sim::vehicle::VehicleConfig;
use nalgebra::Vector3;
use std::sync::atomic::Ordering::Relaxed;

/// Vehicles per fleet thread.
const PER_THREAD: usize = 128;
/// Pass period of a fleet thread: telemetry leaves at most this late.
const TICK: Duration = Duration::from_millis(10);
/// Spacing of the vehicles' homes (m).
const HOME_SPACING_M: f64 = 20.0;

/// The flying vehicles.
#[derive(Debug)]
pub(super) struct Fleet {
    handle: FleetHandle,
}

/// The streams `--telemetry-hz` sets.
const FAST_STREAMS: [u32; 3] = [
    GLOBAL_POSITION_INT_DATA::ID,
    LOCAL_POSITION_NED_DATA::ID,
    ATTITUDE_DATA::ID,
];

/// Vehicle `k`'s home: a grid of 16 columns south of the frame's origin.
fn home(frame: &LocalFrame, k: usize) -> GeoPoint {
    let (row, col) = ((k / 16) as f64, (k % 16) as f64);
    frame.from_enu(&Vector3::new(
        (col - 7.5) * HOME_SPACING_M,
        -600.0 - row * HOME_SPACING_M,
        0.0,
    ))
}

impl Fleet {
    /// Starts vehicles `ids`, sending to `gcs`, streaming at `telemetry_hz`.
    pub(super) fn start(
        ids: &[u8],
        gcs: SocketAddr,
        telemetry_hz: f64,
        origin: GeoPoint,
    ) -> anyhow::Result<Self> {
        let frame = LocalFrame::new(origin);
        let members = ids
            .iter()
            .enumerate()
            .map(|(k, &id)| {
                let config = VehicleConfig {
                    origin: home(&frame, k),
                    ..VehicleConfig::new(id)
                };
                let links = LinkConfig {
                    endpoints: vec![format!("udpout:{gcs}")],
                    signing: None,
                };
                (config, links)
            })
            .collect();
        let handle = spawn_fleet(members, ids.len().div_ceil(PER_THREAD), TICK)
            .context("starting the MAVLink vehicles")?;
        let interval_us = (1e6 / telemetry_hz) as f32;
        for k in 0..handle.len() {
            let mut v = handle.vehicle(k);
            let now = v.sim_time();
            for id in FAST_STREAMS {
                let set = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                    command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                    param1: id as f32,
                    param2: interval_us,
                    ..COMMAND_LONG_DATA::DEFAULT
                });
                v.handle(now, &set);
            }
        }
        Ok(Self { handle })
    }

    /// Vehicles that heard the ground station's HEARTBEAT.
    pub(super) fn hearing_gcs(&self) -> usize {
        (0..self.handle.len())
            .filter(|&k| self.handle.counters(k).gcs_heartbeats.load(Relaxed) > 0)
            .count()
    }

    /// Stops the vehicles: the frames they sent in all.
    pub(super) fn stop(self) -> u64 {
        self.handle.stop()
    }
}
