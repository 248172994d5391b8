//! Hand-off assignments (pure): the messages that hand a track to each vehicle's autopilot
//! instead of streaming setpoints (harrier-link's `handoff`; QGroundControl's long-requested
//! "loiter around a clicked target and point the gimbal", its issue 5803).
//!
//! - `handoff_orbit`: the predicted track, H above it, re-sent every [`ORBIT_PERIOD_S`] as PX4's
//!   MAV_CMD_DO_ORBIT (radius R, the assignment's direction and speed) or ArduPlane's
//!   DO_REPOSITION with the loiter radius R.
//! - `handoff_follow`: FOLLOW_TARGET every [`STREAM_PERIOD_S`] (10 Hz) with the predicted
//!   track's position, velocity and position variances, and the follow mode (PX4
//!   AUTO.FOLLOW_TARGET, ArduCopter FOLLOW) asked for until the vehicle is seen in it.
//! - Once an orbit's or a follow's vehicle is seen in the hand-off's mode (PX4 POSCTL.ORBIT,
//!   ArduPlane GUIDED, the follow mode), a newer HEARTBEAT in another mode, or disarmed, is
//!   someone else's change: the hand-off ends for that vehicle (`overridden`, nothing sent
//!   again). The camera hand-off changes no mode and has no such check.
//! - `handoff_camera`: MAV_CMD_DO_SET_ROI_LOCATION at the track, at once on every update of the
//!   track ([`Handoff::roi`], called when the tracker's snapshot changes) and, between updates,
//!   every [`STREAM_PERIOD_S`] at the track predicted to now (an ROI is a fixed point: a gimbal
//!   pointed at the last estimate of a car at 8 m/s updated at 2 Hz lags it by up to 4 m); to
//!   the gimbal manager the vehicle announced (GIMBAL_MANAGER_INFORMATION, asked for once with
//!   REQUEST_MESSAGE), else to its autopilot for every gimbal.
//!
//! Orbit and follow start once the vehicle is in the air (a vehicle on the ground waits); the
//! camera at once.

use harrier_core::guidance::TargetEstimate;
use harrier_engine::TrackView;
use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
use harrier_link::command::{command_long, set_mode};
use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_link::handoff::{follow_target, loiter_at, orbit, roi as roi_location};
use harrier_link::mavlink::MessageData;
use harrier_link::mavlink::dialects::common::{
    GIMBAL_MANAGER_INFORMATION_DATA, MavCmd, MavMessage,
};
use harrier_link::offboard::Override;
use harrier_link::px4::FlightMode;
use nalgebra::Vector3;

use super::plan::{Law, OrbitDirection, Plan};
use crate::gcs::VehicleSample;

/// Period of the orbit's re-centring (s).
const ORBIT_PERIOD_S: f64 = 0.5;
/// Period of FOLLOW_TARGET and of the camera's ROI between track updates (s): 10 Hz.
const STREAM_PERIOD_S: f64 = 0.1;
/// Shortest wait before the follow mode is asked for again (s).
const MODE_RETRY_S: f64 = 1.0;
/// Height above home (m) from which a vehicle counts as flying.
const AIRBORNE_M: f64 = 1.0;

/// One vehicle's hand-off: when it was last sent what.
#[derive(Debug, Default, Clone, PartialEq)]
pub(super) struct Handoff {
    /// When the next orbit or FOLLOW_TARGET is due (link clock, s): a fixed cadence over the
    /// loop's ticks.
    next_due: Option<f64>,
    last_mode_request: Option<f64>,
    gimbal_asked: bool,
    /// The time of the track estimate last pointed at (the tracker's clock).
    last_roi_t: Option<f64>,
    /// When the vehicle was first seen in the hand-off's mode (its orbit or follow mode): from
    /// then on, a newer status in another mode, or disarmed, is an override.
    engaged_at: Option<f64>,
}

/// The mode an orbit or follow hand-off puts a vehicle of `p` in: PX4's POSCTL.ORBIT (DO_ORBIT),
/// ArduPlane's GUIDED (DO_REPOSITION), the follow mode; `None` for the camera (the vehicle flies
/// on as it was).
fn handoff_mode(law: Law, p: Personality) -> Option<Mode> {
    match (law, p.autopilot, p.frame) {
        (Law::HandoffOrbit, Autopilot::Px4, _) => Some(Mode::Px4(FlightMode::Orbit)),
        (Law::HandoffOrbit, Autopilot::ArduPilot, Frame::FixedWing) => Some(p.guided()),
        (Law::HandoffFollow, ..) => p.follow(),
        _ => None,
    }
}

