//! The session recorder: every detection scan, track estimate, truth sample and API action of a
//! live session into a SQLite file (RECORDING.md documents the schema).
//!
//! [`Recorder::record`] never blocks: it `try_send`s onto a bounded queue, and a full queue drops
//! the record and counts it. One writer thread (rusqlite is synchronous) owns the connection; it
//! gathers records into one transaction and commits it at the latest `flush` after the
//! transaction's first record, so a killed process loses at most what was queued plus the last
//! `flush` of writes. The file is in WAL mode with `synchronous = NORMAL`: a commit survives the
//! process being killed (not a power cut), and readers ([`crate::sessions`]) never block the
//! writer. A failing write is logged (at a bounded rate) and counted, never a panic.
//!
//! One file holds any number of sessions; each [`Recorder::open`] starts a new one.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use harrier_core::detection::{DetectionScan, GeoPoint, TruthSample};
use harrier_core::measurement::MeasKind;
use rusqlite::{Connection, params};

use super::clock::unix_now;
use crate::engine::TrackView;

/// `PRAGMA application_id` of a Harrier session file (`"HRR1"`).
pub const APPLICATION_ID: i32 = 0x4852_5231;
/// `PRAGMA user_version`: the schema version this build writes and reads.
pub const SCHEMA_VERSION: i32 = 1;

