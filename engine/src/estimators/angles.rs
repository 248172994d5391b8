//! Prediction-only angle trackers of \[ESE\] §4 for a single `az_el` sensor: each angle axis is
//! tracked on its own with the CA model, and every estimate line carries the one-step-ahead
//! predicted measurement `Ẑ(k+1|k)` for the sensor's next measurement time (FORMAT.md §5, `state`
//! is `null`).
//!
//! * `ca-kf` — Kalman filter, `Ẑ(k+1|k) = H Φ x̂(k|k)` (\[ESE\] eqs. (7)–(8));
//! * `stf`   — strong tracking filter ([`StrongTracking`]), same prediction;
//! * `ese`   — error-space estimate method ([`ErrorSpacePredictor`], eq. (14)).
//!
//! The CA model is [`WienerAcceleration`]: q is the std of the acceleration increment per sample
//! (rad/s²), the reading of the paper's unit-less "q = 0.000002" that reproduces the reference
//! figures on `zenith_pass` (see the ESE module docs in `harrier_core::filter`). Filters start by three-point differencing
//! of their first samples, so the first prediction comes with the third measurement.
//!
//! Azimuth is tracked as a continuous angle — the previous continuous value plus the wrapped
//! difference of successive measurements — and predictions are wrapped back to `[-π, π)`.
//! Measurements of other sensors are ignored.
//!
//! # References
//! * \[ESE\] M. Cen, C. Fu, K. Chen, X. Liu, "Error-space estimate method for generalized synergic
//!   target tracking" (`shared/papers/004`).

use harrier_core::EstimationError;
use harrier_core::Result;
use harrier_core::filter::{
    DifferenceStart, ErrorSpace, ErrorSpacePredictor, Kalman, Predictor, StfState, StrongTracking,
    Updater,
};
use harrier_core::linalg::wrap_angle;
use harrier_core::measurement::{DirectPosition, MeasKind};
use harrier_core::motion::{LinearTransition, WienerAcceleration};
use harrier_core::scenario::{Estimate, PredictionOut, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::{SMatrix, Vector1};

use crate::{EngineError, EstimatorInfo, Params, ReplayEstimator, Step, setup};

const Q_HELP: &str = "CA model: std of the acceleration increment per sample, rad/s² (discrete \
                      Wiener-process acceleration; default hints.paper_004.q_std, else 2e-6)";
const R_HELP: &str =
    "measurement noise std for both angles, rad (default: the az_el sensor's noise std)";

/// `ca-kf`: CA Kalman filter per angle axis.
pub const CA_KF: EstimatorInfo = EstimatorInfo {
    name: "ca-kf",
    summary: "CA Kalman filter per angle axis of the az_el sensor, one-step predicted angles only ([ESE] baseline)",
    params: &[("q", Q_HELP), ("r", R_HELP)],
    build: |sc, p| build::<KfAxis>(sc, p, "ca-kf"),
};

/// `stf`: strong tracking filter per angle axis.
pub const STF: EstimatorInfo = EstimatorInfo {
    name: "stf",
    summary: "strong tracking filter (CA, Joseph form) per angle axis of the az_el sensor, one-step predicted angles only ([ESE] baseline)",
    params: &[
        ("q", Q_HELP),
        ("r", R_HELP),
        (
            "beta",
            "softening factor β (default hints.paper_004.stf_softening_beta, else 1)",
        ),
        (
            "rho",
            "forgetting factor ρ in (0, 1] (default hints.paper_004.stf_forgetting_rho, else 0.95)",
        ),
    ],
    build: |sc, p| build::<StfAxis>(sc, p, "stf"),
};

/// `ese`: error-space estimate method per angle axis.
pub const ESE: EstimatorInfo = EstimatorInfo {
    name: "ese",
    summary: "error-space estimate method (guide-data KF + guide-error KF, CA) per angle axis of the az_el sensor, one-step predicted angles ([ESE])",
    params: &[("q", Q_HELP), ("r", R_HELP)],
    build: |sc, p| build::<EseAxis>(sc, p, "ese"),
};

/// What the three estimators read from the scenario and the parameters.
#[derive(Debug, Clone, PartialEq)]
struct Settings {
    sensor: String,
    /// CA acceleration-increment std (both axes).
    q: f64,
    /// Measurement noise std `[az, el]`.
    r: [f64; 2],
    beta: f64,
    rho: f64,
}

fn hint(sc: &Scenario, key: &str) -> Option<f64> {
    sc.hints.get("paper_004")?.get(key)?.as_f64()
}

impl Settings {
    fn new(sc: &Scenario, params: &Params, name: &str) -> Result<Self, EngineError> {
        let az_el: Vec<_> = sc
            .sensors
            .iter()
            .filter(|s| s.kind == MeasKind::AzEl)
            .collect();
        let sensor = match az_el.as_slice() {
            [s] => *s,
            [] => {
                let all: Vec<_> = sc
                    .sensors
                    .iter()
                    .map(|s| {
                        let kind = serde_json::to_value(s.kind)
                            .ok()
                            .and_then(|v| v.as_str().map(String::from))
                            .unwrap_or_default();
                        format!("{} ({kind})", s.id)
                    })
                    .collect();
                return Err(setup(format!(
                    "estimator {name:?} predicts the angles of one az_el sensor, but the scenario has none (sensors: {})",
                    if all.is_empty() {
                        "none".to_string()
                    } else {
                        all.join(", ")
                    }
                )));
            }
            many => {
                let ids: Vec<_> = many.iter().map(|s| s.id.as_str()).collect();
                return Err(setup(format!(
                    "estimator {name:?} predicts the angles of one az_el sensor, but the scenario has {}: {}",
                    ids.len(),
                    ids.join(", ")
                )));
            }
        };
        let q = params
            .opt("q")
            .or_else(|| hint(sc, "q_std"))
            .unwrap_or(2e-6);
        if !(q.is_finite() && q >= 0.0) {
            return Err(setup(format!("q must be ≥ 0, got {q}")));
        }
        let r = match params.opt("r") {
            Some(r) => [r, r],
            None => {
                let std = sensor.noise.std();
                std.try_into().map_err(|_| {
                    setup(format!(
                        "sensor {:?}: az_el noise must have 2 components",
                        sensor.id
                    ))
                })?
            }
        };
        if let Some(bad) = r.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(setup(format!("r must be > 0, got {bad}")));
        }
        let beta = params
            .opt("beta")
            .or_else(|| hint(sc, "stf_softening_beta"))
            .unwrap_or(1.0);
        let rho = params
            .opt("rho")
            .or_else(|| hint(sc, "stf_forgetting_rho"))
            .unwrap_or(0.95);
        Ok(Self {
            sensor: sensor.id.clone(),
            q,
            r,
            beta,
            rho,
        })
    }
}

