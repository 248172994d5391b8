//! The safety envelope on every setpoint the guidance sends (`[guidance.safety]`; pure): a
//! geofence (the deployment's no-fly discs, `guidance.obstacles`; a maximum horizontal distance
//! from the frame's origin; an altitude floor and ceiling, up in the server's ENU frame) and a
//! battery floor.
//!
//! - [`Envelope::clip`]: a velocity setpoint is judged by where it would take the vehicle in
//!   `lookahead_s` (p + v·τ). Towards a no-fly disc it keeps only its part along the disc's
//!   tangent (straight tangential motion never gets closer to the centre); beyond the maximum
//!   distance it loses its outward part and is then scaled to end on the circle; vertically it is
//!   limited to end within `[floor, ceiling]`. What still ends outside (constraints that fight)
//!   becomes a hover. Every clipped setpoint is counted.
//! - [`Envelope::outside`]: a vehicle found inside a no-fly disc, beyond the distance or above
//!   the ceiling leaves its slot and is sent to Hold (below the floor is where every launch
//!   starts: it is only kept from descending).
//! - [`Envelope::battery_low`]: a vehicle whose battery is below the floor leaves its slot and is
//!   sent home (MAV_CMD_NAV_RETURN_TO_LAUNCH).
//!
//! A fixed wing cannot hover: a clipped ArduPlane course still turns it along the fence, but a
//! setpoint that must become a hover is flown at its minimum airspeed; its breach is caught by
//! `outside` and ends in its Hold (a loiter).

use harrier_core::guidance::obstacle::Obstacle;
use nalgebra::{Vector2, Vector3};

/// The safety envelope (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Envelope {
    /// Discs (ENU, m) no setpoint may lead into.
    pub no_fly: Vec<Obstacle>,
    /// Largest horizontal distance (m) from the frame's origin; `None`: none.
    pub max_distance_m: Option<f64>,
    /// Lowest height (m, ENU up) a setpoint may lead to; `None`: none.
    pub floor_m: Option<f64>,
    /// Highest height (m, ENU up); `None`: none.
    pub ceiling_m: Option<f64>,
    /// How far ahead (s) a setpoint is judged.
    pub lookahead_s: f64,
    /// Remaining battery (%) below which a vehicle leaves its slot and returns home; `None`:
    /// none.
    pub battery_floor_pct: Option<f64>,
}

impl Default for Envelope {
    /// No fence, no battery floor, 2 s of look-ahead.
    fn default() -> Self {
        Self {
            no_fly: Vec::new(),
            max_distance_m: None,
            floor_m: None,
            ceiling_m: None,
            lookahead_s: 2.0,
            battery_floor_pct: None,
        }
    }
}

/// Slack (m) within which a look-ahead point on a boundary counts as inside.
const SLACK_M: f64 = 1e-6;

impl Envelope {
    /// Whether velocity `v` from `p` keeps the vehicle inside over the look-ahead: the straight
    /// path to `p + v·τ` enters no no-fly disc, and its end is within the distance and between
    /// the floor and the ceiling. What [`Self::clip`] guarantees of its output for a vehicle
    /// inside.
    pub fn keeps_inside(&self, p: &Vector3<f64>, v: &Vector3<f64>) -> bool {
        let q = p + v * self.lookahead_s;
        let (a, b) = (p.xy(), q.xy());
        self.no_fly
            .iter()
            .all(|o| closest(&a, &b, &o.center) >= o.radius - SLACK_M)
            && self.max_distance_m.is_none_or(|d| b.norm() <= d + SLACK_M)
            && self.ceiling_m.is_none_or(|c| q.z <= c + SLACK_M)
            && self.floor_m.is_none_or(|f| q.z >= f - SLACK_M)
    }

