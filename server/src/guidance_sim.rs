//! `harrier guidance-sim`: closed-loop guidance scenarios.
//!
//! A scenario is target motion, N UAVs ([`harrier_core::guidance::kinematics`]), a guidance law
//! and optionally an estimator fed with simulated measurements (seeded `ChaCha8Rng`). The run
//! records every vehicle's trajectory, computes the figures of GUIDANCE.md, and can write the
//! trajectories (CSV or JSONL), a JSON summary and an SVG picture.
//!
//! Built-in cases ([`Case`]):
//!
//! | name | what |
//! |---|---|
//! | `cimm-static` | [CIMM] §5.2: static target at (1500, 1800, 0) m, UAV from (1100, 1000, 400) m, R = H = 300 m |
//! | `cimm-moving` | [CIMM] §5.1 target (10 m/s, right turn 0.008 rad/s at 140 s, left turn 0.01 rad/s at 360 s; the road of `cimm_road_1uav`), UAV from (−500, −500, 400) m |
//! | `three-static` | three UAVs, phase-coordinated, on the static target of `cimm-static` |
//! | `three-moving` | three UAVs on the moving target of `cimm-moving` |
//! | `bot-formation` | [BOT] §IV Fig. 8: leader + 3 followers regulating LOS ranges, four obstacles |
//! | `bot-observability` | [BOT] §II.B: one bearings-only follower, straight following vs. the eq. (4) maneuver |
//!
//! **Estimator.** The moving cases use the road-constrained IMM of [CIMM] §3.2
//! ([`EstimatorKind::Cimm`], the default; modes CV / CT −0.008 / CT +0.01 rad/s and the road of
//! [`road_network`], σ_m = 2 m, see `RoadCimm`) fed with simulated camera geolocation
//! `Position::<2>` measurements, σ = 10 m, 1 Hz per UAV (as in `cimm_road_3uav`), every UAV's fix
//! applied sequentially; the guidance sees the estimate extrapolated to the current time, never the
//! truth. [`EstimatorKind::Kalman`] (`--estimator kf`) is the comparison: a linear Kalman filter
//! (`Kalman`, `ConstantVelocity::<4>`, q = 0.05 m²/s³) on the same fixes. `--estimator truth`
//! feeds the truth instead. The observability case uses a
//! bearings-only EKF (Joseph update, CV model) on the leader, σ = 1°, 10 Hz.

use std::f64::consts::TAU;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use harrier_core::filter::{
    Extended, Imm, ImmState, Kalman, ModeModel, Predictor, Updater, joseph_update,
};
use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::observability::ObservabilityManeuver;
use harrier_core::guidance::obstacle::{Avoidance, Obstacle, avoid};
use harrier_core::guidance::phase::{PhaseNeighbours, phase_of, spacing_errors};
use harrier_core::guidance::togvf::{Togvf, optimal_entry_length};
use harrier_core::guidance::{Command, Limits, Orbit, StandoffLaw, TargetEstimate, UavState};
use harrier_core::linalg::wrap_angle;
use harrier_core::measurement::{Geometry, Position};
use harrier_core::motion::ConstantVelocity;
use harrier_core::road::RoadNetwork;
use harrier_core::scenario::{self, Segment};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix1x4, Matrix4, SMatrix, Vector1, Vector2, Vector3, Vector4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use crate::estimators::imm::road_update;

/// Why a simulation could not run or its output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Bad option.
    #[error("{0}")]
    Setup(String),
    /// Output failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Plotting failure.
    #[error("plot: {0}")]
    Plot(String),
}

/// A built-in scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    /// [CIMM] §5.2 static target, one UAV.
    CimmStatic,
    /// [CIMM] §5.1 moving target, one UAV.
    CimmMoving,
    /// Three UAVs on the static target.
    ThreeStatic,
    /// Three UAVs on the moving target.
    ThreeMoving,
    /// [BOT] leader + 3 followers with four obstacles.
    BotFormation,
    /// [BOT] bearings-only follower, with and without the observability maneuver.
    BotObservability,
}

impl Case {
    /// Every case with its command-line name.
    pub const ALL: [(&'static str, Case); 6] = [
        ("cimm-static", Case::CimmStatic),
        ("cimm-moving", Case::CimmMoving),
        ("three-static", Case::ThreeStatic),
        ("three-moving", Case::ThreeMoving),
        ("bot-formation", Case::BotFormation),
        ("bot-observability", Case::BotObservability),
    ];
    /// The case called `name`.
    pub fn parse(name: &str) -> Result<Self, SimError> {
        Self::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, c)| *c)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|(n, _)| *n).collect();
                SimError::Setup(format!(
                    "unknown case {name:?}; one of {}",
                    names.join(", ")
                ))
            })
    }
    /// Command-line name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, c)| *c == self)
            .map_or("?", |(n, _)| n)
    }
    /// Default duration (s).
    pub fn default_duration(self) -> f64 {
        match self {
            Case::CimmStatic => 200.0,
            Case::ThreeStatic => 400.0,
            Case::CimmMoving | Case::ThreeMoving => 700.0,
            Case::BotFormation => 420.0,
            Case::BotObservability => 300.0,
        }
    }
}

/// Standoff guidance law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LawKind {
    /// [`Togvf`].
    Togvf,
    /// [`Lgvf`].
    Lgvf,
}

impl LawKind {
    /// `togvf` or `lgvf`.
    pub fn parse(name: &str) -> Result<Self, SimError> {
        match name {
            "togvf" => Ok(Self::Togvf),
            "lgvf" => Ok(Self::Lgvf),
            _ => Err(SimError::Setup(format!(
                "unknown law {name:?}; togvf or lgvf"
            ))),
        }
    }
    fn name(self) -> &'static str {
        match self {
            Self::Togvf => "togvf",
            Self::Lgvf => "lgvf",
        }
    }
}

/// What the standoff guidance sees of the target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorKind {
    /// The true target state.
    Truth,
    /// Kalman filter on simulated camera measurements.
    Kalman,
    /// Road-constrained IMM ([CIMM] §3.2) on simulated camera measurements.
    Cimm,
}

/// Options of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Scenario.
    pub case: Case,
    /// Standoff law (standoff cases).
    pub law: LawKind,
    /// Estimator (standoff cases; default: CIMM for moving targets, truth for static ones).
    pub estimator: Option<EstimatorKind>,
    /// Time step (s).
    pub dt: f64,
    /// Duration (s); `None` for the case's default.
    pub duration: Option<f64>,
    /// RNG seed.
    pub seed: u64,
}

impl SimConfig {
    /// Defaults for `case`: TOGVF, 10 Hz, seed 1.
    pub fn new(case: Case) -> Self {
        Self {
            case,
            law: LawKind::Togvf,
            estimator: None,
            dt: 0.1,
            duration: None,
            seed: 1,
        }
    }
}

/// One recorded state.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Position (m).
    pub pos: [f64; 3],
    /// Velocity (m/s).
    pub vel: [f64; 3],
}

