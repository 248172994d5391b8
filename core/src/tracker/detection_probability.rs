//! A sensor's detection probability `P_D` estimated online from what its scans did to the
//! confirmed tracks: each scan of the sensor is, for every track confirmed before it, one
//! Bernoulli trial — detected (the scan's association updated the track) or missed — and the
//! estimate is the mean of the Beta posterior of those trials (the conjugate prior of a Bernoulli
//! rate, \[BDA\] §2.4), with exponential forgetting so that a sensor whose `P_D` changes (a
//! camera re-pointed, weather) is followed:
//!
//! ```text
//! α ← λ α + d,   β ← λ β + (1 − d)          (d = 1 detected, 0 missed; λ = 1 − 1/memory)
//! P̂_D = α / (α + β),   clamped to [PD_MIN, PD_MAX]
//! ```
//!
//! starting from the prior `Beta(w p₀, w (1 − p₀))` (mean `p₀`, worth `w` trials). `α + β` tends
//! to `memory`: the estimate weighs about the last `memory` trials.
//!
//! A scan carries no field of view, so every confirmed track counts as one the sensor could
//! have seen: a sensor that sees part of the scene (a camera slaved to one of two cars) gets the
//! fraction of the confirmed tracks it sees, the average `P_D` of its scans over the tracks,
//! which is what the soft and multi-scan associators' existence needs so that the scans that
//! cannot see a track do not delete it. `PD_MIN` keeps such a sensor's detections able to
//! update a track; `PD_MAX` keeps a miss from ruling a target out.
//!
//! # References
//! * \[BDA\] A. Gelman, J. B. Carlin, H. S. Stern, D. B. Dunson, A. Vehtari, D. B. Rubin,
//!   *Bayesian Data Analysis*, 3rd ed., CRC Press, 2013.

use crate::{EstimationError, Result};

/// The smallest estimate given to the associators.
pub const PD_MIN: f64 = 0.05;
/// The largest estimate given to the associators.
pub const PD_MAX: f64 = 0.99;

/// The online estimate of one sensor's `P_D` (the module's Beta posterior).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdEstimate {
    /// `α`: (discounted) detections plus the prior's.
    alpha: f64,
    /// `β`: (discounted) misses plus the prior's.
    beta: f64,
    /// `λ`, the discount of past trials at each new one.
    forget: f64,
    /// Trials seen (not discounted).
    trials: u64,
}

impl PdEstimate {
    /// The prior `Beta(weight·p0, weight·(1 − p0))`, forgetting with `λ = 1 − 1/memory`. Fails
    /// unless `p0` is in (0, 1), `weight > 0` and `memory ≥ 1`, all finite.
    pub fn new(p0: f64, weight: f64, memory: f64) -> Result<Self> {
        let valid = p0 > 0.0 && p0 < 1.0 && weight > 0.0 && weight.is_finite();
        if !(valid && memory >= 1.0 && memory.is_finite()) {
            return Err(EstimationError::InvalidParameter(format!(
                "P_D estimate needs a prior in (0, 1), a weight > 0 and a memory ≥ 1, got \
                 {p0}, {weight}, {memory}"
            )));
        }
        Ok(Self {
            alpha: weight * p0,
            beta: weight * (1.0 - p0),
            forget: 1.0 - 1.0 / memory,
            trials: 0,
        })
    }

    /// One scan's trials: `detected` confirmed tracks detected, `missed` missed.
    pub fn observe(&mut self, detected: u32, missed: u32) {
        for d in std::iter::repeat_n(1.0, detected as usize)
            .chain(std::iter::repeat_n(0.0, missed as usize))
        {
            self.alpha = self.forget * self.alpha + d;
            self.beta = self.forget * self.beta + (1.0 - d);
        }
        self.trials += u64::from(detected) + u64::from(missed);
    }

    /// The posterior mean `α / (α + β)`, unclamped.
    pub fn mean(&self) -> f64 {
        self.alpha / (self.alpha + self.beta)
    }

    /// The estimate the associators take: [`mean`](Self::mean) within [`PD_MIN`, `PD_MAX`].
    pub fn pd(&self) -> f64 {
        self.mean().clamp(PD_MIN, PD_MAX)
    }

    /// Trials observed so far.
    pub fn trials(&self) -> u64 {
        self.trials
    }

    /// The posterior's standard deviation, `√(αβ / ((α+β)²(α+β+1)))`.
    pub fn std(&self) -> f64 {
        let n = self.alpha + self.beta;
        (self.alpha * self.beta / (n * n * (n + 1.0))).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_starts_at_the_prior_and_converges_to_the_detected_fraction() {
        let mut e = PdEstimate::new(0.9, 4.0, 200.0).unwrap();
        assert!((e.mean() - 0.9).abs() < 1e-12);
        assert_eq!(e.trials(), 0);
        // One of two tracks seen in every scan: the fraction 1/2 (the newest trial, a miss,
        // weighs most: λ / (1 + λ) after a detection and a miss).
        for _ in 0..2_000 {
            e.observe(1, 1);
        }
        assert!((e.mean() - 0.995 / 1.995).abs() < 1e-9, "{}", e.mean());
        assert_eq!(e.trials(), 4_000);
        // The posterior is worth about `memory` trials: std ≈ √(p(1−p)/201).
        assert!(
            (e.std() - (0.25f64 / 201.0).sqrt()).abs() < 1e-3,
            "{}",
            e.std()
        );
        // Hand-computed first step from the prior Beta(3.6, 0.4), λ = 0.995: a miss.
        let mut f = PdEstimate::new(0.9, 4.0, 200.0).unwrap();
        f.observe(0, 1);
        let (a, b) = (0.995 * 3.6, 0.995 * 0.4 + 1.0);
        assert!((f.mean() - a / (a + b)).abs() < 1e-12);
    }

    #[test]
    fn a_changed_sensor_is_followed_and_the_estimate_is_clamped() {
        let mut e = PdEstimate::new(0.5, 2.0, 50.0).unwrap();
        for _ in 0..500 {
            e.observe(1, 0);
        }
        assert_eq!(e.pd(), PD_MAX);
        assert!(e.mean() > 0.999);
        // The sensor stops detecting: within a few memories the estimate follows.
        for _ in 0..300 {
            e.observe(0, 1);
        }
        assert!(e.mean() < 0.01, "{}", e.mean());
        assert_eq!(e.pd(), PD_MIN);
    }

    #[test]
    fn bad_priors_are_refused() {
        assert!(PdEstimate::new(1.0, 4.0, 200.0).is_err());
        assert!(PdEstimate::new(0.9, 0.0, 200.0).is_err());
        assert!(PdEstimate::new(0.9, 4.0, 0.5).is_err());
        assert!(PdEstimate::new(f64::NAN, 4.0, 200.0).is_err());
    }
}
