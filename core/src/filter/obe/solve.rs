//! The one-dimensional searches for the weights of the OBE family (see the `obe` module docs):
//! ρ of the strip update (Fogel–Huang's minimum volume, minimum trace), κ of the prediction
//! (minimum volume), and the Jacobi eigenvalues that one needs.

use nalgebra::{SMatrix, SVector};

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

/// Fogel–Huang minimum-volume weight (\[FH82\]) in normalised form: with `q = g/σ²`, `ε = e²/σ²`,
/// the positive root of `(n−1) q² ρ² + q [(2n−1) − q + ε] ρ + [n (1 − ε) − q]`, or 0 if none.
pub(super) fn rho_min_volume(n: f64, q: f64, eps: f64) -> f64 {
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

/// Minimum-trace weight (\[MN96\]), see the `obe` module docs: `T(ρ) = N₁ N₂ / D²` with
/// `D = 1 + qρ`, `N₁ = 1 + (1 + q − ε)ρ + qρ²`, `N₂ = t + (tq − η)ρ` (`t = tr P`, `η = aᵀP²a/σ²`);
/// `T′ = R / D³` with the cubic `R = r₀ + r₁ρ + r₂ρ² + r₃ρ³`, convex on ρ ≥ 0. Returns 0 when
/// `R(0) ≥ 0`, else the positive root of R by Newton's method from the right of it, starting at
/// `start` (doubled until `R > 0`).
pub(super) fn rho_min_trace(q: f64, eps: f64, t: f64, eta: f64, start: f64) -> f64 {
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
pub(super) fn sym_eigenvalues<const W: usize>(mut a: SMatrix<f64, W, W>) -> SVector<f64, W> {
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

/// Minimum-volume prediction weight κ (the `obe` module docs): the root of the increasing, concave
/// `γ(κ) = Σ κkᵢ/(1 + κkᵢ) − n/(1 + κ)` (kᵢ ≥ 0 the eigenvalues of K), by Newton's method from
/// the left of it: from the root of `n/(1 + κ) = κ Σkᵢ`, or from `start` if that is still left of
/// the root.
pub(super) fn kappa_min_volume<const W: usize>(n: f64, k: &SVector<f64, W>, start: f64) -> f64 {
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
