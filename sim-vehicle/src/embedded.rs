//! harrier-sim's world embedded in another process: vehicles on real MAVLink sockets, the live
//! sensor loop publishing over a Zenoh session, and optionally a launch to a station per vehicle.
//!
//! This is what `harrier-sim` runs as a program, as a library: `harrier demo` and the end-to-end
//! tests start a [`SimWorld`] beside the ground station in their own process.
//!
//! - Every vehicle runs on its own thread ([`crate::net::spawn`]) with a MAVLink link
//!   `udpin:{mavlink_ip}:0`: it answers whoever sends to [`SimWorld::mavlink_addrs`], so a ground
//!   station can connect to it; with [`WorldConfig::gcs`] set it also sends its telemetry to that
//!   ground station (`udpout:`, as PX4 sends to UDP 14550) and takes its commands.
//! - The live sensor loop ([`crate::sensor_loop`]) scans every vehicle from its real pose and
//!   publishes detections and truth on a session opened from [`WorldConfig::zenoh`].
//! - Each vehicle has its own personality (PX4 or ArduPilot, multirotor or fixed wing,
//!   [`WorldVehicle::personality`]).
//! - A vehicle given a station is launched like a client would do it, through its MAVLink
//!   protocol (harrier-link's [`OffboardSequence`] in its autopilot's sequence: PX4 arm,
//!   takeoff, OFFBOARD velocity setpoints towards the station; ArduPilot GUIDED, arm, takeoff,
//!   targets), and switched to its hold mode once there (PX4 Hold, ArduPilot LOITER), so it
//!   hovers on station (a fixed wing circles it) and takes commands from any client afterwards.
//!   A vehicle without a station stays on the ground at the origin.
//!
//! ```no_run
//! use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
//! use harrier_sim::sensor_loop::SensorLoopConfig;
//! use harrier_sim::setup::SimScenario;
//! let sensor_loop = SensorLoopConfig {
//!     scenario: SimScenario::load("cimm-road")?,
//!     seed: 1,
//!     speedup: 1.0,
//!     truth_hz: 10.0,
//!     clock: Default::default(),
//! };
//! let mut config = WorldConfig::new(sensor_loop);
//! config.vehicles = vec![WorldVehicle::at(1, [0.0, 0.0, 100.0])];
//! config.zenoh.listen = vec!["tcp/127.0.0.1:7448".into()];
//! let world = SimWorld::start(&config)?;
//! println!("vehicle MAVLink links: {:?}", world.mavlink_addrs());
//! world.stop();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use harrier_link::autopilot::{Autopilot, Frame, Personality, VehicleStatus};
use harrier_link::command::set_mode;
use harrier_link::offboard::{OffboardConfig, OffboardSequence, Steer};
use mavlink::dialects::common::{MavMessage, MavResult};
use nalgebra::Vector3;

use crate::bus::{Bus, BusConfig, BusCounters, BusError};
use crate::net::{LinkConfig, LinkError, Signing, SimHandle, spawn};
use crate::sensor_loop::{SensorLoopConfig, SensorLoopError, SensorLoopHandle};
use crate::vehicle::{Vehicle, VehicleConfig};
use crate::worker::Worker;

/// One vehicle of a [`SimWorld`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldVehicle {
    /// MAVLink system id (1–255, unique in the world).
    pub id: u8,
    /// Where to fly after the start: ENU position (m) relative to the scenario's origin, `z` the
    /// height above the ground; `None`: stay on the ground at the origin.
    pub station: Option<[f64; 3]>,
    /// The autopilot and airframe it behaves as.
    pub personality: Personality,
}

impl WorldVehicle {
    /// Vehicle `id`, a PX4 multirotor on the ground at the origin.
    pub fn grounded(id: u8) -> Self {
        Self {
            id,
            station: None,
            personality: Personality::PX4_MULTIROTOR,
        }
    }
    /// Vehicle `id`, a PX4 multirotor flown to `station` (ENU, m).
    pub fn at(id: u8, station: [f64; 3]) -> Self {
        Self {
            station: Some(station),
            ..Self::grounded(id)
        }
    }
    /// This vehicle as another personality.
    pub fn with_personality(self, personality: Personality) -> Self {
        Self {
            personality,
            ..self
        }
    }
}

/// What a [`SimWorld`] runs.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldConfig {
    /// The vehicles; each carries every sensor of the scenario.
    pub vehicles: Vec<WorldVehicle>,
    /// World, sensors, seed, speed-up (also the vehicles') and truth rate.
    pub sensor_loop: SensorLoopConfig,
    /// Address the vehicles' MAVLink (UDP) links bind, each on a free port.
    pub mavlink_ip: IpAddr,
    /// The Zenoh session detections and truth are published on.
    pub zenoh: BusConfig,
    /// A ground station every vehicle also sends its telemetry to (`udpout:` this address, as
    /// PX4 sends to UDP 14550), and takes commands from; `None`: only the `udpin` link.
    pub gcs: Option<SocketAddr>,
    /// MAVLink 2 signing on every vehicle's links (`None`: off).
    pub signing: Option<Signing>,
}

