//! Late detections by retrodiction: a track's log of its own updates over a fixed lag
//! ([`UpdateLog`]), the track's state at an earlier time from it ([`UpdateLog::prior_at`]), and
//! the update with a detection older than the track ([`UpdateLog::replay`]).
//!
//! A detection made at `τ` reaches the tracker after scans of later times have updated the
//! track (an out-of-sequence measurement, OOSM: a radio link or a Zenoh mesh delays one
//! vehicle's scan behind the others'). The track keeps, for every update of the last `lag`
//! seconds, the time, the sensor model of its scan (platform pose, noise), the detection and the
//! filter state after the update, plus the newest update before that window (the **base**). For
//! a detection at `τ`, with `tᵦ ≤ τ` the newest logged update not after it:
//!
//! ```text
//! x̂(τ | tᵦ)   = predict(x̂(tᵦ | tᵦ), τ − tᵦ)             the retrodicted prior, gated against
//! x̂(τ | τ)    = update(x̂(τ | tᵦ), z(τ))                  the late detection
//! x̂(tᵢ | tᵢ)  = update(predict(x̂(tᵢ₋₁ | tᵢ₋₁), tᵢ − tᵢ₋₁), zᵢ)   every later logged update, again
//! x̂(T | t_last) = predict(x̂(t_last | t_last), T − t_last)   back to the tracker's time T
//! ```
//!
//! For a linear-Gaussian track this is the exact OOSM solution, the estimate in-order
//! processing would have given with the same associations: it is the "reprocessing" solution
//! against which Bar-Shalom (2002, "Update with out-of-sequence measurements in tracking: exact
//! solution", IEEE TAES 38(3)) derives his one-step Algorithm A, and Bar-Shalom, Chen & Mallick
//! (2004, "One-step solution for the multistep out-of-sequence-measurement problem in tracking",
//! IEEE TAES 40(1)) the multistep Bl1 and its approximations; it holds for any number of steps
//! of lag. The constant-velocity and constant-acceleration models are exactly discretised, so
//! one prediction over `a + b` equals two over `a` then `b`, and the rerun does not need the
//! scans the track coasted through. For an EKF/CDKF track it reruns the same filter (the
//! linearisation points move with the late detection, as in-order processing would have moved
//! them); for an IMM track the modes are mixed once per logged update instead of once per scan,
//! an approximation of the same order as MATLAB's filter retrodiction for `trackingIMM`.
//!
//! The cost of one late detection is one rerun of the track's own updates in the lag, not of
//! the scans of every sensor: a track updated 10 times a second with a 2-s lag reruns at most
//! about 20 updates.

use std::collections::VecDeque;

use nalgebra::SVector;

use super::filter::TrackFilter;
use crate::measurement::{Locate, MeasurementModel, SensorModel, WithSensor};
use crate::{EstimationError, Result};

/// The most updates a track's log holds: 10 updates a second from 4 sensors over a 2-s lag (a
/// track updated faster keeps a shorter window).
pub const MAX_LOGGED: usize = 80;

/// One update of a track: when, under which sensor model, with which detections, and the
/// track's filter state after it. A hard association (GNN, MHT) used one detection with weight 1;
/// a soft one (JIPDA) the mixture of its gated detections with their marginal probabilities `βⱼ`
/// and "no detection" with `β₀` ([`TrackFilter::update_mixture`]). A rerun keeps the weights of
/// the first pass (the weights a late detection would have changed are not recomputed).
#[derive(Debug, Clone, PartialEq)]
pub struct LoggedUpdate<S> {
    /// Scan time of the update (s).
    pub t: f64,
    /// The scan's sensor model (kind, platform pose, noise).
    pub sensor: SensorModel,
    /// The detections (their first [`SensorModel::dim`] components) and their weights.
    pub mixture: Vec<([f64; 3], f64)>,
    /// The weight of "no detection" (0 for a hard association).
    pub miss: f64,
    /// The filter state after the update.
    pub posterior: S,
}

impl<S> LoggedUpdate<S> {
    /// The update at `t` of `sensor` with the one detection `z` (of `sensor.dim()` components),
    /// whose posterior is `posterior`; `None` when `z` has the wrong length.
    pub fn new(t: f64, sensor: SensorModel, z: &[f64], posterior: S) -> Option<Self> {
        Self::mixture(t, sensor, &[(z, 1.0)], 0.0, posterior)
    }

