//! `tracker`: the multi-target tracker of `harrier_core::tracker` (KF with the CV model, χ² gating,
//! global nearest neighbour, single-point initiation with M-of-N confirmation, miss/covariance
//! deletion) over a multi-target scenario (FORMAT-MULTI.md): one position sensor whose scans carry
//! unlabeled detections, clutter included.
//!
//! Each estimate line holds every confirmed track after the scan (`"state": null`, `"tracks"`):
//! see FORMAT-MULTI.md §4.

use harrier_core::filter::Kalman;
use harrier_core::measurement::Position;
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, MeasKind, Scenario};
use harrier_core::tracker::{
    Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, Tracker, TrackerConfig,
};
use nalgebra::{SMatrix, SVector};
use serde_json::{Value, json};

use super::{cv_estimate, geometry};
use crate::engine::{EngineError, EstimatorInfo, Params, ReplayEstimator, Step, setup};

/// `tracker`: GNN multi-target tracker.
pub const TRACKER: EstimatorInfo = EstimatorInfo {
    name: "tracker",
    summary: "multi-target GNN tracker (KF, CV, χ² gate, M-of-N): all confirmed tracks per scan (FORMAT-MULTI.md)",
    params: &[
        (
            "q",
            "acceleration spectral density, m²/s³ (default motion.accel_std²)",
        ),
        ("vel_std", "velocity prior of a new track, m/s (default 12)"),
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
            "consecutive misses that delete a confirmed track (default 5)",
        ),
        (
            "max_pos_var",
            "position-variance trace that deletes a track, m² (default 1e5)",
        ),
    ],
    build: |sc, p| {
        let s = match sc.sensors.as_slice() {
            [s] if s.kind == MeasKind::Position => s,
            _ => {
                return Err(setup(
                    "the tracker takes scenarios with exactly one position sensor",
                ));
            }
        };
        match (sc.dims, s.dim()) {
            (2, 2) => Ok(Box::new(MultiTracker::<4, 2>::new(sc, p)?)),
            (3, 3) => Ok(Box::new(MultiTracker::<6, 3>::new(sc, p)?)),
            (d, m) => Err(setup(format!(
                "the tracker needs a position sensor with ncomp = dims, got {m} components for dims {d}"
            ))),
        }
    },
};

type Kf<const N: usize, const M: usize> = GaussianFilter<Kalman, ConstantVelocity<N>, Position<M>>;

/// The tracker for an N-state CV layout and M-component position detections.
#[derive(Debug)]
struct MultiTracker<const N: usize, const M: usize> {
    tracker: Tracker<Kf<N, M>, SinglePointInitiator<M>, N, M>,
    sc: Scenario,
}

/// An integer parameter ≥ 1.
fn count(p: &Params, name: &str, default: u32) -> Result<u32, EngineError> {
    let v = p.get(name, f64::from(default));
    if v.fract() != 0.0 || !(1.0..=1e6).contains(&v) {
        return Err(setup(format!("--param {name} must be a whole number ≥ 1")));
    }
    Ok(v as u32)
}

impl<const N: usize, const M: usize> MultiTracker<N, M> {
    fn new(sc: &Scenario, p: &Params) -> Result<Self, EngineError> {
        let q = p.opt("q").or(sc.accel_q()).ok_or_else(|| {
            setup("scenario.json has no motion.accel_std; pass --param q=<m²/s³>")
        })?;
        let std: [f64; M] = sc.sensors[0]
            .noise
            .std()
            .try_into()
            .map_err(|_| setup("sensor noise does not match its components"))?;
        let filter = GaussianFilter {
            filter: Kalman,
            motion: ConstantVelocity::<N>::new(q),
            sensor: Position::new(geometry(sc), std),
        };
        let r = SMatrix::<f64, M, M>::from_diagonal(&SVector::from_fn(|i, _| std[i] * std[i]));
        let init = SinglePointInitiator::new(r, p.get("vel_std", 12.0))?;
        let config = TrackerConfig {
            gater: Gater::chi2(p.get("gate", 0.999), M)?,
            tentative_gater: Gater::chi2(p.get("tentative_gate", 0.95), M)?,
            confirm: MOfN::new(count(p, "m", 2)?, count(p, "n", 4)?)?,
            deleter: Deleter::new(count(p, "misses", 5)?, p.get("max_pos_var", 1e5), M)?,
        };
        Ok(Self {
            tracker: Tracker::new(filter, init, config),
            sc: sc.clone(),
        })
    }
}

impl<const N: usize, const M: usize> ReplayEstimator for MultiTracker<N, M> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let dets: Vec<SVector<f64, M>> = step
            .measurements
            .iter()
            .map(|m| SVector::from_iterator(m.z.iter().copied()))
            .collect();
        // Work on a copy so that a failed scan leaves the tracker as it was.
        let mut tracker = self.tracker.clone();
        // Scans without any detection have no measurement line: run them as empty scans so that
        // the M-of-N and miss counts see them (scan times t0 + k·dt, FORMAT-MULTI.md §3).
        if let Some(last) = tracker.time() {
            let dt = self.sc.time.dt;
            let gap = ((step.t - last) / dt - 0.5).floor().clamp(0.0, 1e6) as u32;
            for k in 1..=gap {
                tracker.step(last + f64::from(k) * dt, &[])?;
            }
        }
        tracker.step(step.t, &dets)?;
        self.tracker = tracker;
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
