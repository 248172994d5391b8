//! A feed that happens to send through the MAVLink link (it reads the tracker, the link never
//! does): Harrier's tracks offered to the router's MAVLink clients as traffic: every confirmed
//! track, at
//! `mavlink.tracks_hz`, as one ADSB_VEHICLE message from the ground station: the traffic
//! message MAVProxy's `adsb` module and QGroundControl's ADS-B display read (tested with
//! pymavlink). Sent to the router's clients only, never to the vehicles (an autopilot would take
//! it for traffic to avoid).
//!
//! | field | value |
//! |---|---|
//! | `ICAO_address` | the track id (mod 2²⁴) |
//! | `callsign` | `T` and the track id (`T12`), as the dashboard names it |
//! | `lat`, `lon`, `altitude` | the estimate's position converted from the server's ENU frame (WGS-84 degE7; mm above the frame origin's datum, `ADSB_ALTITUDE_TYPE_GEOMETRIC`) |
//! | `heading`, `hor_velocity`, `ver_velocity` | course over ground (cdeg from north), ground speed (cm/s) and climb rate (cm/s, up) of the estimate |
//! | `tslc` | seconds since the track's last detection (0–255) |
//! | `emitter_type` | `ADSB_EMITTER_TYPE_NO_INFO` |
//! | `flags` | coordinates, altitude, heading, velocity, vertical velocity and callsign valid |
//!
//! The estimate is the track's at its last scan (the tracker's time line), not predicted on.

use std::sync::Arc;
use std::time::Duration;

use harrier_link::geo::LocalFrame;
use harrier_link::mavlink::dialects::common::{
    ADSB_VEHICLE_DATA, AdsbAltitudeType, AdsbEmitterType, AdsbFlags, MavMessage,
};
use nalgebra::Vector3;
use tokio::sync::watch;

use crate::gcs::transport::stopped;
use crate::gcs::{GcsLink, Request};
use crate::tracker::Snapshot;
use harrier_engine::{TrackStatus, TrackView};

/// The ADSB_VEHICLE message of a confirmed track, `None` for a tentative one or an estimate
/// that is not finite.
pub fn adsb_vehicle(track: &TrackView, frame: &LocalFrame) -> Option<MavMessage> {
    if track.status != TrackStatus::Confirmed || !track.state.iter().all(|v| v.is_finite()) {
        return None;
    }
    let [x, y, z, vx, vy, vz] = track.state;
    let geo = frame.from_enu(&Vector3::new(x, y, z));
    let (lat, lon) = (geo.lat_deg * 1e7, geo.lon_deg * 1e7);
    let altitude_mm = geo.alt_m * 1e3;
    if !(lat.is_finite() && lon.is_finite() && altitude_mm.is_finite()) {
        return None;
    }
    let course = vx.atan2(vy).to_degrees().rem_euclid(360.0);
    let since = (track.t - track.last_update).max(0.0);
    Some(MavMessage::ADSB_VEHICLE(ADSB_VEHICLE_DATA {
        ICAO_address: (track.id & 0xFF_FFFF) as u32,
        lat: lat.round() as i32,
        lon: lon.round() as i32,
        // `as` saturates: a track far outside i32 millimetres stays at the bound.
        altitude: altitude_mm.round() as i32,
        heading: ((course * 100.0).round() as u16) % 36_000,
        hor_velocity: (vx.hypot(vy) * 100.0).round() as u16,
        ver_velocity: (vz * 100.0).round() as i16,
        flags: AdsbFlags::ADSB_FLAGS_VALID_COORDS
            | AdsbFlags::ADSB_FLAGS_VALID_ALTITUDE
            | AdsbFlags::ADSB_FLAGS_VALID_HEADING
            | AdsbFlags::ADSB_FLAGS_VALID_VELOCITY
            | AdsbFlags::ADSB_FLAGS_VERTICAL_VELOCITY_VALID
            | AdsbFlags::ADSB_FLAGS_VALID_CALLSIGN,
        squawk: 0,
        altitude_type: AdsbAltitudeType::ADSB_ALTITUDE_TYPE_GEOMETRIC,
        callsign: format!("T{}", track.id).as_str().into(),
        emitter_type: AdsbEmitterType::ADSB_EMITTER_TYPE_NO_INFO,
        tslc: since.min(255.0) as u8,
    }))
}

