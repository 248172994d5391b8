//! Multiple-model estimators (\[CIMM\] §3): `imm`, the road-constrained `cimm` (centralised: one
//! CIMM updated sequentially with every UAV's measurements), and the multi-UAV variants
//! `cimm-fusion` (one CIMM per UAV + state-vector fusion, \[CIMM\] §3.3) and `cimm-ci` (one CIMM
//! per UAV + covariance intersection).
//!
//! Modes come from `motion.models` (`CV`, and `CT` with its known `turn_rate`), with
//! `motion.transition_matrix` and `motion.initial_probs` (defaults: 0.98 on the diagonal and the
//! rest spread evenly; uniform initial probabilities), process noise `motion.accel_std²` (or
//! `--param q=`), measurement noise from the sensors. Every mode filter is an EKF
//! (`harrier_core::filter::Extended`), so any measurement kind works. The CIMM estimators apply
//! the road pseudo-measurement of `harrier_core::road::RoadConstraint` once per time step in every
//! mode filter (after the measurements of that time), on the road nearest to the estimate, with
//! the road's `sigma_m` and a normal-velocity std `sigma_v`. The default `sigma_v = sigma_m / time.dt`
//! says the lateral offset may change by about its own std within one sensor period: a weak
//! constraint that does not over-trust the road heading (on the reference scenarios any value from
//! 0.05 to 1000 m/s changes the position RMSE by less than 2 %).
//!
//! Estimate lines carry `model_probs` aligned with `motion.models` (for the fused variants, the
//! mean of the per-UAV mode probabilities). Planar scenarios only (state `[x, y, vx, vy]`).

use harrier_core::Result;
use harrier_core::filter::{Extended, Imm, ImmState, ModeModel};
use harrier_core::fusion::{self, CiCriterion};
use harrier_core::measurement::{Locate, MeasurementModel, SensorModel, WithSensor};
use harrier_core::road::{RoadConstraint, RoadNetwork};
use harrier_core::scenario::{Estimate, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::Vector2;

use super::{cv_estimate, geometry, imm_of, mode_models, model_for, prior, reading};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

const SIGMA_V_PARAM: (&str, &str) = (
    "sigma_v",
    "std of the velocity component normal to the road, m/s (default: the road's sigma_m per \
     second of the nominal period, sigma_m / time.dt)",
);
const ROAD_PARAMS: &[(&str, &str)] = &[Q_PARAM, SIGMA_V_PARAM];

/// `imm`: IMM of EKFs over `motion.models`.
pub const IMM: EstimatorInfo = EstimatorInfo {
    name: "imm",
    summary: "IMM (CV / known-rate CT modes from motion.models), EKF mode filters, centralised",
    params: &[Q_PARAM],
    build: |sc, p| build(sc, p, Variant::Imm),
};

/// `cimm`: road-constrained IMM, all measurements in one filter.
pub const CIMM: EstimatorInfo = EstimatorInfo {
    name: "cimm",
    summary: "road-constrained IMM ([CIMM] §3.2), centralised sequential updates over all UAVs",
    params: ROAD_PARAMS,
    build: |sc, p| build(sc, p, Variant::Cimm),
};

/// `cimm-fusion`: one CIMM per UAV, state-vector fusion.
pub const CIMM_FUSION: EstimatorInfo = EstimatorInfo {
    name: "cimm-fusion",
    summary: "one CIMM per UAV + state-vector fusion ignoring cross-covariance ([CIMM] §3.3)",
    params: ROAD_PARAMS,
    build: |sc, p| build(sc, p, Variant::Fusion),
};

/// `cimm-ci`: one CIMM per UAV, covariance intersection.
pub const CIMM_CI: EstimatorInfo = EstimatorInfo {
    name: "cimm-ci",
    summary: "one CIMM per UAV + covariance intersection (min-trace ω), consistent for unknown correlation",
    params: ROAD_PARAMS,
    build: |sc, p| build(sc, p, Variant::Ci),
};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Variant {
    Imm,
    Cimm,
    Fusion,
    Ci,
}

/// One IMM over some of the measurements (all, or one platform's).
#[derive(Debug, Clone)]
struct Local<const R: usize> {
    /// Platform whose sensors feed it; `None` = every sensor.
    platform: Option<String>,
    t: f64,
    state: ImmState<4, R>,
}

/// One target estimated by an IMM (or one IMM per UAV, fused) over the measurements of a
/// scenario.
struct SingleTargetImm<const R: usize> {
    imm: Imm<Extended, ModeModel, R>,
    sc: Scenario,
    roads: Option<(RoadNetwork, Option<f64>)>,
    variant: Variant,
    locals: Vec<Local<R>>,
}

impl<const R: usize> SingleTargetImm<R> {
    fn new(
        sc: &Scenario,
        models: &[ModeModel],
        variant: Variant,
        roads: Option<(RoadNetwork, Option<f64>)>,
    ) -> Result<Self, EngineError> {
        let (imm, probs) = imm_of::<R>(sc.motion.as_ref(), models)?;
        let (t, g) = prior::<4>(sc, super::cv_dims(4))?;
        let state =
            ImmState::new(g, probs).map_err(|e| setup(format!("motion.initial_probs: {e}")))?;
        let platforms: Vec<Option<String>> = match variant {
            Variant::Imm | Variant::Cimm => vec![None],
            Variant::Fusion | Variant::Ci => {
                let mut p: Vec<String> = sc.sensors.iter().map(|s| s.platform.clone()).collect();
                p.sort();
                p.dedup();
                p.into_iter().map(Some).collect()
            }
        };
        Ok(Self {
            imm,
            sc: sc.clone(),
            roads,
            variant,
            locals: platforms
                .into_iter()
                .map(|platform| Local { platform, t, state })
                .collect(),
        })
    }

    /// IMM update with a measurement line whose model is known only at run time.
    fn update(&self, model: &SensorModel, s: &ImmState<4, R>, z: &[f64]) -> Result<ImmState<4, R>> {
        struct Visit<'a, const R: usize> {
            imm: &'a Imm<Extended, ModeModel, R>,
            state: &'a ImmState<4, R>,
            z: &'a [f64],
        }
        impl<const R: usize> WithSensor<4> for Visit<'_, R> {
            type Output = Result<ImmState<4, R>>;
            fn with<H, const M: usize>(self, model: &H) -> Self::Output
            where
                H: MeasurementModel<4, M> + Locate<M>,
            {
                self.imm.update_with(model, self.state, &reading(self.z)?)
            }
        }
        model.apply(Visit {
            imm: &self.imm,
            state: s,
            z,
        })
    }

    /// Brings one local IMM to the step's time with its measurements and the road constraint.
    fn advance(&self, local: &Local<R>, step: &Step<'_>) -> Result<Local<R>, EngineError> {
        let geo = geometry(&self.sc);
        let mut s = local.state;
        let mut t = local.t;
        for m in step.measurements {
            if let Some(p) = &local.platform {
                if self.sc.sensor(&m.sensor).is_none_or(|s| &s.platform != p) {
                    continue;
                }
            }
            if m.t > t {
                s = self.imm.predict(&s, m.t - t)?;
                t = m.t;
            }
            let model = model_for(&self.sc, geo, m, None)?;
            s = self.update(&model, &s, &m.z)?;
        }
        if step.t > t {
            s = self.imm.predict(&s, step.t - t)?;
            t = step.t;
        }
        if let Some((net, sigma_v)) = &self.roads {
            s = road_update(&self.imm, &s, net, *sigma_v, self.sc.time.dt)?;
        }
        Ok(Local {
            platform: local.platform.clone(),
            t,
            state: s,
        })
    }
}

