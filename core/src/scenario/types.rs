//! `scenario.json` as readers see it: [`Scenario`] and its blocks (time, target, platforms,
//! sensors and their noise, roads, motion hints, prior, linear system, scoring).

use serde::{Deserialize, Serialize};

use crate::measurement::MeasKind;

/// The format identifier this module reads and writes.
pub const FORMAT_ID: &str = "gcs-scenario/1";

/// `scenario.json`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Scenario {
    /// Must be [`FORMAT_ID`].
    pub format: String,
    /// Scenario name.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// 2 = planar (z = `plane_z`), 3 = full 3-D.
    pub dims: u8,
    /// Up coordinate of planar scenarios.
    #[serde(default)]
    pub plane_z: Option<f64>,
    /// Timing.
    pub time: TimeSpec,
    /// The target.
    pub target: Target,
    /// Sensor platforms.
    #[serde(default)]
    pub platforms: Vec<Platform>,
    /// Sensors.
    pub sensors: Vec<Sensor>,
    /// Road network (may be empty).
    #[serde(default)]
    pub roads: Vec<Road>,
    /// Motion-model hints.
    #[serde(default)]
    pub motion: Option<Motion>,
    /// Gaussian prior.
    #[serde(default)]
    pub prior: Option<Prior>,
    /// Bounded-noise linear system (set-membership case, FORMAT.md §2.1).
    #[serde(default)]
    pub linear_system: Option<LinearSystem>,
    /// Free-form tuning hints from the paper.
    #[serde(default)]
    pub hints: serde_json::Value,
    /// Scoring settings.
    #[serde(default)]
    pub scoring: Scoring,
    /// What the sensors are known to do (FORMAT-MULTI.md §1 `detection`): detection probability
    /// and clutter, which a multi-target tracker may read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detection: Option<DetectionSpec>,
}

/// `time` block.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct TimeSpec {
    /// Scenario epoch (s).
    #[serde(default)]
    pub t0: f64,
    /// Nominal sensor period (s).
    pub dt: f64,
    /// End time (s).
    pub t_end: f64,
}

/// `target` block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Target {
    /// Target id.
    pub id: String,
    /// Characteristic size (m) when known to the estimator.
    #[serde(default)]
    pub size_m: Option<f64>,
    /// Size prior when the size is unknown.
    #[serde(default)]
    pub size_prior: Option<SizePrior>,
    /// Ground target.
    #[serde(default)]
    pub on_ground: Option<bool>,
}

/// Gaussian prior on an unknown target size (m).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct SizePrior {
    /// Mean (m).
    pub mean: f64,
    /// Standard deviation (m).
    pub std: f64,
}

/// A sensor platform.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Platform {
    /// Platform id.
    pub id: String,
    /// Kind (uav, multirotor, ground, …).
    #[serde(default)]
    pub kind: String,
}

/// A sensor.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Sensor {
    /// Sensor id.
    pub id: String,
    /// Id of the platform carrying it.
    pub platform: String,
    /// Measurement kind.
    pub kind: MeasKind,
    /// Components of a position sensor (2 or 3).
    #[serde(default)]
    pub ncomp: Option<usize>,
    /// Nominal rate (Hz).
    #[serde(default)]
    pub rate_hz: Option<f64>,
    /// Noise description.
    pub noise: Noise,
    /// Bias description (`{"model": "unknown"}` for radars with unknown bias).
    #[serde(default)]
    pub bias: Option<serde_json::Value>,
}

impl Sensor {
    /// Measurement dimension.
    pub fn dim(&self) -> usize {
        self.kind.len(self.ncomp)
    }
}

/// Noise block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Noise {
    /// Independent Gaussian noise with per-component standard deviations.
    Gaussian {
        /// Standard deviation per component.
        std: Vec<f64>,
    },
    /// Unknown-but-bounded noise `|v_i| ≤ bound_i`.
    Bounded {
        /// Bound per component.
        bound: Vec<f64>,
        /// Shape of the bound (`box`).
        #[serde(default)]
        shape: Option<String>,
    },
}

