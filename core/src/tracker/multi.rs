//! The multi-target tracker step (Stone Soup's `MultiTargetTracker`): predict every track to the
//! scan time, associate the tracks with the scan's detections, update or coast, confirm or
//! delete, and initiate tentative tracks from the detections no track took. Each scan brings its
//! own sensor model (kind, platform position, noise), so scans of cameras on moving UAVs and of a
//! ground radar update the same tracks, and every step reports what happened as [`TrackEvent`]s.
//!
//! The association is the configuration's [`Association`]: global nearest neighbour (one hard
//! assignment per scan, M-of-N confirmation, a miss count), JIPDA (soft association with track
//! existence, [`jipda`](super::jipda)) or the multi-scan track-oriented MHT
//! ([`mht`](super::mht)). All three report the same events and keep track ids for life, so one
//! tracker's tracks can be [adopted](Tracker::adopt) by a tracker with another associator.

use nalgebra::SVector;

use super::associate::Gater;
use super::delete::{DeleteReason, Deleter};
use super::existence::Existence;
use super::filter::TrackFilter;
use super::initiate::{Initiator, MOfN};
use super::mht::{Mht, MhtState};
pub use super::track::{DetectionModel, Track, TrackStatus};
use crate::measurement::{Locate, MeasurementModel, SensorModel, WithSensor};
use crate::state::Gaussian;
use crate::{EstimationError, Result};
use late::Retrodiction;

mod late;
mod multiscan;
mod single;
#[cfg(test)]
mod tests;

/// JIPDA's tuning ([`jipda`](super::jipda)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jipda {
    /// `P_D` and the clutter density.
    pub detection: DetectionModel,
    /// Existence: its Markov chain, the initial value and the confirm / delete thresholds (which
    /// replace M-of-N and the miss count).
    pub existence: Existence,
    /// A detection starts a tentative track when the probability that no track's target made it
    /// is at least this.
    pub birth: f64,
    /// Nodes per layer of a cluster's EHM net before the net is cut (counted in
    /// [`AssociationStats::capped`]).
    pub max_net_nodes: usize,
    /// Coalescence avoidance ([`jpda_star`](super::jpda_star)): nodes a cluster's enumeration of
    /// joint events may visit for JPDA*'s pruning; a larger cluster gets the exact JIPDA
    /// marginals (counted in [`AssociationStats::capped`]). 0: plain JIPDA.
    pub star_nodes: usize,
    /// Which tracks JPDA* keeps apart: two tracks move together when the difference of their
    /// velocities lies inside this probability's χ² ellipsoid of their velocity covariances
    /// ([`move_together`](super::jpda_star::move_together)); only the permutations among tracks
    /// that move together are pruned. 1: every track (JPDA*).
    pub star_gate: f64,
}

/// How the tracker associates a scan's detections with its tracks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Association {
    /// Global nearest neighbour: one optimal assignment per cluster and scan, M-of-N
    /// confirmation, deletion after consecutive misses.
    Gnn,
    /// Joint integrated probabilistic data association: every track updated with the mixture
    /// of its gated detections weighted by their exact marginal probabilities, and a probability
    /// of existence that confirms and deletes tracks.
    Jipda(Jipda),
    /// Track-oriented multiple hypotheses over a sliding window of scans, N-scan pruning.
    Mht(Mht),
}

/// Tuning of a [`Tracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// χ² gate of confirmed tracks.
    pub gater: Gater,
    /// χ² gate of tentative tracks, normally tighter: it is what keeps pairs of clutter
    /// detections from confirming.
    pub tentative_gater: Gater,
    /// Confirmation rule for tentative tracks (GNN).
    pub confirm: MOfN,
    /// Deletion rule for confirmed tracks: misses (GNN) and the covariance bound (all).
    pub deleter: Deleter,
    /// The associator.
    pub association: Association,
}

