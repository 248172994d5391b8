//! harrier-sim: simulated UAVs that MAVLink clients (pymavlink, MAVSDK, QGroundControl, Harrier's
//! server) can fly as if they were PX4 SITL instances.
//!
//! What the ground station shares with the simulator — geodesy, the Zenoh session configuration,
//! the PX4 mode codec, MAVLink commands and setpoints, the offboard sequence — lives in
//! harrier-link, which both depend on.
//!
//! - [`bus`]: Zenoh session publishing detections and truth (keys and schema of
//!   `harrier_core::detection`).
//! - [`embedded`]: [`embedded::SimWorld`], the whole simulated world (vehicles on real MAVLink
//!   sockets, sensor loop on Zenoh, launches to stations) started inside another process.
//! - [`sensor_loop`]: the live sensor loop: world, sensors of every vehicle, Zenoh publication.
//! - [`vehicle`]: one vehicle — point-mass flight with harrier-core's kinematic limits, PX4 modes,
//!   and the MAVLink 2 protocol (commands, parameters, offboard setpoints, telemetry streams),
//!   independent of sockets and clock.
//! - [`net`]: UDP and TCP links from connection strings and [`net::spawn`], which runs a vehicle on its
//!   own thread over real sockets (bind port 0 and read [`net::SimHandle::local_addrs`] in tests).
//! - [`setup`]: [`setup::SimScenario`], the world, sensors and vehicle behaviour of a
//!   simulation — built-in presets by name or a JSON file.
//! - [`world`]: seeded, deterministic targets (road vehicles, CV/CT segments, the \[BOT\] leader).
//! - [`sensors`]: gimbal cameras and radars of one vehicle ([`sensors::SensorSuite`]) producing
//!   harrier-core's [`DetectionScan`](harrier_core::detection::DetectionScan)s.
//! - [`record`]: `harrier-sim record`, a whole run written as a `gcs-scenario/1` directory.
//!
//! ```no_run
//! use harrier_sim::{net::{spawn, LinkConfig}, vehicle::VehicleConfig};
//! let sim = spawn(VehicleConfig::new(1), &LinkConfig::px4_defaults(1))?;
//! println!("API link on {:?}", sim.local_addrs()[1]);
//! # Ok::<(), harrier_sim::net::LinkError>(())
//! ```

pub mod bus;
pub mod embedded;
pub mod net;
pub mod record;
pub mod sensor_loop;
pub mod sensors;
pub mod setup;
pub mod vehicle;
mod worker;
pub mod world;

pub use mavlink;
