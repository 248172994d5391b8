//! Many vehicles on a few threads ([`spawn_fleet`], [`FleetHandle`]): a swarm's load.
//!
//! [`spawn`](super::spawn) gives every vehicle a thread that wakes every 5 ms; 255 of them wake
//! 51 000 times a second. A fleet thread runs one tick of each of its vehicles in turn (the same
//! tick as a vehicle's own thread: messages in, TIMESYNC answered, telemetry out) and then
//! sleeps until its next pass, `tick` after the last one started. Telemetry keeps its cadence:
//! a stream is due at its interval and a pass sends what is due, so a message is at most one
//! pass late.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use harrier_link::frame::Endpoint;
use harrier_link::signing::Signing;

use super::config::{LinkConfig, LinkError};
use super::link::Link;
use super::tick::run_once;
use crate::vehicle::{Vehicle, VehicleConfig};
use crate::worker::Worker;

/// Counters of one vehicle of a fleet, updated after each of its ticks.
#[derive(Debug, Default)]
pub struct FleetCounters {
    /// Frames it sent, over all its links ([`Link::frames_sent`]).
    pub frames_sent: AtomicU64,
    /// Ground station HEARTBEATs it received.
    pub gcs_heartbeats: AtomicU64,
}

/// One vehicle of a fleet as its thread holds it.
struct Member {
    vehicle: Arc<Mutex<Vehicle>>,
    links: Vec<Link>,
    counters: Arc<FleetCounters>,
}

/// Vehicles running on fleet threads; stopped when dropped.
#[derive(Debug)]
pub struct FleetHandle {
    vehicles: Vec<Arc<Mutex<Vehicle>>>,
    counters: Vec<Arc<FleetCounters>>,
    local_addrs: Vec<Vec<Option<SocketAddr>>>,
    workers: Vec<Worker>,
}

impl FleetHandle {
    /// Vehicles, in the order given.
    pub fn len(&self) -> usize {
        self.vehicles.len()
    }
    /// Whether the fleet has no vehicle.
    pub fn is_empty(&self) -> bool {
        self.vehicles.is_empty()
    }
    /// Locks vehicle `i` (its thread waits meanwhile).
    pub fn vehicle(&self, i: usize) -> MutexGuard<'_, Vehicle> {
        self.vehicles[i]
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }
    /// Vehicle `i`'s counters.
    pub fn counters(&self, i: usize) -> &FleetCounters {
        &self.counters[i]
    }
    /// Frames sent by every vehicle so far.
    pub fn frames_sent(&self) -> u64 {
        self.counters
            .iter()
            .map(|c| c.frames_sent.load(Ordering::Relaxed))
            .sum()
    }
    /// The bound local address of each link of vehicle `i`, in the order of its
    /// [`LinkConfig::endpoints`].
    pub fn local_addrs(&self, i: usize) -> &[Option<SocketAddr>] {
        &self.local_addrs[i]
    }
    /// Stops every vehicle, waits for the threads, and returns the frames sent in all.
    pub fn stop(mut self) -> u64 {
        for w in &mut self.workers {
            w.stop();
        }
        self.frames_sent()
    }
}

/// Opens every vehicle's links and runs the vehicles on `threads` threads (at least one, at most
/// one per vehicle), each passing over its share of them every `tick`.
pub fn spawn_fleet(
    members: Vec<(VehicleConfig, LinkConfig)>,
    threads: usize,
    tick: Duration,
) -> Result<FleetHandle, LinkError> {
    let start = Instant::now();
    let mut opened = Vec::with_capacity(members.len());
    let mut local_addrs = Vec::with_capacity(members.len());
    for (config, links) in members {
        let signer = links
            .signing
            .as_ref()
            .and_then(Signing::signer)
            .map(Arc::new);
        let open = links
            .endpoints
            .iter()
            .map(|e| Link::open(&Endpoint::parse(e)?, signer.clone()))
            .collect::<Result<Vec<_>, _>>()?;
        local_addrs.push(open.iter().map(Link::local_addr).collect());
        opened.push(Member {
            vehicle: Arc::new(Mutex::new(Vehicle::new(config, 0.0))),
            links: open,
            counters: Arc::default(),
        });
    }
    let vehicles = opened.iter().map(|m| Arc::clone(&m.vehicle)).collect();
    let counters = opened.iter().map(|m| Arc::clone(&m.counters)).collect();
    let threads = threads.clamp(1, opened.len().max(1));
    let per_thread = opened.len().div_ceil(threads).max(1);
    let mut workers = Vec::new();
    let mut rest = opened;
    let mut k = 0;
    while !rest.is_empty() {
        let tail = rest.split_off(per_thread.min(rest.len()));
        let mut mine = std::mem::replace(&mut rest, tail);
        let mut buf = vec![0u8; 65_536];
        let mut next = Instant::now();
        let worker = Worker::spawn(format!("harrier-sim-fleet-{k}"), move || {
            for m in &mut mine {
                let mut v = m.vehicle.lock().unwrap_or_else(PoisonError::into_inner);
                let heard = run_once(
                    &mut v,
                    &mut m.links,
                    &mut buf,
                    start.elapsed().as_secs_f64(),
                );
                m.counters
                    .gcs_heartbeats
                    .fetch_add(heard, Ordering::Relaxed);
                let sent = m.links.iter().map(Link::frames_sent).sum();
                m.counters.frames_sent.store(sent, Ordering::Relaxed);
            }
            // The next pass `tick` after this one's start; no burst after a stall.
            next = (next + tick).max(Instant::now());
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
        })
        .map_err(|e| LinkError::Io {
            what: "spawn a fleet thread for",
            address: format!("{per_thread} vehicles"),
            source: e,
        })?;
        workers.push(worker);
        k += 1;
    }
    Ok(FleetHandle {
        vehicles,
        counters,
        local_addrs,
        workers,
    })
}
