//! The estimators in the loop, from the registry: a simulation describes its sensors as a small
//! in-memory `gcs-scenario/1` [`Scenario`], builds the named estimator with
//! [`registry::build`] (the one place where an estimator is chosen by name) and feeds it
//! measurement lines, exactly as `harrier replay` does.
//!
//! * Standoff cases ([`camera_scenario`]): every UAV carries a camera whose geolocation fixes are
//!   `position` measurements, σ = [`FIX_STD`], one per UAV every [`FIX_PERIOD`] (as in
//!   `cimm_road_3uav`); the `motion` block and the road are those of `cimm_road_1uav` (modes CV /
//!   CT −0.008 / CT +0.01 rad/s, q = accel_std² = 0.0025 m²/s³, transition matrix 0.98 on the
//!   diagonal, initial probabilities 0.98 / 0.01 / 0.01, road σ_m = 2 m, σ_v = σ_m / 1 s). The
//!   single-model CV filters (`kf`, `ekf`, `cdkf`) run with q = [`CV_Q`], which lets them follow
//!   the turns. The first fix starts the estimator: its prior is that fix with velocity 0,
//!   σ = 10 m and 10 m/s.
//! * Observability case ([`bearing_scenario`]): `ekf` on one `az_el` camera on the follower.

use harrier_core::scenario::{Estimate, Measurement, Prior, Scenario};
use nalgebra::Vector4;

use super::error::SimError;
use super::truth;
use harrier_engine::registry::{self, ESTIMATORS};
use harrier_engine::{EngineError, Params, ReplayEstimator, Step};

/// Standard deviation of a camera geolocation fix (m).
pub const FIX_STD: f64 = 10.0;
/// Period of the fixes of each UAV (s).
pub const FIX_PERIOD: f64 = 1.0;
/// Acceleration spectral density of the single-model CV filters on the standoff cases (m²/s³).
pub const CV_Q: f64 = 0.05;

/// A `gcs-scenario/1` document parsed into a [`Scenario`].
fn parse(doc: &serde_json::Value) -> Result<Scenario, SimError> {
    Scenario::parse(&doc.to_string())
        .map_err(|e| SimError::Setup(format!("simulated scenario: {e}")))
}

/// Sensor id of UAV `i`'s camera.
pub fn camera(i: usize) -> String {
    format!("cam{}", i + 1)
}

/// The standoff cases' sensors and target knowledge for `uavs` UAVs (see the module docs).
pub fn camera_scenario(uavs: usize) -> Result<Scenario, SimError> {
    let sensors: Vec<_> = (0..uavs)
        .map(|i| {
            serde_json::json!({
                "id": camera(i), "platform": format!("uav{}", i + 1), "kind": "position",
                "ncomp": 2, "noise": {"type": "gaussian", "std": [FIX_STD, FIX_STD]},
            })
        })
        .collect();
    let platforms: Vec<_> = (0..uavs)
        .map(|i| serde_json::json!({"id": format!("uav{}", i + 1), "kind": "uav"}))
        .collect();
    let [_, (_, right), (_, left)] = truth::ROAD_LEGS;
    let road = truth::road().map_err(|e| SimError::Setup(format!("road: {e}")))?;
    parse(&serde_json::json!({
        "format": "gcs-scenario/1", "name": "guidance-sim standoff", "dims": 2, "plane_z": 0.0,
        "time": {"t0": 0.0, "dt": FIX_PERIOD, "t_end": 36000.0},
        "target": {"id": "target"},
        "platforms": platforms,
        "sensors": sensors,
        "roads": [road],
        "motion": {
            "models": [
                {"name": "CV", "type": "CV"},
                {"name": "CT-right", "type": "CT", "turn_rate": right},
                {"name": "CT-left", "type": "CT", "turn_rate": left},
            ],
            "transition_matrix": [[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]],
            "initial_probs": [0.98, 0.01, 0.01],
            "accel_std": 0.05,
        },
    }))
}