impl Noise {
    /// Per-component scale: the std of Gaussian noise, or the bound of bounded noise.
    pub fn scale(&self) -> &[f64] {
        match self {
            Self::Gaussian { std } => std,
            Self::Bounded { bound, .. } => bound,
        }
    }
    /// Per-component standard deviation; bounded noise is treated as uniform (σ = bound/√3).
    pub fn std(&self) -> Vec<f64> {
        match self {
            Self::Gaussian { std } => std.clone(),
            Self::Bounded { bound, .. } => bound.iter().map(|b| b / 3f64.sqrt()).collect(),
        }
    }
}

/// A road (FORMAT.md §2 `roads`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Road {
    /// Road id.
    pub id: String,
    /// Physical width (m).
    #[serde(default)]
    pub width_m: Option<f64>,
    /// Std of the lateral offset from the centre line (m).
    #[serde(default)]
    pub sigma_m: Option<f64>,
    /// Centre-line segments in travel order.
    pub segments: Vec<Segment>,
}

/// A road segment.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Segment {
    /// Straight line.
    Line {
        /// Start (x, y).
        start: [f64; 2],
        /// End (x, y).
        end: [f64; 2],
    },
    /// Circular arc.
    Arc {
        /// Centre (x, y).
        center: [f64; 2],
        /// Radius (m).
        radius: f64,
        /// Start (x, y).
        start: [f64; 2],
        /// End (x, y).
        end: [f64; 2],
        /// Signed sweep: > 0 counter-clockwise.
        sweep_rad: f64,
    },
}

/// `motion` hints.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Motion {
    /// Candidate models.
    #[serde(default)]
    pub models: Vec<MotionModelSpec>,
    /// Initial model probabilities, aligned with `models`.
    #[serde(default)]
    pub initial_probs: Option<Vec<f64>>,
    /// Markov transition matrix, row i = from model i.
    #[serde(default)]
    pub transition_matrix: Option<Vec<Vec<f64>>>,
    /// White-noise acceleration std (m/s²); spectral density = accel_std².
    #[serde(default)]
    pub accel_std: Option<f64>,
    /// Hard acceleration bound (m/s²).
    #[serde(default)]
    pub accel_bound: Option<f64>,
}

impl Motion {
    /// The hints of a constant-velocity target: one `CV` model, white-noise acceleration std
    /// `accel_std` (m/s²).
    pub fn cv(accel_std: f64) -> Self {
        Self {
            models: vec![MotionModelSpec {
                name: "CV".into(),
                kind: "CV".into(),
                turn_rate: None,
            }],
            initial_probs: None,
            transition_matrix: None,
            accel_std: Some(accel_std),
            accel_bound: None,
        }
    }

    /// Acceleration spectral density from `accel_std` (m²/s³), if given.
    pub fn accel_q(&self) -> Option<f64> {
        self.accel_std.map(|a| a * a)
    }
}

/// One motion model of the hints.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct MotionModelSpec {
    /// Name (truth `mode` labels use it).
    pub name: String,
    /// `CV`, `CT`, …
    #[serde(rename = "type")]
    pub kind: String,
    /// Turn rate for CT (rad/s, > 0 counter-clockwise).
    #[serde(default)]
    pub turn_rate: Option<f64>,
}

/// Gaussian prior at time `t` over the canonical dims `cov_dims`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Prior {
    /// Time of the prior (s).
    #[serde(default)]
    pub t: f64,
    /// Canonical 6-state.
    pub state: [f64; 6],
    /// Covariance of `state[cov_dims]`.
    pub cov: Vec<Vec<f64>>,
    /// Canonical indices of `cov`.
    #[serde(default)]
    pub cov_dims: Option<Vec<usize>>,
}

