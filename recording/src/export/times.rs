//! The time axis of an export: the time line ([`TimeLine`]: `time_unix` or the senders' `t`),
//! the multi-target scan grid ([`Grid`]) and the scenario's scan times ([`ScanTimes`]).

use std::collections::BTreeMap;

use harrier_core::detection::DetectionScan;

use harrier_core::measurement::MeasKind;
use harrier_core::scenario as fmt;

/// Tolerance of "the same time" and of the multi-target scan grid (s), as the formats say.
pub(super) const TIME_TOL_S: f64 = 1e-6;

/// One (vehicle, sensor) of a session as a scenario sensor.
#[derive(Debug)]
pub(super) struct SensorEntry {
    pub(super) kind: MeasKind,
    pub(super) noise_std: Vec<f64>,
    /// Scan times (relative).
    pub(super) times: Vec<f64>,
}

/// One measurement line before sorting.
#[derive(Debug)]
pub(super) struct Line {
    pub(super) t: f64,
    pub(super) sensor: (u8, String),
    pub(super) m: fmt::Measurement,
}

/// The scan grid `origin + k·dt` of a multi-target export (FORMAT-MULTI.md puts every scan on
/// one), fitted to scan times that a live source stamps with some jitter.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    /// Scan period (s).
    dt: f64,
    /// Time of grid point 0 (s, on the export's time line before the shift).
    origin: f64,
    /// Largest distance of a scan from its grid point (s).
    max_shift: f64,
}

impl Grid {
    /// Fits the grid: `dt` first from the shortest median period of any sensor, then each
    /// distinct scan time gets its grid index from its gap to the previous one (so no error
    /// accumulates), and `origin` and `dt` are the least-squares line through (index, time).
    /// Refused when a scan is more than a quarter period off its point. With fewer than two
    /// scans of any sensor the grid is `fallback` from the first scan.
    fn fit(sensors: &BTreeMap<(u8, String), SensorEntry>, fallback: f64) -> Result<Self, String> {
        let median_period = |times: &[f64]| {
            let mut gaps: Vec<f64> = times
                .windows(2)
                .map(|w| w[1] - w[0])
                .filter(|g| *g > TIME_TOL_S)
                .collect();
            gaps.sort_by(f64::total_cmp);
            gaps.get(gaps.len() / 2).copied()
        };
        let mut times: Vec<f64> = sensors.values().flat_map(|e| e.times.clone()).collect();
        times.sort_by(f64::total_cmp);
        let first = times.first().copied().unwrap_or(0.0);
        let Some(dt0) = sensors
            .values()
            .filter_map(|e| median_period(&e.times))
            .min_by(f64::total_cmp)
        else {
            return Ok(Self {
                dt: fallback,
                origin: first,
                max_shift: 0.0,
            });
        };
        let mut k = 0.0;
        let mut points = vec![(0.0, first)];
        for w in times.windows(2) {
            k += ((w[1] - w[0]) / dt0).round();
            points.push((k, w[1]));
        }
        let n = points.len() as f64;
        let (sk, st) = points
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
        let (mk, mt) = (sk / n, st / n);
        let (skk, skt) = points.iter().fold((0.0, 0.0), |a, p| {
            (a.0 + (p.0 - mk) * (p.0 - mk), a.1 + (p.0 - mk) * (p.1 - mt))
        });
        let dt = if skk > 0.0 { skt / skk } else { dt0 };
        let origin = mt - dt * mk;
        let max_shift = points
            .iter()
            .map(|p| (p.1 - origin - p.0 * dt).abs())
            .fold(0.0, f64::max);
        if !(dt > 0.0 && max_shift <= dt / 4.0) {
            return Err(format!(
                "the scan times fit no grid t0 + k·dt (FORMAT-MULTI.md): with dt = {dt} s a scan \
                 is {max_shift:.3} s off its grid point"
            ));
        }
        if k > 1e7 {
            return Err(format!("{k} scans of {dt} s are too many"));
        }
        Ok(Self {
            dt,
            origin,
            max_shift,
        })
    }

    /// The grid index of time `t`.
    fn index(&self, t: f64) -> i64 {
        ((t - self.origin) / self.dt).round() as i64
    }
}

/// The time line of an export: UNIX time when every scan of the session carries it (what the
/// tracker used), else the senders' `t`; relative to `epoch`, the first scan.
#[derive(Debug, Clone, Copy)]
pub(super) struct TimeLine {
    unix: bool,
    pub(super) epoch: f64,
}

impl TimeLine {
    pub(super) fn new(scans: &[(i64, DetectionScan)]) -> Self {
        let unix = scans.iter().all(|s| s.1.time_unix.is_some());
        let mut line = Self { unix, epoch: 0.0 };
        line.epoch = scans
            .iter()
            .filter_map(|s| line.absolute(s.1.t, s.1.time_unix))
            .fold(f64::INFINITY, f64::min);
        line
    }
    /// A message's time on this line (`None`: it lacks `time_unix`).
    pub(super) fn absolute(self, t: f64, time_unix: Option<f64>) -> Option<f64> {
        if self.unix { time_unix } else { Some(t) }
    }
    /// A message's time relative to the epoch.
    pub(super) fn relative(self, t: f64, time_unix: Option<f64>) -> Option<f64> {
        Some(self.absolute(t, time_unix)? - self.epoch)
    }
    pub(super) fn name(self) -> &'static str {
        if self.unix { "time_unix" } else { "t" }
    }
}

