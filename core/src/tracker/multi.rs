//! The multi-target tracker step (Stone Soup's `MultiTargetTracker`): predict every track to the
//! scan time, associate every track with the scan's detections in one global-nearest-neighbour
//! assignment, update or coast, confirm or delete, and initiate tentative tracks from the
//! detections no track took. Each scan brings its own sensor model (kind, platform position,
//! noise), so scans of cameras on moving UAVs and of a ground radar update the same tracks, and
//! every step reports what happened as [`TrackEvent`]s.

use nalgebra::SVector;

use super::associate::{Gater, TrackHypotheses, global_nearest_neighbour, hypothesise};
use super::delete::{DeleteReason, Deleter};
use super::filter::TrackFilter;
use super::initiate::{Initiator, MOfN, Verdict};
use crate::measurement::{Locate, MeasurementModel, SensorModel, WithSensor};
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

/// What the tracker reports for a track after a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSnapshot<const N: usize> {
    /// Track id.
    pub id: u64,
    /// Scan time (s).
    pub t: f64,
    /// Gaussian estimate at `t` (moment-matched for mixtures).
    pub estimate: Gaussian<N>,
    /// Tentative or confirmed.
    pub status: TrackStatus,
    /// Whether a detection was associated in the last scan (`false`: coasted).
    pub updated: bool,
    /// Scans since initiation.
    pub age: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
    /// Mode probabilities of a mixture filter (IMM), empty otherwise.
    pub mode_probabilities: Vec<f64>,
}

/// What happened to a track, or to a detection, in one scan.
#[derive(Debug, Clone, PartialEq)]
pub enum TrackEvent {
    /// A tentative track was started from detection `detection` of the scan.
    Born {
        /// New track id.
        id: u64,
        /// Index of the detection in the scan.
        detection: usize,
    },
    /// A tentative track met the M-of-N rule.
    Confirmed {
        /// Track id.
        id: u64,
    },
    /// A track was updated with detection `detection`.
    Updated {
        /// Track id.
        id: u64,
        /// Index of the detection in the scan.
        detection: usize,
        /// Normalised innovation squared `d²` of the detection.
        nis: f64,
    },
    /// A track had no detection in this scan.
    Coasted {
        /// Track id.
        id: u64,
        /// Consecutive misses, this scan included.
        misses: u32,
    },
    /// A track was deleted.
    Deleted {
        /// Track id.
        id: u64,
        /// Why.
        reason: DeleteReason,
    },
    /// Something of this scan could not be used: a track's measurement prediction or update
    /// failed (it coasts), or a detection could not start a track.
    Rejected {
        /// The track concerned, if any.
        id: Option<u64>,
        /// The detection concerned, if any.
        detection: Option<usize>,
        /// Why.
        reason: String,
    },
}

/// Global-nearest-neighbour multi-target tracker over any [`TrackFilter`] `F` and [`Initiator`]
/// `I`, on N-dimensional states.
#[derive(Debug, Clone)]
pub struct Tracker<F: TrackFilter<N>, I, const N: usize> {
    filter: F,
    initiator: I,
    config: TrackerConfig,
    tracks: Vec<Track<F::State>>,
    next_id: u64,
    t: Option<f64>,
}

