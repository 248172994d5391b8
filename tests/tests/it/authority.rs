//! The operator stays in command: on `harrier demo`'s ring of three PX4 multirotors orbiting a
//! car (in process, real UDP MAVLink, a real Zenoh session, the router on a free port):
//!
//! - a router client (pymavlink, `tests/python/mode_switch.py`: the MAV_CMD_DO_SET_MODE
//!   QGroundControl's flight-mode menu sends) puts UAV 2 in Hold: its slot is `overridden` (by
//!   `router_client`) within one guidance tick of the HEARTBEAT that shows the change; for
//!   60 simulated seconds it stays in Hold and the ground station sends it no command, mode
//!   request or setpoint; UAVs 1 and 3 re-space to 180°; after `resume` through the API it flies
//!   its slot again;
//! - the API's `hold` to UAV 3 answers `accepted` with the assignment it took the vehicle out
//!   of, and UAV 3 stays in Hold, sent nothing more;
//! - an impostor claiming system id 1 from another UDP address is flagged within 1 s (a
//!   `conflict` event, `identity.conflict` on `GET /api/v1/vehicles`, the counters), receives
//!   nothing at all, and UAV 1 keeps flying its slot (range error unchanged);
//! - UAV 1's battery below the safety envelope's floor (25 %): out of its slot (`failed`, the
//!   reason named) and sent home: in RTL, nearer home 5 s later.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use harrier_cli::demo::{self, DemoConfig};
use harrier_server::LiveServer;
use harrier_server::gcs::LinkEventKind;
use harrier_server::guidance::{AssignmentView, OverrideSource, SlotState};
use harrier_sim::mavlink::MavHeader;
use harrier_sim::mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavType};
use harrier_tests::{python_script, require_python_module, runtime, wait_with_deadline, within};
use serde_json::Value;

use crate::live_server::{get, get_json, metric, send};

/// The demo's standoff radius (m).
const R: f64 = 150.0;
/// Simulated seconds per wall second.
const SPEEDUP: f64 = 5.0;

/// The first assignment, as the guidance publishes it.
pub(crate) fn assignment(s: &LiveServer) -> Option<AssignmentView> {
    s.guidance()?.assignments.borrow().first().cloned()
}

/// Waits (up to `secs`) until `ok` holds of the first assignment.
async fn until(s: &LiveServer, secs: u64, what: &str, ok: impl Fn(&AssignmentView) -> bool) {
    let mut rx = s.guidance().expect("guidance").assignments.clone();
    within(secs, what, async {
        loop {
            if rx.borrow_and_update().first().is_some_and(&ok) {
                return;
            }
            rx.changed().await.expect("guidance running");
        }
    })
    .await;
}

/// Whether `vehicles` all fly their slots on the circle (offboard, |r − R| < 5 % of R).
fn on_circle(a: &AssignmentView, vehicles: &[u8]) -> bool {
    vehicles.iter().all(|id| {
        a.vehicles.iter().any(|s| {
            s.vehicle == *id
                && s.state == SlotState::Offboard
                && s.range_error_m.is_some_and(|e| e.abs() < 0.05 * R)
        })
    })
}

/// The phase gaps (degrees) between the slots of `vehicles` around the circle, and their range
/// errors, sampled every 250 ms for `secs` wall seconds: (spacing error RMS against `spacing`,
/// range error RMS).
async fn ring_errors(s: &LiveServer, vehicles: &[u8], spacing: f64, secs: u64) -> (f64, f64) {
    let (mut sp2, mut r2, mut n, mut m) = (0.0, 0.0, 0usize, 0usize);
    for _ in 0..secs * 4 {
        tokio::time::sleep(Duration::from_millis(250)).await;
        let Some(a) = assignment(s) else { continue };
        let slots: Vec<_> = a
            .vehicles
            .iter()
            .filter(|x| vehicles.contains(&x.vehicle))
            .collect();
        let mut phases: Vec<f64> = slots.iter().filter_map(|x| x.phase_deg).collect();
        for e in slots.iter().filter_map(|x| x.range_error_m) {
            r2 += e * e;
            m += 1;
        }
        if phases.len() != vehicles.len() {
            continue;
        }
        phases.sort_by(f64::total_cmp);
        for i in 0..phases.len() {
            let gap = (phases[(i + 1) % phases.len()] - phases[i]).rem_euclid(360.0);
            sp2 += (gap - spacing).powi(2);
            n += 1;
        }
    }
    (
        (sp2 / n.max(1) as f64).sqrt(),
        (r2 / m.max(1) as f64).sqrt(),
    )
}

