//! The server a run loads ([`Target`]) and a free loopback endpoint for its Zenoh session.

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
}
