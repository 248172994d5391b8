//! Bearings-only (angle + subtended angle) tracking from a moving platform with the modified-polar
//! EKF of \[BOT\] §II (`harrier_core::filter::mpekf`), for scenarios with one `bearing_size` or
//! `az_el` sensor:
//!
//! * `mpekf` — the modified-spherical EKF relative to the platform (\[BOT\] eq. (1) in 3-D), with the
//!   subtended-angle measurement and, when `target.size_m` is not given, a size state whose prior is
//!   `target.size_prior` (\[BOT\] §II.C);
//! * `mpekf-nn` — the same filter augmented with the adaptive neural network of \[BOT\] §II.D
//!   (`harrier_core::filter::nn`), which estimates the target acceleration online.
//!
//! The filter starts from the scenario's Cartesian prior transformed to modified-spherical
//! coordinates around the platform (first-order covariance transform), and every estimate line is
//! the posterior transformed back to the canonical Cartesian state. Planar scenarios (`dims` 2) are
//! tracked in 3-D with the Up coordinate known (`plane_z`, a 1 m / 0.1 m/s prior and no vertical
//! process noise); only `[x, y, vx, vy]` is reported. Extra keys: `size_est` (m) with a size
//! state, `accel_est` (m/s², ENU) with the network.
//!
//! # The network's training signal
//!
//! \[BOT\] trains the network on "the residuals produced by the EKF". The residual enters the state
//! through the gain, and what it says about the acceleration is the velocity correction of the
//! update over the step, `e = (ḋ⁺ − ḋ⁻)/Δt` (relative Cartesian velocity, m/s²): zero on average
//! exactly when the acceleration the network feeds to the prediction explains the data. The network
//! inputs are a bias, the estimated target heading `û` (unit velocity) and its change `û − ū`
//! against a lagged heading `ū` (first-order lag `nn_lag`: the tapped-delay input of \[BOT\]'s
//! refs. \[14\], \[15\], which tells a left from a right turn at the same heading), normalised by the
//! largest turn `nn_lag · nn_amax / speed`; the output is bounded by `nn_amax`.
//!
//! What the network has not learnt yet is still acceleration the CV model does not contain. Its
//! low-passed training error `ē` (time constant `nn_tau`) is added to the process noise as white
//! acceleration of density `nn_tau · ‖ē‖² / D` (D = 2 planar, 3 spatial), which widens the
//! covariance while the network adapts. This is only partial: with the size unknown the remaining
//! acceleration error still biases the size and range and the NEES stays above its bound (figures
//! in `tests/tests/it/bearings.rs`).
//!
//! After each update 1/r is projected back onto `r ≤ 100 km` (and S onto `S ≥ 1 cm`) when a
//! linear update overshoots through infinite range, which angles-only data can cause
//! ([`project_lower_bound`]).
//!
//! # References
//! * \[BOT\] "Vision-based estimation and formation control of multiple aircraft"
//!   (`shared/papers/002`), §II.

use harrier_core::filter::mpekf::{
    INV_RANGE, ModifiedPolarEkf, MpAzEl, MpBearingSize, PlatformStep, SIZE, from_cartesian,
    mp_to_relative, project_lower_bound, to_cartesian,
};
use harrier_core::filter::nn::AdaptiveNn;
use harrier_core::filter::{Extended, Predictor, Updater};
use harrier_core::measurement::{MeasKind, TargetSize};
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, Measurement, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::{SMatrix, SVector, Vector2, Vector3, Vector6};

use super::{cv_dims, prior};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

/// `mpekf`: modified-polar EKF without the network.
pub const MPEKF: EstimatorInfo = EstimatorInfo {
    name: "mpekf",
    summary: "modified-polar (spherical) EKF relative to the moving platform, subtended angle, size state if unknown ([BOT] §II); one bearing_size or az_el sensor",
    params: &[Q_PARAM],
    build: |sc, p| build(sc, p, false),
};

/// `mpekf-nn`: modified-polar EKF with the adaptive network.
pub const MPEKF_NN: EstimatorInfo = EstimatorInfo {
    name: "mpekf-nn",
    summary: "mpekf augmented with the adaptive neural network that learns the target acceleration ([BOT] §II.D)",
    params: &[
        Q_PARAM,
        (
            "nn_tau",
            "adaptation time constant of the network, s (default 2)",
        ),
        (
            "nn_amax",
            "bound on the network's acceleration, m/s² (default motion.accel_bound, else 3·accel_std)",
        ),
        ("nn_kappa", "e-modification leak gain (default 0.01)"),
        (
            "nn_lag",
            "time constant of the lagged-heading input, s (default 1)",
        ),
    ],
    build: |sc, p| build(sc, p, true),
};