impl TrackerConfig {
    /// The gate of a track of `status`.
    pub fn gater_for(&self, status: TrackStatus) -> Gater {
        match status {
            TrackStatus::Confirmed => self.gater,
            TrackStatus::Tentative => self.tentative_gater,
        }
    }
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
    /// Probability of existence (JIPDA, MHT); `None` under GNN.
    pub existence: Option<f64>,
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
    /// A tentative track met the M-of-N rule (or its existence the confirmation threshold).
    Confirmed {
        /// Track id.
        id: u64,
    },
    /// A track was updated with detection `detection` (soft association: its most probable
    /// detection, when that is more probable than none).
    Updated {
        /// Track id.
        id: u64,
        /// Index of the detection in the scan.
        detection: usize,
        /// Normalised innovation squared `d²` of the detection.
        nis: f64,
    },
    /// A track had no detection in this scan (soft association: "no detection" was its most
    /// probable hypothesis).
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

/// What the associators did so far: how often the bounds on clusters and hypotheses were hit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AssociationStats {
    /// Scans processed.
    pub scans: u64,
    /// Clusters of tracks sharing detections that were solved (GNN, JIPDA; MHT: of trees).
    pub clusters: u64,
    /// Most tracks (MHT: trees) in one cluster.
    pub largest_cluster: usize,
    /// Largest JIPDA EHM net (nodes), or most MHT hypotheses (leaves) after a scan.
    pub largest_net: usize,
    /// Clusters whose exact solution hit its bound (an EHM net cut to `max_net_nodes` nodes per
    /// layer, an MHT search stopped at its node budget): the answer of the bounded fallback.
    pub capped: u64,
}

/// Multi-target tracker over any [`TrackFilter`] `F` and [`Initiator`] `I`, on N-dimensional
/// states, with the association of its configuration.
#[derive(Debug, Clone)]
pub struct Tracker<F: TrackFilter<N>, I, const N: usize> {
    filter: F,
    initiator: I,
    config: TrackerConfig,
    tracks: Vec<Track<F::State>>,
    /// The hypothesis trees of the multi-scan associator (empty otherwise).
    mht: MhtState<F::State>,
    next_id: u64,
    t: Option<f64>,
    stats: AssociationStats,
    /// The tracks' update logs, when late scans are retrodicted.
    retro: Option<Retrodiction<F::State>>,
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
            mht: MhtState::default(),
            next_id: 1,
            t: None,
            stats: AssociationStats::default(),
            retro: None,
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

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// What the associator did so far.
    pub fn stats(&self) -> AssociationStats {
        self.stats
    }

    /// Sets the clutter density the soft and multi-scan associators assume for the next scans
    /// (`None`: estimated from each scan); no effect under GNN. A caller whose sensors differ
    /// (a known density on the ground for position sensors, none for cameras) sets it per scan.
    pub fn set_clutter_density(&mut self, density: Option<f64>) {
        match &mut self.config.association {
            Association::Gnn => {}
            Association::Jipda(j) => j.detection.clutter_density = density,
            Association::Mht(m) => m.detection.clutter_density = density,
        }
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
                existence: k.existence,
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
    /// between them. Every scan counts towards the M-of-N and miss counts (and the existence) of
    /// every track.
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
        self.forget_scan();
        let events = match self.config.association {
            Association::Mht(m) => self.step_mht(&m, t, dt, sensor, detections)?,
            _ => self.step_single(t, dt, sensor, detections)?,
        };
        self.stats.scans += 1;
        self.t = Some(t);
        Ok(events)
    }

    /// A new tentative track from detection `j`, or the reason it cannot start one (the
    /// detection fixes no position, or the initiator or filter refuses it).
    fn start<H, const M: usize>(
        &self,
        sensor: &H,
        z: &SVector<f64, M>,
        t: f64,
        existence: Option<f64>,
    ) -> std::result::Result<Track<F::State>, String>
    where
        H: Locate<M>,
    {
        let fix = sensor
            .locate(z)
            .ok_or_else(|| "the detection fixes no position".to_string())?;
        let state = self
            .initiator
            .initiate(&fix)
            .and_then(|g| self.filter.start(g))
            .map_err(|e| e.to_string())?;
        Ok(Track {
            id: 0,
            state,
            status: TrackStatus::Tentative,
            scans: 1,
            hits: 1,
            consecutive_misses: 0,
            last_update: t,
            existence,
        })
    }

