//! The ingest actor: detection payloads from Zenoh → validated [`SensorScan`]s in the server's
//! frame.
//!
//! The Zenoh subscriber's callback only copies each payload into a bounded queue (`try_send`:
//! when the queue is full the payload is dropped and counted as `queue_full`, so Zenoh is never
//! blocked). The ingest task decodes it with [`DetectionScan::from_json`], counts `seq` gaps,
//! converts it with harrier-link's [`scan_in_frame`] and sends it on to the tracker. Every bad
//! payload is counted per vehicle and reason, logged at most once per second per reason, and
//! dropped: nothing from outside can panic the service.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use harrier_core::detection::{DetectionScan, GeoPoint};
use harrier_core::measurement::{Geometry, TargetSize};
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;
use tokio::sync::mpsc;

use super::clock::{ClockConfig, SourceClock, unix_now};
use super::metrics::{DropReason, Metrics, vehicle_label};
use harrier_engine::SensorScan;
use harrier_recording::writer::{Record, Recorder};

/// A payload as it arrived: the vehicle label of its key and its bytes.
#[derive(Debug)]
pub struct Payload {
    /// Vehicle label (see [`vehicle_label`]).
    pub vehicle: String,
    /// The vehicle id in the key, if it is one.
    pub key_id: Option<u8>,
    /// The bytes.
    pub bytes: Vec<u8>,
    /// When it arrived.
    pub received: Instant,
    /// When it arrived, as UNIX time on the server's clock (s).
    pub arrival_unix: f64,
}

impl Payload {
    /// A payload received on Zenoh key `key`.
    pub fn new(key: &str, bytes: Vec<u8>) -> Self {
        let segment = key.split('/').nth(3).unwrap_or("");
        let vehicle = vehicle_label(segment);
        Self {
            key_id: vehicle.parse().ok(),
            vehicle,
            bytes,
            received: Instant::now(),
            arrival_unix: unix_now(),
        }
    }
}

/// A scan ready for the tracker, with the vehicle it came from.
#[derive(Debug, Clone)]
pub struct ReadyScan {
    /// Vehicle label.
    pub vehicle: String,
    /// Sensor id on the vehicle (orders scans of equal time).
    pub sensor: String,
    /// The scan in the server's frame.
    pub scan: SensorScan,
    /// Platform position at the scan (ENU, server frame).
    pub platform: [f64; 3],
    /// Platform velocity at the scan (ENU, server frame, m/s).
    pub platform_vel: [f64; 3],
    /// Platform position at the scan (WGS-84).
    pub geodetic: GeoPoint,
    /// When its payload arrived from Zenoh.
    pub received: Instant,
    /// Per-component noise std of the detections, as published.
    pub noise_std: Vec<f64>,
}

/// At most one log line per reason and interval; the lines in between are counted.
#[derive(Debug)]
struct LogLimiter {
    every: Duration,
    last: HashMap<DropReason, (Instant, u64)>,
}

impl LogLimiter {
    fn log(&mut self, reason: DropReason, vehicle: &str, message: &dyn std::fmt::Display) {
        let now = Instant::now();
        match self.last.get_mut(&reason) {
            Some((at, suppressed)) if now.duration_since(*at) < self.every => *suppressed += 1,
            entry => {
                let suppressed = entry.map_or(0, |(_, s)| *s);
                tracing::warn!(
                    vehicle,
                    reason = reason.as_str(),
                    suppressed,
                    "dropped a detection payload: {message}"
                );
                self.last.insert(reason, (now, 0));
            }
        }
    }
}

/// Most (vehicle, sensor) sequences followed for `seq` gaps.
const MAX_SEQUENCES: usize = 4096;

/// The ingest state: the frame, the `seq` of every sensor, the counters.
#[derive(Debug)]
pub struct Ingest {
    frame: LocalFrame,
    geometry: Geometry,
    metrics: Arc<Metrics>,
    last_seq: HashMap<(u8, String), u64>,
    log: LogLimiter,
    sensors: Vec<String>,
    target_size: Option<TargetSize>,
    recorder: Option<Recorder>,
    clock: ClockConfig,
    /// The clock of every vehicle that stamps `time_unix` (at most [`MAX_SEQUENCES`]).
    clocks: HashMap<u8, SourceClock>,
    /// The last (corrected) time of every sequence: a correction never takes a source back.
    last_t: HashMap<(u8, String), f64>,
}

impl Ingest {
    /// Ingest into the ENU frame `frame`, targets placed as `geometry` says.
    pub fn new(frame: LocalFrame, geometry: Geometry, metrics: Arc<Metrics>) -> Self {
        Self {
            frame,
            geometry,
            metrics,
            last_seq: HashMap::new(),
            log: LogLimiter {
                every: Duration::from_secs(1),
                last: HashMap::new(),
            },
            sensors: Vec::new(),
            target_size: None,
            recorder: None,
            clock: ClockConfig::default(),
            clocks: HashMap::new(),
            last_t: HashMap::new(),
        }
    }

