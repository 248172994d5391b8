//! A seeded generator of registration scenarios (FORMAT-REGISTRATION.md §5): a ground target
//! driving legs of straight road and turns; a ground radar ~3 km away (1 Hz, σ 5 m and 2 mrad);
//! two fixed-wing UAVs circling it on a 300 m standoff orbit at 120 m in a steady wind (so that
//! they go round faster downwind than upwind), whose gimbal cameras (`az_el`, 5 Hz, σ 2 mrad)
//! both lose the target together for 40–90 s several times (outages: the radar alone carries the
//! target then). The [`Case`] says which sensor is biased and how; the [`Variant`] says what the
//! written scenario tells the estimator.
//!
//! Pure: everything comes from one ChaCha8 stream seeded by the caller, drawn in the same order
//! whatever the case and variant, so that the cases and variants of one seed share the
//! trajectory, the outages and every noise sample: the `none` case of a seed is the unbiased run
//! of its `mounting` case, and the `told-bias` variant holds the very noise of the biased data.
//!
//! The data are made with the exact geometry (a time offset δ: target and platform where they
//! were at `t − δ`), not with the estimator's first-order model. The wind matters: on an orbit
//! centred on the target, a camera's latency shifts its azimuth by `δ s / R` (s the UAV's speed
//! relative to the target along the circle); at a constant `s` that is a constant azimuth
//! offset, and the two could not be told apart.

use std::f64::consts::{FRAC_PI_2, TAU};
use std::fmt::Write as _;

use nalgebra::{Vector2, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::model::{BiasPrior, SensorBias, Term};
use crate::measurement::{Geometry, MeasKind, MeasurementModel, SensorModel};
use crate::motion::{ConstantTurn, TransitionModel};
use crate::scenario as fmt;
use crate::{EstimationError, Result};

/// Which biases the data carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Case {
    /// No bias.
    None,
    /// Constant radar range offset (±20–60 m), azimuth offset (±3–8 mrad) and range scale
    /// (±0.1–0.3 %).
    Constant,
    /// Gauss–Markov radar range offset (σ 20–40 m) and azimuth offset (σ 3–6 mrad), one
    /// correlation time τ of 60–200 s for both, started from their stationary distribution.
    GaussMarkov,
    /// Both cameras mounted 0.5° off in azimuth and in elevation (signs drawn).
    Mounting,
    /// Camera `cam1` 200 ms late.
    TimeOffset,
    /// The radar alone (no camera) with [`Case::Constant`]'s biases, painting UAV `uav1`, whose
    /// GPS reports are the cooperative references (`references.jsonl`).
    RadarReference,
    /// The radar alone with [`Case::Constant`]'s biases and no reference.
    RadarAlone,
}

impl Case {
    /// Every case.
    pub const ALL: [Self; 7] = [
        Self::None,
        Self::Constant,
        Self::GaussMarkov,
        Self::Mounting,
        Self::TimeOffset,
        Self::RadarReference,
        Self::RadarAlone,
    ];

    /// The name on the command line and in scenario names.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Constant => "constant",
            Self::GaussMarkov => "gauss-markov",
            Self::Mounting => "mounting",
            Self::TimeOffset => "time-offset",
            Self::RadarReference => "radar-reference",
            Self::RadarAlone => "radar-alone",
        }
    }

    /// The case called `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }

    /// Whether the cameras take part (every case but the radar-alone ones).
    pub fn cameras(self) -> bool {
        !matches!(self, Self::RadarReference | Self::RadarAlone)
    }
}

/// What the written scenario tells the estimator about the biases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variant {
    /// The deployment's configuration: every sensor with [`SensorBias::typical`] of its kind,
    /// the same whatever the case (the estimator's one tuning).
    Deployment,
    /// Each sensor with the true bias model: only the terms the case biases, with their true
    /// dynamics (a Gauss–Markov term's σ and τ) but not their values.
    ToldModel,
    /// The true bias values: the measurements with the biases taken out (the same noise), no
    /// bias block and no reference.
    ToldBias,
}

