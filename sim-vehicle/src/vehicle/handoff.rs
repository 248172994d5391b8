//! A target handed to the autopilot (harrier-link's `handoff`), as the autopilots take it:
//!
//! - PX4's `MAV_CMD_DO_ORBIT`: the vehicle switches to POSCTL.ORBIT and circles the centre
//!   (latitude, longitude, altitude AMSL whatever the frame says, as PX4's orbit task reads
//!   it; unset: where it is) at the radius (positive
//!   clockwise; NaN: 50 m) and tangential speed (NaN: 3 m/s), facing it (PX4's Orbit mode;
//!   MAVLink's DO_ORBIT); armed and in the air, else DENIED. ArduPilot: UNSUPPORTED (an ArduPlane
//!   loiters at a DO_REPOSITION's radius instead, `guided.rs`).
//! - `FOLLOW_TARGET`: the target's position (and velocity, with `est_capabilities` bit 1) for
//!   PX4's AUTO.FOLLOW_TARGET — FLW_TGT_DST behind the target along its velocity, FLW_TGT_HT above
//!   it — and ArduCopter's FOLLOW, which keeps the offset it had when engaged (AP_Follow with
//!   FOLL_OFS_* zero).
//! - `MAV_CMD_DO_SET_ROI_LOCATION` (param1 the gimbal device: 0, 1 or [`GIMBAL_DEVICE_ID`]) and
//!   `MAV_CMD_DO_SET_ROI_NONE`: the region of interest its gimbal points at, announced as a gimbal
//!   manager (GIMBAL_MANAGER_INFORMATION, `telemetry.rs`); a camera with `pointing: roi` looks
//!   along [`Vehicle::gimbal_direction`].

use harrier_link::autopilot::Mode;
use harrier_link::geo::{Geodetic, ned_to_enu};
use harrier_link::handoff::FOLLOW_POS_VEL;
use harrier_link::px4::FlightMode;
use mavlink::dialects::common::{FOLLOW_TARGET_DATA, MavFrame, MavResult};
use nalgebra::Vector3;

use super::modes::Behaviour;
use super::protocol::Cmd;
use super::{Followed, OrbitTarget, Vehicle};

/// The component id of the simulated gimbal (`MAV_COMP_ID_GIMBAL`) its gimbal manager announces.
pub const GIMBAL_DEVICE_ID: u8 = 154;

/// A DO_ORBIT's default radius (m) and tangential speed (m/s).
const ORBIT_DEFAULTS: (f64, f64) = (50.0, 3.0);

impl Vehicle {
    /// The ENU point of a command's x, y (degrees; NaN or a COMMAND_INT's INT32_MAX: where the
    /// vehicle is) and z (AMSL, or above home in a relative frame; NaN: its altitude).
    pub(super) fn command_point(&self, c: &Cmd) -> Option<Vector3<f64>> {
        let unset = |v: f64| !v.is_finite() || v >= f64::from(i32::MAX) * 1e-7;
        let here = self.position();
        let (lat, lon) = if unset(c.x) || unset(c.y) {
            (here.lat_deg, here.lon_deg)
        } else {
            (c.x, c.y)
        };
        if !(lat.abs() <= 90.0 && lon.abs() <= 180.0) {
            return None;
        }
        let mut p = self.frame.to_enu(&Geodetic::new(lat, lon, 0.0));
        p.z = if c.z.is_finite() {
            let frame = c.frame.unwrap_or(MavFrame::MAV_FRAME_GLOBAL);
            self.enu_height(frame, lat, lon, f64::from(c.z))?
        } else {
            self.state.position.z
        };
        Some(p)
    }

