//! Single-model Gaussian filters (KF, EKF, CDKF) with the nearly-constant-velocity model of the
//! scenario (`motion.accel_std`), planar or 3-D, over any mix of measurement kinds.

use harrier_core::filter::{CentralDifference, Extended, Kalman, Predictor, Updater};
use harrier_core::measurement::{MeasKind, SensorModel};
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, Scenario};
use harrier_core::state::Gaussian;
use harrier_core::{EstimationError, Result};

use super::{cv_estimate, geometry, model_for, prior, reading, update};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

const PARAMS: &[(&str, &str)] = &[Q_PARAM];

/// `kf`: linear Kalman filter (position measurements only).
pub const KF: EstimatorInfo = EstimatorInfo {
    name: "kf",
    summary: "Kalman filter, CV model, Joseph form (linear position measurements only)",
    params: PARAMS,
    build: |sc, p| {
        if let Some(s) = sc.sensors.iter().find(|s| s.kind != MeasKind::Position) {
            return Err(setup(format!(
                "the linear KF takes only position measurements, sensor {:?} is {:?}; use ekf or cdkf",
                s.id, s.kind
            )));
        }
        build(sc, p, Kalman)
    },
};

/// `ekf`: extended Kalman filter.
pub const EKF: EstimatorInfo = EstimatorInfo {
    name: "ekf",
    summary: "extended Kalman filter, CV model, any measurement kind",
    params: PARAMS,
    build: |sc, p| build(sc, p, Extended),
};

/// `cdkf`: central-difference Kalman filter.
pub const CDKF: EstimatorInfo = EstimatorInfo {
    name: "cdkf",
    summary: "central-difference Kalman filter (h² = 3), CV model, any measurement kind ([ICDKF] baseline)",
    params: &[Q_PARAM, ("h", "central-difference interval (default √3)")],
    build: |sc, p| {
        let cd = CentralDifference::new(p.get("h", 3f64.sqrt()))?;
        build(sc, p, cd)
    },
};

/// The measurement update of a filter usable by [`SingleTargetCv`] (the prediction is its
/// [`Predictor`] for the CV model): EKF and CDKF take every measurement kind, the linear KF only
/// positions.
pub trait CvUpdate<const N: usize> {
    /// Update with the measurement `z` of model `model`.
    fn update_one(&self, model: &SensorModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>>;
}

impl<const N: usize> CvUpdate<N> for Extended {
    fn update_one(&self, model: &SensorModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        update(self, model, g, z)
    }
}

impl<const N: usize> CvUpdate<N> for CentralDifference {
    fn update_one(&self, model: &SensorModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        update(self, model, g, z)
    }
}

impl<const N: usize> CvUpdate<N> for Kalman {
    fn update_one(&self, model: &SensorModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        match model {
            SensorModel::Position2(h) => Ok(self.update(h, g, &reading(z)?)?.state),
            SensorModel::Position3(h) => Ok(self.update(h, g, &reading(z)?)?.state),
            _ => Err(EstimationError::InvalidParameter(
                "the linear KF takes only position measurements; use ekf or cdkf".into(),
            )),
        }
    }
}

/// One target estimated by one Gaussian filter with the CV model, over the measurements of a
/// scenario.
#[derive(Debug)]
pub struct SingleTargetCv<F, const N: usize> {
    algo: F,
    motion: ConstantVelocity<N>,
    sc: Scenario,
    t: f64,
    state: Gaussian<N>,
}

impl<F, const N: usize> SingleTargetCv<F, N> {
    fn new(sc: &Scenario, params: &Params, algo: F) -> Result<Self, EngineError> {
        let q = params.q(sc)?;
        let (t, state) = prior::<N>(sc, super::cv_dims(N))?;
        Ok(Self {
            algo,
            motion: ConstantVelocity::new(q),
            sc: sc.clone(),
            t,
            state,
        })
    }
}

impl<F, const N: usize> ReplayEstimator for SingleTargetCv<F, N>
where
    F: Predictor<ConstantVelocity<N>, N, State = Gaussian<N>> + CvUpdate<N>,
{
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let geo = geometry(&self.sc);
        let mut g = self.state;
        let mut t = self.t;
        for m in step.measurements {
            if m.t > t {
                g = self.algo.predict(&self.motion, &g, m.t - t)?;
                t = m.t;
            }
            let model = model_for(&self.sc, geo, m, None)?;
            g = self.algo.update_one(&model, &g, &m.z)?;
        }
        self.state = g;
        self.t = t;
        Ok(Some(cv_estimate(self.sc.plane_z(), t, &g)))
    }
}

fn build<F>(
    sc: &Scenario,
    params: &Params,
    algo: F,
) -> Result<Box<dyn ReplayEstimator>, EngineError>
where
    F: Predictor<ConstantVelocity<4>, 4, State = Gaussian<4>>
        + Predictor<ConstantVelocity<6>, 6, State = Gaussian<6>>
        + CvUpdate<4>
        + CvUpdate<6>
        + 'static,
{
    Ok(if sc.dims == 2 {
        Box::new(SingleTargetCv::<F, 4>::new(sc, params, algo)?)
    } else {
        Box::new(SingleTargetCv::<F, 6>::new(sc, params, algo)?)
    })
}
