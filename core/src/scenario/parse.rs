//! Parsing and checking the files ([`Scenario::parse`], [`parse_measurements`],
//! [`parse_truth`], [`ScenarioData::parse`]) and the errors that name the file and line.

use std::collections::HashMap;
use std::fmt;

use super::lines::{Measurement, Reference, ScenarioData, TruthRow};
use super::types::{FORMAT_ID, Scenario};
use crate::measurement::MeasKind;

/// The files of a scenario directory: FORMAT.md's three and the registration extension's two
/// (FORMAT-REGISTRATION.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScenarioFile {
    /// `scenario.json`
    Scenario,
    /// `measurements.jsonl`
    Measurements,
    /// `truth.csv`
    Truth,
    /// `references.jsonl`: detections of cooperative references (optional).
    References,
    /// `bias_truth.csv`: the sensors' true biases (optional).
    BiasTruth,
}

impl ScenarioFile {
    /// File name inside the scenario directory.
    pub fn file_name(self) -> &'static str {
        match self {
            Self::Scenario => "scenario.json",
            Self::Measurements => "measurements.jsonl",
            Self::Truth => "truth.csv",
            Self::References => "references.jsonl",
            Self::BiasTruth => "bias_truth.csv",
        }
    }
}

/// A malformed or inconsistent scenario: which file, which line (1-based) and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct FormatError {
    /// File the problem is in.
    pub file: ScenarioFile,
    /// 1-based line, when the problem is on one line.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{}: {}", self.file.file_name(), l, self.message),
            None => write!(f, "{}: {}", self.file.file_name(), self.message),
        }
    }
}

pub(crate) fn err(
    file: ScenarioFile,
    line: Option<usize>,
    message: impl Into<String>,
) -> FormatError {
    FormatError {
        file,
        line,
        message: message.into(),
    }
}

/// The index in a CSV `header` of each column of `names`, and of the optional `mode` column; the
/// error names the first missing column (line 1 of `file`).
pub(crate) fn header_columns<const K: usize>(
    header: &[&str],
    names: [&str; K],
    file: ScenarioFile,
) -> Result<([usize; K], Option<usize>), FormatError> {
    let mut col = [0usize; K];
    for (c, n) in col.iter_mut().zip(names) {
        *c = header
            .iter()
            .position(|h| *h == n)
            .ok_or_else(|| err(file, Some(1), format!("header has no column {n:?}")))?;
    }
    Ok((col, header.iter().position(|h| *h == "mode")))
}

/// A CSV cell that must be a finite number; the error names the column, the value and the line.
pub(crate) fn finite_cell(
    cell: &str,
    column: &str,
    file: ScenarioFile,
    line: usize,
) -> Result<f64, FormatError> {
    cell.trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| {
            err(
                file,
                Some(line),
                format!("{column:?} = {cell:?} is not a finite number"),
            )
        })
}

