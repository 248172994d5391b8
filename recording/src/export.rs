//! A recorded session exported as a `gcs-scenario/1` directory ([`export`]) that `harrier
//! replay` runs and `score.py` scores.
//!
//! An export puts the session's scans into the session's ENU frame (harrier-link's
//! `scan_in_frame`) and its times relative to the first scan, on the time line the tracker used
//! (`time_unix` when every scan carries it, else the senders' `t`). It is single-target
//! (FORMAT.md) unless the truth has several targets or a scan holds several detections (clutter
//! or several targets), then FORMAT-MULTI.md — as harrier-sim's `record` decides.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use harrier_core::detection::{DetectionScan, GeoPoint, TruthSample};
use harrier_core::measurement::MeasKind;
use harrier_core::measurement::{
    Geometry, Locate, MeasurementModel, PositionFix, SensorModel, WithSensor,
};
use harrier_core::scenario as fmt;
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;
use harrier_link::scenario_out;
use nalgebra::{SVector, Vector3};
use serde_json::json;

use super::reader::{Db, SessionError, SessionInfo};

/// Velocity standard deviation of an export's prior (m/s): a ground target of unknown speed.
const PRIOR_VEL_STD_MPS: f64 = 15.0;
/// An export's prior inflates the first detection's position-fix covariance by this factor (the
/// estimator updates with that detection again).
const PRIOR_POS_INFLATION: f64 = 4.0;
/// Truth samples further apart than this (s) are not interpolated between (the target was not
/// seen, or truth was lost).
const MAX_TRUTH_GAP_S: f64 = 2.0;
/// Tolerance of "the same time" and of the multi-target scan grid (s), as the formats say.
const TIME_TOL_S: f64 = 1e-6;

/// A session exported as a `gcs-scenario/1` directory, in memory.
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct Exported {
    /// Session id.
    pub session: i64,
    /// `scenario.json`.
    pub scenario_json: String,
    /// `measurements.jsonl`.
    pub measurements_jsonl: String,
    /// `truth.csv`, when the session recorded truth.
    pub truth_csv: Option<String>,
    /// Whether it is the multi-target format (FORMAT-MULTI.md).
    pub multi: bool,
    /// Scenario time 0 on the session's time line (UNIX s, or the senders' `t`).
    pub epoch: f64,
    /// The time line: `time_unix` (every scan carried it) or `t`.
    pub time_line: String,
    /// Largest shift of a scan's time onto the multi-target scan grid (s; 0 for single target).
    pub max_time_shift_s: f64,
    /// Scans read.
    pub scans: u64,
    /// Measurement lines written (one per detection).
    pub lines: u64,
    /// Truth rows written.
    pub truth_rows: u64,
    /// Scenario sensor ids (`cam1`: sensor `cam` of vehicle 1).
    pub sensors: Vec<String>,
}

/// The scans of session `id` in `frame`, one measurement line per detection (time on `line`,
/// no sensor id yet), and each (vehicle, sensor)'s kind, noise and scan times.
fn framed(
    d: &Db<'_>,
    id: i64,
    scans: &[(i64, DetectionScan)],
    line: TimeLine,
    frame: &LocalFrame,
    geometry: Geometry,
) -> Result<Framed, SessionError> {
    let mut sensors: BTreeMap<(u8, String), SensorEntry> = BTreeMap::new();
    let mut lines = Vec::new();
    let mut several = false;
    let mut times = Vec::with_capacity(scans.len());
    for (row, scan) in scans {
        let t = micros(line.relative(scan.t, scan.time_unix).unwrap_or(scan.t));
        times.push(t);
        let local = scan_in_frame(scan, frame, geometry)
            .map_err(|e| d.malformed(id, format!("scans row {row}: {e}")))?;
        let key = (scan.vehicle, scan.sensor.clone());
        let entry = sensors.entry(key.clone()).or_insert_with(|| SensorEntry {
            kind: scan.kind,
            noise_std: scan.noise_std.clone(),
            times: Vec::new(),
        });
        if entry.kind != scan.kind || entry.noise_std.len() != scan.noise_std.len() {
            return Err(d.export_error(
                id,
                format!(
                    "sensor {} of vehicle {} changes from {:?} ({} components) to {:?} ({}) \
                     at seq {}",
                    scan.sensor,
                    scan.vehicle,
                    entry.kind,
                    entry.noise_std.len(),
                    scan.kind,
                    scan.noise_std.len(),
                    scan.seq
                ),
            ));
        }
        entry.times.push(t);
        several |= local.detections.len() > 1;
        for z in local.detections.iter() {
            lines.push(Line {
                t,
                sensor: key.clone(),
                m: scenario_out::measurement(&local, t, "", z.clone()),
            });
        }
    }
    Ok(Framed {
        sensors,
        lines,
        times,
        several,
    })
}

