//! Unit tests of the mission protocol (upload, download, clear, current, fence and rally lists,
//! retries and timeouts, refused items) and of flying a mission (PX4 AUTO.MISSION, ArduCopter
//! AUTO).

// The `_INT` frames are superseded; QGroundControl and MAVSDK still send them.
#![allow(deprecated)]

use super::tests_ardupilot::{ack_of, run};
use super::*;
use harrier_link::command::{arm, command_long, set_mode, takeoff_relative};
use mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, MavCmd, MavFrame, MavMessage,
    MavMissionResult, MavResult,
};

const GCS: (u8, u8) = (245, 190);

/// Sends `m` with `mission_type` `t` from [`GCS`]: the replies.
fn send(v: &mut Vehicle, now: f64, m: &MavMessage, t: u8) -> Vec<Outgoing> {
    v.handle_frame(
        now,
        Incoming {
            message: m,
            sender: GCS,
            mission_type: t,
        },
    )
}

fn count(n: u16) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n,
        target_system: 1,
        target_component: 1,
    })
}

/// A mission item at `north`, `east` m from home, `up` m above it.
fn item(
    v: &Vehicle,
    seq: u16,
    cmd: MavCmd,
    north: f64,
    east: f64,
    up: f32,
) -> MISSION_ITEM_INT_DATA {
    let g = v.frame.from_enu(&Vector3::new(east, north, 0.0));
    MISSION_ITEM_INT_DATA {
        x: (g.lat_deg * 1e7).round() as i32,
        y: (g.lon_deg * 1e7).round() as i32,
        z: up,
        seq,
        command: cmd,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        autocontinue: 1,
        ..MISSION_ITEM_INT_DATA::DEFAULT
    }
}

/// The sequence number a reply requests, the result of an ack, or a panic.
fn requested(r: &[Outgoing]) -> u16 {
    match r.first().map(|o| &o.message) {
        Some(MavMessage::MISSION_REQUEST_INT(q)) => {
            assert_eq!((q.target_system, q.target_component), GCS);
            q.seq
        }
        other => panic!("no MISSION_REQUEST_INT: {other:?}"),
    }
}

fn mission_ack(r: &[Outgoing]) -> (MavMissionResult, u8) {
    match r.first() {
        Some(Outgoing {
            message: MavMessage::MISSION_ACK(a),
            ..
        }) => (a.mavtype, r[0].extension().first().copied().unwrap_or(0)),
        other => panic!("no MISSION_ACK: {other:?}"),
    }
}

/// Uploads `items` as list `t`: the final answer.
fn upload(
    v: &mut Vehicle,
    now: f64,
    items: &[MISSION_ITEM_INT_DATA],
    t: u8,
) -> (MavMissionResult, u8) {
    let mut r = send(v, now, &count(items.len() as u16), t);
    for i in items {
        assert_eq!(requested(&r), i.seq);
        assert_eq!(r[0].extension().first().copied().unwrap_or(0), t);
        r = send(v, now, &MavMessage::MISSION_ITEM_INT(i.clone()), t);
    }
    mission_ack(&r)
}

/// Downloads list `t`.
fn download(v: &mut Vehicle, now: f64, t: u8) -> Vec<MISSION_ITEM_INT_DATA> {
    let list = MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 1,
    });
    let n = match send(v, now, &list, t).first().map(|o| &o.message) {
        Some(MavMessage::MISSION_COUNT(c)) => c.count,
        other => panic!("{other:?}"),
    };
    (0..n)
        .map(|seq| {
            let req = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq,
                target_system: 1,
                target_component: 1,
            });
            match send(v, now, &req, t).first().map(|o| &o.message) {
                Some(MavMessage::MISSION_ITEM_INT(i)) => i.clone(),
                other => panic!("{other:?}"),
            }
        })
        .collect()
}

