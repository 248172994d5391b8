//! Recorded sessions: the SQLite files of the live recorder ([`crate::live::recorder`],
//! RECORDING.md), read offline — [`list`] and [`info`] summarise them, [`export`] turns one
//! into a `gcs-scenario/1` directory that `harrier replay` runs and `score.py` scores; the
//! `harrier sessions` command line. Files are opened read-only, so this works while a server is
//! still writing (WAL mode) and on the file of a killed one.
//!
//! An export puts the session's scans into the session's ENU frame (harrier-link's
//! `scan_in_frame`) and its times relative to the first scan, on the time line the tracker used
//! (`time_unix` when every scan carries it, else the senders' `t`). It is single-target
//! (FORMAT.md) unless the truth has several targets or a scan holds several detections (clutter
//! or several targets), then FORMAT-MULTI.md — as harrier-sim's `record` decides.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write as _;
use std::path::{Path, PathBuf};

use harrier_core::detection::{DetectionScan, GeoPoint, TruthSample};
use harrier_core::measurement::{
    Geometry, Locate, MeasKind, MeasurementModel, PositionFix, SensorModel, WithSensor,
};
use harrier_core::scenario as fmt;
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;
use harrier_link::scenario_out::{self, WriteError};
use nalgebra::{SVector, Vector3};
use rusqlite::{Connection, OpenFlags, OptionalExtension};
use serde_json::json;

use crate::live::recorder::schema_problem;

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

/// Arguments of `harrier sessions`.
#[derive(Debug, clap::Args)]
pub struct SessionsArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: SessionsCommand,
}

/// `harrier sessions` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum SessionsCommand {
    /// List the sessions recorded in a SQLite file (`[recorder] path` of `harrier serve`).
    List {
        /// The session file.
        db: PathBuf,
        /// Print JSON (an array of sessions) instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Show one session's summary.
    Info {
        /// The session file.
        db: PathBuf,
        /// Session id (`harrier sessions list`).
        id: i64,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Export one session as a gcs-scenario/1 directory (FORMAT-MULTI.md when the truth has several
    /// targets or a scan several detections), for `harrier replay` and `score.py`.
    Export {
        /// The session file.
        db: PathBuf,
        /// Session id (`harrier sessions list`).
        id: i64,
        /// Output directory (must not exist, or be empty; written atomically).
        out_dir: PathBuf,
    },
}

/// A session's summary.
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct SessionInfo {
    /// Session id in its file.
    pub id: i64,
    /// When the service started (UNIX s).
    pub started_unix: f64,
    /// When the recorder was closed (UNIX s); `None` while it runs, or when it was killed.
    pub ended_unix: Option<f64>,
    /// Track filter at the start.
    pub estimator: String,
    /// WGS-84 origin of the session's ENU frame: latitude (deg).
    pub origin_lat_deg: f64,
    /// Longitude (deg).
    pub origin_lon_deg: f64,
    /// Altitude (m).
    pub origin_alt_m: f64,
    /// Up coordinate of the ground plane (m).
    pub plane_z: f64,
    /// Scan rows.
    pub scans: u64,
    /// Detection rows.
    pub detections: u64,
    /// Track rows.
    pub track_rows: u64,
    /// Truth rows.
    pub truth_rows: u64,
    /// Action rows.
    pub actions: u64,
    /// Records the recorder dropped (queue full), as of its last commit.
    pub dropped: u64,
    /// Receive time of the first scan (UNIX s).
    pub first_received_unix: Option<f64>,
    /// Receive time of the last scan (UNIX s).
    pub last_received_unix: Option<f64>,
    /// Time of the last commit (UNIX s).
    pub last_commit_unix: Option<f64>,
    /// Vehicles (MAVLink system ids) that sent scans.
    pub vehicles: Vec<String>,
    /// Their sensors, `vehicle/sensor` (e.g. `1/cam`).
    pub sensors: Vec<String>,
}

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

/// Why a session file or session cannot be read or exported. Messages name the file and session.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The file does not exist or SQLite cannot open it.
    #[error("{}: cannot open: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// Why.
        source: rusqlite::Error,
    },
    /// The file is not a Harrier session file (or of a newer schema).
    #[error("{}: {message}", path.display())]
    NotSessionFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A query failed.
    #[error("{}: {source}", path.display())]
    Sqlite {
        /// The file.
        path: PathBuf,
        /// SQLite's error.
        source: rusqlite::Error,
    },
    /// No session has this id.
    #[error("{}: no session {id}", path.display())]
    NotFound {
        /// The file.
        path: PathBuf,
        /// The id asked for.
        id: i64,
    },
    /// A row cannot be read (names the table and row).
    #[error("{}: session {id}: {message}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The session.
        id: i64,
        /// What is wrong, and where.
        message: String,
    },
    /// The session cannot be written as a scenario (no scans, scans off any grid, …).
    #[error("{}: session {id}: cannot export: {message}", path.display())]
    Export {
        /// The file.
        path: PathBuf,
        /// The session.
        id: i64,
        /// Why.
        message: String,
    },
    /// The directory cannot be written.
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// A session file opened read-only.
struct Db<'a> {
    path: &'a Path,
    conn: Connection,
}

