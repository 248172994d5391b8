//! Modified-polar (modified-spherical) coordinate EKF for bearings-only tracking from a moving
//! platform, \[BOT\] §II.A eq. (1) extended to 3-D, with the subtended-angle measurement and the
//! target-size state of \[BOT\] §II.C.
//!
//! # State
//!
//! Relative to the sensor platform (`d = target − platform`, `ḋ` its rate, both ENU), with
//! `r = |d|`, azimuth `β = atan2(dE, dN)` (FORMAT.md §1: clockwise from North) and elevation
//! `ε = atan2(dU, hypot(dE, dN))`:
//!
//! ```text
//! y = [β̇, ε̇, ṙ/r, β, ε, 1/r]            (N = 6, size known)
//! y = [β̇, ε̇, ṙ/r, β, ε, 1/r, S]         (N = 7, size S estimated, \[BOT\] §II.C)
//! ```
//!
//! The planar part `[β̇, ṙ/r, β, 1/r]` is \[BOT\] eq. (1); elevation and its rate are the 3-D
//! extension the paper mentions. The paper's text is garbled in places, so the form used is the
//! modified-polar coordinates of Aidala & Hammel 1983 \[AH83\] with the modified-spherical extension of
//! Stallard 1987 \[ST87\]. With `u = (cε sβ, cε cβ, sε)` the line-of-sight unit vector, `s = ṙ/r`,
//! `w = 1/r` and `a` the relative acceleration (target minus platform):
//!
//! ```text
//! d/dt β̇   = −2 s β̇ + 2 β̇ ε̇ tan ε + w (a·e_β) / cos ε        e_β = (cβ, −sβ, 0)
//! d/dt ε̇   = −2 s ε̇ − β̇² sin ε cos ε + w (a·e_ε)            e_ε = (−sε sβ, −sε cβ, cε)
//! d/dt ṙ/r = β̇² cos² ε + ε̇² − s² + w (a·u)
//! d/dt β = β̇,  d/dt ε = ε̇,  d/dt 1/r = −s w
//! ```
//!
//! At ε = 0 this is \[BOT\] eq. (1) with the paper's `(a_x, a_y)` = (North, East): the paper
//! measures β from its x axis towards its y axis, which is FORMAT.md's clockwise-from-North
//! azimuth when x = North and y = East ([`mp_derivative`]).
//!
//! # Prediction
//!
//! As in \[AH83\] §III the prediction is the *exact* discrete solution of these dynamics, computed
//! through relative Cartesian coordinates: `x = g(y)` ([`mp_to_relative`]), the target moves with
//! constant velocity plus a known acceleration `a_t` (the adaptive network's estimate, \[BOT\] §II.D,
//! zero without it), the platform's motion is the measured one (FORMAT.md §3: platform position and
//! velocity are exact at every measurement), and `y⁻ = g⁻¹(x⁻)` ([`relative_to_mp`]):
//!
//! ```text
//! d⁻ = d + ḋ Δt + ½ a_t Δt² − (p_s(t⁺) − p_s(t) − v_s(t) Δt)
//! ḋ⁻ = ḋ + a_t Δt − (v_s(t⁺) − v_s(t))
//! F  = ∂g⁻¹/∂x(x⁻) Φ ∂g/∂y(y),   Q_y = ∂g⁻¹/∂x(x⁻) Q_x ∂g⁻¹/∂x(x⁻)ᵀ
//! ```
//!
//! `Φ`, `Q_x` are the nearly-constant-velocity transition and continuous white-noise acceleration
//! covariance (\[BLK01\] §6.2.2) of the target; S is constant.
//!
//! # Update
//!
//! In these coordinates the angle measurements are linear and the subtended angle
//! `2·atan(S/2ρ) = 2·atan(S w / 2)` (\[BOT\] §II.C) depends on `w` and S only. The update is the EKF
//! update of [`Extended`](super::kalman::Extended) (Joseph form, Cholesky solve, wrapped azimuth
//! residual).
//!
//! # References
//! * \[BOT\] "Vision-based estimation and formation control of multiple aircraft"
//!   (`shared/papers/002`), §II.
//! * \[AH83\] V. J. Aidala, S. E. Hammel, "Utilization of modified polar coordinates for
//!   bearings-only tracking", *IEEE Trans. Automatic Control* 28(3), 1983.
//! * \[ST87\] D. V. Stallard, "An angle-only tracking filter in modified spherical coordinates",
//!   AIAA GNC 1987.
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
#![allow(non_snake_case)]

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3, Vector6};

