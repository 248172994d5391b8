//! What a simulation contains: targets, roads, the sensors every vehicle carries and how the
//! vehicles fly during `harrier-sim record` — a [`SimScenario`], built in by name ([`PRESETS`]) or
//! read from a JSON file of the same structure (`--scenario NAME|PATH`).
//!
//! A file that is not valid JSON, has an unknown or missing key, or an out-of-range number (a
//! negative rate, a probability outside `[0, 1]`, a field of view ≤ 0, …) is refused with the
//! file, the line and the column ([`ScenarioError::Parse`]); consistency problems found after
//! parsing (a target on a road that does not exist, a noise vector of the wrong length, …) name
//! the file and the field ([`ScenarioError::Invalid`]).
//!
//! Conventions are those of `gcs-scenario/1` (FORMAT.md §1): ENU metres, turn rate > 0
//! counter-clockwise (left), azimuths clockwise from North. Every target moves in a horizontal
//! plane (ground targets at z = 0, an aircraft at its altitude), so recorded scenarios are planar.

use std::fmt;
use std::path::Path;

use harrier_core::detection::GeoPoint;
use harrier_core::road::road_from_turn_legs;
use harrier_core::scenario::{Motion, MotionModelSpec, Road};
use nalgebra::Vector2;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

/// Names of the built-in scenarios, for `--scenario NAME`.
pub const PRESETS: [&str; 6] = [
    "cimm-road",
    "leader",
    "radar",
    "radar-abrupt",
    "radar-markov",
    "crossing",
];

/// A simulation: world, sensors, vehicle behaviour and the hints written for estimators.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SimScenario {
    /// Name (recorded scenarios are called `sim_{name}_seed{seed}`).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Geodetic origin of the ENU frame; also the vehicles' home.
    #[serde(default = "default_origin")]
    pub origin: GeoPoint,
    /// Targets (at least one).
    pub targets: Vec<TargetSpec>,
    /// Road network; road targets refer to a road by id.
    #[serde(default)]
    pub roads: Vec<Road>,
    /// The sensors every vehicle carries (at least one).
    pub sensors: Vec<SensorSpec>,
    /// How the vehicles fly during `record`.
    pub vehicles: VehicleSpec,
    /// What `record` writes for estimators (motion hints, prior, scoring).
    #[serde(default)]
    pub estimator: EstimatorHints,
}

/// One target.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// Target id (unique).
    pub id: String,
    /// Characteristic size S (m), used by `bearing_size` cameras.
    #[serde(default = "default_size", deserialize_with = "positive")]
    pub size_m: f64,
    /// Whether a recorded scenario tells the estimators the size (`target.size_m`) or only a
    /// prior (`size_prior`, mean 1.2 S, std 0.3 S as the reference scenarios).
    #[serde(default)]
    pub size_known: bool,
    /// How it moves.
    pub motion: TargetMotion,
    /// Seeded perturbation of the initial conditions.
    #[serde(default)]
    pub jitter: Jitter,
}

/// Target motion models. All are planar (constant altitude).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum TargetMotion {
    /// A ground vehicle driving along a road's centre line at constant speed, straight on lines
    /// (mode `CV`) and turning on arcs (modes `left` / `right`, turn rate ±speed/R): the road
    /// target of [CIMM] §5.1. It parks at the end of the road.
    Road {
        /// Id of a road of [`SimScenario::roads`].
        road: String,
        /// Speed (m/s).
        #[serde(deserialize_with = "positive")]
        speed_mps: f64,
        /// Arc length along the road at t = 0 (m).
        #[serde(default, deserialize_with = "non_negative")]
        start_m: f64,
        /// RMS lateral offset from the centre line (m), a smooth seeded wander (0 = on the line).
        #[serde(default, deserialize_with = "non_negative")]
        lateral_std_m: f64,
    },
    /// Piecewise constant-velocity / constant-turn motion ([CIMM] §5.1, [ICDKF] §4): each segment
    /// turns at a constant rate (0 = straight) for a duration; after the last one it goes straight.
    Segments {
        /// Position at t = 0 (x, y) (m).
        position: [f64; 2],
        /// Velocity at t = 0 (m/s).
        velocity: [f64; 2],
        /// Altitude (m).
        #[serde(default)]
        z_m: f64,
        /// Segments in time order.
        segments: Vec<MotionSegment>,
    },
    /// The aircraft leader of [BOT] §IV: constant speed, heading
    /// `χ(t) = χ₀ + A sin(2π t / T)` (clockwise from North), level flight.
    Leader {
        /// Position at t = 0 (x, y) (m).
        position: [f64; 2],
        /// Altitude (m).
        #[serde(default)]
        z_m: f64,
        /// Speed (m/s).
        #[serde(deserialize_with = "positive")]
        speed_mps: f64,
        /// Mean heading χ₀ (degrees clockwise from North).
        #[serde(default)]
        heading_deg: f64,
        /// Amplitude A (degrees).
        #[serde(default, deserialize_with = "non_negative")]
        amplitude_deg: f64,
        /// Period T (s).
        #[serde(deserialize_with = "positive")]
        period_s: f64,
    },
}

