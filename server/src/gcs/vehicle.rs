//! What the ground station knows of one vehicle from its MAVLink telemetry: its autopilot and
//! airframe, flight mode in that autopilot's table and armed state (HEARTBEAT: PX4, ArduCopter,
//! ArduPlane), position and velocity (GLOBAL_POSITION_INT, in the server's ENU frame),
//! attitude (ATTITUDE), battery (SYS_STATUS), and the link's quality: message rate over the last
//! second and frames lost, from the gaps in the sender's MAVLink sequence numbers.

use std::collections::HashMap;
use std::time::Instant;

use harrier_core::detection::GeoPoint;
use harrier_link::autopilot::{Autopilot, Frame, VehicleStatus};
use harrier_link::geo::{Geodetic, LocalFrame, ned_to_enu};
use harrier_link::mavlink::MavHeader;
use harrier_link::mavlink::dialects::common::{MavMessage, MavModeFlag, MavState};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::identity::{Identity, IdentityView};
use super::timesync::{Timesync, TimesyncView};
use super::transport::Peer;

/// Link state of a vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    /// Heard within the loss timeout.
    Connected,
    /// Silent for longer than the loss timeout (`mavlink.lost_after_s`).
    Lost,
}

/// A vehicle's MAV_STATE (its HEARTBEAT's `system_status`), sent by its MAVLink name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum SystemStatus {
    /// `MAV_STATE_UNINIT`: uninitialized, state unknown.
    MavStateUninit,
    /// `MAV_STATE_BOOT`: booting up.
    MavStateBoot,
    /// `MAV_STATE_CALIBRATING`: calibrating, not flight-ready.
    MavStateCalibrating,
    /// `MAV_STATE_STANDBY`: grounded and on standby, ready to launch.
    MavStateStandby,
    /// `MAV_STATE_ACTIVE`: active, maybe airborne, motors engaged.
    MavStateActive,
    /// `MAV_STATE_CRITICAL`: in a failsafe mode, still navigating.
    MavStateCritical,
    /// `MAV_STATE_EMERGENCY`: in a failsafe mode, control lost (mayday).
    MavStateEmergency,
    /// `MAV_STATE_POWEROFF`: powering down.
    MavStatePoweroff,
    /// `MAV_STATE_FLIGHT_TERMINATION`: terminating itself (failsafe or commanded).
    MavStateFlightTermination,
}

impl From<MavState> for SystemStatus {
    fn from(s: MavState) -> Self {
        match s {
            MavState::MAV_STATE_UNINIT => Self::MavStateUninit,
            MavState::MAV_STATE_BOOT => Self::MavStateBoot,
            MavState::MAV_STATE_CALIBRATING => Self::MavStateCalibrating,
            MavState::MAV_STATE_STANDBY => Self::MavStateStandby,
            MavState::MAV_STATE_ACTIVE => Self::MavStateActive,
            MavState::MAV_STATE_CRITICAL => Self::MavStateCritical,
            MavState::MAV_STATE_EMERGENCY => Self::MavStateEmergency,
            MavState::MAV_STATE_POWEROFF => Self::MavStatePoweroff,
            MavState::MAV_STATE_FLIGHT_TERMINATION => Self::MavStateFlightTermination,
        }
    }
}

/// A vehicle's autopilot, as its HEARTBEAT's `autopilot` field says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum VehicleAutopilot {
    /// PX4 (`MAV_AUTOPILOT_PX4`, and any other autopilot: decoded as PX4).
    Px4,
    /// ArduPilot (`MAV_AUTOPILOT_ARDUPILOTMEGA`): ArduCopter or ArduPlane.
    Ardupilot,
}

impl From<Autopilot> for VehicleAutopilot {
    fn from(a: Autopilot) -> Self {
        match a {
            Autopilot::Px4 => Self::Px4,
            Autopilot::ArduPilot => Self::Ardupilot,
        }
    }
}

