//! The line-oriented files: measurement lines, truth rows and estimate lines, and a whole parsed
//! directory ([`ScenarioData`]) with its grouping by time and truth interpolation.

use serde::{Deserialize, Serialize};

use super::types::{EllipsoidSpec, Scenario};
use crate::measurement::MeasKind;

/// Platform pose in a measurement line.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct PlatformPose {
    /// ENU position (m).
    pub pos: [f64; 3],
    /// ENU velocity (m/s).
    #[serde(default)]
    pub vel: [f64; 3],
}

/// One line of `measurements.jsonl`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Measurement {
    /// Time (s).
    pub t: f64,
    /// Sensor id.
    pub sensor: String,
    /// Kind (must match the sensor's).
    pub kind: MeasKind,
    /// Sensor platform pose at `t`.
    pub platform: PlatformPose,
    /// Measured value; `null` components are read as NaN (and such measurements are skipped).
    #[serde(deserialize_with = "nullable_floats")]
    pub z: Vec<f64>,
}

impl Measurement {
    /// Whether every component of `z` is finite.
    pub fn is_finite(&self) -> bool {
        self.z.iter().all(|v| v.is_finite())
    }
}

fn nullable_floats<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    let v: Vec<Option<f64>> = Deserialize::deserialize(d)?;
    Ok(v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
}

/// One line of `references.jsonl` (FORMAT-REGISTRATION.md §2): a sensor's detection of a known
/// object (a cooperative reference: a UAV reporting its own GPS position), not of the target.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Reference {
    /// The detection, a measurement line of the sensor.
    #[serde(flatten)]
    pub measurement: Measurement,
    /// What it saw.
    pub object: ReferenceObject,
}

/// The known object of a [`Reference`]: where it reported itself at the line's time.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct ReferenceObject {
    /// Its id (a platform's).
    pub id: String,
    /// ENU position (m).
    pub pos: [f64; 3],
    /// ENU velocity (m/s).
    #[serde(default)]
    pub vel: [f64; 3],
    /// Standard deviation of each position component (m).
    pub std: [f64; 3],
}

/// One row of `truth.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Time (s).
    pub t: f64,
    /// Canonical state.
    pub state: [f64; 6],
    /// Motion-mode label (may be empty).
    pub mode: String,
}

/// A whole scenario directory, parsed and checked for consistency.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioData {
    /// `scenario.json`.
    pub scenario: Scenario,
    /// `measurements.jsonl`, in file order (sorted by time, then sensor).
    pub measurements: Vec<Measurement>,
    /// `truth.csv` when present.
    pub truth: Option<Vec<TruthRow>>,
    /// `references.jsonl` (FORMAT-REGISTRATION.md; empty when absent), in file order.
    pub references: Vec<Reference>,
}

impl ScenarioData {
    /// Measurements grouped by time (within 1e-9 s), in time order; each group sorted by sensor.
    pub fn groups(&self) -> Vec<(f64, Vec<&Measurement>)> {
        group_by_time(&self.measurements)
    }
}

/// Groups measurements by time (within 1e-9 s): `[(t, [lines…])]` in time order.
pub fn group_by_time(meas: &[Measurement]) -> Vec<(f64, Vec<&Measurement>)> {
    let mut groups: Vec<(f64, Vec<&Measurement>)> = Vec::new();
    for m in meas {
        match groups.last_mut() {
            Some((t, g)) if (m.t - *t).abs() <= 1e-9 => g.push(m),
            _ => groups.push((m.t, vec![m])),
        }
    }
    for (_, g) in &mut groups {
        g.sort_by(|a, b| a.sensor.cmp(&b.sensor));
    }
    groups
}

/// Truth state at `t`: the row within 1 µs, else linear interpolation; `None` outside the rows.
/// Also returns the mode label in force and whether the row was exact (as `score.py` does).
pub fn truth_at(truth: &[TruthRow], t: f64) -> Option<([f64; 6], &str, bool)> {
    let i = truth.partition_point(|r| r.t < t);
    for j in [i.wrapping_sub(1), i] {
        if let Some(r) = truth.get(j) {
            if (r.t - t).abs() <= 1e-6 {
                return Some((r.state, &r.mode, true));
            }
        }
    }
    if i == 0 || i >= truth.len() {
        return None;
    }
    let (a, b) = (&truth[i - 1], &truth[i]);
    let w = (t - a.t) / (b.t - a.t);
    let s: [f64; 6] = std::array::from_fn(|k| (1.0 - w) * a.state[k] + w * b.state[k]);
    Some((s, &a.mode, false))
}

/// One line of `estimates.jsonl` (FORMAT.md §5).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
pub struct Estimate {
    /// Time (s).
    pub t: f64,
    /// Canonical state, or `null` for prediction-only estimators.
    pub state: Option<[f64; 6]>,
    /// Covariance of `state[cov_dims]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cov: Option<Vec<Vec<f64>>>,
    /// Canonical indices of `cov`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cov_dims: Option<Vec<usize>>,
    /// Set estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ellipsoid: Option<EllipsoidSpec>,
    /// Model probabilities aligned with `motion.models`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_probs: Option<Vec<f64>>,
    /// One-step-ahead predicted measurement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction: Option<PredictionOut>,
    /// Extra keys (`bias_est`, `size_est`, …), ignored by readers.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// `prediction` of an estimate line.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct PredictionOut {
    /// Time the prediction is for.
    pub t: f64,
    /// Sensor it predicts.
    pub sensor: String,
    /// Predicted measurement.
    pub z: Vec<f64>,
}
