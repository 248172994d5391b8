//! Type erasure of the estimators: every estimator Harrier can run by name implements
//! [`ReplayEstimator`] and is listed once in [`ESTIMATORS`]. This is the only place where generic
//! harrier-core filters become trait objects.

use std::collections::BTreeMap;

use harrier_core::EstimationError;
use harrier_core::scenario::{Estimate, Measurement, Scenario};

use crate::estimators;

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
    fn names(&self) -> impl Iterator<Item = &str> {
        self.0.keys().map(String::as_str)
    }
}

/// Builds an estimator for a scenario.
pub type BuildFn = fn(&Scenario, &Params) -> Result<Box<dyn ReplayEstimator>, EngineError>;

/// A named estimator.
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

/// Every estimator Harrier can run by name.
pub static ESTIMATORS: &[EstimatorInfo] = &[
    estimators::gaussian::KF,
    estimators::gaussian::EKF,
    estimators::gaussian::CDKF,
    estimators::angles::CA_KF,
    estimators::angles::STF,
    estimators::angles::ESE,
    estimators::obe::OBE,
    estimators::obe::OBE_TRACE,
    estimators::icdkf::ICDKF,
    estimators::icdkf::ICDKF_GENERAL,
    estimators::bias::CDKF_BIAS,
    estimators::bearings::MPEKF,
    estimators::bearings::MPEKF_NN,
    estimators::imm::IMM,
    estimators::imm::CIMM,
    estimators::imm::CIMM_FUSION,
    estimators::imm::CIMM_CI,
    estimators::tracker::TRACKER,
];

/// Looks up `name` and builds it for `sc`, rejecting unknown parameters.
pub fn build(
    name: &str,
    sc: &Scenario,
    params: &Params,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let info = ESTIMATORS.iter().find(|e| e.name == name).ok_or_else(|| {
        let names: Vec<_> = ESTIMATORS.iter().map(|e| e.name).collect();
        setup(format!(
            "unknown estimator {name:?}; known: {}",
            names.join(", ")
        ))
    })?;
    if let Some(bad) = params
        .names()
        .find(|p| !info.params.iter().any(|(n, _)| n == p))
    {
        let known: Vec<_> = info.params.iter().map(|(n, _)| *n).collect();
        return Err(setup(format!(
            "estimator {name:?} has no parameter {bad:?}; it takes: {}",
            if known.is_empty() {
                "none".to_string()
            } else {
                known.join(", ")
            }
        )));
    }
    (info.build)(sc, params)
}