/// One segment of [`TargetMotion::Segments`].
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSegment {
    /// Mode label written to `truth.csv` (e.g. `CV`, `left`, `right`).
    pub mode: String,
    /// Turn rate (rad/s, > 0 counter-clockwise); 0 = straight.
    #[serde(default)]
    pub turn_rate: f64,
    /// Duration (s).
    #[serde(deserialize_with = "positive")]
    pub duration_s: f64,
}

/// Seeded Gaussian perturbation of a target's initial conditions (standard deviations).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Jitter {
    /// Position (m); along the road for road targets.
    #[serde(default, deserialize_with = "non_negative")]
    pub position_m: f64,
    /// Heading (degrees); not for road targets.
    #[serde(default, deserialize_with = "non_negative")]
    pub heading_deg: f64,
    /// Speed (m/s).
    #[serde(default, deserialize_with = "non_negative")]
    pub speed_mps: f64,
}

/// A sensor carried by every vehicle.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Sensor id, unique on a vehicle (recorded scenarios append the vehicle id: `cam` → `cam1`).
    pub id: String,
    /// Scan rate (Hz); scans at t = k / rate.
    #[serde(deserialize_with = "positive")]
    pub rate_hz: f64,
    /// Probability of detecting a target in view, per scan.
    #[serde(default = "one", deserialize_with = "probability")]
    pub pd: f64,
    /// Mean number of clutter detections per scan (Poisson), uniform in the field of view.
    #[serde(default, deserialize_with = "non_negative")]
    pub clutter_rate: f64,
    /// Largest range at which anything is seen (m).
    #[serde(default = "default_range", deserialize_with = "positive")]
    pub max_range_m: f64,
    /// Gaussian noise std of each measured component (units of `z`, FORMAT.md §3).
    pub noise_std: Vec<f64>,
    /// Camera or radar.
    pub model: SensorModel,
}

/// Sensor models.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SensorModel {
    /// Gimbal camera: sees what lies within `fov_deg / 2` of its boresight.
    Camera {
        /// What it reports.
        output: CameraOutput,
        /// Full cone angle of the field of view (degrees, in (0, 180)).
        #[serde(deserialize_with = "positive")]
        fov_deg: f64,
        /// Where the boresight points.
        pointing: Pointing,
    },
    /// Radar: `range_bearing`, all around, with an optional bias ([ICDKF] eq. (9)).
    Radar {
        /// Bias model.
        #[serde(default)]
        bias: BiasModel,
    },
}

/// What a camera reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraOutput {
    /// `az_el` angles.
    AzEl,
    /// `bearing_size`: angles and subtended angle 2·atan(S / 2ρ) ([BOT] §II.C).
    BearingSize,
    /// `position`: the target geolocated on its plane, `[x, y]` ([CIMM] §5.1's camera).
    Position,
}

/// Gimbal pointing (roll and pitch stabilised).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum Pointing {
    /// Straight down.
    Nadir,
    /// Fixed pan (degrees clockwise from the vehicle's yaw) and depression below the horizon.
    Fixed {
        /// Pan (degrees, clockwise from the nose).
        pan_deg: f64,
        /// Depression (degrees, > 0 below the horizon).
        depression_deg: f64,
    },
    /// Slaved to a target by an image tracker: the boresight follows target `target` (index).
    Track {
        /// Index into [`SimScenario::targets`].
        target: usize,
    },
}

/// Radar measurement bias, [ICDKF] eq. (9): `z_i = (1 + s_i) h_i + o_i + v_i`, i = range, azimuth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum BiasModel {
    /// No bias ([ICDKF] §4 type 1).
    #[default]
    None,
    /// Switched on at `t_on`, off at `t_off` ([ICDKF] §4 type 2).
    Abrupt {
        /// Start (s).
        t_on: f64,
        /// End (s).
        t_off: f64,
        /// Scale `[s_r, s_az]`.
        scale: [f64; 2],
        /// Offset `[o_r (m), o_az (rad)]`.
        offset: [f64; 2],
    },
    /// Offsets follow a first-order Gauss–Markov process about `mean` with stationary std `std`
    /// and correlation time `tau_s` (drawn from the stationary law at the first scan); constant
    /// scale ([ICDKF] §4 type 3).
    Markov {
        /// Mean offset `[o_r (m), o_az (rad)]`.
        mean: [f64; 2],
        /// Stationary std of the offsets.
        std: [f64; 2],
        /// Correlation time (s).
        #[serde(deserialize_with = "positive")]
        tau_s: f64,
        /// Scale `[s_r, s_az]`.
        scale: [f64; 2],
    },
}

/// Airframe of the recorded vehicles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AirframeSpec {
    /// Multirotor (hovers).
    Multirotor,
    /// Fixed wing (minimum speed).
    FixedWing,
}

