//! ADS-B in: a TCP client of an ADS-B receiver's BaseStation (SBS-1) output (dump1090, readsb:
//! port 30003) or, with `adsb.format = "beast"`, its Beast binary output (port 30005). Every
//! SBS-1 line is parsed ([`crate::wire::sbs`]); every Beast frame is split from the stream
//! ([`crate::wire::beast`]) and its Mode S message decoded ([`crate::wire::mode_s`]) into the
//! same report. Each report is stamped with its arrival time and applied to the aircraft's own
//! track ([`IdentifiedTracks`], keyed by the 24-bit address); twice a second the aircraft silent
//! for `adsb.stale_s` are dropped and the list ([`AircraftList`]) is published on a `watch` for
//! the API and the page.
//!
//! The socket is this actor's queue: it reads as fast as lines or frames come (a few µs each)
//! and TCP holds the receiver back, so nothing is dropped. A malformed line (not UTF-8, longer
//! than [`MAX_LINE`], refused by the parser) or Beast frame (bytes outside a frame, an unknown
//! type, cut short, an extended squitter in a short frame, a bad callsign character) is counted
//! (`malformed`) and skipped, and logged at most once per 5 s. A lost connection is retried with
//! doubling waits up to `adsb.reconnect_max_s`; the tracks are kept meanwhile (and age out).
//!
//! Counters (`harrier_feed_events_total{feed="adsb"}`): `lines` (SBS-1), `frames` (Beast),
//! `malformed`, `crc_failed` (Beast: a DF17/18 whose parity fails), `cpr_wait` (Beast: a position
//! message waiting for its even/odd pair), `cpr_failed` (Beast: a pair that does not decode),
//! `other` (valid non-`MSG` lines; Mode A/C and Mode S messages not used), `started`, `updated`,
//! `gated`, `late`, `no_track`, `reset`, `aged_out`, `connects`, `connect_errors`,
//! `disconnects`.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use harrier_core::tracker::identified::{IdentifiedTracks, Outcome, Report};
use harrier_link::geo::{Geodetic, LocalFrame};
use nalgebra::Vector3;
use tokio::net::TcpStream;
use tokio::sync::watch;

use super::throttle::Throttle;
use super::{FeedContext, FeedCounters};
use crate::clock::unix_now;
use crate::config::{AdsbConfig, AdsbFormat};
use crate::wire::aircraft::{AdsbFeedState, AircraftInfo, AircraftList, aircraft_dto};
use crate::wire::beast::{BeastDecoder, BeastFrame, FrameKind, Refusal};
use crate::wire::mode_s::{AdsbDecoder, Decoded, ModeSError};
use crate::wire::sbs::{self, SbsReport};

/// The counters' feed label.
const FEED: &str = "adsb";
/// The longest line kept, bytes (an SBS-1 line is under 200).
const MAX_LINE: usize = 1024;
/// Feet to metres.
const FT: f64 = 0.3048;
/// Knots to m/s.
const KT: f64 = 1852.0 / 3600.0;

/// The aircraft and what was heard of them.
struct Aircraft {
    tracks: IdentifiedTracks<u32>,
    info: BTreeMap<u32, AircraftInfo>,
    /// Last reported altitude per aircraft, m (for a position without one).
    altitude: BTreeMap<u32, f64>,
    /// Beast: the Mode S decoder and its CPR memory.
    mode_s: AdsbDecoder,
    frame: LocalFrame,
    counters: Arc<FeedCounters>,
    /// `adsb.stale_s`.
    stale_s: f64,
}

impl Aircraft {
    /// Parses and applies one line that arrived at `now` (UNIX s).
    fn line(&mut self, bytes: &[u8], now: f64, log: &mut Throttle) {
        if bytes.iter().all(u8::is_ascii_whitespace) {
            return;
        }
        self.counters.add(FEED, "lines", 1);
        let text = match std::str::from_utf8(bytes) {
            Ok(t) => t.trim_end_matches('\r'),
            Err(_) => return self.malformed(log, "not UTF-8"),
        };
        match sbs::parse(text) {
            Ok(Some(r)) => self.apply(&r, now),
            Ok(None) => self.counters.add(FEED, "other", 1),
            Err(e) => self.malformed(log, &format!("{e}: {text:.120}")),
        }
    }