/// What the ground station uploaded comes back (its target ids its own), per list type; a
/// clear empties one type or all.
#[test]
fn missions_fences_and_rally_points_round_trip() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let mission = [
        item(&v, 0, MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 10.0),
        item(&v, 1, MavCmd::MAV_CMD_NAV_WAYPOINT, 50.0, 0.0, 10.0),
        item(&v, 2, MavCmd::MAV_CMD_NAV_LAND, 50.0, 0.0, 0.0),
    ];
    let mut fence: Vec<_> = [
        (100.0, 100.0),
        (100.0, -100.0),
        (-100.0, -100.0),
        (-100.0, 100.0),
    ]
    .iter()
    .enumerate()
    .map(|(k, &(n, e))| {
        let mut i = item(
            &v,
            k as u16,
            MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            n,
            e,
            0.0,
        );
        i.param1 = 4.0;
        i
    })
    .collect();
    fence[0].frame = MavFrame::MAV_FRAME_GLOBAL_INT;
    let rally = [item(
        &v,
        0,
        MavCmd::MAV_CMD_NAV_RALLY_POINT,
        20.0,
        20.0,
        15.0,
    )];
    assert_eq!(
        upload(&mut v, 0.0, &mission, 0),
        (MavMissionResult::MAV_MISSION_ACCEPTED, 0)
    );
    assert_eq!(
        upload(&mut v, 0.0, &fence, 1),
        (MavMissionResult::MAV_MISSION_ACCEPTED, 1)
    );
    assert_eq!(
        upload(&mut v, 0.0, &rally, 2),
        (MavMissionResult::MAV_MISSION_ACCEPTED, 2)
    );
    let back = |i: &MISSION_ITEM_INT_DATA, seq: u16| MISSION_ITEM_INT_DATA {
        target_system: GCS.0,
        target_component: GCS.1,
        current: u8::from(seq == 0),
        ..*i
    };
    let got = download(&mut v, 0.0, 0);
    assert_eq!(
        got,
        mission.iter().map(|i| back(i, i.seq)).collect::<Vec<_>>()
    );
    let got = download(&mut v, 0.0, 1);
    // Only the mission has a current item.
    let fence_back: Vec<_> = fence
        .iter()
        .map(|i| MISSION_ITEM_INT_DATA {
            current: 0,
            ..back(i, 1)
        })
        .collect();
    assert_eq!(got, fence_back);
    assert_eq!(download(&mut v, 0.0, 2).len(), 1);
    let clear = |t: u8, v: &mut Vehicle| {
        let m = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: 1,
            target_component: 1,
        });
        mission_ack(&send(v, 0.0, &m, t))
    };
    assert_eq!(
        clear(1, &mut v),
        (MavMissionResult::MAV_MISSION_ACCEPTED, 1)
    );
    assert!(download(&mut v, 0.0, 1).is_empty());
    assert_eq!(download(&mut v, 0.0, 0).len(), 3, "the mission stays");
    assert_eq!(clear(255, &mut v).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert!(download(&mut v, 0.0, 0).is_empty() && download(&mut v, 0.0, 2).is_empty());
}