/// How the vehicles fly during `record`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleSpec {
    /// Airframe.
    pub airframe: AirframeSpec,
    /// Seconds the vehicles fly before t = 0 (targets wait at their t = 0 position) to take off
    /// and reach their station.
    #[serde(default, deserialize_with = "non_negative")]
    pub preroll_s: f64,
    /// The behaviour that computes their OFFBOARD velocity setpoints.
    pub behaviour: Behaviour,
}

/// Built-in vehicle behaviours (OFFBOARD velocity setpoints from the true target state).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Behaviour {
    /// Standoff orbit of a target with harrier-core's LGVF ([CIMM] §5 baseline), several vehicles
    /// spaced by phase coordination ([CIMM] §4.3).
    Orbit {
        /// Index of the target.
        target: usize,
        /// Radius (m).
        #[serde(deserialize_with = "positive")]
        radius_m: f64,
        /// Height above the target (m).
        #[serde(deserialize_with = "positive")]
        height_m: f64,
        /// Speed relative to the target (m/s).
        #[serde(deserialize_with = "positive")]
        speed_mps: f64,
    },
    /// Hold a position relative to a target, in its velocity frame (leader–follower, [BOT] §IV).
    Follow {
        /// Index of the target.
        target: usize,
        /// Offset `[right, forward]` (m) of the first vehicle.
        offset_m: [f64; 2],
        /// Height above the target (m).
        #[serde(default)]
        height_m: f64,
        /// Further vehicles sit this far to the right of the previous one (m).
        #[serde(default = "default_spacing")]
        spacing_m: f64,
    },
    /// Hover over a point (multirotor).
    Hold {
        /// Position `[x, y, z]` (m) of the first vehicle.
        position: [f64; 3],
        /// Further vehicles sit this far east of the previous one (m).
        #[serde(default = "default_spacing")]
        spacing_m: f64,
    },
    /// Fly a constant horizontal velocity at an altitude.
    Cruise {
        /// Velocity `[vx, vy]` (m/s).
        velocity: [f64; 2],
        /// Altitude (m).
        #[serde(deserialize_with = "positive")]
        altitude_m: f64,
    },
}

/// What `record` writes for the estimators.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorHints {
    /// `motion` block (models named like the truth modes, transition matrix, `accel_std`).
    #[serde(default)]
    pub motion: Option<Motion>,
    /// Prior std `[x, y, vx, vy]`: the prior mean is the truth at t = 0 plus this noise.
    #[serde(default = "default_prior_std")]
    pub prior_std: [f64; 4],
    /// `scoring.t_start` (s).
    #[serde(default = "default_t_start", deserialize_with = "non_negative")]
    pub scoring_t_start: f64,
}

impl Default for EstimatorHints {
    fn default() -> Self {
        Self {
            motion: None,
            prior_std: default_prior_std(),
            scoring_t_start: default_t_start(),
        }
    }
}

fn default_origin() -> GeoPoint {
    GeoPoint {
        lat_deg: 47.397_742,
        lon_deg: 8.545_594,
        alt_m: 488.0,
    }
}
fn default_size() -> f64 {
    10.0
}
fn default_range() -> f64 {
    10_000.0
}
fn default_spacing() -> f64 {
    30.0
}
fn default_prior_std() -> [f64; 4] {
    [20.0, 20.0, 2.0, 2.0]
}
fn default_t_start() -> f64 {
    5.0
}
fn one() -> f64 {
    1.0
}

fn checked<'de, D: Deserializer<'de>>(
    d: D,
    ok: impl Fn(f64) -> bool,
    what: &str,
) -> Result<f64, D::Error> {
    let v = f64::deserialize(d)?;
    if v.is_finite() && ok(v) {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "invalid value {v}: must be {what}"
        )))
    }
}
fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| v > 0.0, "> 0")
}
fn non_negative<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| v >= 0.0, ">= 0")
}
fn probability<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| (0.0..=1.0).contains(&v), "a probability in [0, 1]")
}

/// Where a scenario came from, for error messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// A built-in preset.
    Preset(String),
    /// A file.
    File(String),
    /// A scenario already in memory, by name.
    Named(String),
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Preset(n) => write!(f, "preset {n}"),
            Self::File(p) => f.write_str(p),
            Self::Named(n) => write!(f, "scenario {n}"),
        }
    }
}

/// A scenario that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScenarioError {
    /// Neither a preset nor a readable file.
    #[error("cannot read scenario {name:?}: {message} (presets: {presets})", presets = PRESETS.join(", "))]
    NotFound {
        /// What was asked for.
        name: String,
        /// The I/O error.
        message: String,
    },
    /// Malformed JSON, unknown or missing key, or an out-of-range number.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Inconsistent values.
    #[error("{origin}: {message}")]
    Invalid {
        /// The file or preset.
        origin: String,
        /// What is wrong, naming the field.
        message: String,
    },
}