/// One angle axis: consumes `(t, z)` and predicts `z` at a later time. Values, not places: a step
/// returns the next filter, so a failed step leaves the old one intact.
trait AxisFilter: Sized + Copy {
    fn new(s: &Settings, axis: usize) -> Result<Self, EngineError>;
    fn step(&self, z: f64, t: f64) -> Result<Self>;
    /// `None` until the filter has started.
    fn predict(&self, t_next: f64) -> Result<Option<f64>>;
}

fn check_dt(t_prev: f64, t: f64) -> Result<f64> {
    let dt = t - t_prev;
    if dt.is_finite() && dt > 0.0 {
        Ok(dt)
    } else {
        Err(EstimationError::InvalidParameter(format!(
            "measurement time {t} is not after {t_prev}"
        )))
    }
}

/// The phase of one angle axis's filter: the three-point start, then a running state at time `t`.
#[derive(Debug, Clone, Copy)]
enum AxisPhase<S> {
    Start(DifferenceStart<1>),
    Run { t: f64, state: S },
}

#[derive(Debug, Clone, Copy)]
struct KfAxis {
    motion: WienerAcceleration<3>,
    meas: DirectPosition<1>,
    r2: SMatrix<f64, 1, 1>,
    phase: AxisPhase<Gaussian<3>>,
}

impl AxisFilter for KfAxis {
    fn new(s: &Settings, axis: usize) -> Result<Self, EngineError> {
        Ok(Self {
            motion: WienerAcceleration::new(s.q),
            meas: DirectPosition::new([s.r[axis]]),
            r2: SMatrix::<f64, 1, 1>::new(s.r[axis] * s.r[axis]),
            phase: AxisPhase::Start(DifferenceStart::default()),
        })
    }
    fn step(&self, z: f64, t: f64) -> Result<Self> {
        let z = Vector1::new(z);
        let phase = match self.phase {
            AxisPhase::Start(mut start) => match start.push(t, &z, &self.r2)? {
                Some(state) => AxisPhase::Run { t, state },
                None => AxisPhase::Start(start),
            },
            AxisPhase::Run { t: tp, state } => {
                let pred = Kalman.predict(&self.motion, &state, check_dt(tp, t)?)?;
                let state = Kalman.update(&self.meas, &pred, &z)?.state;
                AxisPhase::Run { t, state }
            }
        };
        Ok(Self { phase, ..*self })
    }
    fn predict(&self, t_next: f64) -> Result<Option<f64>> {
        Ok(match &self.phase {
            AxisPhase::Start(_) => None,
            // Ẑ(k+1|k) = H Φ x̂(k|k), [ESE] eqs. (7)–(8).
            AxisPhase::Run { t, state } => Some((self.motion.matrix(t_next - t) * state.mean)[0]),
        })
    }
}