use crate::linalg::{ensure_covariance, ensure_finite, symmetrize, wrap_angle};
use crate::measurement::{MeasurementModel, TargetSize};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Index of β̇ (azimuth rate, rad/s) in the modified-spherical state.
pub const AZ_RATE: usize = 0;
/// Index of ε̇ (elevation rate, rad/s).
pub const EL_RATE: usize = 1;
/// Index of ṙ/r (1/s).
pub const RANGE_RATE_OVER_RANGE: usize = 2;
/// Index of β (azimuth, FORMAT.md §1).
pub const AZ: usize = 3;
/// Index of ε (elevation).
pub const EL: usize = 4;
/// Index of 1/r (1/m).
pub const INV_RANGE: usize = 5;
/// Index of the target size S (m) when it is estimated (N = 7).
pub const SIZE: usize = 6;

/// Line-of-sight unit vector `u` and its partial derivatives `∂u/∂β`, `∂u/∂ε`.
fn los(beta: f64, eps: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (sb, cb) = beta.sin_cos();
    let (se, ce) = eps.sin_cos();
    (
        Vector3::new(ce * sb, ce * cb, se),
        Vector3::new(ce * cb, -ce * sb, 0.0),
        Vector3::new(-se * sb, -se * cb, ce),
    )
}

/// `x = g(y)`: modified-spherical `[β̇, ε̇, ṙ/r, β, ε, 1/r]` to relative Cartesian `[d; ḋ]` (ENU):
/// `d = u/w`, `ḋ = (s u + β̇ ∂u/∂β + ε̇ ∂u/∂ε)/w` (\[AH83\] eq. (8), spherical form of \[ST87\]).
pub fn mp_to_relative(y: &Vector6<f64>) -> Vector6<f64> {
    let (u, ub, ue) = los(y[AZ], y[EL]);
    let r = 1.0 / y[INV_RANGE];
    let d = u * r;
    let v = (u * y[RANGE_RATE_OVER_RANGE] + ub * y[AZ_RATE] + ue * y[EL_RATE]) * r;
    Vector6::new(d.x, d.y, d.z, v.x, v.y, v.z)
}

/// `∂g/∂y`, the Jacobian of [`mp_to_relative`].
pub fn mp_to_relative_jacobian(y: &Vector6<f64>) -> SMatrix<f64, 6, 6> {
    let (beta, eps) = (y[AZ], y[EL]);
    let (u, ub, ue) = los(beta, eps);
    let (sb, cb) = beta.sin_cos();
    let (se, ce) = eps.sin_cos();
    let ubb = Vector3::new(-ce * sb, -ce * cb, 0.0);
    let ube = Vector3::new(-se * cb, se * sb, 0.0);
    let uee = -u;
    let w = y[INV_RANGE];
    let r = 1.0 / w;
    let (om, et, s) = (y[AZ_RATE], y[EL_RATE], y[RANGE_RATE_OVER_RANGE]);
    let v = (u * s + ub * om + ue * et) * r;
    let mut j = SMatrix::<f64, 6, 6>::zeros();
    let mut put = |row0: usize, col: usize, c: Vector3<f64>| {
        for k in 0..3 {
            j[(row0 + k, col)] = c[k];
        }
    };
    // d = u r
    put(0, AZ, ub * r);
    put(0, EL, ue * r);
    put(0, INV_RANGE, -u * r * r);
    // ḋ = (s u + β̇ u_β + ε̇ u_ε) r
    put(3, AZ_RATE, ub * r);
    put(3, EL_RATE, ue * r);
    put(3, RANGE_RATE_OVER_RANGE, u * r);
    put(3, AZ, (ub * s + ubb * om + ube * et) * r);
    put(3, EL, (ue * s + ube * om + uee * et) * r);
    put(3, INV_RANGE, -v * r);
    j
}

