//! Set-membership state bounding with ellipsoids: the optimal bounding ellipsoid (OBE) filter for
//! linear systems with unknown-but-bounded noise (FORMAT.md §2.1, \[ELL\] §III–IV):
//!
//! ```text
//! x_{k+1} = A x_k + B w_k,   ‖w_k‖₂ ≤ r
//! y_k     = C x_k + v_k,     |v_{k,i}| ≤ σ_i
//! ```
//!
//! The state is an ellipsoid `E(c, P) = {x : (x − c)ᵀ P⁻¹ (x − c) ≤ 1}` that is guaranteed to
//! contain every state consistent with the prior set and the data. Neither exact set operation keeps
//! ellipsoids ellipsoidal, so each step returns a member of a one-parameter family of *outer*
//! ellipsoids, the one that minimises the volume ([`ObeCriterion::MinVolume`]) or the trace
//! ([`ObeCriterion::MinTrace`]) of the shape matrix.
//!
//! # Measurement update: ellipsoid ∩ strip
//!
//! One row `a` of C with bound σ gives the strip `{x : |y − aᵀx| ≤ σ}`; a vector measurement is
//! processed as one strip per component, in order. With `g = aᵀPa` the strip is first tightened to
//! the ellipsoid's support interval `[aᵀc − √g, aᵀc + √g]`: `lo = max(y − σ, aᵀc − √g)`,
//! `hi = min(y + σ, aᵀc + √g)`; `lo > hi` means the data contradict the set
//! ([`EstimationError::EmptyIntersection`]), a strip that covers the support changes nothing, and
//! otherwise `y ← (lo + hi)/2`, `σ ← (hi − lo)/2` leaves the intersection unchanged but gives a
//! tighter bound. Adding ρ ≥ 0 times the strip inequality `(y − aᵀx)²/σ² ≤ 1` to the ellipsoid's
//! and completing the square (Sherman–Morrison) gives the family of \[Sch68\], \[FH82\], [MN96]:
//!
//! ```text
//! e = y − aᵀc
//! c⁺ = c + ρ P a e / (σ² + ρ g)
//! P⁺ = δ(ρ) (P − ρ P a aᵀ P / (σ² + ρ g)),    δ(ρ) = 1 + ρ − ρ e² / (σ² + ρ g)
//! det P⁺ = δⁿ det P · σ² / (σ² + ρ g)
//! ```
//!
//! *Minimum volume* (\[FH82\]): `d/dρ [n ln δ − ln(σ² + ρg)] = Q(ρ) / (δ (σ² + ρg)²)` with
//!
//! ```text
//! Q(ρ) = (n − 1) g² ρ² + g [(2n − 1) σ² − g + e²] ρ + σ² [n (σ² − e²) − g]
//! ```
//!
//! so the volume decreases until the positive root of Q and increases after it; if Q(0) ≥ 0 the
//! linear coefficient is positive too, Q has no positive root and ρ = 0 (the strip does not cut
//! enough to help). For n = 1 the intersection of two intervals is an interval and is returned
//! exactly.
//!
//! *Minimum trace* (\[MN96\]): minimise `T(ρ) = δ(ρ) (tr P − ρ aᵀP²a / (σ² + ρg))` over ρ ≥ 0.
//! T is a cubic over `(1 + qρ)²` (`q = g/σ²`), so `T′ = R / (1 + qρ)³` with a cubic R whose ρ² and
//! ρ³ coefficients are ≥ 0 (because `aᵀP²a ≤ tr P · aᵀPa`): R is convex on ρ ≥ 0. After the
//! tightening (`g ≥ σ²`), `R(0) ≥ 0` forces `e² < σ²` and then a non-negative linear coefficient,
//! so T never decreases and ρ = 0; otherwise R has exactly one positive root, the global minimiser.
//! Newton's method reaches it monotonically from its right, starting at the zero of R's tangent at
//! 0 (right of the root because R is convex) or at the Fogel–Huang ρ when that is closer; a bounded
//! search of at most 100 steps, in practice a handful.
//!
//! The [`Posterior`] of a vector update carries the innovation `ν = y − C c` (prior centre) and, as
//! `innovation_cov`, the shape of an outer ellipsoid of the predicted measurement set
//! `C E(c, P) ⊕ {v : |vᵢ| ≤ σᵢ}`: the box lies in `E(0, M diag σ²)` and the sum is bounded as in the
//! prediction below with the min-trace weight, `S = (1 + 1/κ) C P Cᵀ + (1 + κ) M diag σ²`,
//! `κ = √(tr C P Cᵀ / (M Σσᵢ²))`. Hence `Posterior::nis() ≤ 1` for every measurement consistent
//! with the prior set, a cheap gate.
//!
//! # Prediction: linear image ⊕ noise ellipsoid
//!
//! `A E(c, P) = E(A c, A P Aᵀ)` exactly; the noise set `{B w : ‖w‖ ≤ r} = E(0, r² B Bᵀ)` may be
//! degenerate (B is n × W). \[ELL\] Theorem 2 (a Schur-complement inequality) gives Theorem 3, the
//! family of outer ellipsoids of a Minkowski sum `W₁ + … + W_m`, and in the proof of Theorem 4 its
//! sub-family `Λᵢ = λᵢ I`, `λ` on the unit simplex, with shape `Σ Qᵢ / λᵢ`. With m = 2:
//!
//! ```text
//! c⁺ = A c,    P⁺ = A P Aᵀ / λ + r² B Bᵀ / (1 − λ),    λ ∈ (0, 1)
//!            = (1 + 1/κ) A P Aᵀ + (1 + κ) r² B Bᵀ,      κ = λ / (1 − λ) > 0
//! ```
//!
//! (the theorems assume full-dimensional ellipsoids; a degenerate noise set is the limit of
//! `E(0, r²BBᵀ + εI)` as ε → 0, and containment passes to the limit because `A P Aᵀ` is positive
//! definite). *Minimum trace*: `tr P⁺ = t₁/λ + t₂/(1 − λ)` is minimal at
//! `λ = √t₁ / (√t₁ + √t₂)`, i.e. `κ = √(t₁/t₂)`. *Minimum volume* (\[ELL\] Theorem 4 restricted to
//! this family): with `H = rB` and `K = Hᵀ (A P Aᵀ)⁻¹ H` (W × W, from one Cholesky factorisation),
//! the matrix determinant lemma gives
//!
//! ```text
//! ln det P⁺ = ln det(A P Aᵀ) + n ln(1 + 1/κ) + ln det(I_W + κ K)
//! ```
//!
//! which is strictly convex in `s = ln κ`. Its derivative in s is
//! `γ(κ) = Σ κkᵢ/(1 + κkᵢ) − n/(1 + κ)` (kᵢ ≥ 0 the eigenvalues of K, from Jacobi rotations of the
//! small W × W matrix), increasing and concave in κ. Since `Σ κkᵢ/(1 + κkᵢ) ≤ κ tr K`, γ ≤ 0 at
//! the positive root of `n/(1 + κ) = κ tr K`, so Newton's method started there (or at the
//! min-trace κ when γ is still ≤ 0 at it) climbs monotonically to the unique root, the global
//! minimiser: a few scalar evaluations, no n × n factorisation per trial.
//!
//! # Not implemented: \[ELL\] Theorem 1
//!
//! \[ELL\] Theorem 1 claims that the intersection of an ellipsoid and a strip is again an ellipsoid
//! and gives it in closed form. That is false: a disc cut by a strip has two flat sides, and the
//! formula needs `C A₁` to be invertible, which a single measurement row never is. This module
//! computes outer ellipsoids of the intersection instead, as above.
//!
//! All shapes are symmetrised and checked (finite, positive definite); failures come back as
//! [`EstimationError`] and leave the input untouched. Everything works on statically sized
//! matrices: no step allocates.
//!
//! # References
//! * \[ELL\] Dong Liushuan, "Ellipsoidal Method for UAVs Target Tracking and Recognition", *IEEE
//!   Access* 10, 2022, doi:10.1109/ACCESS.2022.3216883 (`shared/papers/000`).
//! * \[Sch68\] F. C. Schweppe, "Recursive state estimation: unknown but bounded errors and system
//!   inputs", *IEEE Trans. Automatic Control* 13(1), 22–28, 1968.
//! * \[FH82\] E. Fogel, Y. F. Huang, "On the value of information in system identification — bounded
//!   noise case", *Automatica* 18(2), 229–238, 1982.
//! * \[MN96\] D. G. Maksarov, J. P. Norton, "State bounding with ellipsoidal set description of the
//!   uncertainty", *Int. J. Control* 65(5), 847–866, 1996.
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::{Predictor, Updater};
use crate::linalg::{cholesky, ensure_finite, symmetrize};
use crate::state::{Ellipsoid, Posterior};
use crate::{EstimationError, Result};