impl SimScenario {
    /// A preset by name, a JSON file otherwise.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        if let Some(s) = Self::preset(name_or_path) {
            return Ok(s);
        }
        let text = std::fs::read_to_string(name_or_path).map_err(|e| ScenarioError::NotFound {
            name: name_or_path.to_owned(),
            message: e.to_string(),
        })?;
        Self::from_json(&text, Path::new(name_or_path))
    }

    /// Parses and validates the JSON text of `file` (the path is only used in errors).
    pub fn from_json(text: &str, file: &Path) -> Result<Self, ScenarioError> {
        let file = file.display().to_string();
        let s: Self = serde_json::from_str(text).map_err(|e| {
            let full = e.to_string();
            let message = full
                .rsplit_once(" at line ")
                .map_or(full.as_str(), |(m, _)| m)
                .to_owned();
            ScenarioError::Parse {
                file: file.clone(),
                line: e.line(),
                column: e.column(),
                message,
            }
        })?;
        s.validate(&Source::File(file))?;
        Ok(s)
    }

    /// Pretty JSON (the structure [`Self::from_json`] reads).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The built-in scenario `name` (see [`PRESETS`]).
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "cimm-road" => Some(cimm_road()),
            "leader" => Some(leader()),
            "radar" => Some(radar(BiasModel::None, "radar")),
            "radar-abrupt" => Some(radar(
                BiasModel::Abrupt {
                    t_on: 100.0,
                    t_off: 200.0,
                    scale: [0.01, 0.0],
                    offset: [100.0, 0.01],
                },
                "radar-abrupt",
            )),
            "radar-markov" => Some(radar(
                BiasModel::Markov {
                    mean: [60.0, 0.006],
                    std: [30.0, 0.004],
                    tau_s: 40.0,
                    scale: [0.005, 0.0],
                },
                "radar-markov",
            )),
            "crossing" => Some(crossing()),
            _ => None,
        }
    }

    /// Whether a recording of this scenario needs the multi-target extension (FORMAT-MULTI.md):
    /// several targets or clutter.
    pub fn is_multi(&self) -> bool {
        self.targets.len() > 1 || self.sensors.iter().any(|s| s.clutter_rate > 0.0)
    }

    /// Checks what the types cannot: finite numbers, references, lengths, unique ids.
    pub fn validate(&self, source: &Source) -> Result<(), ScenarioError> {
        let bad = |message: String| ScenarioError::Invalid {
            origin: source.to_string(),
            message,
        };
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let o = &self.origin;
        if !(o.lat_deg.abs() <= 90.0 && o.lon_deg.abs() <= 180.0 && o.alt_m.is_finite()) {
            return Err(bad(format!("origin {o:?} is not a valid geodetic point")));
        }
        if self.targets.is_empty() {
            return Err(bad("targets is empty".into()));
        }
        if self.sensors.is_empty() {
            return Err(bad("sensors is empty".into()));
        }
        unique(self.targets.iter().map(|t| t.id.as_str()), "targets").map_err(&bad)?;
        unique(self.sensors.iter().map(|s| s.id.as_str()), "sensors").map_err(&bad)?;
        unique(self.roads.iter().map(|r| r.id.as_str()), "roads").map_err(&bad)?;
        for (i, r) in self.roads.iter().enumerate() {
            harrier_core::road::Road::from_scenario(r)
                .map_err(|e| bad(format!("roads[{i}] ({}): {e}", r.id)))?;
        }
        let mut z = None;
        for (i, t) in self.targets.iter().enumerate() {
            let at = |m: &str| bad(format!("targets[{i}] ({}): {m}", t.id));
            if !(t.size_m.is_finite() && t.size_m > 0.0) {
                return Err(at("size_m must be > 0"));
            }
            let j = &t.jitter;
            if !finite(&[j.position_m, j.heading_deg, j.speed_mps]) {
                return Err(at("jitter must be finite"));
            }
            let tz = match &t.motion {
                TargetMotion::Road {
                    road,
                    speed_mps,
                    start_m,
                    lateral_std_m,
                } => {
                    if !self.roads.iter().any(|r| &r.id == road) {
                        return Err(at(&format!("road {road:?} is not in roads")));
                    }
                    if !(finite(&[*speed_mps, *start_m, *lateral_std_m]) && *speed_mps > 0.0) {
                        return Err(at(
                            "speed_mps must be > 0, start_m and lateral_std_m finite",
                        ));
                    }
                    0.0
                }
                TargetMotion::Segments {
                    position,
                    velocity,
                    z_m,
                    segments,
                } => {
                    let ok = finite(position)
                        && finite(velocity)
                        && z_m.is_finite()
                        && segments
                            .iter()
                            .all(|s| s.turn_rate.is_finite() && s.duration_s > 0.0);
                    if !ok {
                        return Err(at("segments need finite numbers and durations > 0"));
                    }
                    *z_m
                }
                TargetMotion::Leader {
                    position,
                    z_m,
                    speed_mps,
                    heading_deg,
                    amplitude_deg,
                    period_s,
                } => {
                    let ok = finite(position)
                        && finite(&[*z_m, *heading_deg, *amplitude_deg])
                        && *speed_mps > 0.0
                        && speed_mps.is_finite()
                        && *period_s > 0.0
                        && period_s.is_finite();
                    if !ok {
                        return Err(at("leader needs finite numbers, speed and period > 0"));
                    }
                    *z_m
                }
            };
            match z {
                None => z = Some(tz),
                Some(z0) if z0 != tz => {
                    return Err(at(&format!(
                        "altitude {tz} m differs from the first target's {z0} m \
                         (all targets share one plane)"
                    )));
                }
                _ => {}
            }
        }
        for (i, s) in self.sensors.iter().enumerate() {
            let at = |m: &str| bad(format!("sensors[{i}] ({}): {m}", s.id));
            if s.id.is_empty() {
                return Err(at("id is empty"));
            }
            if !(s.rate_hz > 0.0 && s.rate_hz <= 1000.0) {
                return Err(at("rate_hz must be in (0, 1000]"));
            }
            if !((0.0..=1.0).contains(&s.pd) && s.clutter_rate >= 0.0 && s.clutter_rate <= 1e4) {
                return Err(at("pd must be in [0, 1] and clutter_rate in [0, 10000]"));
            }
            if !(s.max_range_m > 0.0 && s.max_range_m.is_finite()) {
                return Err(at("max_range_m must be > 0"));
            }
            if !s.noise_std.iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(at("noise_std must be finite and > 0"));
            }
            let n = s.kind().len(Some(2));
            if s.noise_std.len() != n {
                return Err(at(&format!(
                    "noise_std has {} components, {:?} needs {n}",
                    s.noise_std.len(),
                    s.kind()
                )));
            }
            match &s.model {
                SensorModel::Camera {
                    fov_deg, pointing, ..
                } => {
                    if !(*fov_deg > 0.0 && *fov_deg < 180.0) {
                        return Err(at("fov_deg must be in (0, 180)"));
                    }
                    match pointing {
                        Pointing::Fixed {
                            pan_deg,
                            depression_deg,
                        } if !(pan_deg.is_finite() && depression_deg.abs() <= 90.0) => {
                            return Err(at("pointing needs a finite pan and |depression| <= 90"));
                        }
                        Pointing::Track { target } if *target >= self.targets.len() => {
                            return Err(at(&format!("pointing.target {target} does not exist")));
                        }
                        _ => {}
                    }
                }
                SensorModel::Radar { bias } => {
                    let ok = match bias {
                        BiasModel::None => true,
                        BiasModel::Abrupt {
                            t_on,
                            t_off,
                            scale,
                            offset,
                        } => finite(&[*t_on, *t_off]) && finite(scale) && finite(offset),
                        BiasModel::Markov {
                            mean,
                            std,
                            tau_s,
                            scale,
                        } => {
                            finite(mean)
                                && finite(scale)
                                && std.iter().all(|v| v.is_finite() && *v >= 0.0)
                                && tau_s.is_finite()
                                && *tau_s > 0.0
                        }
                    };
                    if !ok {
                        return Err(at("bias needs finite numbers, std >= 0 and tau_s > 0"));
                    }
                }
            }
        }
        let v = &self.vehicles;
        if !(v.preroll_s.is_finite() && (0.0..=3600.0).contains(&v.preroll_s)) {
            return Err(bad("vehicles.preroll_s must be in [0, 3600]".into()));
        }
        let behaviour_ok = match &v.behaviour {
            Behaviour::Orbit {
                target,
                radius_m,
                height_m,
                speed_mps,
            } => {
                *target < self.targets.len()
                    && finite(&[*radius_m, *height_m, *speed_mps])
                    && *radius_m > 0.0
                    && *speed_mps > 0.0
            }
            Behaviour::Follow {
                target,
                offset_m,
                height_m,
                spacing_m,
            } => {
                *target < self.targets.len() && finite(offset_m) && finite(&[*height_m, *spacing_m])
            }
            Behaviour::Hold {
                position,
                spacing_m,
            } => finite(position) && spacing_m.is_finite(),
            Behaviour::Cruise {
                velocity,
                altitude_m,
            } => finite(velocity) && altitude_m.is_finite() && *altitude_m > 0.0,
        };
        if !behaviour_ok {
            return Err(bad(
                "vehicles.behaviour: target index out of range or a number is not finite/positive"
                    .into(),
            ));
        }
        let h = &self.estimator;
        if !h.prior_std.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(bad("estimator.prior_std must be finite and > 0".into()));
        }
        Ok(())
    }

    /// The plane of the targets (m): all share one altitude.
    pub fn plane_z(&self) -> f64 {
        self.targets.first().map_or(0.0, |t| match &t.motion {
            TargetMotion::Road { .. } => 0.0,
            TargetMotion::Segments { z_m, .. } | TargetMotion::Leader { z_m, .. } => *z_m,
        })
    }
}

