//! The filter a track runs, behind one small trait ([`TrackFilter`]) so that the tracker does not
//! care whether a track is a single Gaussian filter ([`GaussianFilter`]: EKF, CDKF) or a mixture
//! ([`ImmFilter`]: IMM over EKF or CDKF mode filters; [`CimmFilter`]: the road-constrained IMM of
//! \[CIMM\]). The sensor is not part of the filter: every
//! call takes the measurement model of the scan at hand, so one track is updated by cameras on
//! moving UAVs and by a ground radar alike.
//!
//! # References
//! * \[PDAF\] Y. Bar-Shalom, F. Daum, J. Huang, "The probabilistic data association filter",
//!   *IEEE Control Systems Magazine* 29(6), 82–100, 2009.

use nalgebra::SVector;

use crate::Result;
use crate::filter::{Imm, ImmState, MeasurementPrediction, NonlinearFilter, Predictor};
use crate::measurement::MeasurementModel;
use crate::road::{RoadConstraint, RoadNetwork};
use crate::state::{Gaussian, moment_match};

/// What the tracker needs from a track's filter: predict, predict the measurement of a sensor (for
/// gating and association; Stone Soup's `MeasurementPredictor`), update, and a Gaussian summary
/// for output and deletion.
pub trait TrackFilter<const N: usize> {
    /// Per-track filter state.
    type State: Clone + std::fmt::Debug;
    /// Filter state of a new track from the initiator's Gaussian.
    fn start(&self, initial: Gaussian<N>) -> Result<Self::State>;
    /// Predicts `state` forward by `dt` seconds.
    fn predict(&self, state: &Self::State, dt: f64) -> Result<Self::State>;
    /// Predicted measurement `ẑ`, `S` of `predicted` under the sensor model `sensor`.
    fn predict_measurement<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Self::State,
        sensor: &H,
    ) -> Result<MeasurementPrediction<M>>;
    /// Updates `predicted` with the detection `z` of `sensor`.
    fn update<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Self::State,
        sensor: &H,
        z: &SVector<f64, M>,
    ) -> Result<Self::State>;
    /// The update with a mixture of association hypotheses (soft association, PDA): "no
    /// detection" with weight `miss` and each detection `zⱼ` with its weight `βⱼ` (the weights
    /// sum to 1), reduced to one state of the filter by moment matching; each component is a
    /// Joseph-form update. For a single Gaussian (the PDA update of \[PDAF\], written as the
    /// moments of the mixture so that it holds for any gain):
    ///
    /// ```text
    /// x = β₀ x̂ + Σⱼ βⱼ xⱼ,   P = β₀ [P̂ + (x̂ − x)(x̂ − x)ᵀ] + Σⱼ βⱼ [Pⱼ + (xⱼ − x)(xⱼ − x)ᵀ]
    /// ```
    ///
    /// with `xⱼ, Pⱼ` the update of the prediction `x̂, P̂` with `zⱼ`; a mixture filter (IMM)
    /// does it per mode ([`Imm::update_mixture_with`]).
    fn update_mixture<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Self::State,
        sensor: &H,
        detections: &[(SVector<f64, M>, f64)],
        miss: f64,
    ) -> Result<Self::State>;
    /// Gaussian summary of `state` (moment-matched for mixtures).
    fn estimate(&self, state: &Self::State) -> Gaussian<N>;
    /// Mode probabilities of a mixture (empty for a single Gaussian).
    fn mode_probabilities(&self, _state: &Self::State) -> Vec<f64> {
        Vec::new()
    }
    /// `state` moved to the Gaussian summary `g` by an update made outside the filter (sensor
    /// registration's joint update of every track with the biases). A single Gaussian becomes
    /// `g`; a mixture keeps its mode probabilities, every mode shifted by the change of the
    /// combined mean and its covariance changed by that of the combined covariance.
    fn recentre(&self, _state: &Self::State, g: Gaussian<N>) -> Result<Self::State> {
        self.start(g)
    }
}