#[derive(Debug, Clone, Copy)]
struct StfAxis {
    stf: StrongTracking,
    motion: WienerAcceleration<3>,
    meas: DirectPosition<1>,
    r2: SMatrix<f64, 1, 1>,
    phase: AxisPhase<StfState<3, 1>>,
}

impl AxisFilter for StfAxis {
    fn new(s: &Settings, axis: usize) -> Result<Self, EngineError> {
        Ok(Self {
            stf: StrongTracking::new(s.beta, s.rho).map_err(|e| setup(e.to_string()))?,
            motion: WienerAcceleration::new(s.q),
            meas: DirectPosition::new([s.r[axis]]),
            r2: SMatrix::<f64, 1, 1>::new(s.r[axis] * s.r[axis]),
            phase: AxisPhase::Start(DifferenceStart::default()),
        })
    }
    fn step(&self, z: f64, t: f64) -> Result<Self> {
        let z = Vector1::new(z);
        let phase = match self.phase {
            AxisPhase::Start(mut start) => match start.push(t, &z, &self.r2)? {
                Some(g) => AxisPhase::Run {
                    t,
                    state: StfState::new(g),
                },
                None => AxisPhase::Start(start),
            },
            AxisPhase::Run { t: tp, state } => {
                let out = self
                    .stf
                    .step(&self.motion, &self.meas, &state, &z, check_dt(tp, t)?)?;
                AxisPhase::Run {
                    t,
                    state: out.state,
                }
            }
        };
        Ok(Self { phase, ..*self })
    }
    fn predict(&self, t_next: f64) -> Result<Option<f64>> {
        Ok(match &self.phase {
            AxisPhase::Start(_) => None,
            AxisPhase::Run { t, state } => {
                Some((self.motion.matrix(t_next - t) * state.estimate.mean)[0])
            }
        })
    }
}

#[derive(Debug, Clone, Copy)]
struct EseAxis(ErrorSpacePredictor<WienerAcceleration<3>, DirectPosition<1>, 3, 1>);

impl AxisFilter for EseAxis {
    fn new(s: &Settings, axis: usize) -> Result<Self, EngineError> {
        // [ESE] §4: the same CA model and the same q, r for both filters.
        Ok(Self(ErrorSpacePredictor::new(ErrorSpace::symmetric(
            WienerAcceleration::new(s.q),
            DirectPosition::new([s.r[axis]]),
        ))))
    }
    fn step(&self, z: f64, t: f64) -> Result<Self> {
        let mut next = *self;
        next.0.step(&Vector1::new(z), t)?;
        Ok(next)
    }
    fn predict(&self, t_next: f64) -> Result<Option<f64>> {
        Ok(self.0.predict(t_next)?.map(|z| z[0]))
    }
}

/// Runs one [`AxisFilter`] on the continuous azimuth and one on the elevation.
#[derive(Debug)]
struct AnglePredictor<A> {
    sensor: String,
    /// `[azimuth, elevation]`.
    axes: [A; 2],
    /// Last measured (wrapped) azimuth and its continuous value.
    azimuth: Option<(f64, f64)>,
}

impl<A: AxisFilter> ReplayEstimator for AnglePredictor<A> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let mut axes = self.axes;
        let mut azimuth = self.azimuth;
        let mut seen = false;
        for m in step.measurements.iter().filter(|m| m.sensor == self.sensor) {
            let [az, el] = m.z[..] else {
                return Err(setup(format!(
                    "az_el measurement at t = {} has {} components",
                    m.t,
                    m.z.len()
                )));
            };
            // Continuous azimuth: accumulate wrapped differences.
            let az_c = azimuth.map_or(az, |(raw, cont)| cont + wrap_angle(az - raw));
            axes = [axes[0].step(az_c, m.t)?, axes[1].step(el, m.t)?];
            azimuth = Some((az, az_c));
            seen = true;
        }
        if !seen {
            return Ok(None);
        }
        let prediction = match (step.next_time)(&self.sensor) {
            Some(tn) => match (axes[0].predict(tn)?, axes[1].predict(tn)?) {
                (Some(az), Some(el)) => Some(PredictionOut {
                    t: tn,
                    sensor: self.sensor.clone(),
                    z: vec![wrap_angle(az), el],
                }),
                _ => None,
            },
            None => None,
        };
        self.axes = axes;
        self.azimuth = azimuth;
        Ok(Some(Estimate {
            t: step.t,
            state: None,
            prediction,
            ..Estimate::default()
        }))
    }
}