impl SensorSpec {
    /// The measurement kind of its detections.
    pub fn kind(&self) -> harrier_core::scenario::MeasKind {
        use harrier_core::scenario::MeasKind;
        match &self.model {
            SensorModel::Radar { .. } => MeasKind::RangeBearing,
            SensorModel::Camera { output, .. } => match output {
                CameraOutput::AzEl => MeasKind::AzEl,
                CameraOutput::BearingSize => MeasKind::BearingSize,
                CameraOutput::Position => MeasKind::Position,
            },
        }
    }
}

fn unique<'a>(ids: impl Iterator<Item = &'a str>, what: &str) -> Result<(), String> {
    let mut seen: Vec<&str> = Vec::new();
    for id in ids {
        if id.is_empty() {
            return Err(format!("{what}: an id is empty"));
        }
        if seen.contains(&id) {
            return Err(format!("{what}: id {id:?} appears twice"));
        }
        seen.push(id);
    }
    Ok(())
}

/// Hints for a single white-noise-acceleration CV model, scored from t = 5 s.
fn cv_hints(accel_std: f64, prior_std: [f64; 4]) -> EstimatorHints {
    EstimatorHints {
        motion: Some(Motion {
            models: vec![model("CV", None)],
            initial_probs: None,
            transition_matrix: None,
            accel_std: Some(accel_std),
            accel_bound: None,
        }),
        prior_std,
        scoring_t_start: 5.0,
    }
}

