//! Measurement models `z = h(x) + v`, `v ~ N(0, R)`, for the four kinds of FORMAT.md §3:
//! [`Position`], [`RangeBearing`], [`AzEl`] and [`BearingSize`] (with the subtended-angle model
//! `2·atan(S / 2ρ)` of \[BOT\] §II.C).
//!
//! Angles follow FORMAT.md §1: azimuth `atan2(dE, dN)`, clockwise from North, wrapped to `[-π, π)`;
//! elevation `atan2(dU, hypot(dE, dN))`. Azimuth residuals are always wrapped.
//!
//! The target position is read from the state through a [`Geometry`]: `x[0], x[1]` are East and
//! North, and Up is `x[2]` in 3-D layouts or the constant `plane_z` in planar ones. This holds for
//! every state layout of [`crate::motion`] and for augmented states that append extra components.

use nalgebra::{
    Matrix1x3, Matrix2, Matrix2x3, Matrix3, Matrix3x2, SMatrix, SVector, Vector2, Vector3,
};

use serde::{Deserialize, Serialize};

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
    /// Whether component `i` is an angle whose residuals [`residual`](Self::residual) wraps to
    /// `[-π, π)` (an azimuth): what a spatial index over detections needs to know.
    fn is_angle(&self, _i: usize) -> bool {
        false
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
/// `z = [I 0] x + v`, `v ~ N(0, diag(std²))` — \[ESE\] eqs. (6) and (12) for one or more angle axes.
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
    fn is_angle(&self, i: usize) -> bool {
        i == 1
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
    fn is_angle(&self, i: usize) -> bool {
        i == 0
    }
}

/// Where the target size S of [`BearingSize`] comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TargetSize {
    /// Known size (m), `target.size_m` of the scenario.
    Known(f64),
    /// Size is the state component at this index (estimated, \[BOT\] §II.C).
    State(usize),
}

/// `[azimuth, elevation, subtended]` with `subtended = 2·atan(S / 2ρ)` (\[BOT\] §II.C, FORMAT.md §3
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
    /// Where the target size comes from.
    pub fn size(&self) -> TargetSize {
        self.size
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
    fn is_angle(&self, i: usize) -> bool {
        i == 0
    }
}

/// Where one detection puts the target: a position (ENU, m) and its covariance, the measurement
/// noise propagated to first order through the inverse of `h` (a "converted measurement"). Angle-only
/// detections are inverted with the ground-plane constraint: the target is where the line of sight
/// meets the plane `Up = plane_z` of the model's [`Geometry`] (for 3-D layouts, `plane_z` is the
/// ground height assumed for initiation). Components the detection says nothing about (Up of a
/// planar fix) have zero variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionFix {
    /// Target position (E, N, U), m.
    pub pos: Vector3<f64>,
    /// Covariance of `pos`, m².
    pub cov: Matrix3<f64>,
}

/// Measurement models that a single detection can be inverted for: what a track initiator needs to
/// start a track from any sensor kind. `None` when the detection does not fix a position (a line of
/// sight that never meets the ground plane, a range shorter than the height difference, an
/// estimated target size).
pub trait Locate<const M: usize> {
    /// The position fix of detection `z`.
    fn locate(&self, z: &SVector<f64, M>) -> Option<PositionFix>;
}

/// `pos = sensor + (r sin az, r cos az, Δu)` for horizontal range `r` and height difference `Δu`,
/// with `J = ∂pos/∂(r, az)`.
fn horizontal_fix(
    sensor: &Vector3<f64>,
    r: f64,
    az: f64,
    du: f64,
) -> (Vector3<f64>, Matrix3x2<f64>) {
    let (s, c) = az.sin_cos();
    let pos = sensor + Vector3::new(r * s, r * c, du);
    let j = Matrix3x2::new(s, r * c, c, -r * s, 0.0, 0.0);
    (pos, j)
}

/// The fix only when every entry is finite.
fn finite_fix(pos: Vector3<f64>, cov: Matrix3<f64>) -> Option<PositionFix> {
    (pos.iter().all(|v| v.is_finite()) && cov.iter().all(|v| v.is_finite())).then(|| PositionFix {
        pos,
        cov: crate::linalg::symmetrize(&cov),
    })
}

