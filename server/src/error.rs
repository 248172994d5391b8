//! Why the service could not start ([`LiveError`]): a leaf the start-up steps share.

use std::net::SocketAddr;

use harrier_engine::EngineError;

use crate::config::ConfigError;
use crate::gcs;

/// Why the service could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The track engine cannot be built.
    #[error("track engine: {0}")]
    Engine(#[from] EngineError),
    /// The API address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The Zenoh session or subscriber cannot be opened.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The MAVLink link cannot start.
    #[error(transparent)]
    Gcs(#[from] gcs::GcsError),
    /// The map's tiles cannot be served: `map.mbtiles` is missing or not an MBTiles file (the
    /// message names the file).
    #[error("map: {0}")]
    Map(String),
    /// A feed the configuration turns on cannot start (its socket cannot be bound).
    #[error("feed {feed}: {message}")]
    Feed {
        /// The feed (its configuration section).
        feed: &'static str,
        /// Why.
        message: String,
    },
}