/// A recorded trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Track {
    /// Identifier (`uav1`, `target`, `estimate`, `leader`, …).
    pub id: String,
    /// `uav`, `target` or `estimate`.
    pub kind: &'static str,
    /// States, one per step.
    pub samples: Vec<Sample>,
}

impl Track {
    fn new(id: impl Into<String>, kind: &'static str) -> Self {
        Self {
            id: id.into(),
            kind,
            samples: Vec::new(),
        }
    }
    fn push(&mut self, t: f64, p: Vector3<f64>, v: Vector3<f64>) {
        self.samples.push(Sample {
            t,
            pos: [p.x, p.y, p.z],
            vel: [v.x, v.y, v.z],
        });
    }
}

/// Per-UAV figures of a standoff run (truth-based).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UavFigures {
    /// UAV id.
    pub id: String,
    /// Horizontal path length until first on the circle (|r − R| ≤ 3 m, heading within 1° of the
    /// tangent), m.
    pub path_to_circle_m: Option<f64>,
    /// Time of that event (s).
    pub time_to_circle_s: Option<f64>,
    /// First time with |z − z_t − H| ≤ 1 m (s).
    pub time_to_height_s: Option<f64>,
    /// Bang-bang minimum time from the start height at rest to H (s).
    pub bang_bang_time_s: f64,
    /// Largest excursion beyond H on the far side from the start (m).
    pub height_overshoot_m: f64,
    /// RMS of r − R after first reaching the circle (m).
    pub standoff_rms_m: Option<f64>,
}

/// Figures of the whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Case name.
    pub case: &'static str,
    /// Law name (standoff cases).
    pub law: &'static str,
    /// Estimator used by the guidance.
    pub estimator: &'static str,
    /// Time step (s).
    pub dt: f64,
    /// Duration (s).
    pub duration: f64,
    /// Number of UAVs.
    pub uavs: usize,
    /// Wall time of the simulation loop (ms).
    pub elapsed_ms: f64,
    /// Standoff radius R (m), standoff cases.
    pub radius_m: Option<f64>,
    /// Height H (m), standoff cases.
    pub height_m: Option<f64>,
    /// Per-UAV standoff figures.
    pub per_uav: Vec<UavFigures>,
    /// Geometric optimum entry length (turn + tangent) for the first UAV, static single case (m).
    pub optimal_path_m: Option<f64>,
    /// RMS target-position error of the estimate used by the guidance (m).
    pub estimate_rms_m: Option<f64>,
    /// Max |phase spacing error| over the last 30 % of the run (deg).
    pub phase_max_error_deg: Option<f64>,
    /// RMS phase spacing error over the last 30 % of the run (deg).
    pub phase_rms_error_deg: Option<f64>,
    /// Max |r − R_com| / R_com over all pairs in the last 40 s (formation), percent.
    pub formation_steady_error_pct: Option<f64>,
    /// Max over the whole run, percent.
    pub formation_max_error_pct: Option<f64>,
    /// Samples inside an obstacle (must be 0).
    pub obstacle_penetrations: Option<usize>,
    /// Smallest distance from any vehicle to an obstacle boundary (m).
    pub obstacle_min_clearance_m: Option<f64>,
    /// Range-estimate RMS error over the second half, straight following (m).
    pub range_rms_straight_m: Option<f64>,
    /// Same with the observability maneuver (m).
    pub range_rms_maneuver_m: Option<f64>,
    /// `range_rms_straight_m / range_rms_maneuver_m`.
    pub observability_factor: Option<f64>,
    /// Largest horizontal speed flown (m/s).
    pub max_speed: f64,
    /// Smallest horizontal speed flown (m/s).
    pub min_speed: f64,
    /// Largest turn rate flown (rad/s).
    pub max_turn_rate: f64,
    /// Largest |v_z| (m/s).
    pub max_vz: f64,
    /// Largest |a_z| (m/s²).
    pub max_az: f64,
    /// Limits of the vehicles.
    pub limits: LimitsOut,
}

/// [`Limits`] in the summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LimitsOut {
    /// m/s.
    pub v_max: f64,
    /// m/s.
    pub v_min: f64,
    /// rad/s.
    pub turn_rate_max: f64,
    /// m/s.
    pub vz_max: f64,
    /// m/s².
    pub az_max: f64,
}

impl From<Limits> for LimitsOut {
    fn from(l: Limits) -> Self {
        Self {
            v_max: l.v_max,
            v_min: l.v_min,
            turn_rate_max: l.turn_rate_max,
            vz_max: l.vz_max,
            az_max: l.az_max,
        }
    }
}

/// Everything a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct SimResult {
    /// Figures.
    pub summary: Summary,
    /// Trajectories (UAVs, target, estimate).
    pub tracks: Vec<Track>,
    /// Obstacles of the case.
    pub obstacles: Vec<Obstacle>,
    /// Standoff circle to draw (centre at the final target position, radius).
    pub circle: Option<(Vector2<f64>, f64)>,
}

// ---------------------------------------------------------------------------------------------
// Scenario constants.

/// Standoff radius and height of the [CIMM] cases (m).
pub const R: f64 = 300.0;
/// Observation height (m).
pub const H: f64 = 300.0;
/// Nominal relative speed v₀ (m/s).
pub const V0: f64 = 25.0;
/// Static target of [CIMM] §5.2.
pub const STATIC_TARGET: [f64; 3] = [1500.0, 1800.0, 0.0];
/// UAV start of [CIMM] §5.2.
pub const STATIC_START: [f64; 3] = [1100.0, 1000.0, 400.0];

