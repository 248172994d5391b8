//! The `gcs-scenario/1` format (`shared/scenarios/FORMAT.md`): `scenario.json`,
//! `measurements.jsonl`, `truth.csv` and the estimator output `estimates.jsonl`.
//!
//! Parsing works on strings (the caller reads the files) and every error says which file, which
//! line and what is wrong ([`FormatError`]). Unknown keys are ignored, as FORMAT.md requires.
//! Readers never look at the `generator` block.

use std::collections::HashMap;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::measurement::MeasKind;

/// The three files of a scenario directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScenarioFile {
    /// `scenario.json`
    Scenario,
    /// `measurements.jsonl`
    Measurements,
    /// `truth.csv`
    Truth,
}

impl ScenarioFile {
    /// File name inside the scenario directory.
    pub fn file_name(self) -> &'static str {
        match self {
            Self::Scenario => "scenario.json",
            Self::Measurements => "measurements.jsonl",
            Self::Truth => "truth.csv",
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

/// The format identifier this module reads and writes.
pub const FORMAT_ID: &str = "gcs-scenario/1";

/// `scenario.json`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Scenario {
    /// Must be [`FORMAT_ID`].
    pub format: String,
    /// Scenario name.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// 2 = planar (z = `plane_z`), 3 = full 3-D.
    pub dims: u8,
    /// Up coordinate of planar scenarios.
    #[serde(default)]
    pub plane_z: Option<f64>,
    /// Timing.
    pub time: TimeSpec,
    /// The target.
    pub target: Target,
    /// Sensor platforms.
    #[serde(default)]
    pub platforms: Vec<Platform>,
    /// Sensors.
    pub sensors: Vec<Sensor>,
    /// Road network (may be empty).
    #[serde(default)]
    pub roads: Vec<Road>,
    /// Motion-model hints.
    #[serde(default)]
    pub motion: Option<Motion>,
    /// Gaussian prior.
    #[serde(default)]
    pub prior: Option<Prior>,
    /// Bounded-noise linear system (set-membership case, FORMAT.md §2.1).
    #[serde(default)]
    pub linear_system: Option<LinearSystem>,
    /// Free-form tuning hints from the paper.
    #[serde(default)]
    pub hints: serde_json::Value,
    /// Scoring settings.
    #[serde(default)]
    pub scoring: Scoring,
}

/// `time` block.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct TimeSpec {
    /// Scenario epoch (s).
    #[serde(default)]
    pub t0: f64,
    /// Nominal sensor period (s).
    pub dt: f64,
    /// End time (s).
    pub t_end: f64,
}

/// `target` block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Target {
    /// Target id.
    pub id: String,
    /// Characteristic size (m) when known to the estimator.
    #[serde(default)]
    pub size_m: Option<f64>,
    /// Size prior when the size is unknown.
    #[serde(default)]
    pub size_prior: Option<SizePrior>,
    /// Ground target.
    #[serde(default)]
    pub on_ground: Option<bool>,
}

/// Gaussian prior on an unknown target size (m).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct SizePrior {
    /// Mean (m).
    pub mean: f64,
    /// Standard deviation (m).
    pub std: f64,
}

/// A sensor platform.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Platform {
    /// Platform id.
    pub id: String,
    /// Kind (uav, multirotor, ground, …).
    #[serde(default)]
    pub kind: String,
}

/// A sensor.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Sensor {
    /// Sensor id.
    pub id: String,
    /// Id of the platform carrying it.
    pub platform: String,
    /// Measurement kind.
    pub kind: MeasKind,
    /// Components of a position sensor (2 or 3).
    #[serde(default)]
    pub ncomp: Option<usize>,
    /// Nominal rate (Hz).
    #[serde(default)]
    pub rate_hz: Option<f64>,
    /// Noise description.
    pub noise: Noise,
    /// Bias description (`{"model": "unknown"}` for radars with unknown bias).
    #[serde(default)]
    pub bias: Option<serde_json::Value>,
}

impl Sensor {
    /// Measurement dimension.
    pub fn dim(&self) -> usize {
        self.kind.len(self.ncomp)
    }
}

/// Noise block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Noise {
    /// Independent Gaussian noise with per-component standard deviations.
    Gaussian {
        /// Standard deviation per component.
        std: Vec<f64>,
    },
    /// Unknown-but-bounded noise `|v_i| ≤ bound_i`.
    Bounded {
        /// Bound per component.
        bound: Vec<f64>,
        /// Shape of the bound (`box`).
        #[serde(default)]
        shape: Option<String>,
    },
}

