//! The \[BOT\] range-observability case: one bearings-only follower regulating its range to the
//! leader on the *estimated* range and LOS, straight following against the eq. (4) maneuver. The
//! leader is tracked by the registry's `ekf` on the follower's `az_el` camera (the leader flies
//! level with the follower, so the elevation is 0 and only the azimuth informs).

use std::time::Instant;

use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::observability::ObservabilityManeuver;
use harrier_core::guidance::{Command, Limits, UavState};
use harrier_core::linalg::wrap_angle;
use harrier_core::measurement::MeasKind;
use harrier_core::scenario::{Measurement, PlatformPose};
use nalgebra::{Vector2, Vector3, Vector4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::error::SimError;
use super::estimate::{self, SimEstimator};
use super::figures::base_summary;
use super::truth::LEADER_SPEED;
use super::types::{SimConfig, SimResult, Trajectory};
use harrier_engine::Params;

/// Altitude of the leader and the follower (m).
const ALTITUDE: f64 = 100.0;
/// Bearing noise std (rad): 1°.
fn sigma() -> f64 {
    1f64.to_radians()
}
/// Acceleration spectral density of the EKF's CV model (m²/s³).
const Q: f64 = 0.01;

fn limits() -> Limits {
    Limits {
        v_max: 30.0,
        ..Limits::fixed_wing()
    }
}

/// One leader + one bearings-only follower; returns the trajectories and the range-estimate RMS
/// over the second half.
fn fly(
    cfg: &SimConfig,
    duration: f64,
    maneuver: Option<ObservabilityManeuver>,
) -> Result<(Vec<Trajectory>, f64), SimError> {
    let limits = limits();
    let reg = RangeRegulator::default();
    let r_cmd = 150.0;
    let sigma = sigma();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noise = Normal::new(0.0, sigma).ok();
    let mut leader = UavState::new(
        Vector3::new(0.0, 0.0, ALTITUDE),
        Vector3::new(0.0, LEADER_SPEED, 0.0),
    );
    let mut follower = UavState::new(
        Vector3::new(-90.0, -120.0, ALTITUDE),
        Vector3::new(0.0, LEADER_SPEED, 0.0),
    );
    let mut est = SimEstimator::new(
        "ekf",
        estimate::bearing_scenario(ALTITUDE, sigma)?,
        Params::default().with("q", Q),
    )?;
    // Prior: bearing known, range guessed 300 m (true 150 m), velocity unknown (σ 10 m/s).
    let b0 =
        (leader.position.x - follower.position.x).atan2(leader.position.y - follower.position.y);
    let guess = follower.horizontal_position() + Vector2::new(b0.sin(), b0.cos()) * 300.0;
    est.start(
        0.0,
        Vector4::new(guess.x, guess.y, 0.0, LEADER_SPEED),
        Vector4::new(150.0f64.powi(2), 150.0f64.powi(2), 100.0, 100.0),
    )?;
    let mut pair = PairState::start(300.0);
    let mut paths = vec![
        Trajectory::new("leader", "uav"),
        Trajectory::new("follower", "uav"),
        Trajectory::new("estimate", "estimate"),
    ];
    let steps = (duration / cfg.dt).round() as usize;
    let (mut sum, mut cnt) = (0.0, 0usize);
    for k in 0..=steps {
        let t = k as f64 * cfg.dt;
        let x = est.latest().map_or_else(Vector4::zeros, |(_, x)| x);
        paths[0].push(t, leader.position, leader.velocity);
        paths[1].push(t, follower.position, follower.velocity);
        paths[2].push(
            t,
            Vector3::new(x[0], x[1], ALTITUDE),
            Vector3::new(x[2], x[3], 0.0),
        );
        let rel_true = (leader.position - follower.position).xy();
        let rel_est = Vector2::new(x[0], x[1]) - follower.horizontal_position();
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
        // Bearing (and the level elevation) of the leader from the follower.
        let d = leader.position - follower.position;
        let az = d.x.atan2(d.y) + noise.map_or(0.0, |nd| nd.sample(&mut rng));
        let el = d.z.atan2(d.xy().norm());
        let tm = (k + 1) as f64 * cfg.dt;
        let line = Measurement {
            t: tm,
            sensor: "eo".into(),
            kind: MeasKind::AzEl,
            platform: PlatformPose {
                pos: follower.position.into(),
                vel: follower.velocity.into(),
            },
            z: vec![wrap_angle(az), el],
        };
        est.step(tm, std::slice::from_ref(&line))?;
    }
    Ok((paths, (sum / cnt.max(1) as f64).sqrt()))
}

pub(super) fn run(cfg: &SimConfig, duration: f64) -> Result<SimResult, SimError> {
    let started = Instant::now();
    // K₁ K₂ = 1 → ω = √K₁ = 0.1 rad/s (period ≈ 63 s); bearing amplitude 15°.
    let maneuver = ObservabilityManeuver::from_weights(0.01, 100.0, 15f64.to_radians());
    let (_, straight) = fly(cfg, duration, None)?;
    let (paths, with) = fly(cfg, duration, maneuver)?;
    let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut summary = base_summary(cfg, duration, 2, elapsed_ms, &paths, limits());
    summary.law = "bot-formation + observability maneuver (eq. (4), ω = 0.1 rad/s, B = 15°)";
    summary.estimator = "ekf (az_el camera on the follower, σ = 1°, 10 Hz)".to_string();
    summary.range_rms_straight_m = Some(straight);
    summary.range_rms_maneuver_m = Some(with);
    summary.observability_factor = (with > 0.0).then(|| straight / with);
    Ok(SimResult {
        summary,
        trajectories: paths,
        obstacles: Vec::new(),
        circle: None,
    })
}
