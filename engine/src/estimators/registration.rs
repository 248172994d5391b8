//! `registration`: the target and every sensor's bias terms in one augmented EKF
//! (harrier-core's [`Registration`]), updated from every sensor's detections of the target
//! (targets of opportunity) and from cooperative references (`references.jsonl`); each estimate
//! line carries `bias_est` (FORMAT-REGISTRATION.md §4). A sensor's terms and their priors come
//! from its `bias` block (FORMAT-REGISTRATION.md §1); a sensor without one is taken as unbiased.

use harrier_core::measurement::{Geometry, SensorModel, TargetSize};
use harrier_core::registration::{
    DriftModes, Observation, Registration, RegistrationImm, RegistrationImmState, Seen, SensorBias,
    Tuning,
};
use harrier_core::scenario::{Estimate, Measurement, Scenario};
use nalgebra::Vector3;

use super::{cv_dims, cv_estimate, known_object, prior};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

/// `registration`.
pub const REGISTRATION: EstimatorInfo = EstimatorInfo {
    name: "registration",
    summary: "sensor registration: the target and every sensor's bias terms (sensors[*].bias) in one \
              augmented EKF, terms held at their prior until observable; writes bias_est",
    params: &[
        Q_PARAM,
        (
            "kappa",
            "observability threshold: a term is estimated once its std would be ≤ κ × its prior's (default 0.3)",
        ),
        (
            "hold",
            "1: hold terms at their prior until observable (default); 0: estimate every term from the start",
        ),
        (
            "drift_factor",
            "the drifting mode's random-walk terms drift this many times faster (default 20; 1: one mode)",
        ),
        (
            "drift_sojourn",
            "mean time in a drift mode before switching, s (default 300)",
        ),
        (
            "drift_prob",
            "probability of the drifting mode at the start, of the biased modes' share (default 0.1)",
        ),
        (
            "none_prob",
            "probability of the \"no bias\" mode at the start (default 0.5)",
        ),
        (
            "presence_sojourn",
            "mean time before a bias disappears, s: re-seeds the \"no bias\" mode (default 3600)",
        ),
        (
            "per_sensor",
            "1: weigh every set of biased sensors (up to 4 sensors with terms; default); 0: every sensor biased, or none",
        ),
    ],
    build,
};

/// The bias terms a state may hold beyond the target's: the const sizes the driver instantiates.
const BIAS_CAPACITY: [usize; 3] = [4, 12, 20];

fn build(sc: &Scenario, p: &Params) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let q = p.q(sc)?;
    let tuning = Tuning {
        kappa: p.get("kappa", Tuning::default().kappa),
        hold: p.get("hold", 1.0) != 0.0,
    };
    let d = DriftModes::default();
    let drift = DriftModes {
        factor: p.get("drift_factor", d.factor),
        sojourn: p.get("drift_sojourn", d.sojourn),
        initial: p.get("drift_prob", d.initial),
        unbiased: p.get("none_prob", d.unbiased),
        presence_sojourn: p.get("presence_sojourn", d.presence_sojourn),
        per_sensor: p.get("per_sensor", 1.0) != 0.0,
    };
    let mut biases = Vec::with_capacity(sc.sensors.len());
    for s in &sc.sensors {
        let b = match &s.bias {
            Some(block) => SensorBias::from_block(block, s.dim())
                .map_err(|e| setup(format!("sensor {:?}: {e}", s.id)))?,
            None => None,
        };
        biases.push(b);
    }
    let terms: usize = biases.iter().flatten().map(|b| b.terms().count()).sum();
    let capacity = BIAS_CAPACITY
        .into_iter()
        .find(|c| *c >= terms)
        .ok_or_else(|| {
            setup(format!(
                "registration holds at most {} bias terms, the scenario's sensors have {terms}",
                BIAS_CAPACITY[BIAS_CAPACITY.len() - 1]
            ))
        })?;
    macro_rules! boxed {
        ($k:literal, $n:literal) => {
            Box::new(Driver::<$k, $n>::new(sc, q, &biases, tuning, drift)?)
        };
    }
    Ok(match (sc.dims == 2, capacity) {
        (true, 4) => boxed!(4, 8),
        (true, 12) => boxed!(4, 16),
        (true, _) => boxed!(4, 24),
        (false, 4) => boxed!(6, 10),
        (false, 12) => boxed!(6, 18),
        (false, _) => boxed!(6, 26),
    })
}