/// What the link knows of vehicle `id`: its mode and the commands the ground station sent it.
pub(crate) fn link_of(s: &LiveServer, id: u8) -> (Option<String>, u64) {
    s.link()
        .expect("link")
        .vehicles
        .borrow()
        .iter()
        .find(|v| v.view.id == id)
        .map_or((None, 0), |v| (v.view.mode.clone(), v.view.commands_sent))
}

/// Watches vehicle `id` for `secs` wall seconds: it must stay in `mode`, and the ground station
/// must send it nothing that steers it. Returns how often it was sampled.
pub(crate) async fn stays_out(s: &LiveServer, id: u8, mode: &str, secs: u64) -> usize {
    let (_, sent) = link_of(s, id);
    let mut samples = 0;
    let until = Instant::now() + Duration::from_secs(secs);
    while Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let (m, now) = link_of(s, id);
        assert_eq!(m.as_deref(), Some(mode), "UAV {id} left {mode}");
        assert_eq!(
            now, sent,
            "the ground station commanded UAV {id} after it was taken"
        );
        samples += 1;
    }
    samples
}

/// Runs `tests/python/mode_switch.py`: pymavlink through the router at `router` puts vehicle
/// `id` in `mode` (pymavlink's name), as QGroundControl's flight-mode menu does.
pub(crate) async fn router_client_mode(router: SocketAddr, id: u8, mode: &str) {
    let mut child = python_script("mode_switch.py")
        .args([
            "--connect",
            &format!("udpout:{router}"),
            "--vehicle",
            &id.to_string(),
            "--mode",
            mode,
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("run mode_switch.py");
    let status = tokio::task::spawn_blocking(move || {
        wait_with_deadline(&mut child, Duration::from_secs(60), "mode_switch.py")
    })
    .await
    .expect("join");
    assert!(status.success(), "mode_switch.py: {status}");
}

#[test]
fn the_operator_wins_over_the_guidance() {
    require_python_module("pymavlink", "pymavlink");
    runtime().block_on(within(420, "the authority test", async {
        let config = DemoConfig {
            speedup: SPEEDUP,
            seed: 2,
            radius: R,
            router: vec!["udpin:127.0.0.1:0".into()],
            ..DemoConfig::ephemeral(SocketAddr::from(([127, 0, 0, 1], 0)))
        };
        let demo = within(30, "start the demo", demo::start(&config))
            .await
            .expect("start the demo");
        let server = demo.server();
        let addr = server.local_addr();
        let token = server.token().0.to_owned();
        let link = server.link().expect("link");
        let router = link.router().next().expect("a router endpoint").addr();
        let gcs = link.gcs().next().expect("a GCS endpoint").addr();
        let started = Instant::now();
        until(server, 180, "the ring on its circle", |a| {
            on_circle(a, &[1, 2, 3])
        })
        .await;
        eprintln!(
            "authority: ring on the circle after {:.1} s",
            started.elapsed().as_secs_f64()
        );

        // 1. A router client's Hold to UAV 2, as QGroundControl's flight-mode menu sends it.
        let mut link_events = link.events.subscribe();
        let mut slot_events = server.guidance().expect("guidance").events.subscribe();
        let held = tokio::spawn(async move {
            loop {
                let e = link_events.recv().await.expect("link events");
                if e.vehicle == 2
                    && e.event == LinkEventKind::Mode
                    && e.mode.as_deref() == Some("HOLD")
                {
                    return Instant::now();
                }
            }
        });
        let taken = tokio::spawn(async move {
            loop {
                let a = slot_events.recv().await.expect("assignment events");
                if let Some(s) = a.vehicles.iter().find(|s| s.vehicle == 2)
                    && s.state == SlotState::Overridden
                {
                    return (Instant::now(), s.clone());
                }
            }
        });
        router_client_mode(router, 2, "LOITER").await;
        let held = within(10, "UAV 2's HEARTBEAT in HOLD", held)
            .await
            .expect("join");
        let (at, slot) = within(10, "UAV 2's slot overridden", taken)
            .await
            .expect("join");
        let lag = at.saturating_duration_since(held).as_secs_f64();
        let o = slot.overridden.expect("what was seen");
        eprintln!(
            "authority: router client's Hold: slot overridden {:.0} ms after the HEARTBEAT's \
             event ({}: {:?} -> {:?}; {})",
            lag * 1e3,
            o.by.as_str(),
            o.from_mode,
            o.to_mode,
            o.detail
        );
        // One guidance tick (50 ms) after the link's 20 Hz publication of the HEARTBEAT.
        assert!(lag <= 0.15, "overridden {lag} s after the HEARTBEAT");
        assert_eq!(o.by, OverrideSource::RouterClient, "{o:?}");
        assert!(o.detail.contains("MAV_CMD_DO_SET_MODE"), "{}", o.detail);
        assert_eq!(o.to_mode.as_deref(), Some("HOLD"));
        // 60 simulated seconds in Hold, sent nothing; meanwhile 1 and 3 re-space to 180°.
        let respacing = Instant::now();
        let watch = stays_out(server, 2, "HOLD", (60.0 / SPEEDUP) as u64);
        let (samples, respaced) = tokio::join!(watch, async {
            until(server, 120, "UAVs 1 and 3 180° apart", |a| {
                let p: Vec<f64> = a
                    .vehicles
                    .iter()
                    .filter(|s| s.vehicle != 2)
                    .filter_map(|s| s.phase_deg)
                    .collect();
                on_circle(a, &[1, 3])
                    && p.len() == 2
                    && ((p[1] - p[0]).rem_euclid(360.0) - 180.0).abs() < 10.0
            })
            .await;
            respacing.elapsed().as_secs_f64()
        });
        let (spacing, range) = ring_errors(server, &[1, 3], 180.0, 6).await;
        eprintln!(
            "authority: UAV 2 in HOLD over {samples} samples, 0 commands; UAVs 1 and 3 within \
             10° of 180° apart after {respaced:.1} s ({:.0} simulated), then spacing error RMS \
             {spacing:.1}°, |r - R| RMS {range:.2} m",
            respaced * SPEEDUP
        );
        assert!(stays_out(server, 2, "HOLD", 1).await > 0);
        let a = assignment(server).expect("assignment");
        assert!((a.spacing_deg - 180.0).abs() < 1e-9, "{a:?}");
        assert!(spacing <= 15.0, "spacing error RMS {spacing}°");
        assert!(range <= 0.05 * R, "|r - R| RMS {range} m");

        // 2. The operator takes it back: it flies its slot again (a second resume: 409).
        for expected in [200, 409] {
            let path = "/api/v1/assignments/1/vehicles/2/resume";
            let (status, body) = send(addr, "POST", path, Some(&token), None).await;
            assert_eq!(status, expected, "{body}");
        }
        let resumed = Instant::now();
        until(server, 90, "UAV 2 back on the circle", |a| {
            on_circle(a, &[1, 2, 3])
        })
        .await;
        eprintln!(
            "authority: UAV 2 resumed: the three on the circle again after {:.1} s",
            resumed.elapsed().as_secs_f64()
        );

        // 3. The API's Hold to UAV 3: out of its slot first, and it holds.
        let hold = serde_json::json!({"command": "hold"});
        let (status, body) = send(
            addr,
            "POST",
            "/api/v1/vehicles/3/commands",
            Some(&token),
            Some(&hold),
        )
        .await;
        assert_eq!(status, 200, "{body}");
        let answer: Value = serde_json::from_str(&body).expect("json");
        assert_eq!(answer["result"], "accepted", "{answer}");
        assert_eq!(answer["released_from_assignment"], 1, "{answer}");
        let slot = assignment(server)
            .and_then(|a| a.vehicles.into_iter().find(|s| s.vehicle == 3))
            .expect("slot");
        assert_eq!(slot.state, SlotState::Overridden);
        assert_eq!(slot.overridden.map(|o| o.by), Some(OverrideSource::Api));
        within(10, "UAV 3 in HOLD", async {
            while link_of(server, 3).0.as_deref() != Some("HOLD") {
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
        .await;
        let samples = stays_out(server, 3, "HOLD", 4).await;
        eprintln!("authority: API hold: UAV 3 in HOLD over {samples} samples, 0 commands after");

        // 4. An impostor claims system id 1 from another address while UAV 1 flies its slot.
        let (_, before) = ring_errors(server, &[1], 360.0, 3).await;
        let impostor = UdpSocket::bind("127.0.0.1:0").expect("bind");
        impostor
            .set_read_timeout(Some(Duration::from_millis(20)))
            .expect("timeout");
        let me = impostor.local_addr().expect("addr");
        let mut conflicts = link.events.subscribe();
        let first = Instant::now();
        let flagged = tokio::spawn(async move {
            loop {
                let e = conflicts.recv().await.expect("link events");
                if e.vehicle == 1 && e.event == LinkEventKind::Conflict {
                    return (Instant::now(), e.detail.unwrap_or_default());
                }
            }
        });
        let claims = tokio::task::spawn_blocking(move || impostor_claims(&impostor, gcs, 30));
        let ((_, during), (sent, received)) =
            tokio::join!(ring_errors(server, &[1], 360.0, 3), async {
                claims.await.expect("join")
            });
        let (at, detail) = within(5, "the conflict event", flagged)
            .await
            .expect("join");
        let after = at.saturating_duration_since(first).as_secs_f64();
        let (_, vehicles) = get_json(addr, "/api/v1/vehicles").await;
        let identity = &vehicles["vehicles"][0]["link"]["identity"];
        let (_, metrics) = get(addr, "/api/v1/metrics").await;
        eprintln!(
            "authority: impostor {me}: flagged after {:.0} ms ({detail}); sent {sent} frames, \
             received {received}; UAV 1 |r - R| RMS {before:.2} m before, {during:.2} m during",
            after * 1e3
        );
        assert!(after <= 1.0, "flagged after {after} s");
        assert_eq!(received, 0, "the impostor was sent something");
        assert_eq!(
            identity["conflict"]["address"],
            format!("udp:{me}"),
            "{identity}"
        );
        assert_eq!(identity["state"], "confirmed", "{identity}");
        assert!(metric(&metrics, "harrier_mavlink_identity_conflicts_total") >= 1.0);
        assert!(
            metric(&metrics, "harrier_mavlink_impostor_frames_total") >= 1.0,
            "{metrics}"
        );
        assert!(
            metric(
                &metrics,
                "harrier_guidance_overrides_total{by=\"router_client\"}"
            ) >= 1.0
        );
        assert!(metric(&metrics, "harrier_guidance_overrides_total{by=\"api\"}") >= 1.0);
        let a = assignment(server).expect("assignment");
        assert!(on_circle(&a, &[1]), "UAV 1 left its slot: {a:?}");
        assert!(
            during <= before + 0.02 * R,
            "UAV 1's range error {before} -> {during} m"
        );

        // 5. UAV 1's battery drops below the floor (25 %): out of its slot, sent home.
        let uav1 = &demo.world().vehicles()[0];
        let from_home = || uav1.vehicle().state().horizontal_position().norm();
        uav1.vehicle().set_battery(0.24);
        let low = Instant::now();
        until(server, 10, "UAV 1 out for its battery", |a| {
            a.vehicles.iter().any(|s| {
                s.vehicle == 1
                    && s.state == SlotState::Failed
                    && s.error.as_deref().is_some_and(|e| e.contains("battery"))
            })
        })
        .await;
        within(10, "UAV 1 in RTL", async {
            while link_of(server, 1).0.as_deref() != Some("RTL") {
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
        .await;
        let (d0, t0) = (from_home(), Instant::now());
        tokio::time::sleep(Duration::from_secs(5)).await;
        let d1 = from_home();
        let (_, metrics) = get(addr, "/api/v1/metrics").await;
        eprintln!(
            "authority: UAV 1 at 24 %: out of its slot and in RTL {:.1} s after; {d0:.0} m from \
             home, {d1:.0} m {:.1} s later",
            t0.saturating_duration_since(low).as_secs_f64(),
            t0.elapsed().as_secs_f64()
        );
        assert!(d1 < d0 - 50.0, "not on its way home: {d0} -> {d1} m");
        assert!(
            metric(
                &metrics,
                "harrier_guidance_safety_total{action=\"battery_rtl\"}"
            ) >= 1.0,
            "{metrics}"
        );
        demo.stop().await;
    }));
}

/// Sends `n` HEARTBEATs (an armed PX4 quadrotor's) as system 1 from `socket` to `gcs`, 100 ms
/// apart, reading whatever comes back meanwhile: (frames sent, datagrams received).
fn impostor_claims(socket: &UdpSocket, gcs: SocketAddr, n: u8) -> (u8, usize) {
    let mut received = 0;
    let mut buf = [0u8; 2048];
    for sequence in 0..n {
        let mut frame = Vec::new();
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence,
        };
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            ..HEARTBEAT_DATA::DEFAULT
        });
        harrier_sim::mavlink::write_v2_msg(&mut frame, header, &hb).expect("frame");
        socket.send_to(&frame, gcs).expect("send");
        let until = Instant::now() + Duration::from_millis(100);
        while Instant::now() < until {
            if socket.recv(&mut buf).is_ok() {
                received += 1;
            }
        }
    }
    (n, received)
}