/// Cap on the Newton iterations of the one-dimensional solves. They converge monotonically,
/// usually in well under 20 steps; the cap only bounds the work.
const MAX_NEWTON_ITERS: usize = 100;

/// Newton's methods stop once a step is below this fraction of the iterate (the next step would
/// be of its square, far below what matters for the bounds).
const NEWTON_RTOL: f64 = 1e-12;

/// Cap on the doublings that bracket the minimum-trace root from the right.
const MAX_DOUBLINGS: usize = 64;

/// Cap on the cyclic Jacobi sweeps of [`sym_eigenvalues`] (a handful suffice for W ≤ 6).
const JACOBI_SWEEPS: usize = 30;

/// A tightened strip narrower than this fraction of the ellipsoid's extent along `a` is widened
/// to it, so that a strip just touching the ellipsoid still yields a (thin) positive definite
/// outer ellipsoid. Widening a strip keeps the bound an outer bound.
const MIN_STRIP_FRACTION: f64 = 1e-9;

/// Which size measure of the outer ellipsoid each step minimises.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum ObeCriterion {
    /// Minimum volume (`det P`): Fogel & Huang's closed form for the update, a convex
    /// one-dimensional root search for the prediction (\[FH82\], \[ELL\] Theorem 4).
    #[default]
    MinVolume,
    /// Minimum trace (sum of squared semi-axes): closed form for the prediction, a bounded
    /// one-dimensional root search for the update (\[MN96\]).
    MinTrace,
}

/// The optimal bounding ellipsoid filter (see the module docs): a [`Predictor`] for
/// [`BoundedLinearTransition`] and an [`Updater`] for [`BoundedLinearMeasurement`] on
/// [`Ellipsoid`] states.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Obe {
    /// What each step minimises.
    pub criterion: ObeCriterion,
}

impl Obe {
    /// OBE filter minimising `criterion`.
    pub const fn new(criterion: ObeCriterion) -> Self {
        Self { criterion }
    }
}