fn build<A: AxisFilter + 'static>(
    sc: &Scenario,
    params: &Params,
    name: &str,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let s = Settings::new(sc, params, name)?;
    Ok(Box::new(AnglePredictor {
        sensor: s.sensor.clone(),
        axes: [A::new(&s, 0)?, A::new(&s, 1)?],
        azimuth: None,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::scenario::{Measurement, PlatformPose};

    /// Builds one of this module's estimators by name.
    fn build_estimator(
        name: &str,
        sc: &Scenario,
        p: &Params,
    ) -> Result<Box<dyn ReplayEstimator>, EngineError> {
        let info = [CA_KF, STF, ESE]
            .into_iter()
            .find(|e| e.name == name)
            .unwrap();
        (info.build)(sc, p)
    }

    fn scenario(sensors: &str) -> Scenario {
        Scenario::parse(&format!(
            r#"{{"format":"gcs-scenario/1","name":"t","dims":3,
                "time":{{"t0":0,"dt":0.02,"t_end":1}},"target":{{"id":"tgt"}},
                "sensors":[{sensors}],
                "hints":{{"paper_004":{{"q_std":3e-6,"stf_forgetting_rho":0.9}}}}}}"#
        ))
        .unwrap()
    }

    const EO: &str = r#"{"id":"eo1","platform":"site","kind":"az_el","noise":{"type":"gaussian","std":[2e-6,3e-6]}}"#;

    #[test]
    fn settings_come_from_hints_sensor_and_params() {
        let sc = scenario(EO);
        let s = Settings::new(&sc, &Params::default(), "stf").unwrap();
        assert_eq!(s.sensor, "eo1");
        assert_eq!((s.q, s.r, s.beta, s.rho), (3e-6, [2e-6, 3e-6], 1.0, 0.9));
        let p = Params::parse(&["q=1e-5", "r=4e-6", "beta=2", "rho=0.5"]).unwrap();
        let s = Settings::new(&sc, &p, "stf").unwrap();
        assert_eq!((s.q, s.r, s.beta, s.rho), (1e-5, [4e-6, 4e-6], 2.0, 0.5));
        assert!(Settings::new(&sc, &Params::parse(&["r=0"]).unwrap(), "ese").is_err());
        let bad = build_estimator("stf", &sc, &Params::parse(&["rho=2"]).unwrap());
        assert!(bad.is_err());
    }

    #[test]
    fn needs_exactly_one_az_el_sensor() {
        let radar = r#"{"id":"r1","platform":"p","kind":"range_bearing","noise":{"type":"gaussian","std":[5,0.005]}}"#;
        let err = build_estimator("ese", &scenario(radar), &Params::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("one az_el sensor") && err.contains("none"),
            "{err}"
        );
        let two = format!("{EO},{}", EO.replace("eo1", "eo2"));
        let err = build_estimator("ca-kf", &scenario(&two), &Params::default())
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("has 2: eo1, eo2"), "{err}");
    }

    #[test]
    fn azimuth_is_unwrapped_across_south_and_predictions_wrapped() {
        // Azimuth rising steadily through +π (due South): the filters see a continuous angle and the
        // prediction comes back wrapped.
        let sc = scenario(EO);
        let rate = 0.5; // rad/s
        let az = |t: f64| wrap_angle(3.0 + rate * t);
        let ms: Vec<Measurement> = (0..100)
            .map(|k| Measurement {
                t: 0.02 * f64::from(k),
                sensor: "eo1".into(),
                kind: MeasKind::AzEl,
                platform: PlatformPose {
                    pos: [0.0; 3],
                    vel: [0.0; 3],
                },
                z: vec![az(0.02 * f64::from(k)), 0.3],
            })
            .collect();
        for name in ["ca-kf", "stf", "ese"] {
            let mut est = build_estimator(name, &sc, &Params::default()).unwrap();
            for (k, m) in ms.iter().enumerate() {
                let tn = ms.get(k + 1).map(|m| m.t);
                let next = move |_: &str| tn;
                let group = [m];
                let e = est
                    .step(&Step {
                        t: m.t,
                        measurements: &group,
                        references: &[],
                        next_time: &next,
                    })
                    .unwrap()
                    .unwrap();
                assert!(e.state.is_none());
                match (&e.prediction, tn) {
                    (Some(p), Some(tn)) => {
                        assert!(k >= 2);
                        assert_eq!(p.t, tn);
                        assert!((-std::f64::consts::PI..std::f64::consts::PI).contains(&p.z[0]));
                        assert!(wrap_angle(p.z[0] - az(tn)).abs() < 1e-9, "{name} k={k}");
                        assert!((p.z[1] - 0.3).abs() < 1e-12);
                    }
                    (None, _) => assert!(k < 2 || tn.is_none(), "{name} k={k}"),
                    (Some(_), None) => panic!("prediction without a next time"),
                }
            }
        }
    }
}