/// The schema (RECORDING.md). Every statement is idempotent.
const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS sessions (
    id INTEGER PRIMARY KEY,
    started_unix REAL NOT NULL,
    ended_unix REAL,
    origin_lat_deg REAL NOT NULL,
    origin_lon_deg REAL NOT NULL,
    origin_alt_m REAL NOT NULL,
    plane_z REAL NOT NULL,
    estimator TEXT NOT NULL,
    config_json TEXT NOT NULL,
    harrier_version TEXT NOT NULL,
    scans INTEGER NOT NULL DEFAULT 0,
    detections INTEGER NOT NULL DEFAULT 0,
    track_rows INTEGER NOT NULL DEFAULT 0,
    truth_rows INTEGER NOT NULL DEFAULT 0,
    actions INTEGER NOT NULL DEFAULT 0,
    dropped INTEGER NOT NULL DEFAULT 0,
    first_received_unix REAL,
    last_received_unix REAL,
    last_commit_unix REAL
);
CREATE TABLE IF NOT EXISTS sensors (
    session INTEGER NOT NULL REFERENCES sessions (id),
    vehicle INTEGER NOT NULL,
    sensor TEXT NOT NULL,
    kind TEXT NOT NULL,
    first_received_unix REAL NOT NULL,
    PRIMARY KEY (session, vehicle, sensor)
) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS scans (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL REFERENCES sessions (id),
    received_unix REAL NOT NULL,
    t REAL NOT NULL,
    time_unix REAL,
    vehicle INTEGER NOT NULL,
    sensor TEXT NOT NULL,
    kind TEXT NOT NULL,
    seq INTEGER NOT NULL,
    n_detections INTEGER NOT NULL,
    json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS scans_session ON scans (session);
CREATE TABLE IF NOT EXISTS detections (
    scan INTEGER NOT NULL REFERENCES scans (id),
    idx INTEGER NOT NULL,
    z0 REAL,
    z1 REAL,
    z2 REAL,
    PRIMARY KEY (scan, idx)
) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS tracks (
    session INTEGER NOT NULL REFERENCES sessions (id),
    t REAL NOT NULL,
    track INTEGER NOT NULL,
    status TEXT NOT NULL,
    x REAL, y REAL, z REAL, vx REAL, vy REAL, vz REAL,
    cov_json TEXT NOT NULL,
    cov_dims TEXT NOT NULL,
    updated INTEGER NOT NULL,
    age INTEGER NOT NULL,
    last_update REAL,
    mode_probabilities TEXT
);
CREATE INDEX IF NOT EXISTS tracks_session ON tracks (session, track, t);
CREATE TABLE IF NOT EXISTS truth (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL REFERENCES sessions (id),
    t REAL NOT NULL,
    time_unix REAL,
    targets INTEGER NOT NULL,
    json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS truth_session ON truth (session);
CREATE TABLE IF NOT EXISTS actions (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL REFERENCES sessions (id),
    time_unix REAL NOT NULL,
    method TEXT NOT NULL,
    path TEXT NOT NULL,
    body TEXT NOT NULL,
    status INTEGER NOT NULL
);
CREATE INDEX IF NOT EXISTS actions_session ON actions (session);
CREATE TABLE IF NOT EXISTS vehicle_log (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL REFERENCES sessions (id),
    time_unix REAL NOT NULL,
    vehicle INTEGER,
    kind TEXT NOT NULL,
    json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS vehicle_log_session ON vehicle_log (session);
";

const INSERT_SCAN: &str = "INSERT INTO scans (session, received_unix, t, time_unix, vehicle, \
     sensor, kind, seq, n_detections, json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)";
const INSERT_VEHICLE_LOG: &str =
    "INSERT INTO vehicle_log (session, time_unix, vehicle, kind, json) VALUES (?1, ?2, ?3, ?4, ?5)";
const INSERT_DETECTION: &str =
    "INSERT INTO detections (scan, idx, z0, z1, z2) VALUES (?1, ?2, ?3, ?4, ?5)";
const INSERT_SENSOR: &str = "INSERT OR IGNORE INTO sensors (session, vehicle, sensor, kind, \
     first_received_unix) VALUES (?1, ?2, ?3, ?4, ?5)";
const INSERT_TRACK: &str = "INSERT INTO tracks (session, t, track, status, x, y, z, vx, vy, vz, \
     cov_json, cov_dims, updated, age, last_update, mode_probabilities) \
     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16)";
const INSERT_TRUTH: &str =
    "INSERT INTO truth (session, t, time_unix, targets, json) VALUES (?1, ?2, ?3, ?4, ?5)";
const INSERT_ACTION: &str = "INSERT INTO actions (session, time_unix, method, path, body, status) \
     VALUES (?1, ?2, ?3, ?4, ?5, ?6)";
const UPDATE_SUMMARY: &str = "UPDATE sessions SET scans = scans + ?2, \
     detections = detections + ?3, track_rows = track_rows + ?4, truth_rows = truth_rows + ?5, \
     actions = actions + ?6, dropped = ?7, \
     first_received_unix = coalesce(min(first_received_unix, ?8), ?8, first_received_unix), \
     last_received_unix = coalesce(max(last_received_unix, ?9), ?9, last_received_unix), \
     last_commit_unix = ?10 WHERE id = ?1";

/// What the session is: written once into its `sessions` row.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionMeta {
    /// When the service started (UNIX s).
    pub started_unix: f64,
    /// WGS-84 origin of the server's ENU frame.
    pub origin: GeoPoint,
    /// Up coordinate (m) of the ground plane.
    pub plane_z: f64,
    /// Track filter at the start (a change at run time is an action).
    pub estimator: String,
    /// The whole configuration, as JSON.
    pub config_json: String,
}

/// One thing to record.
#[derive(Debug, Clone)]
pub enum Record {
    /// A valid detection scan as received from Zenoh (before frame conversion), with the server's
    /// receive time (UNIX s).
    Scan {
        /// When the server received it (UNIX s, the server's clock).
        received_unix: f64,
        /// The scan, as published.
        scan: DetectionScan,
    },
    /// A truth sample of the simulator (`harrier/v1/sim/truth`).
    Truth(TruthSample),
    /// The estimates of the tracks a processed scan changed, at scan time `t` (the tracker's time
    /// line: UNIX time when scans carry `time_unix`).
    Tracks {
        /// Scan time.
        t: f64,
        /// The changed tracks.
        tracks: Vec<TrackView>,
    },
    /// An API action (mutating request).
    Action {
        /// When it was answered (UNIX s).
        time_unix: f64,
        /// HTTP method.
        method: String,
        /// Request path.
        path: String,
        /// Request body.
        body: String,
        /// Response status.
        status: u16,
    },
    /// What the MAVLink link and the guidance did: a vehicle's telemetry (1 Hz), a link event,
    /// a command's outcome, an assignment's change.
    Vehicle {
        /// When (UNIX s).
        time_unix: f64,
        /// The vehicle, when the row is about one.
        vehicle: Option<u8>,
        /// `telemetry`, `event`, `command` or `assignment`.
        kind: &'static str,
        /// The API's JSON of it (`VehicleLinkView`, `LinkEvent`, `CommandOutcome`,
        /// `AssignmentView`).
        json: String,
    },
}

/// What the recorder has done so far. Row counts are committed rows.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct RecorderStats {
    /// The session's id in the file.
    pub session: i64,
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
    /// Vehicle log rows (telemetry, link events, commands, assignments).
    pub vehicle_rows: u64,
    /// Records dropped because the queue was full (or the writer had stopped).
    pub dropped: u64,
    /// Transactions committed.
    pub commits: u64,
    /// Failed writes and commits (logged).
    pub errors: u64,
    /// Time of the last commit (UNIX s).
    pub last_commit_unix: Option<f64>,
}

/// Why the recorder could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    /// The file cannot be opened, set up or written.
    #[error("session file {path}: {source}")]
    Sqlite {
        /// The file.
        path: PathBuf,
        /// SQLite's error.
        source: rusqlite::Error,
    },
    /// The file is not a Harrier session file, or of a newer schema.
    #[error("session file {path}: {message}")]
    Schema {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The directory or the writer thread cannot be created.
    #[error("session file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The writer thread panicked.
    #[error("session file {path}: the writer thread panicked")]
    Panicked {
        /// The file.
        path: PathBuf,
    },
}

/// The counters the writer and the senders share.
#[derive(Debug, Default)]
struct Shared {
    scans: AtomicU64,
    detections: AtomicU64,
    track_rows: AtomicU64,
    truth_rows: AtomicU64,
    actions: AtomicU64,
    vehicle_rows: AtomicU64,
    dropped: AtomicU64,
    commits: AtomicU64,
    errors: AtomicU64,
    /// `f64` bits; 0: never.
    last_commit: AtomicU64,
}

#[derive(Debug)]
struct Inner {
    path: PathBuf,
    session: i64,
    /// `None` asks the writer to stop.
    tx: SyncSender<Option<Record>>,
    shared: Arc<Shared>,
    writer: Mutex<Option<JoinHandle<rusqlite::Result<()>>>>,
}

/// The live writer of one session. Cheap to clone (every clone feeds the same writer thread).
#[derive(Debug, Clone)]
pub struct Recorder {
    inner: Arc<Inner>,
}

/// Why a file is not a Harrier session file this build can read, or `None` when it is one (or is
/// empty: `allow_empty`, for a file about to be set up).
pub(crate) fn schema_problem(
    conn: &Connection,
    allow_empty: bool,
) -> rusqlite::Result<Option<String>> {
    let app: i32 = conn.query_row("PRAGMA application_id", [], |r| r.get(0))?;
    let version: i32 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
    let tables: i64 = conn.query_row("SELECT count(*) FROM sqlite_schema", [], |r| r.get(0))?;
    Ok(if app == 0 && tables == 0 {
        (!allow_empty).then(|| "empty file: no session recorded yet".to_owned())
    } else if app != APPLICATION_ID {
        Some(format!(
            "not a Harrier session file (application_id {app:#x}, expected {APPLICATION_ID:#x})"
        ))
    } else if version > SCHEMA_VERSION {
        Some(format!(
            "schema version {version} is newer than this harrier's ({SCHEMA_VERSION})"
        ))
    } else {
        None
    })
}

/// Name of a measurement kind, as in the JSON payloads.
pub(crate) fn kind_name(k: MeasKind) -> &'static str {
    match k {
        MeasKind::Position => "position",
        MeasKind::RangeBearing => "range_bearing",
        MeasKind::AzEl => "az_el",
        MeasKind::BearingSize => "bearing_size",
    }
}

