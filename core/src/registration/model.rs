//! The bias models: which terms a sensor's bias has ([`Term`]), how each one evolves
//! ([`Dynamics`]) and its prior ([`BiasPrior`]), and a sensor's whole configuration
//! ([`SensorBias`]) as a deployment or a scenario's `sensors[*].bias` block carries it
//! (FORMAT-REGISTRATION.md §1).
//!
//! A measurement component `i` of a biased sensor reads
//!
//! ```text
//! z_i(t) = (1 + s_i) · h_i(x(t − δ)) + o_i + v_i          (FORMAT.md §3's radar bias, plus δ)
//! ```
//!
//! with an offset `o_i`, a scale `s_i` and a time offset δ (latency: a measurement stamped `t`
//! shows the world at `t − δ`). Each term a sensor has is one state of the registration filter.

use serde::{Deserialize, Serialize};

use crate::measurement::MeasKind;
use crate::{EstimationError, Result};

/// One bias term of a sensor: an additive offset or a scale of measurement component `i`, or the
/// sensor's time offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Term {
    /// `o_i`, in the units of component `i` (m, rad).
    Offset(usize),
    /// `s_i`, dimensionless (`z_i = (1 + s_i) h_i`).
    Scale(usize),
    /// δ (s): the measurement stamped `t` was taken at `t − δ`.
    TimeOffset,
}

impl Term {
    /// The name in files: `offset0`, `scale0`, `time_offset`.
    pub fn name(self) -> String {
        match self {
            Self::Offset(i) => format!("offset{i}"),
            Self::Scale(i) => format!("scale{i}"),
            Self::TimeOffset => "time_offset".into(),
        }
    }

    /// The term named `name` (the inverse of [`Term::name`]).
    pub fn parse(name: &str) -> Option<Self> {
        if name == "time_offset" {
            return Some(Self::TimeOffset);
        }
        let index = |rest: &str| rest.parse::<usize>().ok().filter(|i| *i < MAX_COMPONENTS);
        if let Some(rest) = name.strip_prefix("offset") {
            return index(rest).map(Self::Offset);
        }
        name.strip_prefix("scale").and_then(index).map(Self::Scale)
    }
}

/// The most measurement components a sensor has (`bearing_size`, 3-D `position`).
pub const MAX_COMPONENTS: usize = 3;

/// How a bias term evolves between two times Δt apart.
///
/// ```text
/// constant:      b_k = b_{k−1}
/// random walk:   b_k = b_{k−1} + w,               Var w = d² Δt
/// Gauss–Markov:  b_k − μ = φ (b_{k−1} − μ) + w,   φ = exp(−Δt/τ),  Var w = σ² (1 − φ²)
/// ```
/// The Gauss–Markov line is the exact discretisation of `db = −(b − μ)/τ dt + σ √(2/τ) dW`, whose
/// stationary standard deviation σ is the prior's `std` and whose mean μ is the prior's `mean`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Dynamics {
    /// An unknown constant.
    Constant,
    /// A random walk with drift intensity `drift` (units per √s).
    RandomWalk {
        /// Standard deviation of the change over one second.
        drift: f64,
    },
    /// A first-order Gauss–Markov process with correlation time `tau` (s).
    GaussMarkov {
        /// Correlation time τ (s).
        tau: f64,
    },
}

/// A bias term's model: its dynamics and its Gaussian prior `N(mean, std²)` (for a Gauss–Markov
/// term also the process's mean and stationary standard deviation).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct BiasPrior {
    /// Dynamics (`"model"` in files).
    #[serde(flatten)]
    pub dynamics: Dynamics,
    /// Prior mean (and the mean a Gauss–Markov term returns to).
    #[serde(default)]
    pub mean: f64,
    /// Prior standard deviation (> 0).
    pub std: f64,
}

impl BiasPrior {
    /// A constant term, prior `N(0, std²)`.
    pub fn constant(std: f64) -> Self {
        Self {
            dynamics: Dynamics::Constant,
            mean: 0.0,
            std,
        }
    }

    /// A random walk of drift intensity `drift` (units/√s), prior `N(0, std²)`.
    pub fn random_walk(std: f64, drift: f64) -> Self {
        Self {
            dynamics: Dynamics::RandomWalk { drift },
            mean: 0.0,
            std,
        }
    }