/// The road pseudo-measurement of \[CIMM\] §3.1 applied once in every mode filter of `s`, on the
/// road of `net` nearest to the combined estimate, with normal-velocity std `sigma_v` (default
/// the road's `sigma_m / dt`, `dt` the sensor period). Without a road, `s` is returned as is.
fn road_update<const R: usize>(
    imm: &Imm<Extended, ModeModel, R>,
    s: &ImmState<4, R>,
    net: &RoadNetwork,
    sigma_v: Option<f64>,
    dt: f64,
) -> Result<ImmState<4, R>> {
    let c = s.combined().mean;
    match net.nearest(&Vector2::new(c[0], c[1])) {
        Some(road) => {
            let sigma_v = sigma_v.unwrap_or(road.sigma_m() / dt);
            imm.update(&RoadConstraint::new(road, sigma_v), s, &RoadConstraint::z())
        }
        None => Ok(*s),
    }
}

impl<const R: usize> ReplayEstimator for SingleTargetImm<R> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let locals = self
            .locals
            .iter()
            .map(|l| self.advance(l, step))
            .collect::<Result<Vec<_>, _>>()?;
        let tracks: Vec<Gaussian<4>> = locals.iter().map(|l| l.state.combined()).collect();
        let fused = match self.variant {
            Variant::Imm | Variant::Cimm | Variant::Fusion => fusion::state_vector_fusion(&tracks),
            Variant::Ci => fusion::covariance_intersection(&tracks, CiCriterion::Trace),
        }?;
        let n = locals.len() as f64;
        let probs: Vec<f64> = (0..R)
            .map(|j| locals.iter().map(|l| l.state.probs[j]).sum::<f64>() / n)
            .collect();
        let t = locals.first().map_or(step.t, |l| l.t);
        self.locals = locals;
        let mut e = cv_estimate(self.sc.plane_z(), t, &fused);
        e.model_probs = Some(probs);
        Ok(Some(e))
    }
}

fn build(
    sc: &Scenario,
    params: &Params,
    variant: Variant,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    if sc.dims != 2 {
        return Err(setup(
            "the IMM estimators support planar scenarios (dims = 2) only",
        ));
    }
    let q = params.q(sc)?;
    let models = mode_models(sc.motion.as_ref(), q)?;
    let roads = if variant == Variant::Imm {
        None
    } else {
        let net = RoadNetwork::from_scenario(&sc.roads)
            .map_err(|e| setup(format!("scenario.json roads: {e}")))?;
        if net.is_empty() {
            return Err(setup(
                "scenario.json has no roads; the CIMM estimators need them",
            ));
        }
        match params.opt("sigma_v") {
            // `Params` only holds finite values.
            Some(v) if v <= 0.0 => {
                return Err(setup(format!("sigma_v must be > 0, got {v}")));
            }
            sigma_v => Some((net, sigma_v)),
        }
    };
    fn boxed<const R: usize>(
        sc: &Scenario,
        models: &[ModeModel],
        variant: Variant,
        roads: Option<(RoadNetwork, Option<f64>)>,
    ) -> Result<Box<dyn ReplayEstimator>, EngineError> {
        Ok(Box::new(SingleTargetImm::<R>::new(
            sc, models, variant, roads,
        )?))
    }
    match models.len() {
        1 => boxed::<1>(sc, &models, variant, roads),
        2 => boxed::<2>(sc, &models, variant, roads),
        3 => boxed::<3>(sc, &models, variant, roads),
        4 => boxed::<4>(sc, &models, variant, roads),
        5 => boxed::<5>(sc, &models, variant, roads),
        n => Err(setup(format!(
            "motion.models has {n} models; the IMM estimators support 1 to 5"
        ))),
    }
}