/// Discrete-time linear transition with ball-bounded process noise:
/// `x_{k+1} = A x_k + B w_k`, `‖w_k‖₂ ≤ r`, B n × W.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundedLinearTransition<const N: usize, const W: usize> {
    A: SMatrix<f64, N, N>,
    B: SMatrix<f64, N, W>,
    w_radius: f64,
}

impl<const N: usize, const W: usize> BoundedLinearTransition<N, W> {
    /// Checks that A and B are finite and `w_radius` is finite and ≥ 0.
    pub fn new(A: SMatrix<f64, N, N>, B: SMatrix<f64, N, W>, w_radius: f64) -> Result<Self> {
        ensure_finite(&A, "transition matrix A")?;
        ensure_finite(&B, "noise input matrix B")?;
        if !(w_radius.is_finite() && w_radius >= 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "process-noise radius must be finite and >= 0, got {w_radius}"
            )));
        }
        Ok(Self { A, B, w_radius })
    }
    /// Transition matrix A.
    pub fn matrix(&self) -> &SMatrix<f64, N, N> {
        &self.A
    }
    /// Noise input matrix B.
    pub fn input(&self) -> &SMatrix<f64, N, W> {
        &self.B
    }
    /// Radius r of the noise ball `‖w‖₂ ≤ r`.
    pub fn w_radius(&self) -> f64 {
        self.w_radius
    }
}

/// Linear measurement with box-bounded noise: `y = C x + v`, `|vᵢ| ≤ σᵢ`, C M × n.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundedLinearMeasurement<const N: usize, const M: usize> {
    C: SMatrix<f64, M, N>,
    half_width: SVector<f64, M>,
}

impl<const N: usize, const M: usize> BoundedLinearMeasurement<N, M> {
    /// Checks that C is finite and every half-width σᵢ is finite and > 0.
    pub fn new(C: SMatrix<f64, M, N>, half_width: SVector<f64, M>) -> Result<Self> {
        ensure_finite(&C, "measurement matrix C")?;
        if !half_width.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "measurement-noise half-widths must be finite and > 0, got {:?}",
                half_width.as_slice()
            )));
        }
        Ok(Self { C, half_width })
    }
    /// Measurement matrix C.
    pub fn matrix(&self) -> &SMatrix<f64, M, N> {
        &self.C
    }
    /// Half-widths σ of the noise box.
    pub fn half_width(&self) -> &SVector<f64, M> {
        &self.half_width
    }
}

/// Fogel–Huang minimum-volume weight (\[FH82\]) in normalised form: with `q = g/σ²`, `ε = e²/σ²`,
/// the positive root of `(n−1) q² ρ² + q [(2n−1) − q + ε] ρ + [n (1 − ε) − q]`, or 0 if none.
fn rho_min_volume(n: f64, q: f64, eps: f64) -> f64 {
    let alpha = (n - 1.0) * q * q;
    let beta = q * ((2.0 * n - 1.0) - q + eps);
    let gamma = n * (1.0 - eps) - q;
    if gamma >= 0.0 || alpha <= 0.0 {
        // Q(0) ≥ 0 ⇒ β > 0 as well: no positive root, the volume grows with ρ.
        return 0.0;
    }
    // α > 0 > γ: one positive root; pick the form without cancellation.
    let sqrt_disc = (beta * beta - 4.0 * alpha * gamma).sqrt();
    if beta >= 0.0 {
        -2.0 * gamma / (beta + sqrt_disc)
    } else {
        (sqrt_disc - beta) / (2.0 * alpha)
    }
}

/// Minimum-trace weight (\[MN96\]), see the module docs: `T(ρ) = N₁ N₂ / D²` with `D = 1 + qρ`,
/// `N₁ = 1 + (1 + q − ε)ρ + qρ²`, `N₂ = t + (tq − η)ρ` (`t = tr P`, `η = aᵀP²a/σ²`);
/// `T′ = R / D³` with the cubic `R = r₀ + r₁ρ + r₂ρ² + r₃ρ³`, convex on ρ ≥ 0. Returns 0 when
/// `R(0) ≥ 0`, else the positive root of R by Newton's method from the right of it, starting at
/// `start` (doubled until `R > 0`).
fn rho_min_trace(q: f64, eps: f64, t: f64, eta: f64, start: f64) -> f64 {
    let n1 = 1.0 + q - eps;
    let m1 = t * q - eta;
    // N₁ N₂ = p₀ + p₁ρ + p₂ρ² + p₃ρ³, p₀ = t.
    let p1 = n1 * t + m1;
    let p2 = q * t + n1 * m1;
    let p3 = q * m1;
    // R = (N₁N₂)′ D − 2q N₁N₂.
    let (r0, r1, r2, r3) = (p1 - 2.0 * q * t, 2.0 * p2 - q * p1, 3.0 * p3, q * p3);
    if r0.is_nan() || r0 >= 0.0 {
        return 0.0;
    }
    let poly = |x: f64| ((r3 * x + r2) * x + r1) * x + r0;
    let slope = |x: f64| (3.0 * r3 * x + 2.0 * r2) * x + r1;
    // Start right of the root: the zero of the tangent at 0 (R convex) or `start`, whichever is
    // smaller and valid, else double until R > 0.
    let mut x = f64::INFINITY;
    if r1 > 0.0 {
        x = -r0 / r1;
    }
    if start.is_finite() && start > 0.0 && start < x && poly(start) > 0.0 {
        x = start;
    }
    if !x.is_finite() {
        x = if start.is_finite() && start > 0.0 {
            start
        } else {
            1.0
        };
        for _ in 0..MAX_DOUBLINGS {
            if poly(x) > 0.0 {
                break;
            }
            x *= 2.0;
        }
    }
    for _ in 0..MAX_NEWTON_ITERS {
        let step = poly(x) / slope(x);
        if step.is_nan() || step <= 0.0 {
            break;
        }
        x -= step;
        if step <= NEWTON_RTOL * x {
            break;
        }
    }
    let objective = |x: f64| {
        let d = 1.0 + q * x;
        (1.0 + (n1 + q * x) * x) * (t + m1 * x) / (d * d)
    };
    if x.is_finite() && x > 0.0 && objective(x) < t {
        x
    } else {
        0.0
    }
}