impl Scenario {
    /// Parses and validates `scenario.json`.
    pub fn parse(text: &str) -> Result<Self, FormatError> {
        let f = ScenarioFile::Scenario;
        let sc: Self = serde_json::from_str(text)
            .map_err(|e| err(f, Some(e.line()), strip_position(&e.to_string())))?;
        if sc.format != FORMAT_ID {
            return Err(err(
                f,
                None,
                format!("format is {:?}, expected {FORMAT_ID:?}", sc.format),
            ));
        }
        if sc.dims != 2 && sc.dims != 3 {
            return Err(err(
                f,
                None,
                format!("dims must be 2 or 3, got {}", sc.dims),
            ));
        }
        if !(sc.time.dt.is_finite() && sc.time.dt > 0.0) {
            return Err(err(
                f,
                None,
                format!("time.dt must be > 0, got {}", sc.time.dt),
            ));
        }
        let mut ids = HashMap::new();
        for s in &sc.sensors {
            if ids.insert(s.id.as_str(), ()).is_some() {
                return Err(err(f, None, format!("sensor id {:?} is not unique", s.id)));
            }
            if s.kind == MeasKind::Position && !matches!(s.ncomp, Some(2) | Some(3) | None) {
                return Err(err(
                    f,
                    None,
                    format!("sensor {:?}: ncomp must be 2 or 3", s.id),
                ));
            }
            let scale = s.noise.scale();
            if scale.len() != s.dim() {
                return Err(err(
                    f,
                    None,
                    format!(
                        "sensor {:?}: noise has {} components, expected {}",
                        s.id,
                        scale.len(),
                        s.dim()
                    ),
                ));
            }
            if let Some(bad) = scale.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(err(
                    f,
                    None,
                    format!("sensor {:?}: noise scale {bad} is not > 0", s.id),
                ));
            }
        }
        if let Some(p) = &sc.prior {
            let dims = p.dims();
            let k = p.cov.len();
            if dims.len() != k || p.cov.iter().any(|r| r.len() != k) {
                return Err(err(
                    f,
                    None,
                    "prior.cov must be square and match prior.cov_dims",
                ));
            }
            if dims.iter().any(|&d| d > 5) {
                return Err(err(
                    f,
                    None,
                    "prior.cov_dims must be canonical indices 0..5",
                ));
            }
            if p.state
                .iter()
                .chain(p.cov.iter().flatten())
                .any(|v| !v.is_finite())
            {
                return Err(err(f, None, "prior contains a non-finite number"));
            }
            if dims.iter().enumerate().any(|(i, _)| p.cov[i][i] <= 0.0) {
                return Err(err(f, None, "prior.cov has a non-positive variance"));
            }
        }
        if let Some(m) = &sc.motion {
            if let Some(a) = m.accel_std {
                if !(a.is_finite() && a >= 0.0) {
                    return Err(err(
                        f,
                        None,
                        format!("motion.accel_std must be ≥ 0, got {a}"),
                    ));
                }
            }
        }
        Ok(sc)
    }
}

/// serde_json appends " at line L column C"; we report the line ourselves.
fn strip_position(msg: &str) -> String {
    match msg.rfind(" at line ") {
        Some(i) => msg[..i].to_string(),
        None => msg.to_string(),
    }
}

/// Parses `measurements.jsonl` and checks it against the scenario: known sensor, matching kind,
/// right number of components, finite platform pose, time order.
pub fn parse_measurements(text: &str, sc: &Scenario) -> Result<Vec<Measurement>, FormatError> {
    jsonl(
        text,
        ScenarioFile::Measurements,
        sc,
        |m: &Measurement| m,
        |_| Ok(()),
    )
}

/// Parses `references.jsonl` (FORMAT-REGISTRATION.md §2): measurement lines checked as
/// [`parse_measurements`] does, each with a finite `z` and the `object` it saw (finite position
/// and velocity, standard deviations > 0).
pub fn parse_references(text: &str, sc: &Scenario) -> Result<Vec<Reference>, FormatError> {
    jsonl(
        text,
        ScenarioFile::References,
        sc,
        |r: &Reference| &r.measurement,
        |r| {
            let o = &r.object;
            if !r.measurement.is_finite() {
                Err("z is not finite".into())
            } else if o.pos.iter().chain(&o.vel).any(|v| !v.is_finite())
                || o.std.iter().any(|s| !(s.is_finite() && *s > 0.0))
            {
                Err(format!(
                    "object {:?}: pos and vel must be finite, std > 0",
                    o.id
                ))
            } else {
                Ok(())
            }
        },
    )
}

/// The lines of a JSON-lines file of measurement lines (`line` reaches each one's measurement),
/// each checked against the scenario ([`check_line`]) and by `extra`; errors name the line.
fn jsonl<T: serde::de::DeserializeOwned>(
    text: &str,
    f: ScenarioFile,
    sc: &Scenario,
    line: impl Fn(&T) -> &Measurement,
    extra: impl Fn(&T) -> Result<(), String>,
) -> Result<Vec<T>, FormatError> {
    let mut out = Vec::new();
    let mut last_t = f64::NEG_INFINITY;
    for (i, text) in text.lines().enumerate() {
        let ln = i + 1;
        if text.trim().is_empty() {
            continue;
        }
        let item: T = serde_json::from_str(text)
            .map_err(|e| err(f, Some(ln), strip_position(&e.to_string())))?;
        check_line(line(&item), sc, f, ln, &mut last_t)?;
        extra(&item).map_err(|m| err(f, Some(ln), m))?;
        out.push(item);
    }
    Ok(out)
}

