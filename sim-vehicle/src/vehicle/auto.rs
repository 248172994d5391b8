//! Flying the uploaded mission: PX4's AUTO.MISSION and ArduPilot's AUTO.
//!
//! | item | flown as |
//! |---|---|
//! | NAV_TAKEOFF | climb to its altitude over where the vehicle is (a fixed wing is launched) |
//! | NAV_WAYPOINT | fly to it (PX4 multirotor at MPC_XY_CRUISE, ArduCopter at WPNAV_SPEED, a fixed wing at cruise airspeed; a DO_CHANGE_SPEED's speed instead), reached within param2 (0: PX4 NAV_ACC_RAD, ArduCopter WPNAV_RADIUS, ArduPlane WP_RADIUS; a fixed wing no tighter than its turn) and, for a multirotor, 1 m vertically; then hold param1 s |
//! | NAV_LOITER_UNLIM / _TIME / _TURNS | fly there, then hold (a fixed wing circles) for ever / param1 s / param1 turns of its loiter circle |
//! | NAV_DELAY | hold param1 s |
//! | NAV_RETURN_TO_LAUNCH | RTL (as the RTL mode flies it) without leaving the mission mode |
//! | NAV_LAND | fly to its point (latitude and longitude 0: where it is), descend, disarm |
//! | DO_CHANGE_SPEED | param2 m/s for what follows |
//! | DO_SET_ROI_LOCATION, DO_SET_ROI, DO_SET_ROI_NONE | the gimbal's region of interest |
//! | DO_JUMP | to item param1, param2 times |
//! | camera, gimbal, servo items | passed over (no such hardware here) |
//!
//! Altitudes are in the item's frame: above home (GLOBAL_RELATIVE_ALT), AMSL (GLOBAL), or above
//! terrain, taken as above home (the simulated ground is flat at home's altitude).
//!
//! A PX4 vehicle armed on the ground in AUTO.MISSION takes off by itself to the first
//! position's altitude (at least MIS_TAKEOFF_ALT), as PX4's navigator does; an ArduPilot
//! vehicle leaves the ground only by a NAV_TAKEOFF item, and an ArduCopter only once
//! MAV_CMD_MISSION_START started the mission (its AUTO waits for the throttle or that command
//! on the ground). Each item done is reported with MISSION_ITEM_REACHED, every change of the
//! current item with MISSION_CURRENT (also streamed at 1 Hz). After the last item the vehicle
//! holds where it is (a fixed wing circles), in the mission mode; entering the mode again starts
//! the mission over. ArduPilot's item 0 is home: its missions run from item 1.

use harrier_core::guidance::Limits;
use harrier_link::autopilot::Autopilot;
use harrier_link::geo::Geodetic;
use mavlink::dialects::common::{
    MISSION_ITEM_INT_DATA, MISSION_ITEM_REACHED_DATA, MavCmd, MavFrame, MavMessage,
};
use nalgebra::Vector3;

use super::Vehicle;
use super::mission::passed_over;
use super::wire::Outgoing;

/// Where the mission's execution is.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Exec {
    /// The item being flown (its sequence number).
    seq: u16,
    /// The item whose setup has run.
    entered: Option<u16>,
    /// Sim time the current item's position was reached (holds count from there).
    arrived_at: Option<f64>,
    /// MAV_CMD_MISSION_START started it.
    pub(super) started: bool,
    /// Past the last item.
    finished: bool,
    /// DO_JUMP repeats done, by the jump's sequence number.
    jumps: Vec<(u16, u16)>,
    /// DO_CHANGE_SPEED's speed (m/s).
    speed: Option<f64>,
}

/// What an item asks for now.
enum Step {
    /// Fly this velocity.
    Fly(Vector3<f64>),
    /// The item is done: on to the next.
    Done,
    /// Continue at this item.
    Jump(u16),
}

impl Vehicle {
    /// The first item a mission runs: PX4 0, ArduPilot 1 (0 is home).
    fn first_item(&self) -> u16 {
        match self.personality.autopilot {
            Autopilot::Px4 => 0,
            Autopilot::ArduPilot => 1,
        }
    }

