//! One tick of a vehicle on its links: what each link received goes to the vehicle (TIMESYNC
//! requests are answered here, with the vehicle's clock), the replies to the peer each request
//! came from, and the telemetry to every peer.

use mavlink::dialects::common::{MavMessage, MavType, TIMESYNC_DATA};

use super::link::Link;
use crate::vehicle::{ClockSkew, Incoming, Vehicle};

/// The answer to a time-sync request (TIMESYNC with tc1 = 0): this vehicle's clock in ns, `now`
/// s after its start, as PX4 and ArduPilot answer it (theirs reads time since boot; this one
/// reads UNIX time, wrong by `clock`). `None` for every other message.
fn timesync_reply(clock: &ClockSkew, m: &MavMessage, now: f64) -> Option<MavMessage> {
    let MavMessage::TIMESYNC(t) = m else {
        return None;
    };
    if t.tc1 != 0 {
        return None;
    }
    let reading = harrier_link::clock::unix_now() + clock.offset_s + clock.drift_ppm * 1e-6 * now;
    Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: (reading * 1e9) as i64,
        ts1: t.ts1,
    }))
}

/// One tick of `v` at `now`; returns the ground station HEARTBEATs it received (a vehicle
/// that hears none would, on PX4, soon declare its data link lost).
pub(super) fn run_once(v: &mut Vehicle, links: &mut [Link], buf: &mut [u8], now: f64) -> u64 {
    let sysid = v.id();
    let mut gcs_heartbeats = 0;
    for link in links.iter_mut() {
        for r in link.poll(buf) {
            for _ in 0..r.malformed {
                v.count_malformed();
            }
            for &reason in &r.rejected {
                v.count_rejected(reason);
            }
            for f in &r.frames {
                let m = &f.message;
                if matches!(m, MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS) {
                    gcs_heartbeats += 1;
                }
                if let Some(reply) = timesync_reply(&v.config().clock, m, now) {
                    link.send(sysid, &reply.into(), r.from);
                    continue;
                }
                for reply in v.handle_frame(now, Incoming::of(f)) {
                    link.send(sysid, &reply, r.from);
                }
            }
        }
    }
    for m in v.telemetry_frames(now) {
        for link in links.iter_mut() {
            link.broadcast(sysid, &m);
        }
    }
    gcs_heartbeats
}
