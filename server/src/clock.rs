//! The server's clock, and what it knows of every source's clock.
//!
//! The live service reads the time of day through [`unix_now`] (harrier-link's, which the
//! simulator and the recording share). Scans carry the instant of their detections as `time_unix`, on the sending computer's clock; one wrong clock
//! must not move the tracker's time for everyone. So, when sources run on real time
//! ([`ClockConfig::real_time`]):
//!
//! * **The bound**: a scan whose `time_unix` is more than [`ClockConfig::max_ahead_s`] ahead of
//!   the server's clock at its arrival, or more than [`ClockConfig::max_behind_s`] behind it, is
//!   refused (drop reason `clock`). The tracker's time is that of the newest scan it processed,
//!   so it never runs ahead of the server's clock by more than `max_ahead_s`.
//! * **The estimate**: [`SourceClock`] estimates each source's offset from the server's clock
//!   and its drift, from the scans' arrival times. Every scan gives `y = time_unix − arrival =
//!   offset − delay`, and the transport delay is never below its floor, so the upper envelope of
//!   `y` (plus the floor) is the offset: the largest `y` in each of [`BUCKETS`] slices of the last
//!   [`ClockConfig::window_s`], and a least-squares line through them (offset now, drift); O(1)
//!   per scan, whatever the scan rate. A
//!   sample that lies more than [`JUMP_S`] off the line is a suspect; [`JUMP_CONFIRM`] suspects
//!   in a row that agree are a clock jump, and the estimate restarts from them.
//! * **The correction** ([`ClockConfig::correct`]): a scan's time becomes `time_unix − offset`,
//!   so a source whose clock is a second ahead no longer makes everyone else's scans late. A
//!   suspect sample is placed at its arrival time instead.

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

pub use harrier_link::clock::unix_now;

/// `[clock]`: how far the sources' clocks are trusted.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClockConfig {
    /// The sources stamp their scans with real UNIX time (`time_unix`): bound it and estimate
    /// each source's clock. `false` for simulators that run faster than real time (harrier-sim
    /// `--speedup` ≠ 1, whose `time_unix` is its start plus simulated seconds): times are then
    /// taken as sent.
    pub real_time: bool,
    /// Most a scan's `time_unix` may be ahead of the server's clock at its arrival (s). Default
    /// 2 s: NTP- or GPS-disciplined clocks agree within milliseconds, so this only refuses
    /// clocks that are wrong, while leaving room for a source a second off (which the
    /// correction then places right).
    pub max_ahead_s: f64,
    /// Most a scan's `time_unix` may be behind the server's clock at its arrival (s). Default
    /// 60 s: a scan that old is history, not a live detection, and a lone source that old
    /// would take the tracker's time back by as much; a link that buffers for under a minute
    /// still delivers.
    pub max_behind_s: f64,
    /// Correct every source's scan times by its estimated clock offset.
    pub correct: bool,
    /// The transport delay's floor (s): the least time from a detection to its arrival here
    /// (the offset estimate is the envelope of `time_unix − arrival` plus this).
    pub delay_floor_s: f64,
    /// The estimate looks at this much of the past (s of arrival time).
    pub window_s: f64,
}

impl Default for ClockConfig {
    fn default() -> Self {
        Self {
            real_time: true,
            max_ahead_s: 2.0,
            max_behind_s: 60.0,
            correct: true,
            delay_floor_s: 0.0,
            window_s: 60.0,
        }
    }
}