    /// The update at `t` of `sensor` with the mixture of `detections` (each with its weight)
    /// and "no detection" (weight `miss`); `None` when a detection has the wrong length.
    pub fn mixture(
        t: f64,
        sensor: SensorModel,
        detections: &[(&[f64], f64)],
        miss: f64,
        posterior: S,
    ) -> Option<Self> {
        let mut mixture = Vec::with_capacity(detections.len());
        for &(z, w) in detections {
            if z.len() != sensor.dim() {
                return None;
            }
            let mut fixed = [0.0; 3];
            fixed[..z.len()].copy_from_slice(z);
            mixture.push((fixed, w));
        }
        Some(Self {
            t,
            sensor,
            mixture,
            miss,
            posterior,
        })
    }
}

/// A track's updates over the last `lag` seconds, in time order, and the newest one before
/// them (the base a detection as old as the lag is replayed from). A track's first entry is
/// its birth: the initiator's state, with the detection that started it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct UpdateLog<S> {
    entries: VecDeque<LoggedUpdate<S>>,
}

impl<S: Clone> UpdateLog<S> {
    /// An empty log.
    pub fn new() -> Self {
        Self {
            entries: VecDeque::new(),
        }
    }

    /// The updates held, oldest first.
    pub fn entries(&self) -> impl ExactSizeIterator<Item = &LoggedUpdate<S>> {
        self.entries.iter()
    }

    /// Appends an update newer than (or as new as) every one held, then forgets those no late
    /// detection within `lag` of it can need: every entry before the newest one at or before
    /// `t − lag`; and beyond [`MAX_LOGGED`] entries the oldest (memory stays bounded when a
    /// track is updated faster than the lag foresees: a detection older than the log is then
    /// refused, as one older than the lag).
    pub fn record(&mut self, update: LoggedUpdate<S>, lag: f64) {
        debug_assert!(self.entries.back().is_none_or(|b| b.t <= update.t));
        let horizon = update.t - lag;
        self.entries.push_back(update);
        while self.entries.len() > 1 && self.entries[1].t <= horizon
            || self.entries.len() > MAX_LOGGED
        {
            self.entries.pop_front();
        }
    }

    /// The index of the newest entry at or before `tau`: the base of a late detection at `tau`.
    fn base(&self, tau: f64) -> Option<usize> {
        let after = self.entries.partition_point(|e| e.t <= tau);
        after.checked_sub(1)
    }

    /// Whether a detection at `tau` can be replayed (an entry at or before `tau` is held).
    pub fn covers(&self, tau: f64) -> bool {
        self.base(tau).is_some()
    }

    /// The track's state at `tau` from its updates up to `tau` (the retrodicted prior a late
    /// detection is gated against): the newest logged posterior at or before `tau`, predicted to
    /// `tau`. `None` when the log does not reach back to `tau`.
    pub fn prior_at<F, const N: usize>(&self, filter: &F, tau: f64) -> Option<Result<S>>
    where
        F: TrackFilter<N, State = S>,
    {
        let b = &self.entries[self.base(tau)?];
        Some(predict_to(filter, &b.posterior, tau - b.t))
    }