    /// What keeps a vehicle at `p` out of its slot, if anything: inside a no-fly disc, beyond
    /// the maximum distance or above the ceiling (in words).
    pub fn outside(&self, p: &Vector3<f64>) -> Option<String> {
        let h = p.xy();
        if let Some(o) = self
            .no_fly
            .iter()
            .find(|o| (h - o.center).norm() < o.radius)
        {
            return Some(format!(
                "inside the no-fly disc of radius {:.0} m at ({:.0}, {:.0})",
                o.radius, o.center.x, o.center.y
            ));
        }
        if let Some(d) = self.max_distance_m.filter(|d| h.norm() > *d) {
            return Some(format!(
                "{:.0} m from the origin, beyond the fence's {d:.0} m",
                h.norm()
            ));
        }
        self.ceiling_m
            .filter(|c| p.z > *c)
            .map(|c| format!("at {:.0} m, above the ceiling of {c:.0} m", p.z))
    }

    /// Whether a battery at `pct` % is below the floor.
    pub fn battery_low(&self, pct: Option<f64>) -> bool {
        matches!((pct, self.battery_floor_pct), (Some(b), Some(f)) if b < f)
    }

    /// The velocity setpoint `v` for a vehicle at `p`, clipped to the envelope (see the module
    /// documentation), and whether it was clipped.
    pub fn clip(&self, p: &Vector3<f64>, v: &Vector3<f64>) -> (Vector3<f64>, bool) {
        let tau = self.lookahead_s;
        let mut h = v.xy();
        let here = p.xy();
        for o in &self.no_fly {
            let out = here - o.center;
            if closest(&here, &(here + h * tau), &o.center) < o.radius && out.norm() > 0.0 {
                let n = out / out.norm();
                let inward = h.dot(&n).min(0.0);
                h -= n * inward;
            }
        }
        if let Some(d) = self.max_distance_m {
            h = within_circle(&here, h, d, tau);
        }
        let mut vz = v.z;
        if let Some(c) = self.ceiling_m {
            vz = vz.min((c - p.z) / tau);
        }
        if let Some(f) = self.floor_m {
            vz = vz.max((f - p.z) / tau);
        }
        let mut out = Vector3::new(h.x, h.y, vz);
        if !self.keeps_inside(p, &out) {
            // Constraints that fight (a disc against the outer circle): hover, keeping the
            // vertical limit.
            out.x = 0.0;
            out.y = 0.0;
        }
        (out, (out - v).norm() > 1e-9)
    }
}

/// The distance from `c` to the segment from `a` to `b`.
fn closest(a: &Vector2<f64>, b: &Vector2<f64>, c: &Vector2<f64>) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((c - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t - c).norm()
}