/// Largest range the filter reports (m): beyond any camera's detection range.
const MAX_RANGE: f64 = 1.0e5;
/// Smallest target size the filter reports (m).
const MIN_SIZE: f64 = 0.01;

/// Hidden units of the network (the last is the bias unit).
const HIDDEN: usize = 8;
/// The network: input `[1, heading û, heading change û − ū]` (7), output the target acceleration
/// (ENU).
type Net = AdaptiveNn<7, HIDDEN, 3>;

/// Measurement model on the modified-spherical state.
#[derive(Debug, Clone, Copy)]
enum Model {
    BearingSize(MpBearingSize),
    AzEl(MpAzEl),
}

/// The estimate at time `t`: the modified-polar Gaussian and the Cartesian position and velocity
/// it maps to.
#[derive(Debug, Clone, Copy)]
struct MpEstimate<const N: usize> {
    t: f64,
    g: Gaussian<N>,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
}

#[derive(Debug)]
struct MpTracker<const N: usize> {
    filter: ModifiedPolarEkf,
    model: Model,
    sensor: String,
    /// `Some(plane_z)` for planar scenarios.
    plane: Option<f64>,
    q: f64,
    cart_prior: (f64, Gaussian<6>),
    size_prior: Option<(f64, f64)>,
    track: Option<MpEstimate<N>>,
    nn: Option<Net>,
    /// Tapped-delay input of the network: heading low-passed with time constant `lag` (ū).
    lagged_heading: Option<Vector3<f64>>,
    /// Time constant of ū (s).
    lag: f64,
    /// Bound on the network's acceleration (m/s²), also the scale of its heading-change input.
    amax: f64,
    /// Adaptation time constant of the network (s).
    tau: f64,
    /// Low-passed training error ē (m/s²): the acceleration the network does not explain yet.
    unexplained: Vector3<f64>,
}

fn build(
    sc: &Scenario,
    params: &Params,
    with_nn: bool,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let [sensor] = sc.sensors.as_slice() else {
        return Err(setup(format!(
            "mpekf needs exactly one bearing_size or az_el sensor, the scenario has {}",
            sc.sensors.len()
        )));
    };
    let std = sensor.noise.std();
    let q = params.q(sc)?;
    let amax = params
        .opt("nn_amax")
        .or(sc.motion.as_ref().and_then(|m| m.accel_bound))
        .unwrap_or(3.0 * q.sqrt());
    let lag = params.get("nn_lag", 1.0);
    let tau = params.get("nn_tau", 2.0);
    let nn = if with_nn {
        if !(tau > 0.0 && amax > 0.0 && lag > 0.0) {
            return Err(setup("nn_tau, nn_lag and nn_amax must be > 0"));
        }
        let gamma = (sc.time.dt / tau).min(1.0);
        Some(
            Net::new(
                gamma,
                params.get("nn_kappa", 0.01),
                amax / (HIDDEN as f64).sqrt(),
            )
            .map_err(|e| setup(e.to_string()))?,
        )
    } else {
        None
    };
    let plane = (sc.dims == 2).then(|| sc.plane_z());
    let cart_prior = cartesian_prior(sc)?;
    let filter = ModifiedPolarEkf::new(q, if plane.is_some() { 0.0 } else { q })
        .map_err(|e| setup(e.to_string()))?;
    let known = |model: Model| MpTracker::<6> {
        filter,
        model,
        sensor: sensor.id.clone(),
        plane,
        q,
        cart_prior,
        size_prior: None,
        track: None,
        nn,
        lagged_heading: None,
        lag,
        amax,
        tau,
        unexplained: Vector3::zeros(),
    };
    match sensor.kind {
        MeasKind::AzEl => {
            let std: [f64; 2] = std
                .try_into()
                .map_err(|_| setup("az_el noise needs 2 components"))?;
            Ok(Box::new(known(Model::AzEl(MpAzEl::new(std)))) as Box<dyn ReplayEstimator>)
        }
        MeasKind::BearingSize => {
            let std: [f64; 3] = std
                .try_into()
                .map_err(|_| setup("bearing_size noise needs 3 components"))?;
            if let Some(s) = sc.target.size_m {
                let m = MpBearingSize::new(TargetSize::Known(s), std);
                Ok(Box::new(known(Model::BearingSize(m))) as Box<dyn ReplayEstimator>)
            } else {
                let sp = sc.target.size_prior.as_ref().ok_or_else(|| {
                    setup("bearing_size with unknown size needs target.size_m or target.size_prior")
                })?;
                let m = MpBearingSize::new(TargetSize::State(SIZE), std);
                Ok(Box::new(MpTracker::<7> {
                    filter,
                    model: Model::BearingSize(m),
                    sensor: sensor.id.clone(),
                    plane,
                    q,
                    cart_prior,
                    size_prior: Some((sp.mean, sp.std * sp.std)),
                    track: None,
                    nn,
                    lagged_heading: None,
                    lag,
                    amax,
                    tau,
                    unexplained: Vector3::zeros(),
                }))
            }
        }
        k => Err(setup(format!(
            "mpekf takes one bearing_size or az_el sensor, sensor {:?} is {k:?}",
            sensor.id
        ))),
    }
}