impl<F, I, const N: usize> Tracker<F, I, N>
where
    F: TrackFilter<N>,
    I: Initiator<N>,
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

    /// The track filter.
    pub fn filter(&self) -> &F {
        &self.filter
    }

    /// Every live track after the last scan, tentative and confirmed, in id order.
    pub fn snapshot(&self) -> Vec<TrackSnapshot<N>> {
        let t = self.t.unwrap_or(0.0);
        self.tracks
            .iter()
            .map(|k| TrackSnapshot {
                id: k.id,
                t,
                estimate: self.filter.estimate(&k.state),
                status: k.status,
                updated: k.consecutive_misses == 0,
                age: k.scans,
                last_update: k.last_update,
                mode_probabilities: self.filter.mode_probabilities(&k.state),
            })
            .collect()
    }

    /// The confirmed tracks after the last scan, in id order.
    pub fn confirmed(&self) -> Vec<TrackSnapshot<N>> {
        let mut all = self.snapshot();
        all.retain(|k| k.status == TrackStatus::Confirmed);
        all
    }

    /// Processes one scan of one sensor: all its detections at time `t`, clutter included, under
    /// the sensor model `sensor` (which carries the platform position and the noise). Scans of
    /// several sensors at the same `t` are processed one after the other with no prediction
    /// between them. Every scan counts towards the M-of-N and miss counts of every track.
    ///
    /// Fails, leaving the tracker untouched, when `t` is not finite or earlier than the last scan,
    /// or a detection is not finite. A numerical failure inside one track does not fail the scan:
    /// it is reported as an event (a track whose prediction fails is deleted, one whose
    /// measurement prediction or update fails coasts).
    pub fn step<H, const M: usize>(
        &mut self,
        t: f64,
        sensor: &H,
        detections: &[SVector<f64, M>],
    ) -> Result<Vec<TrackEvent>>
    where
        H: MeasurementModel<N, M> + Locate<M>,
    {
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
        let mut events = Vec::new();

        // Predict; a track whose prediction fails is deleted.
        let mut tracks: Vec<Track<F::State>> = Vec::with_capacity(self.tracks.len());
        for k in &self.tracks {
            let state = if dt > 0.0 {
                match self.filter.predict(&k.state, dt) {
                    Ok(s) => s,
                    Err(e) => {
                        events.push(TrackEvent::Deleted {
                            id: k.id,
                            reason: DeleteReason::Failed(e.to_string()),
                        });
                        continue;
                    }
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

        // Associate: every track, confirmed or tentative (each with its own gate), competes for
        // the detections in one assignment.
        let hyps: Vec<TrackHypotheses> = tracks
            .iter()
            .map(|k| {
                let gater = match k.status {
                    TrackStatus::Confirmed => &self.config.gater,
                    TrackStatus::Tentative => &self.config.tentative_gater,
                };
                hypothesise(&self.filter, &k.state, sensor, detections, gater).unwrap_or_else(|e| {
                    events.push(TrackEvent::Rejected {
                        id: Some(k.id),
                        detection: None,
                        reason: format!("measurement prediction: {e}"),
                    });
                    TrackHypotheses::default()
                })
            })
            .collect();
        let assigned = global_nearest_neighbour(&hyps)?;
        let mut taken = vec![false; detections.len()];

        // Update or coast, then confirm / delete.
        let confirm = self.config.confirm;
        let deleter = self.config.deleter;
        let filter = &self.filter;
        let mut kept = Vec::with_capacity(tracks.len() + detections.len());
        for ((mut k, a), h) in tracks.into_iter().zip(assigned).zip(&hyps) {
            let mut updated = false;
            if let Some(d) = a {
                taken[d] = true;
                match filter.update(&k.state, sensor, &detections[d]) {
                    Ok(s) => {
                        k.state = s;
                        k.hits += 1;
                        k.consecutive_misses = 0;
                        k.last_update = t;
                        updated = true;
                        let nis = h
                            .gated
                            .iter()
                            .find(|g| g.detection == d)
                            .map_or(f64::NAN, |g| g.distance_sq);
                        events.push(TrackEvent::Updated {
                            id: k.id,
                            detection: d,
                            nis,
                        });
                    }
                    Err(e) => events.push(TrackEvent::Rejected {
                        id: Some(k.id),
                        detection: Some(d),
                        reason: format!("update: {e}"),
                    }),
                }
            }
            if !updated {
                k.consecutive_misses += 1;
                events.push(TrackEvent::Coasted {
                    id: k.id,
                    misses: k.consecutive_misses,
                });
            }
            let gone = match k.status {
                TrackStatus::Tentative => match confirm.judge(k.hits, k.scans) {
                    Verdict::Confirm => {
                        k.status = TrackStatus::Confirmed;
                        events.push(TrackEvent::Confirmed { id: k.id });
                        None
                    }
                    Verdict::Pending => None,
                    Verdict::Drop => Some(DeleteReason::Unconfirmed),
                },
                TrackStatus::Confirmed => {
                    deleter.judge(k.consecutive_misses, &filter.estimate(&k.state))
                }
            };
            match gone {
                Some(reason) => events.push(TrackEvent::Deleted { id: k.id, reason }),
                None => kept.push(k),
            }
        }

        // Initiate from the detections no track took.
        for (j, z) in detections.iter().enumerate() {
            if taken[j] {
                continue;
            }
            let started = sensor
                .locate(z)
                .ok_or_else(|| "the detection fixes no position".to_string())
                .and_then(|fix| {
                    self.initiator
                        .initiate(&fix)
                        .and_then(|g| self.filter.start(g))
                        .map_err(|e| e.to_string())
                });
            let state = match started {
                Ok(s) => s,
                Err(reason) => {
                    events.push(TrackEvent::Rejected {
                        id: None,
                        detection: Some(j),
                        reason: format!("initiation: {reason}"),
                    });
                    continue;
                }
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
            events.push(TrackEvent::Born {
                id: k.id,
                detection: j,
            });
            if confirm.judge(1, 1) == Verdict::Confirm {
                k.status = TrackStatus::Confirmed;
                events.push(TrackEvent::Confirmed { id: k.id });
            }
            kept.push(k);
        }
        kept.sort_by_key(|k| k.id);
        self.tracks = kept;
        self.t = Some(t);
        Ok(events)
    }

    /// Takes over tracks from another tracker (a change of track filter at run time): each keeps
    /// its id, status and hit/miss record, and its Gaussian estimate becomes the state of this
    /// tracker's filter ([`TrackFilter::start`]: a mixture starts every mode from it with the
    /// initial mode probabilities). The tracker's time becomes `t`; new ids continue after the
    /// largest one seen. Replaces the tracks held; fails, changing nothing, when `t` is not
    /// finite, an id repeats or a filter cannot start from an estimate.
    pub fn adopt(&mut self, t: f64, tracks: &[(Track<()>, Gaussian<N>)]) -> Result<()> {
        if !t.is_finite() {
            return Err(EstimationError::InvalidParameter(format!(
                "adopt at t = {t}: not finite"
            )));
        }
        let mut adopted = Vec::with_capacity(tracks.len());
        for (k, g) in tracks {
            if adopted.iter().any(|a: &Track<F::State>| a.id == k.id) {
                return Err(EstimationError::InvalidParameter(format!(
                    "adopt: track id {} given twice",
                    k.id
                )));
            }
            adopted.push(Track {
                id: k.id,
                state: self.filter.start(*g)?,
                status: k.status,
                scans: k.scans,
                hits: k.hits,
                consecutive_misses: k.consecutive_misses,
                last_update: k.last_update,
            });
        }
        adopted.sort_by_key(|k| k.id);
        let top = adopted.iter().map(|k| k.id + 1).max().unwrap_or(1);
        self.next_id = self.next_id.max(top);
        self.tracks = adopted;
        self.t = Some(t);
        Ok(())
    }

    /// The hit/miss record of every live track, without its state (what [`Tracker::adopt`]
    /// takes), in id order.
    pub fn records(&self) -> Vec<Track<()>> {
        self.tracks
            .iter()
            .map(|k| Track {
                id: k.id,
                state: (),
                status: k.status,
                scans: k.scans,
                hits: k.hits,
                consecutive_misses: k.consecutive_misses,
                last_update: k.last_update,
            })
            .collect()
    }

    /// The next id a new track gets.
    pub fn next_id(&self) -> u64 {
        self.next_id
    }

    /// [`Tracker::step`] for a sensor whose kind is known only at run time: each detection is a
    /// slice of [`SensorModel::dim`] components. Fails, leaving the tracker untouched, when a
    /// detection has the wrong length.
    pub fn step_any(
        &mut self,
        t: f64,
        sensor: &SensorModel,
        detections: &[&[f64]],
    ) -> Result<Vec<TrackEvent>> {
        sensor.apply(StepWith {
            tracker: self,
            t,
            detections,
        })
    }
}

/// The visit of [`Tracker::step_any`]: the detections as const-sized vectors of the concrete model.
struct StepWith<'a, 'd, F: TrackFilter<N>, I, const N: usize> {
    tracker: &'a mut Tracker<F, I, N>,
    t: f64,
    detections: &'d [&'d [f64]],
}

impl<F, I, const N: usize> WithSensor<N> for StepWith<'_, '_, F, I, N>
where
    F: TrackFilter<N>,
    I: Initiator<N>,
{
    type Output = Result<Vec<TrackEvent>>;
    fn with<H, const M: usize>(self, model: &H) -> Self::Output
    where
        H: MeasurementModel<N, M> + Locate<M>,
    {
        let mut zs = Vec::with_capacity(self.detections.len());
        for z in self.detections {
            if z.len() != M {
                return Err(EstimationError::InvalidParameter(format!(
                    "a detection has {} components, the sensor measures {M}",
                    z.len()
                )));
            }
            zs.push(SVector::<f64, M>::from_column_slice(z));
        }
        self.tracker.step(self.t, model, &zs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::Extended;
    use crate::measurement::{Geometry, Position};
    use crate::motion::ConstantVelocity;
    use crate::tracker::filter::GaussianFilter;
    use crate::tracker::initiate::SinglePointInitiator;
    use nalgebra::Vector2;

    type Kf = GaussianFilter<Extended, ConstantVelocity<4>>;
    fn cam() -> Position<2> {
        Position::new(Geometry::planar(0.0), [5.0, 5.0])
    }

    fn tracker(m: u32, n: u32) -> Tracker<Kf, SinglePointInitiator, 4> {
        let filter = GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::new(0.5),
        };
        let init = SinglePointInitiator::new(10.0, 10.0).unwrap();
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).unwrap(),
            tentative_gater: Gater::chi2(0.99, 2).unwrap(),
            confirm: MOfN::new(m, n).unwrap(),
            deleter: Deleter::new(3, 1e4, 2).unwrap(),
        };
        Tracker::new(filter, init, config)
    }

    #[test]
    fn adopted_tracks_keep_ids_and_records_and_go_on() {
        let mut a = tracker(2, 3);
        let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
        for k in 0..3 {
            a.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
        }
        let taken: Vec<_> = a
            .records()
            .into_iter()
            .zip(a.snapshot())
            .map(|(r, s)| (r, s.estimate))
            .collect();
        assert_eq!(taken.len(), 1);
        let mut b = tracker(2, 3);
        b.adopt(2.0, &taken).unwrap();
        assert_eq!(b.records(), a.records());
        assert_eq!(b.next_id(), 2);
        let ev = b.step(3.0, &cam(), &[at(3.0), at(30.0)]).unwrap();
        assert!(ev.contains(&TrackEvent::Updated {
            id: 1,
            detection: 0,
            nis: match ev.iter().find_map(|e| match e {
                TrackEvent::Updated { nis, .. } => Some(*nis),
                _ => None,
            }) {
                Some(n) => n,
                None => panic!("no update in {ev:?}"),
            },
        }));
        assert!(
            ev.contains(&TrackEvent::Born {
                id: 2,
                detection: 1
            }),
            "{ev:?}"
        );
        let twice = vec![taken[0].clone(), taken[0].clone()];
        assert!(b.adopt(4.0, &twice).is_err());
        assert!(b.adopt(f64::NAN, &taken).is_err());
        assert_eq!(b.time(), Some(3.0));
    }

    #[test]
    fn two_of_three_confirms_and_deletes() {
        let mut tr = tracker(2, 3);
        let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
        tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
        assert_eq!(tr.tracks().len(), 1);
        assert!(tr.confirmed().is_empty());
        tr.step(1.0, &cam(), &[]).unwrap(); // miss: 1 of 2, still possible
        assert_eq!(tr.tracks().len(), 1);
        tr.step(2.0, &cam(), &[at(2.0)]).unwrap(); // 2 of 3: confirmed
        let c = tr.confirmed();
        assert_eq!((c.len(), c[0].id), (1, 1));
        for k in 3..6 {
            tr.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
        }
        assert_eq!(tr.confirmed()[0].id, 1);
        assert!((tr.confirmed()[0].estimate.mean[2] - 10.0).abs() < 3.0);
        // Three misses delete it.
        for k in 6..9 {
            tr.step(f64::from(k), &cam(), &[]).unwrap();
        }
        assert!(tr.tracks().is_empty());
        // A lone clutter point: hit, miss, miss → dropped.
        tr.step(9.0, &cam(), &[Vector2::new(500.0, 500.0)]).unwrap();
        tr.step(10.0, &cam(), &[]).unwrap();
        tr.step(11.0, &cam(), &[]).unwrap();
        assert!(tr.tracks().is_empty());
        assert_eq!(tr.next_id, 3);
    }

    #[test]
    fn rejects_bad_input_and_keeps_state() {
        let mut tr = tracker(2, 3);
        tr.step(1.0, &cam(), &[Vector2::new(0.0, 0.0)]).unwrap();
        let before = tr.tracks().to_vec();
        assert!(tr.step(0.5, &cam(), &[]).is_err());
        assert!(
            tr.step(2.0, &cam(), &[Vector2::new(f64::NAN, 0.0)])
                .is_err()
        );
        assert!(tr.step(f64::NAN, &cam(), &[]).is_err());
        assert_eq!(tr.tracks(), before.as_slice());
        assert_eq!(tr.time(), Some(1.0));
    }

    #[test]
    fn events_tell_the_life_of_a_track() {
        let mut tr = tracker(2, 3);
        let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
        let ev = tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
        assert_eq!(
            ev,
            vec![TrackEvent::Born {
                id: 1,
                detection: 0
            }]
        );
        let ev = tr.step(1.0, &cam(), &[at(1.0)]).unwrap();
        assert!(matches!(ev[0], TrackEvent::Updated { id: 1, detection: 0, nis } if nis >= 0.0));
        assert_eq!(ev[1], TrackEvent::Confirmed { id: 1 });
        let ev = tr.step(2.0, &cam(), &[]).unwrap();
        assert_eq!(ev, vec![TrackEvent::Coasted { id: 1, misses: 1 }]);
        tr.step(3.0, &cam(), &[]).unwrap();
        let ev = tr.step(4.0, &cam(), &[]).unwrap();
        assert_eq!(
            ev,
            vec![
                TrackEvent::Coasted { id: 1, misses: 3 },
                TrackEvent::Deleted {
                    id: 1,
                    reason: DeleteReason::Misses
                }
            ]
        );
        // A tentative track that cannot reach 2 of 3 is dropped as unconfirmed.
        tr.step(5.0, &cam(), &[at(0.0)]).unwrap();
        tr.step(6.0, &cam(), &[]).unwrap();
        let ev = tr.step(7.0, &cam(), &[]).unwrap();
        assert!(ev.contains(&TrackEvent::Deleted {
            id: 2,
            reason: DeleteReason::Unconfirmed
        }));
        // A camera looking up cannot start a track: rejected, with the reason.
        let sky = crate::measurement::AzEl::new(
            Geometry::planar(0.0),
            nalgebra::Vector3::new(0.0, 0.0, 10.0),
            [0.01, 0.01],
        );
        let ev = tr.step(8.0, &sky, &[Vector2::new(0.0, 0.5)]).unwrap();
        assert!(matches!(
            &ev[..],
            [TrackEvent::Rejected { id: None, detection: Some(0), reason }] if reason.contains("initiation")
        ));
    }

    #[test]
    fn imm_tracks_through_any_sensor() {
        use crate::filter::{Imm, ModeModel};
        use crate::measurement::MeasKind;
        use crate::measurement::{RangeBearing, SensorModel};
        use crate::tracker::filter::ImmFilter;
        let q = 0.05;
        let imm = Imm::new(
            Extended,
            [ModeModel::Cv { q }, ModeModel::Ct { omega: 0.1, q }],
            [[0.95, 0.05], [0.05, 0.95]],
        )
        .unwrap();
        let filter = ImmFilter {
            imm,
            initial_probs: [0.9, 0.1],
        };
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).unwrap(),
            tentative_gater: Gater::chi2(0.99, 2).unwrap(),
            confirm: MOfN::new(2, 3).unwrap(),
            deleter: Deleter::new(3, 1e4, 2).unwrap(),
        };
        let mut tr = Tracker::new(
            filter,
            SinglePointInitiator::new(10.0, 10.0).unwrap(),
            config,
        );
        let radar = RangeBearing::new(
            Geometry::planar(0.0),
            nalgebra::Vector3::new(0.0, 0.0, 20.0),
            [2.0, 0.002],
        );
        let truth = |t: f64| nalgebra::Vector4::new(500.0 + 8.0 * t, 300.0, 8.0, 0.0);
        for k in 0..20 {
            let t = f64::from(k);
            let z = MeasurementModel::<4, 2>::function(&radar, &truth(t));
            // Every other scan comes through the run-time sensor model.
            if k % 2 == 0 {
                tr.step(t, &radar, &[z]).unwrap();
            } else {
                let any = SensorModel::new(
                    MeasKind::RangeBearing,
                    Geometry::planar(0.0),
                    nalgebra::Vector3::new(0.0, 0.0, 20.0),
                    &[2.0, 0.002],
                    None,
                )
                .unwrap();
                tr.step_any(t, &any, &[z.as_slice()]).unwrap();
            }
        }
        let c = tr.confirmed();
        assert_eq!(c.len(), 1);
        assert!(
            (c[0].estimate.mean - truth(19.0)).norm() < 3.0,
            "{:?}",
            c[0].estimate.mean
        );
        assert_eq!(c[0].mode_probabilities.len(), 2);
        assert!(
            c[0].mode_probabilities[0] > 0.5,
            "{:?}",
            c[0].mode_probabilities
        );
        let pos = SensorModel::new(
            MeasKind::Position,
            Geometry::planar(0.0),
            nalgebra::Vector3::zeros(),
            &[1.0; 3],
            None,
        )
        .unwrap();
        assert!(tr.step_any(20.0, &pos, &[&[1.0, 2.0][..]]).is_err());
        assert_eq!(tr.time(), Some(19.0));
    }
}