/// Legs of the [CIMM] §5.1 target: (start time s, turn rate rad/s). Straight, right turn at
/// −0.008 rad/s from 140 s, left turn at 0.01 rad/s from 360 s (the `motion.models` turn rates of
/// `cimm_road_1uav`).
const ROAD_LEGS: [(f64, f64); 3] = [(0.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
/// End of the road's last segment (s of travel); beyond it the road continues along its tangent.
const ROAD_END_S: f64 = 700.0;
/// Lateral-offset std of the road (m), as `sigma_m` of `cimm_road_1uav`.
pub const ROAD_SIGMA_M: f64 = 2.0;

/// Constant-turn propagation of position `p` and velocity `v` at rate `w` over `dt`.
fn ct_step(p: Vector2<f64>, v: Vector2<f64>, w: f64, dt: f64) -> (Vector2<f64>, Vector2<f64>) {
    if w.abs() < 1e-12 {
        return (p + v * dt, v);
    }
    let (s, c) = (w * dt).sin_cos();
    let p = p + Vector2::new(
        (s * v.x - (1.0 - c) * v.y) / w,
        ((1.0 - c) * v.x + s * v.y) / w,
    );
    (p, Vector2::new(c * v.x - s * v.y, s * v.x + c * v.y))
}

/// The [CIMM] §5.1 target (the road of `cimm_road_1uav`): from (200, 300) m at (6, 8) m/s along
/// [`ROAD_LEGS`].
pub fn road_target(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (mut p, mut v) = (Vector2::new(200.0, 300.0), Vector2::new(6.0, 8.0));
    for (i, &(t0, w)) in ROAD_LEGS.iter().enumerate() {
        if i > 0 && t <= t0 {
            break;
        }
        let t1 = ROAD_LEGS.get(i + 1).map_or(f64::INFINITY, |l| l.0);
        (p, v) = ct_step(p, v, w, t.min(t1) - t0);
    }
    (Vector3::new(p.x, p.y, 0.0), Vector3::new(v.x, v.y, 0.0))
}

/// The road the moving target drives on, built from the same legs as [`road_target`]: one line
/// or arc per leg (arc centre on the turn side at |v|/|ω|, sweep ω·duration), `sigma_m` =
/// [`ROAD_SIGMA_M`], width 7 m. Equals the `roads` of `cimm_road_1uav` up to the line's start.
pub fn road_network() -> Result<RoadNetwork, SimError> {
    let at = |t: f64| {
        let (p, v) = road_target(t);
        (p.xy(), v.xy())
    };
    let segments = ROAD_LEGS
        .iter()
        .enumerate()
        .map(|(i, &(t0, w))| {
            let t1 = ROAD_LEGS.get(i + 1).map_or(ROAD_END_S, |l| l.0);
            let ((a, v), (b, _)) = (at(t0), at(t1));
            if w == 0.0 {
                Segment::Line {
                    start: a.into(),
                    end: b.into(),
                }
            } else {
                Segment::Arc {
                    center: (a + Vector2::new(-v.y, v.x) / w).into(),
                    radius: v.norm() / w.abs(),
                    start: a.into(),
                    end: b.into(),
                    sweep_rad: w * (t1 - t0),
                }
            }
        })
        .collect();
    let road = scenario::Road {
        id: "road1".into(),
        width_m: Some(7.0),
        sigma_m: Some(ROAD_SIGMA_M),
        segments,
    };
    RoadNetwork::from_scenario(&[road]).map_err(|e| SimError::Setup(format!("road: {e}")))
}

/// Runs one simulation.
pub fn run(cfg: &SimConfig) -> Result<SimResult, SimError> {
    if !(cfg.dt > 0.0 && cfg.dt <= 1.0) {
        return Err(SimError::Setup(format!(
            "--dt {} must be in (0, 1] s",
            cfg.dt
        )));
    }
    let duration = cfg.duration.unwrap_or(cfg.case.default_duration());
    if !(duration > 0.0 && duration <= 36_000.0) {
        return Err(SimError::Setup(format!(
            "--duration {duration} must be in (0, 36000] s"
        )));
    }
    match cfg.case {
        Case::CimmStatic | Case::CimmMoving | Case::ThreeStatic | Case::ThreeMoving => {
            run_standoff(cfg, duration)
        }
        Case::BotFormation => Ok(run_formation(cfg, duration)),
        Case::BotObservability => Ok(run_observability(cfg, duration)),
    }
}

// ---------------------------------------------------------------------------------------------
// Standoff cases.

fn run_standoff(cfg: &SimConfig, duration: f64) -> Result<SimResult, SimError> {
    let moving = matches!(cfg.case, Case::CimmMoving | Case::ThreeMoving);
    let starts: Vec<Vector3<f64>> = match cfg.case {
        Case::CimmStatic => vec![Vector3::from(STATIC_START)],
        Case::ThreeStatic => vec![
            Vector3::from(STATIC_START),
            Vector3::new(2300.0, 1300.0, 350.0),
            Vector3::new(900.0, 2500.0, 450.0),
        ],
        Case::CimmMoving => vec![Vector3::new(-500.0, -500.0, 400.0)],
        _ => vec![
            Vector3::new(-500.0, -500.0, 400.0),
            Vector3::new(800.0, -300.0, 350.0),
            Vector3::new(-300.0, 1100.0, 450.0),
        ],
    };
    let n = starts.len();
    let estimator = cfg.estimator.unwrap_or(if moving {
        EstimatorKind::Cimm
    } else {
        EstimatorKind::Truth
    });
    let truth = |t: f64| {
        if moving {
            road_target(t)
        } else {
            (Vector3::from(STATIC_TARGET), Vector3::zeros())
        }
    };
    let limits = Limits::fixed_wing();
    let orbit = if n > 1 { Orbit::Ccw } else { Orbit::Auto };
    let togvf = Togvf {
        orbit,
        ..Togvf::new(R, H, V0)
    };
    let lgvf = Lgvf::new(R, H, V0);
    let law: &dyn StandoffLaw = match cfg.law {
        LawKind::Togvf => &togvf,
        LawKind::Lgvf => &lgvf,
    };
    // Start flying towards the target at v₀.
    let (p_t0, _) = truth(0.0);
    let mut uavs: Vec<UavState> = starts
        .iter()
        .map(|p| {
            let d = (p_t0 - p).xy();
            let v = d / d.norm() * V0;
            UavState::new(*p, Vector3::new(v.x, v.y, 0.0))
        })
        .collect();
    let mut tracks: Vec<Track> = (0..n)
        .map(|i| Track::new(format!("uav{}", i + 1), "uav"))
        .collect();
    let mut target_track = Track::new("target", "target");
    let mut est_track = Track::new("estimate", "estimate");

    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noise = Normal::new(0.0, 10.0).ok();
    let cv = ConstantVelocity::<4>::new(0.05);
    let cam = Position::<2>::new(Geometry::planar(0.0), [10.0, 10.0]);
    let mut kf: Option<(f64, Gaussian<4>)> = None;
    let mut cimm = match estimator {
        EstimatorKind::Cimm => Some(RoadCimm::new()?),
        _ => None,
    };
    let mut next_meas = 0.0;
    let mut est_err2 = (0.0, 0usize);

    let steps = (duration / cfg.dt).round() as usize;
    let started = Instant::now();
    let mut phases = vec![0.0; n];
    let mut order: Vec<usize> = (0..n).collect();
    for k in 0..=steps {
        let t = k as f64 * cfg.dt;
        let (pt, vt) = truth(t);
        // Estimator: camera geolocation at 1 Hz per UAV.
        let estimate = match estimator {
            EstimatorKind::Truth => Some(TargetEstimate {
                position: pt,
                velocity: vt,
            }),
            EstimatorKind::Kalman | EstimatorKind::Cimm => {
                if t + 1e-9 >= next_meas {
                    next_meas += 1.0;
                    let zs: Vec<Vector2<f64>> = (0..n)
                        .map(|_| match noise {
                            Some(nd) => {
                                Vector2::new(pt.x + nd.sample(&mut rng), pt.y + nd.sample(&mut rng))
                            }
                            None => pt.xy(),
                        })
                        .collect();
                    match &mut cimm {
                        Some(c) => c.step(&cam, t, &zs),
                        None => {
                            for z in zs {
                                kf = Some(kalman_step(kf, &cv, &cam, t, z));
                            }
                        }
                    }
                }
                let last = match &cimm {
                    Some(c) => c.estimate(),
                    None => kf.map(|(tk, g)| (tk, g.mean)),
                };
                last.map(|(tk, x)| {
                    let dt = t - tk;
                    TargetEstimate {
                        position: Vector3::new(x[0] + x[2] * dt, x[1] + x[3] * dt, 0.0),
                        velocity: Vector3::new(x[2], x[3], 0.0),
                    }
                })
            }
        };
        if let Some(e) = &estimate {
            est_track.push(t, e.position, e.velocity);
            est_err2.0 += (e.position - pt).xy().norm_squared();
            est_err2.1 += 1;
        }
        target_track.push(t, pt, vt);
        for (i, u) in uavs.iter().enumerate() {
            tracks[i].push(t, u.position, u.velocity);
        }
        if k == steps {
            break;
        }
        // Ring order along the orbit from the estimated phases.
        if let Some(e) = &estimate {
            for (i, u) in uavs.iter().enumerate() {
                phases[i] = phase_of(u.horizontal_position(), e.position.xy());
            }
            order.sort_by(|&a, &b| phases[a].total_cmp(&phases[b]));
        }
        let mut next = uavs.clone();
        for (slot, &i) in order.iter().enumerate() {
            let nb = (n > 1).then(|| PhaseNeighbours {
                ahead: Some(phases[order[(slot + 1) % n]]),
                behind: Some(phases[order[(slot + n - 1) % n]]),
                spacing: TAU / n as f64,
            });
            let cmd = law.command(&uavs[i], estimate.as_ref(), &limits, nb.as_ref());
            next[i] = step(&uavs[i], &cmd, &limits, cfg.dt);
        }
        uavs = next;
    }
    let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;

    // Figures (truth-based).
    let per_uav: Vec<UavFigures> = tracks
        .iter()
        .map(|tr| standoff_figures(tr, &target_track, &limits))
        .collect();
    let optimal_path_m = (cfg.case == Case::CimmStatic).then(|| {
        let u0 = &tracks[0].samples[0];
        let d =
            Vector2::new(u0.pos[0], u0.pos[1]) - Vector2::new(STATIC_TARGET[0], STATIC_TARGET[1]);
        let h = Vector2::new(u0.vel[0], u0.vel[1]);
        let r_min = limits.min_turn_radius(V0);
        [1.0, -1.0]
            .iter()
            .filter_map(|&s| optimal_entry_length(d, h, R, r_min, s))
            .fold(f64::INFINITY, f64::min)
    });
    let (phase_max, phase_rms) = if n > 1 {
        let (m, r) = phase_figures(&tracks, &target_track, 0.7);
        (Some(m), Some(r))
    } else {
        (None, None)
    };
    let last = target_track
        .samples
        .last()
        .map(|s| Vector2::new(s.pos[0], s.pos[1]));
    let mut tracks_all = tracks;
    tracks_all.push(target_track);
    if estimator != EstimatorKind::Truth {
        tracks_all.push(est_track);
    }
    let mut summary = base_summary(cfg, duration, n, elapsed_ms, &tracks_all, limits);
    summary.law = cfg.law.name();
    summary.estimator = match estimator {
        EstimatorKind::Truth => "truth",
        EstimatorKind::Kalman => "kf (CV, camera position σ = 10 m, 1 Hz per UAV)",
        EstimatorKind::Cimm => {
            "cimm (CV / CT −0.008 / CT +0.01 rad/s, road σ_m = 2 m, camera position σ = 10 m, 1 Hz per UAV)"
        }
    };
    summary.radius_m = Some(R);
    summary.height_m = Some(H);
    summary.per_uav = per_uav;
    summary.optimal_path_m = optimal_path_m.filter(|v| v.is_finite());
    summary.estimate_rms_m = (estimator != EstimatorKind::Truth && est_err2.1 > 0)
        .then(|| (est_err2.0 / est_err2.1 as f64).sqrt());
    summary.phase_max_error_deg = phase_max;
    summary.phase_rms_error_deg = phase_rms;
    Ok(SimResult {
        summary,
        tracks: tracks_all,
        obstacles: Vec::new(),
        circle: last.map(|c| (c, R)),
    })
}

/// The road-constrained IMM of the moving cases ([CIMM] §3.2, as the `cimm` estimator): EKF mode
/// filters CV / right turn / left turn with the `motion` block of `cimm_road_1uav` (turn rates of
/// [`ROAD_LEGS`], q = accel_std² = 0.0025 m²/s³, transition matrix 0.98 / 0.01, initial
/// probabilities 0.98 / 0.01 / 0.01), every UAV's camera fix applied sequentially, then the road
/// pseudo-measurement on [`road_network`] (σ_m = 2 m, σ_v = σ_m / 1 s).
struct RoadCimm {
    imm: Imm<Extended, ModeModel, 3>,
    roads: RoadNetwork,
    /// Time and state of the last update; `None` before the first fix.
    state: Option<(f64, ImmState<4, 3>)>,
}

impl RoadCimm {
    const Q: f64 = 0.05 * 0.05;
    const PROBS: [f64; 3] = [0.98, 0.01, 0.01];
    const TPM: [[f64; 3]; 3] = [[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]];

    fn new() -> Result<Self, SimError> {
        let q = Self::Q;
        let models = [
            ModeModel::Cv { q },
            ModeModel::Ct {
                omega: ROAD_LEGS[1].1,
                q,
            },
            ModeModel::Ct {
                omega: ROAD_LEGS[2].1,
                q,
            },
        ];
        let imm = Imm::new(Extended, models, Self::TPM)
            .map_err(|e| SimError::Setup(format!("cimm: {e}")))?;
        Ok(Self {
            imm,
            roads: road_network()?,
            state: None,
        })
    }

    /// Predict to `t`, update with every fix of `zs` in turn, then the road constraint. The first
    /// fix starts the filter (as [`kalman_step`]); a failed step keeps the previous state.
    fn step(&mut self, cam: &Position<2>, t: f64, zs: &[Vector2<f64>]) {
        let (s, rest) = match (self.state, zs.split_first()) {
            (Some((tk, s)), _) => (
                if t > tk {
                    self.imm.predict(&s, t - tk).unwrap_or(s)
                } else {
                    s
                },
                zs,
            ),
            (None, Some((z, rest))) => {
                let prior = Gaussian {
                    mean: Vector4::new(z.x, z.y, 0.0, 0.0),
                    cov: Matrix4::from_diagonal(&Vector4::new(100.0, 100.0, 100.0, 100.0)),
                };
                let Ok(s) = ImmState::new(prior, Self::PROBS) else {
                    return;
                };
                (s, rest)
            }
            (None, None) => return,
        };
        let s = rest
            .iter()
            .fold(s, |s, z| self.imm.update(cam, &s, z).unwrap_or(s));
        let s = road_update(&self.imm, &s, &self.roads, None, 1.0).unwrap_or(s);
        self.state = Some((t, s));
    }

    /// Time and combined mean of the last update.
    fn estimate(&self) -> Option<(f64, Vector4<f64>)> {
        self.state.map(|(t, s)| (t, s.combined().mean))
    }
}

/// Predict-and-update of the target Kalman filter with one camera fix `z` at time `t`; the first
/// fix starts the filter (velocity prior 10 m/s σ).
fn kalman_step(
    kf: Option<(f64, Gaussian<4>)>,
    cv: &ConstantVelocity<4>,
    cam: &Position<2>,
    t: f64,
    z: Vector2<f64>,
) -> (f64, Gaussian<4>) {
    let start = || {
        (
            t,
            Gaussian {
                mean: Vector4::new(z.x, z.y, 0.0, 0.0),
                cov: Matrix4::from_diagonal(&Vector4::new(100.0, 100.0, 100.0, 100.0)),
            },
        )
    };
    let Some((tk, g)) = kf else { return start() };
    let predicted = if t > tk {
        Kalman.predict(cv, &g, t - tk).unwrap_or(g)
    } else {
        g
    };
    match Kalman.update(cam, &predicted, &z) {
        Ok(post) => (t, post.state),
        Err(_) => (t, predicted),
    }
}

fn standoff_figures(tr: &Track, target: &Track, limits: &Limits) -> UavFigures {
    let mut path = 0.0;
    let mut path_to_circle = None;
    let mut time_to_circle = None;
    let mut time_to_height = None;
    let z0 = tr.samples[0].pos[2] - target.samples[0].pos[2];
    let dir0 = (z0 - H).signum();
    let mut overshoot: f64 = 0.0;
    for (k, (s, g)) in tr.samples.iter().zip(&target.samples).enumerate() {
        if k > 0 {
            let p = &tr.samples[k - 1];
            path += (s.pos[0] - p.pos[0]).hypot(s.pos[1] - p.pos[1]);
        }
        let d = Vector2::new(s.pos[0] - g.pos[0], s.pos[1] - g.pos[1]);
        let vrel = Vector2::new(s.vel[0] - g.vel[0], s.vel[1] - g.vel[1]);
        let r = d.norm();
        if path_to_circle.is_none() && (r - R).abs() <= 3.0 && r > 0.0 && vrel.norm() > 0.0 {
            // Heading tangent: velocity perpendicular to the radius within 5°.
            let cos = (d.dot(&vrel) / (r * vrel.norm())).abs();
            if cos <= 1f64.to_radians().sin() {
                path_to_circle = Some(path);
                time_to_circle = Some(s.t);
            }
        }
        let e = s.pos[2] - g.pos[2] - H;
        if time_to_height.is_none() && e.abs() <= 1.0 {
            time_to_height = Some(s.t);
        }
        overshoot = overshoot.max(-dir0 * e);
    }
    let dist = (z0 - H).abs();
    let (vz, az) = (limits.vz_max, limits.az_max);
    let bang_bang = if dist >= vz * vz / az {
        dist / vz + vz / az
    } else {
        2.0 * (dist / az).sqrt()
    };
    let standoff_rms_m = time_to_circle.map(|t0| {
        let (sum, cnt) = tr
            .samples
            .iter()
            .zip(&target.samples)
            .filter(|(s, _)| s.t >= t0)
            .fold((0.0, 0usize), |(a, c), (s, g)| {
                let r = (s.pos[0] - g.pos[0]).hypot(s.pos[1] - g.pos[1]);
                (a + (r - R).powi(2), c + 1)
            });
        (sum / cnt.max(1) as f64).sqrt()
    });
    UavFigures {
        id: tr.id.clone(),
        path_to_circle_m: path_to_circle,
        time_to_circle_s: time_to_circle,
        time_to_height_s: time_to_height,
        bang_bang_time_s: bang_bang,
        height_overshoot_m: overshoot,
        standoff_rms_m,
    }
}

/// Max and RMS |spacing error| (deg) over samples after `from` × duration, true phases.
fn phase_figures(tracks: &[Track], target: &Track, from: f64) -> (f64, f64) {
    let t_end = target.samples.last().map_or(0.0, |s| s.t);
    let mut max: f64 = 0.0;
    let (mut sum, mut cnt) = (0.0, 0usize);
    let mut phases = Vec::with_capacity(tracks.len());
    for (k, g) in target.samples.iter().enumerate() {
        if g.t < from * t_end {
            continue;
        }
        phases.clear();
        phases.extend(tracks.iter().map(|tr| {
            let s = &tr.samples[k];
            phase_of(
                Vector2::new(s.pos[0], s.pos[1]),
                Vector2::new(g.pos[0], g.pos[1]),
            )
        }));
        phases.sort_by(f64::total_cmp);
        for e in spacing_errors(&phases, 1.0) {
            let e = e.to_degrees();
            max = max.max(e.abs());
            sum += e * e;
            cnt += 1;
        }
    }
    (max, (sum / cnt.max(1) as f64).sqrt())
}

fn base_summary(
    cfg: &SimConfig,
    duration: f64,
    n: usize,
    elapsed_ms: f64,
    tracks: &[Track],
    limits: Limits,
) -> Summary {
    let (mut max_speed, mut min_speed, mut max_turn, mut max_vz, mut max_az) =
        (0.0f64, f64::INFINITY, 0.0f64, 0.0f64, 0.0f64);
    for tr in tracks.iter().filter(|t| t.kind == "uav") {
        for w in tr.samples.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            let va = Vector2::new(a.vel[0], a.vel[1]);
            let vb = Vector2::new(b.vel[0], b.vel[1]);
            max_speed = max_speed.max(vb.norm());
            min_speed = min_speed.min(vb.norm());
            let dt = b.t - a.t;
            if va.norm() > 1e-6 && vb.norm() > 1e-6 {
                let turn = (va.x * vb.y - va.y * vb.x).atan2(va.dot(&vb)).abs() / dt;
                max_turn = max_turn.max(turn);
            }
            max_vz = max_vz.max(b.vel[2].abs());
            max_az = max_az.max((b.vel[2] - a.vel[2]).abs() / dt);
        }
    }
    Summary {
        case: cfg.case.name(),
        law: "",
        estimator: "truth",
        dt: cfg.dt,
        duration,
        uavs: n,
        elapsed_ms,
        radius_m: None,
        height_m: None,
        per_uav: Vec::new(),
        optimal_path_m: None,
        estimate_rms_m: None,
        phase_max_error_deg: None,
        phase_rms_error_deg: None,
        formation_steady_error_pct: None,
        formation_max_error_pct: None,
        obstacle_penetrations: None,
        obstacle_min_clearance_m: None,
        range_rms_straight_m: None,
        range_rms_maneuver_m: None,
        observability_factor: None,
        max_speed,
        min_speed: if min_speed.is_finite() {
            min_speed
        } else {
            0.0
        },
        max_turn_rate: max_turn,
        max_vz,
        max_az,
        limits: limits.into(),
    }
}

// ---------------------------------------------------------------------------------------------
// [BOT] formation.

/// The four obstacles of the formation case.
pub fn formation_obstacles() -> Vec<Obstacle> {
    [
        (Vector2::new(-60.0, 900.0), 80.0),
        (Vector2::new(420.0, 1900.0), 90.0),
        (Vector2::new(-350.0, 2700.0), 70.0),
        (Vector2::new(250.0, 3600.0), 100.0),
    ]
    .into_iter()
    .map(|(center, radius)| Obstacle { center, radius })
    .collect()
}

/// Formation shape: follower offsets from the leader (m); ranges between all pairs are regulated.
const SHAPE: [[f64; 2]; 4] = [[0.0, 0.0], [-100.0, -80.0], [100.0, -80.0], [0.0, -180.0]];

/// Leader heading schedule (rad from the x axis): left and right turns, then straight north.
fn leader_heading(t: f64) -> f64 {
    let deg: f64 = match t {
        t if t < 40.0 => 90.0,
        t if t < 90.0 => 110.0,
        t if t < 150.0 => 70.0,
        t if t < 210.0 => 105.0,
        t if t < 260.0 => 75.0,
        _ => 90.0,
    };
    deg.to_radians()
}

const LEADER_SPEED: f64 = 15.0;

fn run_formation(cfg: &SimConfig, duration: f64) -> SimResult {
    let limits = Limits {
        v_max: 30.0,
        ..Limits::fixed_wing()
    };
    let obstacles = formation_obstacles();
    let avoidance = Avoidance {
        lookahead: 220.0,
        margin: 35.0,
    };
    let reg = RangeRegulator::default();
    let n = SHAPE.len();
    let r_com = |i: usize, j: usize| (Vector2::from(SHAPE[i]) - Vector2::from(SHAPE[j])).norm();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let jitter = Normal::new(0.0, 10.0).ok();
    let mut uavs: Vec<UavState> = SHAPE
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let (dx, dy) = match (i, jitter) {
                (0, _) | (_, None) => (0.0, 0.0),
                (_, Some(nd)) => (nd.sample(&mut rng), nd.sample(&mut rng)),
            };
            UavState::new(
                Vector3::new(s[0] + dx, s[1] + dy, 100.0),
                Vector3::new(0.0, LEADER_SPEED, 0.0),
            )
        })
        .collect();
    let mut pairs: Vec<Vec<PairState>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| PairState::start((uavs[i].position - uavs[j].position).xy().norm()))
                .collect()
        })
        .collect();
    let mut tracks: Vec<Track> = (0..n)
        .map(|i| {
            Track::new(
                if i == 0 {
                    "leader".to_string()
                } else {
                    format!("follower{i}")
                },
                "uav",
            )
        })
        .collect();
    let steps = (duration / cfg.dt).round() as usize;
    let started = Instant::now();
    let mut penetrations = 0usize;
    let mut min_clear = f64::INFINITY;
    let (mut max_err, mut steady_err) = (0.0f64, 0.0f64);
    for k in 0..=steps {
        let t = k as f64 * cfg.dt;
        for (i, u) in uavs.iter().enumerate() {
            tracks[i].push(t, u.position, u.velocity);
            for o in &obstacles {
                let c = (u.horizontal_position() - o.center).norm() - o.radius;
                min_clear = min_clear.min(c);
                if c < 0.0 {
                    penetrations += 1;
                }
            }
        }
        for i in 1..n {
            for j in 0..i {
                let r = (uavs[i].position - uavs[j].position).xy().norm();
                let e = (r - r_com(i, j)).abs() / r_com(i, j) * 100.0;
                if t > 20.0 {
                    max_err = max_err.max(e);
                }
                if t >= duration - 40.0 {
                    steady_err = steady_err.max(e);
                }
            }
        }
        if k == steps {
            break;
        }
        let mut next = uavs.clone();
        for i in 0..n {
            let u = &uavs[i];
            let p = u.horizontal_position();
            let mut terms = [(Vector2::zeros(), 0.0); 4];
            let desired = if i == 0 {
                let h = leader_heading(t);
                Vector2::new(h.cos(), h.sin()) * LEADER_SPEED
            } else {
                for (j, term) in terms.iter_mut().enumerate().filter(|(j, _)| *j != i) {
                    let rel = (uavs[j].position - u.position).xy();
                    let r = rel.norm();
                    *term = (
                        rel / r.max(1e-9),
                        reg.pseudo_control(&pairs[i][j], r, r_com(i, j)),
                    );
                }
                vector_sum(terms)
            };
            let (vh, avoiding) = avoid(p, u.horizontal_velocity(), desired, &obstacles, &avoidance);
            for j in (0..n).filter(|&j| i > 0 && j != i) {
                let r = (uavs[j].position - u.position).xy().norm();
                pairs[i][j] = if avoiding {
                    reg.hedge(&pairs[i][j], r)
                } else {
                    reg.advance(&pairs[i][j], r, r_com(i, j), cfg.dt)
                };
            }
            let cmd = Command::new(vh, 0.0);
            next[i] = step(u, &cmd, &limits, cfg.dt);
        }
        uavs = next;
    }
    let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut summary = base_summary(cfg, duration, n, elapsed_ms, &tracks, limits);
    summary.law = "bot-formation (eqs. (5)-(6)) + silhouette-edge avoidance";
    summary.estimator = "measured ranges (subtended angle)";
    summary.formation_steady_error_pct = Some(steady_err);
    summary.formation_max_error_pct = Some(max_err);
    summary.obstacle_penetrations = Some(penetrations);
    summary.obstacle_min_clearance_m = Some(min_clear);
    SimResult {
        summary,
        tracks,
        obstacles,
        circle: None,
    }
}