    /// Bounds, estimates and corrects the sources' clocks as `clock` says.
    pub fn with_clock(mut self, clock: ClockConfig) -> Self {
        self.clock = clock;
        self
    }

    /// The targets' size (m), for `bearing_size` detections.
    pub fn with_target_size(mut self, size_m: Option<f64>) -> Self {
        self.target_size = size_m.map(TargetSize::Known);
        self
    }

    /// Records every valid scan (as received) into `recorder`.
    pub fn with_recorder(mut self, recorder: Option<Recorder>) -> Self {
        self.recorder = recorder;
        self
    }

    /// Only scans of these sensor ids are tracked (the others are counted as `sensor_filtered`
    /// drops); empty: every sensor.
    pub fn with_sensors(mut self, sensors: Vec<String>) -> Self {
        self.sensors = sensors;
        self
    }

    fn drop(&mut self, vehicle: &str, reason: DropReason, message: &dyn std::fmt::Display) {
        self.metrics.dropped(vehicle, reason);
        self.log.log(reason, vehicle, message);
    }

    /// Decodes and converts one payload; `None` when it was dropped (and counted).
    pub fn convert(&mut self, p: &Payload) -> Option<ReadyScan> {
        let v = p.vehicle.as_str();
        let scan = match DetectionScan::from_json(&p.bytes) {
            Ok(s) => s,
            Err(e) => {
                // Valid JSON of the wrong shape or values is `invalid`; anything else `json`.
                let reason = if serde_json::from_slice::<DetectionScan>(&p.bytes).is_ok() {
                    DropReason::Invalid
                } else {
                    DropReason::Json
                };
                self.drop(v, reason, &e);
                return None;
            }
        };
        if p.key_id != Some(scan.vehicle) {
            let m = format!("payload of vehicle {} on the key of {v}", scan.vehicle);
            self.drop(v, DropReason::KeyMismatch, &m);
            return None;
        }
        let t = match scan.time_unix {
            Some(time_unix) if self.clock.real_time => {
                self.place_in_time(v, &scan, time_unix, p.arrival_unix)?
            }
            // Without `time_unix`, `t` is on the publisher's own epoch: taken as sent.
            _ => scan.time_unix.unwrap_or(scan.t),
        };
        self.follow_seq(v, &scan);
        if let Some(r) = &self.recorder {
            r.record(Record::Scan {
                received_unix: unix_now(),
                scan: scan.clone(),
            });
        }
        if !self.sensors.is_empty() && !self.sensors.contains(&scan.sensor) {
            self.metrics.dropped(v, DropReason::SensorFiltered);
            return None;
        }
        let framed = match scan_in_frame(&scan, &self.frame, self.geometry) {
            Ok(f) => f,
            Err(e) => {
                self.drop(v, DropReason::Frame, &e);
                return None;
            }
        };
        let sensor = match framed.sensor_model(self.target_size) {
            Ok(m) => m,
            Err(e) => {
                self.drop(v, DropReason::Frame, &e);
                return None;
            }
        };
        Some(ReadyScan {
            vehicle: p.vehicle.clone(),
            platform: framed.platform_pos.into(),
            platform_vel: framed.platform_vel.into(),
            // A publisher may leave the geodetic position out: it is the same as `pos`.
            geodetic: scan.platform.geodetic.unwrap_or_else(|| {
                LocalFrame::new(scan.origin).from_enu(&nalgebra::Vector3::from(scan.platform.pos))
            }),
            received: p.received,
            noise_std: framed.noise_std,
            sensor: scan.sensor,
            scan: SensorScan {
                // One time line for every publisher: UNIX time when the scan carries it.
                t,
                sensor,
                detections: framed.detections,
            },
        })
    }

