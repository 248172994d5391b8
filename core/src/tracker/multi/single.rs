//! The step of the single-state associators, GNN and JIPDA: one filter state per track, predicted,
//! gated through the scan's spatial index, associated cluster by cluster, updated (one detection,
//! or the mixture of them) or coasted; then confirmation, deletion and initiation.

use nalgebra::SVector;

use super::{Association, Jipda, Track, TrackEvent, TrackStatus, Tracker};
use crate::Result;
use crate::measurement::{Locate, MeasurementModel};
use crate::metrics::chi2_quantile;
use crate::tracker::associate::{TrackHypotheses, clusters, gnn_clusters, hypothesise_scan};
use crate::tracker::delete::DeleteReason;
use crate::tracker::filter::TrackFilter;
use crate::tracker::initiate::{Initiator, Verdict};
use crate::tracker::jipda::{self, Candidate, Soft};
use crate::tracker::jpda_star::move_together;

/// What association decided for one track.
enum Decision {
    /// GNN: this detection, or none.
    Hard(Option<usize>),
    /// JIPDA: the mixture and the posterior existence.
    Soft(Soft),
}

impl<F, I, const N: usize> Tracker<F, I, N>
where
    F: TrackFilter<N>,
    I: Initiator<N>,
{
    /// One scan of GNN or JIPDA (the caller checked the input).
    pub(super) fn step_single<H, const M: usize>(
        &mut self,
        t: f64,
        dt: f64,
        sensor: &H,
        detections: &[SVector<f64, M>],
    ) -> Result<Vec<TrackEvent>>
    where
        H: MeasurementModel<N, M> + Locate<M>,
    {
        let soft = match self.config.association {
            Association::Jipda(j) => Some(j),
            _ => None,
        };
        let mut events = Vec::new();

        // Predict (state and existence); a track whose prediction fails is deleted.
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
            let existence = match (soft, k.existence) {
                (Some(j), Some(psi)) => Some(j.existence.predict(psi, dt)),
                (Some(j), None) => Some(j.existence.initial),
                (None, e) => e,
            };
            tracks.push(Track {
                state,
                scans: k.scans + 1,
                existence,
                ..k.clone()
            });
        }

        // Gate: every track, confirmed or tentative (each with its own gate), against the
        // detections near it.
        let gaters: Vec<_> = tracks
            .iter()
            .map(|k| self.config.gater_for(k.status))
            .collect();
        let states: Vec<_> = tracks
            .iter()
            .zip(&gaters)
            .map(|(k, g)| (&k.state, g))
            .collect();
        let hyps: Vec<TrackHypotheses> =
            hypothesise_scan(&self.filter, &states, sensor, detections)
                .into_iter()
                .zip(&tracks)
                .map(|(h, k)| {
                    h.unwrap_or_else(|e| {
                        events.push(TrackEvent::Rejected {
                            id: Some(k.id),
                            detection: None,
                            reason: format!("measurement prediction: {e}"),
                        });
                        TrackHypotheses::default()
                    })
                })
                .collect();

        // Associate, cluster by cluster.
        let mut taken = vec![0.0; detections.len()];
        let decisions: Vec<Decision> = match soft {
            None => {
                let cs = clusters(&hyps, detections.len());
                let assigned = gnn_clusters(&hyps, &cs)?;
                for d in assigned.iter().flatten() {
                    taken[*d] = 1.0;
                }
                self.stats.clusters += cs.len() as u64;
                self.stats.largest_cluster = cs
                    .iter()
                    .map(|c| c.tracks.len())
                    .fold(self.stats.largest_cluster, usize::max);
                assigned.into_iter().map(Decision::Hard).collect()
            }
            Some(j) => self.jipda(&j, &tracks, &gaters, &hyps, detections.len(), &mut taken)?,
        };

        // Update or coast, then confirm / delete.
        let mut kept = Vec::with_capacity(tracks.len() + detections.len());
        for ((mut k, decision), h) in tracks.into_iter().zip(decisions).zip(&hyps) {
            let (outcome, state) = match &decision {
                Decision::Hard(None) => (None, Ok(None)),
                Decision::Hard(Some(d)) => (
                    Some(*d),
                    self.filter
                        .update(&k.state, sensor, &detections[*d])
                        .map(Some),
                ),
                Decision::Soft(s) => {
                    k.existence = Some(s.existence);
                    // The most probable detection, when it is more probable than none.
                    let best = s
                        .detections
                        .iter()
                        .filter(|d| d.1 >= s.miss)
                        .max_by(|a, b| a.1.total_cmp(&b.1))
                        .map(|d| d.0);
                    let mixture: Vec<(SVector<f64, M>, f64)> = s
                        .detections
                        .iter()
                        .filter(|d| d.1 > 0.0)
                        .map(|&(d, beta)| (detections[d], beta))
                        .collect();
                    let state = if mixture.is_empty() {
                        Ok(None)
                    } else {
                        self.filter
                            .update_mixture(&k.state, sensor, &mixture, s.miss)
                            .map(Some)
                    };
                    (best, state)
                }
            };
            let mut updated = false;
            let mut failed = false;
            match state {
                Ok(Some(s)) => {
                    k.state = s;
                    match &decision {
                        Decision::Hard(Some(d)) => self.applied(k.id, vec![(*d, 1.0)], 0.0),
                        Decision::Soft(s) => self.applied(
                            k.id,
                            s.detections.iter().filter(|d| d.1 > 0.0).copied().collect(),
                            s.miss,
                        ),
                        Decision::Hard(None) => {}
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    failed = true;
                    events.push(TrackEvent::Rejected {
                        id: Some(k.id),
                        detection: outcome,
                        reason: format!("update: {e}"),
                    });
                }
            }
            if let Some(d) = outcome.filter(|_| !failed) {
                k.hits += 1;
                k.consecutive_misses = 0;
                k.last_update = t;
                updated = true;
                let nis = h.nis(d);
                events.push(TrackEvent::Updated {
                    id: k.id,
                    detection: d,
                    nis,
                });
            }
            if !updated {
                k.consecutive_misses += 1;
                events.push(TrackEvent::Coasted {
                    id: k.id,
                    misses: k.consecutive_misses,
                });
            }
            let gone = self.judge(&mut k, soft.as_ref(), &mut events);
            match gone {
                Some(reason) => events.push(TrackEvent::Deleted { id: k.id, reason }),
                None => kept.push(k),
            }
        }

        // Initiate from the detections no track took (JIPDA: that are probably no known
        // target's).
        let birth = soft.map_or(1.0, |j| 1.0 - j.birth);
        for (j, z) in detections.iter().enumerate() {
            if taken[j] >= birth.max(1e-12) {
                continue;
            }
            let existence = soft.map(|s| s.existence.initial);
            let mut k = match self.start(sensor, z, t, existence) {
                Ok(k) => k,
                Err(reason) => {
                    events.push(TrackEvent::Rejected {
                        id: None,
                        detection: Some(j),
                        reason: format!("initiation: {reason}"),
                    });
                    continue;
                }
            };
            k.id = self.next_id;
            self.next_id += 1;
            events.push(TrackEvent::Born {
                id: k.id,
                detection: j,
            });
            self.applied(k.id, vec![(j, 1.0)], 0.0);
            let confirmed = match soft {
                None => self.config.confirm.judge(1, 1) == Verdict::Confirm,
                Some(s) => s.existence.initial >= s.existence.confirm,
            };
            if confirmed {
                k.status = TrackStatus::Confirmed;
                events.push(TrackEvent::Confirmed { id: k.id });
            }
            kept.push(k);
        }
        kept.sort_by_key(|k| k.id);
        self.tracks = kept;
        Ok(events)
    }

    /// JIPDA on every cluster; fills `taken` with the probability that each detection is a known
    /// target's.
    fn jipda(
        &mut self,
        j: &Jipda,
        tracks: &[Track<F::State>],
        gaters: &[crate::tracker::Gater],
        hyps: &[TrackHypotheses],
        n_det: usize,
        taken: &mut [f64],
    ) -> Result<Vec<Decision>> {
        let pd = j.detection.pd;
        let mut out: Vec<Decision> = tracks
            .iter()
            .zip(gaters)
            .zip(hyps)
            .map(|((k, g), h)| {
                // A track with no gated detection: the IPDA miss update.
                let psi = k.existence.unwrap_or(j.existence.initial);
                let pdpg = pd * g.probability_for(h.dim.max(1));
                Decision::Soft(Soft {
                    existence: (1.0 - pdpg) * psi / (1.0 - pdpg * psi),
                    miss: 1.0,
                    detections: Vec::new(),
                })
            })
            .collect();
        let gate = if j.star_gate >= 1.0 {
            f64::INFINITY
        } else {
            chi2_quantile(j.star_gate, N / 2)
        };
        for c in clusters(hyps, n_det) {
            let cands: Vec<Candidate<'_>> = c
                .tracks
                .iter()
                .map(|&i| Candidate {
                    existence: tracks[i].existence.unwrap_or(j.existence.initial),
                    gate_prob: gaters[i].probability_for(hyps[i].dim),
                    hypotheses: &hyps[i],
                })
                .collect();
            let rho = j
                .detection
                .clutter_density
                .unwrap_or_else(|| jipda::estimated_clutter(&c, &cands, pd));
            // JPDA* looks at the velocities of the tracks of shared clusters only.
            let shared = j.star_nodes > 0 && c.tracks.len() > 1;
            let estimates: Vec<_> = c
                .tracks
                .iter()
                .filter(|_| shared)
                .map(|&i| self.filter.estimate(&tracks[i].state))
                .collect();
            let together = |a: usize, b: usize| move_together(&estimates[a], &estimates[b], gate);
            let o = jipda::associate(&c, &cands, pd, rho, j.max_net_nodes, j.star_nodes, together)?;
            self.stats.clusters += 1;
            self.stats.largest_cluster = self.stats.largest_cluster.max(c.tracks.len());
            self.stats.largest_net = self.stats.largest_net.max(o.nodes);
            self.stats.capped += u64::from(o.capped);
            for (d, p) in o.taken {
                taken[d] += p;
            }
            for (&i, s) in c.tracks.iter().zip(o.tracks) {
                out[i] = Decision::Soft(s);
            }
        }
        Ok(out)
    }

    /// Confirms `k` or says why it goes: M-of-N and misses (GNN) or the existence thresholds
    /// (JIPDA), and the covariance bound (both).
    fn judge(
        &self,
        k: &mut Track<F::State>,
        soft: Option<&Jipda>,
        events: &mut Vec<TrackEvent>,
    ) -> Option<DeleteReason> {
        let deleter = &self.config.deleter;
        match (soft, k.existence) {
            (Some(j), Some(psi)) => {
                if psi < j.existence.delete {
                    return Some(super::gone_by_existence(k.status));
                }
                if k.status == TrackStatus::Tentative && psi >= j.existence.confirm {
                    k.status = TrackStatus::Confirmed;
                    events.push(TrackEvent::Confirmed { id: k.id });
                }
                let covariance = deleter.judge(0, &self.filter.estimate(&k.state));
                covariance.filter(|_| k.status == TrackStatus::Confirmed)
            }
            _ => match k.status {
                TrackStatus::Tentative => match self.config.confirm.judge(k.hits, k.scans) {
                    Verdict::Confirm => {
                        k.status = TrackStatus::Confirmed;
                        events.push(TrackEvent::Confirmed { id: k.id });
                        None
                    }
                    Verdict::Pending => None,
                    Verdict::Drop => Some(DeleteReason::Unconfirmed),
                },
                TrackStatus::Confirmed => {
                    deleter.judge(k.consecutive_misses, &self.filter.estimate(&k.state))
                }
            },
        }
    }
}
