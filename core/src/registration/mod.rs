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
//! update:   ν = z ⊖ ẑ,  S = H P⁻ Hᵀ + R,  K = T P⁻ Hᵀ S⁻¹   (T: the target, and the determined bias directions)
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
//! # Observability: held at the prior until the data determine it
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
//! variances): the smallest eigenvalue of its normalised information against a threshold.
//!
//! What the update estimates is every bias **direction** the data determine: the eigenvectors
//! `V_o` of `C = D^{-1/2} P_f,bb D^{-1/2}` (all terms of all sensors) with eigenvalue ≤ κ²; the
//! gain is projected on them, `K_b = D^{1/2} V_o V_oᵀ D^{-1/2} [K_opt]_b`, once per scan. Every
//! other direction is **held**: a Schmidt–Kalman consider direction (Schmidt 1966), its estimate
//! at the prior (or moving only by its dynamics), its uncertainty still in every covariance the
//! target's estimate carries. Directions, not terms: a radar's range offset and range scale, or a
//! camera's azimuth offset and latency (on an orbit centred on the target a latency looks like an
//! azimuth offset), are each known long before either term alone; holding the terms kept their
//! whole uncertainty in every update (BENCHMARKS.md, "Sensor registration"). A radar alone sees a
//! rotated or scaled CV track as another CV track: its terms stay held and reported unobservable
//! instead of being fitted to the target's manoeuvres.
//!
//! # No bias, steady or drifting: three hypotheses in an IMM
//!
//! [`RegistrationImm`] runs the filter under three hypotheses weighed by their innovations
//! (\[BLK01\] §11.6.6, §11.7): **no bias** (every term pinned at its prior mean: the filter told
//! the sensors are unbiased), the model as configured (**steady**), and every random-walk term
//! drifting 20 times faster (**drifting**). The first is model selection: a filter that learns
//! ten terms pays for them when there is nothing to learn (15 % over 600 s), however close to
//! its bound it is; the unbiased hypothesis has nothing to learn, and the likelihoods carry the
//! Bayes factor's Occam penalty, so without a bias it takes the weight within seconds and the
//! cost goes (BENCHMARKS.md), while a bias the shared targets show rejects it in a few scans.
//! No single drift suits both a steady bias and a Gauss–Markov one (see [`imm`'s
//! docs](RegistrationImm)). Sensor by sensor the same selection is made in the output: each
//! biased mode is split over the sets of biased sensors, each set weighed by the Savage–Dickey
//! ratio of its unbiased sensors' block and its estimate the mode's conditioned on that block at
//! the prior (a camera mounted off and an unbiased radar: the filter takes the radar as
//! unbiased once its block is determined and at zero; `biased_prob` per sensor).
//!
//! # The multi-target form: [`BiasBank`]
//!
//! In the live multi-target tracker a sensor's bias is shared by every track it sees. The bank
//! holds the bias terms and the whole covariance of `[x_1; …; x_T; b]`, the track-to-track
//! cross-covariances a shared bias builds included, while the tracker keeps the tracks' means:
//! each update (a detection associated with a track, or a cooperative reference) is the
//! augmented EKF's on the whole state and moves every track through its correlation with the
//! biases; with one track it is [`Registration`] (`hold: false`) exactly, with two targets it
//! halves the bias error of the single-target filter (the [bank's docs](BiasBank), its tests).
//! [`BiasBank::correct`] gives a detection with the biases taken out and the bias uncertainty
//! to add to its noise, for gating and association. Stone Soup's `GaussianBiasUpdater`, which
//! drops the cross-covariance after each update, learns a camera's mounting offsets less well
//! than the single-target filter on the same data, an order of magnitude apart (BENCHMARKS.md).
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
//! * A. S. Willsky, H. L. Jones, "A generalized likelihood ratio approach to the detection and
//!   estimation of jumps in linear systems", *IEEE Trans. AC* 21(1), 1976.

mod bank;
mod filter;
pub mod generate;
mod imm;
mod model;
mod report;
mod truth;

pub use bank::{BankOutput, BiasBank, Corrected, TrackId, Tracks, UNBIASED_PRIOR};
pub use filter::{
    KnownObject, Observation, Registration, RegistrationState, Seen, SensorSlots, Tuning, Updated,
};
pub use imm::{DriftModes, MAX_SET_SENSORS, MAX_SETS, RegistrationImm, RegistrationImmState};
pub use model::{BiasPrior, Dynamics, MAX_COMPONENTS, SensorBias, Term};
pub use report::{SensorEstimate, TermEstimate};
pub use truth::BiasTruth;

#[cfg(test)]
mod tests;