impl Noise {
    /// Per-component scale: the std of Gaussian noise, or the bound of bounded noise.
    pub fn scale(&self) -> &[f64] {
        match self {
            Self::Gaussian { std } => std,
            Self::Bounded { bound, .. } => bound,
        }
    }
    /// Per-component standard deviation; bounded noise is treated as uniform (σ = bound/√3).
    pub fn std(&self) -> Vec<f64> {
        match self {
            Self::Gaussian { std } => std.clone(),
            Self::Bounded { bound, .. } => bound.iter().map(|b| b / 3f64.sqrt()).collect(),
        }
    }
}

/// A road (FORMAT.md §2 `roads`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Road {
    /// Road id.
    pub id: String,
    /// Physical width (m).
    #[serde(default)]
    pub width_m: Option<f64>,
    /// Std of the lateral offset from the centre line (m).
    #[serde(default)]
    pub sigma_m: Option<f64>,
    /// Centre-line segments in travel order.
    pub segments: Vec<Segment>,
}

/// A road segment.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Segment {
    /// Straight line.
    Line {
        /// Start (x, y).
        start: [f64; 2],
        /// End (x, y).
        end: [f64; 2],
    },
    /// Circular arc.
    Arc {
        /// Centre (x, y).
        center: [f64; 2],
        /// Radius (m).
        radius: f64,
        /// Start (x, y).
        start: [f64; 2],
        /// End (x, y).
        end: [f64; 2],
        /// Signed sweep: > 0 counter-clockwise.
        sweep_rad: f64,
    },
}

/// `motion` hints.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Motion {
    /// Candidate models.
    #[serde(default)]
    pub models: Vec<MotionModelSpec>,
    /// Initial model probabilities, aligned with `models`.
    #[serde(default)]
    pub initial_probs: Option<Vec<f64>>,
    /// Markov transition matrix, row i = from model i.
    #[serde(default)]
    pub transition_matrix: Option<Vec<Vec<f64>>>,
    /// White-noise acceleration std (m/s²); spectral density = accel_std².
    #[serde(default)]
    pub accel_std: Option<f64>,
    /// Hard acceleration bound (m/s²).
    #[serde(default)]
    pub accel_bound: Option<f64>,
}

impl Motion {
    /// The hints of a constant-velocity target: one `CV` model, white-noise acceleration std
    /// `accel_std` (m/s²).
    pub fn cv(accel_std: f64) -> Self {
        Self {
            models: vec![MotionModelSpec {
                name: "CV".into(),
                kind: "CV".into(),
                turn_rate: None,
            }],
            initial_probs: None,
            transition_matrix: None,
            accel_std: Some(accel_std),
            accel_bound: None,
        }
    }

    /// Acceleration spectral density from `accel_std` (m²/s³), if given.
    pub fn accel_q(&self) -> Option<f64> {
        self.accel_std.map(|a| a * a)
    }
}

/// One motion model of the hints.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct MotionModelSpec {
    /// Name (truth `mode` labels use it).
    pub name: String,
    /// `CV`, `CT`, …
    #[serde(rename = "type")]
    pub kind: String,
    /// Turn rate for CT (rad/s, > 0 counter-clockwise).
    #[serde(default)]
    pub turn_rate: Option<f64>,
}

/// Gaussian prior at time `t` over the canonical dims `cov_dims`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Prior {
    /// Time of the prior (s).
    #[serde(default)]
    pub t: f64,
    /// Canonical 6-state.
    pub state: [f64; 6],
    /// Covariance of `state[cov_dims]`.
    pub cov: Vec<Vec<f64>>,
    /// Canonical indices of `cov`.
    #[serde(default)]
    pub cov_dims: Option<Vec<usize>>,
}

impl Prior {
    /// Canonical indices of the covariance (FORMAT.md defaults by size).
    pub fn dims(&self) -> Vec<usize> {
        self.cov_dims
            .clone()
            .unwrap_or_else(|| default_cov_dims(self.cov.len()))
    }
    /// Variance of canonical index `i`, if it is in the covariance.
    pub fn variance(&self, i: usize) -> Option<f64> {
        let k = self.dims().iter().position(|&d| d == i)?;
        self.cov.get(k).and_then(|row| row.get(k)).copied()
    }
}