/// `y = g⁻¹(x)`: relative Cartesian `[d; ḋ]` to modified-spherical coordinates (\[AH83\] eq. (9)):
/// `β = atan2(dE, dN)`, `ε = atan2(dU, h)`, `1/r`, `ṙ/r = d·ḋ/r²`,
/// `β̇ = (dN ḋE − dE ḋN)/h²`, `ε̇ = (h ḋU − dU (dE ḋE + dN ḋN)/h)/r²`, `h = hypot(dE, dN)`.
/// Fails when the target is on the platform or straight above/below it.
pub fn relative_to_mp(x: &Vector6<f64>) -> Result<Vector6<f64>> {
    let (de, dn, du) = (x[0], x[1], x[2]);
    let (ve, vn, vu) = (x[3], x[4], x[5]);
    let h2 = de * de + dn * dn;
    let h = h2.sqrt();
    let r2 = h2 + du * du;
    if !(h > 0.0 && r2.is_finite()) {
        return Err(EstimationError::NonFinite(
            "modified-spherical coordinates (target at the zenith or on the platform)",
        ));
    }
    let y = Vector6::new(
        (dn * ve - de * vn) / h2,
        (h * vu - du * (de * ve + dn * vn) / h) / r2,
        (de * ve + dn * vn + du * vu) / r2,
        de.atan2(dn),
        du.atan2(h),
        1.0 / r2.sqrt(),
    );
    ensure_finite(&y, "modified-spherical state")?;
    Ok(y)
}

/// `∂g⁻¹/∂x` at `x = g(y)`: the inverse of [`mp_to_relative_jacobian`] (inverse-function theorem;
/// a 6×6 stack LU solve). Fails where the coordinates are singular (ε = ±π/2, r → ∞).
pub fn relative_to_mp_jacobian(y: &Vector6<f64>) -> Result<SMatrix<f64, 6, 6>> {
    mp_to_relative_jacobian(y)
        .try_inverse()
        .filter(|j| j.iter().all(|v| v.is_finite()))
        .ok_or(EstimationError::NonFinite(
            "inverse modified-spherical Jacobian",
        ))
}

/// Time derivative of the modified-spherical state under relative acceleration `a` (ENU): the 3-D
/// extension of \[BOT\] eq. (1) given in the module docs. The filter propagates with the exact
/// discrete solution instead (\[AH83\] §III); this is its continuous-time counterpart.
pub fn mp_derivative(y: &Vector6<f64>, a: &Vector3<f64>) -> Vector6<f64> {
    let (u, ub, ue) = los(y[AZ], y[EL]);
    let ce = y[EL].cos();
    let e_beta = ub / ce;
    let (om, et, s, w) = (
        y[AZ_RATE],
        y[EL_RATE],
        y[RANGE_RATE_OVER_RANGE],
        y[INV_RANGE],
    );
    let (se, _) = y[EL].sin_cos();
    Vector6::new(
        -2.0 * s * om + 2.0 * om * et * se / ce + w * a.dot(&e_beta) / ce,
        -2.0 * s * et - om * om * se * ce + w * a.dot(&ue),
        om * om * ce * ce + et * et - s * s + w * a.dot(&u),
        om,
        et,
        -s * w,
    )
}

/// Known platform motion between two measurement times (FORMAT.md §3: exact).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformStep {
    /// Platform position at the start (ENU, m).
    pub from_pos: Vector3<f64>,
    /// Platform velocity at the start (m/s).
    pub from_vel: Vector3<f64>,
    /// Platform position at the end.
    pub to_pos: Vector3<f64>,
    /// Platform velocity at the end.
    pub to_vel: Vector3<f64>,
}

/// The modified-polar EKF's motion tuning: continuous white-noise target acceleration of spectral
/// density `q_horizontal` on East/North and `q_vertical` on Up (m²/s³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModifiedPolarEkf {
    /// Horizontal acceleration spectral density (m²/s³).
    pub q_horizontal: f64,
    /// Vertical acceleration spectral density (m²/s³).
    pub q_vertical: f64,
}

/// The kinematic 6-block of an N-state (N = 6 or 7).
fn kinematic<const N: usize>(v: &SVector<f64, N>) -> Vector6<f64> {
    Vector6::from_fn(|i, _| v[i])
}

impl ModifiedPolarEkf {
    /// Filter with acceleration spectral densities `q_horizontal`, `q_vertical` ≥ 0.
    pub fn new(q_horizontal: f64, q_vertical: f64) -> Result<Self> {
        if q_horizontal.is_finite()
            && q_horizontal >= 0.0
            && q_vertical.is_finite()
            && q_vertical >= 0.0
        {
            Ok(Self {
                q_horizontal,
                q_vertical,
            })
        } else {
            Err(EstimationError::InvalidParameter(format!(
                "acceleration spectral densities must be ≥ 0, got {q_horizontal}, {q_vertical}"
            )))
        }
    }