/// A vehicle's airframe, as its HEARTBEAT's MAV_TYPE says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum VehicleAirframe {
    /// Hovers (a rotorcraft MAV_TYPE).
    Multirotor,
    /// Cannot hover (`MAV_TYPE_FIXED_WING`): minimum airspeed, bank-limited turns.
    FixedWing,
}

impl From<Frame> for VehicleAirframe {
    fn from(f: Frame) -> Self {
        match f {
            Frame::Multirotor => Self::Multirotor,
            Frame::FixedWing => Self::FixedWing,
        }
    }
}

/// A vehicle as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct VehicleLinkView {
    /// MAVLink system id.
    pub id: u8,
    /// `connected` or `lost`.
    pub state: LinkState,
    /// Where its frames come from (`udp:ADDR` or `tcp#N`).
    pub address: String,
    /// Its autopilot, once a HEARTBEAT was heard.
    pub autopilot: Option<VehicleAutopilot>,
    /// Its airframe, once a HEARTBEAT was heard.
    pub airframe: Option<VehicleAirframe>,
    /// Flight mode in its autopilot's table, once a HEARTBEAT was heard: PX4's `HOLD`,
    /// `OFFBOARD`, `TAKEOFF`, `LAND`, `POSCTL` (else `PX4 main M sub S`), ArduCopter's and
    /// ArduPlane's names as MAVProxy prints them (`GUIDED`, `LOITER`, `RTL`, …; else `Mode(N)`).
    pub mode: Option<String>,
    /// Motors armed.
    pub armed: bool,
    /// MAV_STATE of the last HEARTBEAT (`MAV_STATE_ACTIVE`…).
    pub system_status: Option<SystemStatus>,
    /// Position in the server's ENU frame (m), from GLOBAL_POSITION_INT.
    pub position: Option<[f64; 3]>,
    /// Position (WGS-84: `lat_deg`, `lon_deg`, `alt_m` AMSL).
    #[schema(value_type = Option<Object>)]
    pub geodetic: Option<GeoPoint>,
    /// Height above home (m).
    pub relative_alt_m: Option<f64>,
    /// Velocity, ENU (m/s).
    pub velocity: Option<[f64; 3]>,
    /// Heading (degrees from north, clockwise).
    pub heading_deg: Option<f64>,
    /// Roll, pitch, yaw (degrees).
    pub attitude_deg: Option<[f64; 3]>,
    /// Remaining battery (%), when reported.
    pub battery_pct: Option<f64>,
    /// Battery voltage (V), when reported.
    pub battery_v: Option<f64>,
    /// Messages received over the last second.
    pub rate_hz: f64,
    /// Frames lost (sequence gaps) as a share of frames sent (%), since first heard.
    pub loss_pct: f64,
    /// Frames received.
    pub received: u64,
    /// Frames lost (sequence gaps).
    pub lost_frames: u64,
    /// Seconds since its last frame.
    pub last_seen_s: f64,
    /// Times it was marked lost and came back.
    pub reconnects: u64,
    /// Its clock from MAVLink TIMESYNC; `null` before its first answer.
    pub timesync: Option<TimesyncView>,
    /// Who it is: its address confirmed or awaiting the operator's acceptance, and a second
    /// source claiming its system id (gcs::identity).
    pub identity: IdentityView,
    /// Commands, mode requests and setpoints the ground station sent it (the guidance's and the
    /// API's; not its HEARTBEAT, TIMESYNC or what router clients send).
    pub commands_sent: u64,
}

/// A command a router client sent a vehicle, as the guidance reads it when the vehicle's mode
/// changes.
#[derive(Debug, Clone, PartialEq)]
pub struct ClientCommand {
    /// When it passed (s on the link's clock, as `VehicleStatus::at`).
    pub at: f64,
    /// What: the MAV_CMD's name, `SET_MODE`, or `RC override`.
    pub command: String,
    /// Who: the router endpoint and the client's address.
    pub from: String,
}