impl ClockConfig {
    /// Why these settings cannot work, if they cannot.
    pub fn problem(&self) -> Option<String> {
        let positive = [
            ("max_ahead_s", self.max_ahead_s),
            ("max_behind_s", self.max_behind_s),
            ("window_s", self.window_s),
        ];
        if let Some((name, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Some(format!(
                "clock.{name} must be a positive number of seconds, got {v}"
            ));
        }
        if !(self.delay_floor_s.is_finite() && self.delay_floor_s >= 0.0) {
            return Some(format!(
                "clock.delay_floor_s must be ≥ 0 s, got {}",
                self.delay_floor_s
            ));
        }
        None
    }

    /// Why a scan stamped `time_unix` that arrived at `arrival` (both UNIX s) is refused, if
    /// it is: outside the bound (always `None` when the sources do not run on real time).
    pub fn refusal(&self, time_unix: f64, arrival: f64) -> Option<String> {
        if !self.real_time {
            return None;
        }
        let ahead = time_unix - arrival;
        if ahead > self.max_ahead_s {
            Some(format!(
                "time_unix is {ahead:.3} s ahead of the server's clock (clock.max_ahead_s = {} s)",
                self.max_ahead_s
            ))
        } else if -ahead > self.max_behind_s {
            Some(format!(
                "time_unix is {:.3} s behind the server's clock (clock.max_behind_s = {} s)",
                -ahead, self.max_behind_s
            ))
        } else {
            None
        }
    }
}

/// Slices of the window, each giving its largest `time_unix − arrival` to the fit.
pub const BUCKETS: usize = 8;
/// A sample this far (s) off the estimate is a suspect.
pub const JUMP_S: f64 = 1.0;
/// Suspects in a row, agreeing within [`JUMP_S`], that make a clock jump.
pub const JUMP_CONFIRM: usize = 3;
/// The uncertainty is never reported below this (s): the resolution the arrival times have.
const SIGMA_FLOOR_S: f64 = 1e-4;

/// One source's clock, as estimated: its offset from the server's clock and its drift.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
pub struct ClockEstimate {
    /// Source clock minus server clock (s), now: positive when the source is ahead.
    pub offset_s: f64,
    /// Standard uncertainty of `offset_s` (s).
    pub sigma_s: f64,
    /// How fast the offset grows (parts per million: µs per s).
    pub drift_ppm: f64,
    /// Samples (scans) the estimate rests on.
    pub samples: usize,
    /// Clock jumps seen (the estimate restarted).
    pub jumps: u64,
}

#[derive(Debug, Clone, Copy)]
struct Sample {
    arrival: f64,
    y: f64,
}

/// One slice of arrival time: its sample of largest `y`, its smallest `y`, how many.
#[derive(Debug, Clone, Copy)]
struct Slice {
    index: i64,
    top: Sample,
    low: f64,
    n: usize,
}

/// The fitted envelope: `y(arrival) = offset + drift · (arrival − at)`.
#[derive(Debug, Clone, Copy)]
struct Line {
    at: f64,
    offset: f64,
    drift: f64,
    sigma: f64,
}

impl Line {
    fn at(&self, arrival: f64) -> f64 {
        self.offset + self.drift * (arrival - self.at)
    }
}

/// The clock estimate of one source. Each scan costs O([`BUCKETS`]): the samples are kept only
/// as the extremes of the slices of the window they fall in.
#[derive(Debug, Clone)]
pub struct SourceClock {
    window_s: f64,
    delay_floor_s: f64,
    slices: VecDeque<Slice>,
    last_arrival: f64,
    suspects: Vec<Sample>,
    line: Option<Line>,
    jumps: u64,
}

/// What one scan's time told the estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observed {
    /// The source's offset (s) at this scan, as the estimate now has it; for a suspect, the
    /// scan's own `time_unix − arrival` plus the delay floor.
    pub offset_s: f64,
    /// The scan lies off the estimate (a clock jump not yet confirmed, or a long delay).
    pub suspect: bool,
}

impl SourceClock {
    /// An empty estimate with the settings of `config`.
    pub fn new(config: &ClockConfig) -> Self {
        Self {
            window_s: config.window_s,
            delay_floor_s: config.delay_floor_s,
            slices: VecDeque::with_capacity(BUCKETS + 1),
            last_arrival: f64::NEG_INFINITY,
            suspects: Vec::new(),
            line: None,
            jumps: 0,
        }
    }

