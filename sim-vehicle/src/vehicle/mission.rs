//! The MAVLink mission protocol (<https://mavlink.io/en/services/mission.html>) for the
//! mission, geofence and rally-point lists, as PX4's `MavlinkMissionManager` and ArduPilot's
//! `MissionItemProtocol` serve it.
//!
//! - **Upload**: MISSION_COUNT (its `mission_type`) → MISSION_REQUEST_INT for each item in turn
//!   → MISSION_ITEM_INT (or MISSION_ITEM) → MISSION_ACK `MAV_MISSION_ACCEPTED` after the last,
//!   when the new list replaces the old. A count of 0 clears the list; more than the list holds
//!   (mission 500, fence 64, rally 8: PX4's dataman sizes) is `MAV_MISSION_NO_SPACE`. An item is
//!   checked as it arrives: a command the simulator does not know is `MAV_MISSION_UNSUPPORTED`,
//!   a position item outside the global frames `MAV_MISSION_UNSUPPORTED_FRAME`, a latitude or
//!   longitude out of range `MAV_MISSION_INVALID_PARAM5_X` / `_PARAM6_Y`, a polygon vertex
//!   count below 3 `MAV_MISSION_INVALID_PARAM1`; the transfer ends with that answer. A repeated
//!   item (one already received) is ignored; one ahead of the expected is answered
//!   `MAV_MISSION_INVALID_SEQUENCE` and the transfer goes on (ArduPilot's rule). The vehicle
//!   asks again for an item that does not come (PX4 every 250 ms, ArduPilot every 1 s, wall
//!   time) and gives up after PX4's 5 s / ArduPilot's 8 s of silence with
//!   `MAV_MISSION_OPERATION_CANCELLED`; a ground station's MISSION_ACK during the upload
//!   cancels it. ArduPilot also takes MISSION_WRITE_PARTIAL_LIST (items `start`..=`end` of the
//!   list it has replaced in place); PX4 answers it `MAV_MISSION_UNSUPPORTED`.
//! - **Download**: MISSION_REQUEST_LIST → MISSION_COUNT; MISSION_REQUEST_INT (MISSION_REQUEST)
//!   → MISSION_ITEM_INT (MISSION_ITEM), each item as it was uploaded; a sequence number beyond
//!   the list → `MAV_MISSION_INVALID_SEQUENCE`. ArduPilot's mission list always starts with
//!   home (item 0, frame GLOBAL, AMSL), whatever was uploaded there.
//! - MISSION_CLEAR_ALL (one type, or `MAV_MISSION_TYPE_ALL`) → MISSION_ACK; MISSION_SET_CURRENT
//!   and MAV_CMD_DO_SET_MISSION_CURRENT → MISSION_CURRENT; MAV_CMD_MISSION_START.
//!
//! The `mission_type` of every reply is the request's (an extension field: `wire.rs`).
//! Requests and items are addressed to the system and component that started the transfer.

use std::cmp::Ordering;

use harrier_link::autopilot::Autopilot;
#[allow(deprecated)]
use mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MavCmd, MavFrame, MavMessage,
    MavMissionResult, MavMissionType,
};

use super::Vehicle;
use super::protocol::Cmd;
use super::wire::{Incoming, Outgoing};

/// Items a list holds: mission, fence, rally (PX4's dataman: 500 waypoints, 64 fence
/// vertices, 8 safe points).
const CAPACITY: [usize; 3] = [500, 64, 8];

/// The lists and the transfer in progress.
#[derive(Debug, Clone, Default)]
pub(super) struct Missions {
    /// The mission, fence and rally items, as uploaded.
    pub(super) lists: [Vec<MISSION_ITEM_INT_DATA>; 3],
    /// An upload in progress.
    upload: Option<Upload>,
    /// Bumped whenever the mission list changes (its execution restarts).
    pub(super) version: u64,
}