    fn malformed(&self, log: &mut Throttle, why: &str) {
        self.counters.add(FEED, "malformed", 1);
        if let Some(suppressed) = log.allow() {
            tracing::warn!(
                feed = FEED,
                suppressed,
                "malformed SBS-1 line skipped: {why}"
            );
        }
    }

    /// Decodes and applies one Beast frame (or counts its refusal) that arrived at `now`.
    fn frame(&mut self, frame: Result<BeastFrame, Refusal>, now: f64, log: &mut Throttle) {
        let frame = match frame {
            Ok(f) => f,
            Err(why) => return self.malformed_frame(log, &why.to_string()),
        };
        self.counters.add(FEED, "frames", 1);
        if frame.kind == FrameKind::ModeAc {
            return self.counters.add(FEED, "other", 1);
        }
        match self.mode_s.decode(frame.message(), now) {
            Ok(Decoded::Report(r)) => self.apply(&r, now),
            Ok(Decoded::Pending(r)) => {
                self.counters.add(FEED, "cpr_wait", 1);
                self.apply(&r, now);
            }
            Ok(Decoded::Other) => self.counters.add(FEED, "other", 1),
            Err(ModeSError::Crc) => self.counters.add(FEED, "crc_failed", 1),
            Err(ModeSError::Cpr) => self.counters.add(FEED, "cpr_failed", 1),
            Err(e) => self.malformed_frame(log, &e.to_string()),
        }
    }

    fn malformed_frame(&self, log: &mut Throttle, why: &str) {
        self.counters.add(FEED, "malformed", 1);
        if let Some(suppressed) = log.allow() {
            tracing::warn!(
                feed = FEED,
                suppressed,
                "malformed Beast frame skipped: {why}"
            );
        }
    }

    /// One parsed report: its identity's info, then its position and velocity, if any.
    fn apply(&mut self, r: &SbsReport, now: f64) {
        let key = r.icao | (u32::from(r.non_icao) << 24);
        let info = self.info.entry(key).or_default();
        info.messages += 1;
        info.heard_unix = now;
        if r.callsign.is_some() {
            info.callsign.clone_from(&r.callsign);
        }
        info.squawk = r.squawk.or(info.squawk);
        info.on_ground = r.on_ground.or(info.on_ground);
        if let Some(ft) = r.altitude_ft {
            self.altitude.insert(key, ft * FT);
        }
        if let Some((lat, lon)) = r.position {
            // A position without an altitude (a surface position) keeps the last one, else the
            // frame origin's.
            let alt_m = self
                .altitude
                .get(&key)
                .copied()
                .unwrap_or(self.frame.origin().alt_m);
            let geo = Geodetic {
                lat_deg: lat,
                lon_deg: lon,
                alt_m,
            };
            let p = self.frame.to_enu(&geo);
            let outcome = self.tracks.report(key, now, Report::Position(p));
            self.count(outcome);
        }
        if let (Some(gs), Some(track)) = (r.ground_speed_kt, r.track_deg) {
            // Ground velocity in the aircraft's own ENU axes, turned into the server's.
            let (s, c) = track.to_radians().sin_cos();
            let local = Vector3::new(
                gs * KT * s,
                gs * KT * c,
                r.vertical_rate_fpm.unwrap_or(0.0) * FT / 60.0,
            );
            let here = self.tracks.get(&key).map(|t| {
                self.frame
                    .from_enu(&t.state.mean.fixed_rows::<3>(0).into_owned())
            });
            let v = here.map_or(local, |g| {
                LocalFrame::new(g).rotation_to(&self.frame) * local
            });
            let outcome = self.tracks.report(key, now, Report::Velocity(v));
            self.count(outcome);
        }
    }

    fn count(&self, outcome: Outcome) {
        let event = match outcome {
            Outcome::Started => "started",
            Outcome::Updated => "updated",
            Outcome::Gated => "gated",
            Outcome::Late => "late",
            Outcome::NoTrack => "no_track",
            Outcome::Reset => "reset",
        };
        self.counters.add(FEED, event, 1);
    }