impl<const M: usize> Locate<M> for Position<M> {
    /// `pos = z` (Up = `plane_z` for 2-component fixes), `cov = R`.
    fn locate(&self, z: &SVector<f64, M>) -> Option<PositionFix> {
        let mut pos = Vector3::new(z[0], z[1], self.geometry.plane_z);
        let mut cov = Matrix3::zeros();
        for i in 0..M {
            pos[i] = z[i];
            for j in 0..M {
                cov[(i, j)] = self.r[(i, j)];
            }
        }
        finite_fix(pos, cov)
    }
}

impl Locate<2> for RangeBearing {
    /// Slant range ρ and azimuth to a target on the ground plane: horizontal range
    /// `r = √(ρ² − Δu²)`, `∂r/∂ρ = ρ / r`.
    fn locate(&self, z: &Vector2<f64>) -> Option<PositionFix> {
        let du = self.geometry.plane_z - self.sensor.z;
        let r2 = z[0] * z[0] - du * du;
        if r2.is_nan() || r2 <= 0.0 {
            return None;
        }
        let r = r2.sqrt();
        let (pos, j) = horizontal_fix(&self.sensor, r, z[1], du);
        // d(pos)/d(ρ, az) = J · diag(ρ / r, 1)
        let jz = j * Matrix2::new(z[0] / r, 0.0, 0.0, 1.0);
        finite_fix(pos, jz * self.r * jz.transpose())
    }
}

impl Locate<2> for AzEl {
    /// Line of sight meeting the ground plane: `r = Δu / tan(el)` (needs `r > 0`: looking down at a
    /// plane below or up at one above), `∂r/∂el = −Δu / sin²(el)`.
    fn locate(&self, z: &Vector2<f64>) -> Option<PositionFix> {
        let du = self.geometry.plane_z - self.sensor.z;
        let (s, c) = z[1].sin_cos();
        let r = du * c / s;
        if r.is_nan() || r <= 0.0 || s == 0.0 {
            return None;
        }
        let (pos, j) = horizontal_fix(&self.sensor, r, z[0], du);
        // d(pos)/d(az, el) = [∂pos/∂az, ∂pos/∂r · ∂r/∂el]
        let jz = Matrix3x2::from_columns(&[j.column(1).into(), j.column(0) * (-du / (s * s))]);
        finite_fix(pos, jz * self.r * jz.transpose())
    }
}

impl Locate<3> for BearingSize {
    /// Range from the subtended angle of a target of known size, `ρ = S / (2 tan(sub/2))`, along
    /// the line of sight (az, el).
    fn locate(&self, z: &Vector3<f64>) -> Option<PositionFix> {
        let TargetSize::Known(size) = self.size else {
            return None;
        };
        let half = 0.5 * z[2];
        if !(half > 0.0 && half < std::f64::consts::FRAC_PI_2) {
            return None;
        }
        let rho = size / (2.0 * half.tan());
        let drho = -size / (4.0 * half.sin().powi(2)); // ∂ρ/∂sub
        let (sa, ca) = z[0].sin_cos();
        let (se, ce) = z[1].sin_cos();
        let u = Vector3::new(ce * sa, ce * ca, se);
        let pos = self.sensor + u * rho;
        let j = Matrix3::from_columns(&[
            Vector3::new(ce * ca, -ce * sa, 0.0) * rho,
            Vector3::new(-se * sa, -se * ca, ce) * rho,
            u * drho,
        ]);
        finite_fix(pos, j * self.r * j.transpose())
    }
}

/// Measurement kinds of FORMAT.md §3: what a sensor measures, as a scenario file, a detection
/// scan and a [`SensorModel`] name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MeasKind {
    /// Absolute ENU position `[x, y]` or `[x, y, z]`.
    Position,
    /// `[range, azimuth]`.
    RangeBearing,
    /// `[azimuth, elevation]`.
    AzEl,
    /// `[azimuth, elevation, subtended]`.
    BearingSize,
}

impl MeasKind {
    /// The name used in files and messages (`position`, `range_bearing`, `az_el`,
    /// `bearing_size`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Position => "position",
            Self::RangeBearing => "range_bearing",
            Self::AzEl => "az_el",
            Self::BearingSize => "bearing_size",
        }
    }
    /// Number of components (`ncomp` for position sensors).
    pub fn len(self, ncomp: Option<usize>) -> usize {
        match self {
            Self::Position => ncomp.unwrap_or(3),
            Self::RangeBearing | Self::AzEl => 2,
            Self::BearingSize => 3,
        }
    }
    /// Index of the azimuth component that must be wrapped, if any.
    pub fn azimuth_index(self) -> Option<usize> {
        match self {
            Self::Position => None,
            Self::RangeBearing => Some(1),
            Self::AzEl | Self::BearingSize => Some(0),
        }
    }
}

