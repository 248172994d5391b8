//! The simulated vehicles: one Zenoh session of their own, a publisher per sensor of each vehicle
//! on the vehicle's detections key, each publishing a `DetectionScan` (JSON, `position` kind) at
//! a fixed rate on a tokio interval — `seq` +1 per scan, `time_unix` the wall time of the
//! publication (monotonic per sensor), one detection of every target.
//!
//! The targets circle (radius [`CIRCLE_M`], [`SPEED_MPS`]) around centres [`SPACING_M`] apart, so
//! the tracker holds one confirmed, moving track per target and associations stay unambiguous;
//! detections carry Gaussian noise of [`NOISE_M`] (seeded per vehicle and sensor). The targets
//! move on the UNIX clock, so that several publishing processes (and machines whose clocks
//! agree) see the same targets.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Duration;

use anyhow::Context as _;
use harrier_core::detection::{
    DETECTIONS_SCHEMA, Detection, DetectionScan, GeoPoint, PlatformPose, detections_key,
};
use harrier_core::measurement::MeasKind;
use harrier_link::bus::{BusConfig, Mode};
use harrier_link::geo::LocalFrame;
use nalgebra::Vector3;
use rand::SeedableRng as _;
use rand_distr::Distribution as _;
use tokio::sync::watch;
use tokio::task::JoinHandle;

use super::stats::now_unix;

/// Distance between the targets' circle centres (m).
pub(super) const SPACING_M: f64 = 300.0;
/// Radius of each target's circle (m).
pub(super) const CIRCLE_M: f64 = 50.0;
/// Target speed (m/s).
pub(super) const SPEED_MPS: f64 = 5.0;
/// Detection noise, each axis (m).
pub(super) const NOISE_M: f64 = 5.0;
/// Longest wait for the server's subscriber to match a publisher.
const MATCH_TIMEOUT: Duration = Duration::from_secs(15);

/// What the vehicles publish.
#[derive(Debug, Clone)]
pub(super) struct Plan {
    /// MAVLink system ids.
    pub vehicles: Vec<u8>,
    /// Sensors per vehicle, each a source of its own.
    pub sensors: u8,
    /// Scans per second per vehicle.
    pub rate_hz: f64,
    /// Detections per scan (= targets).
    pub detections: usize,
    /// Origin of the scans' ENU frame.
    pub origin: GeoPoint,
    /// Zenoh endpoints of the server.
    pub connect: Vec<String>,
    /// Endpoint this session listens on, as a peer; none: a client of `connect` (a router).
    pub listen: Option<String>,
    /// How the vehicles' publication instants are placed within a period.
    pub phase: Phase,
}

/// Where in the scan period each vehicle publishes. The tracker processes scans in time order,
/// so a scan waits until every other active vehicle has published a newer one: the phases decide
/// how long.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Evenly spread over the period (vehicle k of N at k/N of it): each scan waits about
    /// (N − 1)/N of a period for the others.
    Spread,
    /// Uniformly random in the period (seeded): unsynchronised vehicles.
    Random,
    /// All at the same instant: synchronised sensors.
    Same,
}

/// The publishing vehicles. Stop them with [`Publishers::stop`].
#[derive(Debug)]
pub(super) struct Publishers {
    scans: Arc<AtomicU64>,
    /// The rate factor every vehicle publishes at (`f64` bits; 1: `rate_hz`).
    factor: Arc<AtomicU64>,
    failed: Arc<AtomicU64>,
    stop: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
    session: zenoh::Session,
}

/// Target `j`'s position at UNIX time `t` (s).
pub(super) fn target_position(j: usize, t: f64) -> [f64; 2] {
    let (row, col) = (j / 32, j % 32);
    let phase = j as f64; // spread the targets around their circles
    // The angle turned since the epoch, reduced to one turn first (f64 keeps µm at 50 m).
    let a = phase + (SPEED_MPS / CIRCLE_M * t).rem_euclid(std::f64::consts::TAU);
    [
        SPACING_M * col as f64 + CIRCLE_M * a.cos(),
        SPACING_M * row as f64 + CIRCLE_M * a.sin(),
    ]
}