fn model(name: &str, turn_rate: Option<f64>) -> MotionModelSpec {
    MotionModelSpec {
        name: name.into(),
        kind: if turn_rate.is_some() { "CT" } else { "CV" }.into(),
        turn_rate,
    }
}

/// [CIMM] §5.1: a ground vehicle at 10 m/s on a road, straight 140 s, right turn (−0.008 rad/s)
/// 220 s, left turn (0.01 rad/s) 340 s; camera geolocation with 10 m noise at 1 Hz; fixed wings
/// orbiting it at R = 300 m, 300 m above, 20 m/s (LGVF).
fn cimm_road() -> SimScenario {
    // The target starts at (200, 300) m with (6, 8) m/s: straight 140 s, right 220 s, left
    // 340 s. The road begins 100 m (10 s) before it.
    let v0 = Vector2::new(6.0, 8.0);
    let start = Vector2::new(200.0, 300.0) - v0 * 10.0;
    let legs = [(-10.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
    let road = road_from_turn_legs(start, v0, &legs, 700.0, "road1", Some(7.0), Some(2.0))
        .expect("the CIMM road's legs are valid");
    SimScenario {
        name: "cimm-road".into(),
        description: "[CIMM] §5.1: ground vehicle on a road (straight, right turn, left turn), \
                      camera geolocation 10 m at 1 Hz, UAVs orbiting at R 300 m, 300 m above."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "tgt".into(),
            size_m: 5.0,
            size_known: false,
            motion: TargetMotion::Road {
                road: "road1".into(),
                speed_mps: 10.0,
                start_m: 100.0,
                lateral_std_m: 0.0,
            },
            jitter: Jitter::default(),
        }],
        roads: vec![road],
        sensors: vec![SensorSpec {
            id: "cam".into(),
            rate_hz: 1.0,
            pd: 1.0,
            clutter_rate: 0.0,
            max_range_m: 2000.0,
            noise_std: vec![10.0, 10.0],
            model: SensorModel::Camera {
                output: CameraOutput::Position,
                fov_deg: 30.0,
                pointing: Pointing::Track { target: 0 },
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::FixedWing,
            preroll_s: 90.0,
            behaviour: Behaviour::Orbit {
                target: 0,
                radius_m: 300.0,
                height_m: 300.0,
                speed_mps: 20.0,
            },
        },
        estimator: EstimatorHints {
            motion: Some(Motion {
                models: vec![
                    model("CV", None),
                    model("right", Some(-0.008)),
                    model("left", Some(0.01)),
                ],
                initial_probs: Some(vec![0.98, 0.01, 0.01]),
                transition_matrix: Some(vec![
                    vec![0.98, 0.01, 0.01],
                    vec![0.01, 0.98, 0.01],
                    vec![0.01, 0.01, 0.98],
                ]),
                accel_std: Some(0.05),
                accel_bound: None,
            }),
            prior_std: [20.0, 20.0, 2.0, 2.0],
            scoring_t_start: 5.0,
        },
    }
}

/// [BOT] §IV: a leader aircraft at 25 m/s with sinusoidal heading (±40°, 30 s), 10 m wing span,
/// seen by a follower's `bearing_size` camera at 10 Hz (1 mrad noise); the follower flies 60 m
/// left of and 120 m behind the leader.
fn leader() -> SimScenario {
    SimScenario {
        name: "leader".into(),
        description: "[BOT] §IV: leader with sinusoidal heading, follower's bearing/size camera."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "leader".into(),
            size_m: 10.0,
            size_known: false,
            motion: TargetMotion::Leader {
                position: [60.0, 120.0],
                z_m: 100.0,
                speed_mps: 25.0,
                heading_deg: 0.0,
                amplitude_deg: 40.0,
                period_s: 30.0,
            },
            jitter: Jitter::default(),
        }],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "cam".into(),
            rate_hz: 10.0,
            pd: 1.0,
            clutter_rate: 0.0,
            max_range_m: 2000.0,
            noise_std: vec![0.001, 0.001, 0.001],
            model: SensorModel::Camera {
                output: CameraOutput::BearingSize,
                fov_deg: 40.0,
                pointing: Pointing::Track { target: 0 },
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::FixedWing,
            preroll_s: 30.0,
            behaviour: Behaviour::Follow {
                target: 0,
                offset_m: [-60.0, -120.0],
                height_m: 0.0,
                spacing_m: 30.0,
            },
        },
        estimator: cv_hints(2.0, [40.0, 40.0, 5.0, 5.0]),
    }
}

