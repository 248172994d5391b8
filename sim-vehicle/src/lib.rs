//! harrier-sim: simulated UAVs that MAVLink clients (pymavlink, MAVSDK, QGroundControl, Harrier's
//! server) can fly as if they were PX4 SITL instances.
//!
//! - [`geo`]: WGS-84 geodetic ↔ ECEF ↔ local ENU/NED.
//! - [`vehicle`]: one vehicle — point-mass flight with harrier-core's kinematic limits, PX4 modes,
//!   and the MAVLink 2 protocol (commands, parameters, offboard setpoints, telemetry streams),
//!   independent of sockets and clock.
//! - [`net`]: UDP links from connection strings and [`net::spawn`], which runs a vehicle on its
//!   own thread over real sockets (bind port 0 and read [`net::SimHandle::local_addrs`] in tests).
//!
//! ```no_run
//! use harrier_sim::{net::{spawn, LinkConfig}, vehicle::VehicleConfig};
//! let sim = spawn(VehicleConfig::new(1), &LinkConfig::px4_defaults(1))?;
//! println!("API link on {:?}", sim.local_addrs()[1]);
//! # Ok::<(), harrier_sim::net::LinkError>(())
//! ```

pub mod geo;
pub mod net;
pub mod vehicle;

pub use mavlink;
