//! The live sensor loop: moves the world in (sped-up) wall time, scans every vehicle's sensors from
//! the vehicle's real pose (radars that paint vehicles see the others where they fly), and
//! publishes the scans and the truth over Zenoh.
//!
//! It runs on its own thread beside the vehicles' threads ([`crate::net::spawn`]) and only reads
//! the vehicles (their pose under their lock). Unlike `record`, a live run is not reproducible:
//! the vehicles fly whatever their MAVLink clients command, when the packets arrive.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use harrier_core::detection::{DetectionScan, PlatformPose, TRUTH_SCHEMA, TruthSample};

use harrier_link::geo::LocalFrame;
use nalgebra::Vector3;

use crate::bus::{Bus, BusCounters};
use crate::sensors::{SensorSuite, platform_pose};
use crate::setup::{ScenarioError, SimScenario};
pub use crate::vehicle::ClockSkew;
use crate::vehicle::Vehicle;
use crate::worker::Worker;
use crate::world::World;

/// Settings of the sensor loop.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorLoopConfig {
    /// World and sensors.
    pub scenario: SimScenario,
    /// Seed of the world and of every sensor.
    pub seed: u64,
    /// Simulated seconds per wall-clock second (as the vehicles').
    pub speedup: f64,
    /// Truth publication rate (Hz of simulated time).
    pub truth_hz: f64,
    /// How wrong the clock that stamps `time_unix` is (tests make wrong clocks with it).
    pub clock: ClockSkew,
}

/// The running loop; stopped when dropped.
#[derive(Debug)]
pub struct SensorLoopHandle {
    counters: Arc<Mutex<BusCounters>>,
    worker: Worker,
}

impl SensorLoopHandle {
    /// Publication counters so far.
    pub fn counters(&self) -> BusCounters {
        *self.counters.lock().unwrap_or_else(PoisonError::into_inner)
    }
    /// Stops the loop and waits for it.
    pub fn stop(mut self) {
        self.worker.stop();
    }
}