/// A mixture moved to the Gaussian summary `g`: every mode shifted by the change of the combined
/// mean and its covariance changed by that of the combined covariance, `P_r + (P_g − P)`, or `g`'s
/// own covariance where that is not positive definite; the mode probabilities kept.
fn recentre_modes<const N: usize, const R: usize>(
    state: &ImmState<N, R>,
    g: Gaussian<N>,
) -> Result<ImmState<N, R>> {
    let c = state.combined();
    let (dm, dp) = (g.mean - c.mean, g.cov - c.cov);
    let mut out = *state;
    for m in &mut out.modes {
        let cov = m.cov + dp;
        let cov = (cov + cov.transpose()) * 0.5;
        *m = Gaussian::new(m.mean + dm, cov).or_else(|_| Gaussian::new(m.mean + dm, g.cov))?;
    }
    Ok(out)
}

/// Any Gaussian filter `F` that takes every measurement model ([`NonlinearFilter`]: `Extended`,
/// `CentralDifference`) with its transition model `T`. On linear models (`position` sensors) the
/// EKF is the KF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussianFilter<F, T> {
    /// The filter (`Extended`, `CentralDifference`).
    pub filter: F,
    /// Transition model.
    pub motion: T,
}

impl<F, T, const N: usize> TrackFilter<N> for GaussianFilter<F, T>
where
    F: Predictor<T, N, State = Gaussian<N>> + NonlinearFilter<N>,
{
    type State = Gaussian<N>;

    fn start(&self, initial: Gaussian<N>) -> Result<Gaussian<N>> {
        Ok(initial)
    }

    fn predict(&self, state: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        self.filter.predict(&self.motion, state, dt)
    }

    fn predict_measurement<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Gaussian<N>,
        sensor: &H,
    ) -> Result<MeasurementPrediction<M>> {
        self.filter.predict_measurement_with(sensor, predicted)
    }

    fn update<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Gaussian<N>,
        sensor: &H,
        z: &SVector<f64, M>,
    ) -> Result<Gaussian<N>> {
        Ok(self.filter.update_with(sensor, predicted, z)?.state)
    }

    fn update_mixture<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &Gaussian<N>,
        sensor: &H,
        detections: &[(SVector<f64, M>, f64)],
        miss: f64,
    ) -> Result<Gaussian<N>> {
        let mut gs = Vec::with_capacity(detections.len() + 1);
        let mut ws = Vec::with_capacity(detections.len() + 1);
        gs.push(*predicted);
        ws.push(miss);
        for (z, beta) in detections {
            gs.push(self.filter.update_with(sensor, predicted, z)?.state);
            ws.push(*beta);
        }
        let g = moment_match(&gs, &ws);
        Gaussian::new(g.mean, g.cov)
    }

    fn estimate(&self, state: &Gaussian<N>) -> Gaussian<N> {
        *state
    }
}

/// An IMM track: the [`Imm`] estimator and the mode probabilities a new track starts with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImmFilter<F, T, const R: usize> {
    /// Mode filter, mode models and transition matrix.
    pub imm: Imm<F, T, R>,
    /// Mode probabilities of a new track.
    pub initial_probs: [f64; R],
}

impl<F, T, const N: usize, const R: usize> TrackFilter<N> for ImmFilter<F, T, R>
where
    F: Predictor<T, N, State = Gaussian<N>> + NonlinearFilter<N>,
{
    type State = ImmState<N, R>;

    /// Every mode starts from the initiator's Gaussian.
    fn start(&self, initial: Gaussian<N>) -> Result<ImmState<N, R>> {
        ImmState::new(initial, self.initial_probs)
    }

    fn predict(&self, state: &ImmState<N, R>, dt: f64) -> Result<ImmState<N, R>> {
        self.imm.predict(state, dt)
    }

    fn predict_measurement<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
    ) -> Result<MeasurementPrediction<M>> {
        self.imm.predict_measurement_with(sensor, predicted)
    }

    fn update<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
        z: &SVector<f64, M>,
    ) -> Result<ImmState<N, R>> {
        self.imm.update_with(sensor, predicted, z)
    }

    fn update_mixture<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
        detections: &[(SVector<f64, M>, f64)],
        miss: f64,
    ) -> Result<ImmState<N, R>> {
        self.imm
            .update_mixture_with(sensor, predicted, detections, miss)
    }

    fn estimate(&self, state: &ImmState<N, R>) -> Gaussian<N> {
        state.combined()
    }

    fn mode_probabilities(&self, state: &ImmState<N, R>) -> Vec<f64> {
        state.probs.to_vec()
    }

    fn recentre(&self, state: &ImmState<N, R>, g: Gaussian<N>) -> Result<ImmState<N, R>> {
        recentre_modes(state, g)
    }
}