// ---------------------------------------------------------------------------------------------
// [BOT] observability maneuver.

/// Bearings-only EKF of the leader ([x, y, vx, vy], CV) at a follower: predict + one azimuth
/// update `β = atan2(dE, dN)` (FORMAT.md §1), Joseph form, wrapped innovation.
fn bearing_step(
    g: &Gaussian<4>,
    cv: &ConstantVelocity<4>,
    dt: f64,
    sensor: Vector2<f64>,
    z: f64,
    sigma: f64,
) -> Gaussian<4> {
    let Ok(pred) = Kalman.predict(cv, g, dt) else {
        return *g;
    };
    let de = pred.mean[0] - sensor.x;
    let dn = pred.mean[1] - sensor.y;
    let r2 = de * de + dn * dn;
    if r2.is_nan() || r2 <= 1e-6 {
        return pred;
    }
    let h: SMatrix<f64, 1, 4> = Matrix1x4::new(dn / r2, -de / r2, 0.0, 0.0);
    let nu = Vector1::new(wrap_angle(z - de.atan2(dn)));
    let rr = SMatrix::<f64, 1, 1>::new(sigma * sigma);
    joseph_update(&pred, nu, &h, &rr).map_or(pred, |p| p.state)
}

/// One leader + one bearings-only follower; returns the tracks and the range-estimate RMS over
/// the second half.
fn observability_run(
    cfg: &SimConfig,
    duration: f64,
    maneuver: Option<ObservabilityManeuver>,
) -> (Vec<Track>, f64) {
    let limits = Limits {
        v_max: 30.0,
        ..Limits::fixed_wing()
    };
    let reg = RangeRegulator::default();
    let r_cmd = 150.0;
    let sigma = 1f64.to_radians();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noise = Normal::new(0.0, sigma).ok();
    let cv = ConstantVelocity::<4>::new(0.01);
    let mut leader = UavState::new(
        Vector3::new(0.0, 0.0, 100.0),
        Vector3::new(0.0, LEADER_SPEED, 0.0),
    );
    let mut follower = UavState::new(
        Vector3::new(-90.0, -120.0, 100.0),
        Vector3::new(0.0, LEADER_SPEED, 0.0),
    );
    // Prior: bearing known, range guessed 300 m (true 150 m), velocity unknown (σ 10 m/s).
    let b0 =
        (leader.position.x - follower.position.x).atan2(leader.position.y - follower.position.y);
    let guess = follower.horizontal_position() + Vector2::new(b0.sin(), b0.cos()) * 300.0;
    let mut est = Gaussian {
        mean: Vector4::new(guess.x, guess.y, 0.0, LEADER_SPEED),
        cov: Matrix4::from_diagonal(&Vector4::new(
            150.0f64.powi(2),
            150.0f64.powi(2),
            100.0,
            100.0,
        )),
    };
    let mut pair = PairState::start(300.0);
    let mut tracks = vec![
        Track::new("leader", "uav"),
        Track::new("follower", "uav"),
        Track::new("estimate", "estimate"),
    ];
    let steps = (duration / cfg.dt).round() as usize;
    let (mut sum, mut cnt) = (0.0, 0usize);
    for k in 0..=steps {
        let t = k as f64 * cfg.dt;
        tracks[0].push(t, leader.position, leader.velocity);
        tracks[1].push(t, follower.position, follower.velocity);
        tracks[2].push(
            t,
            Vector3::new(est.mean[0], est.mean[1], 100.0),
            Vector3::new(est.mean[2], est.mean[3], 0.0),
        );
        let rel_true = (leader.position - follower.position).xy();
        let rel_est = Vector2::new(est.mean[0], est.mean[1]) - follower.horizontal_position();
        if t >= duration / 2.0 {
            sum += (rel_est.norm() - rel_true.norm()).powi(2);
            cnt += 1;
        }
        if k == steps {
            break;
        }
        // Follower: LOS-range regulation on the *estimated* range and LOS, plus the maneuver.
        let r_est = rel_est.norm().max(1.0);
        let u = rel_est / r_est;
        let v = reg.pseudo_control(&pair, r_est, r_cmd);
        pair = reg.advance(&pair, r_est, r_cmd, cfg.dt);
        let mut vh = vector_sum([(u, v)]);
        if let Some(m) = &maneuver {
            vh += m.lateral_velocity(rel_est, r_est, t);
        }
        let leader_cmd = Command::new(Vector2::new(0.0, LEADER_SPEED), 0.0);
        leader = step(&leader, &leader_cmd, &limits, cfg.dt);
        follower = step(&follower, &Command::new(vh, 0.0), &limits, cfg.dt);
        // Bearing measurement of the leader from the follower.
        let d = (leader.position - follower.position).xy();
        let z = d.x.atan2(d.y) + noise.map_or(0.0, |nd| nd.sample(&mut rng));
        est = bearing_step(
            &est,
            &cv,
            cfg.dt,
            follower.horizontal_position(),
            wrap_angle(z),
            sigma,
        );
    }
    (tracks, (sum / cnt.max(1) as f64).sqrt())
}