/// JSON text of the small vectors of a track row (plain numbers: serialisation cannot fail).
fn json<T: serde::Serialize + ?Sized>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// An unsigned counter as SQLite's signed integer (saturating; no counter gets near 2⁶³).
fn int(v: u64) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

impl Recorder {
    /// Opens (creates) the SQLite file `path` (and its directory), sets WAL mode, creates the
    /// schema if missing, inserts a session row and starts the writer thread. `flush` is the
    /// longest time between a record's write and its commit (at least 1 ms); `queue` the number
    /// of records waiting for the writer before new ones are dropped.
    pub fn open(
        path: &Path,
        meta: &SessionMeta,
        flush: Duration,
        queue: usize,
    ) -> Result<Recorder, RecorderError> {
        let sql = |source| RecorderError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let io = |source| RecorderError::Io {
            path: path.to_path_buf(),
            source,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        let conn = Connection::open(path).map_err(sql)?;
        conn.busy_timeout(Duration::from_secs(5)).map_err(sql)?;
        if let Some(message) = schema_problem(&conn, true).map_err(sql)? {
            return Err(RecorderError::Schema {
                path: path.to_path_buf(),
                message,
            });
        }
        let mode: String = conn
            .query_row("PRAGMA journal_mode = WAL", [], |r| r.get(0))
            .map_err(sql)?;
        if !mode.eq_ignore_ascii_case("wal") {
            return Err(RecorderError::Schema {
                path: path.to_path_buf(),
                message: format!("cannot switch to WAL mode (journal_mode is {mode})"),
            });
        }
        conn.execute_batch(&format!(
            "PRAGMA synchronous = NORMAL;
             BEGIN IMMEDIATE;
             {SCHEMA}
             PRAGMA application_id = {APPLICATION_ID};
             PRAGMA user_version = {SCHEMA_VERSION};
             COMMIT;"
        ))
        .map_err(sql)?;
        conn.execute(
            "INSERT INTO sessions (started_unix, origin_lat_deg, origin_lon_deg, origin_alt_m, \
             plane_z, estimator, config_json, harrier_version) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            params![
                meta.started_unix,
                meta.origin.lat_deg,
                meta.origin.lon_deg,
                meta.origin.alt_m,
                meta.plane_z,
                meta.estimator,
                meta.config_json,
                env!("CARGO_PKG_VERSION"),
            ],
        )
        .map_err(sql)?;
        let session = conn.last_insert_rowid();
        let (tx, rx) = mpsc::sync_channel(queue.max(1));
        let shared = Arc::new(Shared::default());
        let writer = Writer {
            conn,
            session,
            flush: flush.max(Duration::from_millis(1)),
            shared: Arc::clone(&shared),
            batch: Batch::default(),
            batch_started: None,
            sensors: HashSet::new(),
            last_warning: None,
            suppressed: 0,
        };
        let handle = std::thread::Builder::new()
            .name("harrier-recorder".into())
            .spawn(move || writer.run(&rx))
            .map_err(io)?;
        Ok(Recorder {
            inner: Arc::new(Inner {
                path: path.to_path_buf(),
                session,
                tx,
                shared,
                writer: Mutex::new(Some(handle)),
            }),
        })
    }