impl Variant {
    /// Every variant.
    pub const ALL: [Self; 3] = [Self::Deployment, Self::ToldModel, Self::ToldBias];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Deployment => "deployment",
            Self::ToldModel => "told-model",
            Self::ToldBias => "told-bias",
        }
    }

    /// The variant called `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GenConfig {
    /// The biases.
    pub case: Case,
    /// What the scenario tells.
    pub variant: Variant,
    /// Length of the run (s, ≥ 60): the cameras scan 5 times a second, the radar once.
    pub duration: f64,
}

/// The files of a generated scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Generated {
    /// `scenario.json`.
    pub scenario_json: String,
    /// `measurements.jsonl`.
    pub measurements_jsonl: String,
    /// `truth.csv`.
    pub truth_csv: String,
    /// `references.jsonl` (empty without references).
    pub references_jsonl: String,
    /// `bias_truth.csv`: the true value of every biased term at every scan.
    pub bias_truth_csv: String,
    /// The camera outages `(start, end)` (s).
    pub outages: Vec<(f64, f64)>,
}

/// Radar site (ENU, m) and noise `[σ_range (m), σ_azimuth (rad)]`.
const RADAR_POS: [f64; 3] = [-2400.0, -1800.0, 10.0];
const RADAR_STD: [f64; 2] = [5.0, 0.002];
/// Camera noise `[σ_az, σ_el]` (rad).
const CAMERA_STD: [f64; 2] = [0.002, 0.002];
/// Scans per second of the cameras (the radar scans once a second).
const CAMERA_RATE: usize = 5;
/// UAV orbit: radius (m), height (m), airspeed (m/s); the wind's speed range (m/s).
const ORBIT: [f64; 3] = [300.0, 120.0, 24.0];
const WIND: [f64; 2] = [2.0, 6.0];
/// GPS position noise of the reference UAV (m) and its velocity noise (m/s).
const GPS_STD: [f64; 3] = [1.5, 1.5, 3.0];
const GPS_VEL_STD: f64 = 0.2;
/// Probability that the radar paints the reference UAV in a scan.
const REFERENCE_PD: f64 = 0.9;
/// Prior standard deviations of the target `[x, y, vx, vy]`.
const PRIOR_STD: [f64; 4] = [20.0, 20.0, 2.0, 2.0];
/// Mounting offset of the cameras (rad) and the latency of `cam1` (s).
const MOUNTING: f64 = 0.5 * std::f64::consts::PI / 180.0;
const LATENCY: f64 = 0.2;
/// The motion hint: white-noise acceleration std (m/s²).
const ACCEL_STD: f64 = 0.5;

/// A leg of the target's drive: CT at `omega` (0: straight) from `t0` with state `x0`.
#[derive(Debug, Clone, Copy)]
struct Leg {
    t0: f64,
    omega: f64,
    x0: Vector4<f64>,
}

/// The target's planar trajectory, exact at any time (also before 0).
#[derive(Debug, Clone)]
struct Drive {
    legs: Vec<Leg>,
}

impl Drive {
    fn draw(rng: &mut ChaCha8Rng, duration: f64) -> Self {
        let heading = rng.random_range(0.0..TAU);
        let speed = rng.random_range(8.0..14.0);
        let mut x = Vector4::new(
            rng.random_range(-300.0..300.0),
            rng.random_range(-300.0..300.0),
            speed * f64::sin(heading),
            speed * f64::cos(heading),
        );
        let mut legs = Vec::new();
        let mut t = 0.0;
        while t <= duration {
            let turn = legs.len() % 2 == 1;
            let (omega, len) = if turn {
                let w = rng.random_range(0.03..0.08);
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                (sign * w, rng.random_range(15.0..40.0))
            } else {
                (0.0, rng.random_range(30.0..80.0))
            };
            legs.push(Leg {
                t0: t,
                omega,
                x0: x,
            });
            x = ConstantTurn::<4>::new(omega, 0.0).function(&x, len);
            t += len;
        }
        Self { legs }
    }

    fn leg(&self, t: f64) -> &Leg {
        let i = self.legs.partition_point(|l| l.t0 <= t).max(1) - 1;
        &self.legs[i]
    }

