//! The formats the field already runs, each an actor of its own beside the tracker, with its
//! own bounded queue, its counters ([`FeedCounters`], on `/metrics` as
//! `harrier_feed_events_total`) and its section of the configuration, off by default. An output
//! reads the tracker's latest snapshot (a `watch`, so it never holds the tracker up) and speaks
//! one format to the outside; an input keeps what it hears apart from the ground tracks and
//! shows it on a `watch` of its own. The encodings and decodings are pure and live in
//! [`crate::wire`]; this module only names the actors and starts the ones the configuration
//! turns on.
//!
//! - `adsb`: manned aircraft from an ADS-B receiver's SBS-1 output (`[adsb]`), tracked per
//!   address, on a `watch` the API reads (`GET /api/v1/aircraft`).
//! - [`adsb_out`]: the confirmed tracks as ADSB_VEHICLE traffic to the MAVLink router's clients
//!   (`mavlink.tracks_hz`), sent through the link (started with the link, in `control`).
//! - `asterix`: the tracks as EUROCONTROL ASTERIX CAT062 system track messages over UDP
//!   (`[asterix]`), unicast or multicast.
//! - `cot`: every confirmed track as a Cursor-on-Target event for TAK (`[cot]`), XML or TAK
//!   protobuf, over UDP (multicast or unicast), TCP and TLS.
//! - `foxglove`: the tracks, detections and vehicles on a Foxglove WebSocket server
//!   (`[foxglove]`), at `foxglove.listen` ([`crate::LiveServer::foxglove_addr`]), and into a
//!   live MCAP file.

mod adsb;
pub mod adsb_out;
mod asterix;
mod cot;
mod counters;
mod foxglove;
mod throttle;

use std::net::SocketAddr;
use std::sync::Arc;

use tokio::sync::{broadcast, watch};
use tokio::task::JoinHandle;

use crate::config::Config;
use crate::error::LiveError;
use crate::tracker::{ScanEvents, Snapshot};
use crate::wire::aircraft::AircraftList;

pub use counters::FeedCounters;

/// What every feed gets: the tracker's snapshots, the server's frame, the counters and the
/// service's stop signal.
#[derive(Debug, Clone)]
pub(crate) struct FeedContext {
    /// The tracker's latest snapshot.
    pub(crate) snapshot: watch::Receiver<Arc<Snapshot>>,
    /// The tracker's scan events, for a feed that wants every scan (subscribe at start).
    pub(crate) events: broadcast::Sender<Arc<ScanEvents>>,
    /// The server's ENU frame (its origin is the configuration's `frame.origin`).
    pub(crate) frame: harrier_link::geo::LocalFrame,
    /// The feeds' counters.
    pub(crate) counters: Arc<FeedCounters>,
    /// Set once when the service stops.
    pub(crate) stop: watch::Receiver<bool>,
}

/// The running feeds.
#[derive(Debug)]
pub(crate) struct Feeds {
    /// The ADS-B aircraft (an empty list, feed `off`, unless `[adsb]` is on).
    pub(crate) aircraft: watch::Receiver<Arc<AircraftList>>,
    /// The address of the Foxglove WebSocket server, when `foxglove.enabled`.
    pub(crate) foxglove: Option<SocketAddr>,
    /// One task per feed the configuration turns on; they end at `stop`.
    tasks: Vec<(&'static str, JoinHandle<()>)>,
}

impl Feeds {
    /// Starts every feed the configuration turns on. Fails when one cannot start (an address
    /// that cannot be bound): a feed the operator asked for is not silently missing.
    pub(crate) async fn spawn(config: &Config, ctx: &FeedContext) -> Result<Self, LiveError> {
        let mut tasks = Vec::new();
        let (aircraft_tx, aircraft) = watch::channel(Arc::new(AircraftList::default()));
        if config.adsb.enabled {
            let task = adsb::run(config.adsb.clone(), ctx.clone(), aircraft_tx);
            tasks.push(("adsb", tokio::spawn(task)));
        }
        if config.asterix.enabled {
            let (socket, dest) =
                asterix::bind(&config.asterix)
                    .await
                    .map_err(|message| LiveError::Feed {
                        feed: "asterix",
                        message,
                    })?;
            let task = asterix::run(config.asterix.clone(), ctx.clone(), socket, dest);
            tasks.push(("asterix", tokio::spawn(task)));
        }
        if config.cot.enabled {
            let task = cot::start(config.cot.clone(), ctx.clone())
                .await
                .map_err(|message| LiveError::Feed {
                    feed: "cot",
                    message,
                })?;
            tasks.push(("cot", tokio::spawn(task)));
        }
        let mut foxglove = None;
        if config.foxglove.on() {
            let (task, addr) =
                foxglove::start(&config.foxglove, config.frame.plane_z, ctx.clone()).await?;
            tasks.push(("foxglove", task));
            foxglove = addr;
        }
        Ok(Self {
            aircraft,
            foxglove,
            tasks,
        })
    }

    /// Waits for the feeds, which end once `stop` is set.
    pub(crate) async fn join(self) {
        for (name, t) in self.tasks {
            if let Err(e) = t.await {
                tracing::warn!(feed = name, "the feed ended abnormally: {e}");
            }
        }
    }
}