/// [ICDKF] §4: a target manoeuvring in the plane (CV 80 s, left 0.05 rad/s 30 s, CV 70 s, right
/// −0.04 rad/s 30 s, CV) seen by a radar (5 m, 5 mrad, 1 Hz) on a multirotor cruising east at
/// 5 m/s, with the given bias.
fn radar(bias: BiasModel, name: &str) -> SimScenario {
    let seg = |mode: &str, turn_rate, duration_s| MotionSegment {
        mode: mode.into(),
        turn_rate,
        duration_s,
    };
    SimScenario {
        name: name.into(),
        description: "[ICDKF] §4: manoeuvring target, range/bearing radar on a moving multirotor."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "tgt".into(),
            size_m: 10.0,
            size_known: false,
            motion: TargetMotion::Segments {
                position: [1000.0, 5000.0],
                velocity: [15.0, -10.0],
                z_m: 0.0,
                segments: vec![
                    seg("CV", 0.0, 80.0),
                    seg("left", 0.05, 30.0),
                    seg("CV", 0.0, 70.0),
                    seg("right", -0.04, 30.0),
                    seg("CV", 0.0, 90.0),
                ],
            },
            jitter: Jitter::default(),
        }],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "radar".into(),
            rate_hz: 1.0,
            pd: 1.0,
            clutter_rate: 0.0,
            max_range_m: 20_000.0,
            noise_std: vec![5.0, 0.005],
            model: SensorModel::Radar { bias },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::Multirotor,
            preroll_s: 10.0,
            behaviour: Behaviour::Cruise {
                velocity: [5.0, 0.0],
                altitude_m: 20.0,
            },
        },
        estimator: cv_hints(1.0, [100.0, 100.0, 5.0, 5.0]),
    }
}

