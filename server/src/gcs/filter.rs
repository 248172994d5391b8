//! The router's per-endpoint filters ([`RouterFilter`]): which frames going out to one client
//! endpoint pass, and which frames its clients send on to the vehicles, read from the raw frame's
//! header ([`FrameKey::read`]: MAVLink 1 and 2, no decoding), and the rate limit per message id
//! and source on the way out.
//!
//! The checks and their order follow mavlink-router's filters: outgoing `AllowMsgIdOut`,
//! `BlockMsgIdOut`, `AllowSrcCompOut`, `BlockSrcCompOut`, `AllowSrcSysOut`, `BlockSrcSysOut`,
//! and the same six `…In` lists for the frames an endpoint's clients send
//! (`Endpoint::allowed_by_incoming_filters`): an allow list, when not empty, lets only its
//! members through; a block list stops its members; message ids are checked first, then source
//! components, then source systems. The rate limit (`max_rate_hz`, which mavlink-router does not
//! have) comes last and only on the way out: only a frame that passed the lists uses up its
//! stream's slot.
//!
//! **Rate.** A stream is one (source system, source component, message id) on one endpoint; its
//! frames are let through at most at the configured rate, with the generic cell rate
//! algorithm: each stream has a theoretical time `due` for its next frame; a frame passes when it
//! comes no sooner than `due − period/4`, and then `due = max(due, now) + period`. Over any
//! window of `L` seconds a stream sends at most `1 + (L + period/4)/period` frames (never above
//! the rate in the long run), and a faster source sampled at a multiple of the rate is let
//! through at the full rate despite its jitter (a source at 10 Hz limited to 2 Hz: one frame in
//! five, every 0.5 s; a plain "no sooner than 1/rate after the last one sent" would miss the
//! slot whenever a frame came a millisecond early, and fall to 1.67 Hz).
//!
//! Per frame: at most two hash-set and four bit-set look-ups, and for a limited message a
//! hash-map look-up; nothing is allocated but when a stream is first seen (at most
//! [`MAX_STREAMS`] per endpoint: a full table is emptied, each stream then sends one frame early
//! at most).

use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

/// Most rate-limited streams remembered per endpoint.
pub const MAX_STREAMS: usize = 4096;

/// Which way a frame crosses a router endpoint (the `direction` label of
/// `harrier_router_filtered_total`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// From the vehicles (and the ground station) to the endpoint's clients.
    Out,
    /// From the endpoint's clients to the vehicles.
    In,
}

impl Direction {
    /// Both, in the order of their `usize` values.
    pub const ALL: [Self; 2] = [Self::Out, Self::In];

    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Out => "out",
            Self::In => "in",
        }
    }
}

/// Why a frame did not cross an endpoint (the `reason` label of `harrier_router_filtered_total`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Filtered {
    /// Its message id is in the block list.
    BlockedMsg,
    /// There is an allow list of message ids and its id is not in it.
    NotAllowedMsg,
    /// Its source component is in the block list.
    BlockedComp,
    /// There is an allow list of source components and its component is not in it.
    NotAllowedComp,
    /// Its source system is in the block list.
    BlockedSys,
    /// There is an allow list of source systems and its system is not in it.
    NotAllowedSys,
    /// Sooner than its stream's `max_rate_hz` allows (outgoing only).
    Rate,
}

impl Filtered {
    /// Every reason, in the order of their `usize` values.
    pub const ALL: [Self; 7] = [
        Self::BlockedMsg,
        Self::NotAllowedMsg,
        Self::BlockedComp,
        Self::NotAllowedComp,
        Self::BlockedSys,
        Self::NotAllowedSys,
        Self::Rate,
    ];

    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::BlockedMsg => "blocked_msg",
            Self::NotAllowedMsg => "not_allowed_msg",
            Self::BlockedComp => "blocked_comp",
            Self::NotAllowedComp => "not_allowed_comp",
            Self::BlockedSys => "blocked_sys",
            Self::NotAllowedSys => "not_allowed_sys",
            Self::Rate => "rate",
        }
    }
}

