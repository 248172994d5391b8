//! The registry: every estimator Harrier can run by name ([`ESTIMATORS`]) and [`build`], which
//! turns a name, a scenario and `--param` settings into a `Box<dyn ReplayEstimator>`. This is the
//! only module that knows the drivers; `harrier replay`, `harrier guidance-sim` (and the live
//! service) get their estimators here.

use harrier_core::scenario::Scenario;

use crate::engine::{
    Deployment, EngineError, EstimatorInfo, Params, ReplayEstimator, TrackEngine, TrackEngineInfo,
    setup,
};
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

/// Every track engine by the name of its per-track estimator: the live service's choice, and
/// what `harrier replay -e tracker` runs (`ekf`).
pub static TRACK_ENGINES: &[TrackEngineInfo] = &[
    tracker::ENGINE_EKF,
    tracker::ENGINE_CDKF,
    tracker::ENGINE_IMM,
    tracker::ENGINE_CIMM,
];

/// `name`'s parameters: an error naming the first one not in `known`.
fn check_params(
    what: &str,
    name: &str,
    known: &[(&str, &str)],
    params: &Params,
) -> Result<(), EngineError> {
    match params.names().find(|p| !known.iter().any(|(n, _)| n == p)) {
        None => Ok(()),
        Some(bad) => {
            let known: Vec<_> = known.iter().map(|(n, _)| *n).collect();
            Err(setup(format!(
                "{what} {name:?} has no parameter {bad:?}; it takes: {}",
                if known.is_empty() {
                    "none".to_string()
                } else {
                    known.join(", ")
                }
            )))
        }
    }
}

/// Looks up `name` and builds it for `sc`, rejecting unknown parameters.
pub fn build(
    name: &str,
    sc: &Scenario,
    params: &Params,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let info = find(name)?;
    check_params("estimator", name, info.params, params)?;
    (info.build)(sc, params)
}

/// Looks up the track engine `name` and builds it for `deployment`, rejecting unknown parameters.
pub fn build_track_engine(
    name: &str,
    deployment: &Deployment,
    params: &Params,
) -> Result<Box<dyn TrackEngine>, EngineError> {
    let info = TRACK_ENGINES
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| {
            let names: Vec<_> = TRACK_ENGINES.iter().map(|e| e.name).collect();
            setup(format!(
                "unknown track estimator {name:?}; known: {}",
                names.join(", ")
            ))
        })?;
    check_params("track estimator", name, info.params, params)?;
    (info.build)(deployment, params)
}