    /// The current mission item (MISSION_CURRENT's `seq`).
    pub(super) fn mission_seq(&self) -> u16 {
        self.mission_exec.seq
    }

    /// Whether there is a mission to fly (ArduPilot: beyond home).
    pub(super) fn has_mission(&self) -> bool {
        self.missions.lists[0].len() > usize::from(self.first_item())
    }

    /// Makes `seq` the current item (MISSION_SET_CURRENT, DO_SET_MISSION_CURRENT): ignored
    /// beyond the list.
    pub(super) fn set_mission_seq(&mut self, seq: u16) {
        let seq = seq.max(self.first_item());
        if usize::from(seq) < self.missions.lists[0].len() {
            self.goto_item(seq);
        }
    }

    /// Back to the mission's first item.
    pub(super) fn restart_mission(&mut self) {
        self.mission_exec = Exec {
            seq: self.first_item(),
            ..Exec::default()
        };
    }

    /// Entering the mission mode: a finished mission starts over; the current item is set up
    /// afresh.
    pub(super) fn enter_mission(&mut self) {
        if self.mission_exec.finished {
            self.restart_mission();
        }
        self.mission_exec.entered = None;
        self.mission_exec.arrived_at = None;
        self.mission_exec.started = false;
    }

    fn goto_item(&mut self, seq: u16) {
        let changed = seq != self.mission_exec.seq;
        self.mission_exec.seq = seq;
        self.mission_exec.entered = None;
        self.mission_exec.arrived_at = None;
        self.mission_exec.finished = false;
        if changed {
            self.push_out(self.mission_current().into());
        }
    }

    /// Queues a message for the next telemetry pass (at most 64 wait).
    pub(super) fn push_out(&mut self, m: Outgoing) {
        if self.outbox.len() < 64 {
            self.outbox.push(m);
        }
    }

