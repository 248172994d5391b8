//! `harrier-sim record`: runs a [`SimScenario`] for T simulated seconds, as fast as possible (no
//! sockets, no wall clock), and writes what the vehicles' sensors saw as a `gcs-scenario/1`
//! directory (`../shared/scenarios/FORMAT.md`), or its multi-target extension (`FORMAT-MULTI.md`)
//! when there are several targets or clutter, so every simulated run can be replayed with
//! `harrier replay` and scored with `score.py`.
//!
//! The vehicles are [`Vehicle`]s flown through their MAVLink interface like a client would, by
//! harrier-link's [`OffboardSequence`]: COMMAND_LONG arm and takeoff, then OFFBOARD with a
//! SET_POSITION_TARGET_LOCAL_NED velocity setpoint every physics step, computed from the true
//! target state by the scenario's [`Behaviour`] (LGVF standoff orbit, leader–follower offset,
//! hold, cruise). Vehicle `k` (ids 1…K) launches `3 (k − 1)` s after the first, which also breaks the symmetry of several
//! vehicles orbiting one target (phase coordination then spreads them, \[CIMM\] §4.3). During the
//! scenario's pre-roll the targets wait at their t = 0 state and nothing is recorded.
//!
//! Time runs on a 50 Hz grid; every sensor rate must divide 50 Hz, so scan times are exact
//! (`k / rate`). `truth.csv` has a row (per target) at every scan time of any sensor.

use std::path::{Path, PathBuf};

use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::phase::{PhaseNeighbours, phase_of};
use harrier_core::guidance::{Limits, StandoffLaw, TargetEstimate, UavState};
use harrier_core::measurement::{Geometry, MeasKind};
use harrier_core::scenario as fmt;
use harrier_link::autopilot::VehicleStatus;
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;
use harrier_link::offboard::{OffboardConfig, OffboardError, OffboardSequence, Steer};
use harrier_link::scenario_out;
use nalgebra::{Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde_json::json;

use crate::sensors::{SensorSuite, platform_pose};
use crate::setup::{
    AirframeSpec, Behaviour, ScenarioError, SensorType, SimScenario, Source, TargetMotion,
};
use crate::vehicle::{Airframe, Vehicle, VehicleConfig};
use crate::world::World;

/// Rate of the simulation grid (Hz): physics, setpoints and the times sensors may scan at.
pub const GRID_HZ: u32 = 50;
/// ChaCha stream of the prior's draw (the world uses 0, sensors `1 << 32 | …`).
const PRIOR_STREAM: u64 = 1;
/// Delay between two vehicles' launches (s).
const LAUNCH_STAGGER_S: f64 = 3.0;
/// Height of the initial takeoff before OFFBOARD takes over (m).
const TAKEOFF_HEIGHT_M: f32 = 10.0;
/// Longest run (s).
const MAX_DURATION_S: f64 = 86_400.0;

/// `harrier-sim record` options.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// Preset name (cimm-road, leader, radar, radar-abrupt, radar-markov, crossing) or JSON file.
    #[arg(long)]
    pub scenario: String,
    /// Seed of every random draw (targets, noise, detection, clutter, prior).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated duration (s) after the pre-roll.
    #[arg(long)]
    pub duration: f64,
    /// Output directory (must not exist, or be empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of vehicles (ids 1…K), each with every sensor of the scenario.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..))]
    pub count: u8,
}

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The scenario is unusable.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// Options or scenario do not fit `record`.
    #[error("{0}")]
    Config(String),
    /// A vehicle refused a command.
    #[error("vehicle {vehicle}: {message}")]
    Vehicle {
        /// Vehicle id.
        vehicle: u8,
        /// What it refused.
        message: String,
    },
    /// The output could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// Path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// What to record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordConfig {
    /// Seed of every random draw.
    pub seed: u64,
    /// Simulated duration after the pre-roll (s).
    pub duration_s: f64,
    /// Number of vehicles.
    pub count: u8,
}

/// Counts of a recording.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RecordStats {
    /// Sensor scans (all vehicles).
    pub scans: u64,
    /// Target-originated detections.
    pub detections: u64,
    /// Clutter detections written (multi-target format only).
    pub clutter: u64,
    /// Truth rows.
    pub truth_rows: u64,
    /// Whether the multi-target extension was written.
    pub multi: bool,
}