    /// The session's id in the file (`sessions.id`).
    pub fn session_id(&self) -> i64 {
        self.inner.session
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.inner.path
    }

    /// Queues `r` for the writer. Never blocks: when the queue is full, or the recorder is
    /// closed, the record is dropped and counted.
    pub fn record(&self, r: Record) {
        match self.inner.tx.try_send(Some(r)) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.inner.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> RecorderStats {
        let s = &self.inner.shared;
        let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let last = n(&s.last_commit);
        RecorderStats {
            session: self.inner.session,
            scans: n(&s.scans),
            detections: n(&s.detections),
            track_rows: n(&s.track_rows),
            truth_rows: n(&s.truth_rows),
            actions: n(&s.actions),
            vehicle_rows: n(&s.vehicle_rows),
            dropped: n(&s.dropped),
            commits: n(&s.commits),
            errors: n(&s.errors),
            last_commit_unix: (last != 0).then(|| f64::from_bits(last)),
        }
    }

    /// Writes and commits what is queued, marks the session ended and joins the writer thread.
    /// Idempotent: any clone may call it, later calls just return the counters; records sent
    /// after it are dropped (and counted). Blocks while the writer drains the queue.
    pub fn close(&self) -> Result<RecorderStats, RecorderError> {
        let handle = match self.inner.writer.lock() {
            Ok(mut h) => h.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        };
        if let Some(handle) = handle {
            // The writer only stops on this message (or when every sender is gone), so it is
            // still receiving: `send` waits for room in the queue at most.
            let _ = self.inner.tx.send(None);
            let path = self.inner.path.clone();
            match handle.join() {
                Ok(Ok(())) => {}
                Ok(Err(source)) => return Err(RecorderError::Sqlite { path, source }),
                Err(_) => return Err(RecorderError::Panicked { path }),
            }
        }
        Ok(self.stats())
    }
}

/// Rows of the open transaction.
#[derive(Debug, Default)]
struct Batch {
    scans: u64,
    detections: u64,
    track_rows: u64,
    truth_rows: u64,
    actions: u64,
    vehicle_rows: u64,
    first_received: Option<f64>,
    last_received: Option<f64>,
}

/// The writer thread's state.
struct Writer {
    conn: Connection,
    session: i64,
    flush: Duration,
    shared: Arc<Shared>,
    batch: Batch,
    /// When the open transaction began (`None`: no transaction).
    batch_started: Option<Instant>,
    /// (vehicle, sensor) pairs already in `sensors`.
    sensors: HashSet<(u8, String)>,
    last_warning: Option<Instant>,
    suppressed: u64,
}

/// Shortest interval between two logged write errors.
const WARN_EVERY: Duration = Duration::from_secs(5);

impl Writer {
    fn run(mut self, rx: &Receiver<Option<Record>>) -> rusqlite::Result<()> {
        loop {
            let msg = match self.batch_started {
                None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
                Some(t0) => rx.recv_timeout(self.flush.saturating_sub(t0.elapsed())),
            };
            match msg {
                Ok(Some(r)) => self.write(&r),
                Ok(None) | Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {}
            }
            if self
                .batch_started
                .is_some_and(|t0| t0.elapsed() >= self.flush)
            {
                self.commit();
            }
        }
        self.commit();
        self.conn.execute(
            "UPDATE sessions SET ended_unix = ?2, dropped = ?3 WHERE id = ?1",
            params![
                self.session,
                unix_now(),
                int(self.shared.dropped.load(Ordering::Relaxed))
            ],
        )?;
        Ok(())
    }

    /// Logs a failed write (at most one line per [`WARN_EVERY`]) and counts it.
    fn failed(&mut self, what: &str, e: &rusqlite::Error) {
        self.shared.errors.fetch_add(1, Ordering::Relaxed);
        if self.last_warning.is_some_and(|t| t.elapsed() < WARN_EVERY) {
            self.suppressed += 1;
            return;
        }
        tracing::warn!(
            session = self.session,
            suppressed = self.suppressed,
            "recorder: {what}: {e}"
        );
        self.last_warning = Some(Instant::now());
        self.suppressed = 0;
    }