/// `h` from `here` over `tau` s kept within the circle of radius `d` about the origin: its
/// outward part dropped when it would leave, then scaled to end on the circle.
fn within_circle(here: &Vector2<f64>, mut h: Vector2<f64>, d: f64, tau: f64) -> Vector2<f64> {
    if (here + h * tau).norm() <= d {
        return h;
    }
    if here.norm() > 0.0 {
        let n = here / here.norm();
        let outward = h.dot(&n).max(0.0);
        h -= n * outward;
    }
    // |here + s·h·τ| = d for the largest s in [0, 1]: a quadratic in s.
    let (a, b, c) = (
        (h * tau).norm_squared(),
        2.0 * here.dot(&(h * tau)),
        here.norm_squared() - d * d,
    );
    if a <= 0.0 || c > 0.0 {
        // Outside already: nothing that leads further out.
        return if c > 0.0 { Vector2::zeros() } else { h };
    }
    let s = ((-b + (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)).clamp(0.0, 1.0);
    h * s
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;

    fn fence() -> Envelope {
        Envelope {
            no_fly: vec![Obstacle {
                center: Vector2::new(200.0, 0.0),
                radius: 80.0,
            }],
            max_distance_m: Some(500.0),
            floor_m: Some(10.0),
            ceiling_m: Some(300.0),
            lookahead_s: 2.0,
            battery_floor_pct: Some(25.0),
        }
    }

    /// Over 20 000 random vehicles inside the fence and random setpoints up to 30 m/s, every
    /// clipped setpoint keeps its vehicle inside over the look-ahead; setpoints that already do
    /// pass unchanged.
    #[test]
    fn no_clipped_setpoint_leads_outside() {
        let e = fence();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut clipped, mut n) = (0, 0);
        while n < 20_000 {
            let p = Vector3::new(
                rng.random_range(-520.0..520.0),
                rng.random_range(-520.0..520.0),
                rng.random_range(0.0..320.0),
            );
            if e.outside(&p).is_some() {
                continue;
            }
            n += 1;
            let v = Vector3::new(
                rng.random_range(-30.0..30.0),
                rng.random_range(-30.0..30.0),
                rng.random_range(-10.0..10.0),
            );
            let (out, was) = e.clip(&p, &v);
            assert!(e.keeps_inside(&p, &out), "{p} {v} -> {out}");
            assert_eq!(was, out != v);
            if e.keeps_inside(&p, &v) {
                assert_eq!(out, v, "an inside setpoint is left alone");
            }
            clipped += usize::from(was);
        }
        assert!(
            clipped > 1_000,
            "the test exercised the clipping: {clipped}"
        );
    }

    #[test]
    fn a_disc_is_skirted_and_breaches_and_batteries_are_named() {
        let e = fence();
        // Heading straight at the disc from 10 m outside its edge: the radial part goes.
        let p = Vector3::new(110.0, 0.0, 100.0);
        let (v, clipped) = e.clip(&p, &Vector3::new(10.0, 5.0, 0.0));
        assert!(clipped);
        assert!(v.x.abs() < 1e-9 && (v.y - 5.0).abs() < 1e-9, "{v}");
        // Near the outer circle: the outward part goes, the rest is kept within it.
        let p = Vector3::new(0.0, 495.0, 100.0);
        let (v, _) = e.clip(&p, &Vector3::new(0.0, 10.0, 0.0));
        assert_eq!(v, Vector3::zeros());
        let (v, _) = e.clip(&p, &Vector3::new(60.0, 10.0, 0.0));
        assert!(v.y.abs() < 1e-9 && v.x > 0.0 && v.x < 60.0, "{v}");
        assert!(
            ((p + v * 2.0).xy().norm() - 500.0).abs() < 1e-6,
            "ends on the circle: {v}"
        );
        // Vertically: no climb through the ceiling, no descent through the floor.
        let (v, _) = e.clip(&Vector3::new(0.0, 0.0, 298.0), &Vector3::new(0.0, 0.0, 5.0));
        assert!((v.z - 1.0).abs() < 1e-9);
        let (v, _) = e.clip(&Vector3::new(0.0, 0.0, 2.0), &Vector3::new(0.0, 0.0, -1.0));
        assert!((v.z - 4.0).abs() < 1e-9, "climbs to the floor: {v}");
        assert!(
            e.outside(&Vector3::new(2.0, 0.0, 9.0)).is_none(),
            "low is no breach"
        );
        assert!(
            e.outside(&Vector3::new(200.0, 10.0, 50.0))
                .is_some_and(|s| s.contains("no-fly"))
        );
        assert!(
            e.outside(&Vector3::new(0.0, 600.0, 50.0))
                .is_some_and(|s| s.contains("beyond"))
        );
        assert!(
            e.outside(&Vector3::new(0.0, 0.0, 301.0))
                .is_some_and(|s| s.contains("ceiling"))
        );
        assert!(e.battery_low(Some(24.0)) && !e.battery_low(Some(25.0)));
        assert!(!e.battery_low(None) && !Envelope::default().battery_low(Some(1.0)));
        // No fence: nothing is clipped.
        let (v, clipped) = Envelope::default().clip(&p, &Vector3::new(1.0, 2.0, 3.0));
        assert_eq!((v, clipped), (Vector3::new(1.0, 2.0, 3.0), false));
    }
}