/// Sends every confirmed track of the tracker's latest snapshot to the router's clients,
/// `hz` times a second, until `stop` (or the link stops). Never waits on the link: when its
/// request queue is full, that round is skipped.
pub async fn run(
    link: GcsLink,
    mut snapshot: watch::Receiver<Arc<Snapshot>>,
    frame: LocalFrame,
    hz: f64,
    mut stop: watch::Receiver<bool>,
) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            () = stopped(&mut stop) => return,
        }
        let tracks = Arc::clone(&snapshot.borrow_and_update().tracks);
        let messages: Vec<MavMessage> = tracks
            .iter()
            .filter_map(|t| adsb_vehicle(t, &frame))
            .collect();
        if messages.is_empty() {
            continue;
        }
        match link.requests.try_send(Request::ToClients(messages)) {
            Ok(()) | Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {}
            Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    fn track(status: TrackStatus, state: [f64; 6]) -> TrackView {
        TrackView {
            id: 12,
            status,
            t: 100.0,
            state,
            cov: Vec::new(),
            cov_dims: Vec::new(),
            updated: true,
            age: 30,
            last_update: 97.5,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    #[test]
    fn a_confirmed_track_becomes_traffic_where_it_is() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        // 300 m east, 400 m north, 20 m up; 3 m/s east, 4 m/s north (course 36.87°), 1 m/s up.
        let t = track(TrackStatus::Confirmed, [300.0, 400.0, 20.0, 3.0, 4.0, 1.0]);
        let Some(MavMessage::ADSB_VEHICLE(a)) = adsb_vehicle(&t, &frame) else {
            panic!("no ADSB_VEHICLE");
        };
        let back = frame.to_enu(&harrier_link::geo::Geodetic {
            lat_deg: f64::from(a.lat) / 1e7,
            lon_deg: f64::from(a.lon) / 1e7,
            alt_m: f64::from(a.altitude) / 1e3,
        });
        // degE7 is 1.1 cm of latitude.
        assert!(
            (back - Vector3::new(300.0, 400.0, 20.0)).norm() < 0.05,
            "{back}"
        );
        assert_eq!(a.ICAO_address, 12);
        assert_eq!(a.callsign.to_str(), Ok("T12"));
        assert_eq!(a.heading, 3687);
        assert_eq!(a.hor_velocity, 500);
        assert_eq!(a.ver_velocity, 100);
        assert_eq!(a.tslc, 2);
    }

    #[test]
    fn tentative_or_non_finite_tracks_are_not_sent() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        assert!(adsb_vehicle(&track(TrackStatus::Tentative, [0.0; 6]), &frame).is_none());
        let nan = track(TrackStatus::Confirmed, [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert!(adsb_vehicle(&nan, &frame).is_none());
        let inf = track(
            TrackStatus::Confirmed,
            [0.0, 0.0, 0.0, f64::INFINITY, 0.0, 0.0],
        );
        assert!(adsb_vehicle(&inf, &frame).is_none());
        // West and due south: courses 270° and 180°, within [0, 360).
        let west = track(TrackStatus::Confirmed, [0.0, 0.0, 0.0, -2.0, 0.0, 0.0]);
        let Some(MavMessage::ADSB_VEHICLE(a)) = adsb_vehicle(&west, &frame) else {
            panic!("no ADSB_VEHICLE");
        };
        assert_eq!(a.heading, 27_000);
        let south = track(TrackStatus::Confirmed, [0.0, 0.0, 0.0, 0.0, -2.0, 0.0]);
        let Some(MavMessage::ADSB_VEHICLE(a)) = adsb_vehicle(&south, &frame) else {
            panic!("no ADSB_VEHICLE");
        };
        assert_eq!(a.heading, 18_000);
    }
}
