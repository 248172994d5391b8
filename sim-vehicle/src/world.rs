//! The simulated world: targets moving in closed form (roads, CV/CT segments) or by a
//! fixed-step integration on a fixed time grid (the \[BOT\] leader), so the state at a time never
//! depends on how often [`World::advance`] was called. Seeded (ChaCha8) perturbations of the
//! initial conditions and of the lateral wander on a road make a seed reproduce a world exactly.

use std::f64::consts::TAU;

use harrier_core::detection::TargetTruth;
use harrier_core::motion::{ConstantTurn, TransitionModel};
use harrier_core::road::{Road, RoadSegment};
use nalgebra::{Vector2, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::setup::{MotionSegment, ScenarioError, SimScenario, Source, TargetMotion};

/// ChaCha stream of the world's random draws (sensors use others, see [`crate::sensors`]).
pub(crate) const WORLD_STREAM: u64 = 0;

/// Step of the leader's heading integration (s).
const LEADER_STEP: f64 = 0.01;
/// Periods of the two sinusoids of a road target's lateral wander (s).
const WANDER_PERIODS: [f64; 2] = [47.0, 19.0];

/// One CV or CT piece of a [`TargetMotion::Segments`] trajectory, with its start state.
#[derive(Debug, Clone)]
struct Piece {
    t0: f64,
    /// Start state `[x, y, vx, vy]`.
    x0: Vector4<f64>,
    /// harrier-core's constant turn at the piece's rate (0: straight).
    motion: ConstantTurn<4>,
    mode: String,
}

impl Piece {
    /// Position and velocity `tau` seconds into the piece (exact CV / CT kinematics).
    fn at(&self, tau: f64) -> (Vector2<f64>, Vector2<f64>) {
        let x = self.motion.function(&self.x0, tau);
        (Vector2::new(x[0], x[1]), Vector2::new(x[2], x[3]))
    }
}

#[derive(Debug, Clone)]
enum Kind {
    Road {
        road: Road,
        length: f64,
        s0: f64,
        speed: f64,
        /// Lateral wander: amplitude per sinusoid (m) and phases.
        wander: f64,
        phases: [f64; 2],
    },
    Pieces(Vec<Piece>),
    Leader {
        p0: Vector2<f64>,
        speed: f64,
        chi0: f64,
        amp: f64,
        period: f64,
        /// Integration grid: position at `n · LEADER_STEP`.
        n: u64,
        p: Vector2<f64>,
    },
}

#[derive(Debug, Clone)]
struct Target {
    id: String,
    z: f64,
    kind: Kind,
}

/// All targets of a scenario at the current time.
#[derive(Debug, Clone)]
pub struct World {
    targets: Vec<Target>,
    t: f64,
}

/// Point, unit tangent and signed curvature of a road segment at arc length `s` (clamped).
fn segment_at(seg: &RoadSegment, s: f64) -> (Vector2<f64>, Vector2<f64>, f64) {
    match *seg {
        RoadSegment::Line { start, end } => {
            let t = (end - start) / (end - start).norm();
            (start + t * s, t, 0.0)
        }
        RoadSegment::Arc {
            center,
            radius,
            start_angle,
            sweep,
        } => {
            let sg = sweep.signum();
            let a = start_angle + sg * s / radius;
            let (sa, ca) = a.sin_cos();
            (
                center + Vector2::new(ca, sa) * radius,
                Vector2::new(-sa, ca) * sg,
                sg / radius,
            )
        }
    }
}

/// Point, tangent, curvature at arc length `s` along a road (clamped to its ends).
fn road_at(road: &Road, s: f64) -> (Vector2<f64>, Vector2<f64>, f64) {
    let segs = road.segments();
    let mut rest = s.max(0.0);
    for (k, seg) in segs.iter().enumerate() {
        let len = seg.length();
        if rest <= len || k + 1 == segs.len() {
            return segment_at(seg, rest.min(len));
        }
        rest -= len;
    }
    // `Road::new` refuses empty roads; an empty one would sit at the origin.
    (Vector2::zeros(), Vector2::new(1.0, 0.0), 0.0)
}

fn pieces(p0: Vector2<f64>, v0: Vector2<f64>, segments: &[MotionSegment]) -> Vec<Piece> {
    let piece = |t0, x0, omega, mode: &str| Piece {
        t0,
        x0,
        // Truth has no process noise.
        motion: ConstantTurn::new(omega, 0.0),
        mode: mode.to_owned(),
    };
    let mut out = Vec::with_capacity(segments.len() + 1);
    let (mut t0, mut x) = (0.0, Vector4::new(p0.x, p0.y, v0.x, v0.y));
    for s in segments {
        let pc = piece(t0, x, s.turn_rate, &s.mode);
        x = pc.motion.function(&x, s.duration_s);
        t0 += s.duration_s;
        out.push(pc);
    }
    // Straight on after the last segment.
    out.push(piece(t0, x, 0.0, "CV"));
    out
}

/// Leader velocity at time `t`: speed along heading `χ(t) = χ₀ + A sin(2π t / T)` clockwise from
/// North (\[BOT\] §IV).
fn leader_velocity(speed: f64, chi0: f64, amp: f64, period: f64, t: f64) -> Vector2<f64> {
    let chi = chi0 + amp * (TAU * t / period).sin();
    Vector2::new(chi.sin(), chi.cos()) * speed
}

/// Simpson's rule for the leader's displacement over `[a, b]` (exact to O(h⁵) per step).
fn leader_step(speed: f64, chi0: f64, amp: f64, period: f64, a: f64, b: f64) -> Vector2<f64> {
    let v = |t| leader_velocity(speed, chi0, amp, period, t);
    (v(a) + v(0.5 * (a + b)) * 4.0 + v(b)) * ((b - a) / 6.0)
}

impl World {
    /// The world of `scenario` at t = 0; `seed` draws the initial-condition jitter and the road
    /// wander phases.
    pub fn new(scenario: &SimScenario, seed: u64) -> Result<Self, ScenarioError> {
        scenario.validate(&Source::Named(scenario.name.clone()))?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(WORLD_STREAM);
        let mut targets = Vec::with_capacity(scenario.targets.len());
        for spec in &scenario.targets {
            let j = spec.jitter;
            // Always draw three numbers per target, so adding jitter to one target does not
            // change another's draws.
            let n: [f64; 3] = [
                rng.sample(StandardNormal),
                rng.sample(StandardNormal),
                rng.sample(StandardNormal),
            ];
            let phases = [rng.random_range(0.0..TAU), rng.random_range(0.0..TAU)];
            let (dpos, dhead, dspeed) = (
                j.position_m * n[0],
                (j.heading_deg * n[1]).to_radians(),
                j.speed_mps * n[2],
            );
            let (z, kind) = match &spec.motion {
                TargetMotion::Road {
                    road,
                    speed_mps,
                    start_m,
                    lateral_std_m,
                } => {
                    let r = scenario
                        .roads
                        .iter()
                        .find(|r| &r.id == road)
                        .ok_or_else(|| invalid(scenario, format!("no road {road:?}")))?;
                    let road = Road::from_scenario(r).map_err(|e| invalid(scenario, e))?;
                    let length = road.segments().iter().map(RoadSegment::length).sum();
                    (
                        0.0,
                        Kind::Road {
                            road,
                            length,
                            s0: (start_m + dpos).max(0.0),
                            speed: (speed_mps + dspeed).max(0.0),
                            // Two unit sinusoids have RMS 1 together: amplitude σ each gives RMS σ.
                            wander: *lateral_std_m,
                            phases,
                        },
                    )
                }
                TargetMotion::Segments {
                    position,
                    velocity,
                    z_m,
                    segments,
                } => {
                    let v = Vector2::new(velocity[0], velocity[1]);
                    let speed = v.norm();
                    let heading = v.y.atan2(v.x) + dhead;
                    let sp = (speed + dspeed).max(0.0);
                    let v0 = Vector2::new(heading.cos(), heading.sin()) * sp;
                    let dir = if speed > 0.0 { v / speed } else { v };
                    let p0 = Vector2::new(position[0], position[1]) + dir * dpos;
                    (*z_m, Kind::Pieces(pieces(p0, v0, segments)))
                }
                TargetMotion::Leader {
                    position,
                    z_m,
                    speed_mps,
                    heading_deg,
                    amplitude_deg,
                    period_s,
                } => {
                    let p0 = Vector2::new(position[0], position[1]);
                    (
                        *z_m,
                        Kind::Leader {
                            p0,
                            speed: (speed_mps + dspeed).max(0.1),
                            chi0: heading_deg.to_radians() + dhead,
                            amp: amplitude_deg.to_radians(),
                            period: *period_s,
                            n: 0,
                            p: p0,
                        },
                    )
                }
            };
            targets.push(Target {
                id: spec.id.clone(),
                z,
                kind,
            });
        }
        Ok(Self { targets, t: 0.0 })
    }

    /// Current time (s).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Number of targets.
    pub fn len(&self) -> usize {
        self.targets.len()
    }

    /// Whether there is no target.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Moves the world to time `t` (s). Going back in time restarts the integration from 0;
    /// non-finite times are ignored.
    pub fn advance(&mut self, t: f64) {
        if !t.is_finite() {
            return;
        }
        self.t = t;
        for target in &mut self.targets {
            if let Kind::Leader {
                p0,
                speed,
                chi0,
                amp,
                period,
                n,
                p,
            } = &mut target.kind
            {
                let goal = (t.max(0.0) / LEADER_STEP).floor() as u64;
                if goal < *n {
                    *n = 0;
                    *p = *p0;
                }
                while *n < goal {
                    let a = *n as f64 * LEADER_STEP;
                    let b = (*n + 1) as f64 * LEADER_STEP;
                    *p += leader_step(*speed, *chi0, *amp, *period, a, b);
                    *n += 1;
                }
            }
        }
    }

    /// Every target's true state at the current time, in scenario order.
    pub fn truth(&self) -> Vec<TargetTruth> {
        self.targets.iter().map(|t| self.truth_of(t)).collect()
    }

    fn truth_of(&self, target: &Target) -> TargetTruth {
        let t = self.t;
        let (p, v, mode): (Vector2<f64>, Vector2<f64>, String) = match &target.kind {
            Kind::Road {
                road,
                length,
                s0,
                speed,
                wander,
                phases,
            } => {
                let s = s0 + speed * t.max(0.0);
                let moving = s < *length;
                let (c, tan, kappa) = road_at(road, s.min(*length));
                let normal = Vector2::new(-tan.y, tan.x);
                let w = [TAU / WANDER_PERIODS[0], TAU / WANDER_PERIODS[1]];
                let n = wander * ((w[0] * t + phases[0]).sin() + (w[1] * t + phases[1]).sin());
                let dn = if moving {
                    wander
                        * (w[0] * (w[0] * t + phases[0]).cos()
                            + w[1] * (w[1] * t + phases[1]).cos())
                } else {
                    0.0
                };
                let n = if moving { n } else { 0.0 };
                let along = if moving {
                    speed * (1.0 - kappa * n)
                } else {
                    0.0
                };
                let mode = if !moving || kappa == 0.0 {
                    "CV"
                } else if kappa > 0.0 {
                    "left"
                } else {
                    "right"
                };
                (c + normal * n, tan * along + normal * dn, mode.to_owned())
            }
            Kind::Pieces(pieces) => {
                let k = pieces.iter().rposition(|pc| pc.t0 <= t).unwrap_or_default();
                let pc = &pieces[k];
                let (p, v) = pc.at(t - pc.t0);
                (p, v, pc.mode.clone())
            }
            Kind::Leader {
                speed,
                chi0,
                amp,
                period,
                n,
                p,
                ..
            } => {
                let a = *n as f64 * LEADER_STEP;
                let tt = t.max(0.0);
                let p = if tt > a {
                    p + leader_step(*speed, *chi0, *amp, *period, a, tt)
                } else {
                    *p
                };
                (
                    p,
                    leader_velocity(*speed, *chi0, *amp, *period, tt),
                    "sinusoidal_heading".to_owned(),
                )
            }
        };
        TargetTruth {
            id: target.id.clone(),
            state: [p.x, p.y, target.z, v.x, v.y, 0.0],
            mode,
        }
    }
}

fn invalid(s: &SimScenario, e: impl std::fmt::Display) -> ScenarioError {
    ScenarioError::Invalid {
        origin: format!("scenario {}", s.name),
        message: e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::{Jitter, TargetSpec};

    /// Heading (rad, clockwise from North) of a velocity.
    fn heading_of(vx: f64, vy: f64) -> f64 {
        vx.atan2(vy)
    }

    fn world(name: &str, seed: u64) -> (SimScenario, World) {
        let s = SimScenario::preset(name).expect("preset");
        let w = World::new(&s, seed).expect("world");
        (s, w)
    }

    #[test]
    fn cimm_road_target_matches_the_reference_truth() {
        let (_, mut w) = world("cimm-road", 1);
        // Reference truth (shared/scenarios/cimm_road_1uav/truth.csv), a few rows.
        for (t, x, y, mode) in [
            (0.0, 200.0, 300.0, "CV"),
            (1.0, 206.0, 308.0, "CV"),
            (139.0, 1034.0, 1412.0, "CV"),
        ] {
            w.advance(t);
            let s = &w.truth()[0];
            assert!(
                (s.state[0] - x).abs() < 1e-9 && (s.state[1] - y).abs() < 1e-9,
                "{t}"
            );
            assert_eq!(s.mode, mode);
        }
        // Turn rate from the velocity: −0.008 on the right arc, +0.01 on the left one.
        for (t, rate, mode) in [(200.0, -0.008, "right"), (500.0, 0.01, "left")] {
            w.advance(t);
            let a = w.truth()[0].clone();
            w.advance(t + 1.0);
            let b = w.truth()[0].clone();
            let ha = a.state[4].atan2(a.state[3]);
            let hb = b.state[4].atan2(b.state[3]);
            assert!(((hb - ha) - rate).abs() < 1e-9, "{t}: {}", hb - ha);
            assert_eq!(a.mode, mode);
            assert!((a.state[3].hypot(a.state[4]) - 10.0).abs() < 1e-9);
        }
        // Parks at the end of the road.
        w.advance(5000.0);
        let end = &w.truth()[0];
        assert_eq!([end.state[3], end.state[4]], [0.0, 0.0]);
        assert!((end.state[0] - 4_247.691_708_011_238).abs() < 1e-6);
    }

    #[test]
    fn road_target_wanders_within_sigma_and_velocity_is_consistent() {
        let mut s = SimScenario::preset("cimm-road").expect("preset");
        let sigma = 2.0;
        if let TargetMotion::Road { lateral_std_m, .. } = &mut s.targets[0].motion {
            *lateral_std_m = sigma;
        }
        let road = Road::from_scenario(&s.roads[0]).expect("road");
        let mut w = World::new(&s, 9).expect("world");
        let (mut sum2, mut n, mut max) = (0.0, 0.0, 0.0_f64);
        let mut prev: Option<[f64; 6]> = None;
        for k in 0..6000 {
            let t = k as f64 * 0.1;
            w.advance(t);
            let st = w.truth()[0].state;
            let off = road.project(&Vector2::new(st[0], st[1])).offset;
            sum2 += off * off;
            n += 1.0;
            max = max.max(off.abs());
            if let Some(p) = prev {
                // Finite-difference velocity agrees with the reported one.
                let vx = (st[0] - p[0]) / 0.1;
                let vy = (st[1] - p[1]) / 0.1;
                assert!((vx - 0.5 * (st[3] + p[3])).abs() < 0.05, "{t}");
                assert!((vy - 0.5 * (st[4] + p[4])).abs() < 0.05, "{t}");
            }
            prev = Some(st);
        }
        let rms = (sum2 / n).sqrt();
        assert!((rms - sigma).abs() < 0.3 * sigma, "rms {rms}");
        assert!(max <= 2.0 * sigma + 1e-9, "max {max}");
    }

    #[test]
    fn leader_heading_is_sinusoidal_and_call_pattern_does_not_matter() {
        let (_, mut a) = world("leader", 3);
        let (_, mut b) = world("leader", 3);
        for k in 1..=600 {
            a.advance(k as f64 * 0.1);
        }
        b.advance(60.0);
        assert_eq!(a.truth(), b.truth());
        // Heading χ(t) = 40° sin(2π t / 30) clockwise from North at 25 m/s ([BOT] §IV).
        for t in [0.0, 3.7, 7.5, 22.5, 41.0] {
            a.advance(t);
            let s = a.truth()[0].state;
            let chi = heading_of(s[3], s[4]);
            let expected = 40f64.to_radians() * (TAU * t / 30.0).sin();
            assert!((chi - expected).abs() < 1e-12, "{t}: {chi} vs {expected}");
            assert!((s[3].hypot(s[4]) - 25.0).abs() < 1e-9);
            assert_eq!(s[2], 100.0);
        }
        // Position integrates the velocity: compare with a fine trapezoid.
        let mut p = Vector2::new(60.0, 120.0);
        let h = 1e-4;
        for k in 0..100_000 {
            let t = k as f64 * h;
            p += (leader_velocity(25.0, 0.0, 40f64.to_radians(), 30.0, t)
                + leader_velocity(25.0, 0.0, 40f64.to_radians(), 30.0, t + h))
                * (h / 2.0);
        }
        a.advance(10.0);
        let s = a.truth()[0].state;
        assert!(
            (s[0] - p.x).abs() < 1e-4 && (s[1] - p.y).abs() < 1e-4,
            "{s:?} vs {p:?}"
        );
    }

    #[test]
    fn segments_turn_with_the_right_sign_and_seeds_matter() {
        let (_, mut w) = world("radar", 1);
        w.advance(79.0);
        let s = w.truth()[0].state;
        let expected = [2185.0, 4210.0, 0.0, 15.0, -10.0, 0.0];
        assert!(
            s.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-9),
            "{s:?}"
        );
        w.advance(90.0);
        let s = w.truth()[0].clone();
        assert_eq!(s.mode, "left");
        let (_, mut w2) = world("radar", 1);
        w2.advance(91.0);
        let s2 = w2.truth()[0].state;
        let turn = s2[4].atan2(s2[3]) - s.state[4].atan2(s.state[3]);
        assert!((turn - 0.05).abs() < 1e-9, "{turn}");
        // Jitter depends on the seed only.
        let (_, c1) = world("crossing", 1);
        let (_, c1b) = world("crossing", 1);
        let (_, c2) = world("crossing", 2);
        assert_eq!(c1.truth(), c1b.truth());
        assert_ne!(c1.truth(), c2.truth());
        assert_eq!(c1.len(), 4);
        // A target without jitter does not change when another target gets some.
        let mut s = SimScenario::preset("radar").expect("preset");
        let extra = TargetSpec {
            id: "b".into(),
            jitter: Jitter {
                position_m: 50.0,
                ..Jitter::default()
            },
            ..s.targets[0].clone()
        };
        let w1 = World::new(&s, 5).expect("world").truth();
        s.targets.push(extra);
        let w2 = World::new(&s, 5).expect("world").truth();
        assert_eq!(w1[0], w2[0]);
        assert_ne!(w2[0].state, w2[1].state);
    }
}
