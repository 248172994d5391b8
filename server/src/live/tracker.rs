//! The tracker actor: owns the `Box<dyn TrackEngine>` and feeds it scans in time order.
//!
//! Scans wait in a short reorder buffer: a scan is processed once a scan at least
//! `reorder_window_s` (scan time) newer has arrived, or when nothing has arrived for that long in
//! wall time (at least 20 ms). A scan older than the last processed one is late: counted and
//! dropped. After each scan the actor publishes the engine's snapshot on a `watch` channel (the
//! latest state, never blocking) and the scan's track events on a bounded `broadcast` channel (a
//! slow subscriber loses events, tracking never waits for it).

use std::sync::Arc;
use std::time::Duration;

use harrier_core::tracker::TrackEvent;
use tokio::sync::{broadcast, mpsc, watch};

use super::ingest::ReadyScan;
use super::metrics::{DropReason, Metrics};
use crate::engine::{TrackEngine, TrackView};

/// The engine's state after a scan.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    /// Time of the last processed scan.
    pub t: Option<f64>,
    /// Every live track, in id order.
    pub tracks: Vec<TrackView>,
}

/// The track events of one processed scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanEvents {
    /// Scan time.
    pub t: f64,
    /// The vehicle label of the scan.
    pub vehicle: String,
    /// What happened.
    pub events: Vec<TrackEvent>,
}

/// The tracker actor.
#[derive(Debug)]
pub struct TrackerActor {
    engine: Box<dyn TrackEngine>,
    window: f64,
    metrics: Arc<Metrics>,
    pending: Vec<ReadyScan>,
    snapshot: watch::Sender<Arc<Snapshot>>,
    events: broadcast::Sender<Arc<ScanEvents>>,
}

impl TrackerActor {
    /// An actor over `engine` holding scans `window` seconds of scan time.
    pub fn new(
        engine: Box<dyn TrackEngine>,
        window: f64,
        metrics: Arc<Metrics>,
        snapshot: watch::Sender<Arc<Snapshot>>,
        events: broadcast::Sender<Arc<ScanEvents>>,
    ) -> Self {
        Self {
            engine,
            window,
            metrics,
            pending: Vec::new(),
            snapshot,
            events,
        }
    }

    /// Takes one scan into the reorder buffer, then processes what the window releases.
    pub fn push(&mut self, s: ReadyScan) {
        if self.engine.time().is_some_and(|last| s.scan.t < last) {
            self.metrics.dropped(&s.vehicle, DropReason::Late);
            tracing::debug!(vehicle = s.vehicle, t = s.scan.t, "late scan dropped");
            return;
        }
        let newest = self
            .pending
            .iter()
            .map(|p| p.scan.t)
            .fold(s.scan.t, f64::max);
        self.pending.push(s);
        self.release(newest - self.window);
    }

    /// Processes every buffered scan with time ≤ `until`, oldest first (equal times by vehicle
    /// and sensor).
    pub fn release(&mut self, until: f64) {
        self.pending.sort_by(|a, b| {
            a.scan
                .t
                .total_cmp(&b.scan.t)
                .then_with(|| a.vehicle.cmp(&b.vehicle))
                .then_with(|| a.sensor.cmp(&b.sensor))
        });
        let n = self.pending.partition_point(|p| p.scan.t <= until);
        let ready: Vec<ReadyScan> = self.pending.drain(..n).collect();
        for s in ready {
            self.process(s);
        }
    }

    fn process(&mut self, s: ReadyScan) {
        match self.engine.ingest(&s.scan) {
            Ok(events) => {
                let tracks = self.engine.snapshot();
                let confirmed = tracks.iter().filter(|k| k.status == "confirmed").count();
                self.metrics.ingested(
                    &s.vehicle,
                    s.scan.detections.len(),
                    s.scan.t,
                    confirmed,
                    tracks.len(),
                );
                self.snapshot.send_replace(Arc::new(Snapshot {
                    t: Some(s.scan.t),
                    tracks,
                }));
                // No subscriber is not an error.
                let _ = self.events.send(Arc::new(ScanEvents {
                    t: s.scan.t,
                    vehicle: s.vehicle,
                    events,
                }));
            }
            Err(e) => {
                self.metrics.dropped(&s.vehicle, DropReason::Rejected);
                tracing::warn!(vehicle = s.vehicle, t = s.scan.t, "scan rejected: {e}");
            }
        }
    }

    /// Runs until the scan queue closes, then processes what is left.
    pub async fn run(mut self, mut rx: mpsc::Receiver<ReadyScan>) {
        let idle = Duration::from_secs_f64(self.window).max(Duration::from_millis(20));
        loop {
            match tokio::time::timeout(idle, rx.recv()).await {
                Ok(Some(s)) => self.push(s),
                Ok(None) => break,
                Err(_) => self.release(f64::INFINITY),
            }
        }
        self.release(f64::INFINITY);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::SensorScan;
    use crate::live::config::Config;
    use harrier_core::measurement::{Geometry, SensorModel};
    use harrier_core::scenario::MeasKind;
    use nalgebra::Vector3;

    fn scan(t: f64, vehicle: &str) -> ReadyScan {
        let sensor = SensorModel::new(
            MeasKind::Position,
            Geometry::planar(0.0),
            Vector3::zeros(),
            &[10.0, 10.0],
            None,
        )
        .expect("model");
        ReadyScan {
            vehicle: vehicle.into(),
            sensor: "cam".into(),
            scan: SensorScan {
                t,
                sensor,
                detections: vec![vec![100.0 + t, 50.0]],
            },
        }
    }

    #[test]
    fn scans_are_reordered_within_the_window_and_late_ones_dropped() {
        let c = Config::default();
        let engine =
            crate::registry::build_track_engine("ekf", &c.scenario().expect("sc"), &c.params())
                .expect("engine");
        let metrics = Arc::new(Metrics::default());
        let (snap_tx, snap_rx) = watch::channel(Arc::new(Snapshot::default()));
        let (ev_tx, mut ev_rx) = broadcast::channel(16);
        let mut a = TrackerActor::new(engine, 0.5, Arc::clone(&metrics), snap_tx, ev_tx);
        a.push(scan(1.0, "1"));
        a.push(scan(0.8, "2")); // out of order, inside the window: processed first
        assert_eq!(snap_rx.borrow().t, None);
        a.push(scan(1.6, "1")); // releases 0.8 and 1.0
        assert_eq!(snap_rx.borrow().t, Some(1.0));
        assert_eq!(ev_rx.try_recv().expect("events").t, 0.8);
        a.push(scan(0.9, "2")); // older than the last processed: late
        a.release(f64::INFINITY);
        assert_eq!(snap_rx.borrow().t, Some(1.6));
        assert_eq!(
            metrics.vehicle_counters("2").dropped.get(&DropReason::Late),
            Some(&1)
        );
        assert_eq!(metrics.scans_ingested(), 3);
        assert!(!snap_rx.borrow().tracks.is_empty());
    }
}