    fn write(&mut self, r: &Record) {
        if self.batch_started.is_none() {
            if let Err(e) = self.conn.execute_batch("BEGIN") {
                self.failed("begin a transaction", &e);
                return;
            }
            self.batch_started = Some(Instant::now());
        }
        let (what, result) = match r {
            Record::Scan {
                received_unix,
                scan,
            } => (
                "write a scan",
                self.atomic(|w| w.scan(*received_unix, scan)),
            ),
            Record::Truth(s) => ("write a truth sample", self.truth(s)),
            Record::Tracks { t, tracks } => ("write tracks", self.atomic(|w| w.tracks(*t, tracks))),
            Record::Action {
                time_unix,
                method,
                path,
                body,
                status,
            } => (
                "write an action",
                self.conn.prepare_cached(INSERT_ACTION).and_then(|mut st| {
                    st.execute(params![self.session, time_unix, method, path, body, status])
                        .map(|_| ())
                }),
            ),
            Record::Vehicle {
                time_unix,
                vehicle,
                kind,
                json,
            } => (
                "write a vehicle log row",
                self.conn
                    .prepare_cached(INSERT_VEHICLE_LOG)
                    .and_then(|mut st| {
                        st.execute(params![self.session, time_unix, vehicle, kind, json])
                            .map(|_| ())
                    }),
            ),
        };
        match result {
            Ok(()) => self.count(r),
            Err(e) => {
                self.failed(what, &e);
                if self.conn.is_autocommit() {
                    // SQLite rolled the whole transaction back (I/O error, full disk): its rows
                    // are gone, start afresh.
                    self.batch = Batch::default();
                    self.batch_started = None;
                    self.sensors.clear();
                }
            }
        }
    }

    /// Runs `f` as one unit of the open transaction: all its rows or none.
    fn atomic(&mut self, f: impl FnOnce(&Self) -> rusqlite::Result<()>) -> rusqlite::Result<()> {
        self.conn.prepare_cached("SAVEPOINT record")?.execute([])?;
        let result = f(self);
        if result.is_err() && !self.conn.is_autocommit() {
            if let Err(e) = self
                .conn
                .execute_batch("ROLLBACK TO record; RELEASE record")
            {
                self.failed("roll back a record", &e);
            }
            return result;
        }
        result?;
        self.conn.prepare_cached("RELEASE record")?.execute([])?;
        Ok(())
    }

    /// Counts the rows of `r`, written.
    fn count(&mut self, r: &Record) {
        let b = &mut self.batch;
        match r {
            Record::Scan {
                received_unix,
                scan,
            } => {
                let received = *received_unix;
                b.scans += 1;
                b.detections += scan.detections.len() as u64;
                b.first_received = Some(b.first_received.map_or(received, |f| f.min(received)));
                b.last_received = Some(b.last_received.map_or(received, |l| l.max(received)));
                self.sensors.insert((scan.vehicle, scan.sensor.clone()));
            }
            Record::Truth(_) => b.truth_rows += 1,
            Record::Tracks { tracks, .. } => b.track_rows += tracks.len() as u64,
            Record::Action { .. } => b.actions += 1,
            Record::Vehicle { .. } => b.vehicle_rows += 1,
        }
    }

    fn scan(&self, received: f64, scan: &DetectionScan) -> rusqlite::Result<()> {
        let kind = kind_name(scan.kind);
        if !self.sensors.contains(&(scan.vehicle, scan.sensor.clone())) {
            self.conn.prepare_cached(INSERT_SENSOR)?.execute(params![
                self.session,
                scan.vehicle,
                scan.sensor,
                kind,
                received
            ])?;
        }
        self.conn.prepare_cached(INSERT_SCAN)?.execute(params![
            self.session,
            received,
            scan.t,
            scan.time_unix,
            scan.vehicle,
            scan.sensor,
            kind,
            int(scan.seq),
            int(scan.detections.len() as u64),
            scan.to_json(),
        ])?;
        let id = self.conn.last_insert_rowid();
        let mut st = self.conn.prepare_cached(INSERT_DETECTION)?;
        for (i, d) in scan.detections.iter().enumerate() {
            let z = |k: usize| d.z.get(k).copied();
            st.execute(params![id, int(i as u64), z(0), z(1), z(2)])?;
        }
        Ok(())
    }

    fn truth(&self, s: &TruthSample) -> rusqlite::Result<()> {
        self.conn.prepare_cached(INSERT_TRUTH)?.execute(params![
            self.session,
            s.t,
            s.time_unix,
            int(s.targets.len() as u64),
            s.to_json(),
        ])?;
        Ok(())
    }

    fn tracks(&self, t: f64, tracks: &[TrackView]) -> rusqlite::Result<()> {
        let mut st = self.conn.prepare_cached(INSERT_TRACK)?;
        for k in tracks {
            let s = &k.state;
            st.execute(params![
                self.session,
                t,
                int(k.id),
                k.status.as_str(),
                s[0],
                s[1],
                s[2],
                s[3],
                s[4],
                s[5],
                json(&k.cov),
                json(&k.cov_dims),
                k.updated,
                k.age,
                k.last_update,
                (!k.mode_probabilities.is_empty()).then(|| json(&k.mode_probabilities)),
            ])?;
        }
        Ok(())
    }

