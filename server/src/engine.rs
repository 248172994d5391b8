//! The engine's interface: what an estimator looks like once its filter types are erased. Every
//! estimator Harrier can run by name implements [`ReplayEstimator`] and is described by an
//! [`EstimatorInfo`]; the drivers in [`crate::estimators`] build them from a scenario and
//! [`Params`], and [`crate::registry`] lists them and builds one by name. A `Box<dyn
//! ReplayEstimator>` is the only form in which the offline tools (`replay`, `guidance-sim`) see a
//! filter.
//!
//! This module is a leaf: it imports nothing from the crate, so drivers depend on it and never on
//! the registry.

use std::collections::BTreeMap;

use harrier_core::EstimationError;
use harrier_core::scenario::{Estimate, Measurement, Scenario};

/// Why an estimator could not be built or could not process a time step.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The scenario lacks something the estimator needs, or a parameter is wrong.
    #[error("{0}")]
    Setup(String),
    /// A numeric failure on this step's data; the estimator's state is unchanged.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}

/// Shorthand for a setup error.
pub fn setup(msg: impl Into<String>) -> EngineError {
    EngineError::Setup(msg.into())
}

/// One time step of a replay: every finite measurement with time `t`.
pub struct Step<'a> {
    /// Measurement time (s).
    pub t: f64,
    /// The measurements at `t`, sorted by sensor id, all with finite `z`.
    pub measurements: &'a [&'a Measurement],
    /// Next measurement time of a sensor after `t` (for one-step-ahead predictions).
    pub next_time: &'a dyn Fn(&str) -> Option<f64>,
}

impl std::fmt::Debug for Step<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Step")
            .field("t", &self.t)
            .field("measurements", &self.measurements)
            .finish()
    }
}

/// An estimator driven one measurement time at a time.
pub trait ReplayEstimator {
    /// Processes the measurements of one time and returns the estimate line for it (`None` when
    /// the estimator has nothing to report yet). On `Err(EngineError::Estimation)` the step's
    /// measurements are rejected and the estimator's state is left as it was.
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError>;
}

/// `--param name=value` settings, checked against the estimator's declared parameters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params(BTreeMap<String, f64>);

impl Params {
    /// Parses `name=value` strings.
    pub fn parse<S: AsRef<str>>(items: &[S]) -> Result<Self, EngineError> {
        let mut map = BTreeMap::new();
        for item in items {
            let item = item.as_ref();
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| setup(format!("--param {item:?}: expected name=value")))?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| setup(format!("--param {item:?}: value is not a finite number")))?;
            map.insert(k.trim().to_string(), v);
        }
        Ok(Self(map))
    }
    /// The value of `name`, or `default`.
    pub fn get(&self, name: &str, default: f64) -> f64 {
        self.0.get(name).copied().unwrap_or(default)
    }
    /// The value of `name`, if given.
    pub fn opt(&self, name: &str) -> Option<f64> {
        self.0.get(name).copied()
    }
    /// These settings with `name` set to `value` (a caller's own tuning, e.g. guidance-sim's).
    pub fn with(mut self, name: &str, value: f64) -> Self {
        self.0.insert(name.to_string(), value);
        self
    }
    /// The parameter names given.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.0.keys().map(String::as_str)
    }
    /// The acceleration spectral density `q` (m²/s³) of the kinematic models ([`Q_PARAM`]):
    /// `--param q=…`, else `motion.accel_std²` of the scenario.
    pub fn q(&self, sc: &Scenario) -> Result<f64, EngineError> {
        self.opt("q")
            .or(sc.accel_q())
            .ok_or_else(|| setup("scenario.json has no motion.accel_std; pass --param q=<m²/s³>"))
    }
}

/// The `q` parameter of every estimator that resolves it with [`Params::q`].
pub const Q_PARAM: (&str, &str) = (
    "q",
    "acceleration spectral density, m²/s³ (default motion.accel_std²)",
);

/// Builds an estimator for a scenario.
pub type BuildFn = fn(&Scenario, &Params) -> Result<Box<dyn ReplayEstimator>, EngineError>;

/// A named estimator, as a driver declares it and [`crate::registry::ESTIMATORS`] lists it.
#[derive(Debug)]
pub struct EstimatorInfo {
    /// Name used with `--estimator`.
    pub name: &'static str,
    /// One line for `harrier estimators`.
    pub summary: &'static str,
    /// Accepted `--param` names with a description (and default).
    pub params: &'static [(&'static str, &'static str)],
    /// Constructor.
    pub build: BuildFn,
}

