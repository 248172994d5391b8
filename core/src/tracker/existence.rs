//! Track existence: the probability ψ that a track follows a real target, as integrated
//! probabilistic data association carries it (\[IPDA\]), and the rules that confirm and delete
//! tracks by it instead of M-of-N and a miss count.
//!
//! Existence is a two-state Markov chain (a target exists, or the track follows nothing); a track
//! never turns into a target by itself (`p₂₁ = 0`), so the prediction over `Δt` is
//!
//! ```text
//! ψ_{k|k−1} = p_S(Δt) ψ_{k−1|k−1},   p_S(Δt) = p_S^Δt       ([IPDA]'s chain, p₁₁ = p_S^Δt, p₂₁ = 0)
//! ```
//!
//! with `p_S` the probability that a target persists for one second. A scan's update with the
//! detections `zⱼ` in the gate (gate probability `P_G`, detection probability `P_D`, clutter
//! density `ρ` in measurement space):
//!
//! ```text
//! Λⱼ = P_D N(zⱼ; ẑ, S) / ρ                                   (likelihood ratio of detection j)
//! δ  = P_D P_G − Σⱼ Λⱼ
//! ψ_{k|k} = (1 − δ) ψ_{k|k−1} / (1 − δ ψ_{k|k−1})
//! β₀ = (1 − P_D P_G) / (1 − δ),   βⱼ = Λⱼ / (1 − δ)
//! ```
//!
//! `βⱼ` is the probability that detection j is the target's given that the target exists, `β₀`
//! that none is. [`ipda`] is this single-track update; the joint one of tracks sharing detections
//! is `jipda`'s, which reduces to it for a lone track.
//!
//! # References
//! * \[IPDA\] D. Mušicki, R. Evans, S. Stanković, "Integrated probabilistic data association",
//!   *IEEE Trans. Automatic Control* 39(6), 1237–1241, 1994.

use crate::{EstimationError, Result};

/// Existence tuning: the Markov chain and the thresholds that confirm and delete tracks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Existence {
    /// `p_S`: probability that a target persists for one second.
    pub survival: f64,
    /// `ψ₀`: existence of a track started from one detection.
    pub initial: f64,
    /// A tentative track whose existence reaches this is confirmed.
    pub confirm: f64,
    /// A track whose existence falls below this is deleted.
    pub delete: f64,
}

impl Existence {
    /// Checked tuning: every value in (0, 1), `delete < initial`, `delete < confirm`.
    pub fn new(survival: f64, initial: f64, confirm: f64, delete: f64) -> Result<Self> {
        let unit = |v: f64| v > 0.0 && v < 1.0;
        if !(unit(survival) && unit(initial) && unit(confirm) && unit(delete))
            || delete >= initial
            || delete >= confirm
        {
            return Err(EstimationError::InvalidParameter(format!(
                "existence needs survival, initial, confirm, delete in (0, 1) with delete below \
                 initial and confirm, got {survival}, {initial}, {confirm}, {delete}"
            )));
        }
        Ok(Self {
            survival,
            initial,
            confirm,
            delete,
        })
    }

    /// `ψ_{k|k−1} = p_S^Δt ψ_{k−1|k−1}` (\[IPDA\]'s Markov chain with `p₂₁ = 0`).
    pub fn predict(&self, psi: f64, dt: f64) -> f64 {
        psi * self.survival.powf(dt.max(0.0))
    }
}

/// What the single-track update of [`ipda`] gives.
#[derive(Debug, Clone, PartialEq)]
pub struct IpdaUpdate {
    /// `ψ_{k|k}`.
    pub existence: f64,
    /// `β₀`: no detection is the target's, given that it exists.
    pub miss: f64,
    /// `βⱼ` of each detection, in the order of the ratios given.
    pub detections: Vec<f64>,
}

/// The IPDA update of one track (the module's equations, \[IPDA\]): predicted existence `psi`, `P_D P_G`,
/// and the likelihood ratio `Λⱼ = P_D N(zⱼ) / ρ` of each gated detection.
pub fn ipda(psi: f64, pd_pg: f64, ratios: &[f64]) -> IpdaUpdate {
    let delta = pd_pg - ratios.iter().sum::<f64>();
    let one_minus = 1.0 - delta;
    IpdaUpdate {
        existence: one_minus * psi / (1.0 - delta * psi),
        miss: (1.0 - pd_pg) / one_minus,
        detections: ratios.iter().map(|r| r / one_minus).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_update() {
        // ψ = 0.5, P_D = 0.9, P_G = 0.99, two detections with N = 0.01 and 0.002 at ρ = 0.001:
        // Λ = 9 and 1.8, δ = 0.891 − 10.8 = −9.909, ψ' = 10.909·0.5 / (1 + 4.9545) = 0.916030…,
        // β₀ = 0.109 / 10.909, β = 9 / 10.909, 1.8 / 10.909.
        let u = ipda(0.5, 0.9 * 0.99, &[0.9 * 0.01 / 0.001, 0.9 * 0.002 / 0.001]);
        assert!((u.existence - 10.909 * 0.5 / 5.9545).abs() < 1e-12, "{u:?}");
        assert!((u.miss - 0.109 / 10.909).abs() < 1e-12);
        assert!((u.detections[0] - 9.0 / 10.909).abs() < 1e-12);
        assert!((u.detections[1] - 1.8 / 10.909).abs() < 1e-12);
        assert!((u.miss + u.detections.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        // A miss: ψ' = (1 − P_D P_G) ψ / (1 − P_D P_G ψ) = 0.109·0.5 / 0.5545.
        let m = ipda(0.5, 0.891, &[]);
        assert!((m.existence - 0.109 * 0.5 / 0.5545).abs() < 1e-12);
        assert_eq!((m.miss, m.detections.len()), (1.0, 0));
    }

    #[test]
    fn markov_prediction_and_checks() {
        let e = Existence::new(0.99, 0.1, 0.9, 0.01).unwrap();
        assert!((e.predict(0.5, 2.0) - 0.5 * 0.99 * 0.99).abs() < 1e-15);
        assert_eq!(e.predict(0.5, 0.0), 0.5);
        assert!(Existence::new(1.0, 0.1, 0.9, 0.01).is_err());
        assert!(Existence::new(0.99, 0.01, 0.9, 0.01).is_err());
        assert!(Existence::new(0.99, 0.1, 0.9, f64::NAN).is_err());
    }
}
