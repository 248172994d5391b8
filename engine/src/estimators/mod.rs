//! The drivers: each turns scenario measurements into the calls of one estimator family's filters
//! and declares its [`EstimatorInfo`](crate::EstimatorInfo) entries (and
//! [`multi_target`] its [`TrackFilterInfo`](crate::TrackFilterInfo)s, [`associators`] the
//! [`AssociatorInfo`](crate::AssociatorInfo)s); and the glue they
//! share: the prior and the measurement models from `scenario.json`, updates with a run-time
//! measurement kind, estimate lines. Drivers import [the crate root](crate) only; the registry
//! ([`crate::registry`]) lists them and is the only module that imports them.

pub mod angles;
pub mod associators;
pub mod bearings;
pub mod bias;
pub mod gaussian;
pub mod icdkf;
pub mod imm;
pub mod multi_target;
pub mod obe;
pub mod registrar;
pub mod registration;

use harrier_core::EstimationError;
use harrier_core::filter::{Extended, Imm, ModeModel, NonlinearFilter};
use harrier_core::measurement::{
    Geometry, Locate, MeasKind, MeasurementModel, SensorModel, TargetSize, WithSensor,
};
use harrier_core::registration::KnownObject;
use harrier_core::scenario::{Estimate, Measurement, Motion, ReferenceObject, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::{EngineError, Params, setup};

/// Canonical indices of an N-state CV layout: planar `[x, y, vx, vy]` or 3-D `[x, y, z, vx, vy, vz]`.
pub fn cv_dims(n: usize) -> &'static [usize] {
    if n == 4 {
        &[0, 1, 3, 4]
    } else {
        &[0, 1, 2, 3, 4, 5]
    }
}

/// Where the target position sits in CV-layout states for this scenario.
pub fn geometry(sc: &Scenario) -> Geometry {
    if sc.dims == 2 {
        Geometry::planar(sc.plane_z())
    } else {
        Geometry::spatial()
    }
}

/// The scenario's Gaussian prior restricted to the canonical `dims` (missing variances are an error)
/// and its time.
pub fn prior<const N: usize>(
    sc: &Scenario,
    dims: &[usize],
) -> Result<(f64, Gaussian<N>), EngineError> {
    let p = sc
        .prior
        .as_ref()
        .ok_or_else(|| setup("scenario.json has no prior; this estimator needs one"))?;
    let pd = p.dims();
    let mut mean = SVector::<f64, N>::zeros();
    let mut cov = SMatrix::<f64, N, N>::zeros();
    for (i, &di) in dims.iter().enumerate() {
        mean[i] = p.state[di];
        let ki = pd.iter().position(|&d| d == di).ok_or_else(|| {
            setup(format!(
                "prior.cov does not cover canonical state index {di}"
            ))
        })?;
        for (j, &dj) in dims.iter().enumerate() {
            if let Some(kj) = pd.iter().position(|&d| d == dj) {
                cov[(i, j)] = p.cov[ki][kj];
            }
        }
    }
    let g = Gaussian::new(mean, cov).map_err(|e| setup(format!("prior: {e}")))?;
    Ok((p.t, g))
}

/// A cooperative reference's object (`references.jsonl`, FORMAT-REGISTRATION.md §2) as the
/// registration filters take it: its position and velocity, the covariance of its reported
/// standard deviations.
pub fn known_object(o: &ReferenceObject) -> KnownObject {
    KnownObject {
        pos: Vector3::from(o.pos),
        vel: Vector3::from(o.vel),
        cov: Matrix3::from_diagonal(&Vector3::from(o.std).map(|s| s * s)),
    }
}

/// The measurement model of one measurement line (sensor noise from the scenario, sensor at the
/// platform): the run-time kind of the line as a [`SensorModel`], which [`SensorModel::apply`]
/// turns back into the concrete model.
pub fn model_for(
    sc: &Scenario,
    geo: Geometry,
    m: &Measurement,
    size: Option<TargetSize>,
) -> Result<SensorModel, EngineError> {
    let sensor = sc
        .sensor(&m.sensor)
        .ok_or_else(|| setup(format!("unknown sensor {:?}", m.sensor)))?;
    let size = size.or(sc.target.size_m.map(TargetSize::Known));
    if m.kind == MeasKind::BearingSize && size.is_none() {
        return Err(setup(
            "bearing_size measurements need target.size_m or a size state",
        ));
    }
    SensorModel::new(
        m.kind,
        geo,
        Vector3::from(m.platform.pos),
        &sensor.noise.std(),
        size,
    )
    .map_err(|e| setup(format!("sensor {:?}: {e}", m.sensor)))
}

/// The components of a measurement line as the fixed-size vector of an M-component model.
pub fn reading<const M: usize>(z: &[f64]) -> harrier_core::Result<SVector<f64, M>> {
    <[f64; M]>::try_from(z).map(SVector::from).map_err(|_| {
        EstimationError::InvalidParameter(format!(
            "measurement has {} components, its sensor model {M}",
            z.len()
        ))
    })
}