/// What the filters read of a frame: its source and message id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrameKey {
    /// Source system id (MAVLink 2 frames may carry a 32-bit one).
    pub system: u32,
    /// Source component id.
    pub component: u8,
    /// Message id.
    pub message: u32,
}

impl FrameKey {
    /// Reads the header of a raw frame: MAVLink 1 (`0xFE`) or 2 (`0xFD`, with or without the
    /// 32-bit system id flag). `None` when the bytes are too short or start otherwise.
    pub fn read(bytes: &[u8]) -> Option<Self> {
        /// MAVLink 2's incompatibility flag of a 4-byte system id (as the mavlink crate reads it).
        const IFLAG_SYSID32: u8 = 0x02;
        match *bytes {
            [0xFE, _len, _seq, system, component, message, ..] => Some(Self {
                system: system.into(),
                component,
                message: message.into(),
            }),
            [0xFD, _len, incompat, _compat, _seq, ref rest @ ..] => {
                if incompat & IFLAG_SYSID32 != 0 {
                    let [s0, s1, s2, s3, component, m0, m1, m2, ..] = *rest else {
                        return None;
                    };
                    Some(Self {
                        system: u32::from_le_bytes([s0, s1, s2, s3]),
                        component,
                        message: u32::from_le_bytes([m0, m1, m2, 0]),
                    })
                } else {
                    let [system, component, m0, m1, m2, ..] = *rest else {
                        return None;
                    };
                    Some(Self {
                        system: system.into(),
                        component,
                        message: u32::from_le_bytes([m0, m1, m2, 0]),
                    })
                }
            }
            _ => None,
        }
    }
}

/// The allow and block lists of one direction (each empty: no check).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Lists {
    /// Only these message ids pass (empty: any).
    pub allow_msg: Vec<u32>,
    /// These message ids never pass.
    pub block_msg: Vec<u32>,
    /// Only frames of these source components pass (empty: any).
    pub allow_src_comp: Vec<u8>,
    /// Frames of these source components never pass.
    pub block_src_comp: Vec<u8>,
    /// Only frames of these source systems pass (empty: any).
    pub allow_src_sys: Vec<u8>,
    /// Frames of these source systems never pass.
    pub block_src_sys: Vec<u8>,
}

/// One endpoint's filter settings, checked (`[[mavlink.router_filter]]` with its message names
/// resolved). The default lets everything through both ways.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FilterSpec {
    /// The lists of frames going out to the endpoint's clients.
    pub out: Lists,
    /// Most frames per second going out of each (source system, source component) for a
    /// message id.
    pub max_rate_hz: Vec<(u32, f64)>,
    /// The lists of frames the endpoint's clients send to the vehicles.
    pub incoming: Lists,
}

impl FilterSpec {
    /// Whether it lets every frame through both ways.
    pub fn is_open(&self) -> bool {
        *self == Self::default()
    }
}

/// A set of 8-bit ids (systems or components).
#[derive(Debug, Clone, Copy, Default)]
struct IdSet([u64; 4]);

impl IdSet {
    fn of(ids: &[u8]) -> Self {
        let mut s = Self::default();
        for &id in ids {
            s.0[usize::from(id >> 6)] |= 1 << (id & 63);
        }
        s
    }

    fn is_empty(&self) -> bool {
        self.0 == [0; 4]
    }

    fn contains(&self, id: u32) -> bool {
        u8::try_from(id).is_ok_and(|id| self.0[usize::from(id >> 6)] & (1 << (id & 63)) != 0)
    }
}

/// [`Lists`] ready to check.
#[derive(Debug, Clone, Default)]
struct ListFilter {
    allow_msg: HashSet<u32>,
    block_msg: HashSet<u32>,
    allow_comp: IdSet,
    block_comp: IdSet,
    allow_sys: IdSet,
    block_sys: IdSet,
    /// Every list is empty.
    open: bool,
}

impl ListFilter {
    fn new(lists: &Lists) -> Self {
        Self {
            allow_msg: lists.allow_msg.iter().copied().collect(),
            block_msg: lists.block_msg.iter().copied().collect(),
            allow_comp: IdSet::of(&lists.allow_src_comp),
            block_comp: IdSet::of(&lists.block_src_comp),
            allow_sys: IdSet::of(&lists.allow_src_sys),
            block_sys: IdSet::of(&lists.block_src_sys),
            open: *lists == Lists::default(),
        }
    }

