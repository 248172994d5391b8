//! Motion (transition) models: `x_k = f(x_{k−1}, Δt) + w`, `w ~ N(0, Q(Δt))`.
//!
//! State layouts (D = spatial dimension, 2 or 3):
//!
//! * [`ConstantVelocity<N>`], N = 2D: `[p₁..p_D, v₁..v_D]`, i.e. `[x, y, vx, vy]` or
//!   `[x, y, z, vx, vy, vz]`;
//! * [`ConstantAcceleration<N>`], N = 3D: `[p, v, a]` blocks;
//! * [`ConstantTurn<N>`], N = 4 or 6: the CV layout, horizontal turn at a known rate ω
//!   (ω > 0 counter-clockwise seen from above, FORMAT.md §1), z in straight flight.
//!
//! Process noise is continuous white noise of spectral density `q` on the highest derivative,
//! discretised exactly (Bar-Shalom, Li & Kirubarajan 2001, §6.2.2 and §6.2.3).
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.

use nalgebra::{SMatrix, SVector};

/// `x_k = f(x_{k−1}, Δt) + w`, `w ~ N(0, Q)`.
pub trait TransitionModel<const N: usize> {
    /// `f(x, Δt)`.
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N>;
    /// `∂f/∂x` at `x`.
    fn jacobian(&self, x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N>;
    /// Process-noise covariance `Q(Δt)`.
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N>;
    /// `F P Fᵀ` with `F = ∂f/∂x` at `x`: the propagated covariance without `Q`. Models whose `F`
    /// is sparse override it to skip the dense N×N×N products (the CV model does).
    fn propagate_cov(
        &self,
        x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
        dt: f64,
    ) -> SMatrix<f64, N, N> {
        let f = self.jacobian(x, dt);
        f * p * f.transpose()
    }
}

/// A transition model with `f(x) = F x`.
pub trait LinearTransition<const N: usize>: TransitionModel<N> {
    /// The transition matrix `F(Δt)`.
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N>;
}

/// Nearly-constant velocity with continuous white-noise acceleration (\[BLK01\] §6.2.2):
///
/// ```text
/// F = [I  Δt·I]      Q = q [Δt³/3·I  Δt²/2·I]
///     [0    I ]            [Δt²/2·I    Δt·I ]
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocity<const N: usize> {
    /// Spectral density of the acceleration noise, m²/s³ (`accel_std²` of FORMAT.md).
    pub q: f64,
}

impl<const N: usize> ConstantVelocity<N> {
    /// CV model with acceleration spectral density `q` (m²/s³).
    pub fn new(q: f64) -> Self {
        const { assert!(N % 2 == 0, "CV state is [position; velocity]") };
        Self { q }
    }
}

impl<const N: usize> TransitionModel<N> for ConstantVelocity<N> {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        self.matrix(dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        self.matrix(dt)
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_noise::<N, 2>(self.q, dt)
    }
    /// Block form of `F P Fᵀ` for `F = [I Δt·I; 0 I]`, `P = [A B; Bᵀ C]`:
    /// `[A + Δt(B + Bᵀ) + Δt²C,  B + Δt·C;  Bᵀ + Δt·C,  C]` (same result as the dense product).
    fn propagate_cov(
        &self,
        _x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
        dt: f64,
    ) -> SMatrix<f64, N, N> {
        let d = N / 2;
        SMatrix::<f64, N, N>::from_fn(|i, j| match (i < d, j < d) {
            (true, true) => {
                p[(i, j)] + dt * (p[(i, j + d)] + p[(i + d, j)]) + dt * dt * p[(i + d, j + d)]
            }
            (true, false) => p[(i, j)] + dt * p[(i + d, j)],
            (false, true) => p[(i, j)] + dt * p[(i, j + d)],
            (false, false) => p[(i, j)],
        })
    }
}

impl<const N: usize> LinearTransition<N> for ConstantVelocity<N> {
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_matrix::<N, 2>(dt)
    }
}

/// Nearly-constant acceleration with continuous white-noise jerk (\[BLK01\] §6.2.3; the CA model of
/// \[ESE\] §4):
///
/// ```text
/// F = [I  Δt·I  Δt²/2·I]      Q = q [Δt⁵/20  Δt⁴/8  Δt³/6]
///     [0    I     Δt·I ]            [Δt⁴/8   Δt³/3  Δt²/2]  (⊗ I)
///     [0    0       I  ]            [Δt³/6   Δt²/2   Δt  ]
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantAcceleration<const N: usize> {
    /// Spectral density of the jerk noise (units of the position squared per s⁵).
    pub q: f64,
}