/// Eigenvalues of a symmetric matrix by cyclic Jacobi rotations (no allocation, any W).
fn sym_eigenvalues<const W: usize>(mut a: SMatrix<f64, W, W>) -> SVector<f64, W> {
    for _ in 0..JACOBI_SWEEPS {
        let mut off = 0.0;
        for p in 0..W {
            for q in p + 1..W {
                off += a[(p, q)] * a[(p, q)];
            }
        }
        if off <= 1e-26 * a.diagonal().norm_squared() {
            break;
        }
        for p in 0..W {
            for q in p + 1..W {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // Rotation in the (p, q) plane that zeroes a_pq (Numerical Recipes §11.1).
                let theta = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + theta.hypot(1.0));
                let c = 1.0 / t.hypot(1.0);
                let s = t * c;
                for k in 0..W {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..W {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
            }
        }
    }
    a.diagonal()
}

/// Minimum-volume prediction weight κ (module docs): the root of the increasing, concave
/// `γ(κ) = Σ κkᵢ/(1 + κkᵢ) − n/(1 + κ)` (kᵢ ≥ 0 the eigenvalues of K), by Newton's method from
/// the left of it: from the root of `n/(1 + κ) = κ Σkᵢ`, or from `start` if that is still left of
/// the root.
fn kappa_min_volume<const W: usize>(n: f64, k: &SVector<f64, W>, start: f64) -> f64 {
    let gamma = |x: f64| {
        let (mut v, mut d) = (-n / (1.0 + x), n / ((1.0 + x) * (1.0 + x)));
        for &ki in k.iter() {
            let u = 1.0 + x * ki;
            v += x * ki / u;
            d += ki / (u * u);
        }
        (v, d)
    };
    // Σ κkᵢ/(1 + κkᵢ) ≤ κ Σkᵢ, so the root is at least the positive root of
    // n/(1 + κ) = κ Σkᵢ, where γ ≤ 0.
    let tr = k.sum();
    let mut x = 2.0 * n / (tr + (tr * tr + 4.0 * n * tr).sqrt());
    if start.is_finite() && start > x && gamma(start).0 <= 0.0 {
        x = start;
    }
    for _ in 0..MAX_NEWTON_ITERS {
        let (v, d) = gamma(x);
        let step = -v / d;
        if step.is_nan() || step <= 0.0 {
            break;
        }
        x += step;
        if step <= NEWTON_RTOL * x {
            break;
        }
    }
    x
}

/// Outer ellipsoid of `E(c, P) ∩ {x : |y − aᵀx| ≤ σ}` minimising `criterion` (module docs,
/// \[Sch68\], \[FH82\], \[MN96\]). Returns `e` unchanged when the strip covers it, and
/// [`EstimationError::EmptyIntersection`] when the strip misses it.
pub fn intersect_strip<const N: usize>(
    e: &Ellipsoid<N>,
    a: &SVector<f64, N>,
    y: f64,
    sigma: f64,
    criterion: ObeCriterion,
) -> Result<Ellipsoid<N>> {
    match strip_step(e, a, y, sigma, criterion)? {
        Some(post) => {
            cholesky(&post.shape, "OBE updated shape")?;
            Ok(post)
        }
        None => Ok(*e),
    }
}

/// [`intersect_strip`] without the final positive-definiteness check (the vector update checks
/// once after all strips); `None` when the ellipsoid is unchanged.
fn strip_step<const N: usize>(
    e: &Ellipsoid<N>,
    a: &SVector<f64, N>,
    y: f64,
    sigma: f64,
    criterion: ObeCriterion,
) -> Result<Option<Ellipsoid<N>>> {
    ensure_finite(a, "strip normal")?;
    if !y.is_finite() {
        return Err(EstimationError::NonFinite("measurement"));
    }
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(EstimationError::InvalidParameter(format!(
            "strip half-width must be finite and > 0, got {sigma}"
        )));
    }
    let P = &e.shape;
    let Pa = P * a;
    let g = a.dot(&Pa);
    let ac = a.dot(&e.center);
    if !(g.is_finite() && ac.is_finite()) {
        return Err(EstimationError::NonFinite("ellipsoid"));
    }
    // Support interval of the ellipsoid along a, and the tightened strip.
    let sg = g.max(0.0).sqrt();
    let (lo, hi) = ((y - sigma).max(ac - sg), (y + sigma).min(ac + sg));
    if lo > hi {
        return Err(EstimationError::EmptyIntersection);
    }
    if y - sigma <= ac - sg && y + sigma >= ac + sg {
        return Ok(None); // the strip covers the ellipsoid (always the case when g = 0)
    }
    let y = 0.5 * (lo + hi);
    let sigma = (0.5 * (hi - lo)).max(MIN_STRIP_FRACTION * sg);
    let innov = y - ac;
    if N == 1 {
        // Exact: the intersection of two intervals. g > 0 here, so a[0] ≠ 0.
        let a0 = a[0];
        let center = SVector::<f64, N>::from_element(y / a0);
        let shape = SMatrix::<f64, N, N>::from_element((sigma / a0).powi(2));
        return finite(center, shape).map(Some);
    }
    let sigma2 = sigma * sigma;
    let q = g / sigma2;
    let eps = innov * innov / sigma2;
    let rho_volume = rho_min_volume(N as f64, q, eps);
    let rho = match criterion {
        ObeCriterion::MinVolume => rho_volume,
        ObeCriterion::MinTrace => {
            rho_min_trace(q, eps, P.trace(), Pa.norm_squared() / sigma2, rho_volume)
        }
    };
    if rho.is_nan() || rho <= 0.0 {
        return Ok(None);
    }
    let s = 1.0 + rho * q; // (σ² + ρg)/σ²
    let delta = 1.0 + rho - rho * eps / s;
    if !(delta.is_finite() && delta > 0.0) {
        return Err(EstimationError::NotPositiveDefinite("OBE updated shape"));
    }
    let k = rho / (sigma2 * s); // ρ / (σ² + ρg)
    let center = e.center + Pa * (k * innov);
    let shape = symmetrize(&((P - Pa * Pa.transpose() * k) * delta));
    finite(center, shape).map(Some)
}