    /// Drops the silent aircraft, then the list as the API sends it.
    fn list(&mut self, now: f64, feed: AdsbFeedState) -> AircraftList {
        let aged = self.tracks.age_out(now);
        if aged > 0 {
            self.counters.add(FEED, "aged_out", aged as u64);
        }
        // What an aircraft without a track yet said (its callsign before its first position) is
        // kept as long as a track would be.
        let (tracks, stale) = (&self.tracks, self.stale_s);
        self.info
            .retain(|k, i| tracks.get(k).is_some() || now - i.heard_unix <= stale);
        let info = &self.info;
        self.altitude.retain(|k, _| info.contains_key(k));
        self.mode_s.forget_before(now - stale);
        let aircraft = tracks
            .iter()
            .filter_map(|(&k, t)| {
                let info = self.info.get(&k).cloned().unwrap_or_default();
                aircraft_dto(k, t, &info, &self.frame, now)
            })
            .collect();
        AircraftList {
            time_unix: now,
            feed,
            aircraft,
        }
    }
}

/// Splits `buf` into complete lines, applying each; keeps the unfinished tail in `buf`. A tail
/// longer than [`MAX_LINE`] is dropped as malformed and the rest of its line skipped
/// (`discarding`).
fn split_lines(
    buf: &mut Vec<u8>,
    discarding: &mut bool,
    aircraft: &mut Aircraft,
    now: f64,
    log: &mut Throttle,
) {
    let mut start = 0;
    while let Some(n) = buf[start..].iter().position(|&b| b == b'\n') {
        let line = &buf[start..start + n];
        if std::mem::take(discarding) {
            // The end of an over-long line, already counted.
        } else if line.len() > MAX_LINE {
            aircraft.counters.add(FEED, "lines", 1);
            aircraft.malformed(log, "line too long");
        } else {
            aircraft.line(line, now, log);
        }
        start += n + 1;
    }
    buf.drain(..start);
    if buf.len() > MAX_LINE {
        if !*discarding {
            aircraft.counters.add(FEED, "lines", 1);
            aircraft.malformed(log, "line too long");
        }
        *discarding = true;
        buf.clear();
    }
}

/// Decodes the Beast frames of `bytes` (the decoder keeps a frame split between reads) and
/// applies each.
fn beast_frames(
    decoder: &mut BeastDecoder,
    bytes: &[u8],
    aircraft: &mut Aircraft,
    now: f64,
    log: &mut Throttle,
) {
    decoder.push(bytes, |f| aircraft.frame(f, now, log));
}