/// Default canonical indices implied by a covariance of size `n` (FORMAT.md §5).
pub fn default_cov_dims(n: usize) -> Vec<usize> {
    match n {
        6 => vec![0, 1, 2, 3, 4, 5],
        4 => vec![0, 1, 3, 4],
        3 => vec![0, 1, 2],
        2 => vec![0, 1],
        _ => (0..n).collect(),
    }
}

/// Bounded-noise linear system (FORMAT.md §2.1).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[allow(non_snake_case)]
pub struct LinearSystem {
    /// Canonical indices of the system state.
    pub state_dims: Vec<usize>,
    /// Transition matrix.
    pub A: Vec<Vec<f64>>,
    /// Process-noise input matrix.
    pub B: Vec<Vec<f64>>,
    /// Measurement matrix.
    pub C: Vec<Vec<f64>>,
    /// Bound on w: `{"type": "ball", "radius": r}`.
    pub w_bound: serde_json::Value,
    /// Bound on v: `{"type": "box", "half_width": [...]}`.
    pub v_bound: serde_json::Value,
    /// Initial set.
    pub x0_ellipsoid: EllipsoidSpec,
}

/// An ellipsoid `{x : (x[dims] − center)ᵀ shape⁻¹ (x[dims] − center) ≤ 1}`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct EllipsoidSpec {
    /// Centre.
    pub center: Vec<f64>,
    /// Shape matrix (SPD).
    pub shape: Vec<Vec<f64>>,
    /// Canonical indices.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dims: Option<Vec<usize>>,
}

/// `scoring` block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Scoring {
    /// Estimates before this time are not scored.
    #[serde(default)]
    pub t_start: f64,
    /// `state`, `prediction` or `ellipsoid`.
    #[serde(default = "default_primary")]
    pub primary: String,
}

impl Default for Scoring {
    fn default() -> Self {
        Self {
            t_start: 0.0,
            primary: default_primary(),
        }
    }
}

fn default_primary() -> String {
    "state".into()
}

/// `frame` block: ENU metres about an optional geodetic origin (FORMAT.md §2).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Frame {
    /// Always `ENU`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Always `m`.
    pub units: String,
    /// WGS-84 origin of the frame, when it has one.
    pub origin_geodetic: Option<crate::detection::GeoPoint>,
}

impl Frame {
    /// The ENU frame (metres) at `origin`.
    pub fn enu(origin: Option<crate::detection::GeoPoint>) -> Self {
        Self {
            kind: "ENU".into(),
            units: "m".into(),
            origin_geodetic: origin,
        }
    }
}

/// `generator` block: provenance of a generated scenario. Estimators never read it.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Generator {
    /// Which generator wrote the scenario.
    pub family: String,
    /// Its seed.
    pub seed: u64,
    /// Everything else needed to regenerate it.
    pub params: serde_json::Value,
}

/// `scenario.json` as a generator writes it: the [`Scenario`] readers parse, plus the blocks they
/// do not interpret — the `frame`, the keys of format extensions (FORMAT-MULTI.md's `targets` and
/// `detection`) and the `generator`. [`Scenario::parse`] reads the result back.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioDocument {
    /// What readers parse.
    #[serde(flatten)]
    pub scenario: Scenario,
    /// The local frame.
    pub frame: Frame,
    /// Extension keys, written at the top level (must not repeat a [`Scenario`] key).
    #[serde(flatten)]
    pub extensions: serde_json::Map<String, serde_json::Value>,
    /// Provenance.
    pub generator: Generator,
}

impl ScenarioDocument {
    /// Pretty JSON text of `scenario.json`, ending with a newline.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        Ok(text)
    }
}

/// Platform pose in a measurement line.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct PlatformPose {
    /// ENU position (m).
    pub pos: [f64; 3],
    /// ENU velocity (m/s).
    #[serde(default)]
    pub vel: [f64; 3],
}

/// One line of `measurements.jsonl`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Measurement {
    /// Time (s).
    pub t: f64,
    /// Sensor id.
    pub sensor: String,
    /// Kind (must match the sensor's).
    pub kind: MeasKind,
    /// Sensor platform pose at `t`.
    pub platform: PlatformPose,
    /// Measured value; `null` components are read as NaN (and such measurements are skipped).
    #[serde(deserialize_with = "nullable_floats")]
    pub z: Vec<f64>,
}

impl Measurement {
    /// Whether every component of `z` is finite.
    pub fn is_finite(&self) -> bool {
        self.z.iter().all(|v| v.is_finite())
    }
}

fn nullable_floats<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    let v: Vec<Option<f64>> = Deserialize::deserialize(d)?;
    Ok(v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
}