/// Whether the vehicle is in the air (height above home known and above [`AIRBORNE_M`]).
pub(super) fn airborne(v: &VehicleSample) -> bool {
    v.view.relative_alt_m.is_some_and(|h| h > AIRBORNE_M)
}

fn personality(v: &VehicleSample) -> Personality {
    v.status
        .map_or(Personality::PX4_MULTIROTOR, |s| s.personality)
}

/// The geodetic point of an ENU position, `up` metres higher.
fn point(frame: &LocalFrame, p: &Vector3<f64>, up: f64) -> Geodetic {
    frame.from_enu(&Vector3::new(p.x, p.y, p.z + up))
}

impl Handoff {
    /// The messages of a hand-off due at `t` (link clock, s; FOLLOW_TARGET's timestamp in ms),
    /// for vehicle `v`, the track predicted to now (`target`) and `track` (its covariance).
    /// Nothing for an orbit or follow while the vehicle is on the ground. An orbit or follow
    /// whose vehicle, once seen in the hand-off's mode, is seen in another (or disarmed) is
    /// someone else's: the override, and nothing sent.
    pub(super) fn step(
        &mut self,
        t: f64,
        v: &VehicleSample,
        target: &TargetEstimate,
        track: &TrackView,
        plan: &Plan,
        frame: &LocalFrame,
    ) -> Result<Vec<MavMessage>, Override> {
        let id = v.view.id;
        let p = personality(v);
        let period = match plan.law {
            Law::HandoffOrbit => ORBIT_PERIOD_S,
            Law::HandoffFollow | Law::HandoffCamera => STREAM_PERIOD_S,
            _ => return Ok(Vec::new()),
        };
        if let (Some(mode), Some(status)) = (handoff_mode(plan.law, p), v.status) {
            match self.engaged_at {
                Some(at) => {
                    let allowed = |m: Option<Mode>| m == Some(mode);
                    if let Some(o) =
                        Override::of(&status, Some(mode), Some(at), allowed).filter(|o| o.at > at)
                    {
                        return Err(o);
                    }
                }
                None if status.mode == Some(mode) => self.engaged_at = Some(status.at),
                None => {}
            }
        }
        let camera = plan.law == Law::HandoffCamera;
        if (!camera && !airborne(v)) || self.next_due.is_some_and(|d| t < d - 1e-6) {
            return Ok(Vec::new());
        }
        // Keep the cadence across the ticks; after a stall start it again from now.
        self.next_due = Some(match self.next_due {
            Some(d) if t - d < period => d + period,
            _ => t + period,
        });
        let ccw = plan.orbit == OrbitDirection::Ccw;
        Ok(match plan.law {
            Law::HandoffCamera => self.point(v, target, frame),
            Law::HandoffOrbit => {
                let centre = point(frame, &target.position, plan.height);
                let (r, speed) = (plan.radius as f32, plan.speed as f32);
                vec![match (p.autopilot, p.frame) {
                    (Autopilot::ArduPilot, Frame::FixedWing) => loiter_at(id, &centre, r, ccw),
                    _ => orbit(id, &centre, r, ccw, speed),
                }]
            }
            _ => {
                let var = |i| track.cov_at(i, i).unwrap_or(0.0).max(0.0);
                // ENU x, y, z → NED north, east, down.
                let cov_ned = [var(1), var(0), var(2)];
                let at = point(frame, &target.position, 0.0);
                let now_ms = (t * 1000.0) as u64;
                let mut out = vec![follow_target(now_ms, &at, &target.velocity, cov_ned)];
                let follow: Option<Mode> = p.follow();
                let in_follow = v
                    .status
                    .is_some_and(|s| s.mode.is_some() && s.mode == follow);
                // Asked for until the vehicle is seen in it, never after (`step`'s override).
                let retry = self.engaged_at.is_none()
                    && self.last_mode_request.is_none_or(|s| t - s >= MODE_RETRY_S);
                if let (Some(m), false, true) = (follow, in_follow, retry) {
                    out.push(set_mode(id, m));
                    self.last_mode_request = Some(t);
                }
                out
            }
        })
    }