/// The three files of a recorded scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// `scenario.json`.
    pub scenario_json: String,
    /// `measurements.jsonl`.
    pub measurements_jsonl: String,
    /// `truth.csv`.
    pub truth_csv: String,
    /// Counts.
    pub stats: RecordStats,
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// A vehicle and where it is in its launch sequence.
struct Pilot {
    vehicle: Vehicle,
    launch_at: f64,
    sequence: OffboardSequence,
    limits: Limits,
}

impl Pilot {
    /// From `launch_at` on, the offboard sequence at vehicle time `now` with the behaviour's
    /// velocity `cmd`, every message delivered at once and every reply fed back (so arming,
    /// takeoff and the OFFBOARD switch may all happen within one step).
    fn fly(&mut self, now: f64, cmd: Option<Vector3<f64>>) -> Result<(), RecordError> {
        if now < self.launch_at {
            return Ok(());
        }
        let id = self.vehicle.id();
        let refused = |e: OffboardError| RecordError::Vehicle {
            vehicle: id,
            message: e.to_string(),
        };
        loop {
            let status = VehicleStatus {
                armed: self.vehicle.armed(),
                personality: self.vehicle.personality(),
                mode: Some(self.vehicle.mode()),
                at: now,
            };
            let height = Some(self.vehicle.state().position.z);
            let steer = cmd.map(Steer::velocity);
            let out = self
                .sequence
                .next(now, &status, height, steer)
                .map_err(refused)?;
            if out.is_empty() {
                return Ok(());
            }
            for msg in &out {
                for reply in self.vehicle.handle(now, msg) {
                    self.sequence.handle(now, &reply).map_err(refused)?;
                }
            }
        }
    }
}

/// The fixed wing of the \[CIMM\] cases (harrier-core's `Limits::fixed_wing`: 12–35 m/s, about
/// 0.3 rad/s at 25 m/s), set through the vehicle's PX4 parameters as a user would: airspeed
/// 12–35 m/s, trim 25 m/s, a 40° bank limit.
fn configure_cimm_fixed_wing(v: &mut Vehicle) {
    use mavlink::dialects::common::{MavMessage, MavParamType, PARAM_SET_DATA};
    for (name, value) in [
        ("FW_AIRSPD_MAX", 35.0),
        ("FW_AIRSPD_MIN", 12.0),
        ("FW_AIRSPD_TRIM", 25.0),
        ("FW_R_LIM", 40.0),
    ] {
        let set = MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: v.id(),
            target_component: 1,
            param_id: name.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        });
        v.handle(0.0, &set);
    }
}

/// Velocity command of behaviour `b` for vehicle `k` (0-based) of `n`.
fn behaviour_command(
    b: &Behaviour,
    k: usize,
    uav: &UavState,
    others: &[Vector2<f64>],
    targets: &[TargetEstimate],
    limits: &Limits,
) -> Option<Vector3<f64>> {
    let clamp_h = |v: Vector2<f64>| {
        let n = v.norm();
        if n > limits.v_max {
            v * (limits.v_max / n)
        } else {
            v
        }
    };
    let vz_to = |z: f64| (0.5 * (z - uav.position.z)).clamp(-limits.vz_max, limits.vz_max);
    match b {
        Behaviour::Orbit {
            target,
            radius_m,
            height_m,
            speed_mps,
        } => {
            let t = targets.get(*target)?;
            let law = Lgvf::new(*radius_m, *height_m, *speed_mps);
            // Ring order along the (counter-clockwise) orbit: ascending phase.
            let centre = t.position.xy();
            let mut ring: Vec<(f64, usize)> = others
                .iter()
                .enumerate()
                .map(|(i, p)| (phase_of(*p, centre), i))
                .collect();
            ring.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let phases: Vec<f64> = ring.iter().map(|r| r.0).collect();
            let me = ring.iter().position(|r| r.1 == k)?;
            let phase = PhaseNeighbours::ring(&phases, me);
            Some(law.command(uav, Some(t), limits, phase.as_ref()).velocity)
        }
        Behaviour::Follow {
            target,
            offset_m,
            height_m,
            spacing_m,
        } => {
            let t = targets.get(*target)?;
            let vt = t.velocity.xy();
            let fwd = vt.try_normalize(0.1).unwrap_or(Vector2::new(0.0, 1.0));
            let right = Vector2::new(fwd.y, -fwd.x);
            let goal =
                t.position.xy() + right * (offset_m[0] + k as f64 * spacing_m) + fwd * offset_m[1];
            let vh = clamp_h(vt + (goal - uav.horizontal_position()) * 0.3);
            Some(Vector3::new(vh.x, vh.y, vz_to(t.position.z + height_m)))
        }
        Behaviour::Hold {
            position,
            spacing_m,
        } => {
            let goal = Vector2::new(position[0] + k as f64 * spacing_m, position[1]);
            let vh = clamp_h((goal - uav.horizontal_position()) * 0.5);
            Some(Vector3::new(vh.x, vh.y, vz_to(position[2])))
        }
        Behaviour::Cruise {
            velocity,
            altitude_m,
        } => Some(Vector3::new(velocity[0], velocity[1], vz_to(*altitude_m))),
    }
}

