//! The \[BOT\] formation (§III): the track leads, the vehicles hold the line-of-sight ranges of
//! a shape with the range regulators of eqs. (5)–(6), steered around obstacles (§III.B). Pure:
//! the actor calls [`formation_commands`] each tick with the measured vehicle states.

use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::obstacle::{Avoidance, Obstacle, avoid};
use harrier_core::guidance::togvf::Togvf;
use harrier_core::guidance::{Command, Limits, TargetEstimate, UavState};
use nalgebra::Vector2;

use super::plan::Plan;

/// Look-ahead and margin of the formation's obstacle avoidance (\[BOT\] §III.B), scaled to
/// multirotor speeds.
const AVOIDANCE: Avoidance = Avoidance {
    lookahead: 120.0,
    margin: 15.0,
};

/// The \[BOT\] range regulators of a formation: one per ordered pair of members (0 = the leader).
#[derive(Debug, Default)]
pub(super) struct FormationState {
    pairs: Vec<Vec<PairState>>,
    last_t: Option<f64>,
}

/// Desired LOS range between members `i` and `j` of the shape: the leader (0) at the centre,
/// follower `k` at `R (cos((k−1)Δ), sin((k−1)Δ))`.
fn shape_range(i: usize, j: usize, radius: f64, spacing: f64) -> f64 {
    let at = |k: usize| {
        if k == 0 {
            Vector2::zeros()
        } else {
            let a = (k - 1) as f64 * spacing;
            Vector2::new(a.cos(), a.sin()) * radius
        }
    };
    (at(i) - at(j)).norm()
}

impl FormationState {
    /// The formation's commands at tracker time `t`, one per vehicle (`None` without
    /// telemetry): \[BOT\] eq. (6), the vector sum of eq. (5)'s pseudo-controls along every
    /// line of sight to the leader (the track estimate) and to the other vehicles, then
    /// §III.B's silhouette-edge avoidance (a regulator is hedged, not advanced, while its
    /// vehicle avoids); vertically \[CIMM\] §4.1's climb to H above the target. The shape is
    /// `plan`'s: followers at R, `spacing` apart around the leader.
    pub(super) fn commands(
        &mut self,
        states: &[Option<UavState>],
        target: &TargetEstimate,
        plan: &Plan,
        t: f64,
        limits: &Limits,
        obstacles: &[Obstacle],
    ) -> Vec<Option<Command>> {
        let f = self;
        let (radius, height, spacing) = (plan.radius, plan.height, plan.spacing_of(states.len()));
        let reg = RangeRegulator::default();
        let n = states.len() + 1;
        let pos = |j: usize| {
            if j == 0 {
                Some(target.position.xy())
            } else {
                states[j - 1].as_ref().map(UavState::horizontal_position)
            }
        };
        if f.pairs.len() != n {
            f.pairs = (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| {
                            let r = match (pos(i), pos(j)) {
                                (Some(a), Some(b)) => (a - b).norm(),
                                _ => shape_range(i, j, radius, spacing),
                            };
                            PairState::start(r)
                        })
                        .collect()
                })
                .collect();
        }
        let dt = f.last_t.map_or(0.0, |last| (t - last).clamp(0.0, 1.0));
        f.last_t = Some(t);
        (1..n)
            .map(|k| {
                let u = states[k - 1].as_ref()?;
                let p = u.horizontal_position();
                let lines: Vec<(usize, Vector2<f64>, f64)> = (0..n)
                    .filter(|&j| j != k)
                    .filter_map(|j| {
                        let rel = pos(j)? - p;
                        let r = rel.norm();
                        Some((j, rel / r.max(1e-9), r))
                    })
                    .collect();
                // Eq. (6) with û along the line of sight to the neighbour, as in `guidance-sim`.
                let desired = vector_sum(lines.iter().map(|&(j, los, r)| {
                    (
                        los,
                        reg.pseudo_control(&f.pairs[k][j], r, shape_range(k, j, radius, spacing)),
                    )
                }));
                let (vh, avoiding) =
                    avoid(p, u.horizontal_velocity(), desired, obstacles, &AVOIDANCE);
                for &(j, _, r) in &lines {
                    let r_com = shape_range(k, j, radius, spacing);
                    f.pairs[k][j] = if avoiding {
                        reg.hedge(&f.pairs[k][j], r)
                    } else {
                        reg.advance(&f.pairs[k][j], r, r_com, dt)
                    };
                }
                let vz = Togvf::vertical_speed(u.position.z - target.position.z - height, limits);
                Some(Command::new(vh, vz).or_hold(u, limits))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    /// A follower south of the leader closes in along the line of sight; with an obstacle on that
    /// line it is steered around it (§III.B), and its regulators are hedged meanwhile.
    #[test]
    fn the_formation_closes_in_and_steers_around_an_obstacle() {
        let limits = Limits::multirotor();
        let target = TargetEstimate::fixed(Vector3::zeros());
        let uav = UavState::new(Vector3::new(0.0, -300.0, 60.0), Vector3::new(0.0, 5.0, 0.0));
        let plan = Plan {
            radius: 80.0,
            height: 60.0,
            spacing: Some(std::f64::consts::TAU),
            speed: 10.0,
            orbit: crate::guidance::OrbitDirection::Ccw,
            law: crate::guidance::Law::Formation,
        };
        let run = |obstacles: &[Obstacle]| {
            let mut f = FormationState::default();
            let mut cmd = None;
            for k in 0..5 {
                cmd = f.commands(
                    &[Some(uav)],
                    &target,
                    &plan,
                    f64::from(k) * 0.1,
                    &limits,
                    obstacles,
                )[0];
            }
            cmd.expect("a command").velocity
        };
        let free = run(&[]);
        assert!(free.y > 1.0 && free.x.abs() < 1e-6, "{free:?}");
        let blocked = run(&[Obstacle {
            center: Vector2::new(0.0, -220.0),
            radius: 20.0,
        }]);
        assert!(blocked.x.abs() > 0.5, "{blocked:?}");
        // Three followers 120° apart on R = 80 m: √3 R from each other, R from the leader.
        let third = std::f64::consts::TAU / 3.0;
        assert!((shape_range(1, 2, 80.0, third) - 80.0 * 3f64.sqrt()).abs() < 1e-9);
        assert!((shape_range(3, 0, 80.0, third) - 80.0).abs() < 1e-9);
    }
}
