//! What the bank reports over the hypotheses of which sensors are biased: its tracks
//! ([`BiasBank::output`]), its biases ([`BiasBank::state`], [`BiasBank::report`]), each the
//! mixture over the hypotheses weighed by their Savage–Dickey ratios (see the parent module).

use super::*;

/// A hypothesis of [`BiasBank::output`] this far below the likeliest in log weight (e⁻⁴⁰ of it)
/// is left out before its conditioning.
const NEGLIGIBLE_LOG_WEIGHT: f64 = 40.0;

/// The bank's tracks weighed over which sensors are biased ([`BiasBank::output`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BankOutput<const K: usize> {
    /// Each track's estimate: the moment-matched mixture over the hypotheses, in the order given.
    pub tracks: Vec<(TrackId, Gaussian<K>)>,
    /// Per sensor (the registration's order), the probability that it is biased.
    pub biased: Vec<f64>,
}

/// One hypothesis of which sensors are biased ([`BiasBank::output`]): those it holds biased
/// (the registration's order), its weight (normalised) and the tracks conditioned on it.
struct Hypothesis<const K: usize, const N: usize> {
    biased: Vec<bool>,
    weight: f64,
    tracks: Vec<Gaussian<K>>,
    biases: Biases<N>,
}

/// What a hypothesis holds of the biases, conditioned only when they are reported
/// ([`BiasBank::state`]; the tracks' output does not need them).
enum Biases<const N: usize> {
    /// Every term free: the bank's.
    Free,
    /// The terms at these state indices at their prior means.
    Pinned(Vec<usize>, PinnedBlock),
    /// A state of its own (the "no bias" mode's).
    Own(RegistrationState<N>),
}

/// The hypotheses of [`BiasBank::output`], weighed, and the biased modes' biases they
/// condition.
struct Weighed<const K: usize, const N: usize> {
    bank: RegistrationState<N>,
    hypotheses: Vec<Hypothesis<K, N>>,
}

/// Per sensor (of `sensors`), the weight of the hypotheses that hold it biased.
fn biased_probs<const K: usize, const N: usize>(
    weighed: &[Hypothesis<K, N>],
    sensors: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; sensors];
    for h in weighed {
        for (p, b) in out.iter_mut().zip(&h.biased) {
            if *b {
                *p += h.weight;
            }
        }
    }
    out
}

impl<const K: usize, const N: usize> BiasBank<K, N> {
    /// The bias terms' mean and covariance, as a registration state with a placeholder target
    /// (mean 0, identity covariance, uncorrelated), reported as the replay estimator's
    /// ([`crate::registration::RegistrationImm::output`]): the mixture over the hypotheses of
    /// [`BiasBank::output`], the full covariance the biased modes' (observability if there is a
    /// bias), and a sensor whose bias the data do not determine with the biased modes'
    /// covariance of its terms. The biases taken out for gating ([`BiasBank::correct`]) are
    /// the biased modes'.
    pub fn state(&self) -> RegistrationState<N> {
        // The hypotheses' weights are finite unless the bank's covariance is not (then the
        // biased modes' state says so too).
        match self.weighed(&[]) {
            Ok(weighed) => self.reported(&weighed),
            Err(_) => Self::biased_modes(&self.modes, &self.probs).state(),
        }
    }

    /// [`BiasBank::state`] from the hypotheses `weighed`.
    fn reported(&self, weighed: &Weighed<K, N>) -> RegistrationState<N> {
        let given_bias = Self::biased_modes(&self.modes, &self.probs).state();
        let (states, w): (Vec<_>, Vec<_>) = weighed
            .hypotheses
            .iter()
            .map(|h| {
                let state = match &h.biases {
                    Biases::Free => weighed.bank,
                    Biases::Pinned(pinned, block) => {
                        self.registration()
                            .conditioned(&weighed.bank, pinned, block)
                    }
                    Biases::Own(state) => *state,
                };
                (state, h.weight)
            })
            .unzip();
        reported(self.registration(), &states, &w, &given_bias)
    }

    /// Every sensor's bias estimate, its standard deviation and observability.
    pub fn estimates(&self) -> Vec<SensorEstimate> {
        self.registration().estimates(&self.state())
    }

