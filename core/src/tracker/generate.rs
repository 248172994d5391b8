//! Seeded generators of multi-target scenarios in the format of `FORMAT-MULTI.md`: [`generate`],
//! pairs of targets whose straight paths cross at the same point at the same scan, detected with
//! probability `pd` by one planar position sensor, plus Poisson clutter uniform over a square;
//! and [`groups::generate`], turning ground targets in close crossing, parallel and opposing
//! groups.
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

pub mod groups;

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
    /// One entry per row of `truth.csv`, in its order: `(t, i, detected)`, whether the sensor
    /// detected target `T{i}` at that scan (what the unlabelled detections do not say).
    pub detected: Vec<(f64, usize, bool)>,
    /// One entry per line of `measurements.jsonl`, in its order: the target `T{i}` the
    /// detection is of, `None` for clutter (the labels a tracker never sees; for the
    /// known-association bound of `harrier track-eval`).
    pub origins: Vec<Option<usize>>,
}

impl Generated {
    /// The targets (`i` of `T{i}`) detected at least twice in their first three scans: those
    /// a rule that needs two detections can confirm within three scans at all.
    pub fn confirmable(&self) -> std::collections::BTreeSet<usize> {
        let mut seen: std::collections::BTreeMap<usize, (usize, usize)> = Default::default();
        for &(_, i, hit) in &self.detected {
            let (scans, hits) = seen.entry(i).or_default();
            if *scans < 3 {
                *scans += 1;
                *hits += usize::from(hit);
            }
        }
        seen.into_iter()
            .filter(|(_, (_, hits))| *hits >= 2)
            .map(|(i, _)| i)
            .collect()
    }
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

    let poisson = clutter(cfg.clutter_rate)?;
    let hw = cfg.half_width;
    let region = Region {
        min: [-hw, -hw],
        max: [hw, hw],
    };
    let mut files = Files::default();
    let mut alive = Vec::new();
    for k in 0..=cfg.scans {
        let t = k as f64 * cfg.dt;
        alive.clear();
        for (i, l) in lines.iter().enumerate().filter(|(_, l)| l.birth <= k) {
            alive.push((i, l.at(t), l.v, "CV"));
        }
        files.scan(
            &mut rng,
            t,
            &alive,
            cfg.pd,
            cfg.noise_std,
            poisson.as_ref(),
            &region,
        );
    }
    let scenario_json = Doc {
        name: format!("multi_crossing_seed{seed}"),
        description: "Targets crossing in pairs (same point, same scan), one planar position \
                      sensor, Pd < 1, Poisson clutter (FORMAT-MULTI.md).",
        targets: lines.len(),
        dt: cfg.dt,
        horizon,
        pd: cfg.pd,
        clutter_rate: cfg.clutter_rate,
        noise_std: cfg.noise_std,
        region,
        motion: crate::scenario::Motion::cv(cfg.accel_std_hint),
        generator: crate::scenario::Generator {
            family: "harrier-multi-crossing".into(),
            seed,
            params: serde_json::json!({
                "targets": cfg.targets, "scans": cfg.scans, "crossings": crossings.len(),
                "speed": [cfg.speed_min, cfg.speed_max], "min_angle_rad": cfg.min_angle
            }),
        },
    }
    .into_json()?;
    Ok(Generated {
        scenario_json,
        measurements_jsonl: files.meas,
        truth_csv: files.truth,
        crossings,
        detected: files.detected,
        origins: files.origins,
    })
}

/// The Poisson law of the clutter count, `None` for no clutter.
fn clutter(rate: f64) -> Result<Option<Poisson<f64>>> {
    if rate > 0.0 {
        Poisson::new(rate)
            .map(Some)
            .map_err(|e| EstimationError::InvalidParameter(format!("clutter rate: {e}")))
    } else {
        Ok(None)
    }
}

/// `truth.csv` and `measurements.jsonl` as a generator writes them, scan by scan.
#[derive(Debug)]
struct Files {
    truth: String,
    meas: String,
    /// Per truth row: `(t, target, detected)`.
    detected: Vec<(f64, usize, bool)>,
    /// Per measurement line: the target it is of, `None` for clutter.
    origins: Vec<Option<usize>>,
}

impl Default for Files {
    fn default() -> Self {
        Self {
            truth: String::from("t,target,x,y,z,vx,vy,vz,mode\n"),
            meas: String::new(),
            detected: Vec::new(),
            origins: Vec::new(),
        }
    }
}