impl<'a> Db<'a> {
    fn open(path: &'a Path) -> Result<Self, SessionError> {
        let open = |source| SessionError::Open {
            path: path.to_path_buf(),
            source,
        };
        if !path.is_file() {
            return Err(open(rusqlite::Error::InvalidPath(path.to_path_buf())));
        }
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(open)?;
        let db = Self { path, conn };
        db.conn
            .busy_timeout(std::time::Duration::from_secs(5))
            .map_err(|e| db.sql(e))?;
        if let Some(message) = schema_problem(&db.conn, false).map_err(|e| db.sql(e))? {
            return Err(SessionError::NotSessionFile {
                path: path.to_path_buf(),
                message,
            });
        }
        Ok(db)
    }

    fn sql(&self, source: rusqlite::Error) -> SessionError {
        SessionError::Sqlite {
            path: self.path.to_path_buf(),
            source,
        }
    }

    fn malformed(&self, id: i64, message: String) -> SessionError {
        SessionError::Malformed {
            path: self.path.to_path_buf(),
            id,
            message,
        }
    }

    fn export_error(&self, id: i64, message: impl Into<String>) -> SessionError {
        SessionError::Export {
            path: self.path.to_path_buf(),
            id,
            message: message.into(),
        }
    }

    fn ids(&self) -> Result<Vec<i64>, SessionError> {
        let mut st = self
            .conn
            .prepare("SELECT id FROM sessions ORDER BY id")
            .map_err(|e| self.sql(e))?;
        st.query_map([], |r| r.get(0))
            .and_then(Iterator::collect)
            .map_err(|e| self.sql(e))
    }

    fn info(&self, id: i64) -> Result<SessionInfo, SessionError> {
        let count = |v: i64| u64::try_from(v).unwrap_or(0);
        let row = self
            .conn
            .query_row(
                "SELECT started_unix, ended_unix, estimator, origin_lat_deg, origin_lon_deg, \
                 origin_alt_m, plane_z, scans, detections, track_rows, truth_rows, actions, \
                 dropped, first_received_unix, last_received_unix, last_commit_unix \
                 FROM sessions WHERE id = ?1",
                [id],
                |r| {
                    Ok(SessionInfo {
                        id,
                        started_unix: r.get(0)?,
                        ended_unix: r.get(1)?,
                        estimator: r.get(2)?,
                        origin_lat_deg: r.get(3)?,
                        origin_lon_deg: r.get(4)?,
                        origin_alt_m: r.get(5)?,
                        plane_z: r.get(6)?,
                        scans: count(r.get(7)?),
                        detections: count(r.get(8)?),
                        track_rows: count(r.get(9)?),
                        truth_rows: count(r.get(10)?),
                        actions: count(r.get(11)?),
                        dropped: count(r.get(12)?),
                        first_received_unix: r.get(13)?,
                        last_received_unix: r.get(14)?,
                        last_commit_unix: r.get(15)?,
                        vehicles: Vec::new(),
                        sensors: Vec::new(),
                    })
                },
            )
            .optional()
            .map_err(|e| self.malformed(id, format!("sessions row: {e}")))?;
        let mut info = row.ok_or_else(|| SessionError::NotFound {
            path: self.path.to_path_buf(),
            id,
        })?;
        let mut st = self
            .conn
            .prepare(
                "SELECT vehicle, sensor FROM sensors WHERE session = ?1 ORDER BY vehicle, sensor",
            )
            .map_err(|e| self.sql(e))?;
        let pairs: Vec<(i64, String)> = st
            .query_map([id], |r| Ok((r.get(0)?, r.get(1)?)))
            .and_then(Iterator::collect)
            .map_err(|e| self.malformed(id, format!("sensors rows: {e}")))?;
        let vehicles: BTreeSet<i64> = pairs.iter().map(|p| p.0).collect();
        info.vehicles = vehicles.iter().map(i64::to_string).collect();
        info.sensors = pairs.iter().map(|(v, s)| format!("{v}/{s}")).collect();
        Ok(info)
    }