/// A road-constrained IMM track (\[CIMM\] §3.1–3.2): the [`ImmFilter`], and after every sensor
/// update the road pseudo-measurement ([`RoadConstraint`]) applied in every mode filter on the
/// road nearest to the combined estimate — when that road's centre line is within `max_offset_m`,
/// so that a target off the network is tracked unconstrained.
#[derive(Debug, Clone, PartialEq)]
pub struct CimmFilter<F, T, const R: usize> {
    /// The IMM of the modes.
    pub imm: ImmFilter<F, T, R>,
    /// The road network.
    pub roads: RoadNetwork,
    /// Normal-velocity std of the constraint, m/s.
    pub sigma_v: f64,
    /// Largest distance from the nearest centre line at which the constraint applies, m.
    pub max_offset_m: f64,
}

impl<F, T, const R: usize> CimmFilter<F, T, R> {
    /// The road update of \[CIMM\] §3.1 on `s` (unchanged away from every road).
    pub fn constrain<const N: usize>(&self, s: &ImmState<N, R>) -> Result<ImmState<N, R>>
    where
        F: NonlinearFilter<N>,
    {
        let c = s.combined().mean;
        let p = nalgebra::Vector2::new(c[0], c[1]);
        match self.roads.nearest(&p) {
            Some(road) if road.project(&p).offset.abs() <= self.max_offset_m => {
                let h = RoadConstraint::new(road, self.sigma_v);
                self.imm.imm.update_with(&h, s, &RoadConstraint::z())
            }
            _ => Ok(*s),
        }
    }
}

impl<F, T, const N: usize, const R: usize> TrackFilter<N> for CimmFilter<F, T, R>
where
    F: Predictor<T, N, State = Gaussian<N>> + NonlinearFilter<N>,
{
    type State = ImmState<N, R>;

    fn start(&self, initial: Gaussian<N>) -> Result<ImmState<N, R>> {
        self.imm.start(initial)
    }

    fn predict(&self, state: &ImmState<N, R>, dt: f64) -> Result<ImmState<N, R>> {
        self.imm.predict(state, dt)
    }

    fn predict_measurement<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
    ) -> Result<MeasurementPrediction<M>> {
        self.imm.predict_measurement(predicted, sensor)
    }

    /// The sensor update of the IMM, then the road update.
    fn update<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
        z: &SVector<f64, M>,
    ) -> Result<ImmState<N, R>> {
        self.constrain(&self.imm.update(predicted, sensor, z)?)
    }

    /// The IMM's mixture update, then the road update.
    fn update_mixture<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        predicted: &ImmState<N, R>,
        sensor: &H,
        detections: &[(SVector<f64, M>, f64)],
        miss: f64,
    ) -> Result<ImmState<N, R>> {
        self.constrain(
            &self
                .imm
                .update_mixture(predicted, sensor, detections, miss)?,
        )
    }

    fn estimate(&self, state: &ImmState<N, R>) -> Gaussian<N> {
        self.imm.estimate(state)
    }

    fn mode_probabilities(&self, state: &ImmState<N, R>) -> Vec<f64> {
        self.imm.mode_probabilities(state)
    }

    /// The mixture moved to `g` as the IMM's is, then the road update: the outside update is a
    /// sensor update, and \[CIMM\] §3.1 follows every sensor update with the road's.
    fn recentre(&self, state: &ImmState<N, R>, g: Gaussian<N>) -> Result<ImmState<N, R>> {
        self.constrain(&recentre_modes(state, g)?)
    }
}
