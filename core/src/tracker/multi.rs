//! The multi-target tracker step (Stone Soup's `MultiTargetTracker`): predict every track to the
//! scan time, associate (confirmed tracks first, then tentative ones), update or coast, confirm
//! or delete, and initiate tentative tracks from the detections left over.

use nalgebra::SVector;

use super::associate::{Gater, TrackHypotheses, global_nearest_neighbour, hypothesise};
use super::delete::Deleter;
use super::filter::TrackFilter;
use super::initiate::{Initiator, MOfN, Verdict};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Tuning of a [`Tracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// χ² gate of confirmed tracks.
    pub gater: Gater,
    /// χ² gate of tentative tracks, normally tighter: it is what keeps pairs of clutter
    /// detections from confirming.
    pub tentative_gater: Gater,
    /// Confirmation rule for tentative tracks.
    pub confirm: MOfN,
    /// Deletion rule for confirmed tracks.
    pub deleter: Deleter,
}

/// Life-cycle stage of a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Started by an unassociated detection, not yet confirmed by the M-of-N rule.
    Tentative,
    /// Confirmed: reported.
    Confirmed,
}

/// One track: a stable id, its filter state and its hit/miss record.
#[derive(Debug, Clone, PartialEq)]
pub struct Track<S> {
    /// Stable id, unique over the tracker's life (never reused).
    pub id: u64,
    /// Filter state after the last scan.
    pub state: S,
    /// Tentative or confirmed.
    pub status: TrackStatus,
    /// Scans since initiation, including the initiating one.
    pub scans: u32,
    /// Scans with an associated detection.
    pub hits: u32,
    /// Consecutive scans without a detection, up to the last one.
    pub consecutive_misses: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
}

/// What the tracker reports for a confirmed track after a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSnapshot<const N: usize> {
    /// Track id.
    pub id: u64,
    /// Scan time (s).
    pub t: f64,
    /// Gaussian estimate at `t`.
    pub estimate: Gaussian<N>,
    /// Whether a detection was associated in this scan (`false`: coasted).
    pub updated: bool,
    /// Scans since initiation.
    pub age: u32,
}

/// Global-nearest-neighbour multi-target tracker over any [`TrackFilter`] `F` and [`Initiator`]
/// `I`, for detections of dimension M from one sensor.
#[derive(Debug, Clone)]
pub struct Tracker<F: TrackFilter<N, M>, I, const N: usize, const M: usize> {
    filter: F,
    initiator: I,
    config: TrackerConfig,
    tracks: Vec<Track<F::State>>,
    next_id: u64,
    t: Option<f64>,
}

impl<F, I, const N: usize, const M: usize> Tracker<F, I, N, M>
where
    F: TrackFilter<N, M>,
    I: Initiator<N, M>,
{
    /// An empty tracker.
    pub fn new(filter: F, initiator: I, config: TrackerConfig) -> Self {
        Self {
            filter,
            initiator,
            config,
            tracks: Vec::new(),
            next_id: 1,
            t: None,
        }
    }

    /// Time of the last scan.
    pub fn time(&self) -> Option<f64> {
        self.t
    }

    /// Every live track, tentative and confirmed.
    pub fn tracks(&self) -> &[Track<F::State>] {
        &self.tracks
    }

    /// The confirmed tracks after the last scan, in id order.
    pub fn confirmed(&self) -> Vec<TrackSnapshot<N>> {
        let t = self.t.unwrap_or(0.0);
        self.tracks
            .iter()
            .filter(|k| k.status == TrackStatus::Confirmed)
            .map(|k| TrackSnapshot {
                id: k.id,
                t,
                estimate: self.filter.estimate(&k.state),
                updated: k.consecutive_misses == 0,
                age: k.scans,
            })
            .collect()
    }

    /// Processes one scan: all detections of the sensor at time `t`, clutter included.
    ///
    /// Fails, leaving the tracker untouched, when `t` is not finite or earlier than the last scan or
    /// a detection is not finite. A numerical failure inside one track does not fail the scan: a
    /// track whose prediction fails is deleted, one whose update fails coasts.
    pub fn step(&mut self, t: f64, detections: &[SVector<f64, M>]) -> Result<()> {
        if !t.is_finite() || self.t.is_some_and(|t0| t < t0) {
            return Err(EstimationError::InvalidParameter(format!(
                "scan time {t} is not finite or earlier than the last scan ({:?})",
                self.t
            )));
        }
        if detections.iter().any(|z| !z.iter().all(|v| v.is_finite())) {
            return Err(EstimationError::NonFinite("detection"));
        }
        let dt = self.t.map_or(0.0, |t0| t - t0);

        // Predict; a track whose prediction fails is dropped.
        let mut tracks: Vec<Track<F::State>> = Vec::with_capacity(self.tracks.len());
        for k in &self.tracks {
            let state = if dt > 0.0 {
                match self.filter.predict(&k.state, dt) {
                    Ok(s) => s,
                    Err(_) => continue,
                }
            } else {
                k.state.clone()
            };
            tracks.push(Track {
                state,
                scans: k.scans + 1,
                ..k.clone()
            });
        }

        // Associate: confirmed tracks first, then tentative ones with what is left.
        let mut taken = vec![false; detections.len()];
        let mut near_confirmed = vec![false; detections.len()];
        let mut assigned: Vec<Option<usize>> = vec![None; tracks.len()];
        for stage in [TrackStatus::Confirmed, TrackStatus::Tentative] {
            let idx: Vec<usize> = (0..tracks.len())
                .filter(|&i| tracks[i].status == stage)
                .collect();
            let gater = match stage {
                TrackStatus::Confirmed => self.config.gater,
                TrackStatus::Tentative => self.config.tentative_gater,
            };
            // Tentative tracks may not take detections in a confirmed track's gate: a tentative
            // duplicate of a confirmed track starves and is dropped.
            let unavailable = match stage {
                TrackStatus::Confirmed => &taken,
                TrackStatus::Tentative => &near_confirmed,
            };
            let hyps: Vec<TrackHypotheses> = idx
                .iter()
                .map(|&i| {
                    hypothesise(
                        &self.filter,
                        &tracks[i].state,
                        detections,
                        unavailable,
                        &gater,
                    )
                    .unwrap_or_default()
                })
                .collect();
            if stage == TrackStatus::Confirmed {
                for h in hyps.iter().flat_map(|h| &h.gated) {
                    near_confirmed[h.detection] = true;
                }
            }
            let a = global_nearest_neighbour(&hyps, &gater)?;
            for (&i, d) in idx.iter().zip(a) {
                if let Some(d) = d {
                    taken[d] = true;
                    assigned[i] = Some(d);
                }
            }
        }

        // Update or coast, then confirm / delete.
        let confirm = self.config.confirm;
        let deleter = self.config.deleter;
        let filter = &self.filter;
        let mut kept = Vec::with_capacity(tracks.len() + detections.len());
        for (mut k, a) in tracks.into_iter().zip(assigned) {
            let updated = a.and_then(|d| filter.update(&k.state, &detections[d]).ok());
            if let Some(s) = updated {
                k.state = s;
                k.hits += 1;
                k.consecutive_misses = 0;
                k.last_update = t;
            } else {
                k.consecutive_misses += 1;
            }
            let keep = match k.status {
                TrackStatus::Tentative => match confirm.judge(k.hits, k.scans) {
                    Verdict::Confirm => {
                        k.status = TrackStatus::Confirmed;
                        true
                    }
                    Verdict::Pending => true,
                    Verdict::Drop => false,
                },
                TrackStatus::Confirmed => {
                    !deleter.should_delete(k.consecutive_misses, &filter.estimate(&k.state))
                }
            };
            if keep {
                kept.push(k);
            }
        }

        // Initiate from detections that no track took and no confirmed track gated.
        for (j, z) in detections.iter().enumerate() {
            if taken[j] || near_confirmed[j] {
                continue;
            }
            let Ok(state) = self
                .initiator
                .initiate(z)
                .and_then(|g| self.filter.start(g))
            else {
                continue;
            };
            let mut k = Track {
                id: self.next_id,
                state,
                status: TrackStatus::Tentative,
                scans: 1,
                hits: 1,
                consecutive_misses: 0,
                last_update: t,
            };
            self.next_id += 1;
            if confirm.judge(1, 1) == Verdict::Confirm {
                k.status = TrackStatus::Confirmed;
            }
            kept.push(k);
        }
        self.tracks = kept;
        self.t = Some(t);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::Kalman;
    use crate::measurement::{Geometry, Position};
    use crate::motion::ConstantVelocity;
    use crate::tracker::filter::GaussianFilter;
    use crate::tracker::initiate::SinglePointInitiator;
    use nalgebra::{Matrix2, Vector2};

    type Kf = GaussianFilter<Kalman, ConstantVelocity<4>, Position<2>>;

    fn tracker(m: u32, n: u32) -> Tracker<Kf, SinglePointInitiator<2>, 4, 2> {
        let filter = GaussianFilter {
            filter: Kalman,
            motion: ConstantVelocity::new(0.5),
            sensor: Position::new(Geometry::planar(0.0), [5.0, 5.0]),
        };
        let init = SinglePointInitiator::new(Matrix2::identity() * 25.0, 10.0).unwrap();
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).unwrap(),
            tentative_gater: Gater::chi2(0.99, 2).unwrap(),
            confirm: MOfN::new(m, n).unwrap(),
            deleter: Deleter::new(3, 1e4, 2).unwrap(),
        };
        Tracker::new(filter, init, config)
    }

    #[test]
    fn two_of_three_confirms_and_deletes() {
        let mut tr = tracker(2, 3);
        let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
        tr.step(0.0, &[at(0.0)]).unwrap();
        assert_eq!(tr.tracks().len(), 1);
        assert!(tr.confirmed().is_empty());
        tr.step(1.0, &[]).unwrap(); // miss: 1 of 2, still possible
        assert_eq!(tr.tracks().len(), 1);
        tr.step(2.0, &[at(2.0)]).unwrap(); // 2 of 3: confirmed
        let c = tr.confirmed();
        assert_eq!((c.len(), c[0].id), (1, 1));
        for k in 3..6 {
            tr.step(f64::from(k), &[at(f64::from(k))]).unwrap();
        }
        assert_eq!(tr.confirmed()[0].id, 1);
        assert!((tr.confirmed()[0].estimate.mean[2] - 10.0).abs() < 3.0);
        // Three misses delete it.
        for k in 6..9 {
            tr.step(f64::from(k), &[]).unwrap();
        }
        assert!(tr.tracks().is_empty());
        // A lone clutter point: hit, miss, miss → dropped.
        tr.step(9.0, &[Vector2::new(500.0, 500.0)]).unwrap();
        tr.step(10.0, &[]).unwrap();
        tr.step(11.0, &[]).unwrap();
        assert!(tr.tracks().is_empty());
        assert_eq!(tr.next_id, 3);
    }

    #[test]
    fn rejects_bad_input_and_keeps_state() {
        let mut tr = tracker(2, 3);
        tr.step(1.0, &[Vector2::new(0.0, 0.0)]).unwrap();
        let before = tr.tracks().to_vec();
        assert!(tr.step(0.5, &[]).is_err());
        assert!(tr.step(2.0, &[Vector2::new(f64::NAN, 0.0)]).is_err());
        assert!(tr.step(f64::NAN, &[]).is_err());
        assert_eq!(tr.tracks(), before.as_slice());
        assert_eq!(tr.time(), Some(1.0));
    }
}
