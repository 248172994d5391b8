//! Sensor registration: every sensor's bias estimated jointly with the target, from what several
//! sensors share (targets of opportunity) and from cooperative references (a UAV a radar paints
//! reports its own GPS position).
//!
//! # Bias model
//!
//! Measurement component `i` of a sensor reads (FORMAT.md §3's radar bias, plus a latency δ)
//!
//! ```text
//! z_i(t) = (1 + s_i) · h_i(p(t − δ) − p_s(t − δ)) + o_i + v_i,     v ~ N(0, R)
//! ```
//!
//! with an offset `o_i` (a radar's range and azimuth offsets, a camera's azimuth and elevation
//! mounting offsets), a scale `s_i` (a radar's range scale) and a time offset δ (the measurement
//! stamped `t` shows the world at `t − δ`). Each term the sensor's [`SensorBias`] names is a
//! state, constant, a random walk or a first-order Gauss–Markov process ([`Dynamics`]), with its
//! Gaussian prior ([`BiasPrior`]).
//!
//! # Estimator: the augmented EKF, with consider updates until a term is observable
//!
//! The state is `X = [x; b]`: the target's nearly-constant-velocity state `x` and the bias terms
//! `b` of every sensor ([`Registration`]). This is the augmented-state form of Lin, Bar-Shalom &
//! Kirubarajan (2005) rather than a separate bias filter fed by the tracks' innovations
//! (Friedland's two-stage filter, Ignagni's separate-bias filter): for one target it is exact to
//! first order and small (N ≤ 26), and it keeps every cross-covariance between the target and
//! the biases, which the separate forms either neglect or need extra bookkeeping for (Stone
//! Soup's `GaussianBiasUpdater` drops them after each update).
//!
//! ```text
//! predict:  x⁻ = F x,  b⁻ = μ + Φ (b − μ),  P⁻ = F_a P F_aᵀ + Q_a        F_a = diag(F, Φ), Q_a = diag(Q, Q_b)
//!           (F, Q: CV, [BLK01] §6.2.2; Φ, Q_b per term, see Dynamics)
//! measure:  p̃ = p − δ (v − v_s)                                          (the target at t − δ, first order)
//!           ẑ_i = (1 + s_i) h_i(p̃) + o_i,  G = diag(1 + s),  H_p = ∂h/∂p at p̃
//!           ∂ẑ/∂p = G H_p,  ∂ẑ/∂v = −δ G H_p,  ∂ẑ/∂δ = −G H_p (v − v_s),
//!           ∂ẑ_i/∂o_i = 1,  ∂ẑ_i/∂s_i = h_i(p̃)
//! update:   ν = z ⊖ ẑ,  S = H P⁻ Hᵀ + R,  K = [P⁻ Hᵀ S⁻¹]_E  (rows of the estimated states E, 0 elsewhere)
//!           X = X⁻ + K ν,  P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ        (Joseph, any gain: consider_update)
//! ```
//!
//! A **cooperative reference** is a detection of a known object (a UAV's GPS position `p_r`,
//! velocity `v_r`, position covariance `Σ_r`): `ẑ` uses `p_r, v_r` instead of the target's, `H`
//! has no target columns, and the GPS error enters the noise, `R_r = R + G H_p Σ_r H_pᵀ Gᵀ`
//! (the nuisance position marginalised to first order, as Okello & Ristic 2003 treat the
//! registration of dissimilar sensors). The target still moves with it, through its correlation
//! with the biases.
//!
//! # Observability: held at the prior until the data determine a term
//!
//! Beside the estimate's covariance `P` the state carries `P_f`, the covariance the full
//! augmented filter (every term estimated from the start) would have along the same
//! linearisation points. With linear-Gaussian dynamics `P_f⁻¹` is the prior's information plus
//! what the measurements gave (the posterior Cramér–Rao recursion of Tichavský, Muravchik &
//! Nehorai 1998, evaluated at the estimate). A term `i` with prior standard deviation `σ_i` is
//! **observable** once
//!
//! ```text
//! (P_f)_ii ≤ κ² σ_i²          (κ = 0.3 by default: the data know it three times better than the prior)
//! ```
//!
//! and a sensor's whole block once `λ_min(D^{1/2} P_f,bb⁻¹ D^{1/2}) ≥ 1/κ²` (`D` the prior
//! variances): the smallest eigenvalue of its normalised information against a threshold. Until
//! then the term is **held**: a Schmidt–Kalman consider state (Schmidt 1966), its gain row zero so
//! that its estimate stays at the prior (or moves only by its dynamics), its uncertainty still in
//! every covariance the target's estimate carries. A radar alone sees a rotated or scaled CV track
//! as another CV track, so its azimuth offset and range scale stay held and reported
//! unobservable instead of being fitted to the target's manoeuvres.
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
//!   and Navigation*, Wiley 2001.
//! * X. Lin, Y. Bar-Shalom, T. Kirubarajan, "Multisensor multitarget bias estimation for general
//!   asynchronous sensors", *IEEE Trans. AES* 41(3), 2005.
//! * D. Belfadel, R. W. Osborne III, Y. Bar-Shalom, "Bias estimation and observability for optical
//!   sensor measurements with targets of opportunity", *JAIF* 9(2), 2014.
//! * N. Okello, B. Ristic, "Maximum likelihood registration for multiple dissimilar sensors",
//!   *IEEE Trans. AES* 39(3), 2003.
//! * P. Tichavský, C. H. Muravchik, A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time
//!   nonlinear filtering", *IEEE Trans. SP* 46(5), 1998.
//! * B. Friedland, "Treatment of bias in recursive filtering", *IEEE Trans. AC* 14(4), 1969.
//! * S. F. Schmidt, "Application of state-space methods to navigation problems", *Advances in
//!   Control Systems* 3, 1966.

mod filter;
pub mod generate;
mod imm;
mod model;
mod report;
mod truth;

pub use filter::{
    KnownObject, Observation, Registration, RegistrationState, Seen, SensorSlots, Tuning, Updated,
};
pub use imm::{DriftModes, RegistrationImm, RegistrationImmState};
pub use model::{BiasPrior, Dynamics, MAX_COMPONENTS, SensorBias, Term};
pub use report::{SensorEstimate, TermEstimate};
pub use truth::BiasTruth;

#[cfg(test)]
mod tests;