    /// The lists in mavlink-router's order: message ids, source components, source systems.
    fn check(&self, key: FrameKey) -> Result<(), Filtered> {
        if self.open {
            return Ok(());
        }
        if !self.allow_msg.is_empty() && !self.allow_msg.contains(&key.message) {
            return Err(Filtered::NotAllowedMsg);
        }
        if self.block_msg.contains(&key.message) {
            return Err(Filtered::BlockedMsg);
        }
        let component = u32::from(key.component);
        if !self.allow_comp.is_empty() && !self.allow_comp.contains(component) {
            return Err(Filtered::NotAllowedComp);
        }
        if self.block_comp.contains(component) {
            return Err(Filtered::BlockedComp);
        }
        if !self.allow_sys.is_empty() && !self.allow_sys.contains(key.system) {
            return Err(Filtered::NotAllowedSys);
        }
        if self.block_sys.contains(key.system) {
            return Err(Filtered::BlockedSys);
        }
        Ok(())
    }
}

/// One router endpoint's filter and its outgoing streams' rate state.
#[derive(Debug, Clone)]
pub struct RouterFilter {
    out: ListFilter,
    incoming: ListFilter,
    /// The period of each limited message id.
    period: HashMap<u32, Duration>,
    /// Each limited stream's theoretical time of its next frame.
    due: HashMap<FrameKey, Instant>,
}

impl RouterFilter {
    /// The filter of `spec` (whose rates are finite and > 0: the configuration checks them).
    pub fn new(spec: &FilterSpec) -> Self {
        Self {
            out: ListFilter::new(&spec.out),
            incoming: ListFilter::new(&spec.incoming),
            period: spec
                .max_rate_hz
                .iter()
                .map(|&(id, hz)| (id, Duration::from_secs_f64(1.0 / hz)))
                .collect(),
            due: HashMap::new(),
        }
    }

    /// Whether the frame `bytes` goes out to the endpoint at `now`; a frame whose header cannot
    /// be read passes (the parser only hands over whole frames).
    pub fn check(&mut self, bytes: &[u8], now: Instant) -> Result<(), Filtered> {
        if self.out.open && self.period.is_empty() {
            return Ok(());
        }
        let Some(key) = FrameKey::read(bytes) else {
            return Ok(());
        };
        self.check_key(key, now)
    }

    /// Whether a frame one of the endpoint's clients sent goes on to the vehicles.
    pub fn check_incoming(&self, key: FrameKey) -> Result<(), Filtered> {
        self.incoming.check(key)
    }