impl WorldConfig {
    /// No vehicles, MAVLink on loopback, a default Zenoh peer session (no endpoints: set
    /// `zenoh.listen` or `zenoh.connect`).
    pub fn new(sensor_loop: SensorLoopConfig) -> Self {
        Self {
            vehicles: Vec::new(),
            sensor_loop,
            mavlink_ip: IpAddr::V4(Ipv4Addr::LOCALHOST),
            zenoh: BusConfig::default(),
            gcs: None,
            signing: None,
        }
    }
}

/// Why a [`SimWorld`] could not start.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// A vehicle id is 0 or appears twice.
    #[error("vehicle id {0} is 0 or not unique")]
    VehicleId(u8),
    /// A station is not a finite position above the ground.
    #[error("vehicle {0}: the station must be finite with z > 0")]
    Station(u8),
    /// A vehicle's link could not be opened.
    #[error("vehicle {id}: {source}")]
    Link {
        /// Vehicle id.
        id: u8,
        /// Why.
        source: LinkError,
    },
    /// The Zenoh session could not be opened.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The sensor loop could not start.
    #[error(transparent)]
    SensorLoop(#[from] SensorLoopError),
    /// The launch thread could not be started.
    #[error("cannot start the launch thread: {0}")]
    Thread(std::io::Error),
}

/// A running world; [`SimWorld::stop`] (or drop) stops it.
#[derive(Debug)]
pub struct SimWorld {
    // Field order is drop order: the loops that read the vehicles go first.
    pilot: Option<Worker>,
    sensor_loop: SensorLoopHandle,
    vehicles: Vec<SimHandle>,
    stationed: Arc<AtomicUsize>,
    with_station: usize,
}