#[derive(Debug, Clone)]
struct Upload {
    mission_type: u8,
    /// The first and one past the last sequence number to receive.
    first: u16,
    end: u16,
    /// The items received so far (from `first`).
    items: Vec<MISSION_ITEM_INT_DATA>,
    /// Who uploads.
    peer: (u8, u8),
    /// Wall time of the last request sent and of the last item received.
    requested_at: f64,
    heard_at: f64,
}

impl Upload {
    fn next(&self) -> u16 {
        self.first + self.items.len() as u16
    }
}

/// The list of a `mission_type`: 0, 1 or 2.
fn list_index(mission_type: u8) -> Option<usize> {
    (usize::from(mission_type) < CAPACITY.len()).then_some(usize::from(mission_type))
}

/// Commands of mission items the simulator flies or passes over.
pub(super) fn known_command(cmd: MavCmd, mission_type: u8) -> bool {
    use MavCmd as C;
    match mission_type {
        1 => matches!(
            cmd,
            C::MAV_CMD_NAV_FENCE_RETURN_POINT
                | C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                | C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
                | C::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
                | C::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
        ),
        2 => cmd == C::MAV_CMD_NAV_RALLY_POINT,
        _ => is_positional(cmd) || passed_over(cmd) || matches!(cmd, C::MAV_CMD_NAV_DELAY),
    }
}

/// Mission commands with a position (x, y, z in a global frame).
#[allow(deprecated)]
pub(super) fn is_positional(cmd: MavCmd) -> bool {
    use MavCmd as C;
    matches!(
        cmd,
        C::MAV_CMD_NAV_WAYPOINT
            | C::MAV_CMD_NAV_LOITER_UNLIM
            | C::MAV_CMD_NAV_LOITER_TURNS
            | C::MAV_CMD_NAV_LOITER_TIME
            | C::MAV_CMD_NAV_RETURN_TO_LAUNCH
            | C::MAV_CMD_NAV_LAND
            | C::MAV_CMD_NAV_TAKEOFF
            | C::MAV_CMD_DO_SET_ROI_LOCATION
            | C::MAV_CMD_DO_SET_ROI
    )
}

/// DO commands a mission may hold: flown (speed, region of interest, jump) or passed over
/// (camera, gimbal, servo: no such hardware here).
#[allow(deprecated)]
pub(super) fn passed_over(cmd: MavCmd) -> bool {
    use MavCmd as C;
    matches!(
        cmd,
        C::MAV_CMD_DO_CHANGE_SPEED
            | C::MAV_CMD_DO_SET_ROI_NONE
            | C::MAV_CMD_DO_JUMP
            | C::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
            | C::MAV_CMD_DO_MOUNT_CONTROL
            | C::MAV_CMD_DO_MOUNT_CONFIGURE
            | C::MAV_CMD_IMAGE_START_CAPTURE
            | C::MAV_CMD_IMAGE_STOP_CAPTURE
            | C::MAV_CMD_VIDEO_START_CAPTURE
            | C::MAV_CMD_VIDEO_STOP_CAPTURE
            | C::MAV_CMD_DO_SET_CAM_TRIGG_DIST
            | C::MAV_CMD_DO_DIGICAM_CONTROL
            | C::MAV_CMD_SET_CAMERA_MODE
            | C::MAV_CMD_SET_CAMERA_ZOOM
            | C::MAV_CMD_SET_CAMERA_FOCUS
            | C::MAV_CMD_DO_SET_SERVO
    )
}

/// Whether `frame` is one a position item may use: global, AMSL or above home or terrain
/// (terrain taken as above home: no terrain data here), in the float or `_INT` spelling.
#[allow(deprecated)]
pub(super) fn global_frame(frame: MavFrame) -> bool {
    use MavFrame as F;
    matches!(
        frame,
        F::MAV_FRAME_GLOBAL
            | F::MAV_FRAME_GLOBAL_INT
            | F::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | F::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            | F::MAV_FRAME_GLOBAL_TERRAIN_ALT
            | F::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
    )
}