    /// Relative Cartesian process noise `Q_x` over `dt` (\[BLK01\] eq. (6.2.2-12) per axis).
    fn cartesian_noise(&self, dt: f64) -> SMatrix<f64, 6, 6> {
        let mut q = SMatrix::<f64, 6, 6>::zeros();
        for (a, qa) in [self.q_horizontal, self.q_horizontal, self.q_vertical]
            .into_iter()
            .enumerate()
        {
            q[(a, a)] = qa * dt.powi(3) / 3.0;
            q[(a, a + 3)] = qa * dt * dt / 2.0;
            q[(a + 3, a)] = qa * dt * dt / 2.0;
            q[(a + 3, a + 3)] = qa * dt;
        }
        q
    }

    /// Exact relative Cartesian propagation `x⁻ = Φ x + (target acceleration) − (platform motion)`.
    fn propagate_relative(
        x: &Vector6<f64>,
        platform: &PlatformStep,
        accel: &Vector3<f64>,
        dt: f64,
    ) -> Vector6<f64> {
        let d = Vector3::new(x[0], x[1], x[2]);
        let v = Vector3::new(x[3], x[4], x[5]);
        let platform_dp = platform.to_pos - platform.from_pos - platform.from_vel * dt;
        let d1 = d + v * dt + accel * (0.5 * dt * dt) - platform_dp;
        let v1 = v + accel * dt - (platform.to_vel - platform.from_vel);
        Vector6::new(d1.x, d1.y, d1.z, v1.x, v1.y, v1.z)
    }

    /// Predicted mean only: `y⁻ = g⁻¹(Φ g(y) + …)` (module docs).
    pub fn predict_mean<const N: usize>(
        &self,
        y: &SVector<f64, N>,
        platform: &PlatformStep,
        accel: &Vector3<f64>,
        dt: f64,
    ) -> Result<SVector<f64, N>> {
        let x = Self::propagate_relative(&mp_to_relative(&kinematic(y)), platform, accel, dt);
        let y6 = relative_to_mp(&x)?;
        let mut out = *y;
        out.fixed_rows_mut::<6>(0).copy_from(&y6);
        // Keep the predicted azimuth next to the prior one (continuity; the value is wrapped).
        out[AZ] = wrap_angle(out[AZ]);
        Ok(out)
    }

    /// Time update over `dt` with the platform's known motion and an assumed target acceleration
    /// `accel` (ENU, m/s²; zero for the plain filter, the network's output for the adaptive one).
    /// The prior is left untouched on error.
    pub fn predict<const N: usize>(
        &self,
        prior: &Gaussian<N>,
        platform: &PlatformStep,
        accel: &Vector3<f64>,
        dt: f64,
    ) -> Result<Gaussian<N>> {
        const {
            assert!(
                N == 6 || N == 7,
                "modified-spherical state has 6 or 7 components"
            )
        };
        let y = kinematic(&prior.mean);
        let x = mp_to_relative(&y);
        let x1 = Self::propagate_relative(&x, platform, accel, dt);
        let y1 = relative_to_mp(&x1)?;
        let jin = mp_to_relative_jacobian(&y);
        let jout = relative_to_mp_jacobian(&y1)?;
        let mut phi = SMatrix::<f64, 6, 6>::identity();
        for a in 0..3 {
            phi[(a, a + 3)] = dt;
        }
        let f6 = jout * phi * jin;
        let q6 = jout * self.cartesian_noise(dt) * jout.transpose();
        let mut F = SMatrix::<f64, N, N>::identity();
        F.fixed_view_mut::<6, 6>(0, 0).copy_from(&f6);
        let mut Q = SMatrix::<f64, N, N>::zeros();
        Q.fixed_view_mut::<6, 6>(0, 0).copy_from(&q6);
        let mut mean = prior.mean;
        mean.fixed_rows_mut::<6>(0).copy_from(&y1);
        let cov = symmetrize(&(F * prior.cov * F.transpose() + Q));
        ensure_finite(&mean, "predicted mean")?;
        ensure_covariance(&cov, "predicted covariance")?;
        Ok(Gaussian { mean, cov })
    }
}

