//! MAVLink TIMESYNC: each vehicle's clock as its autopilot tells it.
//!
//! Once a second the GCS link sends every vehicle a request (`tc1 = 0`, `ts1` = the server's
//! UNIX time in ns); PX4 and ArduPilot answer with `tc1` = their own clock (ns) and `ts1`
//! mirrored. One exchange gives the offset `tc1 − (ts1 + t_back)/2` to within half its round trip
//! `t_back − ts1`; the estimate is the exchange with the shortest round trip of the last
//! [`EXCHANGES`] (the one the transport delayed least). Only answers to the link's own recent
//! requests count. PX4's and ArduPilot's clocks read time since boot, so their offset is large and
//! says nothing of the companion computer's `time_unix`; harrier-sim's reads UNIX time, wrong by
//! `--clock-offset-s`.

use std::collections::VecDeque;

use harrier_link::mavlink::dialects::common::{MavMessage, TIMESYNC_DATA};
use serde::Serialize;
use utoipa::ToSchema;

/// Exchanges kept per vehicle.
pub const EXCHANGES: usize = 16;
/// Requests remembered (answers to older ones are ignored).
const REQUESTS: usize = 8;

/// A vehicle's clock from TIMESYNC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
pub struct TimesyncView {
    /// The vehicle's clock minus the server's (s).
    pub offset_s: f64,
    /// Bound on the error of `offset_s` (s): half the round trip of the exchange it rests on.
    pub uncertainty_s: f64,
    /// Shortest round trip of the exchanges kept (s).
    pub rtt_s: f64,
    /// Answers received.
    pub answers: u64,
}

/// One vehicle's TIMESYNC exchanges.
#[derive(Debug, Clone, Default)]
pub struct Timesync {
    exchanges: VecDeque<(f64, f64)>,
    answers: u64,
}

impl Timesync {
    /// Takes an answer: the vehicle's clock `tc1` (ns) to the request sent at `ts1` (ns), back
    /// at `now` (ns; server clock).
    pub fn answer(&mut self, tc1: i64, ts1: i64, now: i64) {
        let rtt = (i128::from(now) - i128::from(ts1)) as f64 * 1e-9;
        if !(0.0..10.0).contains(&rtt) {
            return;
        }
        let mid = (i128::from(ts1) + i128::from(now)) / 2;
        let offset = (i128::from(tc1) - mid) as f64 * 1e-9;
        if self.exchanges.len() == EXCHANGES {
            self.exchanges.pop_front();
        }
        self.exchanges.push_back((rtt, offset));
        self.answers += 1;
    }

    /// The estimate, once an answer came.
    pub fn view(&self) -> Option<TimesyncView> {
        let (rtt, offset) = self
            .exchanges
            .iter()
            .copied()
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some(TimesyncView {
            offset_s: offset,
            uncertainty_s: rtt / 2.0,
            rtt_s: rtt,
            answers: self.answers,
        })
    }
}

/// The link's recent requests, so that only answers to them count.
#[derive(Debug, Default)]
pub struct Requests(VecDeque<i64>);

impl Requests {
    /// A request stamped `now` (ns), remembered.
    pub fn request(&mut self, now: i64) -> MavMessage {
        if self.0.len() == REQUESTS {
            self.0.pop_front();
        }
        self.0.push_back(now);
        MavMessage::TIMESYNC(TIMESYNC_DATA { tc1: 0, ts1: now })
    }

    /// Whether `ts1` is one of the remembered requests.
    pub fn sent(&self, ts1: i64) -> bool {
        self.0.contains(&ts1)
    }
}

/// The server's clock in ns, for TIMESYNC.
pub fn now_ns(unix_s: f64) -> i64 {
    (unix_s * 1e9) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shortest_round_trip_gives_the_offset() {
        let mut t = Timesync::default();
        let s = 1_800_000_000_000_000_000_i64;
        // The vehicle is 1.5 s ahead; 20 ms each way, then 2 ms each way, then 100 ms out and
        // 1 ms back (the asymmetric one has the longer round trip and loses).
        t.answer(s + 1_500_000_000 + 20_000_000, s, s + 40_000_000);
        t.answer(s + 1_500_000_000 + 2_000_000, s, s + 4_000_000);
        t.answer(s + 1_500_000_000 + 100_000_000, s, s + 101_000_000);
        let v = t.view().expect("an estimate");
        assert!((v.offset_s - 1.5).abs() < 1e-6, "{v:?}");
        assert!((v.rtt_s - 0.004).abs() < 1e-9);
        assert!((v.uncertainty_s - 0.002).abs() < 1e-9);
        assert_eq!(v.answers, 3);
    }

    #[test]
    fn only_answers_to_recent_requests_count_and_absurd_ones_are_ignored() {
        let mut r = Requests::default();
        for k in 0..10 {
            r.request(k);
        }
        assert!(!r.sent(1) && r.sent(2) && r.sent(9));
        let mut t = Timesync::default();
        t.answer(5, 100, 50); // back before it left
        t.answer(5, 0, 20_000_000_000); // 20 s round trip
        assert!(t.view().is_none());
    }
}