/// One (vehicle, sensor) of a session as a scenario sensor.
#[derive(Debug)]
struct SensorEntry {
    kind: MeasKind,
    noise_std: Vec<f64>,
    /// Scan times (relative).
    times: Vec<f64>,
}

/// A session's scans in its frame ([`framed`]).
#[derive(Debug)]
struct Framed {
    /// Each (vehicle, sensor).
    sensors: BTreeMap<(u8, String), SensorEntry>,
    /// A line per detection, in scan order.
    lines: Vec<Line>,
    /// Each scan's relative time, in scan order.
    times: Vec<f64>,
    /// Whether a scan holds several detections.
    several: bool,
}

/// One measurement line before sorting.
#[derive(Debug)]
struct Line {
    t: f64,
    sensor: (u8, String),
    m: fmt::Measurement,
}

/// Rounds a relative time to the microsecond (the formats' tolerance).
fn micros(t: f64) -> f64 {
    (t * 1e6).round() / 1e6
}

/// Calls `locate` on the concrete model of a run-time sensor.
struct LocateWith<'a>(&'a [f64]);

impl WithSensor<4> for LocateWith<'_> {
    type Output = Option<PositionFix>;
    fn with<H, const M: usize>(self, model: &H) -> Option<PositionFix>
    where
        H: MeasurementModel<4, M> + Locate<M>,
    {
        (self.0.len() == M)
            .then(|| model.locate(&SVector::<f64, M>::from_column_slice(self.0)))
            .flatten()
    }
}

/// The settings of the session's configuration an export uses: motion models, roads, scan
/// period (defaults of `harrier serve` when a key is missing).
fn deployment(config_json: &str) -> Result<(fmt::Motion, Vec<fmt::Road>, f64), String> {
    let v: serde_json::Value =
        serde_json::from_str(config_json).map_err(|e| format!("config_json: {e}"))?;
    let tracker = &v["tracker"];
    let motion = match &tracker["motion"] {
        serde_json::Value::Null => fmt::Motion::cv(1.0),
        m => serde_json::from_value(m.clone())
            .map_err(|e| format!("config_json tracker.motion: {e}"))?,
    };
    let roads = match &tracker["roads"] {
        serde_json::Value::Null => Vec::new(),
        r => serde_json::from_value(r.clone())
            .map_err(|e| format!("config_json tracker.roads: {e}"))?,
    };
    let dt = tracker["scan_period_s"]
        .as_f64()
        .filter(|d| d.is_finite() && *d > 0.0)
        .unwrap_or(1.0);
    Ok((motion, roads, dt))
}