    /// [`BiasBank::estimates`] and, per sensor, the probability that it is biased (the weight
    /// of the hypotheses of [`BiasBank::output`] that hold it biased; they depend on the biases
    /// alone), from one weighing.
    pub fn report(&self) -> Result<(Vec<SensorEstimate>, Vec<f64>)> {
        let weighed = self.weighed(&[])?;
        Ok((
            self.registration().estimates(&self.reported(&weighed)),
            biased_probs(&weighed.hypotheses, self.registration().sensors().len()),
        ))
    }

    /// The tracks `tracks` (every track of the bank, the tracker's estimates at the bank's
    /// time) weighed over the hypotheses of which sensors are biased, as the replay estimator's
    /// output ([`crate::registration::RegistrationImm`]): no sensor biased (prior [`UNBIASED_PRIOR`]), and each
    /// non-empty set of the sensors with terms (equal priors; the set of all alone above
    /// [`crate::registration::MAX_SET_SENSORS`] sensors), a constant sensor's time offset weighed apart from
    /// its other terms (the replay estimator's module docs). A hypothesis holds the terms of the
    /// sensors it takes as unbiased (and the pinned ways') at their prior means `μ_c`; its
    /// Bayes factor against every term free is the
    /// Savage–Dickey ratio and its estimate the bank's conditioned on them
    /// (`Registration::given_prior`, over the bank's joint covariance):
    ///
    /// ```text
    /// B_S = N(μ_c; b̂_c, P_cc) / N(μ_c; μ_c, Σ_c),   P(S | data) ∝ P(S) B_S
    /// x̂_i,S = x̂_i + P_ic P_cc⁻¹ (μ_c − b̂_c),   P_ii,S = P_ii − P_ic P_cc⁻¹ P_ci
    /// ```
    ///
    /// exact, for constant biases and a linear model, as the filter told those sensors are
    /// unbiased (Dickey 1971; Verdinelli & Wasserman 1995). The recursion is unchanged: the
    /// bank keeps estimating every term and the tracker keeps its tracks; this is what they
    /// report. A hypothesis whose `P_cc` is not positive definite is left out. With the modes
    /// ([`BiasBank::with_drift`]) "no sensor biased" is the "no bias" mode, its tracks and its
    /// probability, and the sets share the biased modes' (moment-matched) probability.
    pub fn output(&self, tracks: &[(TrackId, Gaussian<K>)]) -> Result<BankOutput<K>> {
        let order = self.order(tracks)?;
        let given: Vec<Gaussian<K>> = order.iter().map(|&k| tracks[k].1).collect();
        let weighed = self.weighed(&given)?.hypotheses;
        let w: Vec<f64> = weighed.iter().map(|h| h.weight).collect();
        let tracks = order
            .iter()
            .enumerate()
            .map(|(t, &k)| {
                let components: Vec<Gaussian<K>> = weighed.iter().map(|h| h.tracks[t]).collect();
                (tracks[k].0, moment_match(&components, &w))
            })
            .collect();
        Ok(BankOutput {
            tracks,
            biased: biased_probs(&weighed, self.registration().sensors().len()),
        })
    }

