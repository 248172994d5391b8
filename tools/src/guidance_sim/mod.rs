//! `harrier guidance-sim`: closed-loop guidance scenarios.
//!
//! A scenario is target motion ([`truth`]), N UAVs ([`harrier_core::guidance::kinematics`]), a
//! guidance law and optionally an estimator fed with simulated measurements (seeded `ChaCha8Rng`).
//! The run records every vehicle's [`Trajectory`], computes the figures of GUIDANCE.md
//! (`figures`), and can write the trajectories as CSV or JSONL and the summary (`output`) and
//! an SVG picture (`plot`).
//!
//! Built-in cases ([`Case`]):
//!
//! | name | what |
//! |---|---|
//! | `cimm-static` | \[CIMM\] §5.2: static target at (1500, 1800, 0) m, UAV from (1100, 1000, 400) m, R = H = 300 m |
//! | `cimm-moving` | \[CIMM\] §5.1 target (10 m/s, right turn 0.008 rad/s at 140 s, left turn 0.01 rad/s at 360 s; the road of `cimm_road_1uav`), UAV from (−500, −500, 400) m |
//! | `three-static` | three UAVs, phase-coordinated, on the static target of `cimm-static` |
//! | `three-moving` | three UAVs on the moving target of `cimm-moving` |
//! | `bot-formation` | \[BOT\] §IV Fig. 8: leader + 3 followers regulating LOS ranges, four obstacles |
//! | `bot-observability` | \[BOT\] §II.B: one bearings-only follower, straight following vs. the eq. (4) maneuver |
//!
//! **Estimators.** Every estimator in the loop comes from the registry
//! ([`harrier_engine::registry::build`]) and runs on measurement lines of a small simulated scenario
//! ([`estimate`]): the moving cases use `cimm` by default (the road-constrained IMM of \[CIMM\]
//! §3.2) on camera geolocation fixes, σ = 10 m, 1 Hz per UAV, every UAV's fix applied
//! sequentially; `--estimator kf` is the comparison, `--estimator truth` feeds the truth, and any
//! other registry estimator that takes position fixes can be named. The guidance sees the estimate
//! extrapolated to the current time, never the truth. The observability case tracks the leader
//! with `ekf` on an `az_el` camera, σ = 1°, 10 Hz.

mod cases;
mod error;
pub mod estimate;
mod figures;
mod formation;
mod observability;
mod output;
mod plot;
mod standoff;
pub mod truth;
mod types;

pub use cases::{Case, H, R, STATIC_START, STATIC_TARGET, V0, formation_obstacles};
pub use error::SimError;
pub use output::{summary_lines, write_trajectories};
pub use plot::plot_svg;
pub use types::{
    LawKind, LimitsOut, Sample, SimConfig, SimResult, Summary, Trajectory, UavFigures,
};

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
            standoff::run(cfg, duration)
        }
        Case::BotFormation => Ok(formation::run(cfg, duration)),
        Case::BotObservability => observability::run(cfg, duration),
    }
}
