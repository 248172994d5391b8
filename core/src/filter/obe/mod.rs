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
//! Split by concern: the filter and its models are here, the set operations (strip cut,
//! Minkowski sum, predicted measurement set) and the criterion they minimise in `sets.rs`, the
//! one-dimensional weight searches in `solve.rs`.
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

mod sets;
mod solve;
#[cfg(test)]
mod tests;

use nalgebra::{SMatrix, SVector};

pub use sets::{ObeCriterion, intersect_strip, minkowski_outer};

use crate::filter::traits::{Predictor, Updater};
use crate::linalg::{cholesky, ensure_finite};
use crate::state::{Ellipsoid, Posterior};
use crate::{EstimationError, Result};
use sets::{measurement_set_shape, strip_step};

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