/// The time axis of an export.
#[derive(Debug)]
pub(super) struct ScanTimes {
    /// The scenario's scan times (relative, distinct, in order).
    pub(super) times: Vec<f64>,
    /// Its time step (s).
    pub(super) dt: f64,
    /// Largest shift of a scan's time onto the grid (s; 0 when the times are as recorded).
    pub(super) max_shift: f64,
}

impl ScanTimes {
    /// A single-target export's: the scan times as recorded, the configured period as its step.
    pub(super) fn as_recorded(mut times: Vec<f64>, scan_period: f64) -> Self {
        times.sort_by(f64::total_cmp);
        times.dedup_by(|a, b| (*a - *b).abs() <= TIME_TOL_S);
        Self {
            times,
            dt: scan_period,
            max_shift: 0.0,
        }
    }

    /// A multi-target export's: the scan grid fitted to the scan times of `sensors`, each of
    /// `lines` moved onto it, and time 0 being grid point 0 (`line`'s epoch moves there).
    /// Refused when a sensor scans twice at one grid time.
    pub(super) fn on_grid(
        sensors: &BTreeMap<(u8, String), SensorEntry>,
        lines: &mut [Line],
        scan_period: f64,
        line: &mut TimeLine,
    ) -> Result<Self, String> {
        let g = Grid::fit(sensors, scan_period)?;
        line.epoch += g.origin;
        for ((v, s), e) in sensors {
            let k: Vec<i64> = e.times.iter().map(|t| g.index(*t)).collect();
            if let Some(w) = k.windows(2).find(|w| w[0] == w[1]) {
                return Err(format!(
                    "sensor {s} of vehicle {v} scans twice at grid time {} s (dt {} s)",
                    w[0] as f64 * g.dt,
                    g.dt
                ));
            }
        }
        for l in lines.iter_mut() {
            l.m.t = g.index(l.t) as f64 * g.dt;
        }
        let last = sensors
            .values()
            .flat_map(|e| &e.times)
            .map(|t| g.index(*t))
            .max()
            .unwrap_or(0);
        Ok(Self {
            times: (0..=last).map(|k| k as f64 * g.dt).collect(),
            dt: g.dt,
            max_shift: g.max_shift,
        })
    }

    /// The last scan time.
    pub(super) fn t_end(&self) -> f64 {
        self.times.last().copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::session::micros;
    use harrier_core::measurement::MeasKind;

    #[test]
    fn the_scan_grid() {
        let sensors = |series: &[Vec<f64>]| -> BTreeMap<(u8, String), SensorEntry> {
            (1..)
                .zip(series)
                .map(|(v, times)| {
                    let e = SensorEntry {
                        kind: MeasKind::Position,
                        noise_std: vec![1.0, 1.0],
                        times: times.clone(),
                    };
                    ((v, "cam".to_owned()), e)
                })
                .collect()
        };
        // On a grid to the µs.
        let exact: Vec<f64> = (0..50).map(|k| micros(f64::from(k) * 0.2 + 3e-7)).collect();
        let g = Grid::fit(&sensors(&[exact.clone(), exact]), 1.0).expect("grid");
        assert!((g.dt - 0.2).abs() < 1e-9 && g.max_shift < 1e-6, "{g:?}");
        // Stamped up to 30 ms late, two sources 10 ms apart, 400 scans: no drift.
        let late =
            |k: u32, j: f64| f64::from(k) * 0.5 + 0.03 * (f64::from(k) * 1.7).sin().abs() + j;
        let a: Vec<f64> = (0..400).map(|k| late(k, 0.0)).collect();
        let b: Vec<f64> = (0..400)
            .filter(|k| k % 3 != 0)
            .map(|k| late(k, 0.01))
            .collect();
        let g = Grid::fit(&sensors(&[a.clone(), b]), 1.0).expect("grid");
        assert!((g.dt - 0.5).abs() < 1e-4 && g.max_shift < 0.03, "{g:?}");
        assert!(a.iter().zip(0..).all(|(t, k)| g.index(*t) == k), "{g:?}");
        // One scan each: the fallback period.
        let g = Grid::fit(&sensors(&[vec![3.0], vec![3.1]]), 0.5).expect("one scan");
        assert_eq!((g.dt, g.origin), (0.5, 3.0));
        let e = Grid::fit(&sensors(&[vec![0.0, 0.5, 1.2, 1.5, 2.0]]), 1.0).expect_err("irregular");
        assert!(e.contains("fit no grid"), "{e}");
    }
}