/// Checks that a new ellipsoid is finite.
fn finite<const N: usize>(
    center: SVector<f64, N>,
    shape: SMatrix<f64, N, N>,
) -> Result<Ellipsoid<N>> {
    ensure_finite(&center, "OBE centre")?;
    ensure_finite(&shape, "OBE shape")?;
    Ok(Ellipsoid { center, shape })
}

/// Outer ellipsoid of the Minkowski sum `A E(c, P) ⊕ {H w : ‖w‖₂ ≤ 1}` (`H = r B`) minimising
/// `criterion` within the family of \[ELL\] Theorems 3–4 (module docs). Needs `A P Aᵀ` positive
/// definite (A invertible).
pub fn minkowski_outer<const N: usize, const W: usize>(
    e: &Ellipsoid<N>,
    A: &SMatrix<f64, N, N>,
    H: &SMatrix<f64, N, W>,
    criterion: ObeCriterion,
) -> Result<Ellipsoid<N>> {
    let center = A * e.center;
    let Q1 = symmetrize(&(A * e.shape * A.transpose()));
    let chol = cholesky(&Q1, "A P Aᵀ")?;
    let t2 = H.norm_squared(); // tr(H Hᵀ)
    ensure_finite(H, "process-noise input")?;
    if t2 == 0.0 {
        return finite(center, Q1); // no process noise: the image is exact
    }
    let kappa_trace = (Q1.trace() / t2).sqrt();
    let kappa = match criterion {
        ObeCriterion::MinTrace => kappa_trace,
        ObeCriterion::MinVolume => {
            // K = Hᵀ Q1⁻¹ H = Gᵀ G with L G = H; its eigenvalues kᵢ ≥ 0.
            let G = chol
                .l_dirty()
                .solve_lower_triangular(H)
                .ok_or(EstimationError::NotPositiveDefinite("A P Aᵀ"))?;
            let k = sym_eigenvalues(G.transpose() * G).map(|v| v.max(0.0));
            ensure_finite(&k, "process-noise ellipsoid")?;
            if k.sum() > 0.0 {
                kappa_min_volume(N as f64, &k, kappa_trace)
            } else {
                kappa_trace // K underflowed: any κ > 0 still gives an outer bound
            }
        }
    };
    if !(kappa.is_finite() && kappa > 0.0) {
        return Err(EstimationError::NonFinite("OBE prediction weight"));
    }
    let shape = symmetrize(&(Q1 * (1.0 + 1.0 / kappa) + H * H.transpose() * (1.0 + kappa)));
    ensure_finite(&center, "OBE predicted centre")?;
    ensure_finite(&shape, "OBE predicted shape")?;
    Ok(Ellipsoid { center, shape })
}

/// Shape of an outer ellipsoid of the predicted measurement set `C E(c, P) ⊕ box(σ)` (module
/// docs): `(1 + 1/κ) C P Cᵀ + (1 + κ) M diag σ²`, `κ = √(tr C P Cᵀ / (M Σσᵢ²))`.
fn measurement_set_shape<const N: usize, const M: usize>(
    C: &SMatrix<f64, M, N>,
    P: &SMatrix<f64, N, N>,
    half_width: &SVector<f64, M>,
) -> SMatrix<f64, M, M> {
    let cpc = symmetrize(&(C * P * C.transpose()));
    let noise =
        SMatrix::<f64, M, M>::from_diagonal(&half_width.component_mul(half_width)) * M as f64;
    let t1 = cpc.trace();
    if t1.is_nan() || t1 <= 0.0 {
        return noise;
    }
    let kappa = (t1 / noise.trace()).sqrt();
    cpc * (1.0 + 1.0 / kappa) + noise * (1.0 + kappa)
}

