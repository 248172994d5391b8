//! What the registration filter says about each sensor: every bias term's estimate, standard
//! deviation and observability ([`SensorEstimate`]), and its `bias_est` JSON
//! (FORMAT-REGISTRATION.md §4).

use nalgebra::{DMatrix, SymmetricEigen};
use serde_json::{Value, json};

use super::filter::{Registration, RegistrationState};
use super::model::Term;

/// One bias term's estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermEstimate {
    /// The term.
    pub term: Term,
    /// Its index in the state.
    pub index: usize,
    /// Estimate.
    pub value: f64,
    /// Standard deviation (of the consider covariance: the true one).
    pub std: f64,
    /// The standard deviation a filter estimating every term would have, over the prior's.
    pub ratio: f64,
    /// Determined by the data (`ratio ≤ κ`): estimated, no longer held at its prior.
    pub observable: bool,
}

/// One sensor's bias estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorEstimate {
    /// Number of measurement components.
    pub dim: usize,
    /// Its terms, in state order.
    pub terms: Vec<TermEstimate>,
    /// Covariance of the terms (rows and columns in the order of `terms`).
    pub cov: Vec<Vec<f64>>,
    /// The smallest eigenvalue of the information a filter estimating every term would have
    /// about the sensor's bias block, normalised by the prior's: `1 / λ_max(D^{-1/2} P D^{-1/2})`,
    /// `D` the prior variances (1 = nothing learnt beyond the prior). `f64::INFINITY` without
    /// terms.
    pub information: f64,
    /// Every direction of the block determined: `information ≥ 1/κ²`.
    pub observable: bool,
}

impl<const K: usize, const N: usize> Registration<K, N> {
    /// Every sensor's bias estimate, in sensor order.
    pub fn estimates(&self, state: &RegistrationState<N>) -> Vec<SensorEstimate> {
        let kappa = self.tuning().kappa;
        self.sensors()
            .iter()
            .map(|slots| {
                let mut terms = Vec::new();
                let mut prior_std = Vec::new();
                for (term, index) in slots.terms() {
                    let sigma = self.prior_of(index).map_or(1.0, |p| p.std);
                    prior_std.push(sigma);
                    terms.push(TermEstimate {
                        term,
                        index,
                        value: state.estimate.mean[index],
                        std: state.estimate.cov[(index, index)].max(0.0).sqrt(),
                        ratio: state.full_cov[(index, index)].max(0.0).sqrt() / sigma,
                        observable: self.determined(state, index),
                    });
                }
                let n = terms.len();
                let cov = (0..n)
                    .map(|a| {
                        (0..n)
                            .map(|b| state.estimate.cov[(terms[a].index, terms[b].index)])
                            .collect()
                    })
                    .collect();
                let information = if n == 0 {
                    f64::INFINITY
                } else {
                    let c = DMatrix::from_fn(n, n, |a, b| {
                        state.full_cov[(terms[a].index, terms[b].index)]
                            / (prior_std[a] * prior_std[b])
                    });
                    let c = (&c + c.transpose()) * 0.5;
                    let top = SymmetricEigen::new(c).eigenvalues.max();
                    if top > 0.0 { 1.0 / top } else { f64::INFINITY }
                };
                SensorEstimate {
                    dim: slots.dim,
                    terms,
                    cov,
                    information,
                    observable: information >= 1.0 / (kappa * kappa),
                }
            })
            .collect()
    }
}

impl SensorEstimate {
    /// The term `term`, if the sensor has it.
    pub fn term(&self, term: Term) -> Option<&TermEstimate> {
        self.terms.iter().find(|t| t.term == term)
    }

    /// The sensor's entry of an estimate line's `bias_est` (FORMAT-REGISTRATION.md §4):
    /// `offset`, `scale` (one entry per measurement component, `null` where the sensor has no
    /// such term) with their `_std`, `time_offset` and `time_offset_std`, `observable` (the same
    /// shapes, plus `all`), `information`, `terms` and `cov`.
    pub fn to_json(&self) -> Value {
        let mut out = serde_json::Map::new();
        let mut observable = serde_json::Map::new();
        for (key, of) in [
            ("offset", Term::Offset as fn(usize) -> Term),
            ("scale", Term::Scale),
        ] {
            let per: Vec<Option<&TermEstimate>> = (0..self.dim).map(|i| self.term(of(i))).collect();
            if per.iter().all(Option::is_none) {
                continue;
            }
            out.insert(
                key.into(),
                json!(per.iter().map(|t| t.map(|t| t.value)).collect::<Vec<_>>()),
            );
            out.insert(
                format!("{key}_std"),
                json!(per.iter().map(|t| t.map(|t| t.std)).collect::<Vec<_>>()),
            );
            observable.insert(
                key.into(),
                json!(
                    per.iter()
                        .map(|t| t.map(|t| t.observable))
                        .collect::<Vec<_>>()
                ),
            );
        }
        if let Some(t) = self.term(Term::TimeOffset) {
            out.insert("time_offset".into(), json!(t.value));
            out.insert("time_offset_std".into(), json!(t.std));
            observable.insert("time_offset".into(), json!(t.observable));
        }
        observable.insert("all".into(), json!(self.observable));
        out.insert("observable".into(), Value::Object(observable));
        if self.information.is_finite() {
            out.insert("information".into(), json!(self.information));
        }
        out.insert(
            "terms".into(),
            json!(self.terms.iter().map(|t| t.term.name()).collect::<Vec<_>>()),
        );
        out.insert("cov".into(), json!(self.cov));
        Value::Object(out)
    }
}
