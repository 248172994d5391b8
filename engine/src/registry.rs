//! The registry: every replay estimator Harrier can run by name ([`ESTIMATORS`]) and [`build`],
//! which turns a name, a scenario and `--param` settings into a `Box<dyn ReplayEstimator>`; every
//! track filter ([`TRACK_FILTERS`]) and associator ([`ASSOCIATORS`]) of the live tracker by name,
//! and [`build_track_engine`], which turns a track filter's and an associator's names, a
//! [`Deployment`] and parameters into a `Box<dyn TrackEngine>` ([`build_tracker`]: the same
//! engine as the replay estimator `tracker`). This is the only module that knows the drivers;
//! `harrier replay`, `harrier guidance-sim` and the live service get their estimators here.

use harrier_core::scenario::Scenario;

use crate::estimators::{
    angles, associators, bearings, bias, gaussian, icdkf, imm, multi_target, obe, registration,
};
use crate::{
    AssociatorInfo, Deployment, EngineError, EstimatorInfo, Params, RegisteredSensor,
    ReplayEstimator, TrackEngine, TrackFilterInfo, setup,
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
    named("estimator", ESTIMATORS, name, |e| e.name)
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

/// Every associator by name: how the live tracker associates detections with tracks, chosen
/// like the track filters (any associator runs with any track filter).
pub static ASSOCIATORS: &[AssociatorInfo] = &[
    associators::ASSOCIATOR_GNN,
    associators::ASSOCIATOR_JIPDA,
    associators::ASSOCIATOR_MHT,
];

/// `name`'s parameters: an error naming the first one in none of the lists `known`.
fn check_params(
    what: &str,
    name: &str,
    known: &[&[(&str, &str)]],
    params: &Params,
) -> Result<(), EngineError> {
    let known: Vec<(&str, &str)> = known.iter().flat_map(|k| k.iter().copied()).collect();
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
    check_params("estimator", name, &[info.params], params)?;
    (info.build)(sc, params)
}

/// Looks up the track filter `name` and builds its track engine with the `gnn` associator for
/// `deployment`, rejecting unknown parameters.
pub fn build_track_filter(
    name: &str,
    deployment: &Deployment,
    params: &Params,
) -> Result<Box<dyn TrackEngine>, EngineError> {
    build_track_engine(name, "gnn", deployment, params)
}

/// Looks up the track filter `filter` and the associator `associator` and builds their track
/// engine for `deployment`, rejecting parameters that neither takes.
pub fn build_track_engine(
    filter: &str,
    associator: &str,
    deployment: &Deployment,
    params: &Params,
) -> Result<Box<dyn TrackEngine>, EngineError> {
    let f = named("track filter", TRACK_FILTERS, filter, |f| f.name)?;
    let a = named("associator", ASSOCIATORS, associator, |a| a.name)?;
    check_params(
        "track filter and associator",
        &format!("{filter} + {associator}"),
        &[f.params, a.params],
        params,
    )?;
    (f.build)(deployment, params, (a.build)(deployment, params)?)
}

/// The replay estimator `tracker` with the track filter `filter` and the associator `associator`
/// (`harrier replay -e tracker --track-filter F --associator A`), for `sc`; with `register`
/// (`--register`), estimating the biases of the scenario's sensors that carry a `bias` block
/// jointly with the tracks, as the live service's `[registration]` does
/// ([`RegisteredSensor::of_scenario`]).
pub fn build_tracker(
    filter: &str,
    associator: &str,
    sc: &Scenario,
    params: &Params,
    register: bool,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let mut deployment = Deployment::from(sc);
    if register {
        deployment.registration = RegisteredSensor::of_scenario(sc)?;
        if deployment.registration.is_empty() {
            return Err(setup(
                "--register: no sensor of the scenario has a bias block with terms \
                 (FORMAT-REGISTRATION.md §1)",
            ));
        }
    }
    let engine = build_track_engine(filter, associator, &deployment, params)?;
    multi_target::replay_tracker(sc, engine)
}

/// The entry of `list` called `name`, or an error listing the names.
fn named<'a, T>(
    what: &str,
    list: &'a [T],
    name: &str,
    name_of: impl Fn(&T) -> &'static str,
) -> Result<&'a T, EngineError> {
    list.iter().find(|e| name_of(e) == name).ok_or_else(|| {
        let names: Vec<_> = list.iter().map(&name_of).collect();
        setup(format!(
            "unknown {what} {name:?}; known: {}",
            names.join(", ")
        ))
    })
}