/// Four ground vehicles crossing under a multirotor hovering 400 m up, seen by a nadir gimbal
/// camera (`az_el`, 90° field of view, Pd 0.9, one clutter detection per scan) at 2 Hz.
fn crossing() -> SimScenario {
    let straight = |id: &str, position: [f64; 2], velocity: [f64; 2]| TargetSpec {
        id: id.into(),
        size_m: 5.0,
        size_known: false,
        motion: TargetMotion::Segments {
            position,
            velocity,
            z_m: 0.0,
            segments: Vec::new(),
        },
        jitter: Jitter {
            position_m: 20.0,
            heading_deg: 5.0,
            speed_mps: 1.0,
        },
    };
    SimScenario {
        name: "crossing".into(),
        description: "Ground vehicles crossing under a hovering multirotor; nadir camera with \
                      Pd < 1 and Poisson clutter (FORMAT-MULTI.md)."
            .into(),
        origin: default_origin(),
        targets: vec![
            straight("T0", [-300.0, 0.0], [8.0, 0.0]),
            straight("T1", [0.0, -300.0], [0.0, 8.0]),
            straight("T2", [250.0, 250.0], [-6.0, -6.0]),
            straight("T3", [-250.0, 250.0], [6.0, -6.0]),
        ],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "gimbal".into(),
            rate_hz: 2.0,
            pd: 0.9,
            clutter_rate: 1.0,
            max_range_m: 1500.0,
            noise_std: vec![0.002, 0.002],
            model: SensorModel::Camera {
                output: CameraOutput::AzEl,
                fov_deg: 90.0,
                pointing: Pointing::Nadir,
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::Multirotor,
            preroll_s: 100.0,
            behaviour: Behaviour::Hold {
                position: [0.0, 0.0, 400.0],
                spacing_m: 30.0,
            },
        },
        estimator: cv_hints(0.3, [20.0, 20.0, 2.0, 2.0]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_round_trip() {
        for name in PRESETS {
            let s = SimScenario::preset(name).expect(name);
            s.validate(&Source::Preset(name.into())).expect(name);
            let back = SimScenario::from_json(&s.to_json(), Path::new("x.json")).expect(name);
            // serde_json's float parser may be off by an ulp: compare the JSON values closely.
            let a: serde_json::Value = serde_json::from_str(&s.to_json()).expect("json");
            let b: serde_json::Value = serde_json::from_str(&back.to_json()).expect("json");
            assert!(close_json(&a, &b), "{name}");
        }
        assert!(SimScenario::preset("nope").is_none());
        assert!(SimScenario::preset("crossing").is_some_and(|s| s.is_multi()));
        assert!(SimScenario::preset("cimm-road").is_some_and(|s| !s.is_multi()));
    }

    #[test]
    fn cimm_road_matches_the_reference_geometry() {
        use harrier_core::scenario::Segment;
        let s = cimm_road();
        let segs = &s.roads[0].segments;
        assert_eq!(segs.len(), 3);
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-6;
        match (&segs[0], &segs[1], &segs[2]) {
            (
                Segment::Line { start, end },
                Segment::Arc {
                    center,
                    radius,
                    sweep_rad,
                    ..
                },
                Segment::Arc {
                    center: c2,
                    radius: r2,
                    end: e2,
                    sweep_rad: s2,
                    ..
                },
            ) => {
                assert!(close(*start, [140.0, 220.0]) && close(*end, [1040.0, 1420.0]));
                assert!(close(*center, [2040.0, 670.0]));
                assert!((radius - 1250.0).abs() < 1e-9 && (sweep_rad + 1.76).abs() < 1e-12);
                assert!(close(
                    *c2,
                    [3_704.446_638_142_980_6, 2_183.974_038_342_336_4]
                ));
                assert!((r2 - 1000.0).abs() < 1e-6 && (s2 - 3.4).abs() < 1e-12);
                assert!(close(*e2, [4_247.691_708_011_238, 3_023.548_212_590_115]));
            }
            other => panic!("unexpected segments {other:?}"),
        }
    }

    fn close_json(a: &serde_json::Value, b: &serde_json::Value) -> bool {
        use serde_json::Value as V;
        match (a, b) {
            (V::Number(x), V::Number(y)) => {
                let (x, y) = (
                    x.as_f64().unwrap_or(f64::NAN),
                    y.as_f64().unwrap_or(f64::NAN),
                );
                (x - y).abs() <= 1e-12 * (1.0 + x.abs())
            }
            (V::Array(x), V::Array(y)) => {
                x.len() == y.len() && x.iter().zip(y).all(|(p, q)| close_json(p, q))
            }
            (V::Object(x), V::Object(y)) => {
                x.len() == y.len()
                    && x.iter()
                        .all(|(k, v)| y.get(k).is_some_and(|w| close_json(v, w)))
            }
            _ => a == b,
        }
    }

    fn parse_err(text: &str) -> String {
        SimScenario::from_json(text, Path::new("bad/scn.json"))
            .expect_err("refused")
            .to_string()
    }

    #[test]
    fn bad_files_name_file_line_and_problem() {
        let good = cimm_road().to_json();
        // Syntax error on line 3.
        let mut lines: Vec<&str> = good.lines().collect();
        lines[2] = "  \"description\": oops,";
        let e = parse_err(&lines.join("\n"));
        assert!(e.starts_with("bad/scn.json:3:"), "{e}");
        // Out-of-range values are refused at their line.
        for (from, to, what) in [
            ("\"rate_hz\": 1.0", "\"rate_hz\": -1.0", "must be > 0"),
            ("\"pd\": 1.0", "\"pd\": 1.5", "probability"),
            ("\"fov_deg\": 30.0", "\"fov_deg\": 0.0", "must be > 0"),
            ("\"clutter_rate\": 0.0", "\"clutter_rate\": -2", ">= 0"),
        ] {
            let text = good.replace(from, to);
            let line = text.lines().position(|l| l.contains(to.trim())).expect(to) + 1;
            let e = parse_err(&text);
            // The value's line, or the end of the tagged object (`model`) holding it.
            let at: usize = e
                .strip_prefix("bad/scn.json:")
                .and_then(|r| r.split(':').next())
                .and_then(|l| l.parse().ok())
                .expect("line number");
            assert!((line..line + 8).contains(&at), "{e} (value on line {line})");
            assert!(e.contains(what), "{e}");
        }
        let e = parse_err(&good.replace("\"speed_mps\": 10.0", "\"speeed\": 10.0"));
        assert!(
            e.contains("unknown field") && e.contains("bad/scn.json:"),
            "{e}"
        );
        // Consistency problems name the field.
        let e = parse_err(&good.replace("\"road\": \"road1\"", "\"road\": \"road9\""));
        assert!(e.contains("targets[0] (tgt)") && e.contains("road9"), "{e}");
        let e = parse_err(&good.replace("\"fov_deg\": 30.0", "\"fov_deg\": 200.0"));
        assert!(e.contains("fov_deg must be in (0, 180)"), "{e}");
        let e = parse_err(&good.replace("10.0,\n        10.0", "10.0"));
        assert!(e.contains("noise_std has 1 components"), "{e}");
        let e = SimScenario::load("/nonexistent/x.json").expect_err("missing");
        assert!(e.to_string().contains("cimm-road"), "{e}");
    }
}