/// Enforces `x[index] ≥ min` on a Gaussian by estimate projection (Simon & Chia 2002, with the
/// covariance as weight): `x ← x − P eᵢ (xᵢ − min) / Pᵢᵢ` when violated, covariance unchanged. Used
/// to keep 1/r (and S) positive after an angles-only update has overshot through infinite range,
/// the known failure of linear updates in these coordinates (\[AH83\] §IV).
pub fn project_lower_bound<const N: usize>(
    g: &Gaussian<N>,
    index: usize,
    min: f64,
) -> Result<Gaussian<N>> {
    if index >= N || !min.is_finite() {
        return Err(EstimationError::InvalidParameter(format!(
            "lower bound on component {index} of {N}: {min}"
        )));
    }
    let excess = g.mean[index] - min;
    if excess >= 0.0 {
        return Ok(*g);
    }
    let pii = g.cov[(index, index)];
    if pii.is_nan() || pii <= 0.0 {
        return Err(EstimationError::NotPositiveDefinite("state covariance"));
    }
    let mut mean = g.mean - g.cov.column(index) * (excess / pii);
    mean[index] = min;
    ensure_finite(&mean, "projected mean")?;
    Ok(Gaussian { mean, cov: g.cov })
}

/// Absolute Cartesian Gaussian `[x, y, z, vx, vy, vz]` (ENU) of a modified-spherical Gaussian, the
/// platform being at `platform_pos` with velocity `platform_vel`: mean `g(y) + platform`,
/// covariance `J P Jᵀ` with `J = ∂g/∂y` (first-order transform).
pub fn to_cartesian<const N: usize>(
    g: &Gaussian<N>,
    platform_pos: &Vector3<f64>,
    platform_vel: &Vector3<f64>,
) -> Result<Gaussian<6>> {
    let y = kinematic(&g.mean);
    let x = mp_to_relative(&y);
    let mean = x + Vector6::new(
        platform_pos.x,
        platform_pos.y,
        platform_pos.z,
        platform_vel.x,
        platform_vel.y,
        platform_vel.z,
    );
    let j = mp_to_relative_jacobian(&y);
    let p6 = g.cov.fixed_view::<6, 6>(0, 0).into_owned();
    let cov = symmetrize(&(j * p6 * j.transpose()));
    ensure_finite(&mean, "Cartesian mean")?;
    ensure_covariance(&cov, "Cartesian covariance")?;
    Ok(Gaussian { mean, cov })
}

/// Modified-spherical Gaussian of an absolute Cartesian Gaussian `cart` seen from the platform:
/// mean `g⁻¹(x − platform)`, covariance `J⁻¹ P J⁻ᵀ` (first-order transform). With N = 7 the size
/// component is appended from `size = (mean, variance)`, uncorrelated (\[BOT\] §II.C).
pub fn from_cartesian<const N: usize>(
    cart: &Gaussian<6>,
    platform_pos: &Vector3<f64>,
    platform_vel: &Vector3<f64>,
    size: Option<(f64, f64)>,
) -> Result<Gaussian<N>> {
    const {
        assert!(
            N == 6 || N == 7,
            "modified-spherical state has 6 or 7 components"
        )
    };
    let rel = cart.mean
        - Vector6::new(
            platform_pos.x,
            platform_pos.y,
            platform_pos.z,
            platform_vel.x,
            platform_vel.y,
            platform_vel.z,
        );
    let y = relative_to_mp(&rel)?;
    let j = relative_to_mp_jacobian(&y)?;
    let mut mean = SVector::<f64, N>::zeros();
    mean.fixed_rows_mut::<6>(0).copy_from(&y);
    let mut cov = SMatrix::<f64, N, N>::zeros();
    cov.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&symmetrize(&(j * cart.cov * j.transpose())));
    if N == 7 {
        let (m, var) = size.ok_or_else(|| {
            EstimationError::InvalidParameter("a size state needs a size prior".into())
        })?;
        mean[N - 1] = m;
        cov[(N - 1, N - 1)] = var;
    }
    Gaussian::new(mean, cov)
}

fn diag_sq<const M: usize>(std: [f64; M]) -> SMatrix<f64, M, M> {
    SMatrix::<f64, M, M>::from_diagonal(&SVector::<f64, M>::from_fn(|i, _| std[i] * std[i]))
}

/// `[azimuth, elevation, subtended]` on a modified-spherical state: `z = [β, ε, 2·atan(S w/2)]`
/// (\[BOT\] §II.C, FORMAT.md §3 `bearing_size`). S is known or the state component [`SIZE`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpBearingSize {
    size: TargetSize,
    r: Matrix3<f64>,
}