/// What a vehicle's telemetry tells (see the module documentation).
#[derive(Debug)]
pub struct VehicleLink {
    id: u8,
    /// The GCS endpoint and peer its frames come from (replies go there).
    pub endpoint: usize,
    /// The peer on that endpoint.
    pub peer: Peer,
    last_seen: Instant,
    state: LinkState,
    status: Option<VehicleStatus>,
    custom_mode: u32,
    system_status: Option<SystemStatus>,
    geodetic: Option<Geodetic>,
    relative_alt: Option<f64>,
    velocity_ned: Option<Vector3<f64>>,
    /// When its last GLOBAL_POSITION_INT arrived.
    position_heard: Option<Instant>,
    heading: Option<f64>,
    attitude: Option<[f64; 3]>,
    battery_pct: Option<f64>,
    battery_v: Option<f64>,
    /// Last sequence number per component.
    sequences: HashMap<u8, u8>,
    received: u64,
    lost_frames: u64,
    reconnects: u64,
    /// Arrival times of the last second's messages.
    window: std::collections::VecDeque<Instant>,
    /// Its TIMESYNC exchanges.
    pub timesync: Timesync,
    /// Its gimbal manager's component id and gimbal device id.
    gimbal_manager: Option<(u8, u8)>,
    /// Who it is (its address, a conflict).
    pub identity: Identity,
    /// The last command a router client sent it.
    pub client_command: Option<ClientCommand>,
    /// Commands, mode requests and setpoints the ground station sent it.
    pub commands_sent: u64,
}

impl VehicleLink {
    /// A vehicle first heard at `now` from `peer` of GCS endpoint `endpoint`.
    pub fn new(id: u8, endpoint: usize, peer: Peer, now: Instant) -> Self {
        Self {
            id,
            endpoint,
            peer,
            last_seen: now,
            state: LinkState::Connected,
            status: None,
            custom_mode: 0,
            system_status: None,
            geodetic: None,
            relative_alt: None,
            velocity_ned: None,
            position_heard: None,
            heading: None,
            attitude: None,
            battery_pct: None,
            battery_v: None,
            sequences: HashMap::new(),
            received: 0,
            lost_frames: 0,
            reconnects: 0,
            window: std::collections::VecDeque::new(),
            timesync: Timesync::default(),
            gimbal_manager: None,
            identity: Identity::default(),
            client_command: None,
            commands_sent: 0,
        }
    }

    /// It speaks again from `peer` of endpoint `endpoint` after it was lost: replies go there,
    /// and its identity is unconfirmed until the operator accepts it.
    pub fn moved(&mut self, endpoint: usize, peer: Peer) {
        self.identity.moved(self.peer);
        (self.endpoint, self.peer) = (endpoint, peer);
        self.sequences.clear();
    }

    /// Its gimbal manager (component id, gimbal device id), once a GIMBAL_MANAGER_INFORMATION
    /// announced it.
    pub fn gimbal_manager(&self) -> Option<(u8, u8)> {
        self.gimbal_manager
    }

    /// Link state.
    pub fn state(&self) -> LinkState {
        self.state
    }

    /// The mode name of the last HEARTBEAT, once one was heard: the autopilot's own
    /// (QGroundControl's for PX4, MAVProxy's for ArduPilot), or `PX4 main M sub S` / `Mode(N)`
    /// for a mode its table lacks.
    pub fn mode(&self) -> Option<String> {
        self.status.map(|s| match s.mode {
            Some(m) => m.name().to_owned(),
            None => s.personality.unknown_mode_name(self.custom_mode),
        })
    }

    /// Mode and armed state from the last HEARTBEAT (`at` in seconds since the link started).
    pub fn status(&self) -> Option<VehicleStatus> {
        self.status
    }