fn run_observability(cfg: &SimConfig, duration: f64) -> SimResult {
    let started = Instant::now();
    // K₁ K₂ = 1 → ω = √K₁ = 0.1 rad/s (period ≈ 63 s); bearing amplitude 15°.
    let maneuver = ObservabilityManeuver::from_weights(0.01, 100.0, 15f64.to_radians());
    let (_, straight) = observability_run(cfg, duration, None);
    let (tracks, with) = observability_run(cfg, duration, maneuver);
    let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
    let limits = Limits {
        v_max: 30.0,
        ..Limits::fixed_wing()
    };
    let mut summary = base_summary(cfg, duration, 2, elapsed_ms, &tracks, limits);
    summary.law = "bot-formation + observability maneuver (eq. (4), ω = 0.1 rad/s, B = 15°)";
    summary.estimator = "bearings-only EKF (σ = 1°, 10 Hz)";
    summary.range_rms_straight_m = Some(straight);
    summary.range_rms_maneuver_m = Some(with);
    summary.observability_factor = (with > 0.0).then(|| straight / with);
    SimResult {
        summary,
        tracks,
        obstacles: Vec::new(),
        circle: None,
    }
}

// ---------------------------------------------------------------------------------------------
// Output.

/// The summary as text lines for stdout.
pub fn summary_lines(s: &Summary) -> Vec<String> {
    let mut out = vec![format!(
        "{}: law {}, {} UAV(s), {} s at {} Hz, estimator {}, simulated in {:.1} ms",
        s.case,
        s.law,
        s.uavs,
        s.duration,
        (1.0 / s.dt).round(),
        s.estimator,
        s.elapsed_ms
    )];
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    for u in &s.per_uav {
        out.push(format!(
            "  {}: path to circle {} m at t = {} s; height ±1 m at t = {} s (bang-bang {:.1} s), overshoot {:.2} m; standoff RMS {} m",
            u.id,
            opt(u.path_to_circle_m),
            opt(u.time_to_circle_s),
            opt(u.time_to_height_s),
            u.bang_bang_time_s,
            u.height_overshoot_m,
            opt(u.standoff_rms_m),
        ));
    }
    if let Some(o) = s.optimal_path_m {
        out.push(format!("  geometric optimum (turn + tangent): {o:.1} m"));
    }
    if let Some(e) = s.estimate_rms_m {
        out.push(format!("  target estimate RMS error: {e:.2} m"));
    }
    if let (Some(m), Some(r)) = (s.phase_max_error_deg, s.phase_rms_error_deg) {
        out.push(format!(
            "  phase spacing error (last 30 %): max {m:.2}°, RMS {r:.2}°"
        ));
    }
    if let (Some(st), Some(mx)) = (s.formation_steady_error_pct, s.formation_max_error_pct) {
        out.push(format!(
            "  commanded-range error: steady state (last 40 s) {st:.2} %, max {mx:.1} %"
        ));
    }
    if let (Some(p), Some(c)) = (s.obstacle_penetrations, s.obstacle_min_clearance_m) {
        out.push(format!(
            "  obstacle penetrations {p}, min clearance {c:.1} m"
        ));
    }
    if let (Some(a), Some(b), Some(f)) = (
        s.range_rms_straight_m,
        s.range_rms_maneuver_m,
        s.observability_factor,
    ) {
        out.push(format!(
            "  range-estimate RMS (2nd half): straight {a:.1} m, maneuver {b:.1} m, factor {f:.1}"
        ));
    }
    out.push(format!(
        "  flown: speed {:.1}–{:.1} m/s, turn rate ≤ {:.3} rad/s, |vz| ≤ {:.2} m/s, |az| ≤ {:.2} m/s² (limits {}–{} m/s, {} rad/s, {} m/s, {} m/s²)",
        s.min_speed,
        s.max_speed,
        s.max_turn_rate,
        s.max_vz,
        s.max_az,
        s.limits.v_min,
        s.limits.v_max,
        s.limits.turn_rate_max,
        s.limits.vz_max,
        s.limits.az_max
    ));
    out
}

