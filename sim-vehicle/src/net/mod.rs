//! MAVLink links over UDP and TCP, and the threads that run vehicles on them.
//!
//! A link is described by a connection string:
//!
//! - `udpin:HOST:PORT` binds a UDP socket and answers whoever sends to it (telemetry goes to every
//!   peer seen); `udpout:HOST:PORT` binds an ephemeral port and sends to HOST:PORT.
//! - `tcpin:HOST:PORT` listens and accepts any number of clients, each a peer that gets the
//!   telemetry from the moment it connects; `tcpout:HOST:PORT` connects to a server and reconnects
//!   (every [`TCP_RETRY`]) when the connection fails or drops, without ever blocking the
//!   simulation loop (the connect runs on a short-lived helper thread).
//!
//! Replies go back on the link, and to the peer (address or TCP connection), the request came
//! from, so a GCS and an API client never see each other's replies. Sockets are non-blocking. TCP
//! is a byte stream: each connection keeps a receive buffer and frames are parsed across reads
//! ([`StreamParser`]), so a frame split over several segments waits for its end.
//!
//! With [`LinkConfig::signing`] (MAVLink 2 signing, harrier-link's [`Signer`], one per vehicle
//! for all its links) every frame sent is signed, and every frame received is checked before the
//! vehicle sees it: a refused frame (unsigned in `signed_only` mode, wrong signature, replay) is
//! counted in [`Counters::rejected`](crate::vehicle::Counters::rejected) by reason, never handled,
//! and never makes its UDP sender a peer that gets telemetry. Refusals are logged on stderr at most
//! once per [`REJECT_LOG_EVERY`].
//!
//! Split by concern: [`Link`] (its transports, sending and polling) is in `link.rs`, a TCP
//! connection's buffers in `tcp.rs`, the vehicle's thread ([`spawn`], [`SimHandle`]) in `run.rs`
//! and one tick of it (messages to the vehicle, TIMESYNC answered, telemetry out) in `tick.rs`;
//! many vehicles on a few threads ([`spawn_fleet`], a swarm's load) in `fleet.rs`.

mod config;
mod fleet;
mod link;
mod received;
mod run;
mod tcp;
#[cfg(test)]
mod tests;
mod tick;

pub use config::{LinkConfig, LinkError};
pub use fleet::{FleetCounters, FleetHandle, spawn_fleet};
pub use harrier_link::frame::{Endpoint, EndpointError, StreamParser};
pub use harrier_link::signing::{Rejection, Rejections, Signer, Signing};
pub use link::{Link, TCP_RETRY};
pub use run::{REJECT_LOG_EVERY, SimHandle, spawn};