/// Runs `scenario` and returns the three files; `progress` gets the fraction done (0–1).
pub fn record(
    scenario: &SimScenario,
    cfg: &RecordConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<Recording, RecordError> {
    scenario.validate(&Source::Named(scenario.name.clone()))?;
    if !(cfg.duration_s.is_finite() && cfg.duration_s > 0.0 && cfg.duration_s <= MAX_DURATION_S) {
        return Err(RecordError::Config(format!(
            "--duration must be in (0, {MAX_DURATION_S}] s, got {}",
            cfg.duration_s
        )));
    }
    if cfg.count == 0 {
        return Err(RecordError::Config("--count must be at least 1".into()));
    }
    let hz = f64::from(GRID_HZ);
    let mut truth_every = 0;
    for s in &scenario.sensors {
        let steps = hz / s.rate_hz;
        if (steps - steps.round()).abs() > 1e-9 || steps.round() < 1.0 {
            return Err(RecordError::Config(format!(
                "sensor {}: record needs rates that divide {GRID_HZ} Hz, got {} Hz",
                s.id, s.rate_hz
            )));
        }
        truth_every = gcd(truth_every, steps.round() as u64);
    }
    let multi = scenario.is_multi();
    let origin = scenario.origin;
    let frame = LocalFrame::new(origin);
    let geometry = Geometry::planar(scenario.plane_z());
    let airframe = match scenario.vehicles.airframe {
        AirframeSpec::Multirotor => Airframe::Multirotor,
        AirframeSpec::FixedWing => Airframe::FixedWing,
    };
    let mut world = World::new(scenario, cfg.seed)?;
    let initial = world.truth();
    let mut pilots = Vec::with_capacity(cfg.count.into());
    let mut suites = Vec::with_capacity(cfg.count.into());
    for k in 0..cfg.count {
        let id = k + 1;
        let config = VehicleConfig {
            airframe,
            origin,
            ..VehicleConfig::new(id)
        };
        let mut vehicle = Vehicle::new(config, 0.0);
        if airframe == Airframe::FixedWing {
            configure_cimm_fixed_wing(&mut vehicle);
        }
        let takeoff = OffboardConfig::new(Some(TAKEOFF_HEIGHT_M), Some(origin.alt_m as f32));
        pilots.push(Pilot {
            limits: vehicle.limits(),
            sequence: OffboardSequence::new(id, vehicle.personality(), takeoff),
            vehicle,
            launch_at: f64::from(k) * LAUNCH_STAGGER_S,
        });
        suites.push(SensorSuite::new(scenario, cfg.seed, id)?);
    }

    let n_pre = (scenario.vehicles.preroll_s * hz).round() as u64;
    let n_run = (cfg.duration_s * hz + 1e-6).floor() as u64;
    let mut meas = String::new();
    let mut truth = String::from(if multi {
        scenario_out::MULTI_TRUTH_HEADER
    } else {
        scenario_out::TRUTH_HEADER
    });
    let mut stats = RecordStats {
        multi,
        ..RecordStats::default()
    };
    let mut last_pct = 0;
    for n in 0..=n_pre + n_run {
        let now = n as f64 / hz;
        let running = n >= n_pre;
        let t = if running {
            (n - n_pre) as f64 / hz
        } else {
            0.0
        };
        world.advance(t);
        let truths = world.truth();
        for p in &mut pilots {
            p.vehicle.advance(now);
        }
        if running {
            let m = n - n_pre;
            if m % truth_every == 0 {
                for tr in &truths {
                    let target = multi.then_some(tr.id.as_str());
                    scenario_out::push_truth_row(&mut truth, t, target, &tr.state, &tr.mode);
                    stats.truth_rows += 1;
                }
            }
            let mut lines: Vec<(String, String)> = Vec::new();
            for (p, suite) in pilots.iter().zip(&mut suites) {
                let id = p.vehicle.id();
                let pose = platform_pose(&p.vehicle);
                for l in suite.scan_labelled(t, id, &pose, origin, &world) {
                    stats.scans += 1;
                    // The scenario's frame is the scans' own: this changes nothing, bit for bit.
                    let local = scan_in_frame(&l.scan, &frame, geometry).map_err(|e| {
                        RecordError::Config(format!("scan of {}: {e}", l.scan.sensor))
                    })?;
                    let sensor = scenario_out::sensor_id(&local.sensor, id);
                    for (z, src) in local.detections.iter().zip(&l.sources) {
                        match src {
                            Some(_) => stats.detections += 1,
                            None if multi => stats.clutter += 1,
                            None => continue,
                        }
                        let line = scenario_out::measurement(&local, t, &sensor, z.clone());
                        let text = serde_json::to_string(&line).map_err(|e| {
                            RecordError::Config(format!("cannot serialise a measurement: {e}"))
                        })?;
                        lines.push((sensor.clone(), text));
                    }
                }
            }
            // Sorted by sensor within a time (stable: a scan's detections keep their order).
            lines.sort_by(|a, b| a.0.cmp(&b.0));
            for (_, l) in lines {
                meas.push_str(&l);
                meas.push('\n');
            }
            let pct = (100 * m / n_run.max(1)) as u32;
            if pct > last_pct {
                last_pct = pct;
                progress(f64::from(pct) / 100.0);
            }
        }
        // Setpoints for the next step, from the state now.
        let estimates: Vec<TargetEstimate> = truths
            .iter()
            .map(|s| TargetEstimate {
                position: Vector3::new(s.state[0], s.state[1], s.state[2]),
                velocity: if running {
                    Vector3::new(s.state[3], s.state[4], s.state[5])
                } else {
                    Vector3::zeros()
                },
            })
            .collect();
        let positions: Vec<Vector2<f64>> = pilots
            .iter()
            .map(|p| p.vehicle.state().horizontal_position())
            .collect();
        for (k, p) in pilots.iter_mut().enumerate() {
            let cmd = behaviour_command(
                &scenario.vehicles.behaviour,
                k,
                &p.vehicle.state(),
                &positions,
                &estimates,
                &p.limits,
            );
            p.fly(now, cmd)?;
        }
    }
    let scenario_json = scenario_json(scenario, cfg, &initial, truth_every, multi)?;
    Ok(Recording {
        scenario_json,
        measurements_jsonl: meas,
        truth_csv: truth,
        stats,
    })
}

/// `scenario.json` of a recording, through harrier-core's scenario types.
fn scenario_json(
    s: &SimScenario,
    cfg: &RecordConfig,
    initial: &[harrier_core::detection::TargetTruth],
    truth_every: u64,
    multi: bool,
) -> Result<String, RecordError> {
    let serr =
        |e: serde_json::Error| RecordError::Config(format!("cannot serialise scenario.json: {e}"));
    let target = |i: usize| {
        let t = &s.targets[i];
        let on_ground = matches!(t.motion, TargetMotion::Road { .. }) || s.plane_z() == 0.0;
        fmt::Target {
            id: t.id.clone(),
            size_m: t.size_known.then_some(t.size_m),
            size_prior: (!t.size_known).then_some(fmt::SizePrior {
                mean: 1.2 * t.size_m,
                std: 0.3 * t.size_m,
            }),
            on_ground: Some(on_ground),
        }
    };
    let kind = match s.vehicles.airframe {
        AirframeSpec::Multirotor => "multirotor",
        AirframeSpec::FixedWing => "fixed_wing",
    };
    let mut sensors = Vec::new();
    let mut platforms = Vec::new();
    for id in 1..=cfg.count {
        platforms.push(fmt::Platform {
            id: scenario_out::platform_id(id),
            kind: kind.into(),
        });
        for spec in &s.sensors {
            let bias = matches!(spec.model, SensorType::Radar { .. }).then(|| {
                json!({"model": "unknown",
                       "description": "z_i = (1 + s_i) h_i + o_i + v_i with unknown, possibly \
                                       time-varying s, o (may be zero)"})
            });
            sensors.push(fmt::Sensor {
                id: scenario_out::sensor_id(&spec.id, id),
                platform: scenario_out::platform_id(id),
                kind: spec.kind(),
                ncomp: (spec.kind() == MeasKind::Position).then_some(2),
                rate_hz: Some(spec.rate_hz),
                noise: fmt::Noise::Gaussian {
                    std: spec.noise_std.clone(),
                },
                bias,
            });
        }
    }
    let motion = s
        .estimator
        .motion
        .clone()
        .unwrap_or_else(|| fmt::Motion::cv(1.0));
    let prior = (!multi).then(|| {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        rng.set_stream(PRIOR_STREAM);
        let x = initial.first().map_or([0.0; 6], |t| t.state);
        let sd = s.estimator.prior_std;
        let mut state = x;
        for (k, i) in [0, 1, 3, 4].into_iter().enumerate() {
            let n: f64 = rng.sample(StandardNormal);
            state[i] += sd[k] * n;
        }
        let cov: Vec<Vec<f64>> = (0..4)
            .map(|r| {
                (0..4)
                    .map(|c| if r == c { sd[r] * sd[r] } else { 0.0 })
                    .collect()
            })
            .collect();
        fmt::Prior {
            t: 0.0,
            state,
            cov,
            cov_dims: Some(vec![0, 1, 3, 4]),
        }
    });
    let scenario = fmt::Scenario {
        format: fmt::FORMAT_ID.into(),
        name: format!("sim_{}_seed{}", s.name.replace('-', "_"), cfg.seed),
        description: format!("harrier-sim record of {}: {}", s.name, s.description),
        dims: 2,
        plane_z: Some(s.plane_z()),
        time: fmt::TimeSpec {
            t0: 0.0,
            dt: truth_every as f64 / f64::from(GRID_HZ),
            t_end: cfg.duration_s,
        },
        target: if multi {
            fmt::Target {
                id: "multi".into(),
                size_m: None,
                size_prior: None,
                on_ground: None,
            }
        } else {
            target(0)
        },
        platforms,
        sensors,
        roads: s.roads.clone(),
        motion: Some(motion),
        prior,
        linear_system: None,
        hints: json!({}),
        scoring: fmt::Scoring {
            t_start: s.estimator.scoring_t_start,
            primary: "state".into(),
        },

        detection: None,
    };
    let mut extensions = serde_json::Map::new();
    if multi {
        let targets: Vec<fmt::Target> = (0..s.targets.len()).map(target).collect();
        extensions.insert(
            "targets".into(),
            serde_json::to_value(targets).map_err(serr)?,
        );
        let first = &s.sensors[0];
        if s.sensors
            .iter()
            .all(|x| x.pd == first.pd && x.clutter_rate == first.clutter_rate)
        {
            extensions.insert(
                "detection".into(),
                json!({"pd": first.pd, "clutter_rate": first.clutter_rate}),
            );
        }
    }
    let generator = fmt::Generator {
        family: "harrier-sim".into(),
        seed: cfg.seed,
        params: json!({
            "scenario": s,
            "count": cfg.count,
            "duration": cfg.duration_s,
            "grid_hz": GRID_HZ,
            "launch_stagger_s": LAUNCH_STAGGER_S,
            "version": env!("CARGO_PKG_VERSION"),
        }),
    };
    fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(Some(s.origin)),
        extensions,
        generator,
    }
    .to_json()
    .map_err(serr)
}

