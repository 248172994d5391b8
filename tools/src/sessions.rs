//! `harrier sessions`: its arguments and [`run`], which prints what [`harrier_recording::reader`] and
//! [`harrier_recording::export`] return.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use harrier_recording::export::{Exported, McapExported, export, mcap};
use harrier_recording::reader::{SessionInfo, info, list};

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
    /// Export one session: as a gcs-scenario/1 directory (FORMAT-MULTI.md when the truth has
    /// several targets or a scan several detections), for `harrier replay` and `score.py`; or, with
    /// `--format mcap`, as an MCAP file of the live Foxglove feed's topics (docs/foxglove.md), for
    /// Foxglove, Lichtblick and the `mcap` tools.
    Export {
        /// The session file.
        db: PathBuf,
        /// Session id (`harrier sessions list`).
        id: i64,
        /// Output: a directory (scenario: must not exist, or be empty) or a file (mcap: must not
        /// exist). Written atomically.
        out: PathBuf,
        /// What to write.
        #[arg(long, value_enum, default_value_t = ExportFormat::Scenario)]
        format: ExportFormat,
    },
}

/// What `harrier sessions export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// A gcs-scenario/1 directory (FORMAT.md, FORMAT-MULTI.md).
    Scenario,
    /// An MCAP file of Foxglove's schemas (`foxglove.SceneUpdate`, `foxglove.LocationFix`,
    /// `foxglove.FrameTransforms`).
    Mcap,
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

/// The summary of `harrier sessions info`.
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

/// The table of `harrier sessions list`: a line per session.
fn list_lines(db: &Path, all: &[SessionInfo]) -> Vec<String> {
    if all.is_empty() {
        return vec![format!("{}: no sessions", db.display())];
    }
    let mut lines = vec![format!(
        "{:>4}  {:<20}  {:>9}  {:<8}  {:>8}  {:>10}  {:>8}  {:>6}  vehicles",
        "id", "started (UTC)", "duration", "engine", "scans", "detections", "tracks", "truth"
    )];
    for s in all {
        let duration = s
            .ended_unix
            .or(s.last_commit_unix)
            .map_or_else(|| "-".into(), |e| format!("{:.0} s", e - s.started_unix));
        let open = if s.ended_unix.is_none() {
            " (open)"
        } else {
            ""
        };
        lines.push(format!(
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
        ));
    }
    lines
}

/// What `harrier sessions export` wrote into `out_dir`.
fn export_lines(out_dir: &Path, e: &Exported) -> Vec<String> {
    let format = if e.multi {
        "gcs-scenario/1 + FORMAT-MULTI"
    } else {
        "gcs-scenario/1, single target"
    };
    let mut lines = vec![format!(
        "wrote {} ({format}): scenario.json, measurements.jsonl ({} lines from {} scans), {}",
        out_dir.display(),
        e.lines,
        e.scans,
        e.truth_csv.as_ref().map_or_else(
            || "no truth.csv (no truth recorded)".to_owned(),
            |_| format!("truth.csv ({} rows)", e.truth_rows)
        )
    )];
    if e.multi {
        lines.push(format!(
            "  scan times snapped to the FORMAT-MULTI grid, by at most {:.4} s",
            e.max_time_shift_s
        ));
    }
    lines.push(format!(
        "  sensors {}; time 0 = {:.6} ({}); replay: harrier replay {} -e <estimator>",
        e.sensors.join(", "),
        e.epoch,
        e.time_line,
        out_dir.display()
    ));
    lines
}

/// What `harrier sessions export --format mcap` wrote.
fn mcap_lines(e: &McapExported) -> Vec<String> {
    let total: u64 = e.messages.values().sum();
    let mut lines = vec![format!(
        "wrote {} (MCAP, Foxglove schemas): {total} messages from {} scans and {} track rows, \
         {:.1} s on the {} time line",
        e.path.display(),
        e.scans,
        e.track_rows,
        e.span[1] - e.span[0],
        e.time_line
    )];
    lines.extend(e.messages.iter().map(|(t, n)| format!("  {t}: {n}")));
    lines
}

/// Runs `harrier sessions`: the reader's or the export's answer, printed as text or JSON.
pub fn run(args: &SessionsArgs) -> anyhow::Result<()> {
    let lines = match &args.command {
        SessionsCommand::List { db, json } => {
            let all = list(db)?;
            if *json {
                vec![serde_json::to_string_pretty(&all)?]
            } else {
                list_lines(db, &all)
            }
        }
        SessionsCommand::Info { db, id, json } => {
            let s = info(db, *id)?;
            if *json {
                vec![serde_json::to_string_pretty(&s)?]
            } else {
                info_lines(&s)
            }
        }
        SessionsCommand::Export {
            db,
            id,
            out,
            format: ExportFormat::Scenario,
        } => {
            let e = export(db, *id)?;
            e.write_to(out)?;
            export_lines(out, &e)
        }
        SessionsCommand::Export {
            db,
            id,
            out,
            format: ExportFormat::Mcap,
        } => mcap_lines(&mcap(db, *id, out)?),
    };
    let mut stdout = std::io::stdout().lock();
    for l in lines {
        // A closed pipe (`| head`) is not an error.
        let _ = writeln!(stdout, "{l}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc(0.0), "1970-01-01 00:00:00Z");
        assert_eq!(utc(1_700_000_000.9), "2023-11-14 22:13:20Z");
        assert_eq!(utc(951_782_400.0), "2000-02-29 00:00:00Z");
    }
}

#[cfg(test)]
#[path = "sessions_tests.rs"]
mod recorded;