impl<const N: usize, const W: usize> Predictor<BoundedLinearTransition<N, W>, N> for Obe {
    type State = Ellipsoid<N>;
    /// One step `k → k + 1` of the discrete-time system (`dt` is not used): the outer ellipsoid of
    /// `A E(c, P) ⊕ E(0, r² B Bᵀ)`, see [`minkowski_outer`] (\[ELL\] Theorems 2–4).
    fn predict(
        &self,
        model: &BoundedLinearTransition<N, W>,
        prior: &Ellipsoid<N>,
        _dt: f64,
    ) -> Result<Ellipsoid<N>> {
        let H = model.B * model.w_radius;
        minkowski_outer(prior, &model.A, &H, self.criterion)
    }
}

impl<const N: usize, const M: usize> Updater<BoundedLinearMeasurement<N, M>, N, M> for Obe {
    type State = Ellipsoid<N>;
    /// One [`intersect_strip`] per component of `z`, in order (\[Sch68\], \[FH82\], \[MN96\]). The
    /// posterior's `innovation` is `z − C c` and its `innovation_cov` the shape of an outer
    /// ellipsoid of the predicted measurement set, so `nis() ≤ 1` for consistent data.
    fn update(
        &self,
        model: &BoundedLinearMeasurement<N, M>,
        predicted: &Ellipsoid<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Ellipsoid<N>, M>> {
        ensure_finite(z, "measurement")?;
        let C = &model.C;
        let mut state = *predicted;
        let mut changed = false;
        for i in 0..M {
            let a = C.row(i).transpose();
            if let Some(post) = strip_step(&state, &a, z[i], model.half_width[i], self.criterion)? {
                state = post;
                changed = true;
            }
        }
        if changed {
            cholesky(&state.shape, "OBE updated shape")?;
        }
        Ok(Posterior {
            state,
            innovation: z - C * predicted.center,
            innovation_cov: measurement_set_shape(C, &predicted.shape, &model.half_width),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::ln_det;
    use nalgebra::{Matrix2, Matrix4, SMatrix, Vector2, Vector4};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    const TOL: f64 = 1e-9;

    /// Uniform point in the unit ball of R^N, or on its sphere when `surface`.
    fn ball<const N: usize>(rng: &mut ChaCha8Rng, surface: bool) -> SVector<f64, N> {
        let g = SVector::<f64, N>::from_fn(|_, _| rng.sample(StandardNormal));
        let r: f64 = if surface {
            1.0
        } else {
            rng.random::<f64>().powf(1.0 / N as f64)
        };
        g.normalize() * r
    }

    /// A point of `E` (a quarter of them on its boundary).
    fn point_in<const N: usize>(rng: &mut ChaCha8Rng, e: &Ellipsoid<N>) -> SVector<f64, N> {
        let surface = rng.random::<f64>() < 0.25;
        let l = cholesky(&e.shape, "test").unwrap().l();
        e.center + l * ball::<N>(rng, surface)
    }

    fn random_ellipsoid<const N: usize>(rng: &mut ChaCha8Rng) -> Ellipsoid<N> {
        let m = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let shape = m * m.transpose() + SMatrix::<f64, N, N>::identity() * 0.1;
        let center = SVector::<f64, N>::from_fn(|_, _| rng.random_range(-3.0..3.0));
        Ellipsoid::new(center, shape).unwrap()
    }

    fn det<const N: usize>(e: &Ellipsoid<N>) -> f64 {
        ln_det(&cholesky(&e.shape, "test").unwrap()).exp()
    }

    /// Random strip that cuts `e`: normal `a`, centre somewhere in the support, half-width a
    /// fraction of it.
    fn cutting_strip<const N: usize>(
        rng: &mut ChaCha8Rng,
        e: &Ellipsoid<N>,
    ) -> (SVector<f64, N>, f64, f64) {
        let a = ball::<N>(rng, true) * rng.random_range(0.5..2.0);
        let sg = a.dot(&(e.shape * a)).sqrt();
        let y = a.dot(&e.center) + rng.random_range(-0.9..0.9) * sg;
        let sigma = rng.random_range(0.02..0.6) * sg;
        (a, y, sigma)
    }

    #[test]
    fn strip_update_contains_the_intersection() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..200 {
            let e = random_ellipsoid::<4>(&mut rng);
            let (a, y, sigma) = cutting_strip(&mut rng, &e);
            for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
                let post = intersect_strip(&e, &a, y, sigma, crit).unwrap();
                // ρ = 0 (the prior) is in the family, so neither criterion can get worse.
                match crit {
                    ObeCriterion::MinVolume => assert!(det(&post) <= det(&e) * (1.0 + 1e-12)),
                    ObeCriterion::MinTrace => {
                        assert!(post.shape.trace() <= e.shape.trace() * (1.0 + 1e-12));
                    }
                }
                let mut inside = 0;
                for _ in 0..400 {
                    let x = point_in(&mut rng, &e);
                    if (y - a.dot(&x)).abs() <= sigma {
                        inside += 1;
                        assert!(post.contains(&x, TOL).unwrap(), "{crit:?}");
                    }
                }
                assert!(inside > 0);
            }
        }
    }

    #[test]
    fn strip_update_in_one_dimension_is_exact() {
        let e =
            Ellipsoid::new(SVector::<f64, 1>::new(1.0), SMatrix::<f64, 1, 1>::new(4.0)).unwrap();
        // E = [-1, 3]; strip |5 − 2x| ≤ 1 ⇔ x ∈ [2, 3].
        let a = SVector::<f64, 1>::new(2.0);
        let post = intersect_strip(&e, &a, 5.0, 1.0, ObeCriterion::MinVolume).unwrap();
        assert!((post.center[0] - 2.5).abs() < 1e-12);
        assert!((post.shape[(0, 0)] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn covering_strip_is_a_no_op_and_missing_strip_is_empty() {
        let e = Ellipsoid::new(Vector2::new(1.0, -1.0), Matrix2::new(4.0, 1.0, 1.0, 2.0)).unwrap();
        let a = Vector2::new(1.0, 0.5);
        let sg = a.dot(&(e.shape * a)).sqrt();
        let ac = a.dot(&e.center);
        for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
            assert_eq!(
                intersect_strip(&e, &a, ac + 0.1, sg + 0.2, crit).unwrap(),
                e
            );
            assert_eq!(
                intersect_strip(&e, &a, ac + sg + 1.0, 0.5, crit).unwrap_err(),
                EstimationError::EmptyIntersection
            );
            // Just touching: a thin but valid ellipsoid around the touching point.
            let touch = intersect_strip(&e, &a, ac + sg + 0.5, 0.5, crit).unwrap();
            assert!(det(&touch) < 1e-6 * det(&e));
            let model = BoundedLinearMeasurement::new(
                SMatrix::<f64, 1, 2>::new(1.0, 0.5),
                SVector::<f64, 1>::new(0.5),
            )
            .unwrap();
            let err = Obe::new(crit)
                .update(&model, &e, &SVector::<f64, 1>::new(ac - sg - 2.0))
                .unwrap_err();
            assert_eq!(err, EstimationError::EmptyIntersection);
        }
    }

    /// Shape for a given ρ, straight from the family's formula (untightened strip).
    fn family<const N: usize>(
        e: &Ellipsoid<N>,
        a: &SVector<f64, N>,
        y: f64,
        sigma: f64,
        rho: f64,
    ) -> SMatrix<f64, N, N> {
        let pa = e.shape * a;
        let g = a.dot(&pa);
        let innov = y - a.dot(&e.center);
        let s = sigma * sigma + rho * g;
        let delta = 1.0 + rho - rho * innov * innov / s;
        (e.shape - pa * pa.transpose() * (rho / s)) * delta
    }

    #[test]
    fn fogel_huang_root_minimises_volume_and_search_minimises_trace() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..100 {
            let e = random_ellipsoid::<4>(&mut rng);
            let (a, y, sigma) = cutting_strip(&mut rng, &e);
            // Tighten first so that the family below is the one the filter optimises over.
            let sg = a.dot(&(e.shape * a)).sqrt();
            let ac = a.dot(&e.center);
            let (lo, hi) = ((y - sigma).max(ac - sg), (y + sigma).min(ac + sg));
            let (y, sigma) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            let vol = intersect_strip(&e, &a, y, sigma, ObeCriterion::MinVolume).unwrap();
            let tr = intersect_strip(&e, &a, y, sigma, ObeCriterion::MinTrace).unwrap();
            assert!(det(&vol) <= det(&tr) * (1.0 + 1e-9));
            assert!(vol.shape.trace() >= tr.shape.trace() * (1.0 - 1e-9));
            for i in 0..=400 {
                let rho = if i == 0 {
                    0.0
                } else {
                    10f64.powf(-4.0 + i as f64 / 50.0)
                };
                let p = family(&e, &a, y, sigma, rho);
                assert!(det(&vol) <= p.determinant() * (1.0 + 1e-9), "ρ = {rho}");
                assert!(tr.shape.trace() <= p.trace() * (1.0 + 1e-9), "ρ = {rho}");
            }
        }
    }

    #[test]
    fn prediction_contains_the_minkowski_sum_and_optimises_its_criterion() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            let e = random_ellipsoid::<4>(&mut rng);
            let A = Matrix4::from_fn(|_, _| rng.random_range(-1.0..1.0)) + Matrix4::identity();
            let B = SMatrix::<f64, 4, 2>::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let r = rng.random_range(0.1..2.0);
            let model = BoundedLinearTransition::new(A, B, r).unwrap();
            let vol = Obe::new(ObeCriterion::MinVolume).predict(&model, &e, 1.0);
            let tr = Obe::new(ObeCriterion::MinTrace).predict(&model, &e, 1.0);
            let (Ok(vol), Ok(tr)) = (vol, tr) else {
                continue; // A P Aᵀ singular: nothing to check
            };
            assert!(det(&vol) <= det(&tr) * (1.0 + 1e-9));
            assert!(vol.shape.trace() >= tr.shape.trace() * (1.0 - 1e-9));
            for _ in 0..300 {
                let surface = rng.random::<f64>() < 0.5;
                let w = ball::<2>(&mut rng, surface) * r;
                let x = A * point_in(&mut rng, &e) + B * w;
                assert!(vol.contains(&x, TOL).unwrap());
                assert!(tr.contains(&x, TOL).unwrap());
            }
            let q1 = A * e.shape * A.transpose();
            let q2 = B * B.transpose() * (r * r);
            for i in 1..400 {
                let lambda = i as f64 / 400.0;
                let p = q1 / lambda + q2 / (1.0 - lambda);
                assert!(det(&vol) <= p.determinant() * (1.0 + 1e-9));
                assert!(tr.shape.trace() <= p.trace() * (1.0 + 1e-9));
            }
        }
    }

    #[test]
    fn jacobi_eigenvalues_match_nalgebra() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..100 {
            let m = SMatrix::<f64, 3, 3>::from_fn(|_, _| rng.random_range(-2.0..2.0));
            let s = m + m.transpose();
            let mut ours: Vec<f64> = sym_eigenvalues(s).iter().copied().collect();
            let mut theirs: Vec<f64> = s.symmetric_eigen().eigenvalues.iter().copied().collect();
            ours.sort_by(f64::total_cmp);
            theirs.sort_by(f64::total_cmp);
            for (a, b) in ours.iter().zip(&theirs) {
                assert!(
                    (a - b).abs() < 1e-12 * (1.0 + b.abs()),
                    "{ours:?} vs {theirs:?}"
                );
            }
        }
        let one = sym_eigenvalues(SMatrix::<f64, 1, 1>::new(2.5));
        assert_eq!(one[0], 2.5);
    }