impl<const N: usize> ConstantAcceleration<N> {
    /// CA model with jerk spectral density `q`.
    pub fn new(q: f64) -> Self {
        const { assert!(N % 3 == 0, "CA state is [position; velocity; acceleration]") };
        Self { q }
    }
}

impl<const N: usize> TransitionModel<N> for ConstantAcceleration<N> {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        self.matrix(dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        self.matrix(dt)
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_noise::<N, 3>(self.q, dt)
    }
}

impl<const N: usize> LinearTransition<N> for ConstantAcceleration<N> {
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_matrix::<N, 3>(dt)
    }
}

/// Coordinated turn at a known rate ω in the horizontal plane (\[BLK01\] §11.7.1, eq. (11.7.1-4)),
/// straight flight along z for N = 6. ω > 0 turns left (counter-clockwise seen from above).
///
/// ```text
/// x' = x + sin(ωΔt)/ω·vx − (1 − cos(ωΔt))/ω·vy      vx' = cos(ωΔt)·vx − sin(ωΔt)·vy
/// y' = y + (1 − cos(ωΔt))/ω·vx + sin(ωΔt)/ω·vy      vy' = sin(ωΔt)·vx + cos(ωΔt)·vy
/// ```
///
/// The process noise is the CV model's white-noise acceleration `Q` (a common approximation for
/// known-rate turns, \[BLK01\] §11.7.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantTurn<const N: usize> {
    /// Turn rate ω, rad/s, positive counter-clockwise.
    pub omega: f64,
    /// Acceleration spectral density, m²/s³.
    pub q: f64,
}

impl<const N: usize> ConstantTurn<N> {
    /// CT model with known rate `omega` (rad/s) and acceleration spectral density `q`.
    pub fn new(omega: f64, q: f64) -> Self {
        const {
            assert!(
                N == 4 || N == 6,
                "CT is defined for [x, y, vx, vy] and 3-D CV layouts"
            )
        };
        Self { omega, q }
    }
}

impl<const N: usize> TransitionModel<N> for ConstantTurn<N> {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        self.matrix(dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        self.matrix(dt)
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_noise::<N, 2>(self.q, dt)
    }
    /// Block form of `F P Fᵀ` for `F = [I A; 0 G]` (A, G the position–velocity and velocity blocks
    /// of the turn): `[P₁₁ + A P₂₁ + P₁₂ Aᵀ + A P₂₂ Aᵀ, (P₁₂ + A P₂₂) Gᵀ; G (P₂₁ + P₂₂ Aᵀ), G P₂₂ Gᵀ]`,
    /// with D × D blocks instead of one dense N × N × N product.
    fn propagate_cov(
        &self,
        _x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
        dt: f64,
    ) -> SMatrix<f64, N, N> {
        let d = N / 2;
        let f = self.matrix(dt);
        // P₂₂ Aᵀ (D × D) and G rows, read from F: A = F[0..d, d..N], G = F[d..N, d..N].
        let a = |i: usize, k: usize| f[(i, d + k)];
        let g = |i: usize, k: usize| f[(d + i, d + k)];
        // B = P₁₂ + A P₂₂ (D × D, rows: position), C = B Gᵀ, T = P₂₂ Aᵀ.
        let mut out = SMatrix::<f64, N, N>::zeros();
        let mut b = [[0.0; 3]; 3];
        let mut gp = [[0.0; 3]; 3]; // G P₂₂
        for i in 0..d {
            for j in 0..d {
                let (mut ab, mut gq) = (p[(i, d + j)], 0.0);
                for k in 0..d {
                    ab += a(i, k) * p[(d + k, d + j)];
                    gq += g(i, k) * p[(d + k, d + j)];
                }
                b[i][j] = ab;
                gp[i][j] = gq;
            }
        }
        for i in 0..d {
            for j in 0..d {
                // Top-left: P₁₁ + A P₂₁ + B Aᵀ  (= P₁₁ + A P₂₁ + P₁₂ Aᵀ + A P₂₂ Aᵀ).
                let mut tl = p[(i, j)];
                let (mut tr, mut br) = (0.0, 0.0);
                for k in 0..d {
                    tl += a(i, k) * p[(d + k, j)] + b[i][k] * a(j, k);
                    tr += b[i][k] * g(j, k);
                    br += gp[i][k] * g(j, k);
                }
                out[(i, j)] = tl;
                out[(i, d + j)] = tr;
                out[(d + j, i)] = tr;
                out[(d + i, d + j)] = br;
            }
        }
        out
    }
}

