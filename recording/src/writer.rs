//! The session recorder: every detection scan, track estimate, truth sample and API action of a
//! live session into a SQLite file (RECORDING.md documents the schema, [`super::schema`] holds
//! it).
//!
//! [`Recorder::record`] never blocks: it `try_send`s onto a bounded queue, and a full queue drops
//! the record and counts it. One writer thread (rusqlite is synchronous) owns the connection; it
//! gathers records into one transaction and commits it at the latest `flush` after the
//! transaction's first record, so a killed process loses at most what was queued plus the last
//! `flush` of writes. The file is in WAL mode with `synchronous = NORMAL`: a commit survives the
//! process being killed (not a power cut), and readers ([`super::reader`]) never block the
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
use rusqlite::{Connection, params};

use super::schema::{
    APPLICATION_ID, END_SESSION, INSERT_ACTION, INSERT_BIASES, INSERT_DETECTION, INSERT_SCAN,
    INSERT_SENSOR, INSERT_SESSION, INSERT_TRACK, INSERT_TRUTH, INSERT_VEHICLE_LOG, SCHEMA,
    SCHEMA_VERSION, UPDATE_SUMMARY, kind_name, schema_problem,
};
use harrier_engine::TrackView;
use harrier_link::clock::unix_now;

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
    /// The registered sensors' bias estimates (live sensor registration) at scan time `t`, as
    /// `GET /api/v1/biases` gives them (JSON).
    Biases {
        /// Scan time.
        t: f64,
        /// The JSON list.
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
    /// Bias estimate rows (live sensor registration).
    pub bias_rows: u64,
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
    bias_rows: AtomicU64,
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
            INSERT_SESSION,
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
            bias_rows: n(&s.bias_rows),
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
    bias_rows: u64,
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
            END_SESSION,
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
            Record::Biases { t, json } => (
                "write a bias row",
                self.conn
                    .prepare_cached(INSERT_BIASES)
                    .and_then(|mut st| st.execute(params![self.session, t, json]).map(|_| ())),
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
            Record::Biases { .. } => b.bias_rows += 1,
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
                s.bias_rows.fetch_add(b.bias_rows, Ordering::Relaxed);
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
