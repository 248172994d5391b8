//! Publishing detections and truth over Zenoh.
//!
//! Keys and payloads are those of [`harrier_core::detection`] (documented in `DETECTIONS.md`):
//! each vehicle's scans on `harrier/v1/vehicle/{id}/detections`, simulation truth on
//! `harrier/v1/sim/truth`, JSON with encoding `application/json;harrier-detections/1` (resp.
//! `…;harrier-truth/1`). The session comes from harrier-link's [`BusConfig`] (peer or client mode,
//! explicit `--connect` / `--listen` endpoints, multicast scouting off unless asked for, so
//! nothing leaks onto the LAN), as the ground station's does.

use std::collections::HashMap;

use harrier_core::detection::{
    DETECTIONS_SCHEMA, DetectionScan, TRUTH_KEY, TRUTH_SCHEMA, TruthSample, detections_key,
};
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;

/// The session configuration [`Bus::open`] takes, and its errors (harrier-link's).
pub use harrier_link::bus::{BusConfig, BusError};

/// Publication counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusCounters {
    /// Scans published.
    pub scans: u64,
    /// Truth samples published.
    pub truth: u64,
    /// Publications Zenoh refused (logged).
    pub failed: u64,
}

/// An open Zenoh session with a publisher per vehicle.
#[derive(Debug)]
pub struct Bus {
    session: zenoh::Session,
    vehicles: HashMap<u8, Publisher<'static>>,
    truth: Publisher<'static>,
    counters: BusCounters,
}

impl Bus {
    /// Opens the session.
    pub fn open(config: &BusConfig) -> Result<Self, BusError> {
        let session = config.open()?;
        let truth = session
            .declare_publisher(TRUTH_KEY)
            .encoding(Encoding::APPLICATION_JSON.with_schema(TRUTH_SCHEMA))
            .wait()
            .map_err(|e| BusError::Session(format!("declare publisher {TRUTH_KEY}: {e}")))?;
        Ok(Self {
            session,
            vehicles: HashMap::new(),
            truth,
            counters: BusCounters::default(),
        })
    }

    /// Counters so far.
    pub fn counters(&self) -> BusCounters {
        self.counters
    }

    /// Publishes one scan on its vehicle's key.
    pub fn publish_scan(&mut self, scan: &DetectionScan) {
        if !self.vehicles.contains_key(&scan.vehicle) {
            let key = detections_key(scan.vehicle);
            match self
                .session
                .declare_publisher(key.clone())
                .encoding(Encoding::APPLICATION_JSON.with_schema(DETECTIONS_SCHEMA))
                .wait()
            {
                Ok(p) => {
                    self.vehicles.insert(scan.vehicle, p);
                }
                Err(e) => {
                    eprintln!("harrier-sim: zenoh: declare publisher {key}: {e}");
                    self.counters.failed += 1;
                    return;
                }
            }
        }
        let Some(p) = self.vehicles.get(&scan.vehicle) else {
            return;
        };
        match p.put(scan.to_json()).wait() {
            Ok(()) => self.counters.scans += 1,
            Err(e) => {
                self.counters.failed += 1;
                eprintln!("harrier-sim: zenoh: put {}: {e}", p.key_expr());
            }
        }
    }

    /// Publishes a truth sample.
    pub fn publish_truth(&mut self, truth: &TruthSample) {
        match self.truth.put(truth.to_json()).wait() {
            Ok(()) => self.counters.truth += 1,
            Err(e) => {
                self.counters.failed += 1;
                eprintln!("harrier-sim: zenoh: put {TRUTH_KEY}: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::detection::{Detection, GeoPoint, PlatformPose};
    use harrier_core::measurement::MeasKind;
    use std::time::Duration;

    /// A real session on loopback: a subscriber connected to the publisher's listener receives a
    /// scan that decodes to what was sent, with the documented encoding.
    #[test]
    fn a_subscriber_receives_scans() {
        // Zenoh's stable API does not report the port it bound: take a free one from the OS.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("free port")
            .port();
        let endpoint = format!("tcp/127.0.0.1:{port}");
        let mut bus = Bus::open(&BusConfig {
            listen: vec![endpoint.clone()],
            ..BusConfig::default()
        })
        .expect("open publisher session");
        let sub_session = BusConfig {
            connect: vec![endpoint],
            ..BusConfig::default()
        }
        .open()
        .expect("open subscriber session");
        let sub = sub_session
            .declare_subscriber(harrier_core::detection::DETECTIONS_KEY_ALL)
            .wait()
            .expect("subscribe");
        let scan = DetectionScan {
            time_unix: None,
            schema: DETECTIONS_SCHEMA.into(),
            t: 1.5,
            vehicle: 3,
            seq: 0,
            sensor: "radar".into(),
            kind: MeasKind::RangeBearing,
            origin: GeoPoint {
                lat_deg: 47.0,
                lon_deg: 8.0,
                alt_m: 400.0,
            },
            platform: PlatformPose {
                pos: [0.0; 3],
                vel: [0.0; 3],
                attitude: [0.0; 3],
                geodetic: Some(GeoPoint {
                    lat_deg: 47.0,
                    lon_deg: 8.0,
                    alt_m: 400.0,
                }),
            },
            noise_std: vec![5.0, 0.005],
            detections: vec![Detection {
                z: vec![1000.0, 0.5],
            }],
        };
        // Publish until the subscriber's declaration has reached us (no fixed sleep).
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        let sample = loop {
            bus.publish_scan(&scan);
            if let Ok(Some(s)) = sub.recv_timeout(Duration::from_millis(50)) {
                break s;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "no sample within 10 s"
            );
        };
        assert_eq!(
            sample.key_expr().as_str(),
            "harrier/v1/vehicle/3/detections"
        );
        assert_eq!(
            sample.encoding().to_string(),
            "application/json;harrier-detections/1"
        );
        let got = DetectionScan::from_json(&sample.payload().to_bytes()).expect("valid payload");
        assert_eq!(got, scan);
        assert!(bus.counters().scans >= 1);
        assert_eq!(bus.counters().failed, 0);
    }
}
