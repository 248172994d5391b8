//! What the tracker publishes: the snapshot of the tracks, each processed scan's events, the
//! vehicles as their detections show them, and the recent scans and histories the API reads.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use harrier_core::detection::GeoPoint;
use harrier_core::measurement::MeasKind;
use harrier_core::tracker::TrackEvent;
use serde::Serialize;

use super::TrackFilterState;
use crate::bound::BoundView;
use harrier_engine::{SensorBiasView, TrackView};

/// A vehicle as seen in its detections.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct VehicleView {
    /// Vehicle label (MAVLink system id).
    pub vehicle: String,
    /// Time of its last processed scan (the tracker's time line).
    pub last_t: f64,
    /// Scans of it processed.
    pub scans: u64,
    /// Its sensors seen so far.
    pub sensors: Vec<String>,
    /// Platform position at its last scan (ENU, m, in the server's frame).
    pub position: [f64; 3],
    /// Platform position at its last scan (WGS-84: `lat_deg`, `lon_deg`, `alt_m`).
    #[schema(value_type = Object)]
    pub geodetic: GeoPoint,
}

/// The engine's state after a scan.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    /// Time of the last processed scan.
    pub t: Option<f64>,
    /// Scans processed so far (the `seq` of the last [`ScanEvents`]).
    pub seq: u64,
    /// Every live track, in id order.
    pub tracks: Arc<Vec<TrackView>>,
    /// Every vehicle seen, by label. Each view is shared with the snapshots before it that it
    /// did not change: a scan copies one vehicle's view, not the swarm's.
    pub vehicles: Arc<Vec<Arc<VehicleView>>>,
    /// The estimator running.
    pub estimator: Arc<TrackFilterState>,
    /// The registered sensors' bias estimates (`[registration]`; empty when it is off), as of
    /// the last refresh (at most every [`BIAS_PERIOD_S`](super::BIAS_PERIOD_S) of scan time).
    pub biases: Arc<Vec<SensorBiasView>>,
}

/// One processed scan: what it held and what it did to the tracks.
#[derive(Debug)]
pub struct ScanEvents {
    /// Processed-scan counter, from 1 (a subscriber that sees a gap lost messages).
    pub seq: u64,
    /// Scan time.
    pub t: f64,
    /// The vehicle label of the scan.
    pub vehicle: String,
    /// Sensor id on the vehicle.
    pub sensor: String,
    /// Measurement kind.
    pub kind: MeasKind,
    /// Sensor (platform) position, ENU.
    pub platform: [f64; 3],
    /// The detections, in the server's frame (FORMAT.md §3 layout of `kind`).
    pub detections: Vec<Vec<f64>>,
    /// What happened.
    pub events: Vec<TrackEvent>,
    /// Every live track after the scan (the actor's list, brought up to date by the scan's
    /// [`ScanOutcome`](harrier_engine::ScanOutcome)).
    pub tracks: Arc<Vec<TrackView>>,
    /// The registered sensors' bias estimates when this scan refreshed them (at most every
    /// [`BIAS_PERIOD_S`](super::BIAS_PERIOD_S) of scan time), else `None`.
    pub biases: Option<Arc<Vec<SensorBiasView>>>,
    /// The WebSocket message, serialised once for every client (`crate::wire::scan_json`).
    pub(super) json: OnceLock<String>,
}

impl ScanEvents {
    /// The tracks this scan started, confirmed or updated, after the scan: those the WebSocket
    /// `scan` message carries and the recording keeps. (The scan changed the others too — aged,
    /// predicted, coasted — but they are not sent: a coasted track keeps its last state on the
    /// page.)
    pub fn changed_tracks(&self) -> impl Iterator<Item = &TrackView> {
        self.tracks
            .iter()
            .filter(|k| self.events.iter().any(|e| changes(e, k.id)))
    }

    /// Where `crate::wire::scan_json` keeps this scan's serialised WebSocket message.
    pub fn wire_cache(&self) -> &OnceLock<String> {
        &self.json
    }
}

/// Whether `e` changed track `id`'s estimate or status (born, confirmed, updated).
pub fn changes(e: &TrackEvent, id: u64) -> bool {
    matches!(e,
        TrackEvent::Born { id: k, .. }
        | TrackEvent::Confirmed { id: k }
        | TrackEvent::Updated { id: k, .. } if *k == id)
}

/// Shared read access to the recent scans and track histories.
#[derive(Debug, Default)]
pub struct Recent {
    pub(super) scans: Mutex<VecDeque<Arc<ScanEvents>>>,
    pub(super) history: Mutex<HashMap<u64, VecDeque<[f64; 4]>>>,
    pub(super) bounds: Mutex<HashMap<u64, BoundView>>,
}

impl Recent {
    /// The scans processed after `seq` (at most [`RECENT_SCANS`](super::RECENT_SCANS)), oldest first.
    pub fn scans_after(&self, seq: u64) -> Vec<Arc<ScanEvents>> {
        let q = self.scans.lock().unwrap_or_else(PoisonError::into_inner);
        q.iter().filter(|s| s.seq > seq).cloned().collect()
    }
    /// Track `id`'s set-membership bound, when bounds run and it has one.
    pub fn bound(&self, id: u64) -> Option<BoundView> {
        let b = self.bounds.lock().unwrap_or_else(PoisonError::into_inner);
        b.get(&id).cloned()
    }
    /// The `[t, x, y, z]` history of track `id` (the last [`HISTORY_LEN`](super::HISTORY_LEN) updates), oldest first.
    pub fn history(&self, id: u64) -> Vec<[f64; 4]> {
        let h = self.history.lock().unwrap_or_else(PoisonError::into_inner);
        h.get(&id)
            .map(|q| q.iter().copied().collect())
            .unwrap_or_default()
    }
}