impl SimWorld {
    /// Starts the vehicles, the Zenoh session and the sensor loop, and launches the vehicles
    /// that have a station. Blocks while the session opens: from async code, call it through
    /// `spawn_blocking`.
    pub fn start(config: &WorldConfig) -> Result<Self, WorldError> {
        let mut seen = [false; 256];
        for v in &config.vehicles {
            if v.id == 0 || std::mem::replace(&mut seen[usize::from(v.id)], true) {
                return Err(WorldError::VehicleId(v.id));
            }
            if v.station
                .is_some_and(|s| !(s.iter().all(|x| x.is_finite()) && s[2] > 0.0))
            {
                return Err(WorldError::Station(v.id));
            }
        }
        let started = Instant::now();
        let vehicles = config
            .vehicles
            .iter()
            .map(|v| {
                let vc = VehicleConfig {
                    id: v.id,
                    origin: config.sensor_loop.scenario.origin,
                    speedup: config.sensor_loop.speedup,
                    clock: config.sensor_loop.clock,
                    ..VehicleConfig::new(v.id)
                }
                .with_personality(v.personality);
                let mut endpoints =
                    vec![format!("udpin:{}", SocketAddr::new(config.mavlink_ip, 0))];
                endpoints.extend(config.gcs.map(|g| format!("udpout:{g}")));
                let link = LinkConfig {
                    endpoints,
                    signing: config.signing.clone(),
                };
                spawn(vc, &link).map_err(|source| WorldError::Link { id: v.id, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let bus = Bus::open(&config.zenoh)?;
        let sensor_loop = crate::sensor_loop::spawn(
            &config.sensor_loop,
            vehicles.iter().map(SimHandle::shared).collect(),
            bus,
        )?;
        let mut pilots: Vec<Pilot> = config
            .vehicles
            .iter()
            .zip(&vehicles)
            .filter_map(|(v, h)| {
                v.station.map(|s| {
                    // ArduPilot: take off straight to the station's height (a fixed wing to its
                    // TKOFF_ALT); PX4 to its MIS_TAKEOFF_ALT, then up with the setpoints.
                    let height = (v.personality.autopilot == Autopilot::ArduPilot
                        && v.personality.frame == Frame::Multirotor)
                        .then_some(s[2] as f32);
                    Pilot {
                        vehicle: h.shared(),
                        station: Vector3::from(s),
                        sequence: OffboardSequence::new(
                            v.id,
                            v.personality,
                            OffboardConfig::new(height, None),
                        ),
                        state: PilotState::Launching,
                    }
                })
            })
            .collect();
        let with_station = pilots.len();
        let stationed = Arc::new(AtomicUsize::new(0));
        let pilot = if pilots.is_empty() {
            None
        } else {
            let done = Arc::clone(&stationed);
            let worker = Worker::spawn("harrier-sim-launch".into(), move || {
                // The vehicles' clock: wall seconds since their start (a few µs later than this).
                let now = started.elapsed().as_secs_f64();
                let mut finished = 0;
                for p in &mut pilots {
                    p.fly(now);
                    finished += usize::from(p.state != PilotState::Launching);
                }
                done.store(
                    pilots
                        .iter()
                        .filter(|p| p.state == PilotState::OnStation)
                        .count(),
                    Ordering::Relaxed,
                );
                // Setpoints must keep coming while in OFFBOARD; afterwards nothing is left to do.
                std::thread::sleep(if finished == pilots.len() {
                    IDLE_TICK
                } else {
                    PILOT_TICK
                });
            })
            .map_err(WorldError::Thread)?;
            Some(worker)
        };
        Ok(Self {
            pilot,
            sensor_loop,
            vehicles,
            stationed,
            with_station,
        })
    }

    /// The vehicles' MAVLink links: system id and the UDP address that answers whoever sends.
    pub fn mavlink_addrs(&self) -> Vec<(u8, SocketAddr)> {
        self.vehicles
            .iter()
            .filter_map(|h| {
                let addr = h.local_addrs().first().copied().flatten()?;
                Some((h.vehicle().id(), addr))
            })
            .collect()
    }

    /// The running vehicles (to inspect their state).
    pub fn vehicles(&self) -> &[SimHandle] {
        &self.vehicles
    }

    /// Whether every vehicle given a station has reached it (true when none was).
    pub fn on_station(&self) -> bool {
        self.stationed.load(Ordering::Relaxed) == self.with_station
    }

    /// The sensor loop's publication counters.
    pub fn counters(&self) -> BusCounters {
        self.sensor_loop.counters()
    }

    /// Stops the launches, the sensor loop (closing the Zenoh session) and the vehicles, and
    /// waits for their threads.
    pub fn stop(mut self) {
        if let Some(mut p) = self.pilot.take() {
            p.stop();
        }
        self.sensor_loop.stop();
        for v in self.vehicles {
            v.stop();
        }
    }
}

/// Wall-clock period of the launch loop while a vehicle is in the air under its control
/// (PX4's offboard-loss timeout is 0.5 s).
const PILOT_TICK: Duration = Duration::from_millis(20);
/// Period once every launch is over.
const IDLE_TICK: Duration = Duration::from_millis(200);
/// Gain of the velocity command towards the station (1/s).
const STATION_GAIN: f64 = 0.5;
/// Largest horizontal and vertical speed commanded (m/s).
const MAX_SPEED: [f64; 2] = [12.0, 4.0];
/// On station: within this distance (m) and below this speed (m/s); a fixed wing within its
/// loiter radius of it horizontally and this distance vertically.
const ARRIVED: [f64; 2] = [3.0, 1.0];

#[derive(Debug, Clone, PartialEq)]
enum PilotState {
    Launching,
    OnStation,
    Failed,
}

/// The launch of one vehicle to its station.
struct Pilot {
    vehicle: Arc<Mutex<Vehicle>>,
    station: Vector3<f64>,
    sequence: OffboardSequence,
    state: PilotState,
}

impl Pilot {
    /// One step at vehicle wall time `now`: the sequence's messages delivered to the vehicle and
    /// its replies fed back; its hold mode requested once on station.
    fn fly(&mut self, now: f64) {
        if self.state != PilotState::Launching {
            return;
        }
        let mut v = self.vehicle.lock().unwrap_or_else(PoisonError::into_inner);
        let s = v.state();
        let err = self.station - s.position;
        let arrived = if v.limits().can_hover() {
            err.norm() < ARRIVED[0] && s.velocity.norm() < ARRIVED[1]
        } else {
            err.xy().norm() < 100.0 && err.z.abs() < ARRIVED[0]
        };
        if arrived {
            let id = v.id();
            let hold = v.personality().hold();
            let accepted = v.handle(now, &set_mode(id, hold)).iter().any(|r| {
                matches!(r, MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)
            });
            self.state = if accepted {
                PilotState::OnStation
            } else {
                eprintln!("harrier-sim: vehicle {id}: Hold refused on station");
                PilotState::Failed
            };
            return;
        }
        let mut cmd = err * STATION_GAIN;
        let h = cmd.xy().norm();
        if h > MAX_SPEED[0] {
            cmd.x *= MAX_SPEED[0] / h;
            cmd.y *= MAX_SPEED[0] / h;
        }
        cmd.z = cmd.z.clamp(-MAX_SPEED[1], MAX_SPEED[1]);
        // Messages are delivered at once: the whole launch may happen within one step.
        for _ in 0..4 {
            let status = VehicleStatus {
                armed: v.armed(),
                personality: v.personality(),
                mode: Some(v.mode()),
                at: now,
            };
            let steer = Steer {
                velocity: cmd,
                altitude_amsl_m: Some(v.config().origin.alt_m + self.station.z),
            };
            let height = Some(v.state().position.z);
            let out = match self.sequence.next(now, &status, height, Some(steer)) {
                Ok(out) => out,
                Err(e) => {
                    eprintln!("harrier-sim: vehicle {}: launch failed: {e}", v.id());
                    self.state = PilotState::Failed;
                    return;
                }
            };
            if out.is_empty() {
                return;
            }
            for msg in &out {
                for reply in v.handle(now, msg) {
                    if let Err(e) = self.sequence.handle(now, &reply) {
                        eprintln!("harrier-sim: vehicle {}: launch failed: {e}", v.id());
                        self.state = PilotState::Failed;
                        return;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::SimScenario;

    fn sensor_loop(speedup: f64) -> SensorLoopConfig {
        SensorLoopConfig {
            scenario: SimScenario::load("radar").expect("preset"),
            seed: 1,
            speedup,
            truth_hz: 1.0,
            clock: Default::default(),
        }
    }

    #[test]
    fn bad_vehicles_are_refused() {
        for (vehicles, what) in [
            (vec![WorldVehicle::grounded(0)], "id 0"),
            (
                vec![WorldVehicle::grounded(2), WorldVehicle::grounded(2)],
                "id 2",
            ),
            (vec![WorldVehicle::at(3, [0.0, 0.0, -5.0])], "vehicle 3"),
            (vec![WorldVehicle::at(4, [f64::NAN, 0.0, 5.0])], "vehicle 4"),
        ] {
            let mut c = WorldConfig::new(sensor_loop(1.0));
            c.vehicles = vehicles;
            let e = SimWorld::start(&c).expect_err(what);
            assert!(e.to_string().contains(what), "{e}");
        }
    }

    /// Real threads and sockets: vehicles of every personality launched to their stations get
    /// there and hold (the fixed wings circling them), one stays on the ground, each answers on
    /// its own UDP address.
    #[test]
    fn vehicles_fly_to_their_stations_and_hold() {
        use harrier_link::autopilot::Autopilot;
        let p = |a, f| Personality::new(a, f);
        let stations = [
            ([30.0, -20.0, 40.0], Personality::PX4_MULTIROTOR),
            (
                [-30.0, 10.0, 60.0],
                p(Autopilot::ArduPilot, Frame::Multirotor),
            ),
            ([300.0, 200.0, 80.0], p(Autopilot::Px4, Frame::FixedWing)),
            (
                [-300.0, 200.0, 80.0],
                p(Autopilot::ArduPilot, Frame::FixedWing),
            ),
        ];
        let mut c = WorldConfig::new(sensor_loop(20.0));
        c.vehicles = stations
            .iter()
            .zip(1..)
            .map(|((s, p), id)| WorldVehicle::at(id, *s).with_personality(*p))
            .collect();
        c.vehicles.push(WorldVehicle::grounded(5));
        let world = SimWorld::start(&c).expect("start");
        let addrs = world.mavlink_addrs();
        assert_eq!(
            addrs.iter().map(|a| a.0).collect::<Vec<_>>(),
            [1, 2, 3, 4, 5]
        );
        assert!(
            addrs
                .iter()
                .all(|a| a.1.ip().is_loopback() && a.1.port() != 0)
        );
        let deadline = Instant::now() + Duration::from_secs(60);
        while !world.on_station() {
            assert!(Instant::now() < deadline, "not on station within 60 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        for (h, (station, personality)) in world.vehicles().iter().zip(stations) {
            let v = h.vehicle();
            assert_eq!(v.personality(), personality);
            assert_eq!(v.mode(), v.personality().hold());
            let d = v.state().position - Vector3::from(station);
            if personality.frame == Frame::Multirotor {
                assert!(
                    d.norm() < 5.0,
                    "vehicle {} is {d} m from its station",
                    v.id()
                );
            } else {
                assert!(
                    d.xy().norm() < 150.0 && d.z.abs() < 5.0 && v.state().velocity.norm() > 9.0,
                    "fixed wing {} off its station: {d}, {:?}",
                    v.id(),
                    v.state()
                );
            }
        }
        let v5 = world.vehicles()[4].vehicle().state();
        assert_eq!(v5.position, Vector3::zeros());
        world.stop();
    }
}
