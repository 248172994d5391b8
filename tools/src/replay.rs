//! `harrier replay`: runs a named estimator over a `gcs-scenario/1` directory, writes
//! `estimates.jsonl` (atomically: nothing is written when the run fails) and scores the result
//! against `truth.csv` when it is there.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use harrier_core::metrics::{self, Score};
use harrier_core::scenario::{Estimate, FormatError, ScenarioData, ScenarioFile};

use harrier_engine::registry;
use harrier_engine::{EngineError, Params, ReplayEstimator, Step};

/// Why a replay failed. Every variant is the user's input being wrong (exit code 2) except `Io`
/// on the output side.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A scenario file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A scenario file is malformed or inconsistent.
    #[error("{path}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Format {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The estimator cannot run on this scenario (or a parameter is wrong).
    #[error("{0}")]
    Setup(String),
    /// The output could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

impl ReplayError {
    /// Process exit code: 2 for bad input, 1 for output failures.
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::Write { .. } => 1,
            _ => 2,
        }
    }
}

/// Loads a scenario directory (with `references.jsonl` when it is there,
/// FORMAT-REGISTRATION.md); errors name the file and line.
pub fn load(dir: &Path) -> Result<ScenarioData, ReplayError> {
    let read = |f: ScenarioFile| {
        let path = dir.join(f.file_name());
        std::fs::read_to_string(&path).map_err(|source| ReplayError::Read { path, source })
    };
    let sc = read(ScenarioFile::Scenario)?;
    let meas = read(ScenarioFile::Measurements)?;
    let truth_path = dir.join(ScenarioFile::Truth.file_name());
    let truth = truth_path
        .exists()
        .then(|| read(ScenarioFile::Truth))
        .transpose()?;
    let refs_path = dir.join(ScenarioFile::References.file_name());
    let refs = refs_path
        .exists()
        .then(|| read(ScenarioFile::References))
        .transpose()?;
    let format = |e: FormatError| ReplayError::Format {
        path: dir.join(e.file.file_name()),
        line: e.line,
        message: e.message,
    };
    let data = ScenarioData::parse(&sc, &meas, truth.as_deref()).map_err(format)?;
    match refs {
        Some(text) => data.with_references(&text).map_err(format),
        None => Ok(data),
    }
}

/// What a replay did.
#[derive(Debug, Clone)]
pub struct ReplayReport {
    /// Estimate lines, one per processed measurement time.
    pub estimates: Vec<Estimate>,
    /// Measurements read.
    pub measurements: usize,
    /// Measurements skipped because a component was NaN/null/inf.
    pub skipped_nonfinite: usize,
    /// Measurement times whose update failed numerically (state kept, see the log).
    pub rejected: Vec<(f64, String)>,
    /// Score against `truth.csv`, when present.
    pub score: Option<Score>,
    /// Wall time of the estimation loop.
    pub elapsed: Duration,
    /// What a multi-target tracker's associator did (clusters, bounds hit).
    pub association: Option<harrier_core::tracker::AssociationStats>,
}

/// The track filter and associator of the replay estimator `tracker` (`harrier replay -e tracker
/// --track-filter F --associator A`; `harrier estimators` lists both).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrackerChoice {
    /// Track filter name (`ekf`, `cdkf`, `imm`, `cimm`).
    pub filter: String,
    /// Associator name (`gnn`, `jipda`, `mht`).
    pub associator: String,
    /// Estimate the biases of the sensors with a `bias` block jointly with the tracks (the
    /// live registrar; `--register`).
    pub register: bool,
}

/// Runs `estimator` over the scenario `data`.
pub fn run(
    data: &ScenarioData,
    estimator: &str,
    params: &Params,
) -> Result<ReplayReport, ReplayError> {
    let est = registry::build(estimator, &data.scenario, params)
        .map_err(|e| ReplayError::Setup(e.to_string()))?;
    run_estimator(data, est)
}

/// Runs the replay estimator `tracker` with the track filter and associator of `choice` over the
/// scenario `data`.
pub fn run_tracker(
    data: &ScenarioData,
    choice: &TrackerChoice,
    params: &Params,
) -> Result<ReplayReport, ReplayError> {
    let est = registry::build_tracker(
        &choice.filter,
        &choice.associator,
        &data.scenario,
        params,
        choice.register,
    )
    .map_err(|e| ReplayError::Setup(e.to_string()))?;
    run_estimator(data, est)
}