    #[test]
    fn prediction_without_noise_is_the_exact_image() {
        let e = Ellipsoid::new(Vector2::new(1.0, 2.0), Matrix2::new(2.0, 0.5, 0.5, 1.0)).unwrap();
        let A = Matrix2::new(1.0, 0.1, 0.0, 1.0);
        let model = BoundedLinearTransition::new(A, SMatrix::<f64, 2, 1>::zeros(), 1.0).unwrap();
        let p = Obe::default().predict(&model, &e, 0.1).unwrap();
        assert_eq!(p.center, A * e.center);
        assert!((p.shape - A * e.shape * A.transpose()).norm() < 1e-12);
    }

    #[test]
    fn vector_update_gates_consistent_measurements() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let model =
            BoundedLinearMeasurement::new(SMatrix::<f64, 2, 4>::identity(), Vector2::new(0.3, 0.5))
                .unwrap();
        for _ in 0..200 {
            let e = random_ellipsoid::<4>(&mut rng);
            let x = point_in(&mut rng, &e);
            let v = Vector2::new(rng.random_range(-0.3..0.3), rng.random_range(-0.5..0.5));
            let z = model.matrix() * x + v;
            let post = Obe::default().update(&model, &e, &z).unwrap();
            assert!(post.nis().unwrap() <= 1.0 + TOL);
            assert!(post.state.contains(&x, TOL).unwrap());
        }
    }

    /// CV model with bounded acceleration: `x = [px, py, vx, vy]`, `w ∈ R²`, `‖w‖ ≤ 1` scaled by
    /// `a_max`, position measured with box noise.
    fn cv_system(
        dt: f64,
        a_max: f64,
        sigma: Vector2<f64>,
    ) -> (
        BoundedLinearTransition<4, 2>,
        BoundedLinearMeasurement<4, 2>,
    ) {
        let mut A = Matrix4::identity();
        A[(0, 2)] = dt;
        A[(1, 3)] = dt;
        let mut B = SMatrix::<f64, 4, 2>::zeros();
        B[(0, 0)] = 0.5 * dt * dt * a_max;
        B[(1, 1)] = 0.5 * dt * dt * a_max;
        B[(2, 0)] = dt * a_max;
        B[(3, 1)] = dt * a_max;
        let C = SMatrix::<f64, 2, 4>::identity();
        (
            BoundedLinearTransition::new(A, B, 1.0).unwrap(),
            BoundedLinearMeasurement::new(C, sigma).unwrap(),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn truth_stays_inside_on_random_bounded_systems(
            seed in any::<u64>(),
            dt in 0.02f64..1.0,
            a_max in 0.05f64..5.0,
            sx in 0.01f64..2.0,
            sy in 0.01f64..2.0,
            semi in proptest::array::uniform4(0.1f64..5.0),
            worst in 0.0f64..1.0,
        ) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let sigma = Vector2::new(sx, sy);
            let (f, h) = cv_system(dt, a_max, sigma);
            let x0 = Ellipsoid::new(
                Vector4::new(10.0, -5.0, 1.0, 0.5),
                Matrix4::from_diagonal(&Vector4::from(semi).component_mul(&Vector4::from(semi))),
            ).unwrap();
            for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
                let obe = Obe::new(crit);
                let mut truth = point_in(&mut ChaCha8Rng::seed_from_u64(seed ^ 1), &x0);
                let mut set = x0;
                for k in 0..50 {
                    if k > 0 {
                        // With probability `worst` the noise sits on its bound.
                        let surface = rng.random::<f64>() < worst;
                        let w = ball::<2>(&mut rng, surface);
                        truth = f.matrix() * truth + f.input() * w;
                        set = obe.predict(&f, &set, dt).unwrap();
                        prop_assert!(set.contains(&truth, TOL).unwrap(), "{crit:?} predict {k}");
                    }
                    let v = Vector2::from_fn(|i, _| {
                        if rng.random::<f64>() < worst {
                            if rng.random::<bool>() { sigma[i] } else { -sigma[i] }
                        } else {
                            rng.random_range(-sigma[i]..=sigma[i])
                        }
                    });
                    let z = h.matrix() * truth + v;
                    set = obe.update(&h, &set, &z).unwrap().state;
                    prop_assert!(set.contains(&truth, TOL).unwrap(), "{crit:?} update {k}");
                }
            }
        }
    }
}
