//! Measurement models `z = h(x) + v`, `v ~ N(0, R)`, for the four kinds of FORMAT.md §3:
//! [`Position`], [`RangeBearing`], [`AzEl`] and [`BearingSize`] (with the subtended-angle model
//! `2·atan(S / 2ρ)` of [BOT] §II.C).
//!
//! Angles follow FORMAT.md §1: azimuth `atan2(dE, dN)`, clockwise from North, wrapped to `[-π, π)`;
//! elevation `atan2(dU, hypot(dE, dN))`. Azimuth residuals are always wrapped.
//!
//! The target position is read from the state through a [`Geometry`]: `x[0], x[1]` are East and
//! North, and Up is `x[2]` in 3-D layouts or the constant `plane_z` in planar ones. This holds for
//! every state layout of [`crate::motion`] and for augmented states that append extra components.

use nalgebra::{Matrix1x3, Matrix2x3, Matrix3, SMatrix, SVector, Vector2, Vector3};

use crate::linalg::wrap_angle;

/// `z = h(x) + v`, `v ~ N(0, R)`.
pub trait MeasurementModel<const N: usize, const M: usize> {
    /// Noise-free measurement `h(x)`.
    fn function(&self, x: &SVector<f64, N>) -> SVector<f64, M>;
    /// `∂h/∂x` at `x`.
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, M, N>;
    /// Measurement-noise covariance `R`.
    fn covar(&self) -> SMatrix<f64, M, M>;
    /// `a ⊖ b`: the difference of two measurements, angle components wrapped to `[-π, π)`.
    fn residual(&self, a: &SVector<f64, M>, b: &SVector<f64, M>) -> SVector<f64, M> {
        a - b
    }
}

/// A measurement model with `h(x) = H x`.
pub trait LinearMeasurement<const N: usize, const M: usize>: MeasurementModel<N, M> {
    /// The measurement matrix `H`.
    fn matrix(&self) -> SMatrix<f64, M, N>;
}

/// Where the target position sits in a state vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// `true`: Up is `x[2]`; `false`: Up is the constant `plane_z` (planar scenario).
    pub up_in_state: bool,
    /// Up coordinate of a planar scenario (m).
    pub plane_z: f64,
}

impl Geometry {
    /// Planar layout (`[x, y, …]`, z = `plane_z`).
    pub fn planar(plane_z: f64) -> Self {
        Self {
            up_in_state: false,
            plane_z,
        }
    }
    /// 3-D layout (`[x, y, z, …]`).
    pub fn spatial() -> Self {
        Self {
            up_in_state: true,
            plane_z: 0.0,
        }
    }
    /// Target position (E, N, U) in the state `x`.
    #[inline]
    pub fn position<const N: usize>(&self, x: &SVector<f64, N>) -> Vector3<f64> {
        let up = if self.up_in_state { x[2] } else { self.plane_z };
        Vector3::new(x[0], x[1], up)
    }
    /// Chain rule: `∂h/∂x` from `∂h/∂p` (p = target position).
    #[inline]
    fn lift<const N: usize, const M: usize>(
        &self,
        dh_dp: &SMatrix<f64, M, 3>,
    ) -> SMatrix<f64, M, N> {
        let mut j = SMatrix::<f64, M, N>::zeros();
        let cols = if self.up_in_state { 3 } else { 2 };
        for c in 0..cols {
            j.set_column(c, &dh_dp.column(c));
        }
        j
    }
}

fn diag_sq<const M: usize>(std: [f64; M]) -> SMatrix<f64, M, M> {
    SMatrix::<f64, M, M>::from_diagonal(&SVector::<f64, M>::from_fn(|i, _| std[i] * std[i]))
}

/// Absolute target position `[x, y]` (M = 2) or `[x, y, z]` (M = 3) in ENU (FORMAT.md §3 `position`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position<const M: usize> {
    geometry: Geometry,
    r: SMatrix<f64, M, M>,
}