/// Why the loop could not start.
#[derive(Debug, thiserror::Error)]
pub enum SensorLoopError {
    /// The scenario does not build a world or sensors.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A rate or the speed-up is not a finite positive number.
    #[error("{0} must be a finite number > 0")]
    NotPositive(&'static str),
    /// The clock skew is not finite.
    #[error("{0} offset and drift must be finite numbers")]
    NotFinite(&'static str),
    /// The thread could not be started.
    #[error("cannot start the sensor thread: {0}")]
    Thread(std::io::Error),
}

/// Longest wall-clock sleep between two passes of the loop.
const MAX_TICK: Duration = Duration::from_millis(5);

/// Starts the loop for `vehicles` (their sensor suites are built from the scenario, seeded per
/// vehicle id), publishing on `bus`.
pub fn spawn(
    config: &SensorLoopConfig,
    vehicles: Vec<Arc<Mutex<Vehicle>>>,
    mut bus: Bus,
) -> Result<SensorLoopHandle, SensorLoopError> {
    for (name, v) in [("speedup", config.speedup), ("truth_hz", config.truth_hz)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(SensorLoopError::NotPositive(name));
        }
    }
    let skew = config.clock;
    if !(skew.offset_s.is_finite() && skew.drift_ppm.is_finite()) {
        return Err(SensorLoopError::NotFinite("clock"));
    }
    let mut world = World::new(&config.scenario, config.seed)?;
    let mut suites = Vec::with_capacity(vehicles.len());
    for v in &vehicles {
        let id = v.lock().unwrap_or_else(PoisonError::into_inner).id();
        suites.push((id, SensorSuite::new(&config.scenario, config.seed, id)?));
    }
    let origin = config.scenario.origin;
    // Sleep a quarter of the fastest sensor's period, at most MAX_TICK (wall time).
    let fastest = config
        .scenario
        .sensors
        .iter()
        .map(|s| s.rate_hz)
        .fold(config.truth_hz, f64::max);
    let tick = Duration::from_secs_f64(0.25 / (fastest * config.speedup)).min(MAX_TICK);
    let truth_period = 1.0 / config.truth_hz;
    let speedup = config.speedup;
    let counters = Arc::new(Mutex::new(BusCounters::default()));
    let c = Arc::clone(&counters);
    let start = Instant::now();
    // Scans carry `t` (simulated seconds since this start, their stamp) and the same instant as
    // UNIX time. A sensor with a time offset δ > 0 stamps a scan taken at t with t + δ and it is
    // published then (by the first pass at or after it), with the platform's pose of then (that
    // pass's pose moved back to the stamp along its velocity), as a companion computer that
    // stamps a camera's frame after δ of processing attaches the autopilot's pose of that
    // instant and sends it (registration's model, FORMAT-REGISTRATION.md §1): its stamp is never
    // ahead of its arrival (which a real-time server would take for a clock ahead, [clock] in
    // the server).
    let start_unix = harrier_link::clock::unix_now();
    let frame = LocalFrame::new(origin);
    let mut next_truth = 0.0;
    let mut stamped_later: Vec<(usize, DetectionScan)> = Vec::new();
    let worker = Worker::spawn("harrier-sim-sensors".into(), move || {
        let t = start.elapsed().as_secs_f64() * speedup;
        world.advance(t);
        let (poses, gimbals): (Vec<_>, Vec<_>) = vehicles
            .iter()
            .map(|v| {
                let v = v.lock().unwrap_or_else(PoisonError::into_inner);
                (platform_pose(&v), v.gimbal_direction())
            })
            .unzip();
        for (i, (id, suite)) in suites.iter_mut().enumerate() {
            let pose = &poses[i];
            suite.set_gimbal(gimbals[i]);
            if suite.paints_vehicles() {
                let others = poses.iter().enumerate().filter(|(j, _)| *j != i);
                suite.set_vehicles(others.map(|(_, p)| Vector3::from(p.pos)));
            }
            for mut scan in suite.scan(t, *id, pose, origin, &world) {
                scan.time_unix = Some(skew.read(start_unix, scan.t));
                if scan.t > t {
                    stamped_later.push((i, scan));
                } else {
                    bus.publish_scan(&scan);
                }
            }
        }
        stamped_later.sort_by(|a, b| a.1.t.total_cmp(&b.1.t));
        let due = stamped_later.partition_point(|(_, s)| s.t <= t);
        for (i, mut scan) in stamped_later.drain(..due) {
            scan.platform = pose_at(&poses[i], scan.t - t, &frame);
            bus.publish_scan(&scan);
        }
        if t >= next_truth {
            bus.publish_truth(&TruthSample {
                schema: TRUTH_SCHEMA.into(),
                t,
                time_unix: Some(skew.read(start_unix, t)),
                origin,
                targets: world.truth(),
            });
            next_truth = (t / truth_period).floor() * truth_period + truth_period;
        }
        *c.lock().unwrap_or_else(PoisonError::into_inner) = bus.counters();
        std::thread::sleep(tick);
    })
    .map_err(SensorLoopError::Thread)?;
    Ok(SensorLoopHandle { counters, worker })
}

/// `pose` moved `dt` seconds along its velocity (`dt` ≤ 0: back to a scan's stamp from the pass
/// that publishes it, up to a pass later), its geodetic position with it.
fn pose_at(pose: &PlatformPose, dt: f64, frame: &LocalFrame) -> PlatformPose {
    let pos = Vector3::from(pose.pos) + Vector3::from(pose.vel) * dt;
    PlatformPose {
        pos: pos.into(),
        geodetic: pose.geodetic.map(|_| frame.from_enu(&pos)),
        ..*pose
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::BusConfig;

    #[test]
    fn bad_rates_are_refused_not_panicked_on() {
        let scenario = SimScenario::load("radar").expect("preset");
        for (speedup, truth_hz, what) in [(0.0, 10.0, "speedup"), (1.0, f64::NAN, "truth_hz")] {
            let bus = Bus::open(&BusConfig::default()).expect("session");
            let config = SensorLoopConfig {
                scenario: scenario.clone(),
                seed: 1,
                speedup,
                truth_hz,
                clock: Default::default(),
            };
            let e = spawn(&config, Vec::new(), bus).expect_err(what);
            assert!(e.to_string().starts_with(what), "{e}");
        }
    }
}
