//! A seeded generator of multi-target scenarios in the format of `FORMAT-MULTI.md`: pairs of
//! targets whose straight paths cross at the same point at the same scan, detected with
//! probability `pd` by one planar position sensor, plus Poisson clutter uniform over a square.
//!
//! Pure: everything comes from a ChaCha8 stream seeded by the caller, so a seed always gives the
//! same three files.

use std::f64::consts::PI;
use std::fmt::Write as _;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};

use super::format::{DetectionSpec, Region};
use crate::{EstimationError, Result};

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GenConfig {
    /// Number of targets (≥ 2); they cross in pairs, an odd one out flies alone.
    pub targets: usize,
    /// Number of scans (scan k at t = k·dt).
    pub scans: usize,
    /// Scan period (s).
    pub dt: f64,
    /// Detection probability per target and scan.
    pub pd: f64,
    /// Mean clutter detections per scan (Poisson), uniform over the region.
    pub clutter_rate: f64,
    /// Position noise std per axis (m).
    pub noise_std: f64,
    /// The region is the square `[−half_width, half_width]²` (m).
    pub half_width: f64,
    /// Target speeds are uniform in `[speed_min, speed_max]` (m/s).
    pub speed_min: f64,
    /// See `speed_min`.
    pub speed_max: f64,
    /// Crossing angles are uniform in `[min_angle, π − min_angle]` (rad).
    pub min_angle: f64,
    /// `motion.accel_std` written as a hint for the trackers (m/s²); the truth itself is straight.
    pub accel_std_hint: f64,
}

impl Default for GenConfig {
    /// Six targets (three crossings), 200 scans at 1 Hz, Pd 0.9, 10 m noise, 10 km × 10 km,
    /// 12–25 m/s, crossing angles 30°–150°, one clutter detection per scan on average.
    fn default() -> Self {
        Self {
            targets: 6,
            scans: 200,
            dt: 1.0,
            pd: 0.9,
            clutter_rate: 1.0,
            noise_std: 10.0,
            half_width: 5000.0,
            speed_min: 12.0,
            speed_max: 25.0,
            min_angle: PI / 6.0,
            accel_std_hint: 0.3,
        }
    }
}

/// The three files of a generated scenario, and where the crossings are.
#[derive(Debug, Clone, PartialEq)]
pub struct Generated {
    /// `scenario.json`.
    pub scenario_json: String,
    /// `measurements.jsonl`.
    pub measurements_jsonl: String,
    /// `truth.csv`.
    pub truth_csv: String,
    /// `(scan, target a, target b)` of each crossing: both are at the same point at that scan.
    pub crossings: Vec<(usize, usize, usize)>,
}

/// A straight-line target alive from scan `birth` on: `p(t) = c + v (t − tc)`.
#[derive(Debug, Clone, Copy)]
struct Line {
    c: [f64; 2],
    tc: f64,
    v: [f64; 2],
    birth: usize,
}

impl Line {
    fn at(&self, t: f64) -> [f64; 2] {
        [
            self.c[0] + self.v[0] * (t - self.tc),
            self.c[1] + self.v[1] * (t - self.tc),
        ]
    }
}

