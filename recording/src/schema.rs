//! The session file's layout, shared by the writer and the readers: the schema (RECORDING.md),
//! the marks that say a file is a Harrier session file of a version this build reads
//! (`schema_problem`), and every statement the writer runs.

use harrier_core::measurement::MeasKind;
use rusqlite::Connection;

/// `PRAGMA application_id` of a Harrier session file (`"HRR1"`).
pub const APPLICATION_ID: i32 = 0x4852_5231;
/// `PRAGMA user_version`: the schema version this build writes and reads.
pub const SCHEMA_VERSION: i32 = 1;

/// The schema (RECORDING.md). Every statement is idempotent.
pub(super) const SCHEMA: &str = "
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
CREATE TABLE IF NOT EXISTS biases (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL REFERENCES sessions (id),
    t REAL NOT NULL,
    json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS biases_session ON biases (session);
";

/// A new session row.
pub(super) const INSERT_SESSION: &str = "INSERT INTO sessions (started_unix, origin_lat_deg, \
     origin_lon_deg, origin_alt_m, plane_z, estimator, config_json, harrier_version) \
     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)";
/// A scan row.
pub(super) const INSERT_SCAN: &str = "INSERT INTO scans (session, received_unix, t, time_unix, \
     vehicle, sensor, kind, seq, n_detections, json) \
     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)";
/// A vehicle log row.
pub(super) const INSERT_VEHICLE_LOG: &str =
    "INSERT INTO vehicle_log (session, time_unix, vehicle, kind, json) VALUES (?1, ?2, ?3, ?4, ?5)";
/// A row of bias estimates.
pub(super) const INSERT_BIASES: &str = "INSERT INTO biases (session, t, json) VALUES (?1, ?2, ?3)";
/// A detection of a scan.
pub(super) const INSERT_DETECTION: &str =
    "INSERT INTO detections (scan, idx, z0, z1, z2) VALUES (?1, ?2, ?3, ?4, ?5)";
/// A sensor at its first scan (ignored when known).
pub(super) const INSERT_SENSOR: &str = "INSERT OR IGNORE INTO sensors (session, vehicle, sensor, \
     kind, first_received_unix) VALUES (?1, ?2, ?3, ?4, ?5)";
/// A track's estimate after a scan.
pub(super) const INSERT_TRACK: &str = "INSERT INTO tracks (session, t, track, status, x, y, z, vx, \
     vy, vz, cov_json, cov_dims, updated, age, last_update, mode_probabilities) \
     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16)";
/// A truth sample.
pub(super) const INSERT_TRUTH: &str =
    "INSERT INTO truth (session, t, time_unix, targets, json) VALUES (?1, ?2, ?3, ?4, ?5)";
/// An API action.
pub(super) const INSERT_ACTION: &str = "INSERT INTO actions (session, time_unix, method, path, \
     body, status) VALUES (?1, ?2, ?3, ?4, ?5, ?6)";
/// A commit's counts and times added to the session's summary.
pub(super) const UPDATE_SUMMARY: &str = "UPDATE sessions SET scans = scans + ?2, \
     detections = detections + ?3, track_rows = track_rows + ?4, truth_rows = truth_rows + ?5, \
     actions = actions + ?6, dropped = ?7, \
     first_received_unix = coalesce(min(first_received_unix, ?8), ?8, first_received_unix), \
     last_received_unix = coalesce(max(last_received_unix, ?9), ?9, last_received_unix), \
     last_commit_unix = ?10 WHERE id = ?1";
/// The session's end: its time and the final count of dropped records.
pub(super) const END_SESSION: &str =
    "UPDATE sessions SET ended_unix = ?2, dropped = ?3 WHERE id = ?1";

/// Why a file is not a Harrier session file this build can read, or `None` when it is one (or is
/// empty: `allow_empty`, for a file about to be set up).
pub(super) fn schema_problem(
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
pub(super) fn kind_name(k: MeasKind) -> &'static str {
    match k {
        MeasKind::Position => "position",
        MeasKind::RangeBearing => "range_bearing",
        MeasKind::AzEl => "az_el",
        MeasKind::BearingSize => "bearing_size",
    }
}
