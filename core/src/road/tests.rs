//! Unit tests of the roads: projection and its continuity, free ends, the constraint's
//! Jacobian, malformed roads, and roads built from turn legs.

use super::*;
use crate::measurement::MeasurementModel;
use approx::assert_relative_eq;
use nalgebra::{Vector2, Vector4};

/// The road of the `cimm_road_*` scenarios: a line, a right arc, a left arc.
fn road() -> Road {
    let json = r#"{"id":"r","sigma_m":2.0,"segments":[
      {"type":"line","start":[140.0,220.0],"end":[1040.0,1420.0]},
      {"type":"arc","center":[2040.0,670.0],"radius":1250.0,"start":[1040.0,1420.0],
       "end":[2964.6925767461007,1511.0966879679652],"sweep_rad":-1.76},
      {"type":"arc","center":[3704.4466381429806,2183.9740383423364],"radius":1000.0000000000066,
       "start":[2964.6925767461007,1511.0966879679652],"end":[4247.691708011238,3023.548212590115],
       "sweep_rad":3.4}]}"#;
    Road::from_scenario(&serde_json::from_str(json).unwrap()).unwrap()
}

#[test]
fn road_from_turn_legs_rebuilds_the_cimm_road() {
    // (200, 300) m at (6, 8) m/s; the road begins 100 m (10 s) before it.
    let legs = [(-10.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
    let (start, v) = (Vector2::new(140.0, 220.0), Vector2::new(6.0, 8.0));
    let built = road_from_turn_legs(start, v, &legs, 700.0, "r", None, Some(2.0)).unwrap();
    let built = Road::from_scenario(&built).unwrap();
    let want = road();
    assert_eq!(built.segments().len(), want.segments().len());
    for (a, b) in built.segments().iter().zip(want.segments()) {
        assert_relative_eq!(a.start(), b.start(), epsilon = 1e-9);
        assert_relative_eq!(a.end(), b.end(), epsilon = 1e-9);
        assert_relative_eq!(a.length(), b.length(), epsilon = 1e-9);
    }
}

#[test]
fn road_from_turn_legs_follows_the_constant_turn_model() {
    use crate::motion::{ConstantTurn, TransitionModel};
    let legs = [
        (0.0, 0.0),
        (20.0, 0.0),
        (50.0, 0.05),
        (80.0, 0.0),
        (90.0, -0.02),
    ];
    let (start, v) = (Vector2::new(10.0, -5.0), Vector2::new(3.0, -4.0));
    let sc = road_from_turn_legs(start, v, &legs, 150.0, "r", Some(7.0), Some(1.0)).unwrap();
    assert_eq!(
        (sc.id.as_str(), sc.width_m, sc.sigma_m),
        ("r", Some(7.0), Some(1.0))
    );
    // Straight legs merge: line, arc, line, arc.
    assert_eq!(sc.segments.len(), 4);
    let road = Road::from_scenario(&sc).unwrap();
    let mut x = Vector4::new(start.x, start.y, v.x, v.y);
    let mut t = 0.0;
    let ends = legs.iter().skip(1).map(|l| l.0).chain([150.0]);
    for (&(_, w), t1) in legs.iter().zip(ends) {
        while t < t1 - 1e-9 {
            let dt = (t1 - t).min(1.0);
            x = ConstantTurn::<4>::new(w, 0.0).function(&x, dt);
            t += dt;
            let rp = road.project(&Vector2::new(x[0], x[1]));
            assert!(rp.offset.abs() < 1e-6, "t {t}: offset {}", rp.offset);
            assert_relative_eq!(rp.tangent, Vector2::new(x[2], x[3]) / 5.0, epsilon = 1e-9);
        }
    }
    assert_relative_eq!(
        road.segments()[3].end(),
        Vector2::new(x[0], x[1]),
        epsilon = 1e-9
    );
}

#[test]
fn road_from_turn_legs_refuses_bad_input() {
    let (p, v) = (Vector2::zeros(), Vector2::new(1.0, 0.0));
    let ok =
        |legs: &[(f64, f64)], end, v| road_from_turn_legs(p, v, legs, end, "r", None, None).is_ok();
    assert!(ok(&[(0.0, 0.1)], 1.0, v));
    assert!(!ok(&[], 1.0, v));
    assert!(!ok(&[(0.0, 0.1)], 0.0, v));
    assert!(!ok(&[(0.0, 0.0), (0.0, 0.1)], 1.0, v));
    assert!(!ok(&[(0.0, f64::NAN)], 1.0, v));
    assert!(!ok(&[(0.0, 0.1)], 1.0, Vector2::zeros()));
}

#[test]
fn points_on_the_centre_line_have_zero_offset() {
    let r = road();
    for (k, seg) in r.segments().iter().enumerate() {
        for f in [0.1, 0.5, 0.9] {
            let s = f * seg.length();
            let rp = r.project(&seg.point_at(s));
            assert!(rp.offset.abs() < 1e-8, "{k} {f}: {}", rp.offset);
            assert_relative_eq!(rp.tangent, seg.tangent_at(s), epsilon = 1e-9);
            // 5 m to the left of travel.
            let left = Vector2::new(-rp.tangent.y, rp.tangent.x);
            let rp2 = r.project(&(seg.point_at(s) + left * 5.0));
            assert_relative_eq!(rp2.offset, 5.0, epsilon = 1e-8);
        }
    }
}

#[test]
fn projection_is_continuous_across_joins() {
    let r = road();
    for w in r.segments().windows(2) {
        let join = w[0].end();
        let t = w[0].tangent_at(w[0].length());
        let left = Vector2::new(-t.y, t.x);
        for lateral in [-6.0, 0.0, 3.0] {
            let mut prev: Option<RoadPoint> = None;
            for i in -200..=200 {
                let p = join + t * (f64::from(i) * 0.01) + left * lateral;
                let rp = r.project(&p);
                if let Some(q) = prev {
                    assert!((rp.point - q.point).norm() < 0.05, "foot jumps at {p}");
                    assert!((rp.offset - q.offset).abs() < 1e-3, "offset jumps at {p}");
                    assert!((rp.normal - q.normal).norm() < 1e-3, "normal jumps at {p}");
                }
                prev = Some(rp);
            }
        }
    }
}

#[test]
fn free_ends_extend_along_the_tangent() {
    let r = road();
    let t = Vector2::new(0.6, 0.8);
    let rp = r.project(&(Vector2::new(140.0, 220.0) - t * 50.0 + Vector2::new(-0.8, 0.6)));
    assert_relative_eq!(rp.offset, 1.0, epsilon = 1e-9);
    assert_relative_eq!(
        rp.point,
        Vector2::new(140.0, 220.0) - t * 50.0,
        epsilon = 1e-9
    );
}

#[test]
fn constraint_jacobian_matches_central_differences() {
    let r = road();
    let c = RoadConstraint::new(&r, 0.5);
    for x in [
        Vector4::new(600.0, 830.0, 6.0, 8.5),
        Vector4::new(2040.0 - 100.0, 670.0 + 1240.0, 10.0, -1.0),
        Vector4::new(3704.0 + 20.0, 2184.0 - 990.0, 9.0, 3.0),
    ] {
        let j = MeasurementModel::<4, 2>::jacobian(&c, &x);
        for col in 0..4 {
            let mut xp = x;
            let mut xm = x;
            xp[col] += 1e-4;
            xm[col] -= 1e-4;
            let num = (MeasurementModel::<4, 2>::function(&c, &xp)
                - MeasurementModel::<4, 2>::function(&c, &xm))
                / 2e-4;
            assert_relative_eq!(j.column(col).into_owned(), num, epsilon = 1e-6);
        }
    }
}

#[test]
fn malformed_roads_are_refused() {
    let gap = r#"{"id":"r","sigma_m":2.0,"segments":[
      {"type":"line","start":[0,0],"end":[10,0]},{"type":"line","start":[11,0],"end":[20,0]}]}"#;
    assert!(Road::from_scenario(&serde_json::from_str(gap).unwrap()).is_err());
    let arc = r#"{"id":"r","sigma_m":2.0,"segments":[{"type":"arc","center":[0,0],"radius":10,
      "start":[10,0],"end":[0,10],"sweep_rad":-1.5707963267948966}]}"#;
    assert!(Road::from_scenario(&serde_json::from_str(arc).unwrap()).is_err());
}