impl<const M: usize> Position<M> {
    /// Position measurement with per-component noise standard deviations `std` (m).
    pub fn new(geometry: Geometry, std: [f64; M]) -> Self {
        const { assert!(M == 2 || M == 3) };
        Self {
            geometry,
            r: diag_sq(std),
        }
    }
}

impl<const N: usize, const M: usize> MeasurementModel<N, M> for Position<M> {
    fn function(&self, x: &SVector<f64, N>) -> SVector<f64, M> {
        let p = self.geometry.position(x);
        SVector::<f64, M>::from_fn(|i, _| p[i])
    }
    fn jacobian(&self, _x: &SVector<f64, N>) -> SMatrix<f64, M, N> {
        self.matrix()
    }
    fn covar(&self) -> SMatrix<f64, M, M> {
        self.r
    }
}

impl<const N: usize, const M: usize> LinearMeasurement<N, M> for Position<M> {
    fn matrix(&self) -> SMatrix<f64, M, N> {
        let dh_dp = SMatrix::<f64, M, 3>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 });
        self.geometry.lift(&dh_dp)
    }
}

/// Direct observation of the first M state components (the position block of a kinematic layout):
/// `z = [I 0] x + v`, `v ~ N(0, diag(std²))` — [ESE] eqs. (6) and (12) for one or more angle axes.
/// Components are plain differences (unwrap angles before using it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectPosition<const M: usize> {
    r: SMatrix<f64, M, M>,
}

impl<const M: usize> DirectPosition<M> {
    /// Observation of the first M components with noise standard deviations `std`.
    pub fn new(std: [f64; M]) -> Self {
        Self {
            r: SMatrix::<f64, M, M>::from_diagonal(&SVector::<f64, M>::from_fn(|i, _| {
                std[i] * std[i]
            })),
        }
    }
}

impl<const N: usize, const M: usize> MeasurementModel<N, M> for DirectPosition<M> {
    fn function(&self, x: &SVector<f64, N>) -> SVector<f64, M> {
        LinearMeasurement::<N, M>::matrix(self) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>) -> SMatrix<f64, M, N> {
        self.matrix()
    }
    fn covar(&self) -> SMatrix<f64, M, M> {
        self.r
    }
}

impl<const N: usize, const M: usize> LinearMeasurement<N, M> for DirectPosition<M> {
    fn matrix(&self) -> SMatrix<f64, M, N> {
        const { assert!(N >= M, "the state must contain the observed components") };
        SMatrix::<f64, M, N>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 })
    }
}

/// Azimuth `atan2(dE, dN)` and its gradient with respect to d = (dE, dN, dU).
#[inline]
fn azimuth(d: &Vector3<f64>) -> (f64, Matrix1x3<f64>) {
    let h2 = d.x * d.x + d.y * d.y;
    (d.x.atan2(d.y), Matrix1x3::new(d.y / h2, -d.x / h2, 0.0))
}

/// Elevation `atan2(dU, hypot(dE, dN))` and its gradient.
#[inline]
fn elevation(d: &Vector3<f64>) -> (f64, Matrix1x3<f64>) {
    let hxy = d.x.hypot(d.y);
    let rho2 = d.norm_squared();
    let k = -d.z / (rho2 * hxy);
    (d.z.atan2(hxy), Matrix1x3::new(k * d.x, k * d.y, hxy / rho2))
}

/// Radar `[range, azimuth]` from a sensor at `sensor` (FORMAT.md §3 `range_bearing`); range is the
/// 3-D distance ρ = |d|.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearing {
    geometry: Geometry,
    sensor: Vector3<f64>,
    r: SMatrix<f64, 2, 2>,
}

impl RangeBearing {
    /// Range/bearing from `sensor` (ENU, m) with noise std `[σ_ρ (m), σ_az (rad)]`.
    pub fn new(geometry: Geometry, sensor: Vector3<f64>, std: [f64; 2]) -> Self {
        Self {
            geometry,
            sensor,
            r: diag_sq(std),
        }
    }
}