    /// [`check`](Self::check) of a frame's header.
    pub fn check_key(&mut self, key: FrameKey, now: Instant) -> Result<(), Filtered> {
        self.out.check(key)?;
        let Some(&period) = self.period.get(&key.message) else {
            return Ok(());
        };
        match self.due.get_mut(&key) {
            Some(due) => {
                if now + period / 4 < *due {
                    return Err(Filtered::Rate);
                }
                *due = (*due).max(now) + period;
            }
            None => {
                if self.due.len() >= MAX_STREAMS {
                    self.due.clear();
                }
                self.due.insert(key, now + period);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::mavlink::MavHeader;
    use harrier_link::mavlink::dialects::common::{ATTITUDE_DATA, HEARTBEAT_DATA, MavMessage};

    const ATTITUDE: u32 = 30;
    const GPS_RAW_INT: u32 = 24;
    const COMMAND_LONG: u32 = 76;

    fn key(system: u32, component: u8, message: u32) -> FrameKey {
        FrameKey {
            system,
            component,
            message,
        }
    }

    fn header(system_id: u32, component_id: u8) -> MavHeader {
        MavHeader {
            system_id,
            component_id,
            sequence: 7,
        }
    }

    #[test]
    fn reads_v1_and_v2_headers() {
        let msg = MavMessage::ATTITUDE(ATTITUDE_DATA::DEFAULT);
        let mut v1 = Vec::new();
        harrier_link::mavlink::write_v1_msg(&mut v1, header(3, 1), &msg).unwrap();
        assert_eq!(FrameKey::read(&v1), Some(key(3, 1, ATTITUDE)));
        let v2 = harrier_link::frame::encode(header(200, 190), &msg).unwrap();
        assert_eq!(v2[0], 0xFD);
        assert_eq!(FrameKey::read(&v2), Some(key(200, 190, ATTITUDE)));
        // A 24-bit message id, and a 32-bit system id (incompatibility flag 0x02).
        let mut big = vec![0xFD, 0, 0, 0, 0, 9, 1, 0x39, 0x30, 0x00];
        assert_eq!(FrameKey::read(&big), Some(key(9, 1, 12345)));
        big = vec![0xFD, 0, 0x02, 0, 0, 0x00, 0x01, 0, 0, 5, 0x39, 0x30, 0x00];
        assert_eq!(FrameKey::read(&big), Some(key(256, 5, 12345)));
        assert_eq!(FrameKey::read(&[0xFD, 0, 0, 0, 0, 9, 1, 0x39]), None);
        assert_eq!(FrameKey::read(&[0xFE, 9, 0]), None);
        assert_eq!(FrameKey::read(b"garbage"), None);
    }

    #[test]
    fn an_empty_spec_lets_everything_through() {
        let mut f = RouterFilter::new(&FilterSpec::default());
        let now = Instant::now();
        for _ in 0..100 {
            assert_eq!(f.check_key(key(1, 1, ATTITUDE), now), Ok(()));
        }
    }

    /// A filter whose outgoing lists are `out`.
    fn out(out: Lists) -> RouterFilter {
        RouterFilter::new(&FilterSpec {
            out,
            ..FilterSpec::default()
        })
    }

    #[test]
    fn allow_and_block_lists_in_mavlink_router_order() {
        let mut f = out(Lists {
            allow_msg: vec![0, ATTITUDE, GPS_RAW_INT],
            block_msg: vec![GPS_RAW_INT],
            allow_src_sys: vec![1, 2, 255],
            block_src_sys: vec![2],
            ..Lists::default()
        });
        let now = Instant::now();
        assert_eq!(f.check_key(key(1, 1, ATTITUDE), now), Ok(()));
        assert_eq!(f.check_key(key(255, 190, 0), now), Ok(()));
        assert_eq!(
            f.check_key(key(1, 1, 33), now),
            Err(Filtered::NotAllowedMsg)
        );
        assert_eq!(
            f.check_key(key(1, 1, GPS_RAW_INT), now),
            Err(Filtered::BlockedMsg)
        );
        assert_eq!(
            f.check_key(key(3, 1, ATTITUDE), now),
            Err(Filtered::NotAllowedSys)
        );
        assert_eq!(
            f.check_key(key(2, 1, ATTITUDE), now),
            Err(Filtered::BlockedSys)
        );
        // A 32-bit system id is in no list of 8-bit ones.
        assert_eq!(
            f.check_key(key(257, 1, 0), now),
            Err(Filtered::NotAllowedSys)
        );
        let mut f = out(Lists {
            block_src_sys: vec![0, 63, 64, 255],
            ..Lists::default()
        });
        for s in [0, 63, 64, 255] {
            assert_eq!(
                f.check_key(key(s, 1, 0), now),
                Err(Filtered::BlockedSys),
                "{s}"
            );
        }
        for s in [1, 62, 65, 128, 254, 256, 319] {
            assert_eq!(f.check_key(key(s, 1, 0), now), Ok(()), "{s}");
        }
    }

    #[test]
    fn components_are_checked_between_messages_and_systems() {
        let now = Instant::now();
        // A camera (component 100) and the autopilot (1) of vehicle 1; the ground station's 190.
        let mut f = out(Lists {
            block_msg: vec![GPS_RAW_INT],
            allow_src_comp: vec![1, 190],
            block_src_sys: vec![3],
            ..Lists::default()
        });
        assert_eq!(f.check_key(key(1, 1, ATTITUDE), now), Ok(()));
        assert_eq!(f.check_key(key(255, 190, 0), now), Ok(()));
        assert_eq!(
            f.check_key(key(1, 100, ATTITUDE), now),
            Err(Filtered::NotAllowedComp)
        );
        // Message ids come first, systems last.
        assert_eq!(
            f.check_key(key(1, 100, GPS_RAW_INT), now),
            Err(Filtered::BlockedMsg)
        );
        assert_eq!(
            f.check_key(key(3, 100, ATTITUDE), now),
            Err(Filtered::NotAllowedComp)
        );
        assert_eq!(
            f.check_key(key(3, 1, ATTITUDE), now),
            Err(Filtered::BlockedSys)
        );
        let mut f = out(Lists {
            block_src_comp: vec![0, 100, 255],
            ..Lists::default()
        });
        for c in [0, 100, 255] {
            assert_eq!(
                f.check_key(key(1, c, 0), now),
                Err(Filtered::BlockedComp),
                "{c}"
            );
        }
        for c in [1, 99, 101, 190, 254] {
            assert_eq!(f.check_key(key(1, c, 0), now), Ok(()), "{c}");
        }
    }

    #[test]
    fn incoming_lists_apply_only_to_what_the_clients_send() {
        let now = Instant::now();
        let mut f = RouterFilter::new(&FilterSpec {
            incoming: Lists {
                block_msg: vec![COMMAND_LONG],
                allow_src_sys: vec![255, 200],
                block_src_comp: vec![191],
                ..Lists::default()
            },
            ..FilterSpec::default()
        });
        assert_eq!(f.check_incoming(key(255, 190, 0)), Ok(()));
        assert_eq!(
            f.check_incoming(key(255, 190, COMMAND_LONG)),
            Err(Filtered::BlockedMsg)
        );
        assert_eq!(
            f.check_incoming(key(200, 191, 0)),
            Err(Filtered::BlockedComp)
        );
        assert_eq!(
            f.check_incoming(key(201, 190, 0)),
            Err(Filtered::NotAllowedSys)
        );
        // The way out is open.
        for k in [key(255, 190, COMMAND_LONG), key(200, 191, 0), key(1, 1, 30)] {
            assert_eq!(f.check_key(k, now), Ok(()));
        }
        // And an outgoing filter leaves the way in open.
        let f = out(Lists {
            block_msg: vec![COMMAND_LONG],
            ..Lists::default()
        });
        assert_eq!(f.check_incoming(key(255, 190, COMMAND_LONG)), Ok(()));
    }

    #[test]
    fn raw_frames_are_checked_by_their_header() {
        let mut f = out(Lists {
            block_msg: vec![0],
            ..Lists::default()
        });
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::DEFAULT);
        let att = MavMessage::ATTITUDE(ATTITUDE_DATA::DEFAULT);
        let now = Instant::now();
        let frame = |m| harrier_link::frame::encode(header(255, 190), m).unwrap();
        assert_eq!(f.check(&frame(&hb), now), Err(Filtered::BlockedMsg));
        assert_eq!(f.check(&frame(&att), now), Ok(()));
        assert_eq!(f.check(b"\xfd", now), Ok(()));
    }

    /// Frames of one stream at `hz` with a deterministic jitter of up to ±`jitter_ms`, for
    /// `secs`: the times they passed.
    fn run(f: &mut RouterFilter, k: FrameKey, hz: f64, jitter_ms: f64, secs: f64) -> Vec<f64> {
        let t0 = Instant::now();
        let mut passed = Vec::new();
        let n = (hz * secs) as u64;
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for i in 0..n {
            // xorshift: a jitter in [-1, 1) × jitter_ms.
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            let t = (i as f64 / hz + u * jitter_ms / 1e3).max(0.0);
            if f.check_key(k, t0 + Duration::from_secs_f64(t)).is_ok() {
                passed.push(t);
            }
        }
        passed
    }

    /// Rate measured from the first to the last frame passed.
    fn rate(times: &[f64]) -> f64 {
        (times.len() - 1) as f64 / (times[times.len() - 1] - times[0])
    }

    #[test]
    fn rate_limit_keeps_the_rate_despite_jitter() {
        for (hz, jitter_ms) in [
            (10.0, 0.0),
            (10.0, 20.0),
            (50.0, 5.0),
            (100.0, 3.0),
            (7.0, 10.0),
        ] {
            let mut f = RouterFilter::new(&FilterSpec {
                max_rate_hz: vec![(ATTITUDE, 2.0)],
                ..FilterSpec::default()
            });
            let passed = run(&mut f, key(1, 1, ATTITUDE), hz, jitter_ms, 60.0);
            let r = rate(&passed);
            eprintln!("{hz} Hz ± {jitter_ms} ms limited to 2 Hz: {r:.4} Hz");
            // A 7 Hz source can only be cut to 7/4 or 7/3 Hz at best; 7/3 > 2 is refused.
            let low = if hz == 7.0 { 1.74 } else { 1.9 };
            assert!(
                (low..=2.01).contains(&r),
                "{hz} Hz ± {jitter_ms} ms: {r} Hz"
            );
            // Never more than 1 + (L + period/4)/period frames in any window of L = 1, 5 s.
            for l in [1.0, 5.0] {
                let most = passed
                    .iter()
                    .map(|&a| passed.iter().filter(|&&b| b >= a && b < a + l).count())
                    .max()
                    .unwrap();
                assert!(
                    most as f64 <= 1.0 + (l + 0.125) / 0.5,
                    "{hz} Hz: {most} in {l} s"
                );
            }
        }
    }

    #[test]
    fn a_slower_source_is_not_limited() {
        let mut f = RouterFilter::new(&FilterSpec {
            max_rate_hz: vec![(ATTITUDE, 2.0)],
            ..FilterSpec::default()
        });
        let passed = run(&mut f, key(1, 1, ATTITUDE), 1.5, 50.0, 30.0);
        assert_eq!(passed.len(), 45);
    }

    #[test]
    fn streams_are_limited_each_on_their_own() {
        let mut f = RouterFilter::new(&FilterSpec {
            max_rate_hz: vec![(ATTITUDE, 2.0)],
            ..FilterSpec::default()
        });
        let t0 = Instant::now();
        let mut counts = HashMap::new();
        for i in 0..100u32 {
            let now = t0 + Duration::from_millis(u64::from(i) * 100);
            for k in [
                key(1, 1, ATTITUDE),
                key(2, 1, ATTITUDE),
                key(1, 2, ATTITUDE),
                key(1, 1, GPS_RAW_INT),
            ] {
                if f.check_key(k, now).is_ok() {
                    *counts.entry(k).or_insert(0) += 1;
                }
            }
        }
        // 10 s at 10 Hz: each limited stream's first frame, then one every 0.5 s from 0.4 s to
        // 9.9 s (a quarter period early is on time); every GPS_RAW_INT (not limited).
        assert_eq!(counts[&key(1, 1, ATTITUDE)], 21);
        assert_eq!(counts[&key(2, 1, ATTITUDE)], 21);
        assert_eq!(counts[&key(1, 2, ATTITUDE)], 21);
        assert_eq!(counts[&key(1, 1, GPS_RAW_INT)], 100);
    }

    #[test]
    fn only_frames_that_pass_the_lists_use_a_slot() {
        let mut f = RouterFilter::new(&FilterSpec {
            out: Lists {
                block_src_sys: vec![2],
                ..Lists::default()
            },
            max_rate_hz: vec![(ATTITUDE, 1.0)],
            ..FilterSpec::default()
        });
        let now = Instant::now();
        assert_eq!(
            f.check_key(key(2, 1, ATTITUDE), now),
            Err(Filtered::BlockedSys)
        );
        assert_eq!(f.check_key(key(1, 1, ATTITUDE), now), Ok(()));
        assert_eq!(f.check_key(key(1, 1, ATTITUDE), now), Err(Filtered::Rate));
    }

    #[test]
    fn the_stream_table_is_bounded() {
        let mut f = RouterFilter::new(&FilterSpec {
            max_rate_hz: vec![(ATTITUDE, 1.0)],
            ..FilterSpec::default()
        });
        let now = Instant::now();
        for s in 0..(MAX_STREAMS as u32 * 3) {
            assert_eq!(f.check_key(key(s, 1, ATTITUDE), now), Ok(()));
            assert!(f.due.len() <= MAX_STREAMS);
        }
    }
}