    /// The time of a scan stamped `time_unix` on the server's time line, or `None` when its
    /// clock is outside the bound (dropped as `clock`, counted and logged). Every stamped scan
    /// feeds its vehicle's clock estimate, the refused ones too (so a wrong clock shows).
    fn place_in_time(
        &mut self,
        vehicle: &str,
        scan: &DetectionScan,
        time_unix: f64,
        arrival: f64,
    ) -> Option<f64> {
        let full = self.clocks.len() >= MAX_SEQUENCES;
        let observed = match self.clocks.get_mut(&scan.vehicle) {
            Some(c) => Some((c.observe(time_unix, arrival), c.estimate(arrival))),
            None if !full => {
                let mut c = SourceClock::new(&self.clock);
                let o = c.observe(time_unix, arrival);
                let e = c.estimate(arrival);
                self.clocks.insert(scan.vehicle, c);
                Some((o, e))
            }
            None => None,
        };
        if let Some((_, Some(estimate))) = observed {
            self.metrics.clock(vehicle, estimate);
        }
        if let Some(why) = self.clock.refusal(time_unix, arrival) {
            self.drop(vehicle, DropReason::Clock, &why);
            return None;
        }
        let Some((o, _)) = observed.filter(|_| self.clock.correct) else {
            return Some(time_unix);
        };
        let key = (scan.vehicle, scan.sensor.clone());
        let last = self.last_t.get(&key).copied().unwrap_or(f64::NEG_INFINITY);
        let t = (time_unix - o.offset_s).max(last);
        if self.last_t.len() < MAX_SEQUENCES || self.last_t.contains_key(&key) {
            self.last_t.insert(key, t);
        }
        Some(t)
    }

    /// Counts the scans missing before `scan` in its sensor's `seq` sequence (a sequence that
    /// goes back is taken as a restarted publisher).
    fn follow_seq(&mut self, vehicle: &str, scan: &DetectionScan) {
        let full = self.last_seq.len() >= MAX_SEQUENCES;
        let key = (scan.vehicle, scan.sensor.clone());
        match self.last_seq.get_mut(&key) {
            Some(last) => {
                if scan.seq > last.saturating_add(1) {
                    self.metrics.seq_lost(vehicle, scan.seq - *last - 1);
                }
                *last = scan.seq;
            }
            None if !full => {
                self.last_seq.insert(key, scan.seq);
            }
            None => {}
        }
    }