/// What is wrong with an item of a `mission_type` list, if anything.
fn check_item(item: &MISSION_ITEM_INT_DATA, mission_type: u8) -> Option<MavMissionResult> {
    use MavMissionResult as R;
    if !known_command(item.command, mission_type) {
        return Some(R::MAV_MISSION_UNSUPPORTED);
    }
    let positional = mission_type != 0 || is_positional(item.command);
    if positional && !(global_frame(item.frame) || item.frame == MavFrame::MAV_FRAME_MISSION) {
        return Some(R::MAV_MISSION_UNSUPPORTED_FRAME);
    }
    let vertex = matches!(
        item.command,
        MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            | MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    );
    // NaN is refused too.
    if vertex
        && !matches!(
            item.param1.partial_cmp(&3.0),
            Some(Ordering::Greater | Ordering::Equal)
        )
    {
        return Some(R::MAV_MISSION_INVALID_PARAM1);
    }
    let circle = matches!(
        item.command,
        MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
    );
    if circle && !(item.param1 > 0.0 && item.param1.is_finite()) {
        return Some(R::MAV_MISSION_INVALID_PARAM1);
    }
    if positional {
        // Latitude and longitude 0 mean "here" to LAND and RTL.
        if item.x.unsigned_abs() > 900_000_000 {
            return Some(R::MAV_MISSION_INVALID_PARAM5_X);
        }
        if item.y.unsigned_abs() > 1_800_000_000 {
            return Some(R::MAV_MISSION_INVALID_PARAM6_Y);
        }
        if !item.z.is_finite() {
            return Some(R::MAV_MISSION_INVALID_PARAM7);
        }
    }
    None
}

/// A MISSION_ITEM (float degrees) as a MISSION_ITEM_INT.
#[allow(deprecated)]
fn from_float(i: &MISSION_ITEM_DATA) -> MISSION_ITEM_INT_DATA {
    let deg7 = |d: f32| {
        let v = (f64::from(d) * 1e7).round();
        if v.is_finite() {
            v.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
        } else {
            i32::MAX
        }
    };
    MISSION_ITEM_INT_DATA {
        param1: i.param1,
        param2: i.param2,
        param3: i.param3,
        param4: i.param4,
        x: deg7(i.x),
        y: deg7(i.y),
        z: i.z,
        seq: i.seq,
        command: i.command,
        target_system: i.target_system,
        target_component: i.target_component,
        frame: i.frame,
        current: i.current,
        autocontinue: i.autocontinue,
    }
}

/// A MISSION_ITEM_INT as a MISSION_ITEM.
#[allow(deprecated)]
fn to_float(i: &MISSION_ITEM_INT_DATA) -> MISSION_ITEM_DATA {
    MISSION_ITEM_DATA {
        param1: i.param1,
        param2: i.param2,
        param3: i.param3,
        param4: i.param4,
        x: (f64::from(i.x) * 1e-7) as f32,
        y: (f64::from(i.y) * 1e-7) as f32,
        z: i.z,
        seq: i.seq,
        command: i.command,
        target_system: i.target_system,
        target_component: i.target_component,
        frame: i.frame,
        current: i.current,
        autocontinue: i.autocontinue,
    }
}

impl Vehicle {
    /// The items of the mission (`mission_type` 0), geofence (1) or rally-point (2) list, as
    /// uploaded (empty for another type).
    pub fn mission_items(&self, mission_type: u8) -> &[MISSION_ITEM_INT_DATA] {
        list_index(mission_type).map_or(&[], |l| &self.missions.lists[l])
    }

    fn mission_for_us(&self, system: u8, component: u8) -> bool {
        (system == 0 || system == self.config.id)
            && (component == 0 || component == harrier_link::px4::COMPONENT_ID)
    }

    fn px4(&self) -> bool {
        self.personality.autopilot == Autopilot::Px4
    }