/// The scenario prior as a 3-D Cartesian Gaussian; planar scenarios get z = plane_z, vz = 0 with
/// 1 m and 0.1 m/s standard deviations.
fn cartesian_prior(sc: &Scenario) -> Result<(f64, Gaussian<6>), EngineError> {
    if sc.dims == 2 {
        let (t, g4) = prior::<4>(sc, cv_dims(4))?;
        let idx = [0, 1, 3, 4];
        let mut mean = Vector6::zeros();
        let mut cov = SMatrix::<f64, 6, 6>::zeros();
        for (i, &di) in idx.iter().enumerate() {
            mean[di] = g4.mean[i];
            for (j, &dj) in idx.iter().enumerate() {
                cov[(di, dj)] = g4.cov[(i, j)];
            }
        }
        mean[2] = sc.plane_z();
        cov[(2, 2)] = 1.0;
        cov[(5, 5)] = 0.01;
        let g = Gaussian::new(mean, cov).map_err(|e| setup(format!("prior: {e}")))?;
        Ok((t, g))
    } else {
        prior::<6>(sc, cv_dims(6))
    }
}

impl<const N: usize> MpTracker<N> {
    /// Estimated target heading (unit velocity, ENU) and speed.
    fn heading(tr: &MpEstimate<N>) -> (Vector3<f64>, f64) {
        let x = mp_to_relative(&Vector6::from_fn(|i, _| tr.g.mean[i]));
        let v = Vector3::new(x[3], x[4], x[5]) + tr.vel;
        let speed = v.norm();
        (v / speed.max(1e-3), speed)
    }

    /// Network input (\[BOT\] §II.D with the tapped-delay inputs of its refs. \[14\], \[15\]): bias, the
    /// heading û and its change û − ū against the lagged heading ū, normalised by the largest turn
    /// over the lag, `lag · nn_amax / speed`.
    fn nn_input(&self, tr: &MpEstimate<N>, lagged: Option<Vector3<f64>>) -> SVector<f64, 7> {
        let (u, speed) = Self::heading(tr);
        let du = lagged.map_or_else(Vector3::zeros, |l| u - l)
            * (speed.max(1.0) / (self.lag * self.amax));
        SVector::<f64, 7>::from_column_slice(&[1.0, u.x, u.y, u.z, du.x, du.y, du.z])
    }

    fn accel(
        &self,
        nn: Option<&Net>,
        tr: &MpEstimate<N>,
        lagged: Option<Vector3<f64>>,
    ) -> Vector3<f64> {
        let mut a = nn.map_or_else(Vector3::zeros, |nn| nn.output(&self.nn_input(tr, lagged)));
        if self.plane.is_some() {
            a.z = 0.0;
        }
        a
    }

    fn update(&self, g: &Gaussian<N>, z: &[f64]) -> Result<Gaussian<N>, EngineError> {
        let post = match &self.model {
            Model::BearingSize(h) => {
                Extended
                    .update(h, g, &Vector3::from_iterator(z.iter().copied()))?
                    .state
            }
            Model::AzEl(h) => {
                Extended
                    .update(h, g, &Vector2::from_iterator(z.iter().copied()))?
                    .state
            }
        };
        // An angles-only update can overshoot through infinite range (1/r < 0): project back onto
        // r ≤ MAX_RANGE, and the size onto S ≥ MIN_SIZE.
        let post = project_lower_bound(&post, INV_RANGE, 1.0 / MAX_RANGE)?;
        Ok(if N == 7 {
            project_lower_bound(&post, SIZE, MIN_SIZE)?
        } else {
            post
        })
    }

