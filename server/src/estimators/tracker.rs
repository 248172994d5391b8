//! `tracker`: the multi-target tracker of `harrier_core::tracker` (EKF with the CV model — the KF on
//! `position` sensors — χ² gating, global nearest neighbour over confirmed and tentative tracks,
//! single-point initiation from any detection kind with M-of-N confirmation, miss/covariance
//! deletion) over a multi-target scenario (FORMAT-MULTI.md): any number of sensors of any kind
//! whose scans carry unlabeled detections, clutter included. Each sensor's detections of one time
//! are one scan, under that sensor's model at its platform pose.
//!
//! Each estimate line holds every confirmed track after the scan (`"state": null`, `"tracks"`):
//! see FORMAT-MULTI.md §4.

use harrier_core::filter::Extended;
use harrier_core::measurement::SensorModel;
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, MeasKind, Scenario};
use harrier_core::tracker::{
    Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, Tracker, TrackerConfig,
};
use serde_json::{Value, json};

use super::{cv_estimate, geometry, model_for};
use crate::engine::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

/// `tracker`: GNN multi-target tracker.
pub const TRACKER: EstimatorInfo = EstimatorInfo {
    name: "tracker",
    summary: "multi-target GNN tracker (EKF, CV, χ² gate, M-of-N), any sensors: all confirmed tracks per scan (FORMAT-MULTI.md)",
    params: &[
        Q_PARAM,
        ("vel_std", "velocity prior of a new track, m/s (default 12)"),
        (
            "up_std",
            "height prior of a new 3-D track when its first detection gives none, m (default 50)",
        ),
        (
            "gate",
            "gate probability of confirmed tracks (default 0.999)",
        ),
        (
            "tentative_gate",
            "gate probability of tentative tracks (default 0.95)",
        ),
        ("m", "confirmation: M hits … (default 2)"),
        ("n", "… within the first N scans (default 4)"),
        (
            "misses",
            "consecutive missed scans that delete a confirmed track (default 5 per sensor)",
        ),
        (
            "max_pos_var",
            "position-variance trace that deletes a track, m² (default 1e5)",
        ),
    ],
    build: |sc, p| {
        if sc.sensors.is_empty() {
            return Err(setup("the tracker needs at least one sensor"));
        }
        if let Some(s) = sc
            .sensors
            .iter()
            .find(|s| s.kind == MeasKind::BearingSize && sc.target.size_m.is_none())
        {
            return Err(setup(format!(
                "sensor {:?}: bearing_size detections need target.size_m to start tracks",
                s.id
            )));
        }
        match sc.dims {
            2 => Ok(Box::new(MultiTracker::<4>::new(sc, p)?)),
            3 => Ok(Box::new(MultiTracker::<6>::new(sc, p)?)),
            d => Err(setup(format!("the tracker needs dims 2 or 3, got {d}"))),
        }
    },
};

type Ekf<const N: usize> = GaussianFilter<Extended, ConstantVelocity<N>>;

/// The tracker for an N-state CV layout.
#[derive(Debug)]
struct MultiTracker<const N: usize> {
    tracker: Tracker<Ekf<N>, SinglePointInitiator, N>,
    sc: Scenario,
    /// The model of the last scan, for the empty scans between measurement lines.
    last_model: Option<SensorModel>,
}

/// An integer parameter ≥ 1.
fn count(p: &Params, name: &str, default: u32) -> Result<u32, EngineError> {
    let v = p.get(name, f64::from(default));
    if v.fract() != 0.0 || !(1.0..=1e6).contains(&v) {
        return Err(setup(format!("--param {name} must be a whole number ≥ 1")));
    }
    Ok(v as u32)
}

impl<const N: usize> MultiTracker<N> {
    fn new(sc: &Scenario, p: &Params) -> Result<Self, EngineError> {
        let filter = GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::<N>::new(p.q(sc)?),
        };
        let init = SinglePointInitiator::new(p.get("vel_std", 12.0), p.get("up_std", 50.0))?;
        // Every sensor's scan counts as a scan for M-of-N and misses.
        let sensors = u32::try_from(sc.sensors.len()).unwrap_or(u32::MAX);
        let config = TrackerConfig {
            gater: Gater::chi2(p.get("gate", 0.999), 2)?,
            tentative_gater: Gater::chi2(p.get("tentative_gate", 0.95), 2)?,
            confirm: MOfN::new(count(p, "m", 2)?, count(p, "n", 4)?)?,
            deleter: Deleter::new(
                count(p, "misses", 5 * sensors)?,
                p.get("max_pos_var", 1e5),
                usize::from(sc.dims),
            )?,
        };
        Ok(Self {
            tracker: Tracker::new(filter, init, config),
            sc: sc.clone(),
            last_model: None,
        })
    }
}