impl<const N: usize> LinearTransition<N> for ConstantTurn<N> {
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N> {
        let d = N / 2;
        let mut f = kinematic_matrix::<N, 2>(dt);
        let wt = self.omega * dt;
        let (s, c) = wt.sin_cos();
        // sin(ωΔt)/ω and (1 − cos(ωΔt))/ω, with their ω → 0 limits Δt and ωΔt²/2.
        let (a, b) = if wt.abs() < 1e-9 {
            (dt, 0.5 * wt * dt)
        } else {
            (s / self.omega, (1.0 - c) / self.omega)
        };
        let (x, y, vx, vy) = (0, 1, d, d + 1);
        f[(x, vx)] = a;
        f[(x, vy)] = -b;
        f[(y, vx)] = b;
        f[(y, vy)] = a;
        f[(vx, vx)] = c;
        f[(vx, vy)] = -s;
        f[(vy, vx)] = s;
        f[(vy, vy)] = c;
        f
    }
}

/// Nearly-constant acceleration in the discrete Wiener-process acceleration form (\[BLK01\] §6.3.3),
/// the CA model of \[ESE\] §4. State `[p; v; a]` in blocks of D = N/3 axes, as in
/// [`ConstantAcceleration`]:
///
/// ```text
/// F = [I  T·I  T²/2·I]      Q = σ² Γ Γᵀ ⊗ I,   Γ = [T²/2, T, 1]ᵀ
///     [0   I     T·I ]
///     [0   0      I  ]
/// ```
///
/// σ is the standard deviation of the acceleration increment over one sampling period (units of the
/// position per s², per step). Unlike a continuous-time density it does not rescale with T.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WienerAcceleration<const N: usize> {
    /// Std σ of the acceleration increment per sampling period.
    pub sigma: f64,
}

impl<const N: usize> WienerAcceleration<N> {
    /// Discrete Wiener-process acceleration model with increment std `sigma`.
    pub fn new(sigma: f64) -> Self {
        const { assert!(N % 3 == 0, "CA state is [position; velocity; acceleration]") };
        Self { sigma }
    }
}

impl<const N: usize> TransitionModel<N> for WienerAcceleration<N> {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        self.matrix(dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        self.matrix(dt)
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        let d = N / 3;
        let gamma = [0.5 * dt * dt, dt, 1.0];
        let s2 = self.sigma * self.sigma;
        let mut q = SMatrix::<f64, N, N>::zeros();
        for (i, gi) in gamma.iter().enumerate() {
            for (j, gj) in gamma.iter().enumerate() {
                for a in 0..d {
                    q[(i * d + a, j * d + a)] = s2 * gi * gj;
                }
            }
        }
        q
    }
}

impl<const N: usize> LinearTransition<N> for WienerAcceleration<N> {
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N> {
        kinematic_matrix::<N, 3>(dt)
    }
}

/// Block transition matrix of a K-th order kinematic chain (K = 2: CV, K = 3: CA), D = N/K axes.
fn kinematic_matrix<const N: usize, const K: usize>(dt: f64) -> SMatrix<f64, N, N> {
    let d = N / K;
    let mut f = SMatrix::<f64, N, N>::identity();
    for i in 0..K {
        for j in (i + 1)..K {
            let p = (j - i) as i32;
            let coef = dt.powi(p) / factorial(p);
            for a in 0..d {
                f[(i * d + a, j * d + a)] = coef;
            }
        }
    }
    f
}

/// Exactly discretised continuous white noise on the K-th state derivative:
/// `Q_ij = q Δt^(2K−1−i−j) / ((K−1−i)! (K−1−j)! (2K−1−i−j))`, i, j = 0..K−1.
fn kinematic_noise<const N: usize, const K: usize>(q: f64, dt: f64) -> SMatrix<f64, N, N> {
    let d = N / K;
    let mut m = SMatrix::<f64, N, N>::zeros();
    for i in 0..K {
        for j in 0..K {
            let (ki, kj) = ((K - 1 - i) as i32, (K - 1 - j) as i32);
            let e = ki + kj + 1;
            let v = q * dt.powi(e) / (factorial(ki) * factorial(kj) * f64::from(e));
            for a in 0..d {
                m[(i * d + a, j * d + a)] = v;
            }
        }
    }
    m
}