/// The checks of one measurement line of `file` (line `ln`) against the scenario.
fn check_line(
    m: &Measurement,
    sc: &Scenario,
    f: ScenarioFile,
    ln: usize,
    last_t: &mut f64,
) -> Result<(), FormatError> {
    if !m.t.is_finite() {
        return Err(err(f, Some(ln), "t is not finite"));
    }
    if m.t < *last_t {
        return Err(err(
            f,
            Some(ln),
            format!("t = {} is earlier than the previous line's {last_t}", m.t),
        ));
    }
    // No line may move the replay's clock without bound: times lie in the scenario's span
    // (one nominal period of slack either side).
    let (t0, t_end, slack) = (sc.time.t0, sc.time.t_end, sc.time.dt.abs());
    if !(m.t >= t0 - slack && m.t <= t_end + slack) {
        return Err(err(
            f,
            Some(ln),
            format!(
                "t = {} is outside the scenario's time span [{t0}, {t_end}] (scenario.json time)",
                m.t
            ),
        ));
    }
    *last_t = m.t;
    let Some(s) = sc.sensor(&m.sensor) else {
        return Err(err(f, Some(ln), format!("unknown sensor {:?}", m.sensor)));
    };
    if s.kind != m.kind {
        return Err(err(
            f,
            Some(ln),
            format!(
                "kind {:?} does not match sensor {:?} ({:?})",
                m.kind, s.id, s.kind
            ),
        ));
    }
    if m.z.len() != s.dim() {
        return Err(err(
            f,
            Some(ln),
            format!(
                "z has {} components, sensor {:?} gives {}",
                m.z.len(),
                s.id,
                s.dim()
            ),
        ));
    }
    if m.platform
        .pos
        .iter()
        .chain(&m.platform.vel)
        .any(|v| !v.is_finite())
    {
        return Err(err(f, Some(ln), "platform pose is not finite"));
    }
    Ok(())
}

/// Parses `truth.csv` (header `t,x,y,z,vx,vy,vz,mode`).
pub fn parse_truth(text: &str) -> Result<Vec<TruthRow>, FormatError> {
    let f = ScenarioFile::Truth;
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => {
            return Err(err(
                f,
                Some(1),
                "empty file: expected header t,x,y,z,vx,vy,vz,mode",
            ));
        }
    };
    let names = ["t", "x", "y", "z", "vx", "vy", "vz"];
    let (col, mode_col) = header_columns(&header, names, f)?;
    let mut rows: Vec<TruthRow> = Vec::new();
    for (i, line) in lines {
        let ln = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        let mut v = [0.0; 7];
        for k in 0..7 {
            let cell = cells
                .get(col[k])
                .ok_or_else(|| err(f, Some(ln), format!("missing column {:?}", names[k])))?;
            v[k] = finite_cell(cell, names[k], f, ln)?;
        }
        if rows.last().is_some_and(|r| r.t > v[0]) {
            return Err(err(f, Some(ln), "rows are not sorted by t"));
        }
        let mode = mode_col
            .and_then(|c| cells.get(c))
            .map(|s| s.trim().to_string())
            .unwrap_or_default();
        rows.push(TruthRow {
            t: v[0],
            state: [v[1], v[2], v[3], v[4], v[5], v[6]],
            mode,
        });
    }
    Ok(rows)
}

impl ScenarioData {
    /// Parses a whole scenario from the contents of its files.
    pub fn parse(
        scenario_json: &str,
        measurements_jsonl: &str,
        truth_csv: Option<&str>,
    ) -> Result<Self, FormatError> {
        let scenario = Scenario::parse(scenario_json)?;
        let measurements = parse_measurements(measurements_jsonl, &scenario)?;
        let truth = truth_csv.map(parse_truth).transpose()?;
        Ok(Self {
            scenario,
            measurements,
            truth,
            references: Vec::new(),
        })
    }

    /// This scenario with the cooperative references of `references.jsonl`
    /// ([`parse_references`]).
    pub fn with_references(mut self, references_jsonl: &str) -> Result<Self, FormatError> {
        self.references = parse_references(references_jsonl, &self.scenario)?;
        Ok(self)
    }
}