/// The observability case's sensor: one `az_el` camera (`eo`, σ = `sigma` on both angles) on the
/// follower, the leader flying level at `altitude` (a planar scenario with `plane_z = altitude`).
pub fn bearing_scenario(altitude: f64, sigma: f64) -> Result<Scenario, SimError> {
    parse(&serde_json::json!({
        "format": "gcs-scenario/1", "name": "guidance-sim observability", "dims": 2,
        "plane_z": altitude,
        "time": {"t0": 0.0, "dt": 0.1, "t_end": 36000.0},
        "target": {"id": "leader"},
        "platforms": [{"id": "follower", "kind": "uav"}],
        "sensors": [{"id": "eo", "platform": "follower", "kind": "az_el",
                     "noise": {"type": "gaussian", "std": [sigma, sigma]}}],
    }))
}

/// Tuning of estimator `name` on the standoff cases (see the module docs).
pub fn standoff_params(name: &str) -> Params {
    if matches!(name, "kf" | "ekf" | "cdkf") {
        Params::default().with("q", CV_Q)
    } else {
        Params::default()
    }
}

/// A registry estimator run on simulated measurement lines, started from a prior when the
/// simulation has one. Reports the planar CV state `[x, y, vx, vy]` of its latest estimate.
pub struct SimEstimator {
    name: String,
    scenario: Scenario,
    params: Params,
    running: Option<Box<dyn ReplayEstimator>>,
    latest: Option<(f64, Vector4<f64>)>,
}

impl std::fmt::Debug for SimEstimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimEstimator")
            .field("name", &self.name)
            .field("started", &self.running.is_some())
            .field("latest", &self.latest)
            .finish()
    }
}

impl SimEstimator {
    /// Registry estimator `name` for `scenario` with `params`; refuses unknown names.
    pub fn new(name: &str, scenario: Scenario, params: Params) -> Result<Self, SimError> {
        if registry::find(name).is_err() {
            let names: Vec<_> = ESTIMATORS.iter().map(|e| e.name).collect();
            return Err(SimError::Setup(format!(
                "unknown estimator {name:?}; truth or one of {}",
                names.join(", ")
            )));
        }
        Ok(Self {
            name: name.to_string(),
            scenario,
            params,
            running: None,
            latest: None,
        })
    }

    /// Whether [`SimEstimator::start`] has run.
    pub fn is_started(&self) -> bool {
        self.running.is_some()
    }

    /// Builds the estimator with the planar prior `mean` = `[x, y, vx, vy]` at `t` (independent
    /// components with variances `var`); it is also the latest estimate until the first step.
    pub fn start(&mut self, t: f64, mean: Vector4<f64>, var: Vector4<f64>) -> Result<(), SimError> {
        let mut sc = self.scenario.clone();
        sc.prior = Some(Prior {
            t,
            state: [mean[0], mean[1], sc.plane_z(), mean[2], mean[3], 0.0],
            cov: (0..4)
                .map(|i| (0..4).map(|j| if i == j { var[i] } else { 0.0 }).collect())
                .collect(),
            cov_dims: Some(vec![0, 1, 3, 4]),
        });
        let built = registry::build(&self.name, &sc, &self.params)
            .map_err(|e| SimError::Setup(format!("estimator {}: {e}", self.name)))?;
        self.running = Some(built);
        self.latest = Some((t, mean));
        Ok(())
    }

    /// Processes the measurement lines of time `t` (sorted by sensor id). A numeric failure
    /// rejects them and keeps the estimator as it was (as `harrier replay` does); an estimator
    /// that cannot run on these measurements is an error. Before [`SimEstimator::start`] it does
    /// nothing.
    pub fn step(&mut self, t: f64, lines: &[Measurement]) -> Result<(), SimError> {
        let Some(est) = &mut self.running else {
            return Ok(());
        };
        let refs: Vec<&Measurement> = lines.iter().collect();
        let no_next = |_: &str| None;
        let step = Step {
            t,
            measurements: &refs,
            references: &[],
            next_time: &no_next,
        };
        match est.step(&step) {
            Ok(Some(Estimate {
                t, state: Some(s), ..
            })) => self.latest = Some((t, Vector4::new(s[0], s[1], s[3], s[4]))),
            Ok(_) | Err(EngineError::Estimation(_)) => {}
            Err(e @ EngineError::Setup(_)) => {
                return Err(SimError::Setup(format!("estimator {}: {e}", self.name)));
            }
        }
        Ok(())
    }

    /// Time and `[x, y, vx, vy]` of the latest estimate.
    pub fn latest(&self) -> Option<(f64, Vector4<f64>)> {
        self.latest
    }
}