    /// PX4's MAV_CMD_DO_ORBIT (see the module documentation).
    pub(super) fn do_orbit(&mut self, now: f64, c: &Cmd) -> MavResult {
        if !self.armed || self.on_ground() {
            return MavResult::MAV_RESULT_DENIED;
        }
        let radius = if c.p[0].is_nan() {
            ORBIT_DEFAULTS.0
        } else {
            f64::from(c.p[0])
        };
        let speed = if c.p[1].is_nan() {
            ORBIT_DEFAULTS.1
        } else {
            f64::from(c.p[1]).abs()
        };
        // PX4's orbit task takes the altitude as AMSL whatever the frame says (MAVSDK's
        // do_orbit sends an AMSL altitude in a frame labelled relative).
        let amsl = Cmd {
            frame: Some(MavFrame::MAV_FRAME_GLOBAL),
            ..*c
        };
        let Some(centre) = self.command_point(&amsl) else {
            return MavResult::MAV_RESULT_DENIED;
        };
        if !(radius.is_finite() && radius.abs() >= 1.0 && radius.abs() <= 10_000.0) {
            return MavResult::MAV_RESULT_DENIED;
        }
        if !(speed.is_finite() && speed <= self.limits().v_max) {
            return MavResult::MAV_RESULT_DENIED;
        }
        self.orbit = Some(OrbitTarget {
            centre,
            radius: radius.abs(),
            ccw: radius < 0.0,
            speed,
        });
        self.set_mode(now, Mode::Px4(FlightMode::Orbit));
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// MAV_CMD_DO_SET_ROI_LOCATION: the gimbal's region of interest.
    pub(super) fn set_roi(&mut self, c: &Cmd) -> MavResult {
        let device = c.p[0];
        if !(device == 0.0 || device == 1.0 || device == f32::from(GIMBAL_DEVICE_ID)) {
            return MavResult::MAV_RESULT_DENIED;
        }
        if !(c.x.is_finite() && c.y.is_finite() && c.z.is_finite()) {
            return MavResult::MAV_RESULT_DENIED;
        }
        match self.command_point(c) {
            Some(p) => {
                self.roi = Some(p);
                MavResult::MAV_RESULT_ACCEPTED
            }
            None => MavResult::MAV_RESULT_DENIED,
        }
    }

    /// MAV_CMD_DO_SET_ROI_NONE: no region of interest.
    pub(super) fn clear_roi(&mut self) -> MavResult {
        self.roi = None;
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// A FOLLOW_TARGET: the target a follow mode follows (position required; velocity when
    /// given). Non-finite fields are refused (counted).
    pub(super) fn follow_target(&mut self, f: &FOLLOW_TARGET_DATA) {
        let lat = f64::from(f.lat) * 1e-7;
        let lon = f64::from(f.lon) * 1e-7;
        let has_pos = f.est_capabilities & 1 != 0;
        let v = ned_to_enu(&Vector3::new(
            f64::from(f.vel[0]),
            f64::from(f.vel[1]),
            f64::from(f.vel[2]),
        ));
        let valid = has_pos
            && lat.abs() <= 90.0
            && lon.abs() <= 180.0
            && f.alt.is_finite()
            && v.iter().all(|x| x.is_finite());
        if !valid {
            self.counters.rejected_setpoints += 1;
            return;
        }
        let position = self
            .frame
            .to_enu(&Geodetic::new(lat, lon, f64::from(f.alt)));
        let velocity = if f.est_capabilities & FOLLOW_POS_VEL == FOLLOW_POS_VEL {
            v
        } else {
            Vector3::zeros()
        };
        self.followed = Some(Followed { position, velocity });
        if self.behaviour() == Behaviour::Follow && self.follow_offset.is_none() {
            self.follow_offset = Some(self.state.position - position);
        }
    }

    /// Where a follow mode flies (ENU) and the target's velocity: PX4 FLW_TGT_DST from the
    /// target at FLW_TGT_FA around its course (180: behind it, along its velocity; its course
    /// taken as north when it stands) and FLW_TGT_HT above it (above home with FLW_TGT_ALT_M 0 or
    /// 1, above the target with 2); ArduCopter at its engagement offset. `None` before a
    /// FOLLOW_TARGET.
    pub(super) fn follow_goal(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let f = self.followed?;
        let offset = match self.follow_offset {
            Some(o) if self.is_copter() => o,
            _ => {
                let course = f
                    .velocity
                    .xy()
                    .try_normalize(0.5)
                    .unwrap_or(nalgebra::Vector2::new(0.0, 1.0));
                // Clockwise by FLW_TGT_FA from the course (ENU: a negative rotation).
                let a = -self.param_f64("FLW_TGT_FA", 180.0).to_radians();
                let (s, c) = a.sin_cos();
                let dir = nalgebra::Vector2::new(
                    c * course.x - s * course.y,
                    s * course.x + c * course.y,
                );
                let d = self.param_f64("FLW_TGT_DST", 8.0);
                let up = self.param_f64("FLW_TGT_HT", 8.0);
                let z = if self.param_f64("FLW_TGT_ALT_M", 0.0) >= 2.0 {
                    up
                } else {
                    up - f.position.z
                };
                Vector3::new(dir.x * d, dir.y * d, z)
            }
        };
        Some((f.position + offset, f.velocity))
    }
}