    /// `[x, y, vx, vy]` at `t`.
    fn at(&self, t: f64) -> Vector4<f64> {
        let l = self.leg(t);
        ConstantTurn::<4>::new(l.omega, 0.0).function(&l.x0, t - l.t0)
    }

    fn mode(&self, t: f64) -> &'static str {
        let w = self.leg(t).omega;
        if w > 0.0 {
            "left"
        } else if w < 0.0 {
            "right"
        } else {
            "CV"
        }
    }
}

/// A UAV on a standoff orbit of radius R around the moving target at constant airspeed in a
/// steady wind: its ground velocity relative to the target is `s t̂` along the circle's tangent
/// `t̂ = (cos θ, −sin θ)` (θ clockwise from North, the UAV at `target + R (sin θ, cos θ)`), with
/// `s` solving `|v_target + s t̂ − wind| = airspeed`, so that it circles fast downwind and slowly
/// upwind, as a fixed-wing UAV tracking a car does. θ is integrated (RK4) on a fine grid.
#[derive(Debug, Clone)]
struct Orbit {
    theta: Vec<f64>,
    wind: Vector2<f64>,
}

/// Orbit integration step (s) and how far before 0 it starts (for time offsets).
const ORBIT_STEP: f64 = 0.05;
const ORBIT_BEFORE: f64 = 2.0;