    /// The camera hand-off at an update of the track at `t` (link clock, s; its estimate at
    /// `track_t`, predicted to `target`): the ROI at once ([`Self::point`]), the periodic ones
    /// due again a period later. Nothing when this estimate was already sent.
    pub(super) fn roi(
        &mut self,
        t: f64,
        track_t: f64,
        v: &VehicleSample,
        target: &TargetEstimate,
        frame: &LocalFrame,
    ) -> Vec<MavMessage> {
        if self.last_roi_t == Some(track_t) {
            return Vec::new();
        }
        self.last_roi_t = Some(track_t);
        self.next_due = Some(t + STREAM_PERIOD_S);
        self.point(v, target, frame)
    }

    /// DO_SET_ROI_LOCATION on the ground under `target`, to the vehicle's gimbal manager for its
    /// gimbal device when it announced one (else to its autopilot, every gimbal), after a
    /// REQUEST_MESSAGE for GIMBAL_MANAGER_INFORMATION the first time.
    fn point(
        &mut self,
        v: &VehicleSample,
        target: &TargetEstimate,
        frame: &LocalFrame,
    ) -> Vec<MavMessage> {
        let id = v.view.id;
        let mut out = Vec::new();
        if !self.gimbal_asked && v.gimbal_manager.is_none() {
            self.gimbal_asked = true;
            let info = GIMBAL_MANAGER_INFORMATION_DATA::ID as f32;
            out.push(command_long(
                id,
                MavCmd::MAV_CMD_REQUEST_MESSAGE,
                [info, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ));
        }
        let (component, device) = v
            .gimbal_manager
            .unwrap_or((harrier_link::px4::COMPONENT_ID, 0));
        out.push(roi_location(
            id,
            component,
            device,
            &point(frame, &target.position, 0.0),
        ));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcs::vehicle::{LinkState, VehicleLinkView};
    use harrier_link::autopilot::VehicleStatus;
    use harrier_link::px4::FlightMode;

    fn sample(p: Personality, height: f64, mode: Option<Mode>) -> VehicleSample {
        VehicleSample {
            view: VehicleLinkView {
                id: 3,
                state: LinkState::Connected,
                address: String::new(),
                autopilot: None,
                airframe: None,
                mode: None,
                armed: true,
                system_status: None,
                position: None,
                geodetic: None,
                relative_alt_m: Some(height),
                velocity: None,
                heading_deg: None,
                attitude_deg: None,
                battery_pct: None,
                battery_v: None,
                rate_hz: 0.0,
                loss_pct: 0.0,
                received: 0,
                lost_frames: 0,
                last_seen_s: 0.0,
                reconnects: 0,
                timesync: None,
                identity: crate::gcs::identity::Identity::default().view(std::time::Instant::now()),
                commands_sent: 0,
            },
            status: Some(VehicleStatus {
                armed: true,
                personality: p,
                mode,
                at: 0.0,
            }),
            home_amsl: Some(488.0),
            gimbal_manager: None,
            position_unix: None,
            confirmed: true,
            client_command: None,
        }
    }

    fn plan(law: Law) -> Plan {
        Plan {
            radius: 60.0,
            height: 40.0,
            spacing: Some(1.0),
            speed: 5.0,
            orbit: OrbitDirection::Ccw,
            law,
        }
    }

    fn track() -> TrackView {
        TrackView {
            id: 1,
            status: harrier_engine::TrackStatus::Confirmed,
            t: 10.0,
            state: [100.0, 200.0, 0.0, 1.0, 0.0, 0.0],
            cov: vec![vec![4.0, 0.0], vec![0.0, 9.0]],
            cov_dims: vec![0, 1],
            updated: true,
            age: 5,
            last_update: 10.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    /// Orbit: PX4's DO_ORBIT or ArduPlane's loiter at the predicted point H up, twice a second,
    /// not on the ground; follow: FOLLOW_TARGET at 10 Hz with the covariance in NED order, and the
    /// follow mode asked for at most once a second.
    #[test]
    fn orbit_and_follow_are_paced_and_carry_the_track() {
        let frame = LocalFrame::new(Geodetic::new(47.0, 8.0, 400.0));
        let target = TargetEstimate {
            position: Vector3::new(100.0, 200.0, 0.0),
            velocity: Vector3::new(1.0, 0.0, 0.0),
        };
        let tr = track();
        let px4 = Personality::PX4_MULTIROTOR;
        let mut h = Handoff::default();
        let grounded = sample(px4, 0.0, None);
        assert!(
            h.step(
                0.0,
                &grounded,
                &target,
                &tr,
                &plan(Law::HandoffOrbit),
                &frame
            )
            .expect("step")
            .is_empty()
        );
        let up = sample(px4, 30.0, None);
        let out = h
            .step(0.0, &up, &target, &tr, &plan(Law::HandoffOrbit), &frame)
            .expect("step");
        let MavMessage::COMMAND_INT(c) = &out[0] else {
            panic!("{out:?}")
        };
        assert_eq!((c.command, c.param1), (MavCmd::MAV_CMD_DO_ORBIT, -60.0));
        assert!((c.z - 440.0).abs() < 0.01, "{}", c.z);
        let centre = frame.to_enu(&Geodetic::new(
            f64::from(c.x) * 1e-7,
            f64::from(c.y) * 1e-7,
            440.0,
        ));
        assert!(
            (centre.xy() - target.position.xy()).norm() < 0.02,
            "{centre}"
        );
        assert!(
            h.step(0.3, &up, &target, &tr, &plan(Law::HandoffOrbit), &frame)
                .expect("step")
                .is_empty()
        );
        assert_eq!(
            h.step(0.5, &up, &target, &tr, &plan(Law::HandoffOrbit), &frame)
                .expect("step")
                .len(),
            1
        );
        let plane = sample(
            Personality::from_label("ardupilot-fw").expect("label"),
            60.0,
            None,
        );
        let mut h = Handoff::default();
        let out = h
            .step(0.0, &plane, &target, &tr, &plan(Law::HandoffOrbit), &frame)
            .expect("step");
        assert!(
            matches!(&out[0], MavMessage::COMMAND_INT(c) if c.command == MavCmd::MAV_CMD_DO_REPOSITION && c.param3 == 60.0)
        );

        let mut h = Handoff::default();
        let out = h
            .step(0.0, &up, &target, &tr, &plan(Law::HandoffFollow), &frame)
            .expect("step");
        let MavMessage::FOLLOW_TARGET(f) = &out[0] else {
            panic!("{out:?}")
        };
        assert_eq!(
            (f.timestamp, f.position_cov, f.vel[1]),
            (0, [9.0, 4.0, 0.0], 1.0)
        );
        assert!(
            matches!(&out[1], MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_DO_SET_MODE)
        );
        assert_eq!(
            h.step(0.1, &up, &target, &tr, &plan(Law::HandoffFollow), &frame)
                .expect("step")
                .len(),
            1
        );
        let following = sample(px4, 30.0, Some(Mode::Px4(FlightMode::FollowTarget)));
        assert_eq!(
            h.step(
                1.2,
                &following,
                &target,
                &tr,
                &plan(Law::HandoffFollow),
                &frame
            )
            .expect("step")
            .len(),
            1
        );
    }

    /// Once seen in its follow (orbit) mode, a vehicle seen in another mode, or disarmed, is
    /// someone else's: the hand-off ends for it; before, the mode is asked for.
    #[test]
    fn leaving_the_handoff_mode_is_an_override() {
        let frame = LocalFrame::new(Geodetic::new(47.0, 8.0, 400.0));
        let target = TargetEstimate::fixed(Vector3::new(10.0, 20.0, 0.0));
        let tr = track();
        let px4 = Personality::PX4_MULTIROTOR;
        let at = |mut v: VehicleSample, t: f64, armed: bool| {
            if let Some(s) = &mut v.status {
                s.at = t;
                s.armed = armed;
            }
            v
        };
        let follow = plan(Law::HandoffFollow);
        let mut h = Handoff::default();
        // Not yet in FOLLOW_TARGET: asked for, no override.
        let hold = at(
            sample(px4, 30.0, Some(Mode::Px4(FlightMode::Hold))),
            0.0,
            true,
        );
        assert_eq!(
            h.step(0.0, &hold, &target, &tr, &follow, &frame)
                .map(|o| o.len()),
            Ok(2)
        );
        let following = sample(px4, 30.0, Some(Mode::Px4(FlightMode::FollowTarget)));
        h.step(
            1.0,
            &at(following.clone(), 1.0, true),
            &target,
            &tr,
            &follow,
            &frame,
        )
        .expect("engaged");
        // The same status again: nothing new; a Hold seen after: the pilot's.
        h.step(
            1.1,
            &at(following, 1.0, true),
            &target,
            &tr,
            &follow,
            &frame,
        )
        .expect("same status");
        let o = h
            .step(1.5, &at(hold, 1.4, true), &target, &tr, &follow, &frame)
            .expect_err("overridden");
        assert_eq!(
            (o.from, o.to, o.disarmed),
            (
                Some(Mode::Px4(FlightMode::FollowTarget)),
                Some(Mode::Px4(FlightMode::Hold)),
                false
            )
        );
        // An orbit whose vehicle lands and disarms in its orbit mode: overridden too.
        let orbit = plan(Law::HandoffOrbit);
        let mut h = Handoff::default();
        let orbiting = sample(px4, 30.0, Some(Mode::Px4(FlightMode::Orbit)));
        h.step(
            0.0,
            &at(orbiting.clone(), 0.5, true),
            &target,
            &tr,
            &orbit,
            &frame,
        )
        .expect("engaged");
        let o = h
            .step(1.0, &at(orbiting, 0.9, false), &target, &tr, &orbit, &frame)
            .expect_err("disarmed");
        assert!(o.disarmed);
        // The camera changes no mode: never an override.
        let mut h = Handoff::default();
        let camera = plan(Law::HandoffCamera);
        let landed = at(
            sample(px4, 0.0, Some(Mode::Px4(FlightMode::Land))),
            3.0,
            false,
        );
        assert!(h.step(3.0, &landed, &target, &tr, &camera, &frame).is_ok());
    }

    /// The camera: once per track estimate, to the gimbal manager once known; between estimates
    /// at 10 Hz, predicted.
    #[test]
    fn roi_goes_once_per_estimate_to_the_gimbal_manager() {
        let frame = LocalFrame::new(Geodetic::new(47.0, 8.0, 400.0));
        let target = TargetEstimate::fixed(Vector3::new(10.0, 20.0, 0.0));
        let mut v = sample(Personality::PX4_MULTIROTOR, 30.0, None);
        let mut h = Handoff::default();
        let out = h.roi(0.0, 1.0, &v, &target, &frame);
        assert_eq!(out.len(), 2, "asks for GIMBAL_MANAGER_INFORMATION first");
        assert!(h.roi(0.01, 1.0, &v, &target, &frame).is_empty());
        v.gimbal_manager = Some((1, 154));
        let out = h.roi(0.5, 2.0, &v, &target, &frame);
        let [MavMessage::COMMAND_INT(c)] = out.as_slice() else {
            panic!("{out:?}")
        };
        assert_eq!(
            (c.command, c.target_component, c.param1),
            (MavCmd::MAV_CMD_DO_SET_ROI_LOCATION, 1, 154.0)
        );
        assert!((c.z - 400.0).abs() < 0.01, "{}", c.z);
        // Between updates, every 100 ms from the last update, at the predicted point (even on
        // the ground).
        let camera = plan(Law::HandoffCamera);
        let tr = track();
        let moved = TargetEstimate::fixed(Vector3::new(12.0, 20.0, 0.0));
        let grounded = VehicleSample {
            gimbal_manager: Some((1, 154)),
            ..sample(Personality::PX4_MULTIROTOR, 0.0, None)
        };
        assert!(
            h.step(0.55, &grounded, &moved, &tr, &camera, &frame)
                .expect("step")
                .is_empty()
        );
        let out = h
            .step(0.6, &grounded, &moved, &tr, &camera, &frame)
            .expect("step");
        let [MavMessage::COMMAND_INT(c)] = out.as_slice() else {
            panic!("{out:?}")
        };
        let at = frame.to_enu(&Geodetic::new(
            f64::from(c.x) * 1e-7,
            f64::from(c.y) * 1e-7,
            f64::from(c.z),
        ));
        assert!((at - moved.position).norm() < 0.02, "{at}");
        assert!(
            h.step(0.65, &grounded, &moved, &tr, &camera, &frame)
                .expect("step")
                .is_empty()
        );
        assert_eq!(
            h.step(0.7, &grounded, &moved, &tr, &camera, &frame)
                .expect("step")
                .len(),
            1
        );
    }
}
