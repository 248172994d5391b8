//! A vehicle on its own thread: [`spawn`] opens its links and runs the loop, [`SimHandle`] holds
//! it, and refused frames are logged at a bounded rate.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use harrier_link::frame::Endpoint;
use harrier_link::signing::{Rejection, Rejections, Signing};

use super::config::{LinkConfig, LinkError};
use super::link::Link;
use super::tick::run_once;
use crate::vehicle::{Vehicle, VehicleConfig};
use crate::worker::Worker;

/// A vehicle running on its own thread; stopped when dropped.
#[derive(Debug)]
pub struct SimHandle {
    vehicle: Arc<Mutex<Vehicle>>,
    local_addrs: Vec<Option<SocketAddr>>,
    worker: Worker,
}

impl SimHandle {
    /// The bound local address of each link, in the order of [`LinkConfig::endpoints`].
    pub fn local_addrs(&self) -> &[Option<SocketAddr>] {
        &self.local_addrs
    }
    /// Locks the vehicle (to inspect it; the simulation waits meanwhile).
    pub fn vehicle(&self) -> MutexGuard<'_, Vehicle> {
        self.vehicle.lock().unwrap_or_else(PoisonError::into_inner)
    }
    /// A shared reference to the vehicle (for other threads: the Zenoh sensor loop).
    pub fn shared(&self) -> Arc<Mutex<Vehicle>> {
        Arc::clone(&self.vehicle)
    }
    /// Stops the vehicle and waits for its thread.
    pub fn stop(mut self) {
        self.worker.stop();
    }
}

/// Wall-clock period of the simulation loop.
const TICK: Duration = Duration::from_millis(5);

/// Shortest time between two log lines about refused frames of one vehicle.
pub const REJECT_LOG_EVERY: Duration = Duration::from_secs(5);

/// Opens the links and runs a vehicle on a new thread.
pub fn spawn(config: VehicleConfig, links: &LinkConfig) -> Result<SimHandle, LinkError> {
    let signer = links
        .signing
        .as_ref()
        .and_then(Signing::signer)
        .map(Arc::new);
    let mut opened = links
        .endpoints
        .iter()
        .map(|e| Link::open(&Endpoint::parse(e)?, signer.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let local_addrs = opened.iter().map(Link::local_addr).collect();
    let start = Instant::now();
    let vehicle = Arc::new(Mutex::new(Vehicle::new(config, 0.0)));
    let v = Arc::clone(&vehicle);
    let mut buf = vec![0u8; 65_536];
    let mut log = RejectLog::default();
    let worker = Worker::spawn(format!("harrier-sim-{}", config.id), move || {
        {
            let mut v = v.lock().unwrap_or_else(PoisonError::into_inner);
            run_once(&mut v, &mut opened, &mut buf, start.elapsed().as_secs_f64());
            log.maybe_log(v.id(), v.counters().rejected, Instant::now());
        }
        std::thread::sleep(TICK);
    })
    .map_err(|e| LinkError::Io {
        what: "spawn thread for",
        address: links.endpoints.join(","),
        source: e,
    })?;
    Ok(SimHandle {
        vehicle,
        local_addrs,
        worker,
    })
}

/// Rate-limited log of refused frames: one line per [`REJECT_LOG_EVERY`] at most, with what was
/// refused since the last line.
#[derive(Debug, Default)]
struct RejectLog {
    logged: Rejections,
    at: Option<Instant>,
}

impl RejectLog {
    fn maybe_log(&mut self, id: u8, now_counts: Rejections, now: Instant) {
        if now_counts == self.logged || self.at.is_some_and(|t| now - t < REJECT_LOG_EVERY) {
            return;
        }
        let new = |r| now_counts.get(r) - self.logged.get(r);
        eprintln!(
            "harrier-sim: vehicle {id}: refused MAVLink frames: unsigned={} bad_signature={} replay={} (totals {} {} {})",
            new(Rejection::Unsigned),
            new(Rejection::BadSignature),
            new(Rejection::Replay),
            now_counts.unsigned,
            now_counts.bad_signature,
            now_counts.replay,
        );
        self.logged = now_counts;
        self.at = Some(now);
    }
}