    /// Commits the open transaction with the session's summary; on failure rolls back (its rows
    /// are lost and counted as one error).
    fn commit(&mut self) {
        if self.batch_started.take().is_none() {
            return;
        }
        let b = std::mem::take(&mut self.batch);
        let now = unix_now();
        let result = self
            .conn
            .prepare_cached(UPDATE_SUMMARY)
            .and_then(|mut st| {
                st.execute(params![
                    self.session,
                    int(b.scans),
                    int(b.detections),
                    int(b.track_rows),
                    int(b.truth_rows),
                    int(b.actions),
                    int(self.shared.dropped.load(Ordering::Relaxed)),
                    b.first_received,
                    b.last_received,
                    now,
                ])
            })
            .and_then(|_| self.conn.execute_batch("COMMIT"));
        match result {
            Ok(()) => {
                let s = &self.shared;
                s.scans.fetch_add(b.scans, Ordering::Relaxed);
                s.detections.fetch_add(b.detections, Ordering::Relaxed);
                s.track_rows.fetch_add(b.track_rows, Ordering::Relaxed);
                s.truth_rows.fetch_add(b.truth_rows, Ordering::Relaxed);
                s.actions.fetch_add(b.actions, Ordering::Relaxed);
                s.vehicle_rows.fetch_add(b.vehicle_rows, Ordering::Relaxed);
                s.commits.fetch_add(1, Ordering::Relaxed);
                s.last_commit.store(now.to_bits(), Ordering::Relaxed);
            }
            Err(e) => {
                self.failed("commit", &e);
                if !self.conn.is_autocommit() {
                    if let Err(e) = self.conn.execute_batch("ROLLBACK") {
                        self.failed("roll back", &e);
                    }
                }
                self.sensors.clear();
            }
        }
    }
}

/// Records for the tests of this module and of [`crate::sessions`].
#[cfg(test)]
pub(crate) mod testing {
    use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, PlatformPose, TargetTruth};
    use harrier_core::detection::{TRUTH_SCHEMA, TruthSample};

    use super::*;

    /// PX4 SITL's home, the session's origin.
    pub(crate) const HOME: GeoPoint = crate::live::config::DEFAULT_ORIGIN;
    /// UNIX time of the tests' scan time 0.
    pub(crate) const T0_UNIX: f64 = 1_795_430_400.25;

    /// The session of a server at [`HOME`] on the ground plane z = 0.
    pub(crate) fn meta(estimator: &str) -> SessionMeta {
        SessionMeta {
            started_unix: T0_UNIX - 5.0,
            origin: HOME,
            plane_z: 0.0,
            estimator: estimator.into(),
            config_json: json(&serde_json::json!({"tracker": {
                "scan_period_s": 1.0,
                "motion": {"accel_std": 0.5, "models": [{"name": "CV", "type": "CV"}]}
            }})),
        }
    }

    /// A `position` scan (10 m noise) of `vehicle`'s `cam` at time `t` (UNIX `T0_UNIX + t`)
    /// from a platform at `pos`, with detections `z`.
    pub(crate) fn scan(vehicle: u8, seq: u64, t: f64, pos: [f64; 3], z: &[[f64; 2]]) -> Record {
        let frame = harrier_link::geo::LocalFrame::new(HOME);
        Record::Scan {
            received_unix: T0_UNIX + t + 0.01,
            scan: DetectionScan {
                schema: DETECTIONS_SCHEMA.into(),
                t,
                time_unix: Some(T0_UNIX + t),
                vehicle,
                seq,
                sensor: "cam".into(),
                kind: MeasKind::Position,
                origin: HOME,
                platform: PlatformPose {
                    pos,
                    vel: [1.0, 0.0, 0.0],
                    attitude: [0.0; 3],
                    geodetic: Some(frame.from_enu(&nalgebra::Vector3::from(pos))),
                },
                noise_std: vec![10.0, 10.0],
                detections: z.iter().map(|z| Detection { z: z.to_vec() }).collect(),
            },
        }
    }

    /// Truth at `t` of targets `(id, state)`.
    pub(crate) fn truth(t: f64, targets: &[(&str, [f64; 6])]) -> Record {
        Record::Truth(TruthSample {
            schema: TRUTH_SCHEMA.into(),
            t,
            time_unix: Some(T0_UNIX + t),
            origin: HOME,
            targets: targets
                .iter()
                .map(|(id, state)| TargetTruth {
                    id: (*id).into(),
                    state: *state,
                    mode: "CV".into(),
                })
                .collect(),
        })
    }

