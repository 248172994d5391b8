//! WGS-84 geodetic coordinates and local tangent planes (ENU and NED) around a geodetic origin.
//!
//! Conversions go through Earth-centred Earth-fixed (ECEF) coordinates, so they stay exact far from
//! the origin (no flat-Earth approximation); ECEF → geodetic uses Bowring's initial value and
//! a few fixed-point iterations, which converge to well below a millimetre at any altitude a UAV
//! flies. Harrier estimates in ENU; MAVLink's local frame is NED: [`enu_to_ned`] / [`ned_to_enu`]
//! are the one place the axes are swapped. Two tangent planes at different origins are related by
//! [`LocalFrame::enu_to_frame`] (points) and [`LocalFrame::rotation_to`] (directions).

use nalgebra::{Matrix3, Vector3};

/// WGS-84 semi-major axis (m).
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS-84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

const E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// A geodetic position: latitude and longitude in degrees, height above the ellipsoid in metres
/// (the simulator reports it as altitude AMSL: it models no geoid). The type of the detection
/// messages, so poses need no conversion.
pub use harrier_core::detection::GeoPoint as Geodetic;

/// ECEF coordinates (m) of a geodetic position.
pub fn to_ecef(g: &Geodetic) -> Vector3<f64> {
    let (lat, lon) = (g.lat_deg.to_radians(), g.lon_deg.to_radians());
    let n = WGS84_A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
    let r = (n + g.alt_m) * lat.cos();
    Vector3::new(
        r * lon.cos(),
        r * lon.sin(),
        (n * (1.0 - E2) + g.alt_m) * lat.sin(),
    )
}

/// The geodetic position of ECEF coordinates (m).
pub fn from_ecef(p: &Vector3<f64>) -> Geodetic {
    let lon = p.y.atan2(p.x);
    let rho = p.x.hypot(p.y);
    let b = WGS84_A * (1.0 - WGS84_F);
    let ep2 = E2 / (1.0 - E2);
    // Bowring's initial latitude, then fixed-point refinement.
    let theta = (p.z * WGS84_A).atan2(rho * b);
    let mut lat =
        (p.z + ep2 * b * theta.sin().powi(3)).atan2(rho - E2 * WGS84_A * theta.cos().powi(3));
    let mut alt = 0.0;
    for _ in 0..4 {
        let n = WGS84_A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
        alt = if lat.cos().abs() > 1e-9 {
            rho / lat.cos() - n
        } else {
            p.z.abs() - b
        };
        lat = p.z.atan2(rho * (1.0 - E2 * n / (n + alt)));
    }
    Geodetic::new(lat.to_degrees(), lon.to_degrees(), alt)
}

/// A local East-North-Up tangent plane at a geodetic origin; NED is the same plane with axes
/// (north, east, down).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: Geodetic,
    origin_ecef: Vector3<f64>,
    /// Rows: east, north, up unit vectors in ECEF.
    ecef_to_enu: Matrix3<f64>,
}

impl LocalFrame {
    /// The tangent plane at `origin`.
    pub fn new(origin: Geodetic) -> Self {
        let (lat, lon) = (origin.lat_deg.to_radians(), origin.lon_deg.to_radians());
        let (sl, cl, so, co) = (lat.sin(), lat.cos(), lon.sin(), lon.cos());
        let ecef_to_enu = Matrix3::new(-so, co, 0.0, -sl * co, -sl * so, cl, cl * co, cl * so, sl);
        Self {
            origin,
            origin_ecef: to_ecef(&origin),
            ecef_to_enu,
        }
    }

    /// The origin.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// ENU coordinates (m) of a geodetic position.
    pub fn to_enu(&self, g: &Geodetic) -> Vector3<f64> {
        self.ecef_to_enu * (to_ecef(g) - self.origin_ecef)
    }

    /// The geodetic position of ENU coordinates (m).
    pub fn from_enu(&self, enu: &Vector3<f64>) -> Geodetic {
        from_ecef(&self.enu_to_ecef(enu))
    }

    /// ECEF coordinates (m) of ENU coordinates (m).
    pub fn enu_to_ecef(&self, enu: &Vector3<f64>) -> Vector3<f64> {
        self.origin_ecef + self.ecef_to_enu.transpose() * enu
    }

    /// ENU coordinates (m) of ECEF coordinates (m).
    pub fn ecef_to_enu(&self, ecef: &Vector3<f64>) -> Vector3<f64> {
        self.ecef_to_enu * (ecef - self.origin_ecef)
    }

    /// The point at `enu` of this frame in the ENU coordinates of `other`, exactly through ECEF
    /// (unchanged when both frames have the same origin).
    pub fn enu_to_frame(&self, other: &LocalFrame, enu: &Vector3<f64>) -> Vector3<f64> {
        if self.origin == other.origin {
            *enu
        } else {
            other.ecef_to_enu(&self.enu_to_ecef(enu))
        }
    }

