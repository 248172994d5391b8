//! Reading session files offline: [`list`] and [`info`] summarise the sessions of a file
//! written by [`super::writer`] (RECORDING.md). Files are opened read-only, so this works while
//! a server is still writing (WAL mode) and on the file of a killed one.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use harrier_engine::{TrackStatus, TrackView};
use harrier_link::scenario_out::WriteError;
use rusqlite::{Connection, OpenFlags, OptionalExtension};

use super::schema::schema_problem;

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

/// Why a session file or session cannot be read or exported. Messages name the file and session.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// There is no such file.
    #[error(
        "{}: cannot open: no such file (a session file is what `harrier serve` records into with \
         `[recorder] path`, or `harrier demo --record FILE`)",
        path.display()
    )]
    Missing {
        /// The file.
        path: PathBuf,
    },
    /// SQLite cannot open the file.
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
    /// The MCAP file cannot be written.
    #[error("{}: cannot write the MCAP file: {message}", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// A session file opened read-only.
pub(super) struct Db<'a> {
    path: &'a Path,
    conn: Connection,
}

impl<'a> Db<'a> {
    pub(super) fn open(path: &'a Path) -> Result<Self, SessionError> {
        let open = |source| SessionError::Open {
            path: path.to_path_buf(),
            source,
        };
        if !path.is_file() {
            return Err(SessionError::Missing {
                path: path.to_path_buf(),
            });
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

    pub(super) fn sql(&self, source: rusqlite::Error) -> SessionError {
        SessionError::Sqlite {
            path: self.path.to_path_buf(),
            source,
        }
    }

    pub(super) fn malformed(&self, id: i64, message: String) -> SessionError {
        SessionError::Malformed {
            path: self.path.to_path_buf(),
            id,
            message,
        }
    }

    pub(super) fn export_error(&self, id: i64, message: impl Into<String>) -> SessionError {
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

    pub(super) fn info(&self, id: i64) -> Result<SessionInfo, SessionError> {
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
    pub(super) fn rows<T, E: std::fmt::Display>(
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

    /// The `tracks` rows of session `id` in the order written (each scan's changed tracks
    /// together), as the views they were made of (a NULL number, a non-finite one written, is
    /// NaN again).
    pub(super) fn tracks(&self, id: i64) -> Result<Vec<TrackView>, SessionError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT rowid, t, track, status, x, y, z, vx, vy, vz, cov_json, cov_dims, updated, \
                 age, last_update, mode_probabilities FROM tracks WHERE session = ?1 ORDER BY rowid",
            )
            .map_err(|e| self.sql(e))?;
        let mut rows = st.query([id]).map_err(|e| self.sql(e))?;
        let mut out = Vec::new();
        while let Some(r) = rows.next().map_err(|e| self.sql(e))? {
            let row: i64 = r.get(0).map_err(|e| self.sql(e))?;
            let bad = |m: String| self.malformed(id, format!("tracks row {row}: {m}"));
            let num = |i: usize| -> Result<f64, SessionError> {
                r.get::<_, Option<f64>>(i)
                    .map(|v| v.unwrap_or(f64::NAN))
                    .map_err(|e| bad(e.to_string()))
            };
            let text = |i: usize| -> Result<Option<String>, SessionError> {
                r.get::<_, Option<String>>(i)
                    .map_err(|e| bad(e.to_string()))
            };
            let status = match text(3)?.as_deref() {
                Some("tentative") => TrackStatus::Tentative,
                Some("confirmed") => TrackStatus::Confirmed,
                other => return Err(bad(format!("status {other:?}"))),
            };
            let cov: Vec<Vec<Option<f64>>> = serde_json::from_str(&text(10)?.unwrap_or_default())
                .map_err(|e| bad(format!("cov_json: {e}")))?;
            let cov_dims: Vec<usize> = serde_json::from_str(&text(11)?.unwrap_or_default())
                .map_err(|e| bad(format!("cov_dims: {e}")))?;
            let mode_probabilities = match text(15)? {
                Some(m) => serde_json::from_str::<Vec<Option<f64>>>(&m)
                    .map_err(|e| bad(format!("mode_probabilities: {e}")))?
                    .into_iter()
                    .map(|p| p.unwrap_or(f64::NAN))
                    .collect(),
                None => Vec::new(),
            };
            let t = num(1)?;
            out.push(TrackView {
                id: u64::try_from(r.get::<_, i64>(2).map_err(|e| bad(e.to_string()))?)
                    .map_err(|e| bad(format!("track: {e}")))?,
                status,
                t,
                state: [num(4)?, num(5)?, num(6)?, num(7)?, num(8)?, num(9)?],
                cov: cov
                    .into_iter()
                    .map(|row| row.into_iter().map(|c| c.unwrap_or(f64::NAN)).collect())
                    .collect(),
                cov_dims,
                updated: r.get(12).map_err(|e| bad(e.to_string()))?,
                age: r.get(13).map_err(|e| bad(e.to_string()))?,
                last_update: num(14)?,
                mode_probabilities,
                existence: None,
            });
        }
        Ok(out)
    }

    /// The configuration session `id` ran with, as JSON.
    pub(super) fn config_json(&self, id: i64) -> Result<String, SessionError> {
        self.conn
            .query_row(
                "SELECT config_json FROM sessions WHERE id = ?1",
                [id],
                |r| r.get(0),
            )
            .map_err(|e| self.malformed(id, format!("sessions row: config_json: {e}")))
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