    /// A confirmed planar track `id` at `state`.
    pub(crate) fn track(id: u64, t: f64, state: [f64; 6]) -> TrackView {
        TrackView {
            id,
            status: crate::engine::TrackStatus::Confirmed,
            t,
            state,
            cov: vec![vec![4.0, 0.0, 0.0, 0.0]; 4],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 3,
            last_update: t,
            mode_probabilities: vec![0.9, 0.1],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testing::*;
    use super::*;

    fn count(conn: &Connection, sql: &str) -> i64 {
        conn.query_row(sql, [], |r| r.get(0)).expect(sql)
    }

    fn reader(path: &Path) -> Connection {
        Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .expect("open read-only")
    }

    #[test]
    fn records_land_in_their_tables_and_a_second_open_is_a_new_session() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("sub/rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(50), 64).expect("open");
        assert_eq!(r.session_id(), 1);
        let clone = r.clone();
        clone.record(scan(
            1,
            0,
            0.0,
            [0.0, 0.0, 100.0],
            &[[10.0, 20.0], [30.0, -40.0]],
        ));
        r.record(truth(0.0, &[("T0", [10.0, 20.0, 0.0, 1.0, 0.0, 0.0])]));
        r.record(Record::Tracks {
            t: T0_UNIX,
            tracks: vec![
                track(1, T0_UNIX, [10.0, 20.0, 0.0, 1.0, 0.0, 0.0]),
                track(2, T0_UNIX, [30.0, -40.0, 0.0, 0.0, 0.0, 0.0]),
            ],
        });
        r.record(Record::Action {
            time_unix: T0_UNIX + 1.0,
            method: "POST".into(),
            path: "/api/v1/estimator".into(),
            body: r#"{"name":"imm"}"#.into(),
            status: 200,
        });
        let stats = clone.close().expect("close");
        assert_eq!(r.close().expect("idempotent"), stats);
        assert_eq!(
            (
                stats.scans,
                stats.detections,
                stats.track_rows,
                stats.truth_rows,
                stats.actions
            ),
            (1, 2, 2, 1, 1),
            "{stats:?}"
        );
        assert_eq!((stats.dropped, stats.errors), (0, 0));
        assert!(stats.commits >= 1 && stats.last_commit_unix.is_some());
        r.record(scan(1, 1, 1.0, [0.0; 3], &[]));
        assert_eq!(
            r.stats().dropped,
            1,
            "a record after close is dropped and counted"
        );

        let c = reader(&path);
        assert_eq!(count(&c, "SELECT count(*) FROM detections"), 2);
        assert_eq!(
            count(
                &c,
                "SELECT count(*) FROM tracks WHERE mode_probabilities = '[0.9,0.1]'"
            ),
            2
        );
        let (scans, ended, kind): (i64, Option<f64>, String) = c
            .query_row(
                "SELECT s.scans, s.ended_unix, k.kind FROM sessions s JOIN scans k \
                 ON k.session = s.id WHERE s.id = 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .expect("session row");
        assert_eq!(
            (scans, ended.is_some(), kind.as_str()),
            (1, true, "position")
        );
        let z1: f64 = c
            .query_row("SELECT z1 FROM detections WHERE idx = 1", [], |r| r.get(0))
            .expect("z1");
        assert_eq!(z1, -40.0);
        drop(c);

        let again =
            Recorder::open(&path, &meta("imm"), Duration::from_millis(50), 64).expect("reopen");
        assert_eq!(again.session_id(), 2);
        again.close().expect("close");
    }

    #[test]
    fn a_record_is_committed_within_the_flush_interval_without_close() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(50), 64).expect("open");
        let sent = Instant::now();
        r.record(scan(1, 0, 0.0, [0.0; 3], &[[1.0, 2.0]]));
        let c = reader(&path);
        while count(&c, "SELECT count(*) FROM scans") == 0 {
            assert!(
                sent.elapsed() < Duration::from_secs(5),
                "no commit within 5 s"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        let lag = sent.elapsed();
        assert!(lag < Duration::from_secs(1), "committed after {lag:?}");
        let (scans, last): (i64, Option<f64>) = c
            .query_row(
                "SELECT scans, last_received_unix FROM sessions WHERE id = 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .expect("summary");
        assert_eq!((scans, last), (1, Some(T0_UNIX + 0.01)));
        assert_eq!(r.stats().scans, 1);
        r.close().expect("close");
    }

    #[test]
    fn a_full_queue_drops_and_counts_and_never_blocks() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 4).expect("open");
        // Another connection holds the write lock: the writer waits on its first insert.
        let blocker = Connection::open(&path).expect("open");
        blocker.execute_batch("BEGIN IMMEDIATE").expect("lock");
        let n = 100;
        let start = Instant::now();
        for i in 0..n {
            r.record(scan(1, i, i as f64, [0.0; 3], &[]));
        }
        let took = start.elapsed();
        blocker.execute_batch("COMMIT").expect("unlock");
        let s = r.close().expect("close");
        assert!(
            took < Duration::from_millis(500),
            "record blocked: {took:?}"
        );
        assert_eq!(s.scans + s.dropped, n, "{s:?}");
        assert!(s.dropped >= n - 5, "queue of 4 (+1 in hand) but {s:?}");
        let dropped: i64 = reader(&path)
            .query_row("SELECT dropped FROM sessions WHERE id = 1", [], |r| {
                r.get(0)
            })
            .expect("dropped");
        assert_eq!(dropped as u64, s.dropped);
    }

    #[test]
    fn a_record_that_fails_half_way_leaves_no_row_and_is_counted() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 64).expect("open");
        // A real SQLite trigger refuses one detection: its scan fails after its scan row.
        Connection::open(&path)
            .and_then(|c| {
                c.execute_batch(
                    "CREATE TRIGGER refuse BEFORE INSERT ON detections WHEN NEW.z0 = 666 \
                     BEGIN SELECT RAISE(ABORT, 'refused by the test'); END;",
                )
            })
            .expect("trigger");
        r.record(scan(1, 0, 0.0, [0.0; 3], &[[1.0, 2.0]]));
        r.record(scan(2, 0, 0.0, [0.0; 3], &[[1.0, 2.0], [666.0, 0.0]]));
        r.record(scan(1, 1, 1.0, [0.0; 3], &[[3.0, 4.0]]));
        let s = r.close().expect("close");
        assert_eq!((s.scans, s.detections, s.errors), (2, 2, 1), "{s:?}");
        let c = reader(&path);
        assert_eq!(count(&c, "SELECT count(*) FROM scans"), 2);
        assert_eq!(count(&c, "SELECT count(*) FROM detections"), 2);
        assert_eq!(count(&c, "SELECT count(*) FROM scans WHERE vehicle = 2"), 0);
        assert_eq!(
            count(&c, "SELECT count(*) FROM sensors"),
            1,
            "vehicle 2's sensor row went with its scan"
        );
        assert_eq!(count(&c, "SELECT scans FROM sessions"), 2);
    }