impl MpBearingSize {
    /// Model with noise std `[σ_az, σ_el, σ_sub]` (rad).
    pub fn new(size: TargetSize, std: [f64; 3]) -> Self {
        Self {
            size,
            r: diag_sq(std),
        }
    }
}

impl<const N: usize> MeasurementModel<N, 3> for MpBearingSize {
    fn function(&self, y: &SVector<f64, N>) -> Vector3<f64> {
        let s = match self.size {
            TargetSize::Known(s) => s,
            TargetSize::State(i) => y[i],
        };
        Vector3::new(y[AZ], y[EL], 2.0 * (0.5 * s * y[INV_RANGE]).atan())
    }
    fn jacobian(&self, y: &SVector<f64, N>) -> SMatrix<f64, 3, N> {
        let w = y[INV_RANGE];
        let s = match self.size {
            TargetSize::Known(s) => s,
            TargetSize::State(i) => y[i],
        };
        // d/dw 2·atan(S w/2) = S/(1 + (S w/2)²);  d/dS = w/(1 + (S w/2)²).
        let den = 1.0 + 0.25 * s * s * w * w;
        let mut j = SMatrix::<f64, 3, N>::zeros();
        j[(0, AZ)] = 1.0;
        j[(1, EL)] = 1.0;
        j[(2, INV_RANGE)] = s / den;
        if let TargetSize::State(i) = self.size {
            j[(2, i)] = w / den;
        }
        j
    }
    fn covar(&self) -> Matrix3<f64> {
        self.r
    }
    fn residual(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(wrap_angle(a[0] - b[0]), a[1] - b[1], a[2] - b[2])
    }
}

/// `[azimuth, elevation]` on a modified-spherical state: `z = [β, ε]` (FORMAT.md §3 `az_el`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpAzEl {
    r: SMatrix<f64, 2, 2>,
}

impl MpAzEl {
    /// Model with noise std `[σ_az, σ_el]` (rad).
    pub fn new(std: [f64; 2]) -> Self {
        Self { r: diag_sq(std) }
    }
}