#[derive(Serialize)]
struct Row<'a> {
    t: f64,
    id: &'a str,
    kind: &'a str,
    x: f64,
    y: f64,
    z: f64,
    vx: f64,
    vy: f64,
    vz: f64,
}

/// Writes the trajectories: JSONL when the file name ends in `.jsonl`, CSV otherwise
/// (`t,id,kind,x,y,z,vx,vy,vz`), through a temporary file renamed at the end.
pub fn write_tracks(path: &Path, tracks: &[Track]) -> Result<(), SimError> {
    let jsonl = path.extension().is_some_and(|e| e == "jsonl");
    let io = |source| SimError::Io {
        path: path.display().to_string(),
        source,
    };
    let tmp = path.with_extension("tmp~");
    let file = std::fs::File::create(&tmp).map_err(io)?;
    let mut w = std::io::BufWriter::new(file);
    let res = (|| -> std::io::Result<()> {
        if !jsonl {
            writeln!(w, "t,id,kind,x,y,z,vx,vy,vz")?;
        }
        for tr in tracks {
            for s in &tr.samples {
                let row = Row {
                    t: s.t,
                    id: &tr.id,
                    kind: tr.kind,
                    x: s.pos[0],
                    y: s.pos[1],
                    z: s.pos[2],
                    vx: s.vel[0],
                    vy: s.vel[1],
                    vz: s.vel[2],
                };
                if jsonl {
                    serde_json::to_writer(&mut w, &row).map_err(std::io::Error::other)?;
                    writeln!(w)?;
                } else {
                    writeln!(
                        w,
                        "{:.3},{},{},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4}",
                        s.t,
                        tr.id,
                        tr.kind,
                        s.pos[0],
                        s.pos[1],
                        s.pos[2],
                        s.vel[0],
                        s.vel[1],
                        s.vel[2]
                    )?;
                }
            }
        }
        w.flush()
    })();
    match res.and_then(|()| std::fs::rename(&tmp, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(io(e))
        }
    }
}