    #[test]
    fn other_files_are_refused_with_their_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let other = dir.path().join("other.sqlite");
        Connection::open(&other)
            .and_then(|c| c.execute_batch("CREATE TABLE t (x)"))
            .expect("other db");
        let e = Recorder::open(&other, &meta("ekf"), Duration::from_millis(50), 4)
            .expect_err("not ours");
        assert!(
            e.to_string().contains("other.sqlite") && e.to_string().contains("not a Harrier"),
            "{e}"
        );
        let text = dir.path().join("notes.txt");
        std::fs::write(
            &text,
            "not a database, just some text that is long enough ".repeat(20),
        )
        .expect("write");
        let e = Recorder::open(&text, &meta("ekf"), Duration::from_millis(50), 4)
            .expect_err("not sqlite");
        assert!(e.to_string().contains("notes.txt"), "{e}");
    }

    /// Writes `n` scans (one detection each) and `n` track rows as fast as they can be queued;
    /// returns the seconds from the first record to the end of `close`.
    fn burst(n: u64) -> (f64, RecorderStats) {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let queue = usize::try_from(2 * n).expect("queue");
        let r =
            Recorder::open(&path, &meta("ekf"), Duration::from_millis(200), queue).expect("open");
        let start = Instant::now();
        for i in 0..n {
            let t = i as f64 * 0.002;
            let v = (i % 10) as u8 + 1;
            r.record(scan(v, i / 10, t, [0.0, 0.0, 100.0], &[[t, 2.0 * t]]));
            r.record(Record::Tracks {
                t: T0_UNIX + t,
                tracks: vec![track(1, T0_UNIX + t, [t, 2.0 * t, 0.0, 1.0, 2.0, 0.0])],
            });
        }
        let s = r.close().expect("close");
        (start.elapsed().as_secs_f64(), s)
    }

    #[test]
    fn the_writer_keeps_up_with_ten_vehicles_at_50_hz() {
        // 5000 scans = 10 s of 10 vehicles × 50 Hz, with a detection and a track row each.
        let (secs, s) = burst(5000);
        let rows = s.scans + s.detections + s.track_rows;
        eprintln!(
            "recorder: {} scans + {} detections + {} track rows in {secs:.3} s: {:.0} scans/s, \
             {:.0} rows/s, {} commits",
            s.scans,
            s.detections,
            s.track_rows,
            s.scans as f64 / secs,
            rows as f64 / secs,
            s.commits
        );
        assert_eq!((s.scans, s.dropped, s.errors), (5000, 0, 0), "{s:?}");
        assert!(
            s.scans as f64 / secs > 500.0,
            "only {:.0} scans/s",
            s.scans as f64 / secs
        );
    }

    /// `cargo test -p harrier-server --lib bench_recorder -- --ignored --nocapture`
    #[test]
    #[ignore = "benchmark"]
    fn bench_recorder_burst() {
        let (secs, s) = burst(50_000);
        let rows = s.scans + s.detections + s.track_rows;
        eprintln!(
            "recorder burst: {rows} rows in {secs:.2} s = {:.0} rows/s ({:.0} scans/s with a \
             detection and a track row each), {} commits",
            rows as f64 / secs,
            s.scans as f64 / secs,
            s.commits
        );
    }
}