/// The measurement model of a sensor whose kind is known only at run time (a scenario's sensor, a
/// detection scan's `kind`): one variant per kind of FORMAT.md §3. It is turned back into the
/// concrete, const-sized model in one place, [`SensorModel::apply`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorModel {
    /// `position`, 2 components.
    Position2(Position<2>),
    /// `position`, 3 components.
    Position3(Position<3>),
    /// `range_bearing`.
    RangeBearing(RangeBearing),
    /// `az_el`.
    AzEl(AzEl),
    /// `bearing_size`.
    BearingSize(BearingSize),
}

/// Something done with a concrete measurement model: the visitor [`SensorModel::apply`] calls with
/// the model's own type and dimension.
pub trait WithSensor<const N: usize> {
    /// What the visit returns.
    type Output;
    /// Called with the concrete model.
    fn with<H, const M: usize>(self, model: &H) -> Self::Output
    where
        H: MeasurementModel<N, M> + Locate<M>;
}

impl SensorModel {
    /// The model of kind `kind` for a sensor at `sensor` (ENU, m) with per-component noise
    /// standard deviations `std` (`position`: 2 or 3 components, by the length of `std`); `size`
    /// is the target size for `bearing_size`. Errors name what is wrong.
    pub fn new(
        kind: MeasKind,
        geometry: Geometry,
        sensor: Vector3<f64>,
        std: &[f64],
        size: Option<TargetSize>,
    ) -> Result<Self, String> {
        if let Some(bad) = std.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(format!("noise std must be finite and > 0, got {bad}"));
        }
        if !sensor.iter().all(|v| v.is_finite()) {
            return Err("sensor position is not finite".into());
        }
        let wrong = |n: &str| {
            Err(format!(
                "{kind:?} takes {n} noise components, got {}",
                std.len()
            ))
        };
        Ok(match (kind, std) {
            (MeasKind::Position, &[a, b]) => Self::Position2(Position::new(geometry, [a, b])),
            (MeasKind::Position, &[a, b, c]) => Self::Position3(Position::new(geometry, [a, b, c])),
            (MeasKind::Position, _) => return wrong("2 or 3"),
            (MeasKind::RangeBearing, &[a, b]) => {
                Self::RangeBearing(RangeBearing::new(geometry, sensor, [a, b]))
            }
            (MeasKind::AzEl, &[a, b]) => Self::AzEl(AzEl::new(geometry, sensor, [a, b])),
            (MeasKind::BearingSize, &[a, b, c]) => {
                let size = size.ok_or("bearing_size needs a target size")?;
                Self::BearingSize(BearingSize::new(geometry, sensor, size, [a, b, c]))
            }
            (MeasKind::RangeBearing | MeasKind::AzEl, _) => return wrong("2"),
            (MeasKind::BearingSize, _) => return wrong("3"),
        })
    }

    /// The measurement kind.
    pub fn kind(&self) -> MeasKind {
        match self {
            Self::Position2(_) | Self::Position3(_) => MeasKind::Position,
            Self::RangeBearing(_) => MeasKind::RangeBearing,
            Self::AzEl(_) => MeasKind::AzEl,
            Self::BearingSize(_) => MeasKind::BearingSize,
        }
    }

    /// Number of measurement components.
    pub fn dim(&self) -> usize {
        match self {
            Self::Position2(_) | Self::RangeBearing(_) | Self::AzEl(_) => 2,
            Self::Position3(_) | Self::BearingSize(_) => 3,
        }
    }

    /// Calls `visit` with the concrete model: the one place where a run-time kind becomes a
    /// const-sized model type.
    pub fn apply<const N: usize, W: WithSensor<N>>(&self, visit: W) -> W::Output {
        match self {
            Self::Position2(h) => visit.with(h),
            Self::Position3(h) => visit.with(h),
            Self::RangeBearing(h) => visit.with(h),
            Self::AzEl(h) => visit.with(h),
            Self::BearingSize(h) => visit.with(h),
        }
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

    /// Central-difference Jacobian of a measurement's inverse (z → position), for the fix covariance.
    fn fix_cov<const M: usize>(
        locate: impl Fn(&SVector<f64, M>) -> Vector3<f64>,
        z: &SVector<f64, M>,
        r: &SMatrix<f64, M, M>,
    ) -> Matrix3<f64> {
        let mut j = SMatrix::<f64, 3, M>::zeros();
        for c in 0..M {
            let e = 1e-6 * (1.0 + z[c].abs());
            let (mut zp, mut zm) = (*z, *z);
            zp[c] += e;
            zm[c] -= e;
            j.set_column(c, &((locate(&zp) - locate(&zm)) / (2.0 * e)));
        }
        j * r * j.transpose()
    }

    #[test]
    fn position_fixes_invert_every_kind() {
        let ground = Geometry::planar(5.0);
        let target = nalgebra::Vector4::new(420.0, -130.0, 3.0, 1.0);
        let truth = Vector3::new(420.0, -130.0, 5.0);
        let uav = Vector3::new(100.0, 50.0, 120.0);
        let check = |fix: PositionFix, z_cov: Matrix3<f64>| {
            assert_relative_eq!(fix.pos, truth, epsilon = 1e-6);
            assert_relative_eq!(fix.cov, z_cov, epsilon = 1e-6, max_relative = 1e-5);
        };
        let p2 = Position::new(ground, [3.0, 4.0]);
        let fix = p2
            .locate(&MeasurementModel::<4, 2>::function(&p2, &target))
            .unwrap();
        check(fix, Matrix3::from_diagonal(&Vector3::new(9.0, 16.0, 0.0)));

        let rb = RangeBearing::new(ground, uav, [2.0, 0.01]);
        let z = MeasurementModel::<4, 2>::function(&rb, &target);
        let inv = |z: &Vector2<f64>| rb.locate(z).unwrap().pos;
        check(rb.locate(&z).unwrap(), fix_cov(inv, &z, &rb.r));

        let ae = AzEl::new(ground, uav, [0.01, 0.02]);
        let z = MeasurementModel::<4, 2>::function(&ae, &target);
        let inv = |z: &Vector2<f64>| ae.locate(z).unwrap().pos;
        check(ae.locate(&z).unwrap(), fix_cov(inv, &z, &ae.r));
        // Looking up, the line of sight never meets the ground.
        assert!(ae.locate(&Vector2::new(0.3, 0.1)).is_none());

        let bs = BearingSize::new(ground, uav, TargetSize::Known(4.0), [0.01, 0.01, 1e-4]);
        let z = MeasurementModel::<4, 3>::function(&bs, &target);
        let inv = |z: &Vector3<f64>| bs.locate(z).unwrap().pos;
        check(bs.locate(&z).unwrap(), fix_cov(inv, &z, &bs.r));
        let unknown = BearingSize::new(ground, uav, TargetSize::State(6), [0.01; 3]);
        assert!(unknown.locate(&z).is_none());
    }

    #[test]
    fn sensor_models_are_built_by_kind_and_checked() {
        let g = Geometry::planar(0.0);
        let at = Vector3::new(1.0, 2.0, 3.0);
        let m = SensorModel::new(MeasKind::AzEl, g, at, &[0.01, 0.02], None).unwrap();
        assert_eq!((m.kind(), m.dim()), (MeasKind::AzEl, 2));
        assert_eq!(m, SensorModel::AzEl(AzEl::new(g, at, [0.01, 0.02])));
        let m = SensorModel::new(MeasKind::Position, g, at, &[1.0, 1.0, 2.0], None).unwrap();
        assert_eq!((m.kind(), m.dim()), (MeasKind::Position, 3));
        for (kind, std, size) in [
            (MeasKind::AzEl, &[0.01][..], None),
            (MeasKind::RangeBearing, &[1.0, -0.01][..], None),
            (MeasKind::Position, &[1.0, f64::NAN][..], None),
            (MeasKind::BearingSize, &[0.01, 0.01, 0.01][..], None),
        ] {
            let e = SensorModel::new(kind, g, at, std, size).unwrap_err();
            assert!(!e.is_empty());
        }
        assert!(
            SensorModel::new(
                MeasKind::AzEl,
                g,
                Vector3::new(f64::NAN, 0.0, 0.0),
                &[0.1; 2],
                None
            )
            .is_err()
        );
    }
}