/// Refusals: too many items, an unknown command, a position in a local frame, a bad latitude,
/// a polygon of two vertices; a repeated item is ignored, one ahead refused with the transfer
/// going on; a request beyond the list is INVALID_SEQUENCE.
#[test]
fn bad_uploads_are_refused_with_mission_protocol_codes() {
    use MavMissionResult as R;
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    assert_eq!(
        mission_ack(&send(&mut v, 0.0, &count(501), 0)).0,
        R::MAV_MISSION_NO_SPACE
    );
    assert_eq!(
        mission_ack(&send(&mut v, 0.0, &count(65), 1)).0,
        R::MAV_MISSION_NO_SPACE
    );
    let wp = item(&v, 0, MavCmd::MAV_CMD_NAV_WAYPOINT, 10.0, 0.0, 5.0);
    let one = |v: &mut Vehicle, i: MISSION_ITEM_INT_DATA, t: u8| upload(v, 0.0, &[i], t).0;
    assert_eq!(
        one(
            &mut v,
            MISSION_ITEM_INT_DATA {
                command: MavCmd::MAV_CMD_DO_FLIGHTTERMINATION,
                ..wp
            },
            0
        ),
        R::MAV_MISSION_UNSUPPORTED
    );
    assert_eq!(
        one(
            &mut v,
            MISSION_ITEM_INT_DATA {
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                ..wp
            },
            0
        ),
        R::MAV_MISSION_UNSUPPORTED_FRAME
    );
    assert_eq!(
        one(
            &mut v,
            MISSION_ITEM_INT_DATA {
                x: 950_000_000,
                ..wp
            },
            0
        ),
        R::MAV_MISSION_INVALID_PARAM5_X
    );
    let vertex = MISSION_ITEM_INT_DATA {
        command: MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        param1: 2.0,
        ..wp
    };
    assert_eq!(one(&mut v, vertex, 1), R::MAV_MISSION_INVALID_PARAM1);
    assert_eq!(
        one(&mut v, wp.clone(), 1),
        R::MAV_MISSION_UNSUPPORTED,
        "a waypoint is no fence item"
    );
    assert!(download(&mut v, 0.0, 0).is_empty(), "nothing kept");

    let items = [
        wp.clone(),
        MISSION_ITEM_INT_DATA {
            seq: 1,
            ..wp.clone()
        },
        MISSION_ITEM_INT_DATA { seq: 2, ..wp },
    ];
    assert_eq!(requested(&send(&mut v, 0.0, &count(3), 0)), 0);
    assert_eq!(
        requested(&send(
            &mut v,
            0.0,
            &MavMessage::MISSION_ITEM_INT(items[0].clone()),
            0
        )),
        1
    );
    assert!(
        send(
            &mut v,
            0.0,
            &MavMessage::MISSION_ITEM_INT(items[0].clone()),
            0
        )
        .is_empty(),
        "repeat"
    );
    let ahead = send(
        &mut v,
        0.0,
        &MavMessage::MISSION_ITEM_INT(items[2].clone()),
        0,
    );
    assert_eq!(mission_ack(&ahead).0, R::MAV_MISSION_INVALID_SEQUENCE);
    assert_eq!(
        requested(&send(
            &mut v,
            0.0,
            &MavMessage::MISSION_ITEM_INT(items[1].clone()),
            0
        )),
        2
    );
    let done = send(
        &mut v,
        0.0,
        &MavMessage::MISSION_ITEM_INT(items[2].clone()),
        0,
    );
    assert_eq!(mission_ack(&done).0, R::MAV_MISSION_ACCEPTED);
    let beyond = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq: 3,
        target_system: 1,
        target_component: 1,
    });
    assert_eq!(
        mission_ack(&send(&mut v, 0.0, &beyond, 0)).0,
        R::MAV_MISSION_INVALID_SEQUENCE
    );
}

/// A silent uploader is asked again (PX4: every 250 ms) and given up after 5 s with
/// OPERATION_CANCELLED; the old mission stays. A ground station's MISSION_ACK cancels.
#[test]
fn a_stalled_upload_is_retried_then_cancelled() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let wp = item(&v, 0, MavCmd::MAV_CMD_NAV_WAYPOINT, 10.0, 0.0, 5.0);
    assert_eq!(
        upload(&mut v, 0.0, &[wp], 0).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    assert_eq!(requested(&send(&mut v, 1.0, &count(2), 0)), 0);
    let mut requests = 0;
    let mut cancelled = None;
    let mut t = 1.0;
    while t < 8.0 {
        t += 0.05;
        for o in v.telemetry_frames(t) {
            match o.message {
                MavMessage::MISSION_REQUEST_INT(q) if q.seq == 0 => requests += 1,
                MavMessage::MISSION_ACK(a) => cancelled = cancelled.or(Some((t, a.mavtype))),
                _ => {}
            }
        }
    }
    assert!((15..=20).contains(&requests), "{requests} retries");
    let (at, result) = cancelled.expect("cancelled");
    assert_eq!(result, MavMissionResult::MAV_MISSION_OPERATION_CANCELLED);
    assert!((at - 6.0).abs() < 0.1, "{at}");
    assert_eq!(download(&mut v, 8.0, 0).len(), 1, "the old mission stays");

    assert_eq!(requested(&send(&mut v, 9.0, &count(2), 0)), 0);
    let cancel = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        target_component: 1,
        mavtype: MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
    });
    assert!(send(&mut v, 9.1, &cancel, 0).is_empty());
    assert!(
        v.telemetry_frames(10.0)
            .iter()
            .all(|o| !matches!(o.message, MavMessage::MISSION_REQUEST_INT(_)))
    );
}