/// The sensor id of sensor `k` of `n` on a vehicle: `cam` when it has one, else `cam0`, `cam1` …
pub(super) fn sensor_id(k: u8, n: u8) -> String {
    if n == 1 {
        "cam".into()
    } else {
        format!("cam{k}")
    }
}

/// One sensor's scan template: everything but `t`, `time_unix`, `seq` and the detections.
fn template(vehicle: u8, sensor: String, origin: GeoPoint, detections: usize) -> DetectionScan {
    let pos = [100.0 * f64::from(vehicle), -500.0, 300.0];
    let geodetic = LocalFrame::new(origin).from_enu(&Vector3::from(pos));
    DetectionScan {
        schema: DETECTIONS_SCHEMA.into(),
        t: 0.0,
        time_unix: None,
        vehicle,
        seq: 0,
        sensor,
        kind: MeasKind::Position,
        origin,
        platform: PlatformPose {
            pos,
            vel: [0.0; 3],
            attitude: [0.0; 3],
            geodetic: Some(geodetic),
        },
        noise_std: vec![NOISE_M, NOISE_M],
        detections: vec![Detection { z: vec![0.0; 2] }; detections],
    }
}

impl Publishers {
    /// Opens the session, declares every sensor's publisher and waits until the server's
    /// subscriber matches each; then every sensor publishes from a start staggered over one
    /// period (so that the scans of all sensors spread evenly in time).
    pub(super) async fn start(plan: &Plan) -> anyhow::Result<Self> {
        let config = BusConfig {
            mode: if plan.listen.is_some() {
                Mode::Peer
            } else {
                Mode::Client
            },
            connect: plan.connect.clone(),
            listen: plan.listen.iter().cloned().collect(),
            ..BusConfig::default()
        }
        .to_zenoh()?;
        let session = zenoh::open(config)
            .await
            .map_err(|e| anyhow::anyhow!("zenoh: cannot open the publishers' session: {e}"))?;
        let mut publishers = Vec::new();
        for &v in &plan.vehicles {
            for k in 0..plan.sensors {
                let key = detections_key(v);
                let p = session
                    .declare_publisher(key.clone())
                    .encoding(
                        zenoh::bytes::Encoding::APPLICATION_JSON.with_schema(DETECTIONS_SCHEMA),
                    )
                    .await
                    .map_err(|e| anyhow::anyhow!("zenoh: declare a publisher on {key}: {e}"))?;
                publishers.push((v, k, p));
            }
        }
        let waited = tokio::time::Instant::now();
        for (v, _, p) in &publishers {
            loop {
                let matching = p
                    .matching_status()
                    .await
                    .map_err(|e| anyhow::anyhow!("zenoh: matching status: {e}"))?
                    .matching();
                if matching {
                    break;
                }
                if waited.elapsed() > MATCH_TIMEOUT {
                    anyhow::bail!(
                        "no subscriber on {} within {MATCH_TIMEOUT:?}: is the server's Zenoh \
                         endpoint {:?} reachable?",
                        detections_key(*v),
                        plan.connect
                    );
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        }
        let noise = rand_distr::Normal::new(0.0, NOISE_M).context("detection noise")?;
        let scans = Arc::new(AtomicU64::new(0));
        let factor = Arc::new(AtomicU64::new(1.0_f64.to_bits()));
        let failed = Arc::new(AtomicU64::new(0));
        let (stop, stop_rx) = watch::channel(false);
        let period = Duration::from_secs_f64(1.0 / plan.rate_hz);
        let epoch = now_unix();
        let start = tokio::time::Instant::now();
        let n = publishers.len() as f64;
        let mut phase_rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let tasks = publishers
            .into_iter()
            .enumerate()
            .map(|(k, (v, sensor, p))| {
                let vehicle = Vehicle {
                    scan: template(
                        v,
                        sensor_id(sensor, plan.sensors),
                        plan.origin,
                        plan.detections,
                    ),
                    rng: rand_chacha::ChaCha8Rng::seed_from_u64(
                        u64::from(v) + 256 * u64::from(sensor),
                    ),
                    noise,
                    epoch,
                    scans: Arc::clone(&scans),
                    failed: Arc::clone(&failed),
                    factor: Arc::clone(&factor),
                };
                let fraction = match plan.phase {
                    Phase::Spread => k as f64 / n,
                    Phase::Random => rand::Rng::random::<f64>(&mut phase_rng),
                    Phase::Same => 0.0,
                };
                let first = start + period.mul_f64(fraction);
                tokio::spawn(vehicle.run(p, first, period, stop_rx.clone()))
            })
            .collect();
        Ok(Self {
            scans,
            factor,
            failed,
            stop,
            tasks,
            session,
        })
    }

    /// Scans published so far.
    pub(super) fn scans(&self) -> u64 {
        self.scans.load(Relaxed)
    }

    /// From now on every vehicle publishes at `factor` × the plan's rate (overload phases).
    pub(super) fn set_rate_factor(&self, factor: f64) {
        self.factor.store(factor.to_bits(), Relaxed);
    }

    /// Stops every vehicle, waits for them and closes the session: scans and failed puts.
    pub(super) async fn stop(self) -> (u64, u64) {
        let _ = self.stop.send(true);
        for t in self.tasks {
            if let Err(e) = t.await {
                tracing::warn!("a publisher ended abnormally: {e}");
            }
        }
        if let Err(e) = self.session.close().await {
            tracing::warn!("zenoh: close the publishers' session: {e}");
        }
        (self.scans.load(Relaxed), self.failed.load(Relaxed))
    }
}

/// One sensor's publication state.
struct Vehicle {
    scan: DetectionScan,
    rng: rand_chacha::ChaCha8Rng,
    noise: rand_distr::Normal<f64>,
    epoch: f64,
    scans: Arc<AtomicU64>,
    failed: Arc<AtomicU64>,
    factor: Arc<AtomicU64>,
}

impl Vehicle {
    /// The next scan, stamped now (later than the last one).
    fn next(&mut self) -> String {
        let now = self
            .scan
            .time_unix
            .map_or(now_unix(), |last| now_unix().max(last + 1e-6));
        let tau = now - self.epoch;
        for (j, d) in self.scan.detections.iter_mut().enumerate() {
            let p = target_position(j, now);
            d.z[0] = p[0] + self.noise.sample(&mut self.rng);
            d.z[1] = p[1] + self.noise.sample(&mut self.rng);
        }
        self.scan.seq += 1;
        self.scan.t = tau;
        self.scan.time_unix = Some(now);
        self.scan.to_json()
    }

    async fn run(
        mut self,
        publisher: zenoh::pubsub::Publisher<'static>,
        first: tokio::time::Instant,
        period: Duration,
        mut stop: watch::Receiver<bool>,
    ) {
        let mut next = first;
        loop {
            tokio::select! {
                () = tokio::time::sleep_until(next) => {}
                _ = async { stop.wait_for(|s| *s).await.is_ok() } => break,
            }
            // The period of the current rate; a vehicle more than a period behind (it cannot
            // publish that fast) skips the missed instants rather than bursting later.
            let p = period.div_f64(f64::from_bits(self.factor.load(Relaxed)));
            next += p;
            let now = tokio::time::Instant::now();
            if next + p < now {
                next = now;
            }
            match publisher.put(self.next()).await {
                Ok(()) => self.scans.fetch_add(1, Relaxed),
                Err(_) => self.failed.fetch_add(1, Relaxed),
            };
        }
        if let Err(e) = publisher.undeclare().await {
            tracing::warn!("zenoh: undeclare a publisher: {e}");
        }
    }
}