    fn item_done(&mut self) {
        let seq = self.mission_exec.seq;
        self.push_out(MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA { seq }).into());
        if usize::from(seq) + 1 >= self.missions.lists[0].len() {
            self.mission_exec.finished = true;
            self.mission_exec.entered = None;
            self.hold_point = self.stop_point();
        } else {
            self.goto_item(seq + 1);
        }
    }

    /// The current item's point (ENU): latitude and longitude 0 mean here; the altitude in its
    /// frame (terrain as above home); `None` for an item without one.
    #[allow(deprecated)]
    fn item_point(&self, item: &MISSION_ITEM_INT_DATA) -> Option<Vector3<f64>> {
        use MavFrame as F;
        let here = self.position();
        let (lat, lon) = if item.x == 0 && item.y == 0 {
            (here.lat_deg, here.lon_deg)
        } else {
            (f64::from(item.x) * 1e-7, f64::from(item.y) * 1e-7)
        };
        let frame = match item.frame {
            F::MAV_FRAME_GLOBAL_TERRAIN_ALT => F::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            F::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT => F::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            f => f,
        };
        let z = self.enu_height(frame, lat, lon, f64::from(item.z))?;
        let mut p = self.frame.to_enu(&Geodetic::new(lat, lon, 0.0));
        p.z = z;
        Some(p)
    }

    /// Mission speed (m/s): DO_CHANGE_SPEED's, else PX4 MPC_XY_CRUISE, ArduCopter WPNAV_SPEED,
    /// a fixed wing's cruise airspeed (within its envelope).
    fn mission_speed(&self, limits: &Limits) -> f64 {
        let default = if !limits.can_hover() {
            self.cruise_speed()
        } else if self.personality.autopilot == Autopilot::Px4 {
            self.param_f64("MPC_XY_CRUISE", 5.0)
        } else {
            self.param_f64("WPNAV_SPEED", 1000.0) * 0.01
        };
        let s = self.mission_exec.speed.unwrap_or(default);
        s.max(limits.v_min).min(limits.v_max)
    }

    /// Acceptance radius of a waypoint (m): param2, else the autopilot's default; a fixed wing's
    /// no tighter than its turn.
    fn acceptance(&self, param2: f32, speed: f64, limits: &Limits) -> f64 {
        let default = match (self.personality.autopilot, limits.can_hover()) {
            (Autopilot::Px4, _) => self.param_f64("NAV_ACC_RAD", 2.0),
            (Autopilot::ArduPilot, true) => self.param_f64("WPNAV_RADIUS", 200.0) * 0.01,
            (Autopilot::ArduPilot, false) => self.param_f64("WP_RADIUS", 90.0),
        };
        let r = if param2.is_finite() && param2 > 0.0 {
            f64::from(param2)
        } else {
            default
        };
        if limits.can_hover() {
            r
        } else {
            r.max(limits.min_turn_radius(speed))
        }
    }

    /// The velocity towards `p` at `speed`: a multirotor slows into it (never faster than it can
    /// stop); a fixed wing heads for it.
    pub(super) fn towards(&self, p: Vector3<f64>, speed: f64, limits: &Limits) -> Vector3<f64> {
        if limits.can_hover() {
            let v = self.hover_at(p);
            let vh = v.xy();
            let vh = if vh.norm() > speed {
                vh * (speed / vh.norm())
            } else {
                vh
            };
            return Vector3::new(vh.x, vh.y, v.z.max(-limits.vz_max).min(limits.vz_max));
        }
        let d = p - self.state.position;
        let vz = (d.z * super::POS_GAIN)
            .max(-limits.vz_max)
            .min(limits.vz_max);
        let vh = d
            .xy()
            .try_normalize(1e-6)
            .map_or(self.state.horizontal_velocity(), |u| u * speed);
        Vector3::new(vh.x, vh.y, vz)
    }

    /// The mission mode's velocity, advancing through the items as they are done.
    pub(super) fn mission_flight(&mut self, limits: &Limits) -> Vector3<f64> {
        // Items without flight (DO_*) pass at once; a DO_JUMP loop is cut after one pass over
        // the list.
        for _ in 0..=self.missions.lists[0].len() {
            if self.mission_exec.finished {
                break;
            }
            let seq = self.mission_exec.seq;
            let Some(item) = self.missions.lists[0].get(usize::from(seq)).cloned() else {
                self.mission_exec.finished = true;
                self.hold_point = self.stop_point();
                break;
            };
            let enter = self.mission_exec.entered != Some(seq);
            self.mission_exec.entered = Some(seq);
            match self.fly_item(&item, enter, limits) {
                Step::Fly(v) => return v,
                Step::Done => self.item_done(),
                Step::Jump(to) => self.goto_item(to),
            }
        }
        self.hold_command(self.hold_point, limits)
    }

    // DO_SET_ROI is superseded by DO_SET_ROI_LOCATION; plans still hold it.
    #[allow(deprecated)]
    fn fly_item(&mut self, item: &MISSION_ITEM_INT_DATA, enter: bool, limits: &Limits) -> Step {
        use MavCmd as C;
        let point = self.item_point(item);
        let speed = self.mission_speed(limits);
        let grounded = self.on_ground() && !self.taking_off;
        match item.command {
            C::MAV_CMD_DO_CHANGE_SPEED => {
                if item.param2.is_finite() && item.param2 > 0.0 {
                    self.mission_exec.speed = Some(f64::from(item.param2));
                }
                Step::Done
            }
            C::MAV_CMD_DO_SET_ROI_LOCATION | C::MAV_CMD_DO_SET_ROI => {
                self.roi = point;
                Step::Done
            }
            C::MAV_CMD_DO_SET_ROI_NONE => {
                self.roi = None;
                Step::Done
            }
            C::MAV_CMD_DO_JUMP => {
                let seq = self.mission_exec.seq;
                let target = item.param1;
                let repeat = item.param2;
                let valid = target.is_finite()
                    && target >= 0.0
                    && (target as usize) < self.missions.lists[0].len();
                let done = self
                    .mission_exec
                    .jumps
                    .iter()
                    .find(|j| j.0 == seq)
                    .map_or(0, |j| j.1);
                if valid && (repeat < 0.0 || f32::from(done) < repeat) {
                    match self.mission_exec.jumps.iter_mut().find(|j| j.0 == seq) {
                        Some(j) => j.1 += 1,
                        None => self.mission_exec.jumps.push((seq, 1)),
                    }
                    Step::Jump(target as u16)
                } else {
                    Step::Done
                }
            }
            c if passed_over(c) => Step::Done,
            C::MAV_CMD_NAV_TAKEOFF => {
                let alt = point.map_or(self.takeoff_alt, |p| p.z);
                if (self.state.position.z - alt).abs() < 1.0 && !self.taking_off {
                    return Step::Done;
                }
                let may_launch = !self.is_copter() || self.mission_exec.started || !grounded;
                if enter && may_launch {
                    self.start_takeoff(alt);
                }
                if grounded && !may_launch {
                    return Step::Fly(Vector3::zeros());
                }
                Step::Fly(self.hold_command(self.state.position, limits))
            }
            C::MAV_CMD_NAV_DELAY => {
                if enter {
                    self.hold_point = self.stop_point();
                }
                let arrived = *self.mission_exec.arrived_at.get_or_insert(self.sim_time);
                if self.sim_time - arrived >= f64::from(item.param1).max(0.0) {
                    Step::Done
                } else {
                    Step::Fly(self.hold_command(self.hold_point, limits))
                }
            }
            C::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                if enter {
                    self.hold_point = Vector3::new(0.0, 0.0, self.return_altitude());
                }
                Step::Fly(self.rtl_command(limits))
            }
            _ => {
                let Some(p) = point else {
                    return Step::Done;
                };
                let land = item.command == C::MAV_CMD_NAV_LAND;
                if grounded {
                    // On the ground a landing is over (the touchdown ends it); PX4 takes off
                    // for anything else.
                    if self.personality.autopilot == Autopilot::Px4 && !land {
                        let alt = p.z.max(self.param_f64("MIS_TAKEOFF_ALT", 2.5));
                        self.start_takeoff(alt);
                    }
                    return Step::Fly(Vector3::new(0.0, 0.0, -1.0));
                }
                if land {
                    let over = Vector3::new(p.x, p.y, self.state.position.z);
                    let r = self.acceptance(0.0, speed, limits);
                    if (over - self.state.position).xy().norm() > r {
                        return Step::Fly(self.towards(over, speed, limits));
                    }
                    let mut v = self.hold_command(over, limits);
                    v.z = -self.land_speed();
                    return Step::Fly(v);
                }
                let r = self.acceptance(item.param2, speed, limits);
                let d = p - self.state.position;
                let vertical_ok = !limits.can_hover() || d.z.abs() < 1.0;
                if self.mission_exec.arrived_at.is_none() {
                    if d.xy().norm() < r && vertical_ok {
                        self.mission_exec.arrived_at = Some(self.sim_time);
                    } else {
                        return Step::Fly(self.towards(p, speed, limits));
                    }
                }
                let since = self.sim_time - self.mission_exec.arrived_at.unwrap_or(self.sim_time);
                let hold = match item.command {
                    C::MAV_CMD_NAV_LOITER_UNLIM => f64::INFINITY,
                    C::MAV_CMD_NAV_LOITER_TURNS => {
                        let radius = if item.param3.is_finite() && item.param3 != 0.0 {
                            f64::from(item.param3).abs()
                        } else {
                            self.loiter_radius()
                        };
                        f64::from(item.param1).max(0.0) * std::f64::consts::TAU * radius
                            / speed.max(0.1)
                    }
                    _ => f64::from(item.param1).max(0.0),
                };
                if since >= hold {
                    Step::Done
                } else {
                    Step::Fly(self.hold_command(p, limits))
                }
            }
        }
    }

    /// Touchdown during the mission: a NAV_LAND or NAV_RETURN_TO_LAUNCH item is done (the
    /// vehicle disarms); whether it was one.
    pub(super) fn mission_touchdown(&mut self) -> bool {
        let item = self.missions.lists[0].get(usize::from(self.mission_exec.seq));
        let landing = item.is_some_and(|i| {
            matches!(
                i.command,
                MavCmd::MAV_CMD_NAV_LAND | MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH
            )
        }) && !self.mission_exec.finished;
        if landing && self.mission_exec.entered.is_some() {
            self.item_done();
            return true;
        }
        false
    }
}