    /// Updates the track with a detection at `late.t`, older than its latest update (see the
    /// module's documentation): the logged updates after it are applied again, and the state at
    /// `now` (the tracker's time, at or after every logged update) is returned. The log then
    /// holds the late update and the new posteriors. Fails, changing nothing, when the log does
    /// not reach back to `late.t`, `now` is before the newest logged update, or a step fails.
    pub fn replay<F, const N: usize>(
        &mut self,
        filter: &F,
        late: LoggedUpdate<()>,
        now: f64,
    ) -> Result<S>
    where
        F: TrackFilter<N, State = S>,
    {
        let b = self.base(late.t).ok_or_else(|| {
            EstimationError::InvalidParameter(format!(
                "a detection at t = {} is older than the track's log",
                late.t
            ))
        })?;
        let newest = self.entries.back().map_or(late.t, |e| e.t);
        if !(now >= newest && now.is_finite()) {
            return Err(EstimationError::InvalidParameter(format!(
                "replay to t = {now}, before the track's newest update at {newest}"
            )));
        }
        let base = &self.entries[b];
        let prior = predict_to(filter, &base.posterior, late.t - base.t)?;
        let late_posterior = update_at(filter, &prior, &late)?;
        let mut state = late_posterior.clone();
        let mut t = late.t;
        let mut rerun = Vec::with_capacity(self.entries.len() - b - 1);
        for e in self.entries.range(b + 1..) {
            state = update_at(filter, &predict_to(filter, &state, e.t - t)?, e)?;
            t = e.t;
            rerun.push(state.clone());
        }
        let now_state = predict_to(filter, &state, now - t)?;
        // Every step succeeded: rewrite the log.
        for (e, s) in self.entries.range_mut(b + 1..).zip(rerun) {
            e.posterior = s;
        }
        self.entries.insert(
            b + 1,
            LoggedUpdate {
                t: late.t,
                sensor: late.sensor,
                mixture: late.mixture,
                miss: late.miss,
                posterior: late_posterior,
            },
        );
        Ok(now_state)
    }
}

/// `state` predicted forward by `dt ≥ 0` (unchanged for `dt = 0`).
fn predict_to<F: TrackFilter<N>, const N: usize>(
    filter: &F,
    state: &F::State,
    dt: f64,
) -> Result<F::State> {
    if dt > 0.0 {
        filter.predict(state, dt)
    } else {
        Ok(state.clone())
    }
}

/// `predicted` updated as `update` was: with its one detection, or its mixture.
fn update_at<F: TrackFilter<N>, const N: usize, S>(
    filter: &F,
    predicted: &F::State,
    update: &LoggedUpdate<S>,
) -> Result<F::State> {
    update.sensor.apply(UpdateWith {
        filter,
        predicted,
        update: (&update.mixture, update.miss),
        dim: update.sensor.dim(),
    })
}

/// The visit of [`update_at`]: the detections as const-sized vectors of the concrete model.
struct UpdateWith<'a, F: TrackFilter<N>, const N: usize> {
    filter: &'a F,
    predicted: &'a F::State,
    update: (&'a [([f64; 3], f64)], f64),
    dim: usize,
}