/// Runs the feed until `stop`: connects, reads, tracks, publishes on `out`.
pub(super) async fn run(
    config: AdsbConfig,
    ctx: FeedContext,
    out: watch::Sender<Arc<AircraftList>>,
) {
    let filter = match IdentifiedTracks::new(config.filter()) {
        Ok(t) => t,
        Err(e) => {
            // Checked with the configuration: not reached.
            tracing::error!(feed = FEED, "the ADS-B feed cannot start: {e}");
            return;
        }
    };
    let mut aircraft = Aircraft {
        tracks: filter,
        info: BTreeMap::new(),
        altitude: BTreeMap::new(),
        mode_s: AdsbDecoder::default(),
        frame: ctx.frame,
        counters: Arc::clone(&ctx.counters),
        stale_s: config.stale_s,
    };
    let mut stop = ctx.stop;
    let mut log = Throttle::default();
    let mut tick = tokio::time::interval(Duration::from_millis(500));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let max_wait = Duration::from_secs_f64(config.reconnect_max_s);
    let mut wait = Duration::from_millis(500);
    loop {
        // Connect, publishing the list meanwhile.
        let connect = TcpStream::connect(config.address.as_str());
        tokio::pin!(connect);
        let stream = loop {
            tokio::select! {
                r = &mut connect => break r,
                _ = tick.tick() => {
                    out.send_replace(Arc::new(aircraft.list(unix_now(), AdsbFeedState::Connecting)));
                }
                () = crate::gcs::transport::stopped(&mut stop) => return,
            }
        };
        let stream = match stream {
            Ok(s) => s,
            Err(e) => {
                ctx.counters.add(FEED, "connect_errors", 1);
                if let Some(suppressed) = log.allow() {
                    tracing::warn!(
                        feed = FEED,
                        address = config.address,
                        suppressed,
                        "cannot connect to the ADS-B receiver: {e}; again in {wait:?}"
                    );
                }
                let pause = tokio::time::sleep(wait);
                tokio::pin!(pause);
                loop {
                    tokio::select! {
                        () = &mut pause => break,
                        _ = tick.tick() => {
                            out.send_replace(Arc::new(aircraft.list(unix_now(), AdsbFeedState::Connecting)));
                        }
                        () = crate::gcs::transport::stopped(&mut stop) => return,
                    }
                }
                wait = (wait * 2).min(max_wait);
                continue;
            }
        };
        ctx.counters.add(FEED, "connects", 1);
        tracing::info!(
            feed = FEED,
            address = config.address,
            format = ?config.format,
            "connected to the ADS-B receiver"
        );
        wait = Duration::from_millis(500);
        out.send_replace(Arc::new(
            aircraft.list(unix_now(), AdsbFeedState::Connected),
        ));
        let mut buf = Vec::with_capacity(2 * MAX_LINE);
        let mut chunk = vec![0_u8; 64 * 1024];
        let mut discarding = false;
        let mut beast = BeastDecoder::default();
        loop {
            tokio::select! {
                r = stream.readable() => {
                    if let Err(e) = r {
                        tracing::warn!(feed = FEED, "ADS-B receiver connection: {e}");
                        break;
                    }
                    match stream.try_read(&mut chunk) {
                        Ok(0) => {
                            tracing::warn!(feed = FEED, "the ADS-B receiver closed the connection");
                            break;
                        }
                        Ok(n) => match config.format {
                            AdsbFormat::Sbs => {
                                buf.extend_from_slice(&chunk[..n]);
                                split_lines(&mut buf, &mut discarding, &mut aircraft, unix_now(), &mut log);
                            }
                            AdsbFormat::Beast => {
                                beast_frames(&mut beast, &chunk[..n], &mut aircraft, unix_now(), &mut log);
                            }
                        },
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                        Err(e) => {
                            tracing::warn!(feed = FEED, "ADS-B receiver connection: {e}");
                            break;
                        }
                    }
                }
                _ = tick.tick() => {
                    out.send_replace(Arc::new(aircraft.list(unix_now(), AdsbFeedState::Connected)));
                }
                () = crate::gcs::transport::stopped(&mut stop) => return,
            }
        }
        ctx.counters.add(FEED, "disconnects", 1);
        out.send_replace(Arc::new(
            aircraft.list(unix_now(), AdsbFeedState::Connecting),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    fn aircraft() -> Aircraft {
        Aircraft {
            tracks: IdentifiedTracks::new(AdsbConfig::default().filter()).unwrap(),
            info: BTreeMap::new(),
            altitude: BTreeMap::new(),
            mode_s: AdsbDecoder::default(),
            frame: LocalFrame::new(DEFAULT_ORIGIN),
            counters: Arc::default(),
            stale_s: 60.0,
        }
    }

    #[test]
    fn lines_split_across_reads_and_broken_lines_are_counted() {
        let mut a = aircraft();
        let mut log = Throttle::default();
        let mut buf = Vec::new();
        let mut discarding = false;
        let id = b"MSG,1,1,1,4CA2D6,1,,,,,RYR4TX,,,,,,,,,,,0\r\n";
        let pos = b"MSG,3,1,1,4CA2D6,1,,,,,,37000,,,47.40,8.55,,,0,0,0,0\n";
        let mut all = Vec::new();
        all.extend_from_slice(id);
        all.extend_from_slice(b"MSG,3,junk\n\n");
        all.extend_from_slice(pos);
        all.extend_from_slice(&[0xff, 0xfe, b'\n']);
        for piece in all.chunks(7) {
            buf.extend_from_slice(piece);
            split_lines(&mut buf, &mut discarding, &mut a, 1000.0, &mut log);
        }
        assert!(buf.is_empty());
        let c = Arc::clone(&a.counters);
        assert_eq!(c.get(FEED, "lines"), 4);
        assert_eq!(c.get(FEED, "malformed"), 2);
        assert_eq!(c.get(FEED, "started"), 1);
        // An over-long line is one malformed line, however many reads it spans.
        for _ in 0..3 {
            buf.extend_from_slice(&[b'A'; MAX_LINE]);
            split_lines(&mut buf, &mut discarding, &mut a, 1000.0, &mut log);
        }
        buf.extend_from_slice(b"AAA\n");
        buf.extend_from_slice(pos);
        split_lines(&mut buf, &mut discarding, &mut a, 1001.0, &mut log);
        assert_eq!(c.get(FEED, "malformed"), 3);
        assert_eq!(c.get(FEED, "lines"), 6);
        assert_eq!(c.get(FEED, "updated"), 1);
        let list = a.list(1001.0, AdsbFeedState::Connected);
        assert_eq!(list.aircraft.len(), 1);
        let ac = &list.aircraft[0];
        assert_eq!(ac.callsign.as_deref(), Some("RYR4TX"));
        assert!((ac.lat_deg - 47.40).abs() < 1e-6 && (ac.lon_deg - 8.55).abs() < 1e-6);
        assert!((ac.altitude_m - 37_000.0 * FT).abs() < 0.01);
        // Silent for stale_s: aged out.
        assert!(
            a.list(1001.0 + 61.0, AdsbFeedState::Connected)
                .aircraft
                .is_empty()
        );
        assert_eq!(c.get(FEED, "aged_out"), 1);
    }

    #[test]
    fn beast_frames_split_across_reads_become_reports_and_refusals_are_counted() {
        use crate::wire::beast::encode;
        let hex = |s: &str| -> Vec<u8> {
            (0..s.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
                .collect()
        };
        let mut a = aircraft();
        let mut log = Throttle::default();
        let mut stream = b"joined mid-frame".to_vec();
        // The Riddle's examples: an identification, a velocity, an odd then even position.
        stream.extend(encode(1, 0x1a, &hex("8D4840D6202CC371C32CE0576098")));
        stream.extend(encode(2, 9, &hex("8D485020994409940838175B284F")));
        stream.extend(encode(3, 9, &hex("8D40621D58C386435CC412692AD6")));
        // One bit off: the parity fails.
        stream.extend(encode(4, 9, &hex("8D40621D58C382D690C8AC2863A6")));
        stream.extend(encode(5, 9, &hex("8D40621D58C382D690C8AC2863A7")));
        // A Mode A/C reply and a DF11 all-call reply: valid, not used.
        stream.extend(encode(6, 9, &[0x12, 0x34]));
        stream.extend(encode(7, 9, &hex("5D484FDEA248F5")));
        let mut decoder = BeastDecoder::default();
        for piece in stream.chunks(5) {
            beast_frames(&mut decoder, piece, &mut a, 1000.0, &mut log);
        }
        let c = Arc::clone(&a.counters);
        let counts = [
            "frames",
            "malformed",
            "crc_failed",
            "cpr_wait",
            "other",
            "started",
            "no_track",
        ]
        .map(|e| c.get(FEED, e));
        // The velocity of 485020 has no track to go to; 40621D's second position starts its.
        assert_eq!(counts, [7, 1, 1, 1, 2, 1, 1]);
        let list = a.list(1000.0, AdsbFeedState::Connected);
        assert_eq!(list.aircraft.len(), 1);
        let ac = &list.aircraft[0];
        assert_eq!(ac.icao, "40621D");
        assert!((ac.lat_deg - 52.257_20).abs() < 1e-5 && (ac.lon_deg - 3.919_37).abs() < 1e-5);
        assert!((ac.altitude_m - 38_000.0 * FT).abs() < 0.01);
        assert_eq!(a.info[&0x48_40D6].callsign.as_deref(), Some("KLM1023"));
    }

    #[test]
    fn a_velocity_report_is_turned_into_the_servers_axes() {
        let mut a = aircraft();
        let mut log = Throttle::default();
        // 1° of longitude east of the origin: its north is turned by ~0.74° from the frame's.
        a.line(
            b"MSG,3,1,1,ABCDEF,1,,,,,,10000,,,47.397742,9.545594,,,0,0,0,0",
            0.0,
            &mut log,
        );
        a.line(b"MSG,4,1,1,ABCDEF,1,,,,,,,200,0,,,0,,,,,0", 0.0, &mut log);
        let list = a.list(0.0, AdsbFeedState::Connected);
        let ac = &list.aircraft[0];
        assert!(
            (ac.course_deg.rem_euclid(360.0)).min(360.0 - ac.course_deg) < 0.5,
            "{}",
            ac.course_deg
        );
        assert!((ac.speed_mps - 200.0 * KT).abs() < 1.0, "{}", ac.speed_mps);
        // In the frame's axes the velocity leans west of its north by the meridians' convergence.
        let heading_in_frame = ac.state[3].atan2(ac.state[4]).to_degrees();
        assert!(
            heading_in_frame < -0.5 && heading_in_frame > -1.0,
            "{heading_in_frame}"
        );
    }
}