    fn first(
        &self,
        m: &Measurement,
        pos: Vector3<f64>,
        vel: Vector3<f64>,
    ) -> Result<Gaussian<N>, EngineError> {
        let (t0, mut cart) = self.cart_prior;
        if m.t > t0 {
            cart = Predictor::predict(
                &Extended,
                &ConstantVelocity::<6>::new(self.q),
                &cart,
                m.t - t0,
            )?;
        }
        Ok(from_cartesian::<N>(&cart, &pos, &vel, self.size_prior)?)
    }

    fn estimate(&self, tr: &MpEstimate<N>) -> Result<Estimate, EngineError> {
        let c = to_cartesian(&tr.g, &tr.pos, &tr.vel)?;
        let dims: &[usize] = if self.plane.is_some() {
            cv_dims(4)
        } else {
            cv_dims(6)
        };
        let mut state = [0.0; 6];
        for (i, s) in state.iter_mut().enumerate() {
            *s = c.mean[i];
        }
        if let Some(z) = self.plane {
            state[2] = z;
            state[5] = 0.0;
        }
        let cov = dims
            .iter()
            .map(|&i| dims.iter().map(|&j| c.cov[(i, j)]).collect())
            .collect();
        let mut extra = serde_json::Map::new();
        if N == 7 {
            extra.insert("size_est".into(), tr.g.mean[SIZE].into());
        }
        if self.nn.is_some() {
            let a = self.accel(self.nn.as_ref(), tr, self.lagged_heading);
            extra.insert("accel_est".into(), vec![a.x, a.y, a.z].into());
        }
        Ok(Estimate {
            t: tr.t,
            state: Some(state),
            cov: Some(cov),
            cov_dims: Some(dims.to_vec()),
            extra,
            ..Estimate::default()
        })
    }
}

impl<const N: usize> ReplayEstimator for MpTracker<N> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let mut track = self.track;
        let mut nn = self.nn;
        let mut lagged = self.lagged_heading;
        let mut unexplained = self.unexplained;
        for m in step.measurements.iter().filter(|m| m.sensor == self.sensor) {
            let pos = Vector3::from(m.platform.pos);
            let vel = Vector3::from(m.platform.vel);
            let Some(tr) = track else {
                let g = self.first(m, pos, vel)?;
                let g = self.update(&g, &m.z)?;
                track = Some(MpEstimate {
                    t: m.t,
                    g,
                    pos,
                    vel,
                });
                continue;
            };
            let dt = m.t - tr.t;
            let platform = PlatformStep {
                from_pos: tr.pos,
                from_vel: tr.vel,
                to_pos: pos,
                to_vel: vel,
            };
            let accel = self.accel(nn.as_ref(), &tr, lagged);
            let pred = if dt > 0.0 {
                // Unexplained acceleration ē as extra white noise of density τ‖ē‖²/D.
                let dims = if self.plane.is_some() { 2.0 } else { 3.0 };
                let q_nn = self.tau * unexplained.norm_squared() / dims;
                let mut f = self.filter;
                f.q_horizontal += q_nn;
                if self.plane.is_none() {
                    f.q_vertical += q_nn;
                }
                f.predict(&tr.g, &platform, &accel, dt)?
            } else {
                tr.g
            };
            let g = self.update(&pred, &m.z)?;
            if let (Some(net), true) = (nn.as_mut(), dt > 0.0) {
                // Training error: the update's relative-velocity correction per second ([BOT] §II.D).
                let kin = |v: &SVector<f64, N>| mp_to_relative(&Vector6::from_fn(|i, _| v[i]));
                let (xa, xb) = (kin(&g.mean), kin(&pred.mean));
                let mut e = Vector3::new(xa[3] - xb[3], xa[4] - xb[4], xa[5] - xb[5]) / dt;
                if self.plane.is_some() {
                    e.z = 0.0;
                }
                net.train(&self.nn_input(&tr, lagged), &e)?;
                unexplained += (e - unexplained) * (dt / self.tau).min(1.0);
            }
            let new = MpEstimate {
                t: m.t,
                g,
                pos,
                vel,
            };
            let (u, _) = Self::heading(&new);
            let k = (dt / self.lag).clamp(0.0, 1.0);
            lagged = Some(lagged.map_or(u, |l| l + (u - l) * k));
            track = Some(new);
        }
        self.nn = nn;
        self.lagged_heading = lagged;
        self.unexplained = unexplained;
        self.track = track;
        self.track.as_ref().map(|tr| self.estimate(tr)).transpose()
    }
}