    /// Runs until the payload queue closes or the tracker is gone.
    pub async fn run(mut self, mut rx: mpsc::Receiver<Payload>, tx: mpsc::Sender<ReadyScan>) {
        while let Some(p) = rx.recv().await {
            if let Some(ready) = self.convert(&p) {
                if tx.send(ready).await.is_err() {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, PlatformPose};
    use harrier_core::measurement::MeasKind;

    use crate::config::DEFAULT_ORIGIN;

    fn scan(seq: u64, z: Vec<f64>) -> DetectionScan {
        DetectionScan {
            time_unix: None,
            schema: DETECTIONS_SCHEMA.into(),
            t: seq as f64,
            vehicle: 2,
            seq,
            sensor: "cam".into(),
            kind: MeasKind::Position,
            origin: DEFAULT_ORIGIN,
            platform: PlatformPose {
                pos: [0.0; 3],
                vel: [0.0; 3],
                attitude: [0.0; 3],
                geodetic: Some(DEFAULT_ORIGIN),
            },
            noise_std: vec![10.0, 10.0],
            detections: vec![Detection { z }],
        }
    }

    #[test]
    fn bad_payloads_are_counted_by_reason_and_gaps_as_losses() {
        let metrics = Arc::new(Metrics::default());
        let mut ingest = Ingest::new(
            LocalFrame::new(DEFAULT_ORIGIN),
            Geometry::planar(0.0),
            Arc::clone(&metrics),
        );
        let key = "harrier/v1/vehicle/2/detections";
        let json = |s: &DetectionScan| s.to_json().into_bytes();
        let ok = ingest.convert(&Payload::new(key, json(&scan(1, vec![5.0, 6.0]))));
        assert_eq!(ok.expect("valid").scan.detections, vec![vec![5.0, 6.0]]);
        assert!(
            ingest
                .convert(&Payload::new(key, b"{not json".to_vec()))
                .is_none()
        );
        let mut bad = scan(2, vec![1.0, 2.0]);
        bad.noise_std = vec![-1.0, 1.0];
        assert!(ingest.convert(&Payload::new(key, json(&bad))).is_none());
        let other = "harrier/v1/vehicle/3/detections";
        assert!(
            ingest
                .convert(&Payload::new(other, json(&scan(3, vec![0.0, 0.0]))))
                .is_none()
        );
        // seq 1 → 5: 3 lost.
        assert!(
            ingest
                .convert(&Payload::new(key, json(&scan(5, vec![0.0, 0.0]))))
                .is_some()
        );
        let c = metrics.vehicle_counters("2");
        assert_eq!(c.dropped.get(&DropReason::Json), Some(&1));
        assert_eq!(c.dropped.get(&DropReason::Invalid), Some(&1));
        assert_eq!(c.seq_lost, 3);
        let c3 = metrics.vehicle_counters("3");
        assert_eq!(c3.dropped.get(&DropReason::KeyMismatch), Some(&1));
    }

    #[test]
    fn bearing_size_scans_need_the_target_size() {
        let metrics = Arc::new(Metrics::default());
        let ingest = |size| {
            Ingest::new(
                LocalFrame::new(DEFAULT_ORIGIN),
                Geometry::planar(0.0),
                Arc::clone(&metrics),
            )
            .with_target_size(size)
        };
        let mut s = scan(1, vec![0.3, -0.2, 0.01]);
        s.kind = MeasKind::BearingSize;
        s.platform.pos = [0.0, 0.0, 100.0];
        s.noise_std = vec![0.01, 0.01, 0.001];
        let p = Payload::new("harrier/v1/vehicle/2/detections", s.to_json().into_bytes());
        assert!(ingest(None).convert(&p).is_none());
        assert_eq!(
            metrics
                .vehicle_counters("2")
                .dropped
                .get(&DropReason::Frame),
            Some(&1)
        );
        let ready = ingest(Some(12.0)).convert(&p).expect("with a size");
        assert_eq!(ready.scan.sensor.kind(), MeasKind::BearingSize);
    }

    #[test]
    fn a_clock_outside_the_bound_is_refused_and_an_offset_one_corrected() {
        let metrics = Arc::new(Metrics::default());
        let mut ingest = Ingest::new(
            LocalFrame::new(DEFAULT_ORIGIN),
            Geometry::planar(0.0),
            Arc::clone(&metrics),
        );
        let key = "harrier/v1/vehicle/2/detections";
        let arrival = 1.8e9;
        let at = |seq: u64, time_unix: f64, arrival_unix: f64| {
            let mut s = scan(seq, vec![5.0, 6.0]);
            s.time_unix = Some(time_unix);
            Payload {
                arrival_unix,
                ..Payload::new(key, s.to_json().into_bytes())
            }
        };
        // 10⁷ s ahead: refused, counted, and it moves nothing.
        assert!(ingest.convert(&at(1, arrival + 1e7, arrival)).is_none());
        let c = metrics.vehicle_counters("2");
        assert_eq!(c.dropped.get(&DropReason::Clock), Some(&1));
        // The estimate shows the wrong clock.
        assert!((c.clock.expect("an estimate").offset_s - 1e7).abs() < 1.0);
        // The clock is fixed but runs 1 s ahead (3 scans confirm the jump back); each scan
        // arrives 10 ms after it was taken and is placed at the instant it was taken.
        for seq in 2..40 {
            let taken = arrival + seq as f64 * 0.1;
            let ready = ingest
                .convert(&at(seq, taken + 1.0, taken + 0.01))
                .expect("accepted");
            if seq >= 4 {
                assert!(
                    (ready.scan.t - taken).abs() < 0.02,
                    "seq {seq}: t = {}, taken {taken}",
                    ready.scan.t
                );
            }
        }
        let estimate = metrics.vehicle_counters("2").clock.expect("an estimate");
        assert!((estimate.offset_s - 0.99).abs() < 1e-3, "{estimate:?}");
        assert_eq!(estimate.jumps, 1);
        // Uncorrected, the same scan keeps its own time.
        let mut raw = Ingest::new(
            LocalFrame::new(DEFAULT_ORIGIN),
            Geometry::planar(0.0),
            Arc::clone(&metrics),
        )
        .with_clock(ClockConfig {
            correct: false,
            ..ClockConfig::default()
        });
        let ready = raw
            .convert(&at(1, arrival + 1.0, arrival))
            .expect("accepted");
        assert_eq!(ready.scan.t, arrival + 1.0);
    }

    #[test]
    fn a_scan_without_the_geodetic_position_gets_it_from_pos() {
        let metrics = Arc::new(Metrics::default());
        let mut ingest = Ingest::new(
            LocalFrame::new(DEFAULT_ORIGIN),
            Geometry::planar(0.0),
            Arc::clone(&metrics),
        );
        let mut s = scan(1, vec![5.0, 6.0]);
        s.platform.pos = [100.0, 200.0, 50.0];
        let mut json: serde_json::Value = serde_json::from_str(&s.to_json()).expect("json");
        json["platform"]
            .as_object_mut()
            .expect("platform")
            .remove("geodetic");
        let bytes = serde_json::to_vec(&json).expect("bytes");
        let ready = ingest
            .convert(&Payload::new("harrier/v1/vehicle/2/detections", bytes))
            .expect("accepted without platform.geodetic");
        let expected =
            LocalFrame::new(DEFAULT_ORIGIN).from_enu(&nalgebra::Vector3::new(100.0, 200.0, 50.0));
        assert!((ready.geodetic.lat_deg - expected.lat_deg).abs() < 1e-9);
        assert!((ready.geodetic.lon_deg - expected.lon_deg).abs() < 1e-9);
        assert!((ready.geodetic.alt_m - expected.alt_m).abs() < 1e-6);
        assert!(metrics.vehicle_counters("2").dropped.is_empty());
    }
}
