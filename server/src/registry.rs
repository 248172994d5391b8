//! The registry: every estimator Harrier can run by name ([`ESTIMATORS`]) and [`build`], which
//! turns a name, a scenario and `--param` settings into a `Box<dyn ReplayEstimator>`. This is the
//! only module that knows the drivers; `harrier replay`, `harrier guidance-sim` (and the live
//! service) get their estimators here.

use harrier_core::scenario::Scenario;

use crate::engine::{EngineError, EstimatorInfo, Params, ReplayEstimator, setup};
use crate::estimators::{angles, bearings, bias, gaussian, icdkf, imm, obe, tracker};

/// Every estimator Harrier can run by name, in the order `harrier estimators` lists them.
pub static ESTIMATORS: &[EstimatorInfo] = &[
    gaussian::KF,
    gaussian::EKF,
    gaussian::CDKF,
    angles::CA_KF,
    angles::STF,
    angles::ESE,
    obe::OBE,
    obe::OBE_TRACE,
    icdkf::ICDKF,
    icdkf::ICDKF_GENERAL,
    bias::CDKF_BIAS,
    bearings::MPEKF,
    bearings::MPEKF_NN,
    imm::IMM,
    imm::CIMM,
    imm::CIMM_FUSION,
    imm::CIMM_CI,
    tracker::TRACKER,
];

/// The estimator called `name`.
pub fn find(name: &str) -> Result<&'static EstimatorInfo, EngineError> {
    ESTIMATORS.iter().find(|e| e.name == name).ok_or_else(|| {
        let names: Vec<_> = ESTIMATORS.iter().map(|e| e.name).collect();
        setup(format!(
            "unknown estimator {name:?}; known: {}",
            names.join(", ")
        ))
    })
}

/// Looks up `name` and builds it for `sc`, rejecting unknown parameters.
pub fn build(
    name: &str,
    sc: &Scenario,
    params: &Params,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let info = find(name)?;
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