    /// The `json` column of every row of `table` of session `id`, in row order, parsed by
    /// `parse`, with each row's id.
    fn rows<T, E: std::fmt::Display>(
        &self,
        table: &str,
        id: i64,
        parse: impl Fn(&[u8]) -> Result<T, E>,
    ) -> Result<Vec<(i64, T)>, SessionError> {
        let mut st = self
            .conn
            .prepare(&format!(
                "SELECT id, json FROM {table} WHERE session = ?1 ORDER BY id"
            ))
            .map_err(|e| self.sql(e))?;
        let mut rows = st.query([id]).map_err(|e| self.sql(e))?;
        let mut out = Vec::new();
        while let Some(r) = rows.next().map_err(|e| self.sql(e))? {
            let row: i64 = r.get(0).map_err(|e| self.sql(e))?;
            let text: String = r
                .get(1)
                .map_err(|e| self.malformed(id, format!("{table} row {row}: json: {e}")))?;
            let v = parse(text.as_bytes())
                .map_err(|e| self.malformed(id, format!("{table} row {row}: {e}")))?;
            out.push((row, v));
        }
        Ok(out)
    }

    /// The scans of session `id` in `frame`, one measurement line per detection (time on `line`,
    /// no sensor id yet), and each (vehicle, sensor)'s kind, noise and scan times.
    fn framed(
        &self,
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
                .map_err(|e| self.malformed(id, format!("scans row {row}: {e}")))?;
            let key = (scan.vehicle, scan.sensor.clone());
            let entry = sensors.entry(key.clone()).or_insert_with(|| SensorEntry {
                kind: scan.kind,
                noise_std: scan.noise_std.clone(),
                times: Vec::new(),
            });
            if entry.kind != scan.kind || entry.noise_std.len() != scan.noise_std.len() {
                return Err(self.export_error(
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
}

/// Every session in `db`, in id order. Opens the file read-only.
pub fn list(db: &Path) -> Result<Vec<SessionInfo>, SessionError> {
    let d = Db::open(db)?;
    d.ids()?.into_iter().map(|id| d.info(id)).collect()
}

/// The session `id` of `db` ([`SessionError::NotFound`] when there is none).
pub fn info(db: &Path, id: i64) -> Result<SessionInfo, SessionError> {
    Db::open(db)?.info(id)
}

/// One (vehicle, sensor) of a session as a scenario sensor.
#[derive(Debug)]
struct SensorEntry {
    kind: MeasKind,
    noise_std: Vec<f64>,
    /// Scan times (relative).
    times: Vec<f64>,
}

/// A session's scans in its frame ([`Db::framed`]).
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

/// Exports session `id` of `db` as a `gcs-scenario/1` scenario, in memory.
pub fn export(db: &Path, id: i64) -> Result<Exported, SessionError> {
    let d = Db::open(db)?;
    let info = d.info(id)?;
    let config_json: String = d
        .conn
        .query_row(
            "SELECT config_json FROM sessions WHERE id = ?1",
            [id],
            |r| r.get(0),
        )
        .map_err(|e| d.malformed(id, format!("sessions row: config_json: {e}")))?;
    let (motion, roads, scan_period) =
        deployment(&config_json).map_err(|m| d.malformed(id, format!("sessions row: {m}")))?;
    let scans: Vec<(i64, DetectionScan)> = d.rows("scans", id, DetectionScan::from_json)?;
    let truth: Vec<(i64, TruthSample)> = d.rows("truth", id, TruthSample::from_json)?;
    if scans.is_empty() {
        return Err(d.export_error(id, "it has no scans"));
    }

    let mut line = TimeLine::new(&scans);
    let origin = GeoPoint::new(info.origin_lat_deg, info.origin_lon_deg, info.origin_alt_m);
    let frame = LocalFrame::new(origin);
    let geometry = Geometry::planar(info.plane_z);

    let Framed {
        sensors,
        mut lines,
        times,
        several,
    } = d.framed(id, &scans, line, &frame, geometry)?;
    let ids = sensor_ids(&sensors);
    let truth_ids: BTreeSet<&str> = truth
        .iter()
        .flat_map(|s| s.1.targets.iter().map(|g| g.id.as_str()))
        .collect();
    let multi = several || truth_ids.len() > 1;

    // Scan times: as recorded (single target), or snapped to the scan grid (multi-target), time
    // 0 then being grid point 0.
    let (times, dt, max_shift) = if multi {
        let g = Grid::fit(&sensors, scan_period).map_err(|m| d.export_error(id, m))?;
        line.epoch += g.origin;
        for ((v, s), e) in &sensors {
            let k: Vec<i64> = e.times.iter().map(|t| g.index(*t)).collect();
            if let Some(w) = k.windows(2).find(|w| w[0] == w[1]) {
                return Err(d.export_error(
                    id,
                    format!(
                        "sensor {s} of vehicle {v} scans twice at grid time {} s (dt {} s)",
                        w[0] as f64 * g.dt,
                        g.dt
                    ),
                ));
            }
        }
        for l in &mut lines {
            l.m.t = g.index(l.t) as f64 * g.dt;
        }
        let last = times.iter().map(|t| g.index(*t)).max().unwrap_or(0);
        let grid: Vec<f64> = (0..=last).map(|k| k as f64 * g.dt).collect();
        (grid, g.dt, g.max_shift)
    } else {
        let mut distinct = times;
        distinct.sort_by(f64::total_cmp);
        distinct.dedup_by(|a, b| (*a - *b).abs() <= TIME_TOL_S);
        (distinct, scan_period, 0.0)
    };
    let t_end = times.last().copied().unwrap_or(0.0);
    let targets = truth_by_target(&truth, &frame, line);

    // measurements.jsonl: sorted by time, then sensor id (a scan's detections keep their order).
    for l in &mut lines {
        l.m.sensor.clone_from(&ids[&l.sensor]);
    }
    lines.sort_by(|a, b| {
        a.m.t
            .total_cmp(&b.m.t)
            .then_with(|| a.m.sensor.cmp(&b.m.sensor))
    });
    let mut measurements_jsonl = String::new();
    for l in &lines {
        let text = serde_json::to_string(&l.m)
            .map_err(|e| d.export_error(id, format!("cannot serialise a measurement: {e}")))?;
        measurements_jsonl.push_str(&text);
        measurements_jsonl.push('\n');
    }

    let (truth_csv, truth_rows) = if targets.is_empty() {
        (None, 0)
    } else {
        let (csv, rows) = truth_csv(&targets, &times, multi);
        (Some(csv), rows)
    };
    let prior = (!multi)
        .then(|| first_fix_prior(&lines, &sensors, geometry))
        .flatten();

    // scenario.json
    let vehicles: BTreeSet<u8> = sensors.keys().map(|k| k.0).collect();
    let platforms = vehicles
        .iter()
        .map(|v| fmt::Platform {
            id: scenario_out::platform_id(*v),
            kind: "uav".into(),
        })
        .collect();
    let sensor_list: Vec<fmt::Sensor> = sensors
        .iter()
        .map(|(k, e)| scenario_sensor(&ids[k], k.0, e))
        .collect();
    let mut extensions = serde_json::Map::new();
    if multi {
        let all: Vec<fmt::Target> = if targets.is_empty() {
            vec![ground_target("unknown")]
        } else {
            targets.keys().map(|k| ground_target(k)).collect()
        };
        extensions.insert("targets".into(), json!(all));
    }
    let (epoch, time_line) = (line.epoch, line.name());
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
        time: fmt::TimeSpec { t0: 0.0, dt, t_end },
        target: ground_target(if multi {
            "multi"
        } else {
            targets.keys().next().map_or("tgt", String::as_str)
        }),
        platforms,
        sensors: sensor_list,
        roads,
        motion: Some(motion),
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
    let scenario_json = fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(Some(origin)),
        extensions,
        generator,
    }
    .to_json()
    .map_err(|e| d.export_error(id, format!("cannot serialise scenario.json: {e}")))?;
    Ok(Exported {
        session: id,
        scenario_json,
        measurements_jsonl,
        truth_csv,
        multi,
        epoch,
        time_line: time_line.into(),
        max_time_shift_s: max_shift,
        scans: scans.len() as u64,
        lines: lines.len() as u64,
        truth_rows,
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

/// A UNIX time as `YYYY-MM-DD hh:mm:ssZ` (UTC).
fn utc(unix: f64) -> String {
    let secs = unix.floor() as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// `writeln!` to stdout that ignores a closed pipe.
macro_rules! out {
    ($($arg:tt)*) => {{
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

fn info_lines(s: &SessionInfo) -> Vec<String> {
    let span = match (s.first_received_unix, s.last_received_unix) {
        (Some(a), Some(b)) => format!("{:.1} s of scans", b - a),
        _ => "no scans".into(),
    };
    vec![
        format!(
            "session {}: started {}, {}",
            s.id,
            utc(s.started_unix),
            s.ended_unix.map_or_else(
                || "not closed (running, or the server was killed)".to_owned(),
                |e| format!("ended {}", utc(e))
            )
        ),
        format!(
            "  track filter {}, origin {:.6}° {:.6}° {:.1} m, ground plane z = {} m",
            s.estimator, s.origin_lat_deg, s.origin_lon_deg, s.origin_alt_m, s.plane_z
        ),
        format!(
            "  {} scans ({span}), {} detections, {} track rows, {} truth rows, {} actions, {} dropped",
            s.scans, s.detections, s.track_rows, s.truth_rows, s.actions, s.dropped
        ),
        format!(
            "  vehicles {}; sensors {}",
            s.vehicles.join(", "),
            s.sensors.join(", ")
        ),
    ]
}

/// Runs `harrier sessions`.
pub fn run(args: &SessionsArgs) -> anyhow::Result<()> {
    match &args.command {
        SessionsCommand::List { db, json } => {
            let all = list(db)?;
            if *json {
                out!("{}", serde_json::to_string_pretty(&all)?);
            } else if all.is_empty() {
                out!("{}: no sessions", db.display());
            } else {
                out!(
                    "{:>4}  {:<20}  {:>9}  {:<8}  {:>8}  {:>10}  {:>8}  {:>6}  vehicles",
                    "id",
                    "started (UTC)",
                    "duration",
                    "engine",
                    "scans",
                    "detections",
                    "tracks",
                    "truth"
                );
                for s in &all {
                    let duration = s
                        .ended_unix
                        .or(s.last_commit_unix)
                        .map_or_else(|| "-".into(), |e| format!("{:.0} s", e - s.started_unix));
                    let open = if s.ended_unix.is_none() {
                        " (open)"
                    } else {
                        ""
                    };
                    out!(
                        "{:>4}  {:<20}  {:>9}  {:<8}  {:>8}  {:>10}  {:>8}  {:>6}  {}{open}",
                        s.id,
                        utc(s.started_unix),
                        duration,
                        s.estimator,
                        s.scans,
                        s.detections,
                        s.track_rows,
                        s.truth_rows,
                        s.vehicles.join(",")
                    );
                }
            }
        }
        SessionsCommand::Info { db, id, json } => {
            let s = info(db, *id)?;
            if *json {
                out!("{}", serde_json::to_string_pretty(&s)?);
            } else {
                for l in info_lines(&s) {
                    out!("{l}");
                }
            }
        }
        SessionsCommand::Export { db, id, out_dir } => {
            let e = export(db, *id)?;
            e.write_to(out_dir)?;
            let format = if e.multi {
                "gcs-scenario/1 + FORMAT-MULTI"
            } else {
                "gcs-scenario/1, single target"
            };
            out!(
                "wrote {} ({format}): scenario.json, measurements.jsonl ({} lines from {} scans), {}",
                out_dir.display(),
                e.lines,
                e.scans,
                e.truth_csv.as_ref().map_or_else(
                    || "no truth.csv (no truth recorded)".to_owned(),
                    |_| format!("truth.csv ({} rows)", e.truth_rows)
                )
            );
            if e.multi {
                out!(
                    "  scan times snapped to the FORMAT-MULTI grid, by at most {:.4} s",
                    e.max_time_shift_s
                );
            }
            out!(
                "  sensors {}; time 0 = {:.6} ({}); replay: harrier replay {} -e <estimator>",
                e.sensors.join(", "),
                e.epoch,
                e.time_line,
                out_dir.display()
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use harrier_core::tracker::format::MultiScenario;

    use super::*;
    use crate::live::recorder::testing::{HOME, T0_UNIX, meta, scan, track, truth};
    use crate::live::recorder::{Record, Recorder};

    /// Target `j` at time `t`: straight lines at 5–8 m/s on the ground plane.
    fn state(t: f64, j: usize) -> [f64; 6] {
        let (p, v) = (
            [100.0 + 300.0 * j as f64, 200.0],
            [5.0, 3.0 + 5.0 * j as f64],
        );
        [p[0] + v[0] * t, p[1] + v[1] * t, 0.0, v[0], v[1], 0.0]
    }

    /// `r`, a scan, re-published in the ENU frame of `origin` (as a vehicle with another home
    /// would): platform and 2-D fixes through ECEF.
    fn moved(r: Record, origin: GeoPoint) -> Record {
        let Record::Scan {
            received_unix,
            mut scan,
        } = r
        else {
            return r;
        };
        let (from, to) = (LocalFrame::new(scan.origin), LocalFrame::new(origin));
        let p = from.enu_to_frame(&to, &Vector3::from(scan.platform.pos));
        scan.platform.pos = p.into();
        for d in &mut scan.detections {
            let q = from.enu_to_frame(&to, &Vector3::new(d.z[0], d.z[1], 0.0));
            d.z = vec![q.x, q.y];
        }
        scan.origin = origin;
        Record::Scan {
            received_unix,
            scan,
        }
    }

    /// A 40 s session of `targets` targets seen by the `position` cameras of vehicles 1 and 2 at
    /// 1 Hz (detections within 3 m; vehicle 2 scans `late` s after vehicle 1 and publishes in a
    /// frame some 300 m away), truth at 10 Hz, a track row per scan.
    fn session(dir: &Path, targets: usize, late: f64) -> PathBuf {
        let path = dir.join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 4096).expect("open");
        let away = GeoPoint::new(HOME.lat_deg + 0.002, HOME.lon_deg + 0.003, HOME.alt_m + 5.0);
        for k in -5..=405 {
            let t = f64::from(k) * 0.1;
            let ids = ["T0", "T1", "T2"];
            let tr: Vec<(&str, [f64; 6])> = (0..targets).map(|j| (ids[j], state(t, j))).collect();
            r.record(truth(t, &tr));
        }
        for k in 0..=40_u64 {
            let t = k as f64;
            for v in [1_u8, 2] {
                let t = if v == 2 { t + late } else { t };
                let z: Vec<[f64; 2]> = (0..targets)
                    .map(|j| {
                        let s = state(t, j);
                        let e = |i: u64| 3.0 * ((7 * k + 3 * j as u64 + 5 * i) as f64).sin();
                        [s[0] + e(u64::from(v)), s[1] + e(u64::from(v) + 1)]
                    })
                    .collect();
                let rec = scan(v, k, t, [f64::from(v) * 50.0, 0.0, 300.0], &z);
                r.record(if v == 2 { moved(rec, away) } else { rec });
            }
            r.record(Record::Tracks {
                t: T0_UNIX + t,
                tracks: vec![track(1, T0_UNIX + t, state(t, 0))],
            });
        }
        let s = r.close().expect("close");
        assert_eq!(s.dropped + s.errors, 0, "{s:?}");
        path
    }

    #[test]
    fn a_single_target_session_lists_exports_replays_and_scores() {
        let dir = tempfile::tempdir().expect("tempdir");
        let db = session(dir.path(), 1, 0.0);
        let all = list(&db).expect("list");
        assert_eq!(all.len(), 1);
        let s = &all[0];
        assert_eq!(
            (s.id, s.scans, s.detections, s.track_rows, s.truth_rows),
            (1, 82, 82, 41, 411)
        );
        assert_eq!(s.vehicles, ["1", "2"]);
        assert_eq!(s.sensors, ["1/cam", "2/cam"]);
        assert!(s.ended_unix.is_some() && s.estimator == "ekf");
        assert_eq!(info(&db, 1).expect("info"), *s);

        let e = export(&db, 1).expect("export");
        assert!(!e.multi);
        assert_eq!((e.epoch, e.time_line.as_str()), (T0_UNIX, "time_unix"));
        assert_eq!((e.scans, e.lines, e.truth_rows), (82, 82, 41));
        assert_eq!(e.sensors, ["cam1", "cam2"]);
        let out = dir.path().join("export");
        e.write_to(&out).expect("write");
        let data = crate::replay::load(&out).expect("the export loads");
        let sc = &data.scenario;
        assert_eq!((sc.sensors.len(), sc.platforms.len()), (2, 2));
        assert_eq!(sc.sensors[1].rate_hz, Some(1.0));
        assert_eq!(sc.time.t_end, 40.0);
        assert_eq!(sc.target.id, "T0");
        assert_eq!(sc.motion.as_ref().and_then(|m| m.accel_std), Some(0.5));
        // Both vehicles' detections, in the session's frame, are within the 3 m of their noise.
        let truth = data.truth.as_ref().expect("truth");
        for m in &data.measurements {
            let (x, ..) = fmt::truth_at(truth, m.t).expect("truth at every scan");
            let err = (m.z[0] - x[0]).hypot(m.z[1] - x[1]);
            assert!(
                err < 3.0 * 2f64.sqrt() + 0.01,
                "{} at t {}: {err} m",
                m.sensor,
                m.t
            );
        }
        let prior = sc.prior.as_ref().expect("prior");
        assert_eq!((prior.t, prior.state[3]), (0.0, 0.0));
        assert!((prior.cov[0][0] - 400.0).abs() < 1e-9, "{:?}", prior.cov);

        let report = crate::replay::run(&data, "kf", &crate::engine::Params::default())
            .expect("kf replays the export");
        assert!(report.rejected.is_empty(), "{:?}", report.rejected);
        assert_eq!(report.estimates.len(), 41);
        let rmse = report.score.and_then(|s| s.pos_rmse).expect("scored");
        assert!(rmse < 3.0, "kf position RMSE {rmse} m");
    }

    #[test]
    fn several_targets_export_as_format_multi_and_replay_with_the_tracker() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Vehicle 2 scans 15 ms after vehicle 1: its scans are snapped to the 1 s grid.
        let db = session(dir.path(), 2, 0.015);
        let e = export(&db, 1).expect("export");
        assert!(e.multi && e.lines == 164 && e.truth_rows == 82, "{e:?}");
        assert!(
            e.max_time_shift_s > 0.005 && e.max_time_shift_s < 0.015,
            "{e:?}"
        );
        assert!(
            (e.epoch - T0_UNIX - 0.0075).abs() < 1e-6,
            "{}",
            e.epoch - T0_UNIX
        );
        let m = MultiScenario::parse(
            &e.scenario_json,
            &e.measurements_jsonl,
            e.truth_csv.as_deref(),
        )
        .expect("a valid FORMAT-MULTI scenario");
        assert_eq!(m.targets.len(), 2);
        assert_eq!((m.scans.len(), m.scenario.time.dt), (41, 1.0));
        assert!(m.scans.iter().all(|s| s.detections.len() == 4));
        assert!(m.scenario.prior.is_none());
        let out = dir.path().join("multi");
        e.write_to(&out).expect("write");
        let data = crate::replay::load(&out).expect("loads");
        let r = crate::replay::run(&data, "tracker", &crate::engine::Params::default())
            .expect("the tracker replays it");
        let last = r.estimates.last().expect("estimates");
        let tracks = serde_json::to_value(last).expect("json")["tracks"].clone();
        assert_eq!(tracks.as_array().map(Vec::len), Some(2), "{tracks}");
    }

    #[test]
    fn errors_name_the_file_the_session_and_the_row() {
        let dir = tempfile::tempdir().expect("tempdir");
        let db = session(dir.path(), 1, 0.0);
        let e = info(&db, 99).expect_err("no such session");
        assert!(matches!(e, SessionError::NotFound { id: 99, .. }), "{e}");
        assert!(e.to_string().ends_with("rec.sqlite: no session 99"), "{e}");
        assert!(matches!(
            export(&db, 99),
            Err(SessionError::NotFound { .. })
        ));

        let missing = dir.path().join("missing.sqlite");
        let e = list(&missing).expect_err("missing");
        assert!(e.to_string().contains("missing.sqlite: cannot open"), "{e}");
        let other = dir.path().join("other.sqlite");
        Connection::open(&other)
            .and_then(|c| c.execute_batch("CREATE TABLE t (x)"))
            .expect("other db");
        let e = list(&other).expect_err("not ours");
        assert!(matches!(e, SessionError::NotSessionFile { .. }), "{e}");
        assert!(
            e.to_string()
                .contains("other.sqlite: not a Harrier session file"),
            "{e}"
        );

        let rw = Connection::open(&db).expect("open");
        rw.execute("UPDATE scans SET json = '{\"schema\": 1' WHERE id = 3", [])
            .expect("corrupt");
        let e = export(&db, 1).expect_err("malformed");
        assert!(matches!(e, SessionError::Malformed { id: 1, .. }), "{e}");
        assert!(
            e.to_string()
                .contains("session 1: scans row 3: malformed detections"),
            "{e}"
        );
        rw.execute(
            "UPDATE scans SET json = (SELECT json FROM scans WHERE id = 4) WHERE id = 3",
            [],
        )
        .expect("repair");
        rw.execute(
            "UPDATE scans SET json = replace(json, '[10.0,10.0]', '[10.0,-1.0]') WHERE id = 5",
            [],
        )
        .expect("invalid noise");
        let e = export(&db, 1).expect_err("invalid");
        assert!(
            e.to_string().contains("scans row 5") && e.to_string().contains("noise_std"),
            "{e}"
        );
        rw.execute("UPDATE sessions SET config_json = 'nope' WHERE id = 1", [])
            .expect("update");
        let e = export(&db, 1).expect_err("config");
        assert!(
            e.to_string()
                .contains("session 1: sessions row: config_json"),
            "{e}"
        );
        drop(rw);

        let empty = Recorder::open(&db, &meta("imm"), Duration::from_millis(20), 16)
            .expect("second session");
        empty.close().expect("close");
        let e = export(&db, 2).expect_err("no scans");
        assert!(
            e.to_string()
                .contains("session 2: cannot export: it has no scans"),
            "{e}"
        );
    }

    #[test]
    fn the_command_line_lists_and_exports() {
        let dir = tempfile::tempdir().expect("tempdir");
        let db = session(dir.path(), 1, 0.0);
        let out = dir.path().join("out/session1");
        for command in [
            SessionsCommand::List {
                db: db.clone(),
                json: false,
            },
            SessionsCommand::List {
                db: db.clone(),
                json: true,
            },
            SessionsCommand::Info {
                db: db.clone(),
                id: 1,
                json: false,
            },
            SessionsCommand::Export {
                db: db.clone(),
                id: 1,
                out_dir: out.clone(),
            },
        ] {
            run(&SessionsArgs { command }).expect("runs");
        }
        for f in ["scenario.json", "measurements.jsonl", "truth.csv"] {
            assert!(out.join(f).is_file(), "{f}");
        }
        let again = SessionsCommand::Export {
            db,
            id: 1,
            out_dir: out.clone(),
        };
        let e = run(&SessionsArgs { command: again }).expect_err("not empty");
        assert!(e.to_string().contains("session1"), "{e}");
    }

    #[test]
    fn helpers() {
        assert_eq!(utc(0.0), "1970-01-01 00:00:00Z");
        assert_eq!(utc(1_700_000_000.9), "2023-11-14 22:13:20Z");
        assert_eq!(utc(951_782_400.0), "2000-02-29 00:00:00Z");
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