impl Files {
    /// One scan at `t`: a truth row for each target alive `(index, position, velocity, mode)`,
    /// each detected with probability `pd` with Gaussian noise of std `noise` per axis, plus
    /// Poisson clutter uniform over `region`, shuffled, as one planar position sensor's lines.
    #[allow(clippy::too_many_arguments)]
    fn scan(
        &mut self,
        rng: &mut ChaCha8Rng,
        t: f64,
        alive: &[(usize, [f64; 2], [f64; 2], &str)],
        pd: f64,
        noise: f64,
        clutter: Option<&Poisson<f64>>,
        region: &Region,
    ) {
        let mut scan: Vec<([f64; 2], Option<usize>)> = Vec::with_capacity(alive.len());
        for (i, p, v, mode) in alive {
            // Writing to a String cannot fail.
            let _ = writeln!(
                self.truth,
                "{t},T{i},{:.4},{:.4},0,{:.4},{:.4},0,{mode}",
                p[0], p[1], v[0], v[1]
            );
            let hit = rng.random_bool(pd);
            if hit {
                let nx: f64 = rng.sample(StandardNormal);
                let ny: f64 = rng.sample(StandardNormal);
                scan.push(([p[0] + noise * nx, p[1] + noise * ny], Some(*i)));
            }
            self.detected.push((t, *i, hit));
        }
        let n_clutter = clutter.map_or(0.0, |p| p.sample(rng)) as usize;
        for _ in 0..n_clutter {
            scan.push((
                [
                    rng.random_range(region.min[0]..=region.max[0]),
                    rng.random_range(region.min[1]..=region.max[1]),
                ],
                None,
            ));
        }
        scan.shuffle(rng);
        for (z, origin) in &scan {
            self.origins.push(*origin);
            self.meas.push_str(&position_line(t, *z));
            self.meas.push('\n');
        }
    }
}

/// One line of a generated `measurements.jsonl`: the planar position sensor "radar" (on the
/// ground at the origin) detecting `z` (m, to 0.1 mm) at `t`.
pub fn position_line(t: f64, z: [f64; 2]) -> String {
    format!(
        r#"{{"t":{t},"sensor":"radar","kind":"position","platform":{{"pos":[0,0,0],"vel":[0,0,0]}},"z":[{:.4},{:.4}]}}"#,
        z[0], z[1]
    )
}

/// `scenario.json` of a generated scenario: one planar position sensor ("radar" on the ground
/// platform "gcs"), targets `T0…`, the detection block, the motion hints.
#[derive(Debug)]
struct Doc {
    name: String,
    description: &'static str,
    targets: usize,
    dt: f64,
    horizon: f64,
    pd: f64,
    clutter_rate: f64,
    noise_std: f64,
    region: Region,
    motion: crate::scenario::Motion,
    generator: crate::scenario::Generator,
}

impl Doc {
    fn into_json(self) -> Result<String> {
        use crate::scenario as fmt;
        let target = |id: String| fmt::Target {
            id,
            size_m: None,
            size_prior: None,
            on_ground: None,
        };
        let targets: Vec<fmt::Target> =
            (0..self.targets).map(|i| target(format!("T{i}"))).collect();
        let json_err =
            |e: serde_json::Error| EstimationError::InvalidParameter(format!("scenario.json: {e}"));
        let mut extensions = serde_json::Map::new();
        extensions.insert(
            "targets".into(),
            serde_json::to_value(&targets).map_err(json_err)?,
        );
        let scenario = fmt::Scenario {
            format: fmt::FORMAT_ID.into(),
            name: self.name,
            description: self.description.into(),
            dims: 2,
            plane_z: Some(0.0),
            time: fmt::TimeSpec {
                t0: 0.0,
                dt: self.dt,
                t_end: self.horizon,
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
                rate_hz: Some(1.0 / self.dt),
                noise: fmt::Noise::Gaussian {
                    std: vec![self.noise_std, self.noise_std],
                },
                bias: None,
            }],
            roads: Vec::new(),
            motion: Some(self.motion),
            prior: None,
            linear_system: None,
            hints: serde_json::Value::Object(serde_json::Map::new()),
            scoring: fmt::Scoring {
                t_start: 0.0,
                primary: "state".into(),
            },
            detection: Some(DetectionSpec {
                pd: self.pd,
                clutter_rate: self.clutter_rate,
                region: Some(self.region),
            }),
        };
        fmt::ScenarioDocument {
            scenario,
            frame: fmt::Frame::enu(None),
            extensions,
            generator: self.generator,
        }
        .to_json()
        .map_err(json_err)
    }
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
