//! The estimators `harrier replay` can run, and the glue they share: building the prior and the
//! measurement models from `scenario.json`, and writing estimate lines.

pub mod angles;
pub mod bearings;
pub mod bias;
pub mod gaussian;
pub mod icdkf;
pub mod imm;
pub mod obe;
pub mod tracker;

use harrier_core::measurement::{AzEl, BearingSize, Geometry, Position, RangeBearing, TargetSize};
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

/// Noise standard deviations of a sensor as a fixed-size array.
fn noise_std<const M: usize>(sc: &Scenario, sensor: &str) -> Result<[f64; M], EngineError> {
    let s = sc
        .sensor(sensor)
        .ok_or_else(|| setup(format!("unknown sensor {sensor:?}")))?;
    let std = s.noise.std();
    std.try_into().map_err(|_| {
        setup(format!(
            "sensor {sensor:?}: noise does not have {M} components"
        ))
    })
}

/// A measurement model for one measurement line, of whichever kind it is.
#[derive(Debug, Clone, Copy)]
pub enum AnyModel {
    /// `position`, 2 components.
    Position2(Position<2>),
    /// `position`, 3 components.
    Position3(Position<3>),
    /// `range_bearing`.
    RangeBearing(RangeBearing),
    /// `az_el`.
    AzEl(AzEl),
    /// `bearing_size`.
    BearingSize(BearingSize),
}

/// Builds the measurement model of `m` (sensor noise from the scenario, sensor at the platform).
pub fn model_for(
    sc: &Scenario,
    geo: Geometry,
    m: &Measurement,
    size: Option<TargetSize>,
) -> Result<AnyModel, EngineError> {
    let pos = Vector3::from(m.platform.pos);
    Ok(match m.kind {
        MeasKind::Position if m.z.len() == 2 => {
            AnyModel::Position2(Position::new(geo, noise_std(sc, &m.sensor)?))
        }
        MeasKind::Position => AnyModel::Position3(Position::new(geo, noise_std(sc, &m.sensor)?)),
        MeasKind::RangeBearing => {
            AnyModel::RangeBearing(RangeBearing::new(geo, pos, noise_std(sc, &m.sensor)?))
        }
        MeasKind::AzEl => AnyModel::AzEl(AzEl::new(geo, pos, noise_std(sc, &m.sensor)?)),
        MeasKind::BearingSize => {
            let size = size
                .or(sc.target.size_m.map(TargetSize::Known))
                .ok_or_else(|| {
                    setup("bearing_size measurements need target.size_m or a size state")
                })?;
            AnyModel::BearingSize(BearingSize::new(geo, pos, size, noise_std(sc, &m.sensor)?))
        }
    })
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
