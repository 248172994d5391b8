//! What a guidance simulation is asked to run ([`SimConfig`], [`LawKind`]) and what it
//! returns ([`SimResult`]: the [`Trajectory`]s, the [`Summary`] of figures).

use harrier_core::guidance::Limits;
use harrier_core::guidance::obstacle::Obstacle;
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use super::cases::Case;
use super::error::SimError;
/// Standoff guidance law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LawKind {
    /// TOGVF: [`harrier_core::guidance::togvf`].
    Togvf,
    /// LGVF: [`harrier_core::guidance::lgvf`].
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
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Togvf => "togvf",
            Self::Lgvf => "lgvf",
        }
    }
}

/// Options of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Scenario.
    pub case: Case,
    /// Standoff law (standoff cases).
    pub law: LawKind,
    /// What the guidance of the standoff cases sees of the target: `truth` or the name of a
    /// registry estimator (`harrier estimators`) run on simulated camera fixes; default `cimm` for
    /// moving targets, `truth` for static ones.
    pub estimator: Option<String>,
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

/// A recorded trajectory of one vehicle (or of the target, or of its estimate).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trajectory {
    /// Identifier (`uav1`, `target`, `estimate`, `leader`, …).
    pub id: String,
    /// `uav`, `target` or `estimate`.
    pub kind: &'static str,
    /// States, one per step.
    pub samples: Vec<Sample>,
}

impl Trajectory {
    pub(crate) fn new(id: impl Into<String>, kind: &'static str) -> Self {
        Self {
            id: id.into(),
            kind,
            samples: Vec::new(),
        }
    }
    pub(crate) fn push(&mut self, t: f64, p: Vector3<f64>, v: Vector3<f64>) {
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
    pub estimator: String,
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
    pub trajectories: Vec<Trajectory>,
    /// Obstacles of the case.
    pub obstacles: Vec<Obstacle>,
    /// Standoff circle to draw (centre at the final target position, radius).
    pub circle: Option<(Vector2<f64>, f64)>,
}