/// Linear interpolation of `samples` (time, state, mode; sorted by time) at `t`: the sample
/// within [`TIME_TOL_S`], else between two samples at most [`MAX_TRUTH_GAP_S`] apart.
fn truth_at(samples: &[(f64, [f64; 6], String)], t: f64) -> Option<([f64; 6], &str)> {
    let i = samples.partition_point(|s| s.0 < t - TIME_TOL_S);
    let after = samples.get(i)?;
    if (after.0 - t).abs() <= TIME_TOL_S {
        return Some((after.1, &after.2));
    }
    let before = samples.get(i.checked_sub(1)?)?;
    if after.0 - before.0 > MAX_TRUTH_GAP_S {
        return None;
    }
    let w = (t - before.0) / (after.0 - before.0);
    let mut s = before.1;
    for (k, v) in s.iter_mut().enumerate() {
        *v += w * (after.1[k] - before.1[k]);
    }
    Some((s, &before.2))
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
struct TimeLine {
    unix: bool,
    epoch: f64,
}

impl TimeLine {
    fn new(scans: &[(i64, DetectionScan)]) -> Self {
        let unix = scans.iter().all(|s| s.1.time_unix.is_some());
        let mut line = Self { unix, epoch: 0.0 };
        line.epoch = scans
            .iter()
            .filter_map(|s| line.absolute(s.1.t, s.1.time_unix))
            .fold(f64::INFINITY, f64::min);
        line
    }
    /// A message's time on this line (`None`: it lacks `time_unix`).
    fn absolute(self, t: f64, time_unix: Option<f64>) -> Option<f64> {
        if self.unix { time_unix } else { Some(t) }
    }
    /// A message's time relative to the epoch.
    fn relative(self, t: f64, time_unix: Option<f64>) -> Option<f64> {
        Some(self.absolute(t, time_unix)? - self.epoch)
    }
    fn name(self) -> &'static str {
        if self.unix { "time_unix" } else { "t" }
    }
}

/// Samples of one target: relative time, canonical state in the session's frame, mode.
type TargetTruth = Vec<(f64, [f64; 6], String)>;