impl<const N: usize> MeasurementModel<N, 2> for RangeBearing {
    fn function(&self, x: &SVector<f64, N>) -> Vector2<f64> {
        let d = self.geometry.position(x) - self.sensor;
        Vector2::new(d.norm(), d.x.atan2(d.y))
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, 2, N> {
        let d = self.geometry.position(x) - self.sensor;
        let rho = d.norm();
        let (_, daz) = azimuth(&d);
        let mut dh = Matrix2x3::zeros();
        dh.set_row(0, &(d.transpose() / rho));
        dh.set_row(1, &daz);
        self.geometry.lift(&dh)
    }
    fn covar(&self) -> SMatrix<f64, 2, 2> {
        self.r
    }
    fn residual(&self, a: &Vector2<f64>, b: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new(a[0] - b[0], wrap_angle(a[1] - b[1]))
    }
}

/// Camera/gimbal `[azimuth, elevation]` (FORMAT.md §3 `az_el`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AzEl {
    geometry: Geometry,
    sensor: Vector3<f64>,
    r: SMatrix<f64, 2, 2>,
}

impl AzEl {
    /// Angles from `sensor` with noise std `[σ_az, σ_el]` (rad).
    pub fn new(geometry: Geometry, sensor: Vector3<f64>, std: [f64; 2]) -> Self {
        Self {
            geometry,
            sensor,
            r: diag_sq(std),
        }
    }
}

impl<const N: usize> MeasurementModel<N, 2> for AzEl {
    fn function(&self, x: &SVector<f64, N>) -> Vector2<f64> {
        let d = self.geometry.position(x) - self.sensor;
        Vector2::new(azimuth(&d).0, elevation(&d).0)
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, 2, N> {
        let d = self.geometry.position(x) - self.sensor;
        let mut dh = Matrix2x3::zeros();
        dh.set_row(0, &azimuth(&d).1);
        dh.set_row(1, &elevation(&d).1);
        self.geometry.lift(&dh)
    }
    fn covar(&self) -> SMatrix<f64, 2, 2> {
        self.r
    }
    fn residual(&self, a: &Vector2<f64>, b: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new(wrap_angle(a[0] - b[0]), a[1] - b[1])
    }
}

/// Where the target size S of [`BearingSize`] comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TargetSize {
    /// Known size (m), `target.size_m` of the scenario.
    Known(f64),
    /// Size is the state component at this index (estimated, [BOT] §II.C).
    State(usize),
}

/// `[azimuth, elevation, subtended]` with `subtended = 2·atan(S / 2ρ)` ([BOT] §II.C, FORMAT.md §3
/// `bearing_size`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BearingSize {
    geometry: Geometry,
    sensor: Vector3<f64>,
    size: TargetSize,
    r: SMatrix<f64, 3, 3>,
}

impl BearingSize {
    /// Angles and subtended angle from `sensor`, noise std `[σ_az, σ_el, σ_sub]` (rad).
    pub fn new(geometry: Geometry, sensor: Vector3<f64>, size: TargetSize, std: [f64; 3]) -> Self {
        Self {
            geometry,
            sensor,
            size,
            r: diag_sq(std),
        }
    }
    fn size_of<const N: usize>(&self, x: &SVector<f64, N>) -> f64 {
        match self.size {
            TargetSize::Known(s) => s,
            TargetSize::State(i) => x[i],
        }
    }
}