impl<F: TrackFilter<N>, const N: usize> WithSensor<N> for UpdateWith<'_, F, N> {
    type Output = Result<F::State>;
    fn with<H, const M: usize>(self, model: &H) -> Self::Output
    where
        H: MeasurementModel<N, M> + Locate<M>,
    {
        if self.dim != M {
            return Err(EstimationError::InvalidParameter(format!(
                "a detection has {} components, the sensor measures {M}",
                self.dim
            )));
        }
        let z = |c: &[f64; 3]| SVector::<f64, M>::from_column_slice(&c[..M]);
        match self.update {
            ([(c, w)], miss) if miss == 0.0 && *w == 1.0 => {
                self.filter.update(self.predicted, model, &z(c))
            }
            (mixture, miss) => {
                let zs: Vec<_> = mixture.iter().map(|(c, w)| (z(c), *w)).collect();
                self.filter.update_mixture(self.predicted, model, &zs, miss)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::{Extended, Imm, ModeModel};
    use crate::measurement::{Geometry, MeasKind};
    use crate::motion::ConstantVelocity;
    use crate::state::Gaussian;
    use crate::tracker::filter::{GaussianFilter, ImmFilter};
    use nalgebra::{Matrix4, Vector3, Vector4};

    type Kf = GaussianFilter<Extended, ConstantVelocity<4>>;

    fn kf() -> Kf {
        GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::new(0.5),
        }
    }

    fn position(noise: f64) -> SensorModel {
        SensorModel::new(
            MeasKind::Position,
            Geometry::planar(0.0),
            Vector3::zeros(),
            &[noise, noise],
            None,
        )
        .unwrap()
    }

    fn radar() -> SensorModel {
        SensorModel::new(
            MeasKind::RangeBearing,
            Geometry::planar(0.0),
            Vector3::new(-400.0, -300.0, 10.0),
            &[3.0, 0.004],
            None,
        )
        .unwrap()
    }

    /// Noisy-looking detections of a target at (10 t, 5 t), alternating two sensors.
    fn detections(n: usize) -> Vec<(f64, SensorModel, Vec<f64>)> {
        (0..n)
            .map(|k| {
                let t = 0.25 * k as f64;
                let wobble = ((k * 7919) % 13) as f64 - 6.0;
                let x = Vector4::new(10.0 * t + wobble, 5.0 * t - 0.5 * wobble, 10.0, 5.0);
                if k % 3 == 1 {
                    let s = radar();
                    let z = s.apply(Measure { x }).unwrap();
                    (t, s, z)
                } else {
                    (t, position(4.0), vec![x[0], x[1]])
                }
            })
            .collect()
    }

    struct Measure {
        x: Vector4<f64>,
    }
    impl WithSensor<4> for Measure {
        type Output = Option<Vec<f64>>;
        fn with<H, const M: usize>(self, model: &H) -> Self::Output
        where
            H: MeasurementModel<4, M> + Locate<M>,
        {
            Some(model.function(&self.x).as_slice().to_vec())
        }
    }

    fn start() -> Gaussian<4> {
        Gaussian::new(
            Vector4::new(0.0, 0.0, 0.0, 0.0),
            Matrix4::from_diagonal(&Vector4::new(100.0, 100.0, 400.0, 400.0)),
        )
        .unwrap()
    }

    /// Runs `order` (indices into `dets`) through the filter, the in-order way for an
    /// in-sequence index and by replay for an older one; returns the state at `now`.
    fn run<F: TrackFilter<4>>(
        filter: &F,
        dets: &[(f64, SensorModel, Vec<f64>)],
        order: &[usize],
        lag: f64,
        now: f64,
    ) -> (F::State, UpdateLog<F::State>) {
        let mut log = UpdateLog::new();
        let s0 = filter.start(start()).unwrap();
        log.record(
            LoggedUpdate::new(-1.0, position(4.0), &[0.0, 0.0], s0.clone()).unwrap(),
            lag,
        );
        let (mut state, mut t) = (s0, -1.0);
        for &i in order {
            let (ti, sensor, z) = &dets[i];
            if *ti >= t {
                let p = predict_to(filter, &state, ti - t).unwrap();
                let hard = LoggedUpdate::new(*ti, *sensor, z, ()).unwrap();
                state = update_at(filter, &p, &hard).unwrap();
                t = *ti;
                log.record(
                    LoggedUpdate::new(*ti, *sensor, z, state.clone()).unwrap(),
                    lag,
                );
            } else {
                let late = LoggedUpdate::new(*ti, *sensor, z, ()).unwrap();
                state = log.replay(filter, late, t).unwrap();
            }
        }
        (predict_to(filter, &state, now - t).unwrap(), log)
    }

    #[test]
    fn a_late_detection_gives_the_in_order_estimate() {
        let f = kf();
        let dets = detections(24);
        let in_order: Vec<usize> = (0..dets.len()).collect();
        let (want, _) = run(&f, &dets, &in_order, 10.0, 6.0);
        // Detections 5 and 6 (t = 1.25, 1.5) arrive after 13 (t = 3.25); 9 arrives last.
        let mut late: Vec<usize> = in_order.clone();
        late.retain(|&i| i != 5 && i != 6 && i != 9);
        let at = late.iter().position(|&i| i == 13).unwrap() + 1;
        late.splice(at..at, [6, 5]);
        late.push(9);
        let (got, log) = run(&f, &dets, &late, 10.0, 6.0);
        assert!(
            (got.mean - want.mean).amax() < 1e-8,
            "{} vs {}",
            got.mean,
            want.mean
        );
        assert!((got.cov - want.cov).amax() < 1e-8);
        // The log is in time order, holding every update.
        let times: Vec<f64> = log.entries().map(|e| e.t).collect();
        assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
        assert_eq!(times.len(), 25);
    }

    #[test]
    fn imm_tracks_replay_close_to_in_order() {
        let imm = Imm::new(
            Extended,
            [
                ModeModel::Cv { q: 0.5 },
                ModeModel::Ct { omega: 0.1, q: 0.5 },
            ],
            [[0.95, 0.05], [0.05, 0.95]],
        )
        .unwrap();
        let f = ImmFilter {
            imm,
            initial_probs: [0.9, 0.1],
        };
        let dets = detections(24);
        let in_order: Vec<usize> = (0..dets.len()).collect();
        let (want, _) = run(&f, &dets, &in_order, 10.0, 6.0);
        let mut late = in_order.clone();
        late.retain(|&i| i != 10);
        late.insert(14, 10);
        let (got, _) = run(&f, &dets, &late, 10.0, 6.0);
        let (a, b) = (f.estimate(&got), f.estimate(&want));
        assert!((a.mean - b.mean).amax() < 0.5, "{} vs {}", a.mean, b.mean);
    }

    #[test]
    fn the_log_keeps_the_lag_and_one_base_before_it() {
        let mut log = UpdateLog::new();
        for k in 0..20 {
            let t = f64::from(k) * 0.5;
            log.record(
                LoggedUpdate::new(t, position(1.0), &[t, 0.0], t).unwrap(),
                2.0,
            );
        }
        // Newest 9.5: the horizon is 7.5, kept as the base; nothing older.
        let times: Vec<f64> = log.entries().map(|e| e.t).collect();
        assert_eq!(times, vec![7.5, 8.0, 8.5, 9.0, 9.5]);
        assert!(log.covers(7.5) && log.covers(8.2) && !log.covers(7.4));
        // A detection older than the log is refused and changes nothing.
        let before = log.clone();
        let late = LoggedUpdate::new(7.0, position(1.0), &[7.0, 0.0], ()).unwrap();
        struct Id;
        impl TrackFilter<4> for Id {
            type State = f64;
            fn start(&self, _: Gaussian<4>) -> Result<f64> {
                Ok(0.0)
            }
            fn predict(&self, s: &f64, _: f64) -> Result<f64> {
                Ok(*s)
            }
            fn predict_measurement<H: MeasurementModel<4, M>, const M: usize>(
                &self,
                _: &f64,
                _: &H,
            ) -> Result<crate::filter::MeasurementPrediction<M>> {
                Err(EstimationError::InvalidParameter("unused".into()))
            }
            fn update<H: MeasurementModel<4, M>, const M: usize>(
                &self,
                s: &f64,
                _: &H,
                z: &SVector<f64, M>,
            ) -> Result<f64> {
                Ok(s + z[0])
            }
            fn update_mixture<H: MeasurementModel<4, M>, const M: usize>(
                &self,
                s: &f64,
                _: &H,
                zs: &[(SVector<f64, M>, f64)],
                _: f64,
            ) -> Result<f64> {
                Ok(s + zs.iter().map(|(z, w)| w * z[0]).sum::<f64>())
            }
            fn estimate(&self, _: &f64) -> Gaussian<4> {
                start()
            }
        }
        assert!(log.replay(&Id, late, 9.5).is_err());
        assert_eq!(log, before);
        // Replaying to a time before the newest update is refused too.
        let late = LoggedUpdate::new(8.2, position(1.0), &[100.0, 0.0], ()).unwrap();
        assert!(log.replay(&Id, late.clone(), 9.0).is_err());
        assert_eq!(log, before);
        // A good one: the late detection's z is added once to every later posterior.
        let now = log.replay(&Id, late, 10.0).unwrap();
        let post: Vec<(f64, f64)> = log.entries().map(|e| (e.t, e.posterior)).collect();
        assert_eq!(
            post,
            vec![
                (7.5, 7.5),
                (8.0, 8.0),
                (8.2, 108.0),
                (8.5, 116.5),
                (9.0, 125.5),
                (9.5, 135.0)
            ]
        );
        assert_eq!(now, 135.0);
        assert!(LoggedUpdate::new(1.0, position(1.0), &[1.0], ()).is_none());
    }

    /// A track updated faster than the lag foresees keeps only the newest `MAX_LOGGED` updates.
    #[test]
    fn the_log_is_bounded() {
        let mut log = UpdateLog::new();
        for k in 0..1000 {
            let t = f64::from(k) * 1e-3;
            log.record(
                LoggedUpdate::new(t, position(1.0), &[t, 0.0], t).unwrap(),
                2.0,
            );
        }
        assert_eq!(log.entries().len(), MAX_LOGGED);
        assert!(!log.covers(0.5) && log.covers(0.95));
    }
}