    /// Takes over tracks from another tracker (a change of track filter or associator at run
    /// time): each keeps its id, status, hit/miss record and existence, and its Gaussian estimate
    /// becomes the state of this tracker's filter ([`TrackFilter::start`]: a mixture starts every
    /// mode from it with the initial mode probabilities). A track without an existence (from a GNN
    /// tracker) gets one from this tracker's thresholds when it needs one: a confirmed track its
    /// confirmation threshold, a tentative one its initial value. The tracker's time becomes `t`;
    /// new ids continue after the largest one seen. Replaces the tracks held; fails, changing
    /// nothing, when `t` is not finite, an id repeats or a filter cannot start from an estimate.
    pub fn adopt(&mut self, t: f64, tracks: &[(Track<()>, Gaussian<N>)]) -> Result<()> {
        if !t.is_finite() {
            return Err(EstimationError::InvalidParameter(format!(
                "adopt at t = {t}: not finite"
            )));
        }
        let existence = match self.config.association {
            Association::Gnn => None,
            Association::Jipda(Jipda { existence, .. })
            | Association::Mht(Mht { existence, .. }) => Some(existence),
        };
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
                existence: existence.map(|e| {
                    k.existence.unwrap_or(match k.status {
                        TrackStatus::Confirmed => e.confirm,
                        TrackStatus::Tentative => e.initial,
                    })
                }),
            });
        }
        adopted.sort_by_key(|k| k.id);
        self.mht = MhtState::adopt(&adopted);
        let top = adopted.iter().map(|k| k.id + 1).max().unwrap_or(1);
        self.next_id = self.next_id.max(top);
        self.tracks = adopted;
        self.t = Some(t);
        self.clear_logs();
        Ok(())
    }

    /// The hit/miss record (and existence) of every live track, without its state (what
    /// [`Tracker::adopt`] takes), in id order.
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
                existence: k.existence,
            })
            .collect()
    }

    /// Moves track `id` to the Gaussian `g` ([`TrackFilter::recentre`]): an update of its
    /// estimate made outside the tracker (sensor registration's joint update of every track with
    /// the biases, at the tracker's time). Errors when there is no such track or `g` is not a
    /// valid state; the track is then unchanged.
    pub fn recentre(&mut self, id: u64, g: Gaussian<N>) -> Result<()> {
        let k = self
            .tracks
            .iter_mut()
            .find(|k| k.id == id)
            .ok_or_else(|| EstimationError::InvalidParameter(format!("no track {id}")))?;
        k.state = self.filter.recentre(&k.state, g)?;
        Ok(())
    }

    /// The next id a new track gets.
    pub fn next_id(&self) -> u64 {
        self.next_id
    }

    /// [`Tracker::step`] for a sensor whose kind is known only at run time: each detection is a
    /// slice of [`SensorModel::dim`] components. With a retrodiction lag
    /// ([`Tracker::set_retrodiction_lag`]) it also takes a scan up to the lag older than the
    /// tracker's time ([`retrodict`](crate::tracker::retrodict)). Fails, leaving the tracker
    /// untouched, when a detection has the wrong length or the scan is older than the lag allows.
    pub fn step_any(
        &mut self,
        t: f64,
        sensor: &SensorModel,
        detections: &[&[f64]],
    ) -> Result<Vec<TrackEvent>> {
        let late = self.is_late(t)?;
        sensor.apply(StepWith {
            tracker: self,
            t,
            sensor,
            late,
            detections,
        })
    }
}

/// Why a track whose existence fell below the threshold goes: a tentative one never confirmed, a
/// confirmed one missed too many scans (only misses lower the existence of a track).
fn gone_by_existence(status: TrackStatus) -> DeleteReason {
    match status {
        TrackStatus::Tentative => DeleteReason::Unconfirmed,
        TrackStatus::Confirmed => DeleteReason::Misses,
    }
}

/// The visit of [`Tracker::step_any`]: the detections as const-sized vectors of the concrete model.
struct StepWith<'a, 'd, F: TrackFilter<N>, I, const N: usize> {
    tracker: &'a mut Tracker<F, I, N>,
    t: f64,
    sensor: &'d SensorModel,
    late: bool,
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
        if self.late {
            return self.tracker.step_late(self.t, model, self.sensor, &zs);
        }
        let events = self.tracker.step(self.t, model, &zs);
        match &events {
            Ok(_) => self.tracker.log_scan(self.t, self.sensor, self.detections),
            Err(_) => self.tracker.forget_scan(),
        }
        events
    }
}