/// The replay of one scenario.
#[derive(Debug)]
struct Driver<const K: usize, const N: usize> {
    filter: RegistrationImm<K, N>,
    sc: Scenario,
    t: f64,
    state: RegistrationImmState<N>,
}

impl<const K: usize, const N: usize> Driver<K, N> {
    fn new(
        sc: &Scenario,
        q: f64,
        biases: &[Option<SensorBias>],
        tuning: Tuning,
        drift: DriftModes,
    ) -> Result<Self, EngineError> {
        let sensors: Vec<_> = sc
            .sensors
            .iter()
            .zip(biases)
            .map(|(s, b)| (s.dim(), b.as_ref()))
            .collect();
        let filter = Registration::<K, N>::new(q, sc.plane_z(), &sensors, tuning)
            .and_then(|f| RegistrationImm::new(f, drift))
            .map_err(|e| setup(format!("registration: {e}")))?;
        let (t, kinematic) = prior::<K>(sc, cv_dims(K))?;
        let state = filter.initial(&kinematic)?;
        Ok(Self {
            filter,
            sc: sc.clone(),
            t,
            state,
        })
    }

    /// The sensor's index and its unbiased model at the line's platform (3-D geometry: the
    /// filter puts the target on the plane itself).
    fn model(&self, m: &Measurement) -> Result<(usize, SensorModel), EngineError> {
        let i = self
            .sc
            .sensors
            .iter()
            .position(|s| s.id == m.sensor)
            .ok_or_else(|| setup(format!("unknown sensor {:?}", m.sensor)))?;
        let s = &self.sc.sensors[i];
        let model = SensorModel::new(
            m.kind,
            Geometry::spatial(),
            Vector3::from(m.platform.pos),
            &s.noise.std(),
            self.sc.target.size_m.map(TargetSize::Known),
        )
        .map_err(|e| setup(format!("sensor {:?}: {e}", m.sensor)))?;
        Ok((i, model))
    }
}

impl<const K: usize, const N: usize> ReplayEstimator for Driver<K, N> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        // Every detection of the step, the references first at equal times, in time order.
        let mut items: Vec<(&Measurement, Seen)> = step
            .references
            .iter()
            .map(|r| (&r.measurement, Seen::Known(known_object(&r.object))))
            .chain(step.measurements.iter().map(|m| (*m, Seen::Target)))
            .collect();
        items.sort_by(|a, b| a.0.t.total_cmp(&b.0.t));
        let mut state = self.state;
        let mut t = self.t;
        for (m, seen) in items {
            if m.t > t {
                state = self.filter.predict(&state, m.t - t)?;
                t = m.t;
            }
            let (sensor, model) = self.model(m)?;
            let obs = Observation {
                sensor,
                model: &model,
                platform_vel: Vector3::from(m.platform.vel),
                z: &m.z,
            };
            state = self.filter.update(&state, &obs, &seen)?;
        }
        self.state = state;
        self.t = t;
        let (combined, biased) = self.filter.output(&self.state);
        let filter = self.filter.filter();
        let mut e = cv_estimate(self.sc.plane_z(), t, &filter.kinematic(&combined));
        let mut bias = serde_json::Map::new();
        for ((s, est), p) in self
            .sc
            .sensors
            .iter()
            .zip(filter.estimates(&combined))
            .zip(biased)
        {
            if !est.terms.is_empty() {
                let mut json = est.to_json();
                json["biased_prob"] = serde_json::json!(p);
                bias.insert(s.id.clone(), json);
            }
        }
        if !bias.is_empty() {
            e.extra
                .insert("bias_est".into(), serde_json::Value::Object(bias));
            e.extra.insert(
                "bias_drift_prob".into(),
                serde_json::json!(self.state.drifting_prob()),
            );
            e.extra.insert(
                "bias_none_prob".into(),
                serde_json::json!(self.state.unbiased_prob()),
            );
        }
        Ok(Some(e))
    }
}