/// PX4 AUTO.MISSION from the ground: refused without a mission; armed, it takes off by itself,
/// flies the waypoints (holding param1 s at the second), reports each item reached, and the
/// NAV_LAND lands and disarms it at the last point.
#[test]
fn px4_flies_a_mission_and_reports_progress() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let mission = Mode::Px4(FlightMode::Mission);
    assert_eq!(
        ack_of(&v.handle(0.0, &set_mode(1, mission))),
        MavResult::MAV_RESULT_DENIED
    );
    let mut hold = item(&v, 1, MavCmd::MAV_CMD_NAV_WAYPOINT, 60.0, 40.0, 15.0);
    hold.param1 = 5.0;
    let mut speed = item(&v, 2, MavCmd::MAV_CMD_DO_CHANGE_SPEED, 0.0, 0.0, 0.0);
    speed.param2 = 3.0;
    speed.frame = MavFrame::MAV_FRAME_MISSION;
    let items = [
        item(&v, 0, MavCmd::MAV_CMD_NAV_WAYPOINT, 0.0, 40.0, 10.0),
        hold,
        speed,
        item(&v, 3, MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0),
    ];
    assert_eq!(
        upload(&mut v, 0.0, &items, 0).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    assert_eq!(
        ack_of(&v.handle(0.0, &arm(1))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        ack_of(&v.handle(0.0, &set_mode(1, mission))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let mut reached = Vec::new();
    let mut at_hold = None;
    let mut fastest_last_leg = 0.0f64;
    let mut t = 0.0;
    while t < 200.0 {
        t += 0.05;
        for o in v.telemetry_frames(t) {
            if let MavMessage::MISSION_ITEM_REACHED(r) = o.message {
                reached.push((r.seq, t));
                if r.seq == 1 {
                    at_hold = Some(v.state().position);
                }
            }
        }
        if reached.len() == 3 {
            fastest_last_leg = fastest_last_leg.max(v.state().horizontal_velocity().norm());
        }
    }
    let seqs: Vec<u16> = reached.iter().map(|r| r.0).collect();
    assert_eq!(seqs, [0, 1, 2, 3]);
    let p = at_hold.expect("reached 1");
    assert!((p - Vector3::new(40.0, 60.0, 15.0)).norm() < 2.5, "{p:?}");
    assert!(
        fastest_last_leg < 3.1,
        "DO_CHANGE_SPEED 3 m/s: {fastest_last_leg}"
    );
    assert!(!v.armed(), "landed");
    assert!(
        v.state().position.xy().norm() < 2.5,
        "{:?}",
        v.state().position
    );
    assert_eq!(v.mode(), mission);
    assert_eq!(v.mission_seq(), 3);
}

/// ArduCopter: item 0 is home (downloaded as home whatever was uploaded); AUTO entered in the
/// air runs from item 1; MAV_CMD_MISSION_START starts it; NAV_RETURN_TO_LAUNCH brings it home
/// and lands it.
#[test]
fn ardupilot_missions_start_after_home_and_return() {
    let copter = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let mut v = Vehicle::new(VehicleConfig::new(1).with_personality(copter), 0.0);
    let items = [
        item(&v, 0, MavCmd::MAV_CMD_NAV_WAYPOINT, 500.0, 500.0, 0.0),
        item(&v, 1, MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 20.0),
        item(&v, 2, MavCmd::MAV_CMD_NAV_WAYPOINT, 80.0, 0.0, 20.0),
        item(&v, 3, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0),
    ];
    assert_eq!(
        upload(&mut v, 0.0, &items, 0).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let down = download(&mut v, 0.0, 0);
    assert_eq!(down.len(), 4);
    assert_eq!(
        (down[0].frame, down[0].z),
        (MavFrame::MAV_FRAME_GLOBAL, 488.0),
        "home"
    );
    assert_eq!(down[0].x, (v.config().origin.lat_deg * 1e7).round() as i32);
    assert_eq!(down[2].x, items[2].x);
    let guided = Mode::Copter(CopterMode::Guided);
    assert_eq!(
        ack_of(&v.handle(0.0, &set_mode(1, guided))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        ack_of(&v.handle(0.0, &arm(1))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let start = command_long(1, MavCmd::MAV_CMD_MISSION_START, [0.0; 7]);
    assert_eq!(
        ack_of(&v.handle(0.0, &start)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Auto));
    let mut reached = Vec::new();
    let mut top = 0.0f64;
    let mut far = 0.0f64;
    run(&mut v, 0.0, 150.0, |v, t| {
        top = top.max(v.state().position.z);
        far = far.max(v.state().position.y);
        for o in v.telemetry_frames(t) {
            if let MavMessage::MISSION_ITEM_REACHED(r) = o.message {
                reached.push(r.seq);
            }
        }
    });
    assert_eq!(reached, [1, 2, 3]);
    assert!((top - 20.0).abs() < 1.0 && far > 77.0, "{top} {far}");
    assert!(
        !v.armed() && v.state().position.norm() < 1.5,
        "{:?}",
        v.state()
    );

    // In the air, AUTO by mode switch (no MISSION_START) starts over from item 1.
    let mut v = Vehicle::new(VehicleConfig::new(1).with_personality(copter), 0.0);
    assert_eq!(
        upload(&mut v, 0.0, &items, 0).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    v.handle(0.0, &set_mode(1, guided));
    v.handle(0.0, &arm(1));
    assert_eq!(
        ack_of(&v.handle(0.0, &takeoff_relative(1, 20.0))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    run(&mut v, 0.0, 20.0, |_, _| {});
    let auto = Mode::Copter(CopterMode::Auto);
    assert_eq!(
        ack_of(&v.handle(20.0, &set_mode(1, auto))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mission_seq(), 1);
    run(&mut v, 20.0, 40.0, |_, _| {});
    assert!(v.mission_seq() >= 2);
}

/// PX4's DO_REPOSITION (MAVSDK's goto_location, COMMAND_INT in GLOBAL: AMSL): Hold flies to the
/// point at MPC_XY_CRUISE and holds it; refused on the ground.
#[test]
fn px4_goto_flies_to_the_point_in_hold() {
    use harrier_link::command::command_int;
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let target = v.frame.from_enu(&Vector3::new(-30.0, 80.0, 20.0));
    let goto = command_int(
        1,
        MavCmd::MAV_CMD_DO_REPOSITION,
        MavFrame::MAV_FRAME_GLOBAL,
        [-1.0, 1.0, 0.0, f32::NAN],
        (
            (target.lat_deg * 1e7).round() as i32,
            (target.lon_deg * 1e7).round() as i32,
            target.alt_m as f32,
        ),
    );
    assert_eq!(ack_of(&v.handle(0.0, &goto)), MavResult::MAV_RESULT_DENIED);
    assert_eq!(
        ack_of(&v.handle(0.0, &arm(1))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let takeoff = command_long(1, MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7]);
    assert_eq!(
        ack_of(&v.handle(0.0, &takeoff)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    run(&mut v, 0.0, 10.0, |_, _| {});
    let pos = Mode::Px4(FlightMode::Position);
    assert_eq!(
        ack_of(&v.handle(10.0, &set_mode(1, pos))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        ack_of(&v.handle(10.0, &goto)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold));
    let mut fastest = 0.0f64;
    run(&mut v, 10.0, 60.0, |v, _| {
        fastest = fastest.max(v.state().horizontal_velocity().norm())
    });
    assert!(fastest < 5.1, "MPC_XY_CRUISE: {fastest}");
    let miss = (v.state().position - Vector3::new(-30.0, 80.0, 20.0)).norm();
    assert!(miss < 0.5, "{:?}", v.state().position);
}