fn factorial(n: i32) -> f64 {
    (1..=n).map(f64::from).product()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix4, Vector4};

    #[test]
    fn cv_matches_textbook() {
        let m = ConstantVelocity::<4>::new(2.0);
        #[rustfmt::skip]
        let f = Matrix4::new(1.0, 0.0, 0.5, 0.0,
                             0.0, 1.0, 0.0, 0.5,
                             0.0, 0.0, 1.0, 0.0,
                             0.0, 0.0, 0.0, 1.0);
        assert_relative_eq!(m.matrix(0.5), f);
        let q = m.covar(0.5);
        assert_relative_eq!(q[(0, 0)], 2.0 * 0.125 / 3.0);
        assert_relative_eq!(q[(0, 2)], 2.0 * 0.25 / 2.0);
        assert_relative_eq!(q[(2, 2)], 2.0 * 0.5);
        assert_relative_eq!(q[(0, 1)], 0.0);
    }

    #[test]
    fn cv_block_propagation_equals_dense_product() {
        let m = ConstantVelocity::<6>::new(1.0);
        let a = nalgebra::Matrix6::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let p = a * a.transpose();
        let f = m.matrix(0.7);
        assert_relative_eq!(
            m.propagate_cov(&nalgebra::Vector6::zeros(), &p, 0.7),
            f * p * f.transpose(),
            max_relative = 1e-12
        );
    }

    #[test]
    fn ct_block_propagation_equals_dense_product() {
        let a = nalgebra::Matrix6::from_fn(|i, j| ((i * 5 + j * 7) % 13) as f64 - 6.0);
        let p = a * a.transpose();
        let m = ConstantTurn::<6>::new(-0.07, 1.0);
        let f = m.matrix(1.3);
        assert_relative_eq!(
            m.propagate_cov(&nalgebra::Vector6::zeros(), &p, 1.3),
            f * p * f.transpose(),
            max_relative = 1e-12
        );
        let p4 = p.fixed_view::<4, 4>(0, 0).into_owned();
        let m4 = ConstantTurn::<4>::new(0.2, 1.0);
        let f4 = m4.matrix(0.9);
        assert_relative_eq!(
            m4.propagate_cov(&Vector4::zeros(), &p4, 0.9),
            f4 * p4 * f4.transpose(),
            max_relative = 1e-12
        );
    }

    #[test]
    fn ca_noise_matches_textbook() {
        let q = ConstantAcceleration::<3>::new(1.0).covar(2.0);
        assert_relative_eq!(q[(0, 0)], 32.0 / 20.0);
        assert_relative_eq!(q[(0, 1)], 16.0 / 8.0);
        assert_relative_eq!(q[(0, 2)], 8.0 / 6.0);
        assert_relative_eq!(q[(1, 1)], 8.0 / 3.0);
        assert_relative_eq!(q[(2, 2)], 2.0);
        let f = ConstantAcceleration::<3>::new(1.0).matrix(2.0);
        assert_relative_eq!(f[(0, 2)], 2.0);
        assert_relative_eq!(f[(0, 1)], 2.0);
    }

    #[test]
    fn ct_quarter_turn_left() {
        // Heading north at 10 m/s, turning left at π/20 rad/s for 10 s: a quarter circle of radius
        // 200/π ending westwards.
        let omega = std::f64::consts::PI / 20.0;
        let m = ConstantTurn::<4>::new(omega, 0.0);
        let x = m.function(&Vector4::new(0.0, 0.0, 0.0, 10.0), 10.0);
        let r = 10.0 / omega;
        assert_relative_eq!(x, Vector4::new(-r, r, -10.0, 0.0), epsilon = 1e-9);
        // ω → 0 is CV.
        let z = ConstantTurn::<4>::new(0.0, 0.0).matrix(3.0);
        assert_relative_eq!(z, ConstantVelocity::<4>::new(0.0).matrix(3.0));
    }

    #[test]
    fn wiener_acceleration_matrices() {
        let m = WienerAcceleration::<3>::new(2.0);
        let f = m.matrix(0.5);
        assert_relative_eq!(
            f,
            nalgebra::Matrix3::new(1.0, 0.5, 0.125, 0.0, 1.0, 0.5, 0.0, 0.0, 1.0)
        );
        // Same F as the continuous-time CA model.
        assert_relative_eq!(f, ConstantAcceleration::<3>::new(1.0).matrix(0.5));
        let g = nalgebra::Vector3::new(0.125, 0.5, 1.0);
        assert_relative_eq!(m.covar(0.5), g * g.transpose() * 4.0);
        // Two axes: blocks [p1 p2 v1 v2 a1 a2].
        let m6 = WienerAcceleration::<6>::new(1.0);
        let q6 = m6.covar(2.0);
        assert_relative_eq!(q6[(1, 5)], 2.0); // T²/2 · 1 for axis 2
        assert_relative_eq!(q6[(0, 1)], 0.0);
        assert_relative_eq!(m6.matrix(2.0)[(1, 3)], 2.0);
    }
}