    /// Takes a scan stamped `time_unix` that arrived at `arrival` (UNIX s on the server's clock).
    pub fn observe(&mut self, time_unix: f64, arrival: f64) -> Observed {
        let s = Sample {
            arrival,
            y: time_unix - arrival,
        };
        if !(s.y.is_finite() && arrival.is_finite()) {
            return Observed {
                offset_s: 0.0,
                suspect: true,
            };
        }
        // A source silent for longer than the window starts afresh.
        let fresh = arrival - self.last_arrival <= self.window_s;
        if let Some(line) = self.line.filter(|_| fresh)
            && (s.y - line.at(arrival)).abs() > JUMP_S
        {
            // Suspects must agree with each other too; a new one that does not starts over.
            if self
                .suspects
                .first()
                .is_some_and(|f| (f.y - s.y).abs() > JUMP_S)
            {
                self.suspects.clear();
            }
            self.suspects.push(s);
            if self.suspects.len() < JUMP_CONFIRM {
                return Observed {
                    offset_s: s.y + self.delay_floor_s,
                    suspect: true,
                };
            }
            self.jumps += 1;
            self.slices.clear();
            for s in std::mem::take(&mut self.suspects) {
                self.add(s);
            }
        } else {
            if !fresh {
                self.slices.clear();
            }
            self.suspects.clear();
            self.add(s);
        }
        self.line = fit(&self.slices, self.last_arrival, self.window_s);
        Observed {
            offset_s: self.line.map_or(s.y, |l| l.at(arrival)) + self.delay_floor_s,
            suspect: false,
        }
    }

    /// Adds a sample to its slice, and forgets the slices that left the window.
    fn add(&mut self, s: Sample) {
        let width = self.window_s / BUCKETS as f64;
        let index = (s.arrival / width).floor() as i64;
        self.last_arrival = self.last_arrival.max(s.arrival);
        match self.slices.back_mut() {
            Some(b) if b.index == index => {
                if s.y > b.top.y {
                    b.top = s;
                }
                b.low = b.low.min(s.y);
                b.n += 1;
            }
            _ => self.slices.push_back(Slice {
                index,
                top: s,
                low: s.y,
                n: 1,
            }),
        }
        while self
            .slices
            .front()
            .is_some_and(|f| f.index <= index - BUCKETS as i64)
        {
            self.slices.pop_front();
        }
    }

    /// The estimate at `now` (UNIX s), once there is one.
    pub fn estimate(&self, now: f64) -> Option<ClockEstimate> {
        let line = self.line?;
        Some(ClockEstimate {
            offset_s: line.at(now) + self.delay_floor_s,
            sigma_s: line.sigma,
            drift_ppm: line.drift * 1e6,
            samples: self.slices.iter().map(|b| b.n).sum(),
            jumps: self.jumps,
        })
    }
}

