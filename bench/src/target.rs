//! The server a run loads ([`Target`]) and free loopback ports for its Zenoh session and its
//! GCS link.

use std::net::SocketAddr;

use anyhow::Context as _;

use super::rest::Api;

/// A Zenoh TCP endpoint on a loopback port that is free now.
pub(super) fn free_loopback_endpoint() -> anyhow::Result<String> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("no free loopback port for a Zenoh endpoint")?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// A loopback UDP address that is free now (the GCS link of a server this tool starts).
pub(super) fn free_loopback_udp() -> anyhow::Result<SocketAddr> {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .context("no free loopback UDP port for the GCS link")
}

/// The server a run loads.
#[derive(Debug)]
pub(super) struct Target {
    /// Its REST API.
    pub(super) api: Api,
    /// Its Zenoh endpoints.
    pub(super) zenoh: Vec<String>,
    /// Its base URL.
    pub(super) url: String,
    /// The process whose resident memory is sampled (`--server-pid`).
    pub(super) rss_pid: Option<u32>,
    /// Whether it runs in this process.
    pub(super) in_process: bool,
    /// Whether this tool configured it (in this process or as its child): the run's server
    /// options apply.
    pub(super) configured: bool,
    /// Its GCS link (UDP), when the vehicles fly (`--mavlink`).
    pub(super) gcs: Option<SocketAddr>,
}