/// Generates a scenario from `seed`.
pub fn generate(seed: u64, cfg: &GenConfig) -> Result<Generated> {
    let ok = cfg.targets >= 2
        && cfg.scans >= 2
        && cfg.dt > 0.0
        && cfg.pd > 0.0
        && cfg.pd <= 1.0
        && cfg.clutter_rate >= 0.0
        && cfg.noise_std > 0.0
        && cfg.half_width > 0.0
        && cfg.speed_min > 0.0
        && cfg.speed_max >= cfg.speed_min
        && cfg.min_angle >= 0.0
        && cfg.min_angle < PI / 2.0
        && cfg.accel_std_hint >= 0.0
        && [
            cfg.dt,
            cfg.clutter_rate,
            cfg.half_width,
            cfg.speed_max,
            cfg.accel_std_hint,
        ]
        .iter()
        .all(|v| v.is_finite());
    if !ok {
        return Err(EstimationError::InvalidParameter(format!(
            "generator configuration out of range: {cfg:?}"
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let horizon = cfg.scans as f64 * cfg.dt;
    let centre_box = 0.15 * cfg.half_width;
    let mut lines = Vec::with_capacity(cfg.targets);
    let mut crossings = Vec::new();
    while lines.len() < cfg.targets {
        let k = ((rng.random_range(0.35..0.65) * cfg.scans as f64).round() as usize).max(1);
        let c = [
            rng.random_range(-centre_box..=centre_box),
            rng.random_range(-centre_box..=centre_box),
        ];
        let h1 = rng.random_range(0.0..2.0 * PI);
        let turn = rng.random_range(cfg.min_angle..=PI - cfg.min_angle);
        let h2 = if rng.random_bool(0.5) {
            h1 + turn
        } else {
            h1 - turn
        };
        let tc = k as f64 * cfg.dt;
        let pair = lines.len() + 1 < cfg.targets;
        for (i, h) in [h1, h2]
            .into_iter()
            .enumerate()
            .take(if pair { 2 } else { 1 })
        {
            let s = rng.random_range(cfg.speed_min..=cfg.speed_max);
            // The second target of a pair appears during the first fifth of the run.
            let birth = if i == 0 {
                0
            } else {
                rng.random_range(0..=cfg.scans / 5).min(k)
            };
            lines.push(Line {
                c,
                tc,
                v: [s * h.sin(), s * h.cos()],
                birth,
            });
        }
        if pair {
            crossings.push((k, lines.len() - 2, lines.len() - 1));
        }
    }

    let mut truth = String::from("t,target,x,y,z,vx,vy,vz,mode\n");
    let mut meas = String::new();
    let poisson = if cfg.clutter_rate > 0.0 {
        Some(
            Poisson::new(cfg.clutter_rate)
                .map_err(|e| EstimationError::InvalidParameter(format!("clutter rate: {e}")))?,
        )
    } else {
        None
    };
    let hw = cfg.half_width;
    let mut scan: Vec<[f64; 2]> = Vec::new();
    for k in 0..=cfg.scans {
        let t = k as f64 * cfg.dt;
        scan.clear();
        for (i, l) in lines.iter().enumerate().filter(|(_, l)| l.birth <= k) {
            let p = l.at(t);
            // Writing to a String cannot fail.
            let _ = writeln!(
                truth,
                "{t},T{i},{:.4},{:.4},0,{:.4},{:.4},0,CV",
                p[0], p[1], l.v[0], l.v[1]
            );
            if rng.random_bool(cfg.pd) {
                let nx: f64 = rng.sample(StandardNormal);
                let ny: f64 = rng.sample(StandardNormal);
                scan.push([p[0] + cfg.noise_std * nx, p[1] + cfg.noise_std * ny]);
            }
        }
        let n_clutter = poisson.map_or(0.0, |p| p.sample(&mut rng)) as usize;
        for _ in 0..n_clutter {
            scan.push([rng.random_range(-hw..=hw), rng.random_range(-hw..=hw)]);
        }
        scan.shuffle(&mut rng);
        for z in &scan {
            let _ = writeln!(
                meas,
                r#"{{"t":{t},"sensor":"radar","kind":"position","platform":{{"pos":[0,0,0],"vel":[0,0,0]}},"z":[{:.4},{:.4}]}}"#,
                z[0], z[1]
            );
        }
    }

    use crate::scenario as fmt;
    let target = |id: String| fmt::Target {
        id,
        size_m: None,
        size_prior: None,
        on_ground: None,
    };
    let targets: Vec<fmt::Target> = (0..lines.len()).map(|i| target(format!("T{i}"))).collect();
    let detection = DetectionSpec {
        pd: cfg.pd,
        clutter_rate: cfg.clutter_rate,
        region: Some(Region {
            min: [-hw, -hw],
            max: [hw, hw],
        }),
    };
    let json_err =
        |e: serde_json::Error| EstimationError::InvalidParameter(format!("scenario.json: {e}"));
    let mut extensions = serde_json::Map::new();
    extensions.insert(
        "targets".into(),
        serde_json::to_value(&targets).map_err(json_err)?,
    );
    extensions.insert(
        "detection".into(),
        serde_json::to_value(&detection).map_err(json_err)?,
    );
    let scenario = fmt::Scenario {
        format: fmt::FORMAT_ID.into(),
        name: format!("multi_crossing_seed{seed}"),
        description: "Targets crossing in pairs (same point, same scan), one planar position \
                      sensor, Pd < 1, Poisson clutter (FORMAT-MULTI.md)."
            .into(),
        dims: 2,
        plane_z: Some(0.0),
        time: fmt::TimeSpec {
            t0: 0.0,
            dt: cfg.dt,
            t_end: horizon,
        },
        target: target("multi".into()),
        platforms: vec![fmt::Platform {
            id: "gcs".into(),
            kind: "ground".into(),
        }],
        sensors: vec![fmt::Sensor {
            id: "radar".into(),
            platform: "gcs".into(),
            kind: crate::measurement::MeasKind::Position,
            ncomp: Some(2),
            rate_hz: Some(1.0 / cfg.dt),
            noise: fmt::Noise::Gaussian {
                std: vec![cfg.noise_std, cfg.noise_std],
            },
            bias: None,
        }],
        roads: Vec::new(),
        motion: Some(fmt::Motion::cv(cfg.accel_std_hint)),
        prior: None,
        linear_system: None,
        hints: serde_json::Value::Object(serde_json::Map::new()),
        scoring: fmt::Scoring {
            t_start: 0.0,
            primary: "state".into(),
        },
    };
    let generator = fmt::Generator {
        family: "harrier-multi-crossing".into(),
        seed,
        params: serde_json::json!({
            "targets": cfg.targets, "scans": cfg.scans, "crossings": crossings.len(),
            "speed": [cfg.speed_min, cfg.speed_max], "min_angle_rad": cfg.min_angle
        }),
    };
    let scenario_json = fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(None),
        extensions,
        generator,
    }
    .to_json()
    .map_err(json_err)?;
    Ok(Generated {
        scenario_json,
        measurements_jsonl: meas,
        truth_csv: truth,
        crossings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::format::MultiScenario;

    #[test]
    fn seeded_and_readable() {
        let cfg = GenConfig {
            scans: 60,
            ..GenConfig::default()
        };
        let a = generate(3, &cfg).unwrap();
        assert_eq!(a, generate(3, &cfg).unwrap());
        assert_ne!(
            a.measurements_jsonl,
            generate(4, &cfg).unwrap().measurements_jsonl
        );
        let m = MultiScenario::parse(&a.scenario_json, &a.measurements_jsonl, Some(&a.truth_csv))
            .unwrap();
        assert_eq!(m.targets.len(), 6);
        assert_eq!(m.scans.len(), 61);
        assert_eq!(a.crossings.len(), 3);
        // At a crossing scan both targets are at the same point.
        for &(k, i, j) in &a.crossings {
            let truths = m.truth_at(m.scans[k].t);
            let p = |id| truths.iter().find(|(x, _)| *x == id).unwrap().1;
            assert!((p(i)[0] - p(j)[0]).abs() < 1e-3 && (p(i)[1] - p(j)[1]).abs() < 1e-3);
        }
        // About Pd · targets + clutter detections per scan.
        let n: usize = m.scans.iter().map(|s| s.detections.len()).sum();
        let per_scan = n as f64 / m.scans.len() as f64;
        assert!(per_scan > 3.0 && per_scan < 9.0, "{per_scan}");
        assert!(generate(1, &GenConfig { targets: 1, ..cfg }).is_err());
    }
}