/// The truth samples per target id, in `frame`, on `line`, sorted by time (samples without a
/// time on the line are left out).
fn truth_by_target(
    truth: &[(i64, TruthSample)],
    frame: &LocalFrame,
    line: TimeLine,
) -> BTreeMap<String, TargetTruth> {
    let mut targets: BTreeMap<String, TargetTruth> = BTreeMap::new();
    for (_, s) in truth {
        let Some(t) = line.relative(s.t, s.time_unix) else {
            continue;
        };
        let from = LocalFrame::new(s.origin);
        let rot = from.rotation_to(frame);
        for g in &s.targets {
            let p = from.enu_to_frame(frame, &Vector3::new(g.state[0], g.state[1], g.state[2]));
            let v = rot * Vector3::new(g.state[3], g.state[4], g.state[5]);
            let state = [p.x, p.y, p.z, v.x, v.y, v.z];
            targets
                .entry(g.id.clone())
                .or_default()
                .push((t, state, g.mode.clone()));
        }
    }
    for samples in targets.values_mut() {
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    targets
}

/// `truth.csv` at `times` (FORMAT-MULTI.md's with a target column when `multi`) and its rows.
fn truth_csv(targets: &BTreeMap<String, TargetTruth>, times: &[f64], multi: bool) -> (String, u64) {
    let mut csv = String::from(if multi {
        scenario_out::MULTI_TRUTH_HEADER
    } else {
        scenario_out::TRUTH_HEADER
    });
    let mut rows = 0;
    for &t in times {
        for (id, samples) in targets {
            if let Some((s, mode)) = truth_at(samples, t) {
                scenario_out::push_truth_row(&mut csv, t, multi.then_some(id.as_str()), &s, mode);
                rows += 1;
            }
        }
    }
    (csv, rows)
}

/// The prior of a single-target export: the first detection of `lines` (sorted) that fixes a
/// position, at its time, its position covariance inflated, velocity 0 ± [`PRIOR_VEL_STD_MPS`].
fn first_fix_prior(
    lines: &[Line],
    sensors: &BTreeMap<(u8, String), SensorEntry>,
    geometry: Geometry,
) -> Option<fmt::Prior> {
    lines.iter().find_map(|l| {
        let e = sensors.get(&l.sensor)?;
        let pos = Vector3::from(l.m.platform.pos);
        let model = SensorModel::new(e.kind, geometry, pos, &e.noise_std, None).ok()?;
        let fix = model.apply(LocateWith(&l.m.z))?;
        let (pv, vv) = (PRIOR_POS_INFLATION, PRIOR_VEL_STD_MPS * PRIOR_VEL_STD_MPS);
        let c = fix.cov;
        Some(fmt::Prior {
            t: l.m.t,
            state: [fix.pos.x, fix.pos.y, geometry.plane_z, 0.0, 0.0, 0.0],
            cov: vec![
                vec![pv * c[(0, 0)], pv * c[(0, 1)], 0.0, 0.0],
                vec![pv * c[(1, 0)], pv * c[(1, 1)], 0.0, 0.0],
                vec![0.0, 0.0, vv, 0.0],
                vec![0.0, 0.0, 0.0, vv],
            ],
            cov_dims: Some(vec![0, 1, 3, 4]),
        })
    })
}

/// Scenario sensor ids of the (vehicle, sensor) pairs: `cam1`, or `cam@1` for every sensor when
/// that naming is ambiguous (`cam1` of vehicle 1 and `cam` of vehicle 11).
fn sensor_ids(sensors: &BTreeMap<(u8, String), SensorEntry>) -> BTreeMap<(u8, String), String> {
    let plain: BTreeSet<String> = sensors
        .keys()
        .map(|(v, s)| scenario_out::sensor_id(s, *v))
        .collect();
    let ambiguous = plain.len() < sensors.len();
    sensors
        .keys()
        .map(|k| {
            let id = if ambiguous {
                format!("{}@{}", k.1, k.0)
            } else {
                scenario_out::sensor_id(&k.1, k.0)
            };
            (k.clone(), id)
        })
        .collect()
}

/// The scenario's sensor entry for `e` with id `id` on vehicle `vehicle`'s platform.
fn scenario_sensor(id: &str, vehicle: u8, e: &SensorEntry) -> fmt::Sensor {
    let span = e.times.last().copied().unwrap_or(0.0) - e.times.first().copied().unwrap_or(0.0);
    fmt::Sensor {
        id: id.into(),
        platform: scenario_out::platform_id(vehicle),
        kind: e.kind,
        ncomp: (e.kind == MeasKind::Position).then_some(e.noise_std.len()),
        rate_hz: (e.times.len() > 1 && span > 0.0).then(|| (e.times.len() - 1) as f64 / span),
        noise: fmt::Noise::Gaussian {
            std: e.noise_std.clone(),
        },
        bias: None,
    }
}

/// A ground target of unknown size.
fn ground_target(id: &str) -> fmt::Target {
    fmt::Target {
        id: id.into(),
        size_m: None,
        size_prior: None,
        on_ground: Some(true),
    }
}

/// What an export reads of a session: its summary, the settings of its configuration an export
/// uses, and its scans and truth samples with their row ids.
struct Recorded {
    info: SessionInfo,
    motion: fmt::Motion,
    roads: Vec<fmt::Road>,
    /// The configured scan period (s): a single-target export's time step, and a multi-target
    /// one's when no sensor scanned twice.
    scan_period: f64,
    scans: Vec<(i64, DetectionScan)>,
    truth: Vec<(i64, TruthSample)>,
}

impl Recorded {
    /// Reads session `id` of `d`; one without scans is refused.
    fn read(d: &Db<'_>, id: i64) -> Result<Self, SessionError> {
        let info = d.info(id)?;
        let (motion, roads, scan_period) = deployment(&d.config_json(id)?)
            .map_err(|m| d.malformed(id, format!("sessions row: {m}")))?;
        let scans = d.rows("scans", id, DetectionScan::from_json)?;
        let truth = d.rows("truth", id, TruthSample::from_json)?;
        if scans.is_empty() {
            return Err(d.export_error(id, "it has no scans"));
        }
        Ok(Self {
            info,
            motion,
            roads,
            scan_period,
            scans,
            truth,
        })
    }

    /// The WGS-84 origin of the session's ENU frame.
    fn origin(&self) -> GeoPoint {
        let i = &self.info;
        GeoPoint::new(i.origin_lat_deg, i.origin_lon_deg, i.origin_alt_m)
    }

    /// Whether the truth has several targets.
    fn several_targets(&self) -> bool {
        let ids: BTreeSet<&str> = self
            .truth
            .iter()
            .flat_map(|s| s.1.targets.iter().map(|g| g.id.as_str()))
            .collect();
        ids.len() > 1
    }
}

/// The time axis of an export.
#[derive(Debug)]
struct ScanTimes {
    /// The scenario's scan times (relative, distinct, in order).
    times: Vec<f64>,
    /// Its time step (s).
    dt: f64,
    /// Largest shift of a scan's time onto the grid (s; 0 when the times are as recorded).
    max_shift: f64,
}

impl ScanTimes {
    /// A single-target export's: the scan times as recorded, the configured period as its step.
    fn as_recorded(mut times: Vec<f64>, scan_period: f64) -> Self {
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
    fn on_grid(
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
    fn t_end(&self) -> f64 {
        self.times.last().copied().unwrap_or(0.0)
    }
}

/// `measurements.jsonl`: `lines` named by their scenario sensor ids (`ids`) and sorted by time,
/// then sensor id (a scan's detections keep their order).
fn measurements_jsonl(
    lines: &mut [Line],
    ids: &BTreeMap<(u8, String), String>,
) -> Result<String, String> {
    for l in lines.iter_mut() {
        l.m.sensor.clone_from(&ids[&l.sensor]);
    }
    lines.sort_by(|a, b| {
        a.m.t
            .total_cmp(&b.m.t)
            .then_with(|| a.m.sensor.cmp(&b.m.sensor))
    });
    let mut out = String::new();
    for l in lines.iter() {
        let text = serde_json::to_string(&l.m)
            .map_err(|e| format!("cannot serialise a measurement: {e}"))?;
        out.push_str(&text);
        out.push('\n');
    }
    Ok(out)
}

/// The scenario's platforms (one per vehicle) and sensors (named by `ids`).
fn scenario_sensors(
    sensors: &BTreeMap<(u8, String), SensorEntry>,
    ids: &BTreeMap<(u8, String), String>,
) -> (Vec<fmt::Platform>, Vec<fmt::Sensor>) {
    let vehicles: BTreeSet<u8> = sensors.keys().map(|k| k.0).collect();
    let platforms = vehicles
        .iter()
        .map(|v| fmt::Platform {
            id: scenario_out::platform_id(*v),
            kind: "uav".into(),
        })
        .collect();
    let list = sensors
        .iter()
        .map(|(k, e)| scenario_sensor(&ids[k], k.0, e))
        .collect();
    (platforms, list)
}

/// The shape of an export: its format, its time line and its time axis.
#[derive(Debug)]
struct Shape {
    /// FORMAT-MULTI.md rather than single-target.
    multi: bool,
    line: TimeLine,
    times: ScanTimes,
}

/// `scenario.json` of the export of `session` (read from `db`): its platforms and sensors,
/// targets, time axis, the session's motion models and roads, and where it came from.
fn scenario_document(
    db: &Path,
    session: &Recorded,
    shape: &Shape,
    (platforms, sensors): (Vec<fmt::Platform>, Vec<fmt::Sensor>),
    targets: &BTreeMap<String, TargetTruth>,
    prior: Option<fmt::Prior>,
) -> fmt::ScenarioDocument {
    let (info, id) = (&session.info, session.info.id);
    let mut extensions = serde_json::Map::new();
    if shape.multi {
        let all: Vec<fmt::Target> = if targets.is_empty() {
            vec![ground_target("unknown")]
        } else {
            targets.keys().map(|k| ground_target(k)).collect()
        };
        extensions.insert("targets".into(), json!(all));
    }
    let (epoch, time_line) = (shape.line.epoch, shape.line.name());
    let scenario = fmt::Scenario {
        format: fmt::FORMAT_ID.into(),
        name: format!("session_{id}"),
        description: format!(
            "harrier serve session {id} of {} (started {:.3} UNIX, track filter {}); time 0 is \
             {epoch:.6} on the {time_line} time line",
            db.display(),
            info.started_unix,
            info.estimator
        ),
        dims: 2,
        plane_z: Some(info.plane_z),
        time: fmt::TimeSpec {
            t0: 0.0,
            dt: shape.times.dt,
            t_end: shape.times.t_end(),
        },
        target: ground_target(if shape.multi {
            "multi"
        } else {
            targets.keys().next().map_or("tgt", String::as_str)
        }),
        platforms,
        sensors,
        roads: session.roads.clone(),
        motion: Some(session.motion.clone()),
        prior,
        linear_system: None,
        hints: json!({}),
        scoring: fmt::Scoring::default(),
    };
    let generator = fmt::Generator {
        family: "harrier sessions export".into(),
        seed: 0,
        params: json!({
            "session": id,
            "started_unix": info.started_unix,
            "ended_unix": info.ended_unix,
            "estimator": info.estimator,
            "epoch": epoch,
            "time_line": time_line,
            "version": env!("CARGO_PKG_VERSION"),
        }),
    };
    fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(Some(session.origin())),
        extensions,
        generator,
    }
}

/// Exports session `id` of `db` as a `gcs-scenario/1` scenario, in memory.
pub fn export(db: &Path, id: i64) -> Result<Exported, SessionError> {
    let d = Db::open(db)?;
    let session = Recorded::read(&d, id)?;
    let frame = LocalFrame::new(session.origin());
    let geometry = Geometry::planar(session.info.plane_z);
    let mut line = TimeLine::new(&session.scans);
    let Framed {
        sensors,
        mut lines,
        times,
        several,
    } = framed(&d, id, &session.scans, line, &frame, geometry)?;
    let multi = several || session.several_targets();
    let times = if multi {
        ScanTimes::on_grid(&sensors, &mut lines, session.scan_period, &mut line)
            .map_err(|m| d.export_error(id, m))?
    } else {
        ScanTimes::as_recorded(times, session.scan_period)
    };
    let targets = truth_by_target(&session.truth, &frame, line);
    let ids = sensor_ids(&sensors);
    let measurements_jsonl =
        measurements_jsonl(&mut lines, &ids).map_err(|m| d.export_error(id, m))?;
    let truth = (!targets.is_empty()).then(|| truth_csv(&targets, &times.times, multi));
    let prior = (!multi)
        .then(|| first_fix_prior(&lines, &sensors, geometry))
        .flatten();
    let shape = Shape { multi, line, times };
    let platforms_and_sensors = scenario_sensors(&sensors, &ids);
    let scenario_json =
        scenario_document(db, &session, &shape, platforms_and_sensors, &targets, prior)
            .to_json()
            .map_err(|e| d.export_error(id, format!("cannot serialise scenario.json: {e}")))?;
    Ok(Exported {
        session: id,
        scenario_json,
        measurements_jsonl,
        truth_rows: truth.as_ref().map_or(0, |t| t.1),
        truth_csv: truth.map(|t| t.0),
        multi,
        epoch: line.epoch,
        time_line: line.name().into(),
        max_time_shift_s: shape.times.max_shift,
        scans: session.scans.len() as u64,
        lines: lines.len() as u64,
        sensors: ids.into_values().collect(),
    })
}

impl Exported {
    /// Writes the scenario directory `dir` atomically (harrier-link's
    /// [`write_dir`](scenario_out::write_dir)): `dir` must not exist or be empty.
    pub fn write_to(&self, dir: &Path) -> Result<(), SessionError> {
        let mut files = vec![
            ("scenario.json", self.scenario_json.as_str()),
            ("measurements.jsonl", self.measurements_jsonl.as_str()),
        ];
        if let Some(t) = &self.truth_csv {
            files.push(("truth.csv", t.as_str()));
        }
        Ok(scenario_out::write_dir(dir, &files)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scan_grid_and_the_truth_interpolation() {
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
        let s = [
            (0.0, [0.0; 6], "a".into()),
            (1.0, [2.0; 6], "b".into()),
            (4.0, [0.0; 6], "c".into()),
        ];
        assert_eq!(truth_at(&s, 0.5), Some(([1.0; 6], "a")));
        assert_eq!(truth_at(&s, 1.0000001), Some(([2.0; 6], "b")));
        assert_eq!(truth_at(&s, 2.0), None, "a gap of 3 s");
        assert_eq!(truth_at(&s, -1.0), None);
    }
}