/// One sensor scan as a track engine takes it, in the engine's local ENU frame: the time, the
/// sensor's measurement model at the platform pose of the scan (kind, position, noise), and the
/// detections, each with the model's number of components. This is what the live service makes
/// of a `DetectionScan` and what `harrier replay` makes of one sensor's measurement lines of one
/// time.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorScan {
    /// Scan time (s).
    pub t: f64,
    /// Measurement model of the sensor at this scan.
    pub sensor: harrier_core::measurement::SensorModel,
    /// The detections (clutter included), each a measurement vector.
    pub detections: Vec<Vec<f64>>,
}

/// What a track engine reports of one track: the estimate in the canonical state layout of an
/// estimate line (`[x, y, z, vx, vy, vz]`, FORMAT.md §5) with its covariance over `cov_dims`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct TrackView {
    /// Stable track id.
    pub id: u64,
    /// `"tentative"` or `"confirmed"`.
    #[schema(value_type = String)]
    pub status: &'static str,
    /// Time of the estimate (s).
    pub t: f64,
    /// `[x, y, z, vx, vy, vz]` (planar: z = the ground plane, vz = 0).
    pub state: [f64; 6],
    /// Covariance over the state indices `cov_dims`.
    pub cov: Vec<Vec<f64>>,
    /// The state indices `cov` covers.
    pub cov_dims: Vec<usize>,
    /// Whether the last scan updated the track (`false`: it coasted).
    pub updated: bool,
    /// Scans since initiation.
    pub age: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
    /// Mode probabilities of an IMM track (empty otherwise).
    pub mode_probabilities: Vec<f64>,
}

/// A multi-target tracker whose filter type is erased: the live shape of an estimator. It ingests
/// one sensor scan at a time (any kind, any platform) and says what happened as
/// [`TrackEvent`](harrier_core::tracker::TrackEvent)s; a snapshot serves the API.
pub trait TrackEngine: Send + std::fmt::Debug {
    /// Processes one scan. On error (time earlier than the last scan, a non-finite detection, a
    /// detection of the wrong size) nothing changes.
    fn ingest(
        &mut self,
        scan: &SensorScan,
    ) -> Result<Vec<harrier_core::tracker::TrackEvent>, EngineError>;
    /// Every live track, tentative and confirmed, in id order.
    fn snapshot(&self) -> Vec<TrackView>;
    /// Time of the last scan.
    fn time(&self) -> Option<f64>;
    /// The live tracks in a form any engine of the same deployment can [`adopt`](Self::adopt).
    fn handover(&self) -> Handover;
    /// Replaces this engine's tracks with `h`'s (a change of estimator at run time): ids, status
    /// and hit/miss records are kept, each estimate starts this engine's filter. On error
    /// nothing changes.
    fn adopt(&mut self, h: &Handover) -> Result<(), EngineError>;
}

/// Tracks passed from one track engine to another: each track's record and its Gaussian estimate
/// in the engine's state layout (`dim` = 4 planar `[x, y, vx, vy]`, 6 in 3-D), covariance
/// row-major.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Handover {
    /// Time of the last scan.
    pub t: Option<f64>,
    /// State dimension of every estimate.
    pub dim: usize,
    /// Record, mean and covariance of each track.
    pub tracks: Vec<(harrier_core::tracker::Track<()>, Vec<f64>, Vec<f64>)>,
}

/// Builds a track engine for a deployment described as a scenario (`dims`, ground plane,
/// `motion`, `roads`).
pub type TrackEngineBuildFn = fn(&Scenario, &Params) -> Result<Box<dyn TrackEngine>, EngineError>;

/// A named track engine, as a driver declares it and [`crate::registry::TRACK_ENGINES`] lists it.
#[derive(Debug)]
pub struct TrackEngineInfo {
    /// Name (the per-track estimator).
    pub name: &'static str,
    /// One line for `harrier estimators`.
    pub summary: &'static str,
    /// Accepted parameter names with a description (and default).
    pub params: &'static [(&'static str, &'static str)],
    /// Constructor.
    pub build: TrackEngineBuildFn,
}
