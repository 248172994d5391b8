//! True motion of the simulated targets: the \[CIMM\] §5.1 road target (piecewise constant turn,
//! propagated with harrier-core's [`ConstantTurn`]) and its road, and the \[BOT\] leader's heading
//! schedule.

use harrier_core::EstimationError;
use harrier_core::motion::{ConstantTurn, TransitionModel};
use harrier_core::road::road_from_turn_legs;
use harrier_core::scenario;
use nalgebra::{Vector2, Vector3, Vector4};

/// Legs of the \[CIMM\] §5.1 target: (start time s, turn rate rad/s). Straight, right turn at
/// −0.008 rad/s from 140 s, left turn at 0.01 rad/s from 360 s (the `motion.models` turn rates of
/// `cimm_road_1uav`).
pub const ROAD_LEGS: [(f64, f64); 3] = [(0.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
/// Start position (m) and velocity (m/s) of the road target.
const ROAD_START: ([f64; 2], [f64; 2]) = ([200.0, 300.0], [6.0, 8.0]);
/// End of the road's last segment (s of travel); beyond it the road continues along its tangent.
const ROAD_END_S: f64 = 700.0;
/// Lateral-offset std of the road (m), as `sigma_m` of `cimm_road_1uav`.
pub const ROAD_SIGMA_M: f64 = 2.0;

/// The \[CIMM\] §5.1 target (the road of `cimm_road_1uav`): from (200, 300) m at (6, 8) m/s along
/// [`ROAD_LEGS`].
pub fn road_target(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let ([x, y], [vx, vy]) = ROAD_START;
    let mut s = Vector4::new(x, y, vx, vy);
    for (i, &(t0, w)) in ROAD_LEGS.iter().enumerate() {
        if i > 0 && t <= t0 {
            break;
        }
        let t1 = ROAD_LEGS.get(i + 1).map_or(f64::INFINITY, |l| l.0);
        s = ConstantTurn::<4>::new(w, 0.0).function(&s, t.min(t1) - t0);
    }
    (Vector3::new(s[0], s[1], 0.0), Vector3::new(s[2], s[3], 0.0))
}

/// The road the moving target drives on, built from the same legs as [`road_target`]
/// ([`road_from_turn_legs`]: one line or arc per leg), `sigma_m` = [`ROAD_SIGMA_M`], width 7 m.
/// Equals the `roads` of `cimm_road_1uav` up to the line's start.
pub fn road() -> Result<scenario::Road, EstimationError> {
    let ([x, y], [vx, vy]) = ROAD_START;
    road_from_turn_legs(
        Vector2::new(x, y),
        Vector2::new(vx, vy),
        &ROAD_LEGS,
        ROAD_END_S,
        "road1",
        Some(7.0),
        Some(ROAD_SIGMA_M),
    )
}

/// Speed of the \[BOT\] leader (m/s).
pub const LEADER_SPEED: f64 = 15.0;

/// Leader heading schedule (rad from the x axis): left and right turns, then straight north.
pub fn leader_heading(t: f64) -> f64 {
    let deg: f64 = match t {
        t if t < 40.0 => 90.0,
        t if t < 90.0 => 110.0,
        t if t < 150.0 => 70.0,
        t if t < 210.0 => 105.0,
        t if t < 260.0 => 75.0,
        _ => 90.0,
    };
    deg.to_radians()
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::road::{RoadNetwork, RoadSegment};

    #[test]
    fn road_target_matches_the_scenario_truth() {
        // cimm_road_1uav/truth.csv at 140, 360 and 700 s.
        let (p, _) = road_target(140.0);
        assert!((p - Vector3::new(1040.0, 1420.0, 0.0)).norm() < 1e-6);
        let (p, v) = road_target(360.0);
        assert!((p - Vector3::new(2964.692577, 1511.096688, 0.0)).norm() < 1e-3);
        assert!((v - Vector3::new(6.728774, -7.397541, 0.0)).norm() < 1e-4);
        let (p, _) = road_target(700.0);
        assert!((p - Vector3::new(4247.691708, 3023.548213, 0.0)).norm() < 1e-3);
    }

    #[test]
    fn road_is_the_scenario_road_and_carries_the_target() {
        let net = RoadNetwork::from_scenario(&[road().unwrap()]).unwrap();
        let road = &net.roads()[0];
        assert_eq!(road.sigma_m(), ROAD_SIGMA_M);
        // cimm_road_1uav/scenario.json roads: arc centres, radii, sweeps, end point.
        let segs = road.segments();
        assert_eq!(segs.len(), 3);
        let expect = [
            (Vector2::new(2040.0, 670.0), 1250.0, -1.76),
            (Vector2::new(3704.446638, 2183.974038), 1000.0, 3.4),
        ];
        for (seg, (c, r, sweep)) in segs[1..].iter().zip(expect) {
            let RoadSegment::Arc {
                center,
                radius,
                sweep: sw,
                ..
            } = *seg
            else {
                panic!("arc expected, got {seg:?}");
            };
            assert!((center - c).norm() < 1e-4, "{center}");
            assert!((radius - r).abs() < 1e-6 && (sw - sweep).abs() < 1e-9);
        }
        assert!((segs[2].end() - Vector2::new(4247.691708, 3023.548213)).norm() < 1e-3);
        for k in 0..=700 {
            let (p, _) = road_target(f64::from(k));
            assert!(road.project(&p.xy()).offset.abs() < 1e-6, "t = {k}");
        }
    }
}
