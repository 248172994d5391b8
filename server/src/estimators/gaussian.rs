//! Single-model Gaussian filters (KF, EKF, CDKF) with the nearly-constant-velocity model of the
//! scenario (`motion.accel_std`), planar or 3-D, over any mix of measurement kinds.

use harrier_core::filter::{CentralDifference, Extended, Kalman, Predictor, Updater};
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, MeasKind, Scenario};
use harrier_core::state::Gaussian;
use harrier_core::{EstimationError, Result};
use nalgebra::{Vector2, Vector3};

use super::{AnyModel, cv_estimate, geometry, model_for, prior};
use crate::engine::{EngineError, EstimatorInfo, Params, ReplayEstimator, Step, setup};

const PARAMS: &[(&str, &str)] = &[(
    "q",
    "acceleration spectral density, m²/s³ (default motion.accel_std²)",
)];

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
    params: &[
        (
            "q",
            "acceleration spectral density, m²/s³ (default motion.accel_std²)",
        ),
        ("h", "central-difference interval (default √3)"),
    ],
    build: |sc, p| {
        let cd = CentralDifference::new(p.get("h", 3f64.sqrt()))?;
        build(sc, p, cd)
    },
};

/// A Gaussian filter algorithm usable by [`CvTracker`]: predicts with CV and updates with any
/// measurement kind it supports.
pub trait GaussianAlgo<const N: usize> {
    /// Predict step.
    fn predict(&self, m: &ConstantVelocity<N>, g: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>>;
    /// Update step with whichever model `model` is.
    fn update(&self, model: &AnyModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>>;
}

/// Update with a nonlinear-capable filter.
fn update_any<F, const N: usize>(
    f: &F,
    model: &AnyModel,
    g: &Gaussian<N>,
    z: &[f64],
) -> Result<Gaussian<N>>
where
    F: Updater<harrier_core::measurement::Position<2>, N, 2, State = Gaussian<N>>
        + Updater<harrier_core::measurement::Position<3>, N, 3, State = Gaussian<N>>
        + Updater<harrier_core::measurement::RangeBearing, N, 2, State = Gaussian<N>>
        + Updater<harrier_core::measurement::AzEl, N, 2, State = Gaussian<N>>
        + Updater<harrier_core::measurement::BearingSize, N, 3, State = Gaussian<N>>,
{
    let z2 = || Vector2::from_iterator(z.iter().copied());
    let z3 = || Vector3::from_iterator(z.iter().copied());
    Ok(match model {
        AnyModel::Position2(h) => f.update(h, g, &z2())?.state,
        AnyModel::Position3(h) => f.update(h, g, &z3())?.state,
        AnyModel::RangeBearing(h) => f.update(h, g, &z2())?.state,
        AnyModel::AzEl(h) => f.update(h, g, &z2())?.state,
        AnyModel::BearingSize(h) => f.update(h, g, &z3())?.state,
    })
}

impl<const N: usize> GaussianAlgo<N> for Extended {
    fn predict(&self, m: &ConstantVelocity<N>, g: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        Predictor::predict(self, m, g, dt)
    }
    fn update(&self, model: &AnyModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        update_any(self, model, g, z)
    }
}

impl<const N: usize> GaussianAlgo<N> for CentralDifference {
    fn predict(&self, m: &ConstantVelocity<N>, g: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        Predictor::predict(self, m, g, dt)
    }
    fn update(&self, model: &AnyModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        update_any(self, model, g, z)
    }
}

impl<const N: usize> GaussianAlgo<N> for Kalman {
    fn predict(&self, m: &ConstantVelocity<N>, g: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        Predictor::predict(self, m, g, dt)
    }
    fn update(&self, model: &AnyModel, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>> {
        match model {
            AnyModel::Position2(h) => {
                Ok(Updater::update(self, h, g, &Vector2::from_iterator(z.iter().copied()))?.state)
            }
            AnyModel::Position3(h) => {
                Ok(Updater::update(self, h, g, &Vector3::from_iterator(z.iter().copied()))?.state)
            }
            _ => Err(EstimationError::InvalidParameter(
                "the linear KF takes only position measurements; use ekf or cdkf".into(),
            )),
        }
    }
}

/// Runs a [`GaussianAlgo`] with the CV model over the measurements of a scenario.
#[derive(Debug)]
pub struct CvTracker<F, const N: usize> {
    algo: F,
    motion: ConstantVelocity<N>,
    sc: Scenario,
    t: f64,
    state: Gaussian<N>,
}

impl<F: GaussianAlgo<N>, const N: usize> CvTracker<F, N> {
    fn new(sc: &Scenario, params: &Params, algo: F) -> Result<Self, EngineError> {
        let q = params.opt("q").or(sc.accel_q()).ok_or_else(|| {
            setup("scenario.json has no motion.accel_std; pass --param q=<m²/s³>")
        })?;
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

impl<F: GaussianAlgo<N>, const N: usize> ReplayEstimator for CvTracker<F, N> {
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
            g = self.algo.update(&model, &g, &m.z)?;
        }
        self.state = g;
        self.t = t;
        Ok(Some(cv_estimate(&self.sc, t, &g)))
    }
}

fn build<F: GaussianAlgo<4> + GaussianAlgo<6> + 'static>(
    sc: &Scenario,
    params: &Params,
    algo: F,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    Ok(if sc.dims == 2 {
        Box::new(CvTracker::<F, 4>::new(sc, params, algo)?)
    } else {
        Box::new(CvTracker::<F, 6>::new(sc, params, algo)?)
    })
}
