//! The setup of a simulation: targets, roads, the sensors every vehicle carries and how the
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
//!
//! Split by concern: the types are here, `presets.rs` builds the named scenarios and `parse.rs`
//! reads and checks JSON files.

use harrier_core::detection::GeoPoint;
use harrier_core::scenario::{Motion, Road};
use serde::{Deserialize, Serialize};

mod check;
mod parse;
mod presets;

pub use check::{PRESETS, ScenarioError, Source};
use check::{non_negative, positive, probability};

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
    /// target of \[CIMM\] §5.1. It parks at the end of the road.
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
    /// Piecewise constant-velocity / constant-turn motion (\[CIMM\] §5.1, \[ICDKF\] §4): each segment
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
    /// The aircraft leader of \[BOT\] §IV: constant speed, heading
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
    /// A time offset δ (s): each scan, taken at `t`, is stamped `t + δ` (a latency: the scan
    /// stamped `t` shows the world at `t − δ`, the time offset registration estimates; default
    /// none).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub time_offset_s: f64,
    /// Camera or radar.
    pub model: SensorType,
}

/// A sensor without a time offset (its `time_offset_s` left out of the file).
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// What a [`SensorSpec`] is — a camera or a radar — with the settings of its type (a sensor's
/// `model` object, tagged by `type`). Not harrier-core's run-time measurement model
/// (`harrier_core::measurement::SensorModel`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SensorType {
    /// Gimbal camera: sees what lies within `fov_deg / 2` of its boresight.
    Camera {
        /// What it reports.
        output: CameraOutput,
        /// Full cone angle of the field of view (degrees, in (0, 180)).
        #[serde(deserialize_with = "positive")]
        fov_deg: f64,
        /// Where the boresight points.
        pointing: Pointing,
        /// A mounting error: `[azimuth, elevation]` (degrees) added to every `az_el` and
        /// `bearing_size` angle it reports (the constant offsets registration estimates; default
        /// none).
        #[serde(default, skip_serializing_if = "no_mounting")]
        mounting_deg: [f64; 2],
    },
    /// Radar: `range_bearing`, all around, with an optional bias (\[ICDKF\] eq. (9)).
    Radar {
        /// Bias model.
        #[serde(default)]
        bias: BiasModel,
        /// Whether it also paints the other vehicles of the world (cooperative targets whose
        /// own GPS position the ground station hears over MAVLink: registration's references),
        /// as it paints the targets; default no.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        paints_vehicles: bool,
    },
}

/// A camera without a mounting error (its `mounting_deg` left out of the file).
fn no_mounting(m: &[f64; 2]) -> bool {
    *m == [0.0, 0.0]
}

/// What a camera reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraOutput {
    /// `az_el` angles.
    AzEl,
    /// `bearing_size`: angles and subtended angle 2·atan(S / 2ρ) (\[BOT\] §II.C).
    BearingSize,
    /// `position`: the target geolocated on its plane, `[x, y]` (\[CIMM\] §5.1's camera).
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
    /// Pointed by the vehicle's gimbal manager at the region of interest the ground station set
    /// (MAV_CMD_DO_SET_ROI_LOCATION: `Vehicle::gimbal_direction`); straight down without one.
    Roi,
}

/// Radar measurement bias, \[ICDKF\] eq. (9): `z_i = (1 + s_i) h_i + o_i + v_i`, i = range, azimuth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum BiasModel {
    /// No bias (\[ICDKF\] §4 type 1).
    #[default]
    None,
    /// Switched on at `t_on`, off at `t_off` (\[ICDKF\] §4 type 2).
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
    /// scale (\[ICDKF\] §4 type 3).
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
    /// Standoff orbit of a target with harrier-core's LGVF (\[CIMM\] §5 baseline), several vehicles
    /// spaced by phase coordination (\[CIMM\] §4.3).
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
    /// Hold a position relative to a target, in its velocity frame (leader–follower, \[BOT\] §IV).
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

pub(crate) fn default_origin() -> GeoPoint {
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

impl SimScenario {
    /// Whether a recording of this scenario needs the multi-target extension (FORMAT-MULTI.md):
    /// several targets or clutter.
    pub fn is_multi(&self) -> bool {
        self.targets.len() > 1 || self.sensors.iter().any(|s| s.clutter_rate > 0.0)
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
    pub fn kind(&self) -> harrier_core::measurement::MeasKind {
        use harrier_core::measurement::MeasKind;
        match &self.model {
            SensorType::Radar { .. } => MeasKind::RangeBearing,
            SensorType::Camera { output, .. } => match output {
                CameraOutput::AzEl => MeasKind::AzEl,
                CameraOutput::BearingSize => MeasKind::BearingSize,
                CameraOutput::Position => MeasKind::Position,
            },
        }
    }
}