/// Runs `est` over the scenario `data`.
fn run_estimator(
    data: &ScenarioData,
    mut est: Box<dyn ReplayEstimator>,
) -> Result<ReplayReport, ReplayError> {
    let sc = &data.scenario;
    // Measurement times per sensor, for Step::next_time.
    let mut times: HashMap<&str, Vec<f64>> = HashMap::new();
    for m in data.measurements.iter().filter(|m| m.is_finite()) {
        times.entry(m.sensor.as_str()).or_default().push(m.t);
    }
    let skipped = data.measurements.iter().filter(|m| !m.is_finite()).count();
    let mut estimates = Vec::new();
    let mut rejected = Vec::new();
    // The references not handed to a step yet (they go with the next step at or after them).
    let mut refs = data.references.iter().peekable();
    let start = Instant::now();
    for (t, group) in data.groups() {
        let finite: Vec<_> = group.into_iter().filter(|m| m.is_finite()).collect();
        if finite.is_empty() {
            continue;
        }
        let mut references = Vec::new();
        while let Some(r) = refs.next_if(|r| r.measurement.t <= t + 1e-9) {
            references.push(r);
        }
        let next_time = |sensor: &str| {
            let v = times.get(sensor)?;
            v.get(v.partition_point(|x| *x <= t + 1e-9)).copied()
        };
        let step = Step {
            t,
            measurements: &finite,
            references: &references,
            next_time: &next_time,
        };
        match est.step(&step) {
            Ok(Some(e)) => estimates.push(e),
            Ok(None) => {}
            Err(EngineError::Estimation(e)) => rejected.push((t, e.to_string())),
            Err(e @ EngineError::Setup(_)) => return Err(ReplayError::Setup(e.to_string())),
        }
    }
    let elapsed = start.elapsed();
    let score = data
        .truth
        .as_ref()
        .map(|truth| metrics::score(sc, &data.measurements, truth, &estimates, sc.target.size_m));
    Ok(ReplayReport {
        estimates,
        measurements: data.measurements.len(),
        skipped_nonfinite: skipped,
        rejected,
        score,
        elapsed,
        association: est.association(),
    })
}

/// Writes estimate lines to `path` through a temporary file in the same directory, so a failed
/// run never leaves a partial file.
pub fn write_estimates(path: &Path, estimates: &[Estimate]) -> Result<(), ReplayError> {
    let werr = |source| ReplayError::Write {
        path: path.to_path_buf(),
        source,
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let file_name = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{file_name}.tmp"));
    let result = (|| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        for e in estimates {
            serde_json::to_writer(&mut w, e)?;
            w.write_all(b"\n")?;
        }
        w.into_inner()
            .map_err(std::io::IntoInnerError::into_error)?
            .sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(werr)
}

/// Human-readable summary of a score, in the spirit of `score.py`'s.
pub fn summary_lines(score: &Score) -> Vec<String> {
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
    let mut out = Vec::new();
    if score.pos_rmse.is_some() {
        out.push(format!(
            "pos RMSE {} m, vel RMSE {} m/s, max pos err {} m ({} scored)",
            f(score.pos_rmse),
            f(score.vel_rmse),
            f(score.pos_max),
            score.scored
        ));
    }
    if score.pos_rmse_by_mode.len() > 1 {
        let by: Vec<_> = score
            .pos_rmse_by_mode
            .iter()
            .map(|(k, v)| format!("{k} {v:.4}"))
            .collect();
        out.push(format!("pos RMSE by mode: {}", by.join(", ")));
    }
    for (name, n) in [("nees", &score.nees), ("nees_pos", &score.nees_pos)] {
        if let Some(n) = n {
            out.push(format!(
                "{name}: mean {:.4} (dof {}, per-dof {:.4}), within chi2 95%: {:.3}",
                n.mean, n.dof, n.mean_per_dof, n.frac_within_95
            ));
        }
    }
    if let Some(e) = &score.ellipsoid {
        out.push(format!(
            "ellipsoid dims {:?}: containment {:.4} ({} violations), mean volume {:.4}",
            e.dims, e.containment, e.violations, e.mean_volume
        ));
    }
    for (kind, p) in &score.prediction {
        out.push(format!(
            "one-step prediction ({kind}): max|err| vs truth {:?}, RMS {:?}",
            p.max_abs_vs_truth, p.rms_vs_truth
        ));
    }
    out
}
