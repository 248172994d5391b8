//! ASTERIX out: every confirmed track (and the tentative ones with `asterix.tentative`) of the
//! tracker's latest snapshot, `asterix.hz` times a second, as EUROCONTROL ASTERIX CAT062
//! system track records ([`crate::wire::asterix`]) in data blocks of at most
//! [`MAX_BLOCK`] octets, one per UDP datagram, to `asterix.destination` (unicast or a multicast
//! group).
//!
//! The time of track information is the estimate's time (`t`, the tracker's time line: UNIX
//! time when the sources stamp their scans with `time_unix`, as they should) since UTC
//! midnight. A track's first record on this feed carries TSB (I062/080); once it has left the
//! snapshot (deleted), its last estimate is sent once more with TSE, so a receiver ends its
//! track service instead of waiting for it to time out.
//!
//! The socket is non-blocking and never waited on: a datagram the kernel will not take now is
//! counted `dropped`, one that fails is counted `errors`; both are logged at most once per 5 s
//! and the feed goes on with the next. The snapshot is a `watch`, so the tracker is never held
//! up.
//!
//! Counters (`harrier_feed_events_total{feed="asterix"}`): `sent` (records in the datagrams
//! sent), `datagrams`, `dropped`, `errors`, `not_finite` (tracks left out), `ended` (TSE records).

use std::collections::HashSet;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use harrier_engine::{TrackStatus, TrackView};
use tokio::net::UdpSocket;

use super::FeedContext;
use super::throttle::Throttle;
use crate::config::AsterixConfig;
use crate::wire::asterix::{Lifecycle, MAX_BLOCK, Source, data_blocks, track_record};

/// The counters' feed label.
const FEED: &str = "asterix";
/// Seconds in a day.
const DAY_S: f64 = 86_400.0;

/// Resolves `asterix.destination` and binds a UDP socket of its family.
pub(super) async fn bind(config: &AsterixConfig) -> Result<(UdpSocket, SocketAddr), String> {
    let dest = tokio::net::lookup_host(config.destination.as_str())
        .await
        .map_err(|e| format!("cannot resolve {:?}: {e}", config.destination))?
        .next()
        .ok_or_else(|| format!("{:?} resolves to no address", config.destination))?;
    let local: SocketAddr = if dest.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = UdpSocket::bind(local)
        .await
        .map_err(|e| format!("cannot bind a UDP socket: {e}"))?;
    if dest.ip().is_multicast() && dest.is_ipv4() {
        socket
            .set_multicast_ttl_v4(config.multicast_ttl)
            .map_err(|e| format!("cannot set the multicast TTL: {e}"))?;
    }
    Ok((socket, dest))
}