/// One row of `truth.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Time (s).
    pub t: f64,
    /// Canonical state.
    pub state: [f64; 6],
    /// Motion-mode label (may be empty).
    pub mode: String,
}

/// A whole scenario directory, parsed and checked for consistency.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioData {
    /// `scenario.json`.
    pub scenario: Scenario,
    /// `measurements.jsonl`, in file order (sorted by time, then sensor).
    pub measurements: Vec<Measurement>,
    /// `truth.csv` when present.
    pub truth: Option<Vec<TruthRow>>,
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

    /// The sensor with this id.
    pub fn sensor(&self, id: &str) -> Option<&Sensor> {
        self.sensors.iter().find(|s| s.id == id)
    }

    /// Up coordinate of planar scenarios (0 when absent).
    pub fn plane_z(&self) -> f64 {
        self.plane_z.unwrap_or(0.0)
    }

    /// Canonical dims that are scored: planar scenarios drop z and vz.
    pub fn active_dims(&self) -> &'static [usize] {
        if self.dims == 2 {
            &[0, 1, 3, 4]
        } else {
            &[0, 1, 2, 3, 4, 5]
        }
    }

    /// Acceleration spectral density from `motion.accel_std` (m²/s³), if given.
    pub fn accel_q(&self) -> Option<f64> {
        self.motion.as_ref().and_then(Motion::accel_q)
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
    let f = ScenarioFile::Measurements;
    let mut out = Vec::new();
    let mut last_t = f64::NEG_INFINITY;
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let m: Measurement = serde_json::from_str(line)
            .map_err(|e| err(f, Some(ln), strip_position(&e.to_string())))?;
        if !m.t.is_finite() {
            return Err(err(f, Some(ln), "t is not finite"));
        }
        if m.t < last_t {
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
        last_t = m.t;
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
        out.push(m);
    }
    Ok(out)
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
        })
    }

    /// Measurements grouped by time (within 1e-9 s), in time order; each group sorted by sensor.
    pub fn groups(&self) -> Vec<(f64, Vec<&Measurement>)> {
        group_by_time(&self.measurements)
    }
}

/// Groups measurements by time (within 1e-9 s): `[(t, [lines…])]` in time order.
pub fn group_by_time(meas: &[Measurement]) -> Vec<(f64, Vec<&Measurement>)> {
    let mut groups: Vec<(f64, Vec<&Measurement>)> = Vec::new();
    for m in meas {
        match groups.last_mut() {
            Some((t, g)) if (m.t - *t).abs() <= 1e-9 => g.push(m),
            _ => groups.push((m.t, vec![m])),
        }
    }
    for (_, g) in &mut groups {
        g.sort_by(|a, b| a.sensor.cmp(&b.sensor));
    }
    groups
}

/// Truth state at `t`: the row within 1 µs, else linear interpolation; `None` outside the rows.
/// Also returns the mode label in force and whether the row was exact (as `score.py` does).
pub fn truth_at(truth: &[TruthRow], t: f64) -> Option<([f64; 6], &str, bool)> {
    let i = truth.partition_point(|r| r.t < t);
    for j in [i.wrapping_sub(1), i] {
        if let Some(r) = truth.get(j) {
            if (r.t - t).abs() <= 1e-6 {
                return Some((r.state, &r.mode, true));
            }
        }
    }
    if i == 0 || i >= truth.len() {
        return None;
    }
    let (a, b) = (&truth[i - 1], &truth[i]);
    let w = (t - a.t) / (b.t - a.t);
    let s: [f64; 6] = std::array::from_fn(|k| (1.0 - w) * a.state[k] + w * b.state[k]);
    Some((s, &a.mode, false))
}

