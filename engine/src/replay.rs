//! The replay shape: a single-target estimator driven one measurement time at a time over a
//! `gcs-scenario/1` directory ([`ReplayEstimator`], [`Step`]), described by an [`EstimatorInfo`],
//! tuned by [`Params`].

use std::collections::BTreeMap;

use harrier_core::scenario::{Estimate, Measurement, Reference, Scenario};

use crate::error::{EngineError, setup};

/// One time step of a replay: every finite measurement with time `t`.
pub struct Step<'a> {
    /// Measurement time (s).
    pub t: f64,
    /// The measurements at `t`, sorted by sensor id, all with finite `z`.
    pub measurements: &'a [&'a Measurement],
    /// The cooperative references (FORMAT-REGISTRATION.md §2) since the previous step, in time
    /// order: every one with a time after the previous step's and at most `t`. Only the
    /// estimators that register sensors read them.
    pub references: &'a [&'a Reference],
    /// Next measurement time of a sensor after `t` (for one-step-ahead predictions).
    pub next_time: &'a dyn Fn(&str) -> Option<f64>,
}

impl std::fmt::Debug for Step<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Step")
            .field("t", &self.t)
            .field("measurements", &self.measurements)
            .field("references", &self.references)
            .finish()
    }
}

/// An estimator driven one measurement time at a time.
pub trait ReplayEstimator {
    /// Processes the measurements of one time and returns the estimate line for it (`None` when
    /// the estimator has nothing to report yet). On `Err(EngineError::Estimation)` the step's
    /// measurements are rejected and the estimator's state is left as it was.
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError>;
    /// What a multi-target tracker's associator did so far; `None` for other estimators.
    fn association(&self) -> Option<harrier_core::tracker::AssociationStats> {
        None
    }
}

/// `--param name=value` settings (or a live service's `[tracker] params`), checked against the
/// estimator's declared parameters.
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
        self.q_or(sc.accel_q())
    }
    /// `q` ([`Q_PARAM`]): `--param q=…`, else `accel_q`, the `motion.accel_std²` of a scenario or
    /// a deployment.
    pub fn q_or(&self, accel_q: Option<f64>) -> Result<f64, EngineError> {
        self.opt("q")
            .or(accel_q)
            .ok_or_else(|| setup("scenario.json has no motion.accel_std; pass --param q=<m²/s³>"))
    }
}

/// Settings given as a name → value map: the live service's `[tracker] params` and the
/// parameters of a `PUT /api/v1/estimator`.
impl From<&BTreeMap<String, f64>> for Params {
    fn from(map: &BTreeMap<String, f64>) -> Self {
        Self(map.clone())
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