impl<const N: usize> MeasurementModel<N, 2> for MpAzEl {
    fn function(&self, y: &SVector<f64, N>) -> Vector2<f64> {
        Vector2::new(y[AZ], y[EL])
    }
    fn jacobian(&self, _y: &SVector<f64, N>) -> SMatrix<f64, 2, N> {
        let mut j = SMatrix::<f64, 2, N>::zeros();
        j[(0, AZ)] = 1.0;
        j[(1, EL)] = 1.0;
        j
    }
    fn covar(&self) -> SMatrix<f64, 2, 2> {
        self.r
    }
    fn residual(&self, a: &Vector2<f64>, b: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new(wrap_angle(a[0] - b[0]), a[1] - b[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::kalman::Extended;
    use crate::filter::traits::Updater;
    use crate::measurement::{BearingSize, Geometry};
    use approx::assert_relative_eq;

    fn sample() -> Vector6<f64> {
        // target 300 m East, 450 m South, 120 m up of the platform, moving.
        relative_to_mp(&Vector6::new(300.0, -450.0, 120.0, 3.0, -11.0, 0.5)).unwrap()
    }

    fn numeric<const M: usize>(
        f: impl Fn(&Vector6<f64>) -> SVector<f64, M>,
        y: &Vector6<f64>,
    ) -> SMatrix<f64, M, 6> {
        let mut j = SMatrix::<f64, M, 6>::zeros();
        for c in 0..6 {
            let e = 1e-6 * (1.0 + y[c].abs());
            let (mut yp, mut ym) = (*y, *y);
            yp[c] += e;
            ym[c] -= e;
            j.set_column(c, &((f(&yp) - f(&ym)) / (2.0 * e)));
        }
        j
    }

    #[test]
    fn conversion_round_trips_in_every_quadrant() {
        for x in [
            Vector6::new(300.0, -450.0, 120.0, 3.0, -11.0, 0.5),
            Vector6::new(-30.0, 45.0, -12.0, -3.0, 20.0, -1.0),
            Vector6::new(-300.0, -4500.0, 0.0, 30.0, 0.0, 0.0),
            Vector6::new(0.5, 1.0, 0.0, 0.0, 0.0, 0.0),
        ] {
            let y = relative_to_mp(&x).unwrap();
            assert_relative_eq!(mp_to_relative(&y), x, epsilon = 1e-9, max_relative = 1e-12);
            assert_relative_eq!(
                relative_to_mp(&mp_to_relative(&y)).unwrap(),
                y,
                epsilon = 1e-12
            );
            assert!((-std::f64::consts::PI..std::f64::consts::PI).contains(&y[AZ]));
        }
        // clockwise from North: a target due East has β = π/2
        let y = relative_to_mp(&Vector6::new(10.0, 0.0, 0.0, 0.0, 1.0, 0.0)).unwrap();
        assert_relative_eq!(y[AZ], std::f64::consts::FRAC_PI_2);
        // moving North while East of the platform: β decreases (counter-clockwise)
        assert!(y[AZ_RATE] < 0.0);
    }

    #[test]
    fn jacobians_match_central_differences() {
        let y = sample();
        assert_relative_eq!(
            mp_to_relative_jacobian(&y),
            numeric(mp_to_relative, &y),
            epsilon = 1e-4,
            max_relative = 1e-6
        );
        let x = mp_to_relative(&y);
        let jinv = relative_to_mp_jacobian(&y).unwrap();
        let mut num = SMatrix::<f64, 6, 6>::zeros();
        for c in 0..6 {
            let e = 1e-5 * (1.0 + x[c].abs());
            let (mut xp, mut xm) = (x, x);
            xp[c] += e;
            xm[c] -= e;
            num.set_column(
                c,
                &((relative_to_mp(&xp).unwrap() - relative_to_mp(&xm).unwrap()) / (2.0 * e)),
            );
        }
        assert_relative_eq!(jinv, num, epsilon = 1e-9, max_relative = 1e-5);
        // measurement Jacobian with a size state
        let mut y7 = SVector::<f64, 7>::zeros();
        y7.fixed_rows_mut::<6>(0).copy_from(&y);
        y7[SIZE] = 11.0;
        let m = MpBearingSize::new(TargetSize::State(SIZE), [1e-3; 3]);
        let mut num = SMatrix::<f64, 3, 7>::zeros();
        for c in 0..7 {
            let e = 1e-6 * (1.0 + y7[c].abs());
            let (mut yp, mut ym) = (y7, y7);
            yp[c] += e;
            ym[c] -= e;
            num.set_column(c, &((m.function(&yp) - m.function(&ym)) / (2.0 * e)));
        }
        assert_relative_eq!(m.jacobian(&y7), num, epsilon = 1e-8, max_relative = 1e-6);
    }

    #[test]
    fn measurements_agree_with_the_cartesian_model() {
        let y = sample();
        let x = mp_to_relative(&y);
        let cart = BearingSize::new(
            Geometry::spatial(),
            Vector3::zeros(),
            TargetSize::Known(12.0),
            [1e-3; 3],
        );
        let mp = MpBearingSize::new(TargetSize::Known(12.0), [1e-3; 3]);
        let a: Vector3<f64> = cart.function(&x);
        let b: Vector3<f64> = mp.function(&y);
        assert_relative_eq!(a, b, epsilon = 1e-12);
    }

    #[test]
    fn derivative_is_the_limit_of_the_exact_propagation() {
        let y = sample();
        let a = Vector3::new(1.5, -2.0, 0.3);
        let f = ModifiedPolarEkf::new(1.0, 1.0).unwrap();
        let still = PlatformStep {
            from_pos: Vector3::zeros(),
            from_vel: Vector3::zeros(),
            to_pos: Vector3::zeros(),
            to_vel: Vector3::zeros(),
        };
        let dt = 1e-4;
        let fwd = f.predict_mean(&y, &still, &a, dt).unwrap();
        let back = f.predict_mean(&y, &still, &a, -dt).unwrap();
        let num = (fwd - back) / (2.0 * dt);
        assert_relative_eq!(
            mp_derivative(&y, &a),
            num,
            epsilon = 1e-8,
            max_relative = 1e-5
        );
        // planar case: the paper's eq. (1) with (a_x, a_y) = (North, East)
        let yp = relative_to_mp(&Vector6::new(80.0, 60.0, 0.0, -5.0, 7.0, 0.0)).unwrap();
        let d = mp_derivative(&yp, &a);
        let (b, om, s, w) = (
            yp[AZ],
            yp[AZ_RATE],
            yp[RANGE_RATE_OVER_RANGE],
            yp[INV_RANGE],
        );
        let (ax, ay) = (a.y, a.x);
        assert_relative_eq!(
            d[AZ_RATE],
            -2.0 * om * s + w * (ay * b.cos() - ax * b.sin())
        );
        assert_relative_eq!(
            d[RANGE_RATE_OVER_RANGE],
            om * om - s * s + w * (ay * b.sin() + ax * b.cos()),
            epsilon = 1e-15
        );
        assert_relative_eq!(d[INV_RANGE], -s * w);
    }

    #[test]
    fn prediction_and_cartesian_covariance_agree_with_a_cartesian_cv_filter() {
        // Known platform motion, no process noise: the MP prediction mapped to Cartesian equals the
        // Cartesian CV prediction (first order) of the same Gaussian.
        let f = ModifiedPolarEkf::new(0.0, 0.0).unwrap();
        let cart = Gaussian::new(
            Vector6::new(300.0, -450.0, 120.0, 3.0, -11.0, 0.5),
            SMatrix::<f64, 6, 6>::from_diagonal(&Vector6::new(0.1, 0.1, 0.1, 0.01, 0.01, 0.01)),
        )
        .unwrap();
        let (p0, v0) = (Vector3::new(1.0, 2.0, 3.0), Vector3::new(20.0, 5.0, 0.0));
        let (p1, v1) = (Vector3::new(21.5, 7.0, 3.0), Vector3::new(21.0, 5.0, 0.0));
        let g: Gaussian<6> = from_cartesian(&cart, &p0, &v0, None).unwrap();
        let back = to_cartesian(&g, &p0, &v0).unwrap();
        assert_relative_eq!(back.mean, cart.mean, epsilon = 1e-9);
        assert_relative_eq!(back.cov, cart.cov, epsilon = 1e-9);
        let step = PlatformStep {
            from_pos: p0,
            from_vel: v0,
            to_pos: p1,
            to_vel: v1,
        };
        let pred = f.predict(&g, &step, &Vector3::zeros(), 1.0).unwrap();
        let c1 = to_cartesian(&pred, &p1, &v1).unwrap();
        let mut phi = SMatrix::<f64, 6, 6>::identity();
        for a in 0..3 {
            phi[(a, a + 3)] = 1.0;
        }
        assert_relative_eq!(c1.mean, phi * cart.mean, epsilon = 1e-9);
        assert_relative_eq!(c1.cov, phi * cart.cov * phi.transpose(), epsilon = 1e-8);
    }

    #[test]
    fn projection_enforces_the_bound_along_the_covariance() {
        let mean = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, -0.001);
        let mut cov = SMatrix::<f64, 6, 6>::identity();
        cov[(2, INV_RANGE)] = 0.5;
        cov[(INV_RANGE, 2)] = 0.5;
        let g = Gaussian::new(mean, cov).unwrap();
        let p = project_lower_bound(&g, INV_RANGE, 1e-5).unwrap();
        assert_relative_eq!(p.mean[INV_RANGE], 1e-5);
        assert_relative_eq!(p.mean[2], 0.5 * (0.001 + 1e-5), epsilon = 1e-15);
        assert_eq!(p.mean[0], 0.0);
        assert_eq!(project_lower_bound(&p, INV_RANGE, 1e-5).unwrap(), p);
        assert!(project_lower_bound(&g, 9, 0.0).is_err());
    }

    #[test]
    fn update_with_the_size_state_moves_towards_the_measurement() {
        let y = sample();
        let mut mean = SVector::<f64, 7>::zeros();
        mean.fixed_rows_mut::<6>(0).copy_from(&y);
        mean[SIZE] = 12.0;
        let mut cov = SMatrix::<f64, 7, 7>::identity() * 1e-4;
        cov[(INV_RANGE, INV_RANGE)] = (0.2 * y[INV_RANGE]).powi(2);
        cov[(SIZE, SIZE)] = 9.0;
        let g = Gaussian::new(mean, cov).unwrap();
        let m = MpBearingSize::new(TargetSize::State(SIZE), [1e-3; 3]);
        let z0: Vector3<f64> = m.function(&mean);
        let z = Vector3::new(z0[0], z0[1], z0[2] * 0.9);
        let post = Extended.update(&m, &g, &z).unwrap();
        let z1: Vector3<f64> = m.function(&post.state.mean);
        assert!((z1[2] - z[2]).abs() < (z0[2] - z[2]).abs());
        assert!(post.state.cov[(SIZE, SIZE)] < 9.0);
    }
}
