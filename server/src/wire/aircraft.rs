//! Manned aircraft from ADS-B as the API sends them (`GET /api/v1/aircraft`): tracks of their
//! own kind, keyed by their 24-bit address, never mixed with the ground tracks.

use harrier_core::linalg::ellipse_axes;
use harrier_core::tracker::identified::IdentifiedTrack;
use harrier_link::geo::LocalFrame;
use nalgebra::{Matrix2, Vector3};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// What an aircraft said of itself beyond its kinematics.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AircraftInfo {
    /// Flight identification.
    pub callsign: Option<String>,
    /// Mode A code.
    pub squawk: Option<u16>,
    /// On the ground.
    pub on_ground: Option<bool>,
    /// Lines of it received.
    pub messages: u64,
    /// UNIX time of its last line, s.
    pub heard_unix: f64,
}

/// One aircraft.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct AircraftDto {
    /// 24-bit address, 6 upper-case hex digits; prefixed with `~` when it is not an ICAO address
    /// (TIS-B, anonymous).
    pub icao: String,
    /// Flight identification (callsign), when received.
    pub callsign: Option<String>,
    /// Mode A code, 4 octal digits, when received.
    pub squawk: Option<String>,
    /// On the ground, when reported.
    pub on_ground: Option<bool>,
    /// UNIX time of the estimate (its last report's arrival), s.
    pub time_unix: f64,
    /// Seconds from the estimate to the list's `time_unix`.
    pub age_s: f64,
    /// Latitude of the estimate, degrees WGS-84.
    pub lat_deg: f64,
    /// Longitude of the estimate, degrees WGS-84.
    pub lon_deg: f64,
    /// Altitude of the estimate, m (the reported pressure altitude, taken as height above the
    /// WGS-84 ellipsoid: it differs from the geometric height by the day's pressure and the
    /// geoid, up to a few hundred metres).
    pub altitude_m: f64,
    /// Estimate `[x, y, z, vx, vy, vz]` in the server's ENU frame (m, m/s).
    pub state: [f64; 6],
    /// Course over ground, degrees from true north where the aircraft is.
    pub course_deg: f64,
    /// Ground speed, m/s.
    pub speed_mps: f64,
    /// Climb rate, m/s (up).
    pub climb_mps: f64,
    /// One-sigma horizontal position error of the estimate (largest axis), m.
    pub sigma_h_m: f64,
    /// Reports that updated its track.
    pub updates: u64,
    /// Lines of it received.
    pub messages: u64,
}

/// The state of the connection to the ADS-B receiver.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AdsbFeedState {
    /// `[adsb]` is off.
    #[default]
    Off,
    /// Connecting, or waiting to connect again.
    Connecting,
    /// Connected; lines arrive.
    Connected,
}

/// `GET /api/v1/aircraft`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct AircraftList {
    /// UNIX time at which the list was made, s.
    pub time_unix: f64,
    /// The receiver connection.
    pub feed: AdsbFeedState,
    /// Every aircraft, by address.
    pub aircraft: Vec<AircraftDto>,
}

/// The address as the API writes it.
pub fn icao_text(key: u32) -> String {
    let hex = format!("{:06X}", key & 0xFF_FFFF);
    if key >> 24 == 0 {
        hex
    } else {
        format!("~{hex}")
    }
}

/// The API's aircraft `key` (its address, bit 24 set for a non-ICAO one) from its track, seen at
/// `now_unix`. `None` when the estimate is not finite.
pub fn aircraft_dto(
    key: u32,
    track: &IdentifiedTrack,
    info: &AircraftInfo,
    frame: &LocalFrame,
    now_unix: f64,
) -> Option<AircraftDto> {
    let m = &track.state.mean;
    let state: [f64; 6] = std::array::from_fn(|i| m[i]);
    if !state.iter().all(|v| v.is_finite()) {
        return None;
    }
    let geo = frame.from_enu(&Vector3::new(m[0], m[1], m[2]));
    // Course, speed and climb in the aircraft's own ENU axes (true north where it is).
    let v = frame.rotation_to(&LocalFrame::new(geo)) * Vector3::new(m[3], m[4], m[5]);
    let [vx, vy, vz] = [v.x, v.y, v.z];
    let h = Matrix2::from(track.state.cov.fixed_view::<2, 2>(0, 0));
    let ([sigma_h, _], _) = ellipse_axes(&h);
    Some(AircraftDto {
        icao: icao_text(key),
        callsign: info.callsign.clone(),
        squawk: info.squawk.map(|s| format!("{s:04o}")),
        on_ground: info.on_ground,
        time_unix: track.t,
        age_s: (now_unix - track.t).max(0.0),
        lat_deg: geo.lat_deg,
        lon_deg: geo.lon_deg,
        altitude_m: geo.alt_m,
        state,
        course_deg: vx.atan2(vy).to_degrees().rem_euclid(360.0),
        speed_mps: vx.hypot(vy),
        climb_mps: vz,
        sigma_h_m: sigma_h,
        updates: track.updates,
        messages: info.messages,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;
    use harrier_core::tracker::identified::{IdentifiedConfig, IdentifiedTracks, Report};

    #[test]
    fn an_aircraft_as_the_api_sends_it() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let mut tracks = IdentifiedTracks::new(IdentifiedConfig {
            q: 1.0,
            position_std: [10.0, 10.0, 10.0],
            velocity_std: [1.0; 3],
            initial_velocity_std: 300.0,
            gate_nis: 30.0,
            max_rejects: 3,
            stale_s: 60.0,
            late_tolerance_s: 1.0,
        })
        .unwrap();
        let key = 0x4C_A2D6;
        tracks.report(
            key,
            100.0,
            Report::Position(Vector3::new(1000.0, 2000.0, 3000.0)),
        );
        tracks.report(key, 100.5, Report::Velocity(Vector3::new(-100.0, 0.0, 2.0)));
        let info = AircraftInfo {
            callsign: Some("RYR4TX".into()),
            squawk: Some(0o7000),
            on_ground: Some(false),
            messages: 5,
            heard_unix: 100.5,
        };
        let a = aircraft_dto(key, tracks.get(&key).unwrap(), &info, &frame, 101.0).unwrap();
        assert_eq!(a.icao, "4CA2D6");
        assert_eq!(a.squawk.as_deref(), Some("7000"));
        assert_eq!(a.time_unix, 100.5);
        assert_eq!(a.age_s, 0.5);
        assert!((a.course_deg - 270.0).abs() < 1.0, "{}", a.course_deg);
        assert!((a.speed_mps - 100.0).abs() < 2.0, "{}", a.speed_mps);
        assert!(a.sigma_h_m > 1.0 && a.sigma_h_m < 60.0, "{}", a.sigma_h_m);
        let back = frame.to_enu(&harrier_link::geo::Geodetic {
            lat_deg: a.lat_deg,
            lon_deg: a.lon_deg,
            alt_m: a.altitude_m,
        });
        assert!((back - Vector3::new(a.state[0], a.state[1], a.state[2])).norm() < 1e-3);
        assert_eq!(icao_text(0x0100_ABCD), "~00ABCD");
    }
}
