//! The registry: every replay estimator Harrier can run by name ([`ESTIMATORS`]) and [`build`],
//! which turns a name, a scenario and `--param` settings into a `Box<dyn ReplayEstimator>`; every
//! track filter of the live tracker by name ([`TRACK_FILTERS`]) and [`build_track_filter`], which
//! turns a name, a [`Deployment`] and parameters into a `Box<dyn TrackEngine>`. This is the only
//! module that knows the drivers; `harrier replay`, `harrier guidance-sim` and the live service
//! get their estimators here.

use harrier_core::scenario::Scenario;

use crate::estimators::{
    angles, bearings, bias, gaussian, icdkf, imm, multi_target, obe, registration,
};
use crate::{
    Deployment, EngineError, EstimatorInfo, Params, ReplayEstimator, TrackEngine, TrackFilterInfo,
    setup,
};

/// Every replay estimator Harrier can run by name (`harrier replay -e NAME`), in the order
/// `harrier estimators` lists them.
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
    registration::REGISTRATION,
    bearings::MPEKF,
    bearings::MPEKF_NN,
    imm::IMM,
    imm::CIMM,
    imm::CIMM_FUSION,
    imm::CIMM_CI,
    multi_target::TRACKER,
];

/// The replay estimator called `name`.
pub fn find(name: &str) -> Result<&'static EstimatorInfo, EngineError> {
    ESTIMATORS.iter().find(|e| e.name == name).ok_or_else(|| {
        let names: Vec<_> = ESTIMATORS.iter().map(|e| e.name).collect();
        setup(format!(
            "unknown estimator {name:?}; known: {}",
            names.join(", ")
        ))
    })
}

/// Every track filter by name: the filter each track of the live tracker runs, chosen by
/// `[tracker] estimator` and `PUT /api/v1/estimator` (the replay estimator `tracker` runs `ekf`).
/// The names `ekf`, `cdkf`, `imm` and `cimm` are also replay estimators, which are other programs.
pub static TRACK_FILTERS: &[TrackFilterInfo] = &[
    multi_target::TRACK_FILTER_EKF,
    multi_target::TRACK_FILTER_CDKF,
    multi_target::TRACK_FILTER_IMM,
    multi_target::TRACK_FILTER_CIMM,
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

/// Looks up the replay estimator `name` and builds it for `sc`, rejecting unknown parameters.
pub fn build(
    name: &str,
    sc: &Scenario,
    params: &Params,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let info = find(name)?;
    check_params("estimator", name, info.params, params)?;
    (info.build)(sc, params)
}

/// Looks up the track filter `name` and builds its track engine for `deployment`, rejecting
/// unknown parameters.
pub fn build_track_filter(
    name: &str,
    deployment: &Deployment,
    params: &Params,
) -> Result<Box<dyn TrackEngine>, EngineError> {
    let info = TRACK_FILTERS
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| {
            let names: Vec<_> = TRACK_FILTERS.iter().map(|e| e.name).collect();
            setup(format!(
                "unknown track filter {name:?}; known: {}",
                names.join(", ")
            ))
        })?;
    check_params("track filter", name, info.params, params)?;
    (info.build)(deployment, params)
}