    /// Takes one frame of this vehicle (from its own address: gcs::identity), received at `now`
    /// (`t` the same instant in seconds since the link started). Returns whether the vehicle
    /// came back from `Lost`.
    pub fn on_frame(&mut self, header: &MavHeader, msg: &MavMessage, now: Instant, t: f64) -> bool {
        self.last_seen = now;
        self.received += 1;
        if let Some(last) = self.sequences.insert(header.component_id, header.sequence) {
            let gap = header.sequence.wrapping_sub(last).wrapping_sub(1);
            // A jump back by less than half the range is a reordered or repeated frame, or a
            // restarted sender: not a loss.
            if gap < 128 {
                self.lost_frames += u64::from(gap);
            }
        }
        self.window.push_back(now);
        while self
            .window
            .front()
            .is_some_and(|f| now.duration_since(*f).as_secs_f64() > 1.0)
        {
            self.window.pop_front();
        }
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                self.status = Some(VehicleStatus::from_heartbeat(hb, t));
                self.custom_mode = if hb
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                {
                    hb.custom_mode
                } else {
                    0
                };
                self.system_status = Some(hb.system_status.into());
            }
            MavMessage::GLOBAL_POSITION_INT(p) => {
                self.geodetic = Some(Geodetic {
                    lat_deg: f64::from(p.lat) * 1e-7,
                    lon_deg: f64::from(p.lon) * 1e-7,
                    alt_m: f64::from(p.alt) * 1e-3,
                });
                self.relative_alt = Some(f64::from(p.relative_alt) * 1e-3);
                self.velocity_ned = Some(Vector3::new(
                    f64::from(p.vx) * 0.01,
                    f64::from(p.vy) * 0.01,
                    f64::from(p.vz) * 0.01,
                ));
                self.heading = (p.hdg != u16::MAX).then(|| f64::from(p.hdg) * 0.01);
                self.position_heard = Some(now);
            }
            // A NaN or infinite angle (the wire allows them) keeps the last good attitude:
            // JSON has no NaN, and the API would serve `null` for a number.
            MavMessage::ATTITUDE(a) if [a.roll, a.pitch, a.yaw].iter().all(|x| x.is_finite()) => {
                self.attitude = Some([
                    f64::from(a.roll).to_degrees(),
                    f64::from(a.pitch).to_degrees(),
                    f64::from(a.yaw).to_degrees(),
                ]);
            }
            MavMessage::GIMBAL_MANAGER_INFORMATION(g) => {
                self.gimbal_manager = Some((header.component_id, g.gimbal_device_id));
            }
            MavMessage::SYS_STATUS(s) => {
                self.battery_pct =
                    (s.battery_remaining >= 0).then(|| f64::from(s.battery_remaining));
                self.battery_v =
                    (s.voltage_battery != u16::MAX).then(|| f64::from(s.voltage_battery) * 1e-3);
            }
            _ => {}
        }
        if self.state == LinkState::Lost {
            self.state = LinkState::Connected;
            self.reconnects += 1;
            return true;
        }
        false
    }

    /// Marks the vehicle lost when it has been silent for `lost_after_s` at `now`; returns
    /// whether it just became lost.
    pub fn check(&mut self, now: Instant, lost_after_s: f64) -> bool {
        if self.state == LinkState::Connected
            && now.duration_since(self.last_seen).as_secs_f64() > lost_after_s
        {
            self.state = LinkState::Lost;
            self.window.clear();
            return true;
        }
        false
    }

    /// Position (ENU in `frame`) and velocity (ENU), once GLOBAL_POSITION_INT was heard.
    pub fn kinematics(&self, frame: &LocalFrame) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let g = self.geodetic?;
        Some((frame.to_enu(&g), ned_to_enu(&self.velocity_ned?)))
    }

    /// Seconds from the arrival of its last GLOBAL_POSITION_INT to `now`, once one was heard.
    pub fn position_age(&self, now: Instant) -> Option<f64> {
        self.position_heard
            .map(|h| now.saturating_duration_since(h).as_secs_f64())
    }

    /// Home altitude AMSL (m): altitude minus height above home.
    pub fn home_amsl(&self) -> Option<f64> {
        Some(self.geodetic?.alt_m - self.relative_alt?)
    }

    /// The API view at `now`.
    pub fn view(&self, frame: &LocalFrame, now: Instant) -> VehicleLinkView {
        let sent = self.received + self.lost_frames;
        let kin = self.kinematics(frame);
        VehicleLinkView {
            id: self.id,
            state: self.state,
            address: self.peer.to_string(),
            autopilot: self.status.map(|s| s.personality.autopilot.into()),
            airframe: self.status.map(|s| s.personality.frame.into()),
            mode: self.mode(),
            armed: self.status.is_some_and(|s| s.armed),
            system_status: self.system_status,
            position: kin.map(|(p, _)| p.into()),
            geodetic: self
                .geodetic
                .map(|g| GeoPoint::new(g.lat_deg, g.lon_deg, g.alt_m)),
            relative_alt_m: self.relative_alt,
            velocity: kin.map(|(_, v)| v.into()),
            heading_deg: self.heading,
            attitude_deg: self.attitude,
            battery_pct: self.battery_pct,
            battery_v: self.battery_v,
            rate_hz: self.window.len() as f64,
            loss_pct: if sent == 0 {
                0.0
            } else {
                100.0 * self.lost_frames as f64 / sent as f64
            },
            received: self.received,
            lost_frames: self.lost_frames,
            last_seen_s: now.duration_since(self.last_seen).as_secs_f64(),
            reconnects: self.reconnects,
            timesync: self.timesync.view(),
            identity: self.identity.view(now),
            commands_sent: self.commands_sent,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::mavlink::dialects::common::{GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA};
    use std::net::SocketAddr;
    use std::time::Duration;

    fn header(sequence: u8) -> MavHeader {
        MavHeader {
            system_id: 1,
            component_id: 1,
            sequence,
        }
    }

    #[test]
    fn telemetry_loss_and_lost_state() {
        let t0 = Instant::now();
        let peer = (0, Peer::Udp(SocketAddr::from(([127, 0, 0, 1], 9))));
        let mut v = VehicleLink::new(1, 0, peer.1, t0);
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: harrier_link::px4::FlightMode::Offboard.px4_custom_mode(),
            base_mode: harrier_link::px4::base_mode(true),
            ..HEARTBEAT_DATA::DEFAULT
        });
        let origin = Geodetic {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        };
        let frame = LocalFrame::new(origin);
        let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            lat: 470_000_000,
            lon: 80_000_000,
            alt: 500_000,
            relative_alt: 100_000,
            vx: 100,
            vy: -200,
            vz: -50,
            hdg: 9000,
            ..GLOBAL_POSITION_INT_DATA::DEFAULT
        });
        // Sequences 0, 1, then 5: three frames lost.
        assert!(!v.on_frame(&header(0), &hb, t0, 0.0));
        assert!(!v.on_frame(&header(1), &pos, t0, 0.0));
        assert!(!v.on_frame(&header(5), &hb, t0, 0.0));
        let view = v.view(&frame, t0);
        assert_eq!((view.received, view.lost_frames), (3, 3));
        assert!((view.loss_pct - 50.0).abs() < 1e-9);
        assert_eq!(view.mode.as_deref(), Some("OFFBOARD"));
        assert_eq!(view.autopilot, Some(VehicleAutopilot::Px4));
        assert!(view.armed);
        assert_eq!(view.system_status, Some(SystemStatus::MavStateUninit));
        let p = view.position.expect("position");
        assert!(p[0].abs() < 1e-6 && p[1].abs() < 1e-6 && (p[2] - 100.0).abs() < 1e-6);
        // NED (1, −2, −0.5) m/s is ENU (−2, 1, 0.5).
        assert_eq!(view.velocity, Some([-2.0, 1.0, 0.5]));
        assert_eq!(v.home_amsl(), Some(400.0));
        // Silent past the timeout: lost once; a frame brings it back.
        assert!(!v.check(t0 + Duration::from_millis(2900), 3.0));
        assert!(v.check(t0 + Duration::from_millis(3100), 3.0));
        assert!(!v.check(t0 + Duration::from_millis(4000), 3.0));
        assert_eq!(v.state(), LinkState::Lost);
        assert!(v.on_frame(&header(6), &hb, t0 + Duration::from_secs(5), 5.0));
        assert_eq!(v.state(), LinkState::Connected);
        assert_eq!(v.view(&frame, t0 + Duration::from_secs(5)).reconnects, 1);
    }

    /// ArduCopter's and ArduPlane's HEARTBEATs: the same number names another mode by MAV_TYPE;
    /// a number outside the table shows as pymavlink shows it.
    #[test]
    fn ardupilot_modes_are_named_by_airframe() {
        use harrier_link::autopilot::ardupilot_base_mode;
        use harrier_link::mavlink::dialects::common::{MavAutopilot, MavType};
        let t0 = Instant::now();
        let peer = (0, Peer::Udp(SocketAddr::from(([127, 0, 0, 1], 9))));
        let mut v = VehicleLink::new(2, 0, peer.1, t0);
        let frame = LocalFrame::new(Geodetic {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        });
        for (mavtype, custom, name, airframe) in [
            (
                MavType::MAV_TYPE_QUADROTOR,
                4,
                "GUIDED",
                VehicleAirframe::Multirotor,
            ),
            (
                MavType::MAV_TYPE_QUADROTOR,
                5,
                "LOITER",
                VehicleAirframe::Multirotor,
            ),
            (
                MavType::MAV_TYPE_FIXED_WING,
                4,
                "ACRO",
                VehicleAirframe::FixedWing,
            ),
            (
                MavType::MAV_TYPE_FIXED_WING,
                15,
                "GUIDED",
                VehicleAirframe::FixedWing,
            ),
            (
                MavType::MAV_TYPE_QUADROTOR,
                12,
                "Mode(12)",
                VehicleAirframe::Multirotor,
            ),
        ] {
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: custom,
                mavtype,
                autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                base_mode: ardupilot_base_mode(true, true),
                ..HEARTBEAT_DATA::DEFAULT
            });
            v.on_frame(&header(0), &hb, t0, 0.0);
            let view = v.view(&frame, t0);
            assert_eq!(view.mode.as_deref(), Some(name));
            assert_eq!(view.autopilot, Some(VehicleAutopilot::Ardupilot));
            assert_eq!(view.airframe, Some(airframe));
            assert!(view.armed);
        }
        assert_eq!(
            serde_json::to_value([VehicleAirframe::FixedWing]).ok(),
            Some(serde_json::json!(["fixed_wing"]))
        );
    }

    /// `system_status` is sent by the MAV_STATE's name, as when it was a string.
    #[test]
    fn a_system_status_is_sent_by_its_mav_state_name() {
        use MavState as S;
        for s in [
            S::MAV_STATE_UNINIT,
            S::MAV_STATE_BOOT,
            S::MAV_STATE_CALIBRATING,
            S::MAV_STATE_STANDBY,
            S::MAV_STATE_ACTIVE,
            S::MAV_STATE_CRITICAL,
            S::MAV_STATE_EMERGENCY,
            S::MAV_STATE_POWEROFF,
            S::MAV_STATE_FLIGHT_TERMINATION,
        ] {
            assert_eq!(
                serde_json::to_value(SystemStatus::from(s)).ok(),
                Some(serde_json::Value::String(format!("{s:?}")))
            );
        }
    }
}