    /// A zero-mean Gauss–Markov term of stationary std `std` and correlation time `tau` (s).
    pub fn gauss_markov(std: f64, tau: f64) -> Self {
        Self {
            dynamics: Dynamics::GaussMarkov { tau },
            mean: 0.0,
            std,
        }
    }

    /// Checks the numbers: finite, std > 0, drift ≥ 0, τ > 0.
    pub fn check(&self) -> Result<()> {
        let ok = self.mean.is_finite()
            && self.std.is_finite()
            && self.std > 0.0
            && match self.dynamics {
                Dynamics::Constant => true,
                Dynamics::RandomWalk { drift } => drift.is_finite() && drift >= 0.0,
                Dynamics::GaussMarkov { tau } => tau.is_finite() && tau > 0.0,
            };
        if ok {
            Ok(())
        } else {
            Err(EstimationError::InvalidParameter(format!(
                "bias model needs finite numbers, std > 0, drift ≥ 0 and τ > 0, got {self:?}"
            )))
        }
    }

    /// `(φ, Var w)` of the transition over `dt` seconds (see [`Dynamics`]).
    pub fn transition(&self, dt: f64) -> (f64, f64) {
        match self.dynamics {
            Dynamics::Constant => (1.0, 0.0),
            Dynamics::RandomWalk { drift } => (1.0, drift * drift * dt),
            Dynamics::GaussMarkov { tau } => {
                let phi = (-dt / tau).exp();
                (phi, self.std * self.std * (1.0 - phi * phi))
            }
        }
    }
}

/// The bias terms of one sensor and their models: what a deployment's configuration or a
/// scenario's `sensors[*].bias` block (FORMAT-REGISTRATION.md §1) says about it. `offset[i]` and
/// `scale[i]` belong to measurement component `i`; `None` means the term is known to be zero.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
pub struct SensorBias {
    /// Offset of each measurement component.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub offset: Vec<Option<BiasPrior>>,
    /// Scale of each measurement component.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scale: Vec<Option<BiasPrior>>,
    /// Time offset (latency).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_offset: Option<BiasPrior>,
}

impl SensorBias {
    /// Harrier's default bias model of a sensor of kind `kind` (the one tuning of the
    /// registration acceptance runs, BENCHMARKS.md):
    ///
    /// * `range_bearing` (a ground radar): range offset, a random walk from `N(0, (50 m)²)`
    ///   drifting 0.1 m/√s; azimuth offset, a random walk from `N(0, (10 mrad)²)` drifting
    ///   0.01 mrad/√s; range scale, constant from `N(0, 0.005²)` (the drifting mode of
    ///   [`RegistrationImm`](super::RegistrationImm) multiplies the drifts by 20);
    /// * `az_el`, `bearing_size` (a gimbal camera's mounting): azimuth and elevation offsets,
    ///   constant from `N(0, (1°)²)`;
    /// * every kind: a constant time offset from `N(0, (0.3 s)²)`.
    pub fn typical(kind: MeasKind) -> Self {
        let time_offset = Some(BiasPrior::constant(0.3));
        let mount = BiasPrior::constant(1f64.to_radians());
        match kind {
            MeasKind::RangeBearing => Self {
                offset: vec![
                    Some(BiasPrior::random_walk(50.0, 0.1)),
                    Some(BiasPrior::random_walk(0.010, 1e-5)),
                ],
                scale: vec![Some(BiasPrior::constant(0.005))],
                time_offset,
            },
            MeasKind::AzEl | MeasKind::BearingSize => Self {
                offset: vec![Some(mount), Some(mount)],
                scale: Vec::new(),
                time_offset,
            },
            MeasKind::Position => Self {
                time_offset,
                ..Self::default()
            },
        }
    }

