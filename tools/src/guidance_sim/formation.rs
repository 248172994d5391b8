//! The \[BOT\] formation case: a leader and three followers regulating their LOS ranges (eqs. (5)–(6))
//! while avoiding four obstacles.

use std::time::Instant;

use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::obstacle::{Avoidance, avoid};
use harrier_core::guidance::{Command, Limits, UavState};
use nalgebra::{Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::cases::{SHAPE, formation_obstacles};
use super::figures::base_summary;
use super::truth::{LEADER_SPEED, leader_heading};
use super::types::{SimConfig, SimResult, Trajectory};

pub(super) fn run(cfg: &SimConfig, duration: f64) -> SimResult {
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
    let mut paths: Vec<Trajectory> = (0..n)
        .map(|i| {
            Trajectory::new(
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
            paths[i].push(t, u.position, u.velocity);
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
    let mut summary = base_summary(cfg, duration, n, elapsed_ms, &paths, limits);
    summary.law = "bot-formation (eqs. (5)-(6)) + silhouette-edge avoidance";
    summary.estimator = "measured ranges (subtended angle)".to_string();
    summary.formation_steady_error_pct = Some(steady_err);
    summary.formation_max_error_pct = Some(max_err);
    summary.obstacle_penetrations = Some(penetrations);
    summary.obstacle_min_clearance_m = Some(min_clear);
    SimResult {
        summary,
        trajectories: paths,
        obstacles,
        circle: None,
    }
}