impl Orbit {
    fn fly(drive: &Drive, wind: Vector2<f64>, theta0: f64, duration: f64) -> Self {
        let rate = |t: f64, th: f64| Self::speed(drive, wind, t, th) / ORBIT[0];
        let n = ((duration + 2.0 * ORBIT_BEFORE) / ORBIT_STEP).ceil() as usize + 1;
        let mut theta = Vec::with_capacity(n);
        let mut th = theta0;
        for k in 0..n {
            theta.push(th);
            let t = k as f64 * ORBIT_STEP - ORBIT_BEFORE;
            let h = ORBIT_STEP;
            let k1 = rate(t, th);
            let k2 = rate(t + h / 2.0, th + h / 2.0 * k1);
            let k3 = rate(t + h / 2.0, th + h / 2.0 * k2);
            let k4 = rate(t + h, th + h * k3);
            th += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        Self { theta, wind }
    }

    /// Ground speed along the tangent relative to the target, `s ≥ 0`.
    fn speed(drive: &Drive, wind: Vector2<f64>, t: f64, theta: f64) -> f64 {
        let x = drive.at(t);
        let tangent = Vector2::new(theta.cos(), -theta.sin());
        let u = Vector2::new(x[2], x[3]) - wind;
        let a = tangent.dot(&u);
        let va = ORBIT[2];
        -a + (a * a + va * va - u.norm_squared()).max(0.0).sqrt()
    }

    /// Position and velocity at `t`.
    fn at(&self, drive: &Drive, t: f64) -> (Vector3<f64>, Vector3<f64>) {
        let f = ((t + ORBIT_BEFORE) / ORBIT_STEP).max(0.0);
        let i = (f.floor() as usize).min(self.theta.len() - 2);
        let w = f - i as f64;
        let th = (1.0 - w) * self.theta[i] + w * self.theta[i + 1];
        let [r, h, _] = ORBIT;
        let x = drive.at(t);
        let s = Self::speed(drive, self.wind, t, th);
        let pos = Vector3::new(x[0] + r * th.sin(), x[1] + r * th.cos(), h);
        let vel = Vector3::new(x[2] + s * th.cos(), x[3] - s * th.sin(), 0.0);
        (pos, vel)
    }
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random_bool(0.5) { 1.0 } else { -1.0 }
}

/// Every bias value and model the cases can use, drawn in one order for every case.
#[derive(Debug, Clone, Copy)]
struct Draws {
    constant: [f64; 3],
    gm_std: [f64; 2],
    gm_tau: f64,
    gm_start: [f64; 2],
    mount_signs: [f64; 4],
}

impl Draws {
    fn draw(rng: &mut ChaCha8Rng) -> Self {
        let constant = [
            sign(rng) * rng.random_range(20.0..60.0),
            sign(rng) * rng.random_range(0.003..0.008),
            sign(rng) * rng.random_range(0.001..0.003),
        ];
        let gm_std = [rng.random_range(20.0..40.0), rng.random_range(0.003..0.006)];
        let gm_tau = rng.random_range(60.0..200.0);
        let gm_start = [gm_std[0] * normal(rng), gm_std[1] * normal(rng)];
        let mount_signs = [sign(rng), sign(rng), sign(rng), sign(rng)];
        Self {
            constant,
            gm_std,
            gm_tau,
            gm_start,
            mount_signs,
        }
    }
}

/// The sensors of a scenario: id, platform, kind and noise.
const SENSORS: [(&str, &str, MeasKind, [f64; 2]); 3] = [
    ("cam1", "uav1", MeasKind::AzEl, CAMERA_STD),
    ("cam2", "uav2", MeasKind::AzEl, CAMERA_STD),
    ("radar1", "site", MeasKind::RangeBearing, RADAR_STD),
];

/// The true bias of each sensor (in [`SENSORS`] order) at one scan: its model and value per term.
type Truth = [Vec<(Term, BiasPrior, f64)>; 3];

/// Generates a scenario from `seed`.
pub fn generate(seed: u64, cfg: &GenConfig) -> Result<Generated> {
    if !(cfg.duration.is_finite() && (60.0..=1e5).contains(&cfg.duration)) {
        return Err(EstimationError::InvalidParameter(format!(
            "duration must be in [60, 100000] s, got {}",
            cfg.duration
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let drive = Drive::draw(&mut rng, cfg.duration + 1.0);
    let phase = rng.random_range(0.0..TAU);
    let wind_dir = rng.random_range(0.0..TAU);
    let wind_speed = rng.random_range(WIND[0]..WIND[1]);
    let wind = Vector2::new(wind_speed * wind_dir.sin(), wind_speed * wind_dir.cos());
    let orbits = [0.0, FRAC_PI_2].map(|p| Orbit::fly(&drive, wind, phase + p, cfg.duration));
    let mut outages = Vec::new();
    let mut t = rng.random_range(60.0..120.0);
    loop {
        let len = rng.random_range(40.0..90.0);
        if t + len > cfg.duration - 20.0 {
            break;
        }
        outages.push((t, t + len));
        t += len + rng.random_range(60.0..120.0);
    }
    let draws = Draws::draw(&mut rng);
    let case = cfg.case;
    let mut truth: Truth = [Vec::new(), Vec::new(), Vec::new()];
    let [c_r, c_a, c_s] = draws.constant;
    let constant = |v: f64, std: f64| (BiasPrior::constant(std), v);
    match case {
        Case::None => {}
        Case::Constant | Case::RadarReference | Case::RadarAlone => {
            let t = SensorBias::typical(MeasKind::RangeBearing);
            let std = |p: Option<BiasPrior>| p.map_or(1.0, |p| p.std);
            truth[2] = vec![
                with(Term::Offset(0), constant(c_r, std(t.offset[0]))),
                with(Term::Offset(1), constant(c_a, std(t.offset[1]))),
                with(Term::Scale(0), constant(c_s, std(t.scale[0]))),
            ];
        }
        Case::GaussMarkov => {
            truth[2] = vec![
                (
                    Term::Offset(0),
                    BiasPrior::gauss_markov(draws.gm_std[0], draws.gm_tau),
                    draws.gm_start[0],
                ),
                (
                    Term::Offset(1),
                    BiasPrior::gauss_markov(draws.gm_std[1], draws.gm_tau),
                    draws.gm_start[1],
                ),
            ];
        }
        Case::Mounting => {
            let std = 1f64.to_radians();
            let s = draws.mount_signs;
            truth[0] = vec![
                with(Term::Offset(0), constant(s[0] * MOUNTING, std)),
                with(Term::Offset(1), constant(s[1] * MOUNTING, std)),
            ];
            truth[1] = vec![
                with(Term::Offset(0), constant(s[2] * MOUNTING, std)),
                with(Term::Offset(1), constant(s[3] * MOUNTING, std)),
            ];
        }
        Case::TimeOffset => {
            truth[0] = vec![with(Term::TimeOffset, constant(LATENCY, 0.3))];
        }
    }

    let prior_noise: [f64; 4] = std::array::from_fn(|_| normal(&mut rng));
    let mut meas = String::new();
    let mut refs = String::new();
    let mut truth_csv = String::from("t,x,y,z,vx,vy,vz,mode\n");
    let mut bias_csv = String::from("t,sensor,term,value\n");
    let told_bias = cfg.variant == Variant::ToldBias;
    let ticks = cfg.duration.floor() as usize * CAMERA_RATE;
    let radar = Vector3::from(RADAR_POS);
    for k in 0..=ticks {
        let t = k as f64 / CAMERA_RATE as f64;
        let radar_scan = k % CAMERA_RATE == 0;
        // Every draw of the scan, whatever the case uses.
        let noise: [[f64; 2]; 3] = std::array::from_fn(|_| [normal(&mut rng), normal(&mut rng)]);
        let painted = rng.random_bool(REFERENCE_PD);
        let ref_noise = [normal(&mut rng), normal(&mut rng)];
        let gps: [f64; 6] = std::array::from_fn(|_| normal(&mut rng));
        let gm_step = [normal(&mut rng), normal(&mut rng)];

        let x = drive.at(t);
        let _ = writeln!(
            truth_csv,
            "{t},{:.6},{:.6},0,{:.6},{:.6},0,{}",
            x[0],
            x[1],
            x[2],
            x[3],
            drive.mode(t)
        );
        if !told_bias {
            for (s, terms) in SENSORS.iter().zip(&truth) {
                for (term, _, v) in terms {
                    let _ = writeln!(bias_csv, "{t},{},{},{v}", s.0, term.name());
                }
            }
        }
        let blind = outages.iter().any(|&(a, b)| t >= a && t < b);
        for (i, (id, _, kind, std)) in SENSORS.iter().enumerate() {
            let camera = i < 2;
            if (camera && (!case.cameras() || blind)) || (!camera && !radar_scan) {
                continue;
            }
            let bias = if told_bias { &[][..] } else { &truth[i][..] };
            let delta = value(bias, Term::TimeOffset);
            let (pos, vel) = if camera {
                orbits[i].at(&drive, t)
            } else {
                (radar, Vector3::zeros())
            };
            let (then, _) = if camera {
                orbits[i].at(&drive, t - delta)
            } else {
                (radar, Vector3::zeros())
            };
            let seen = drive.at(t - delta);
            let z = measure(
                *kind,
                &then,
                &Vector3::new(seen[0], seen[1], 0.0),
                bias,
                std,
                &noise[i],
            )?;
            line(&mut meas, t, id, *kind, &pos, &vel, &z, None);
        }
        if case == Case::RadarReference && !told_bias && painted && radar_scan {
            let (pos, vel) = orbits[0].at(&drive, t);
            let z = measure(
                MeasKind::RangeBearing,
                &radar,
                &pos,
                &truth[2],
                &RADAR_STD,
                &ref_noise,
            )?;
            let reported = Vector3::new(
                pos.x + GPS_STD[0] * gps[0],
                pos.y + GPS_STD[1] * gps[1],
                pos.z + GPS_STD[2] * gps[2],
            );
            let rvel = vel + Vector3::new(gps[3], gps[4], gps[5]) * GPS_VEL_STD;
            let object = format!(
                r#","object":{{"id":"uav1","pos":[{:.4},{:.4},{:.4}],"vel":[{:.4},{:.4},{:.4}],"std":[{},{},{}]}}"#,
                reported.x,
                reported.y,
                reported.z,
                rvel.x,
                rvel.y,
                rvel.z,
                GPS_STD[0],
                GPS_STD[1],
                GPS_STD[2]
            );
            line(
                &mut refs,
                t,
                "radar1",
                MeasKind::RangeBearing,
                &radar,
                &Vector3::zeros(),
                &z,
                Some(&object),
            );
        }
        // Gauss–Markov terms move on to the next scan: b − μ ← φ (b − μ) + σ √(1 − φ²) n.
        for terms in &mut truth {
            for (term, prior, v) in terms.iter_mut() {
                if let super::Dynamics::GaussMarkov { tau } = prior.dynamics {
                    let phi = (-1.0 / (CAMERA_RATE as f64 * tau)).exp();
                    let n = if *term == Term::Offset(0) {
                        gm_step[0]
                    } else {
                        gm_step[1]
                    };
                    *v = prior.mean
                        + phi * (*v - prior.mean)
                        + prior.std * (1.0 - phi * phi).sqrt() * n;
                }
            }
        }
    }

    let x0 = drive.at(0.0);
    let prior_mean: [f64; 4] = std::array::from_fn(|i| x0[i] + PRIOR_STD[i] * prior_noise[i]);
    let scenario = scenario(seed, cfg, &truth_models(&truth), prior_mean)?;
    let generator = fmt::Generator {
        family: "harrier-registration".into(),
        seed,
        params: serde_json::json!({
            "case": case.name(), "variant": cfg.variant.name(), "duration": cfg.duration,
            "outages": outages, "radar": RADAR_POS, "orbit": ORBIT,
            "wind": [wind.x, wind.y],
            "constant": draws.constant, "gm_std": draws.gm_std, "gm_tau": draws.gm_tau,
        }),
    };
    let scenario_json = fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(None),
        extensions: serde_json::Map::new(),
        generator,
    }
    .to_json()
    .map_err(|e| EstimationError::InvalidParameter(format!("scenario.json: {e}")))?;
    Ok(Generated {
        scenario_json,
        measurements_jsonl: meas,
        truth_csv,
        references_jsonl: refs,
        bias_truth_csv: bias_csv,
        outages,
    })
}

fn with(term: Term, (prior, v): (BiasPrior, f64)) -> (Term, BiasPrior, f64) {
    (term, prior, v)
}

fn value(bias: &[(Term, BiasPrior, f64)], term: Term) -> f64 {
    bias.iter()
        .find(|(t, _, _)| *t == term)
        .map_or(0.0, |b| b.2)
}

/// The true model of each sensor (what [`Variant::ToldModel`] tells), `None` when unbiased.
fn truth_models(truth: &Truth) -> [Option<SensorBias>; 3] {
    std::array::from_fn(|i| {
        let terms = &truth[i];
        if terms.is_empty() {
            return None;
        }
        let mut b = SensorBias::default();
        for (term, prior, _) in terms {
            match *term {
                Term::Offset(c) => {
                    b.offset.resize(b.offset.len().max(c + 1), None);
                    b.offset[c] = Some(*prior);
                }
                Term::Scale(c) => {
                    b.scale.resize(b.scale.len().max(c + 1), None);
                    b.scale[c] = Some(*prior);
                }
                Term::TimeOffset => b.time_offset = Some(*prior),
            }
        }
        Some(b)
    })
}

/// `(1 + s) h(target − sensor) + o + σ n`, azimuth wrapped, seen from `sensor` (the geometry of
/// the moment the measurement was taken).
fn measure(
    kind: MeasKind,
    sensor: &Vector3<f64>,
    target: &Vector3<f64>,
    bias: &[(Term, BiasPrior, f64)],
    std: &[f64; 2],
    noise: &[f64; 2],
) -> Result<Vector2<f64>> {
    let model = SensorModel::new(kind, Geometry::spatial(), *sensor, std, None)
        .map_err(EstimationError::InvalidParameter)?;
    let x6 = nalgebra::Vector6::new(target.x, target.y, target.z, 0.0, 0.0, 0.0);
    let h: Vector2<f64> = match model {
        SensorModel::RangeBearing(m) => m.function(&x6),
        SensorModel::AzEl(m) => m.function(&x6),
        _ => return Err(EstimationError::InvalidParameter(format!("{kind:?}"))),
    };
    let mut z = Vector2::zeros();
    for i in 0..2 {
        z[i] = (1.0 + value(bias, Term::Scale(i))) * h[i]
            + value(bias, Term::Offset(i))
            + std[i] * noise[i];
    }
    let az = kind.azimuth_index().unwrap_or(0);
    z[az] = crate::linalg::wrap_angle(z[az]);
    Ok(z)
}

/// Appends one measurement (or reference) line.
#[allow(clippy::too_many_arguments)]
fn line(
    out: &mut String,
    t: f64,
    sensor: &str,
    kind: MeasKind,
    pos: &Vector3<f64>,
    vel: &Vector3<f64>,
    z: &Vector2<f64>,
    object: Option<&str>,
) {
    let _ = writeln!(
        out,
        r#"{{"t":{t},"sensor":"{sensor}","kind":"{}","platform":{{"pos":[{:.4},{:.4},{:.4}],"vel":[{:.4},{:.4},{:.4}]}},"z":[{:.9},{:.9}]{}}}"#,
        kind.as_str(),
        pos.x,
        pos.y,
        pos.z,
        vel.x,
        vel.y,
        vel.z,
        z[0],
        z[1],
        object.unwrap_or("")
    );
}

/// `scenario.json` of a case and variant.
fn scenario(
    seed: u64,
    cfg: &GenConfig,
    models: &[Option<SensorBias>; 3],
    prior_mean: [f64; 4],
) -> Result<fmt::Scenario> {
    let cameras = cfg.case.cameras();
    let sensors = SENSORS
        .iter()
        .zip(models)
        .filter(|((id, ..), _)| cameras || *id == "radar1")
        .map(|((id, platform, kind, std), truth)| {
            let rate = if *kind == MeasKind::AzEl {
                CAMERA_RATE
            } else {
                1
            };
            let bias = match cfg.variant {
                Variant::Deployment => Some(SensorBias::typical(*kind)),
                Variant::ToldModel => truth.clone(),
                Variant::ToldBias => None,
            };
            fmt::Sensor {
                id: (*id).into(),
                platform: (*platform).into(),
                kind: *kind,
                ncomp: None,
                rate_hz: Some(rate as f64),
                noise: fmt::Noise::Gaussian { std: std.to_vec() },
                bias: bias.map(|b| b.to_block()),
            }
        })
        .collect();
    let platform = |id: &str, kind: &str| fmt::Platform {
        id: id.into(),
        kind: kind.into(),
    };
    let var: Vec<Vec<f64>> = (0..4)
        .map(|i| {
            (0..4)
                .map(|j| if i == j { PRIOR_STD[i].powi(2) } else { 0.0 })
                .collect()
        })
        .collect();
    let [x, y, vx, vy] = prior_mean;
    Ok(fmt::Scenario {
        format: fmt::FORMAT_ID.into(),
        name: format!(
            "registration_{}_{}_{seed}",
            cfg.case.name(),
            cfg.variant.name()
        ),
        description: "A ground target seen by a biased ground radar and two UAVs' cameras on a \
                      standoff orbit, with camera outages (FORMAT-REGISTRATION.md §5)."
            .into(),
        dims: 2,
        plane_z: Some(0.0),
        time: fmt::TimeSpec {
            t0: 0.0,
            dt: 1.0 / CAMERA_RATE as f64,
            t_end: cfg.duration.floor(),
        },
        target: fmt::Target {
            id: "tgt".into(),
            size_m: None,
            size_prior: None,
            on_ground: Some(true),
        },
        platforms: vec![
            platform("site", "ground"),
            platform("uav1", "uav"),
            platform("uav2", "uav"),
        ],
        sensors,
        roads: Vec::new(),
        detection: None,
        motion: Some(fmt::Motion::cv(ACCEL_STD)),
        prior: Some(fmt::Prior {
            t: 0.0,
            state: [x, y, 0.0, vx, vy, 0.0],
            cov: var,
            cov_dims: Some(vec![0, 1, 3, 4]),
        }),
        linear_system: None,
        hints: serde_json::Value::Object(serde_json::Map::new()),
        scoring: fmt::Scoring {
            t_start: 10.0,
            primary: "state".into(),
        },
    })
}