    /// The hypotheses of [`BiasBank::output`], weighed, each with the tracks `given` (every
    /// track in the bank's order, or none) conditioned on it.
    fn weighed(&self, given: &[Gaussian<K>]) -> Result<Weighed<K, N>> {
        let maps = track_maps(&self.modes, &self.probs, given)?;
        let mut modes = self.modes.clone();
        for m in &mut modes {
            m.follow(given, &maps);
        }
        let bank = Self::biased_modes(&modes, &self.probs);
        // With the modes, "no bias" is a mode of its own: its tracks, its probability; the
        // biased modes share the rest over the non-empty sets.
        let (none, biased_share) = match self.drift {
            Some(_) => {
                let m = &modes[UNBIASED];
                let tracks = (0..given.len())
                    .map(|t| Gaussian {
                        mean: given[t].mean + m.offset.fixed_rows::<K>(t * K),
                        cov: m.cov.fixed_view::<K, K>(t * K, t * K).into_owned(),
                    })
                    .collect();
                (
                    Some((self.probs[UNBIASED], tracks, m.state())),
                    1.0 - self.probs[UNBIASED],
                )
            }
            None => (None, 1.0),
        };
        let P = &bank.cov;
        let b0 = bank.b0();
        let sensors = bank.reg.sensors();
        let sets = &self.sets;
        let every_term: Vec<usize> = sensors
            .iter()
            .flat_map(|s| s.terms().map(|(_, i)| i))
            .collect();
        let biased_prior = 1.0 - UNBIASED_PRIOR;
        // A Gauss–Markov term wanders about its mean: its value there says nothing of whether
        // the sensor is biased, so no hypothesis holds such a sensor unbiased.
        let wanders = |i: &usize| {
            bank.reg
                .prior_of(*i)
                .is_some_and(|p| matches!(p.dynamics, Dynamics::GaussMarkov { .. }))
        };
        let empty = none
            .is_none()
            .then(|| (vec![false; sensors.len()], every_term, UNBIASED_PRIOR));
        let hypotheses = empty
            .into_iter()
            .chain(
                sets.iter()
                    .map(|s| (s.biased.clone(), s.pinned.clone(), biased_prior * s.prior)),
            )
            .filter(|(_, pinned, _)| !pinned.iter().any(wanders));
        let own = |t: usize| Gaussian {
            mean: given[t].mean + bank.offset.fixed_rows::<K>(t * K),
            cov: SMatrix::<f64, K, K>::from_fn(|r, s| P[(t * K + r, t * K + s)]),
        };
        let bank_state = bank.state();
        // Each hypothesis's Savage–Dickey ratio first (its pinned block alone), then the
        // conditioning for those whose weight is not negligible against the largest's.
        let scored: Vec<_> = hypotheses
            .filter_map(|(biased, pinned, prior)| {
                let block = if pinned.is_empty() {
                    None
                } else {
                    Some(bank.reg.savage_dickey(&bank_state, &pinned)?)
                };
                let weight = prior.ln() + block.as_ref().map_or(0.0, |b| b.log_bf);
                Some((biased, pinned, block, weight))
            })
            .collect();
        let max = scored.iter().map(|h| h.3).fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return Err(EstimationError::NonFinite("bias hypotheses"));
        }
        let mut weighed: Vec<Hypothesis<K, N>> = Vec::new();
        for (biased, pinned, block, weight) in scored {
            if weight < max - NEGLIGIBLE_LOG_WEIGHT {
                continue;
            }
            let Some(block) = block else {
                let tracks = (0..given.len()).map(own).collect();
                weighed.push(Hypothesis {
                    biased,
                    weight,
                    tracks,
                    biases: Biases::Free,
                });
                continue;
            };
            let c: Vec<usize> = pinned.iter().map(|&i| b0 + i - K).collect();
            let tracks = (0..given.len())
                .map(|t| {
                    let mut g = own(t);
                    let Ptc = DMatrix::from_fn(K, c.len(), |r, j| P[(t * K + r, c[j])]);
                    let shift = &Ptc * &block.a;
                    let drop = &Ptc * block.chol.solve(&Ptc.transpose());
                    for r in 0..K {
                        g.mean[r] += shift[r];
                        for s in 0..K {
                            g.cov[(r, s)] -= drop[(r, s)];
                        }
                    }
                    g.cov = (g.cov + g.cov.transpose()) * 0.5;
                    g
                })
                .collect();
            weighed.push(Hypothesis {
                biased,
                weight,
                tracks,
                biases: Biases::Pinned(pinned, block),
            });
        }
        let total: f64 = weighed.iter().map(|h| (h.weight - max).exp()).sum();
        for h in &mut weighed {
            h.weight = biased_share * (h.weight - max).exp() / total;
        }
        if let Some((p, tracks, state)) = none {
            weighed.push(Hypothesis {
                biased: vec![false; sensors.len()],
                weight: p,
                tracks,
                biases: Biases::Own(state),
            });
        }
        Ok(Weighed {
            bank: bank_state,
            hypotheses: weighed,
        })
    }
}