    /// Every term with its model, in state order: offsets, scales, time offset.
    pub fn terms(&self) -> impl Iterator<Item = (Term, BiasPrior)> + '_ {
        let offsets = self.offset.iter().enumerate();
        let offsets = offsets.filter_map(|(i, p)| p.map(|p| (Term::Offset(i), p)));
        let scales = self.scale.iter().enumerate();
        let scales = scales.filter_map(|(i, p)| p.map(|p| (Term::Scale(i), p)));
        offsets
            .chain(scales)
            .chain(self.time_offset.map(|p| (Term::TimeOffset, p)))
    }

    /// Checks the terms against a sensor with `dim` measurement components.
    pub fn check(&self, dim: usize) -> Result<()> {
        for (what, v) in [("offset", &self.offset), ("scale", &self.scale)] {
            if v.len() > dim {
                return Err(EstimationError::InvalidParameter(format!(
                    "{what} has {} entries, the sensor {dim} components",
                    v.len()
                )));
            }
        }
        for (term, prior) in self.terms() {
            prior
                .check()
                .map_err(|e| EstimationError::InvalidParameter(format!("{}: {e}", term.name())))?;
        }
        Ok(())
    }

    /// The registration terms of a scenario sensor's `bias` block (FORMAT-REGISTRATION.md §1):
    /// `None` when the block has none of the keys `offset`, `scale`, `time_offset` (FORMAT.md's
    /// plain `{"model": "unknown"}` says nothing a filter can use). Errors name the key.
    pub fn from_block(block: &serde_json::Value, dim: usize) -> Result<Option<Self>> {
        let has_terms = ["offset", "scale", "time_offset"]
            .iter()
            .any(|k| block.get(k).is_some());
        if !has_terms {
            return Ok(None);
        }
        let bias: Self = serde_json::from_value(block.clone())
            .map_err(|e| EstimationError::InvalidParameter(format!("bias block: {e}")))?;
        bias.check(dim)?;
        Ok(Some(bias))
    }

    /// This model as a scenario's `bias` block: `{"model": "unknown", "offset": …}`.
    pub fn to_block(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        if let Some(map) = v.as_object_mut() {
            map.insert("model".into(), "unknown".into());
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn term_names_round_trip() {
        for t in [
            Term::Offset(0),
            Term::Offset(2),
            Term::Scale(1),
            Term::TimeOffset,
        ] {
            assert_eq!(Term::parse(&t.name()), Some(t));
        }
        for bad in ["offset3", "scale", "offsetx", "time", ""] {
            assert_eq!(Term::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn gauss_markov_keeps_its_stationary_variance() {
        let p = BiasPrior::gauss_markov(30.0, 120.0);
        let (phi, q) = p.transition(7.0);
        assert!((phi * phi * 900.0 + q - 900.0).abs() < 1e-9);
        assert_eq!(BiasPrior::constant(1.0).transition(5.0), (1.0, 0.0));
        assert_eq!(BiasPrior::random_walk(1.0, 0.5).transition(4.0), (1.0, 1.0));
    }

    #[test]
    fn blocks_parse_check_and_round_trip() {
        let plain = serde_json::json!({"model": "unknown", "description": "x"});
        assert_eq!(SensorBias::from_block(&plain, 2).unwrap(), None);
        let typical = SensorBias::typical(MeasKind::RangeBearing);
        let block = typical.to_block();
        assert_eq!(block["model"], "unknown");
        assert_eq!(block["offset"][0]["model"], "random_walk");
        assert_eq!(SensorBias::from_block(&block, 2).unwrap(), Some(typical));
        let terms: Vec<_> = SensorBias::typical(MeasKind::AzEl)
            .terms()
            .map(|(t, _)| t)
            .collect();
        assert_eq!(terms, [Term::Offset(0), Term::Offset(1), Term::TimeOffset]);

        let gm = serde_json::json!({"offset": [null, {"model": "gauss_markov", "std": 0.01, "tau": 60}]});
        let b = SensorBias::from_block(&gm, 2).unwrap().unwrap();
        assert_eq!(b.offset[0], None);
        assert_eq!(
            b.offset[1].unwrap().dynamics,
            Dynamics::GaussMarkov { tau: 60.0 }
        );
        for bad in [
            serde_json::json!({"offset": [{"model": "constant", "std": -1}]}),
            serde_json::json!({"offset": [{"model": "gauss_markov", "std": 1, "tau": 0}]}),
            serde_json::json!({"offset": [{"model": "spline", "std": 1}]}),
            serde_json::json!({"scale": [null, null, null]}),
            serde_json::json!({"time_offset": {"model": "random_walk", "std": 1}}),
        ] {
            let e = SensorBias::from_block(&bad, 2).unwrap_err();
            assert!(!e.to_string().is_empty(), "{bad}");
        }
    }
}