impl Prior {
    /// Canonical indices of the covariance (FORMAT.md defaults by size).
    pub fn dims(&self) -> Vec<usize> {
        self.cov_dims
            .clone()
            .unwrap_or_else(|| default_cov_dims(self.cov.len()))
    }
    /// Variance of canonical index `i`, if it is in the covariance.
    pub fn variance(&self, i: usize) -> Option<f64> {
        let k = self.dims().iter().position(|&d| d == i)?;
        self.cov.get(k).and_then(|row| row.get(k)).copied()
    }
}

/// Default canonical indices implied by a covariance of size `n` (FORMAT.md §5).
pub fn default_cov_dims(n: usize) -> Vec<usize> {
    match n {
        6 => vec![0, 1, 2, 3, 4, 5],
        4 => vec![0, 1, 3, 4],
        3 => vec![0, 1, 2],
        2 => vec![0, 1],
        _ => (0..n).collect(),
    }
}

/// Bounded-noise linear system (FORMAT.md §2.1).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[allow(non_snake_case)]
pub struct LinearSystem {
    /// Canonical indices of the system state.
    pub state_dims: Vec<usize>,
    /// Transition matrix.
    pub A: Vec<Vec<f64>>,
    /// Process-noise input matrix.
    pub B: Vec<Vec<f64>>,
    /// Measurement matrix.
    pub C: Vec<Vec<f64>>,
    /// Bound on w: `{"type": "ball", "radius": r}`.
    pub w_bound: serde_json::Value,
    /// Bound on v: `{"type": "box", "half_width": [...]}`.
    pub v_bound: serde_json::Value,
    /// Initial set.
    pub x0_ellipsoid: EllipsoidSpec,
}

/// An ellipsoid `{x : (x[dims] − center)ᵀ shape⁻¹ (x[dims] − center) ≤ 1}`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct EllipsoidSpec {
    /// Centre.
    pub center: Vec<f64>,
    /// Shape matrix (SPD).
    pub shape: Vec<Vec<f64>>,
    /// Canonical indices.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dims: Option<Vec<usize>>,
}

/// `scoring` block.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Scoring {
    /// Estimates before this time are not scored.
    #[serde(default)]
    pub t_start: f64,
    /// `state`, `prediction` or `ellipsoid`.
    #[serde(default = "default_primary")]
    pub primary: String,
}

impl Default for Scoring {
    fn default() -> Self {
        Self {
            t_start: 0.0,
            primary: default_primary(),
        }
    }
}

fn default_primary() -> String {
    "state".into()
}

impl Scenario {
    /// The sensor with this id.
    pub fn sensor(&self, id: &str) -> Option<&Sensor> {
        self.sensors.iter().find(|s| s.id == id)
    }

    /// Up coordinate of planar scenarios (0 when absent).
    pub fn plane_z(&self) -> f64 {
        self.plane_z.unwrap_or(0.0)
    }

    /// Canonical dims that are scored: planar scenarios drop z and vz.
    pub fn active_dims(&self) -> &'static [usize] {
        if self.dims == 2 {
            &[0, 1, 3, 4]
        } else {
            &[0, 1, 2, 3, 4, 5]
        }
    }

    /// Acceleration spectral density from `motion.accel_std` (m²/s³), if given.
    pub fn accel_q(&self) -> Option<f64> {
        self.motion.as_ref().and_then(Motion::accel_q)
    }
}

/// `detection` block of a multi-target `scenario.json` (FORMAT-MULTI.md §1): what the sensors are known to do.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct DetectionSpec {
    /// Probability of detecting a target in one scan.
    pub pd: f64,
    /// Mean number of clutter detections per scan and sensor (Poisson).
    #[serde(default)]
    pub clutter_rate: f64,
    /// Region where clutter falls (uniformly), `[min, max]` corners in the plane.
    #[serde(default)]
    pub region: Option<Region>,
}

/// An axis-aligned rectangle of the plane.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct Region {
    /// `[x_min, y_min]` (m).
    pub min: [f64; 2],
    /// `[x_max, y_max]` (m).
    pub max: [f64; 2],
}

impl Region {
    /// Area (m²).
    pub fn area(&self) -> f64 {
        (self.max[0] - self.min[0]) * (self.max[1] - self.min[1])
    }
}
