//! The incremental CDKF of \[ICDKF\] (`icdkf`, `icdkf-general`): one sensor, CV model, estimates from
//! measurement increments. The first measurement only sets the reference for the first increment.

use harrier_core::filter::{CentralDifference, IcdkfForm, IncrementalCdkf, Predictor, current};
use harrier_core::measurement::SensorModel;
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::Vector2;

use super::{cv_estimate, geometry, model_for, prior};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

const PARAMS: &[(&str, &str)] = &[Q_PARAM, ("h", "central-difference interval (default √3)")];

/// `icdkf`: additive form.
pub const ICDKF: EstimatorInfo = EstimatorInfo {
    name: "icdkf",
    summary: "incremental CDKF of [ICDKF], additive form (differenced radar measurements)",
    params: PARAMS,
    build: |sc, p| build(sc, p, IcdkfForm::Additive),
};

/// `icdkf-general`: noise-augmented form.
pub const ICDKF_GENERAL: EstimatorInfo = EstimatorInfo {
    name: "icdkf-general",
    summary: "incremental CDKF of [ICDKF], general form (noise augmented into the sigma points)",
    params: PARAMS,
    build: |sc, p| build(sc, p, IcdkfForm::General),
};

fn build(
    sc: &Scenario,
    p: &Params,
    form: IcdkfForm,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    if sc.dims != 2 {
        return Err(setup("icdkf supports planar (dims = 2) scenarios"));
    }
    if sc.sensors.len() != 1 {
        return Err(setup(
            "icdkf differences consecutive measurements of one sensor; the scenario must have exactly one",
        ));
    }
    let q = p.q(sc)?;
    let (t, state) = prior::<4>(sc, super::cv_dims(4))?;
    let filter = IncrementalCdkf {
        cd: CentralDifference::new(p.get("h", 3f64.sqrt()))?,
        form,
    };
    Ok(Box::new(Icdkf {
        filter,
        motion: ConstantVelocity::new(q),
        sc: sc.clone(),
        t,
        state,
        last: None,
    }))
}

#[derive(Debug)]
struct Icdkf {
    filter: IncrementalCdkf,
    motion: ConstantVelocity<4>,
    sc: Scenario,
    t: f64,
    state: Gaussian<4>,
    /// Previous measurement and its model.
    last: Option<(Vector2<f64>, SensorModel)>,
}

impl ReplayEstimator for Icdkf {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let geo = geometry(&self.sc);
        for m in step.measurements {
            let model = model_for(&self.sc, geo, m, None)?;
            let z = Vector2::new(m.z[0], m.z[1]);
            let dt = m.t - self.t;
            match (&self.last, &model) {
                (None, _) => {
                    // First measurement: predict the prior to it; it only sets the reference.
                    if dt > 0.0 {
                        self.state =
                            CentralDifference::default().predict(&self.motion, &self.state, dt)?;
                    }
                }
                (Some((zp, SensorModel::RangeBearing(prev))), SensorModel::RangeBearing(now)) => {
                    let pred: Gaussian<8> = self.filter.predict(&self.motion, &self.state, dt)?;
                    let dz =
                        Vector2::new(z[0] - zp[0], harrier_core::linalg::wrap_angle(z[1] - zp[1]));
                    let post = self.filter.update::<_, 4, 8, 2>(now, prev, &pred, &dz)?;
                    self.state = current(&post.state);
                }
                (Some((zp, SensorModel::AzEl(prev))), SensorModel::AzEl(now)) => {
                    let pred: Gaussian<8> = self.filter.predict(&self.motion, &self.state, dt)?;
                    let dz =
                        Vector2::new(harrier_core::linalg::wrap_angle(z[0] - zp[0]), z[1] - zp[1]);
                    let post = self.filter.update::<_, 4, 8, 2>(now, prev, &pred, &dz)?;
                    self.state = current(&post.state);
                }
                _ => return Err(setup("icdkf supports range_bearing and az_el sensors")),
            }
            self.t = m.t;
            self.last = Some((z, model));
        }
        Ok(Some(cv_estimate(self.sc.plane_z(), self.t, &self.state)))
    }
}