/// Writes a recording into `out` atomically (harrier-link's [`scenario_out::write_dir`]): the
/// files go to a temporary directory beside it, which is then renamed. `out` must not exist or be
/// an empty directory.
pub fn write_dir(rec: &Recording, out: &Path) -> Result<(), RecordError> {
    let files = [
        ("scenario.json", rec.scenario_json.as_str()),
        ("measurements.jsonl", rec.measurements_jsonl.as_str()),
        ("truth.csv", rec.truth_csv.as_str()),
    ];
    scenario_out::write_dir(out, &files).map_err(|e| RecordError::Write {
        path: e.path,
        source: e.source,
    })
}

/// The `record` command: load, run with progress on stderr, write. Returns the counts.
pub fn run(args: &RecordArgs) -> Result<RecordStats, RecordError> {
    let scenario = SimScenario::load(&args.scenario)?;
    let cfg = RecordConfig {
        seed: args.seed,
        duration_s: args.duration,
        count: args.count,
    };
    let start = std::time::Instant::now();
    let mut next_report = 0.1;
    let rec = record(&scenario, &cfg, &mut |f| {
        if f + 1e-9 >= next_report {
            if start.elapsed().as_secs_f64() > 1.0 {
                eprintln!(
                    "harrier-sim record: {:3.0} % ({:.0} / {} s simulated)",
                    f * 100.0,
                    f * cfg.duration_s,
                    cfg.duration_s
                );
            }
            next_report += 0.1;
        }
    })?;
    write_dir(&rec, &args.out)?;
    Ok(rec.stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::scenario::ScenarioData;
    use harrier_core::tracker::format::MultiScenario;

    fn rec(name: &str, seed: u64, duration_s: f64, count: u8) -> Recording {
        let s = SimScenario::preset(name).expect("preset");
        let cfg = RecordConfig {
            seed,
            duration_s,
            count,
        };
        record(&s, &cfg, &mut |_| {}).expect("record")
    }

    #[test]
    fn single_target_recordings_parse_and_are_consistent() {
        let r = rec("cimm-road", 3, 60.0, 2);
        let d = ScenarioData::parse(&r.scenario_json, &r.measurements_jsonl, Some(&r.truth_csv))
            .expect("valid gcs-scenario/1");
        assert_eq!(d.scenario.sensors.len(), 2);
        assert_eq!(d.scenario.platforms.len(), 2);
        // Both UAVs see the target every second, t = 0..60.
        assert_eq!(d.measurements.len(), 2 * 61, "{:?}", r.stats);
        let truth = d.truth.expect("truth");
        assert_eq!(truth.len(), 61);
        // Platforms orbit at about R = 300 m, 300 m above after the pre-roll.
        for m in &d.measurements {
            let (x, y) = harrier_core::scenario::truth_at(&truth, m.t)
                .map(|(s, _, _)| (s[0], s[1]))
                .expect("truth");
            let r = (m.platform.pos[0] - x).hypot(m.platform.pos[1] - y);
            assert!((r - 300.0).abs() < 60.0, "t {} r {r}", m.t);
            assert!(
                (m.platform.pos[2] - 300.0).abs() < 20.0,
                "alt {}",
                m.platform.pos[2]
            );
        }
        assert!(r.stats.detections == 122 && !r.stats.multi);
    }

    #[test]
    fn multi_target_recordings_use_the_extension() {
        let r = rec("crossing", 4, 40.0, 1);
        let m = MultiScenario::parse(&r.scenario_json, &r.measurements_jsonl, Some(&r.truth_csv))
            .expect("valid FORMAT-MULTI");
        assert_eq!(m.targets.len(), 4);
        assert_eq!(m.scans.len(), 81);
        assert!(
            r.stats.multi && r.stats.clutter > 40 && r.stats.clutter < 130,
            "{:?}",
            r.stats
        );
        assert_eq!(m.detection.as_ref().map(|d| d.pd), Some(0.9));
    }

    #[test]
    fn bad_configurations_are_refused() {
        let s = SimScenario::preset("radar").expect("preset");
        let bad = |cfg: RecordConfig| record(&s, &cfg, &mut |_| {}).expect_err("refused");
        let ok = RecordConfig {
            seed: 1,
            duration_s: 10.0,
            count: 1,
        };
        for d in [0.0, -1.0, f64::NAN, 1e9] {
            assert!(
                bad(RecordConfig {
                    duration_s: d,
                    ..ok
                })
                .to_string()
                .contains("--duration")
            );
        }
        let mut s3 = s.clone();
        s3.sensors[0].rate_hz = 3.0;
        let e = record(&s3, &ok, &mut |_| {}).expect_err("3 Hz");
        assert!(e.to_string().contains("divide 50 Hz"), "{e}");
        let dir = std::env::temp_dir().join(format!("harrier-record-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("full")).expect("mkdir");
        std::fs::write(dir.join("full/x"), "x").expect("write");
        let r = record(&s, &ok, &mut |_| {}).expect("record");
        let e = write_dir(&r, &dir.join("full")).expect_err("not empty");
        assert!(e.to_string().contains("full"), "{e}");
        write_dir(&r, &dir.join("new/run")).expect("write");
        assert!(dir.join("new/run/truth.csv").exists());
        assert!(std::fs::read_dir(dir.join("new")).expect("dir").count() == 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
