//! The figures of GUIDANCE.md computed from the recorded trajectories (truth-based).

use harrier_core::guidance::Limits;
use harrier_core::guidance::phase::{phase_of, spacing_errors};
use nalgebra::Vector2;

use super::cases::{H, R};
use super::types::{SimConfig, Summary, Trajectory, UavFigures};

/// Truth-based figures of one UAV's standoff run.
pub(super) fn standoff_figures(
    tr: &Trajectory,
    target: &Trajectory,
    limits: &Limits,
) -> UavFigures {
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
pub(super) fn phase_figures(paths: &[Trajectory], target: &Trajectory, from: f64) -> (f64, f64) {
    let t_end = target.samples.last().map_or(0.0, |s| s.t);
    let mut max: f64 = 0.0;
    let (mut sum, mut cnt) = (0.0, 0usize);
    let mut phases = Vec::with_capacity(paths.len());
    for (k, g) in target.samples.iter().enumerate() {
        if g.t < from * t_end {
            continue;
        }
        phases.clear();
        phases.extend(paths.iter().map(|tr| {
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

/// The figures every case has (flown speeds, turn rates, vertical speed and acceleration), the
/// case-specific ones empty.
pub(super) fn base_summary(
    cfg: &SimConfig,
    duration: f64,
    n: usize,
    elapsed_ms: f64,
    paths: &[Trajectory],
    limits: Limits,
) -> Summary {
    let (mut max_speed, mut min_speed, mut max_turn, mut max_vz, mut max_az) =
        (0.0f64, f64::INFINITY, 0.0f64, 0.0f64, 0.0f64);
    for tr in paths.iter().filter(|t| t.kind == "uav") {
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
        estimator: "truth".to_string(),
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