impl<const N: usize> MeasurementModel<N, 3> for BearingSize {
    fn function(&self, x: &SVector<f64, N>) -> Vector3<f64> {
        let d = self.geometry.position(x) - self.sensor;
        let s = self.size_of(x);
        Vector3::new(
            azimuth(&d).0,
            elevation(&d).0,
            2.0 * (s / (2.0 * d.norm())).atan(),
        )
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, 3, N> {
        let d = self.geometry.position(x) - self.sensor;
        let s = self.size_of(x);
        let rho = d.norm();
        // d/dρ 2·atan(S/2ρ) = −4S/(4ρ² + S²);  d/dS = 4ρ/(4ρ² + S²).
        let den = 4.0 * rho * rho + s * s;
        let mut dh = Matrix3::zeros();
        dh.set_row(0, &azimuth(&d).1);
        dh.set_row(1, &elevation(&d).1);
        dh.set_row(2, &(d.transpose() * (-4.0 * s / (den * rho))));
        let mut j = self.geometry.lift(&dh);
        if let TargetSize::State(i) = self.size {
            j[(2, i)] += 4.0 * rho / den;
        }
        j
    }
    fn covar(&self) -> SMatrix<f64, 3, 3> {
        self.r
    }
    fn residual(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(wrap_angle(a[0] - b[0]), a[1] - b[1], a[2] - b[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{SVector, Vector6};

    fn numeric_jacobian<const N: usize, const M: usize>(
        m: &impl MeasurementModel<N, M>,
        x: &SVector<f64, N>,
    ) -> SMatrix<f64, M, N> {
        let mut j = SMatrix::<f64, M, N>::zeros();
        for c in 0..N {
            let e = 1e-4 * (1.0 + x[c].abs());
            let mut xp = *x;
            let mut xm = *x;
            xp[c] += e;
            xm[c] -= e;
            j.set_column(
                c,
                &(m.residual(&m.function(&xp), &m.function(&xm)) / (2.0 * e)),
            );
        }
        j
    }

    #[test]
    fn azimuth_convention_is_clockwise_from_north() {
        let m = AzEl::new(Geometry::spatial(), Vector3::zeros(), [1e-3; 2]);
        let east = Vector6::new(10.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let west = Vector6::new(-10.0, 0.0, 10.0, 0.0, 0.0, 0.0);
        let z: Vector2<f64> = m.function(&east);
        assert_relative_eq!(z[0], std::f64::consts::FRAC_PI_2);
        let z: Vector2<f64> = m.function(&west);
        assert_relative_eq!(
            z,
            Vector2::new(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_4)
        );
    }

    #[test]
    fn jacobians_match_central_differences() {
        let x = Vector6::new(300.0, -450.0, 120.0, 3.0, -1.0, 0.5);
        let s = Vector3::new(10.0, 20.0, 50.0);
        let rb = RangeBearing::new(Geometry::spatial(), s, [1.0, 1e-3]);
        assert_relative_eq!(rb.jacobian(&x), numeric_jacobian(&rb, &x), epsilon = 1e-7);
        let ae = AzEl::new(Geometry::spatial(), s, [1e-3; 2]);
        assert_relative_eq!(ae.jacobian(&x), numeric_jacobian(&ae, &x), epsilon = 1e-7);
        let bs = BearingSize::new(Geometry::spatial(), s, TargetSize::Known(12.0), [1e-3; 3]);
        assert_relative_eq!(bs.jacobian(&x), numeric_jacobian(&bs, &x), epsilon = 1e-7);
        let xs =
            SVector::<f64, 7>::from_column_slice(&[300.0, -450.0, 120.0, 3.0, -1.0, 0.5, 11.0]);
        let bs = BearingSize::new(Geometry::spatial(), s, TargetSize::State(6), [1e-3; 3]);
        assert_relative_eq!(bs.jacobian(&xs), numeric_jacobian(&bs, &xs), epsilon = 1e-7);
        let planar = RangeBearing::new(Geometry::planar(0.0), s, [1.0, 1e-3]);
        let x4 = nalgebra::Vector4::new(300.0, -450.0, 3.0, -1.0);
        assert_relative_eq!(
            planar.jacobian(&x4),
            numeric_jacobian(&planar, &x4),
            epsilon = 1e-7
        );
    }

    #[test]
    fn azimuth_residual_wraps_across_south() {
        let m = RangeBearing::new(Geometry::planar(0.0), Vector3::zeros(), [1.0, 1e-3]);
        let r = MeasurementModel::<4, 2>::residual(
            &m,
            &Vector2::new(0.0, -3.1),
            &Vector2::new(0.0, 3.1),
        );
        assert_relative_eq!(r[1], 2.0 * std::f64::consts::PI - 6.2, epsilon = 1e-12);
    }
}
