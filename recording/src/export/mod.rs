//! A recorded session exported as a `gcs-scenario/1` directory ([`export`]) that `harrier
//! replay` runs and `score.py` scores, or as an MCAP file of Foxglove's schemas ([`mcap`]).
//!
//! An export puts the session's scans into the session's ENU frame (harrier-link's
//! `scan_in_frame`) and its times relative to the first scan, on the time line the tracker used
//! (`time_unix` when every scan carries it, else the senders' `t`). It is single-target
//! (FORMAT.md) unless the truth has several targets or a scan holds several detections (clutter
//! or several targets), then FORMAT-MULTI.md — as harrier-sim's `record` decides.
//!
//! The export follows the session: `session` reads it and puts its scans in its frame,
//! `times` puts them on the time axis (the time line, the multi-target scan grid), `truth`
//! interpolates the truth at the scan times, and `scenario` builds the scenario's files;
//! `mcap_file` logs the session's scans and tracks as the live Foxglove feed would.

mod mcap_file;
mod scenario;
mod session;
mod times;
mod truth;

use std::path::Path;

use harrier_core::measurement::Geometry;
use harrier_link::geo::LocalFrame;
use harrier_link::scenario_out;

use super::reader::{Db, SessionError};
pub use mcap_file::{McapExported, mcap};
use scenario::{
    Shape, first_fix_prior, measurements_jsonl, scenario_document, scenario_sensors, sensor_ids,
};
use session::{Framed, Recorded, framed};
use times::{ScanTimes, TimeLine};
use truth::{truth_by_target, truth_csv};

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
