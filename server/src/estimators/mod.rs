//! The drivers: each turns scenario measurements into the calls of one estimator family's filters
//! and declares its [`EstimatorInfo`](crate::engine::EstimatorInfo) entries; and the glue they
//! share: the prior and the measurement models from `scenario.json`, updates with a run-time
//! measurement kind, estimate lines. Drivers import [`crate::engine`] only; the registry
//! ([`crate::registry`]) lists them.

pub mod angles;
pub mod bearings;
pub mod bias;
pub mod gaussian;
pub mod icdkf;
pub mod imm;
pub mod obe;
pub mod tracker;

use harrier_core::EstimationError;
use harrier_core::filter::NonlinearFilter;
use harrier_core::measurement::{
    Geometry, Locate, MeasurementModel, SensorModel, TargetSize, WithSensor,
};
use harrier_core::scenario::{Estimate, MeasKind, Measurement, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::{SMatrix, SVector, Vector3};

use crate::engine::{EngineError, setup};

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

/// An estimate line from an N-state CV-layout Gaussian (planar: z = plane_z, vz = 0).
pub fn cv_estimate<const N: usize>(sc: &Scenario, t: f64, g: &Gaussian<N>) -> Estimate {
    let dims = cv_dims(N);
    let mut state = [0.0; 6];
    state[2] = sc.plane_z();
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