/// Sends the tracks until `stop`.
pub(super) async fn run(
    config: AsterixConfig,
    ctx: FeedContext,
    socket: UdpSocket,
    dest: SocketAddr,
) {
    let source = Source {
        sac: config.sac,
        sic: config.sic,
        service_id: config.service_id,
    };
    let FeedContext {
        mut snapshot,
        frame,
        counters,
        mut stop,
        ..
    } = ctx;
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / config.hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    // The tracks sent at the last tick (ids) and the snapshot's tracks then (in id order).
    let mut sent_before: HashSet<u64> = HashSet::new();
    let mut before: Arc<Vec<TrackView>> = Arc::default();
    let mut log = Throttle::default();
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            () = crate::gcs::transport::stopped(&mut stop) => return,
        }
        let tracks = Arc::clone(&snapshot.borrow_and_update().tracks);
        let mut records = Vec::with_capacity(tracks.len());
        let mut sent_now = HashSet::with_capacity(tracks.len());
        for t in tracks
            .iter()
            .filter(|t| config.tentative || t.status == TrackStatus::Confirmed)
        {
            let life = if sent_before.contains(&t.id) {
                Lifecycle::Update
            } else {
                Lifecycle::First
            };
            // A track stays sent while it is in the snapshot, even when one estimate cannot be
            // encoded.
            sent_now.insert(t.id);
            match track_record(t, &frame, source, t.t.rem_euclid(DAY_S), life) {
                Some(r) => records.push(r),
                None => counters.add(FEED, "not_finite", 1),
            }
        }
        // A track sent before and gone now (deleted): its last estimate once more, with TSE.
        for t in before
            .iter()
            .filter(|t| sent_before.contains(&t.id) && !sent_now.contains(&t.id))
        {
            if let Some(r) = track_record(t, &frame, source, t.t.rem_euclid(DAY_S), Lifecycle::Last)
            {
                records.push(r);
                counters.add(FEED, "ended", 1);
            }
        }
        sent_before = sent_now;
        before = tracks;
        for block in data_blocks(&records, MAX_BLOCK) {
            let failure = match socket.try_send_to(&block.bytes, dest) {
                Ok(_) => {
                    counters.add(FEED, "datagrams", 1);
                    counters.add(FEED, "sent", block.records as u64);
                    continue;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    counters.add(FEED, "dropped", 1);
                    "the socket's buffer is full; datagram dropped".to_owned()
                }
                Err(e) => {
                    counters.add(FEED, "errors", 1);
                    format!("cannot send to {dest}: {e}")
                }
            };
            if let Some(suppressed) = log.allow() {
                tracing::warn!(feed = FEED, suppressed, "{failure}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;
    use crate::tracker::Snapshot;
    use harrier_link::geo::LocalFrame;
    use tokio::sync::watch;

    fn track(id: u64, status: TrackStatus) -> TrackView {
        TrackView {
            id,
            status,
            t: 1_795_430_412.5,
            state: [10.0, 20.0, 0.0, 1.0, 0.0, 0.0],
            cov: Vec::new(),
            cov_dims: Vec::new(),
            updated: true,
            age: 5,
            last_update: 1_795_430_412.5,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    /// The records of one datagram: (track number, I062/080).
    fn records(d: &[u8]) -> Vec<(u16, Vec<u8>)> {
        assert_eq!(d[0], 62);
        assert_eq!(usize::from(u16::from_be_bytes([d[1], d[2]])), d.len());
        // Without a covariance: FSPEC BF 0D 10 (FRN 1, 3-7, 12, 13, 18; no I062/500), then 2+1+3+8+6+4 octets.
        let mut at = 3;
        let mut out = Vec::new();
        while at < d.len() {
            assert_eq!(&d[at..at + 3], &[0xBF, 0x0D, 0x10]);
            at += 3 + 24;
            let number = u16::from_be_bytes([d[at], d[at + 1]]);
            at += 2;
            let n = d[at..]
                .iter()
                .position(|o| o & 1 == 0)
                .expect("I062/080 end")
                + 1;
            out.push((number, d[at..at + n].to_vec()));
            at += n + 2;
        }
        out
    }

    #[tokio::test]
    async fn confirmed_tracks_are_sent_and_their_first_record_says_so() {
        let rx = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let config = AsterixConfig {
            enabled: true,
            hz: 50.0,
            destination: rx.local_addr().unwrap().to_string(),
            ..AsterixConfig::default()
        };
        let (socket, dest) = bind(&config).await.unwrap();
        let snapshot = Snapshot {
            tracks: Arc::new(vec![
                track(3, TrackStatus::Confirmed),
                track(4, TrackStatus::Tentative),
            ]),
            ..Snapshot::default()
        };
        let (snap_tx, snap_rx) = watch::channel(Arc::new(snapshot));
        let (stop_tx, stop) = watch::channel(false);
        let counters = Arc::new(crate::feeds::FeedCounters::default());
        let ctx = FeedContext {
            snapshot: snap_rx,
            events: tokio::sync::broadcast::channel(1).0,
            frame: LocalFrame::new(DEFAULT_ORIGIN),
            counters: Arc::clone(&counters),
            stop,
        };
        let task = tokio::spawn(run(config, ctx, socket, dest));
        let mut buf = [0_u8; 2048];
        let mut got = Vec::new();
        for _ in 0..2 {
            let n = tokio::time::timeout(Duration::from_secs(5), rx.recv(&mut buf))
                .await
                .expect("a datagram within 5 s")
                .unwrap();
            got.push(records(&buf[..n]));
        }
        // Only the confirmed track; TSB (first extent) on its first record only.
        assert_eq!(got[0], vec![(3, vec![0x39, 0x20])]);
        assert_eq!(got[1], vec![(3, vec![0x38])]);
        // Track 3 deleted, 5 confirmed: 3's last record (TSE) once, then 5 alone.
        snap_tx.send_replace(Arc::new(Snapshot {
            tracks: Arc::new(vec![track(5, TrackStatus::Confirmed)]),
            ..Snapshot::default()
        }));
        let mut ended = Vec::new();
        while ended.len() < 2 {
            let n = tokio::time::timeout(Duration::from_secs(5), rx.recv(&mut buf))
                .await
                .expect("a datagram within 5 s")
                .unwrap();
            let r = records(&buf[..n]);
            if r.iter().any(|(id, _)| *id == 5) {
                ended.push(r);
            }
        }
        assert_eq!(ended[0], vec![(5, vec![0x39, 0x20]), (3, vec![0x39, 0x40])]);
        assert_eq!(ended[1], vec![(5, vec![0x38])]);
        assert_eq!(counters.get(FEED, "ended"), 1);
        stop_tx.send_replace(true);
        task.await.unwrap();
        assert!(counters.get(FEED, "sent") >= 2);
        assert_eq!(counters.get(FEED, "errors"), 0);
    }
}