    /// The items of list `t` as a ground station downloads them: ArduPilot's mission starts
    /// with home.
    fn download_list(&self, t: usize) -> Vec<MISSION_ITEM_INT_DATA> {
        let mut list = self.missions.lists[t].clone();
        if t == 0 && !self.px4() {
            let home = self.config.origin;
            let item = MISSION_ITEM_INT_DATA {
                x: (home.lat_deg * 1e7).round() as i32,
                y: (home.lon_deg * 1e7).round() as i32,
                z: home.alt_m as f32,
                seq: 0,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame: MavFrame::MAV_FRAME_GLOBAL,
                autocontinue: 1,
                ..MISSION_ITEM_INT_DATA::DEFAULT
            };
            match list.first_mut() {
                Some(first) => *first = item,
                None => list.push(item),
            }
        }
        list
    }

    fn mission_ack(
        &mut self,
        to: (u8, u8),
        mission_type: u8,
        result: MavMissionResult,
    ) -> Outgoing {
        if result != MavMissionResult::MAV_MISSION_ACCEPTED {
            self.counters.refused_commands += 1;
        }
        Outgoing::extended::<MISSION_ACK_DATA>(
            MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system: to.0,
                target_component: to.1,
                mavtype: result,
            }),
            vec![mission_type],
        )
    }

    fn mission_request(u: &Upload) -> Outgoing {
        Outgoing::extended::<MISSION_REQUEST_INT_DATA>(
            MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq: u.next(),
                target_system: u.peer.0,
                target_component: u.peer.1,
            }),
            vec![u.mission_type],
        )
    }

    /// MISSION_CURRENT: the mission item being flown.
    pub(super) fn mission_current(&self) -> MavMessage {
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq: self.mission_seq(),
        })
    }

    /// Handles a mission-protocol message: its replies, `None` for any other message.
    // MISSION_REQUEST and MISSION_ITEM are superseded; clients (pymavlink, MAVProxy) send them.
    #[allow(deprecated)]
    pub(super) fn mission_message(&mut self, now: f64, m: &Incoming<'_>) -> Option<Vec<Outgoing>> {
        let t = m.mission_type;
        let from = m.sender;
        Some(match m.message {
            MavMessage::MISSION_COUNT(c)
                if self.mission_for_us(c.target_system, c.target_component) =>
            {
                self.start_upload(now, from, t, 0, c.count, true)
            }
            MavMessage::MISSION_WRITE_PARTIAL_LIST(p)
                if self.mission_for_us(p.target_system, p.target_component) =>
            {
                let (start, end) = (p.start_index, p.end_index);
                let len = list_index(t).map_or(0, |i| self.missions.lists[i].len());
                let valid = start >= 0 && end >= start && (end as usize) < len;
                if self.px4() || !valid {
                    let result = if self.px4() {
                        MavMissionResult::MAV_MISSION_UNSUPPORTED
                    } else {
                        MavMissionResult::MAV_MISSION_INVALID_SEQUENCE
                    };
                    vec![self.mission_ack(from, t, result)]
                } else {
                    let (first, end) = (start as u16, end as u16 + 1);
                    self.start_upload(now, from, t, first, end, false)
                }
            }
            MavMessage::MISSION_ITEM_INT(i)
                if self.mission_for_us(i.target_system, i.target_component) =>
            {
                self.receive_item(now, from, t, i.clone())
            }
            MavMessage::MISSION_ITEM(i)
                if self.mission_for_us(i.target_system, i.target_component) =>
            {
                self.receive_item(now, from, t, from_float(i))
            }
            MavMessage::MISSION_REQUEST_LIST(r)
                if self.mission_for_us(r.target_system, r.target_component) =>
            {
                match list_index(t) {
                    Some(l) => vec![Outgoing::extended::<MISSION_COUNT_DATA>(
                        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                            count: self.download_list(l).len() as u16,
                            target_system: from.0,
                            target_component: from.1,
                        }),
                        vec![t],
                    )],
                    None => {
                        vec![self.mission_ack(from, t, MavMissionResult::MAV_MISSION_UNSUPPORTED)]
                    }
                }
            }
            MavMessage::MISSION_REQUEST_INT(r)
                if self.mission_for_us(r.target_system, r.target_component) =>
            {
                vec![self.send_item(from, t, r.seq, true)]
            }
            MavMessage::MISSION_REQUEST(r)
                if self.mission_for_us(r.target_system, r.target_component) =>
            {
                vec![self.send_item(from, t, r.seq, false)]
            }
            MavMessage::MISSION_ACK(a)
                if self.mission_for_us(a.target_system, a.target_component) =>
            {
                // The end of a download; during an upload, the ground station cancels it.
                if self
                    .missions
                    .upload
                    .as_ref()
                    .is_some_and(|u| u.mission_type == t)
                {
                    self.missions.upload = None;
                }
                Vec::new()
            }
            MavMessage::MISSION_CLEAR_ALL(c)
                if self.mission_for_us(c.target_system, c.target_component) =>
            {
                let all = t == MavMissionType::MAV_MISSION_TYPE_ALL as u8;
                match list_index(t) {
                    _ if all => {
                        for l in 0..CAPACITY.len() {
                            self.replace_list(l, Vec::new());
                        }
                    }
                    Some(l) => self.replace_list(l, Vec::new()),
                    None => {
                        return Some(vec![self.mission_ack(
                            from,
                            t,
                            MavMissionResult::MAV_MISSION_UNSUPPORTED,
                        )]);
                    }
                }
                vec![self.mission_ack(from, t, MavMissionResult::MAV_MISSION_ACCEPTED)]
            }
            MavMessage::MISSION_SET_CURRENT(s)
                if self.mission_for_us(s.target_system, s.target_component) =>
            {
                self.set_mission_seq(s.seq);
                vec![self.mission_current().into()]
            }
            _ => return None,
        })
    }

    fn start_upload(
        &mut self,
        now: f64,
        from: (u8, u8),
        t: u8,
        first: u16,
        end: u16,
        whole: bool,
    ) -> Vec<Outgoing> {
        use MavMissionResult as R;
        let Some(l) = list_index(t) else {
            return vec![self.mission_ack(from, t, R::MAV_MISSION_UNSUPPORTED)];
        };
        if usize::from(end) > CAPACITY[l] {
            return vec![self.mission_ack(from, t, R::MAV_MISSION_NO_SPACE)];
        }
        if whole && end == 0 {
            self.missions.upload = None;
            self.replace_list(l, Vec::new());
            return vec![self.mission_ack(from, t, R::MAV_MISSION_ACCEPTED)];
        }
        let upload = Upload {
            mission_type: t,
            first,
            end,
            items: Vec::new(),
            peer: from,
            requested_at: now,
            heard_at: now,
        };
        let request = Self::mission_request(&upload);
        self.missions.upload = Some(upload);
        vec![request]
    }

    fn receive_item(
        &mut self,
        now: f64,
        from: (u8, u8),
        t: u8,
        mut item: MISSION_ITEM_INT_DATA,
    ) -> Vec<Outgoing> {
        use MavMissionResult as R;
        let px4 = self.px4();
        let Some(u) = self.missions.upload.as_mut() else {
            return vec![self.mission_ack(from, t, R::MAV_MISSION_ERROR)];
        };
        if u.mission_type != t {
            return vec![self.mission_ack(from, t, R::MAV_MISSION_ERROR)];
        }
        let expected = u.next();
        if item.seq < expected {
            // A repeat (the ground station's retry crossed our request): already stored.
            return Vec::new();
        }
        if item.seq > expected {
            return vec![self.mission_ack(from, t, R::MAV_MISSION_INVALID_SEQUENCE)];
        }
        // ArduPilot's item 0 is home: whatever comes is kept (and replaced on download).
        let home = t == 0 && item.seq == 0 && !px4;
        if !home {
            if let Some(error) = check_item(&item, t) {
                self.missions.upload = None;
                return vec![self.mission_ack(from, t, error)];
            }
        }
        u.heard_at = now;
        u.requested_at = now;
        item.target_system = 0;
        item.target_component = 0;
        u.items.push(item);
        if u.next() < u.end {
            return vec![Self::mission_request(u)];
        }
        let (first, items) = (u.first, std::mem::take(&mut u.items));
        self.missions.upload = None;
        let Some(l) = list_index(t) else {
            return Vec::new();
        };
        let mut list = self.missions.lists[l].clone();
        if first == 0 {
            list = items;
        } else {
            for (k, i) in items.into_iter().enumerate() {
                if let Some(slot) = list.get_mut(usize::from(first) + k) {
                    *slot = i;
                }
            }
        }
        self.replace_list(l, list);
        vec![self.mission_ack(from, t, R::MAV_MISSION_ACCEPTED)]
    }

    #[allow(deprecated)]
    fn send_item(&mut self, to: (u8, u8), t: u8, seq: u16, int: bool) -> Outgoing {
        let item = list_index(t).and_then(|l| self.download_list(l).get(usize::from(seq)).cloned());
        let Some(mut item) = item else {
            return self.mission_ack(to, t, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE);
        };
        item.target_system = to.0;
        item.target_component = to.1;
        item.current = u8::from(t == 0 && seq == self.mission_seq());
        if int {
            Outgoing::extended::<MISSION_ITEM_INT_DATA>(MavMessage::MISSION_ITEM_INT(item), vec![t])
        } else {
            Outgoing::extended::<MISSION_ITEM_DATA>(
                MavMessage::MISSION_ITEM(to_float(&item)),
                vec![t],
            )
        }
    }

    /// Replaces list `l`; a new mission restarts from its first item.
    fn replace_list(&mut self, l: usize, items: Vec<MISSION_ITEM_INT_DATA>) {
        self.missions.lists[l] = items;
        if l == 0 {
            self.missions.version += 1;
            self.restart_mission();
        }
    }

    /// The upload's retries and timeout (wall time `now`): what to send.
    pub(super) fn mission_tick(&mut self, now: f64) -> Option<Outgoing> {
        let (retry, timeout) = if self.px4() { (0.25, 5.0) } else { (1.0, 8.0) };
        let u = self.missions.upload.as_mut()?;
        if now - u.heard_at > timeout {
            let (peer, t) = (u.peer, u.mission_type);
            self.missions.upload = None;
            return Some(self.mission_ack(
                peer,
                t,
                MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
            ));
        }
        if now - u.requested_at > retry {
            u.requested_at = now;
            return Some(Self::mission_request(u));
        }
        None
    }

    /// MAV_CMD_DO_SET_MISSION_CURRENT (param1 the item) and MAV_CMD_MISSION_START (param1 the
    /// first item, 0: from where it is): the answer.
    pub(super) fn mission_command(
        &mut self,
        now: f64,
        c: &Cmd,
    ) -> mavlink::dialects::common::MavResult {
        use mavlink::dialects::common::MavResult as R;
        let seq = c.p[0];
        let len = self.missions.lists[0].len();
        let valid = seq.is_finite() && seq >= 0.0 && (seq as usize) < len.max(1);
        if !valid {
            return R::MAV_RESULT_DENIED;
        }
        if c.command == MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT {
            self.set_mission_seq(seq as u16);
            self.push_out(self.mission_current().into());
            return R::MAV_RESULT_ACCEPTED;
        }
        if seq > 0.0 {
            self.set_mission_seq(seq as u16);
        }
        let auto = self
            .personality
            .mode_named(if self.px4() { "MISSION" } else { "AUTO" });
        match auto {
            Some(mode) => {
                let r = self.request_mode(now, mode);
                if r == R::MAV_RESULT_ACCEPTED {
                    self.mission_exec.started = true;
                }
                r
            }
            None => R::MAV_RESULT_UNSUPPORTED,
        }
    }
}