/// Draws the horizontal paths, the standoff circle and the obstacles as an SVG (plotters), with
/// at most `max_points` points per track.
pub fn plot_svg(path: &Path, result: &SimResult, max_points: usize) -> Result<(), SimError> {
    use plotters::prelude::*;
    let perr = |e: &dyn std::fmt::Display| SimError::Plot(e.to_string());
    // Bounds over every drawn point.
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    let mut grow = |x: f64, y: f64| {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    };
    for tr in &result.tracks {
        for s in &tr.samples {
            grow(s.pos[0], s.pos[1]);
        }
    }
    let circles: Vec<(Vector2<f64>, f64, bool)> = result
        .obstacles
        .iter()
        .map(|o| (o.center, o.radius, true))
        .chain(result.circle.map(|(c, r)| (c, r, false)))
        .collect();
    for (c, r, _) in &circles {
        grow(c.x - r, c.y - r);
        grow(c.x + r, c.y + r);
    }
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(SimError::Plot("nothing to draw".into()));
    }
    // Equal axes.
    let span = (x1 - x0).max(y1 - y0) * 1.05 + 1.0;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (x0, x1, y0, y1) = (
        cx - span / 2.0,
        cx + span / 2.0,
        cy - span / 2.0,
        cy + span / 2.0,
    );
    let root = SVGBackend::new(path, (640, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| perr(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| perr(&e))?;
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
    ];
    let mut uav_i = 0;
    for tr in &result.tracks {
        let stride = tr.samples.len().div_ceil(max_points.max(2)).max(1);
        let pts: Vec<(f64, f64)> = tr
            .samples
            .iter()
            .step_by(stride)
            .chain(tr.samples.last())
            .map(|s| (s.pos[0], s.pos[1]))
            .collect();
        let style = match tr.kind {
            "target" => BLACK.stroke_width(2),
            "estimate" => RGBColor(150, 150, 150).stroke_width(1),
            _ => {
                uav_i += 1;
                palette[(uav_i - 1) % palette.len()].stroke_width(2)
            }
        };
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(|e| perr(&e))?;
    }
    for (c, r, obstacle) in circles {
        let pts: Vec<(f64, f64)> = (0..=120)
            .map(|k| {
                let a = TAU * k as f64 / 120.0;
                (c.x + r * a.cos(), c.y + r * a.sin())
            })
            .collect();
        let style = if obstacle {
            RGBColor(120, 60, 20).stroke_width(3)
        } else {
            RGBColor(255, 127, 14).stroke_width(1)
        };
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(|e| perr(&e))?;
    }
    root.present().map_err(|e| perr(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::road::RoadSegment;

    #[test]
    fn road_target_matches_the_scenario_truth() {
        // cimm_road_1uav/truth.csv at 140, 360 and 700 s.
        let (p, _) = road_target(140.0);
        assert!((p - Vector3::new(1040.0, 1420.0, 0.0)).norm() < 1e-6);
        let (p, v) = road_target(360.0);
        assert!((p - Vector3::new(2964.692577, 1511.096688, 0.0)).norm() < 1e-3);
        assert!((v - Vector3::new(6.728774, -7.397541, 0.0)).norm() < 1e-4);
        let (p, _) = road_target(700.0);
        assert!((p - Vector3::new(4247.691708, 3023.548213, 0.0)).norm() < 1e-3);
    }

    #[test]
    fn road_network_is_the_scenario_road_and_carries_the_target() {
        let net = road_network().unwrap();
        let road = &net.roads()[0];
        assert_eq!(road.sigma_m(), ROAD_SIGMA_M);
        // cimm_road_1uav/scenario.json roads: arc centres, radii, sweeps, end point.
        let segs = road.segments();
        assert_eq!(segs.len(), 3);
        let expect = [
            (Vector2::new(2040.0, 670.0), 1250.0, -1.76),
            (Vector2::new(3704.446638, 2183.974038), 1000.0, 3.4),
        ];
        for (seg, (c, r, sweep)) in segs[1..].iter().zip(expect) {
            let RoadSegment::Arc {
                center,
                radius,
                sweep: sw,
                ..
            } = *seg
            else {
                panic!("arc expected, got {seg:?}");
            };
            assert!((center - c).norm() < 1e-4, "{center}");
            assert!((radius - r).abs() < 1e-6 && (sw - sweep).abs() < 1e-9);
        }
        assert!((segs[2].end() - Vector2::new(4247.691708, 3023.548213)).norm() < 1e-3);
        for k in 0..=700 {
            let (p, _) = road_target(f64::from(k));
            assert!(road.project(&p.xy()).offset.abs() < 1e-6, "t = {k}");
        }
    }

    #[test]
    fn case_names_round_trip() {
        for (n, c) in Case::ALL {
            assert_eq!(Case::parse(n).unwrap(), c);
            assert_eq!(c.name(), n);
        }
        assert!(Case::parse("nope").is_err());
    }
}