/// One update of a Gaussian filter with a measurement line whose model is known only at run time
/// (visited through [`SensorModel::apply`]).
pub fn update<F: NonlinearFilter<N>, const N: usize>(
    filter: &F,
    model: &SensorModel,
    state: &Gaussian<N>,
    z: &[f64],
) -> harrier_core::Result<Gaussian<N>> {
    struct Visit<'a, F, const N: usize> {
        filter: &'a F,
        state: &'a Gaussian<N>,
        z: &'a [f64],
    }
    impl<F: NonlinearFilter<N>, const N: usize> WithSensor<N> for Visit<'_, F, N> {
        type Output = harrier_core::Result<Gaussian<N>>;
        fn with<H, const M: usize>(self, model: &H) -> Self::Output
        where
            H: MeasurementModel<N, M> + Locate<M>,
        {
            Ok(self
                .filter
                .update_with(model, self.state, &reading(self.z)?)?
                .state)
        }
    }
    model.apply(Visit { filter, state, z })
}

/// An estimate line from an N-state CV-layout Gaussian (planar: z = `plane_z`, vz = 0).
pub fn cv_estimate<const N: usize>(plane_z: f64, t: f64, g: &Gaussian<N>) -> Estimate {
    let dims = cv_dims(N);
    let mut state = [0.0; 6];
    state[2] = plane_z;
    for (i, &d) in dims.iter().enumerate() {
        state[d] = g.mean[i];
    }
    let cov = (0..N)
        .map(|i| (0..N).map(|j| g.cov[(i, j)]).collect())
        .collect();
    Estimate {
        t,
        state: Some(state),
        cov: Some(cov),
        cov_dims: Some(dims.to_vec()),
        ..Estimate::default()
    }
}

/// The mode models of `motion.models`.
pub fn mode_models(motion: Option<&Motion>, q: f64) -> Result<Vec<ModeModel>, EngineError> {
    let m = motion
        .filter(|m| !m.models.is_empty())
        .ok_or_else(|| setup("scenario.json has no motion.models; the IMM estimators need them"))?;
    m.models
        .iter()
        .map(|spec| match spec.kind.to_ascii_uppercase().as_str() {
            "CV" => Ok(ModeModel::Cv { q }),
            "CT" => spec
                .turn_rate
                .filter(|w| w.is_finite())
                .map(|omega| ModeModel::Ct { omega, q })
                .ok_or_else(|| setup(format!("motion model {:?}: CT needs turn_rate", spec.name))),
            other => Err(setup(format!(
                "motion model {:?}: type {other:?} is not supported (CV, CT)",
                spec.name
            ))),
        })
        .collect()
}

/// The IMM of `motion.models` (`models`, R of them) with `motion.transition_matrix` (default: stay
/// with probability 0.98) and `motion.initial_probs` (default uniform), EKF mode filters.
pub fn imm_of<const R: usize>(
    motion: Option<&Motion>,
    models: &[ModeModel],
) -> Result<(Imm<Extended, ModeModel, R>, [f64; R]), EngineError> {
    let models: [ModeModel; R] = models
        .try_into()
        .map_err(|_| setup("internal: mode count mismatch"))?;
    let off = if R > 1 { 0.02 / (R - 1) as f64 } else { 0.0 };
    let tpm: [[f64; R]; R] = match motion.and_then(|m| m.transition_matrix.as_ref()) {
        Some(rows) => {
            if rows.len() != R || rows.iter().any(|r| r.len() != R) {
                return Err(setup(format!(
                    "motion.transition_matrix must be {R} × {R} (one row per model)"
                )));
            }
            std::array::from_fn(|i| std::array::from_fn(|j| rows[i][j]))
        }
        None => std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                if i == j {
                    1.0 - off * (R - 1) as f64
                } else {
                    off
                }
            })
        }),
    };
    let probs: [f64; R] = match motion.and_then(|m| m.initial_probs.as_ref()) {
        Some(p) => p
            .as_slice()
            .try_into()
            .map_err(|_| setup(format!("motion.initial_probs must have {R} entries")))?,
        None => [1.0 / R as f64; R],
    };
    let imm = Imm::new(Extended, models, tpm)
        .map_err(|e| setup(format!("motion.transition_matrix: {e}")))?;
    Ok((imm, probs))
}

/// An integer parameter ≥ 1.
pub fn count(p: &Params, name: &str, default: u32) -> Result<u32, EngineError> {
    let v = p.get(name, f64::from(default));
    if v.fract() != 0.0 || !(1.0..=1e6).contains(&v) {
        return Err(setup(format!("--param {name} must be a whole number ≥ 1")));
    }
    Ok(v as u32)
}