    /// The rotation taking a direction in this frame's ENU axes to `other`'s (the identity when
    /// both frames have the same origin).
    pub fn rotation_to(&self, other: &LocalFrame) -> Matrix3<f64> {
        if self.origin == other.origin {
            Matrix3::identity()
        } else {
            other.ecef_to_enu * self.ecef_to_enu.transpose()
        }
    }

    /// NED coordinates (m) of a geodetic position.
    pub fn to_ned(&self, g: &Geodetic) -> Vector3<f64> {
        enu_to_ned(&self.to_enu(g))
    }

    /// The geodetic position of NED coordinates (m).
    pub fn from_ned(&self, ned: &Vector3<f64>) -> Geodetic {
        self.from_enu(&ned_to_enu(ned))
    }
}

/// ENU → NED (also for velocities).
pub fn enu_to_ned(v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(v.y, v.x, -v.z)
}

/// NED → ENU (also for velocities).
pub fn ned_to_enu(v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(v.y, v.x, -v.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecef_of_known_points() {
        let p = to_ecef(&Geodetic::new(0.0, 0.0, 0.0));
        assert!((p - Vector3::new(WGS84_A, 0.0, 0.0)).norm() < 1e-6);
        let pole = to_ecef(&Geodetic::new(90.0, 0.0, 0.0));
        assert!((pole.z - 6_356_752.314_245).abs() < 1e-3);
        let g = from_ecef(&pole);
        assert!((g.lat_deg - 90.0).abs() < 1e-9 && g.alt_m.abs() < 1e-3);
    }

    #[test]
    fn geodetic_ecef_round_trip() {
        for &(lat, lon, alt) in &[
            (47.397_742, 8.545_594, 488.0),
            (-33.9, 151.2, 5.0),
            (89.999, -120.0, 3000.0),
            (0.0, 179.999, -50.0),
            (60.0, -45.0, 20_000.0),
        ] {
            let g = Geodetic::new(lat, lon, alt);
            let back = from_ecef(&to_ecef(&g));
            assert!((back.lat_deg - lat).abs() < 1e-10, "{back:?}");
            assert!((back.lon_deg - lon).abs() < 1e-10, "{back:?}");
            assert!((back.alt_m - alt).abs() < 1e-6, "{back:?}");
        }
    }

    #[test]
    fn enu_and_ned_round_trip() {
        let frame = LocalFrame::new(Geodetic::new(47.397_742, 8.545_594, 488.0));
        for &(e, n, u) in &[
            (0.0, 0.0, 0.0),
            (100.0, -250.0, 30.0),
            (-5_000.0, 12_000.0, 400.0),
            (30_000.0, 30_000.0, -20.0),
        ] {
            let enu = Vector3::new(e, n, u);
            let g = frame.from_enu(&enu);
            assert!((frame.to_enu(&g) - enu).norm() < 1e-6);
            let ned = enu_to_ned(&enu);
            assert!((frame.to_ned(&frame.from_ned(&ned)) - ned).norm() < 1e-6);
        }
    }

    #[test]
    fn frames_at_two_origins_agree_on_points_and_directions() {
        let a = LocalFrame::new(Geodetic::new(47.397_742, 8.545_594, 488.0));
        let b = LocalFrame::new(Geodetic::new(47.41, 8.52, 430.0));
        let p = Vector3::new(1_200.0, -800.0, 150.0);
        let in_b = a.enu_to_frame(&b, &p);
        assert!((b.from_enu(&in_b).lat_deg - a.from_enu(&p).lat_deg).abs() < 1e-10);
        assert!((b.to_enu(&a.from_enu(&p)) - in_b).norm() < 1e-6);
        // A direction rotated into b is the difference of two converted points.
        let d = Vector3::new(3.0, 4.0, -1.0);
        let r = a.rotation_to(&b);
        let moved = a.enu_to_frame(&b, &(p + d)) - in_b;
        assert!((r * d - moved).norm() < 1e-6, "{:?} vs {moved:?}", r * d);
        assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
        // Same origin: exactly the identity.
        assert_eq!(a.rotation_to(&a), Matrix3::identity());
        assert_eq!(a.enu_to_frame(&a, &p), p);
    }

    #[test]
    fn local_axes_point_the_right_way() {
        let o = Geodetic::new(47.0, 8.0, 500.0);
        let frame = LocalFrame::new(o);
        // 100 m north: latitude grows by ~100 / 111 km, longitude unchanged.
        let g = frame.from_ned(&Vector3::new(100.0, 0.0, 0.0));
        assert!(g.lat_deg > o.lat_deg && (g.lon_deg - o.lon_deg).abs() < 1e-9);
        assert!(((g.lat_deg - o.lat_deg) * 111_200.0 - 100.0).abs() < 0.5);
        // 100 m east.
        let g = frame.from_ned(&Vector3::new(0.0, 100.0, 0.0));
        assert!(g.lon_deg > o.lon_deg);
        // 10 m down: altitude drops by 10 m.
        let g = frame.from_ned(&Vector3::new(0.0, 0.0, 10.0));
        assert!((g.alt_m - 490.0).abs() < 1e-6);
    }
}