impl<const N: usize> ReplayEstimator for MultiTracker<N> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let geo = geometry(&self.sc);
        // One scan per sensor (measurements come sorted by sensor id).
        let mut scans: Vec<(SensorModel, Vec<&[f64]>)> = Vec::new();
        let mut last_sensor: Option<&str> = None;
        for m in step.measurements {
            if last_sensor != Some(m.sensor.as_str()) {
                scans.push((model_for(&self.sc, geo, m, None)?, Vec::new()));
                last_sensor = Some(m.sensor.as_str());
            }
            if let Some((_, zs)) = scans.last_mut() {
                zs.push(m.z.as_slice());
            }
        }
        // Work on a copy so that a failed step leaves the tracker as it was.
        let mut tracker = self.tracker.clone();
        // Scans without any detection have no measurement line: run them as empty scans so that
        // the M-of-N and miss counts see them (scan times t0 + k·dt, FORMAT-MULTI.md §3).
        if let (Some(last), Some(model)) = (tracker.time(), self.last_model.as_ref()) {
            let dt = self.sc.time.dt;
            let gap = ((step.t - last) / dt - 0.5).floor().clamp(0.0, 1e6) as u32;
            for k in 1..=gap {
                tracker.step_any(last + f64::from(k) * dt, model, &[])?;
            }
        }
        for (model, zs) in &scans {
            tracker.step_any(step.t, model, zs)?;
        }
        self.tracker = tracker;
        if let Some((model, _)) = scans.last() {
            self.last_model = Some(*model);
        }
        let tracks: Vec<Value> = self
            .tracker
            .confirmed()
            .iter()
            .map(|k| {
                let e = cv_estimate(&self.sc, step.t, &k.estimate);
                json!({
                    "id": k.id,
                    "state": e.state,
                    "cov": e.cov,
                    "cov_dims": e.cov_dims,
                    "updated": k.updated,
                })
            })
            .collect();
        let mut est = Estimate {
            t: step.t,
            ..Estimate::default()
        };
        est.extra.insert("tracks".into(), Value::Array(tracks));
        Ok(Some(est))
    }
}

/// `harrier gen-multi <dir> --seed N`: writes the generator's default crossing-target scenario
/// (`harrier_core::tracker::generate`, FORMAT-MULTI.md §5) into `dir`, creating it.
pub fn write_generated(dir: &std::path::Path, seed: u64) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let g = harrier_core::tracker::generate::generate(
        seed,
        &harrier_core::tracker::generate::GenConfig::default(),
    )?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, text) in [
        ("scenario.json", &g.scenario_json),
        ("measurements.jsonl", &g.measurements_jsonl),
        ("truth.csv", &g.truth_csv),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::engine::Params;
    use crate::replay;

    #[test]
    fn replays_a_generated_scenario() {
        let dir = tempfile::tempdir().unwrap();
        super::write_generated(dir.path(), 5).unwrap();
        let data = replay::load(dir.path()).unwrap();
        let report = replay::run(&data, "tracker", &Params::default()).unwrap();
        assert!(report.rejected.is_empty());
        let last = report.estimates.last().unwrap();
        assert!(last.state.is_none());
        let tracks = last.extra["tracks"].as_array().unwrap();
        assert_eq!(tracks.len(), 6);
        for k in tracks {
            assert!(k["id"].as_u64().is_some());
            assert_eq!(k["state"].as_array().unwrap().len(), 6);
            assert_eq!(k["cov_dims"], serde_json::json!([0, 1, 3, 4]));
        }
        // A parameter out of range is a setup error.
        let bad = Params::parse(&["n=1.5"]).unwrap();
        assert!(replay::run(&data, "tracker", &bad).is_err());
    }
}