/// The upper envelope of the slices: the least-squares line through their largest `y` when
/// they span at least a quarter of the window (else a constant, their largest `y`).
fn fit(slices: &VecDeque<Slice>, last: f64, window_s: f64) -> Option<Line> {
    let first = slices.front()?.top.arrival;
    let tops: Vec<Sample> = slices.iter().map(|b| b.top).collect();
    let n = tops.len() as f64;
    if tops.len() >= 3 && last - first >= window_s / 4.0 {
        let (ma, my) = (
            tops.iter().map(|s| s.arrival - last).sum::<f64>() / n,
            tops.iter().map(|s| s.y).sum::<f64>() / n,
        );
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for s in &tops {
            let dx = s.arrival - last - ma;
            sxx += dx * dx;
            sxy += dx * (s.y - my);
        }
        let drift = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        let line = Line {
            at: last,
            offset: my - drift * ma,
            drift,
            sigma: 0.0,
        };
        let ss: f64 = tops
            .iter()
            .map(|s| (s.y - line.at(s.arrival)).powi(2))
            .sum();
        let sigma = (ss / (n - 2.0).max(1.0) / n).sqrt();
        Some(Line {
            sigma: sigma.max(SIGMA_FLOOR_S),
            ..line
        })
    } else {
        let top = tops.iter().map(|s| s.y).fold(f64::NEG_INFINITY, f64::max);
        let low = slices.iter().map(|b| b.low).fold(f64::INFINITY, f64::min);
        Some(Line {
            at: last,
            offset: top,
            drift: 0.0,
            sigma: ((top - low) / 2.0).max(SIGMA_FLOOR_S),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng as _, SeedableRng as _};

    /// A source `offset` s ahead drifting `drift` s/s, scans every `period` s for `duration` s,
    /// each delayed by 1 ms plus an exponential delay of mean `mean_delay`.
    fn run(offset: f64, drift: f64, mean_delay: f64, duration: f64) -> SourceClock {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut c = SourceClock::new(&ClockConfig::default());
        let t0 = 1.8e9;
        let mut t = 0.0;
        while t < duration {
            let delay = 1e-3 - mean_delay * (1.0 - rng.random::<f64>()).ln();
            let time_unix = t0 + t + offset + drift * t;
            let o = c.observe(time_unix, t0 + t + delay);
            assert!(!o.suspect, "t = {t}: {o:?}");
            t += 0.1;
        }
        c
    }

    #[test]
    fn the_offset_of_a_clock_ahead_or_behind_is_found_within_milliseconds() {
        for (offset, drift) in [(1.0, 0.0), (-0.3, 0.0), (0.0, 0.0), (2.5, 50e-6)] {
            let c = run(offset, drift, 0.02, 40.0);
            let now = 1.8e9 + 40.0;
            let e = c.estimate(now).expect("estimate");
            let truth = offset + drift * 40.0;
            // The envelope sits 1 ms (the delay floor not configured) below the offset.
            assert!(
                (e.offset_s - truth).abs() < 5e-3,
                "offset {offset}, drift {drift}: {e:?}"
            );
            assert!(e.sigma_s < 0.01, "{e:?}");
            assert!((e.drift_ppm - drift * 1e6).abs() < 200.0, "{e:?}");
        }
    }

    #[test]
    fn a_clock_jump_is_suspected_then_followed() {
        let mut c = run(0.0, 0.0, 0.005, 20.0);
        let t0 = 1.8e9 + 20.0;
        let mut seen = Vec::new();
        for k in 0..5 {
            let t = t0 + f64::from(k) * 0.1;
            seen.push(c.observe(t + 3600.0, t + 0.002));
        }
        assert!(seen[0].suspect && seen[1].suspect);
        // The suspects are placed at their arrival (offset = their own y), not 1 h ahead.
        assert!((seen[0].offset_s - 3599.998).abs() < 1e-6);
        assert!(!seen[2].suspect && !seen[4].suspect, "{seen:?}");
        let e = c.estimate(t0 + 0.5).expect("estimate");
        assert!((e.offset_s - 3600.0).abs() < 0.01, "{e:?}");
        assert_eq!(e.jumps, 1);
    }

    #[test]
    fn one_long_delay_is_a_suspect_and_changes_nothing() {
        let mut c = run(0.0, 0.0, 0.005, 20.0);
        let before = c.estimate(1.8e9 + 20.0).expect("estimate");
        let t = 1.8e9 + 20.0;
        let o = c.observe(t, t + 1.5);
        assert!(o.suspect);
        let o = c.observe(t + 0.1, t + 0.102);
        assert!(!o.suspect);
        let after = c.estimate(t + 0.1).expect("estimate");
        assert!((after.offset_s - before.offset_s).abs() < 2e-3);
        assert_eq!(after.jumps, 0);
    }

    #[test]
    fn the_bound_refuses_far_ahead_and_far_behind_only() {
        let c = ClockConfig::default();
        let now = 1.8e9;
        assert!(c.refusal(now + 1e7, now).is_some());
        assert!(c.refusal(now + 1.9, now).is_none());
        assert!(c.refusal(now - 59.0, now).is_none());
        assert!(c.refusal(now - 61.0, now).is_some());
        let sim = ClockConfig {
            real_time: false,
            ..c
        };
        assert!(sim.refusal(now + 1e7, now).is_none());
        assert!(ClockConfig::default().problem().is_none());
        let bad = ClockConfig {
            max_ahead_s: f64::NAN,
            ..ClockConfig::default()
        };
        assert!(bad.problem().is_some_and(|p| p.contains("max_ahead_s")));
    }

    #[test]
    fn non_finite_times_are_suspects_not_samples() {
        let mut c = SourceClock::new(&ClockConfig::default());
        assert!(c.observe(f64::NAN, 1.0).suspect);
        assert!(c.estimate(1.0).is_none());
    }
}