/// One line of `estimates.jsonl` (FORMAT.md §5).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
pub struct Estimate {
    /// Time (s).
    pub t: f64,
    /// Canonical state, or `null` for prediction-only estimators.
    pub state: Option<[f64; 6]>,
    /// Covariance of `state[cov_dims]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cov: Option<Vec<Vec<f64>>>,
    /// Canonical indices of `cov`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cov_dims: Option<Vec<usize>>,
    /// Set estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ellipsoid: Option<EllipsoidSpec>,
    /// Model probabilities aligned with `motion.models`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_probs: Option<Vec<f64>>,
    /// One-step-ahead predicted measurement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction: Option<PredictionOut>,
    /// Extra keys (`bias_est`, `size_est`, …), ignored by readers.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// `prediction` of an estimate line.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct PredictionOut {
    /// Time the prediction is for.
    pub t: f64,
    /// Sensor it predicts.
    pub sensor: String,
    /// Predicted measurement.
    pub z: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    const SC: &str = r#"{"format":"gcs-scenario/1","name":"t","dims":2,"plane_z":0.0,
 "time":{"t0":0,"dt":1,"t_end":2},"target":{"id":"tgt"},
 "sensors":[{"id":"r","platform":"p","kind":"range_bearing","noise":{"type":"gaussian","std":[5,0.005]}}],
 "generator":{"whatever":1}}"#;

    #[test]
    fn documents_parse_back_and_keep_frame_extensions_and_generator() {
        let scenario = Scenario::parse(SC).unwrap();
        let mut extensions = serde_json::Map::new();
        extensions.insert("detection".into(), serde_json::json!({"pd": 0.9}));
        let origin = crate::detection::GeoPoint::new(47.0, 8.0, 400.0);
        let doc = ScenarioDocument {
            scenario: scenario.clone(),
            frame: Frame::enu(Some(origin)),
            extensions,
            generator: Generator {
                family: "test".into(),
                seed: 3,
                params: serde_json::json!({"k": 1}),
            },
        };
        let text = doc.to_json().unwrap();
        assert!(text.ends_with("}\n"));
        assert_eq!(Scenario::parse(&text).unwrap(), scenario);
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["frame"]["type"], "ENU");
        assert_eq!(v["frame"]["origin_geodetic"]["lat_deg"], 47.0);
        assert_eq!(v["detection"]["pd"], 0.9);
        assert_eq!(v["generator"]["seed"], 3);
    }

    #[test]
    fn parses_minimal_scenario_and_ignores_unknown_keys() {
        let sc = Scenario::parse(SC).unwrap();
        assert_eq!(sc.sensors[0].kind, MeasKind::RangeBearing);
        assert_eq!(sc.active_dims(), &[0, 1, 3, 4]);
        for k in [
            MeasKind::Position,
            MeasKind::RangeBearing,
            MeasKind::AzEl,
            MeasKind::BearingSize,
        ] {
            assert_eq!(serde_json::to_value(k).unwrap(), k.as_str());
        }
    }

    #[test]
    fn measurement_errors_name_the_line() {
        let sc = Scenario::parse(SC).unwrap();
        let good =
            r#"{"t":0,"sensor":"r","kind":"range_bearing","platform":{"pos":[0,0,0]},"z":[1,2]}"#;
        let text = format!("{good}\n{{\"t\":1,\"sensor\":\"x\"\n");
        let e = parse_measurements(&text, &sc).unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Measurements, Some(2)));
        let text = format!(
            "{good}\n{}",
            good.replace("\"sensor\":\"r\"", "\"sensor\":\"q\"")
        );
        let e = parse_measurements(&text, &sc).unwrap_err();
        assert_eq!(e.to_string(), "measurements.jsonl:2: unknown sensor \"q\"");
        let text = good.replace("[1,2]", "[1,2,3]");
        assert!(
            parse_measurements(&text, &sc)
                .unwrap_err()
                .message
                .contains("3 components")
        );
        let text = good.replace("[1,2]", "[null,2]");
        assert!(!parse_measurements(&text, &sc).unwrap()[0].is_finite());
    }

    #[test]
    fn scenario_errors_name_the_line() {
        let e = Scenario::parse("{\n\"format\": \"gcs-scenario/1\",\n\"name\": 3\n}").unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Scenario, Some(3)));
        let e = Scenario::parse(&SC.replace("gcs-scenario/1", "gcs-scenario/9")).unwrap_err();
        assert!(e.message.contains("expected \"gcs-scenario/1\""));
    }

    #[test]
    fn truth_parsing_and_interpolation() {
        let t = parse_truth("t,x,y,z,vx,vy,vz,mode\n0,0,0,0,1,0,0,CV\n2,2,0,0,1,0,0,CT\n").unwrap();
        let (s, mode, exact) = truth_at(&t, 1.0).unwrap();
        assert_eq!((s[0], mode, exact), (1.0, "CV", false));
        assert!(truth_at(&t, 2.0 + 1e-7).unwrap().2);
        assert!(truth_at(&t, 3.0).is_none());
        let e = parse_truth("t,x,y,z,vx,vy,vz,mode\n0,0,0,0,1,abc,0,CV\n").unwrap_err();
        assert_eq!(e.line, Some(2));
    }
}
