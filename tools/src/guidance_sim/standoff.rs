//! The standoff cases: one or three UAVs on a circle of radius R at height H over a static or
//! moving target, guided by TOGVF or LGVF on the truth or on a registry estimator's estimate.

use std::time::Instant;

use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::phase::{PhaseNeighbours, phase_of};
use harrier_core::guidance::togvf::{Togvf, optimal_entry_length};
use harrier_core::guidance::{Limits, Orbit, StandoffLaw, TargetEstimate, UavState};
use harrier_core::measurement::MeasKind;
use harrier_core::scenario::{Measurement, PlatformPose};
use nalgebra::{Vector2, Vector3, Vector4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::cases::{Case, H, R, STATIC_TARGET, V0};
use super::error::SimError;
use super::estimate::{self, FIX_PERIOD, FIX_STD, SimEstimator};
use super::figures::{base_summary, phase_figures, standoff_figures};
use super::truth::road_target;
use super::types::{LawKind, SimConfig, SimResult, Trajectory};

pub(super) fn run(cfg: &SimConfig, duration: f64) -> Result<SimResult, SimError> {
    let moving = cfg.case.moving();
    let starts = cfg.case.standoff_starts();
    let n = starts.len();
    let name = cfg
        .estimator
        .as_deref()
        .unwrap_or(if moving { "cimm" } else { "truth" });
    // What the guidance sees of the target: the truth, or this estimator's estimate.
    let mut estimator = match name {
        "truth" => None,
        _ => Some(SimEstimator::new(
            name,
            estimate::camera_scenario(n)?,
            estimate::standoff_params(name),
        )?),
    };
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
    let mut paths: Vec<Trajectory> = (0..n)
        .map(|i| Trajectory::new(format!("uav{}", i + 1), "uav"))
        .collect();
    let mut target_path = Trajectory::new("target", "target");
    let mut est_path = Trajectory::new("estimate", "estimate");

    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noise = Normal::new(0.0, FIX_STD).ok();
    let mut next_fix = 0.0;
    let mut est_err2 = (0.0, 0usize);

    let steps = (duration / cfg.dt).round() as usize;
    let started = Instant::now();
    let mut phases = vec![0.0; n];
    let mut order: Vec<usize> = (0..n).collect();
    let mut ring = vec![0.0; n];
    for k in 0..=steps {
        let t = k as f64 * cfg.dt;
        let (pt, vt) = truth(t);
        let estimate = match &mut estimator {
            None => Some(TargetEstimate {
                position: pt,
                velocity: vt,
            }),
            Some(est) => {
                // Camera geolocation, one fix per UAV every FIX_PERIOD.
                if t + 1e-9 >= next_fix {
                    next_fix += FIX_PERIOD;
                    let fixes: Vec<Measurement> = uavs
                        .iter()
                        .enumerate()
                        .map(|(i, u)| {
                            let z = match noise {
                                Some(nd) => {
                                    vec![pt.x + nd.sample(&mut rng), pt.y + nd.sample(&mut rng)]
                                }
                                None => vec![pt.x, pt.y],
                            };
                            Measurement {
                                t,
                                sensor: estimate::camera(i),
                                kind: MeasKind::Position,
                                platform: PlatformPose {
                                    pos: u.position.into(),
                                    vel: u.velocity.into(),
                                },
                                z,
                            }
                        })
                        .collect();
                    // The first fix starts the estimator, the others update it.
                    let rest = match fixes.split_first() {
                        Some((first, rest)) if !est.is_started() => {
                            let var = FIX_STD * FIX_STD;
                            est.start(
                                t,
                                Vector4::new(first.z[0], first.z[1], 0.0, 0.0),
                                Vector4::repeat(var),
                            )?;
                            rest
                        }
                        _ => &fixes[..],
                    };
                    est.step(t, rest)?;
                }
                est.latest().map(|(tk, x)| {
                    let dt = t - tk;
                    TargetEstimate {
                        position: Vector3::new(x[0] + x[2] * dt, x[1] + x[3] * dt, 0.0),
                        velocity: Vector3::new(x[2], x[3], 0.0),
                    }
                })
            }
        };
        if let Some(e) = &estimate {
            est_path.push(t, e.position, e.velocity);
            est_err2.0 += (e.position - pt).xy().norm_squared();
            est_err2.1 += 1;
        }
        target_path.push(t, pt, vt);
        for (i, u) in uavs.iter().enumerate() {
            paths[i].push(t, u.position, u.velocity);
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
        for (slot, &i) in order.iter().enumerate() {
            ring[slot] = phases[i];
        }
        let mut next = uavs.clone();
        for (slot, &i) in order.iter().enumerate() {
            let nb = PhaseNeighbours::ring(&ring, slot);
            let cmd = law.command(&uavs[i], estimate.as_ref(), &limits, nb.as_ref());
            next[i] = step(&uavs[i], &cmd, &limits, cfg.dt);
        }
        uavs = next;
    }
    let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;

    // Figures (truth-based).
    let per_uav = paths
        .iter()
        .map(|p| standoff_figures(p, &target_path, &limits))
        .collect();
    let optimal_path_m = (cfg.case == Case::CimmStatic).then(|| {
        let u0 = &paths[0].samples[0];
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
        let (m, r) = phase_figures(&paths, &target_path, 0.7);
        (Some(m), Some(r))
    } else {
        (None, None)
    };
    let last = target_path
        .samples
        .last()
        .map(|s| Vector2::new(s.pos[0], s.pos[1]));
    let estimated = estimator.is_some();
    let mut all = paths;
    all.push(target_path);
    if estimated {
        all.push(est_path);
    }
    let mut summary = base_summary(cfg, duration, n, elapsed_ms, &all, limits);
    summary.law = cfg.law.name();
    summary.estimator = if estimated {
        let tuning = if name.starts_with("cimm") {
            "CV / CT −0.008 / CT +0.01 rad/s, road σ_m = 2 m, "
        } else if estimate::standoff_params(name).opt("q").is_some() {
            "CV, "
        } else {
            "CV / CT −0.008 / CT +0.01 rad/s, "
        };
        format!(
            "{name} ({tuning}camera position σ = {FIX_STD} m, {} Hz per UAV)",
            1.0 / FIX_PERIOD
        )
    } else {
        "truth".to_string()
    };
    summary.radius_m = Some(R);
    summary.height_m = Some(H);
    summary.per_uav = per_uav;
    summary.optimal_path_m = optimal_path_m.filter(|v| v.is_finite());
    summary.estimate_rms_m =
        (estimated && est_err2.1 > 0).then(|| (est_err2.0 / est_err2.1 as f64).sqrt());
    summary.phase_max_error_deg = phase_max;
    summary.phase_rms_error_deg = phase_rms;
    Ok(SimResult {
        summary,
        trajectories: all,
        obstacles: Vec::new(),
        circle: last.map(|c| (c, R)),
    })
}
