//! MAVLink on the wire: connection strings ([`Endpoint`]) and frames reassembled from bytes
//! ([`StreamParser`], [`parse_datagram`]), each kept with its header and its raw bytes so that a
//! router can forward it unchanged.
//!
//! Both ends use this: harrier-sim's vehicle links and the ground station's GCS link and router.

use std::net::{SocketAddr, ToSocketAddrs};

use mavlink::consts::MAX_FRAME_SIZE;
use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion, Message};

/// A connection string that is not one of the supported forms.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "bad connection string {0:?}: expected udpin:HOST:PORT, udpout:HOST:PORT, \
     tcpin:HOST:PORT or tcpout:HOST:PORT"
)]
pub struct EndpointError(pub String);

/// A parsed connection string.
///
/// - `udpin:HOST:PORT` binds a UDP socket and answers whoever sends to it; `udpout:HOST:PORT`
///   binds an ephemeral port and sends to HOST:PORT.
/// - `tcpin:HOST:PORT` listens and serves every client that connects; `tcpout:HOST:PORT`
///   connects to a server and reconnects when the connection drops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endpoint {
    /// Bind here and answer whoever sends.
    UdpIn(SocketAddr),
    /// Send to this address from an ephemeral port.
    UdpOut(SocketAddr),
    /// Listen here and serve every client that connects.
    TcpIn(SocketAddr),
    /// Connect to this server, and reconnect when the connection drops.
    TcpOut(SocketAddr),
}

impl Endpoint {
    /// Parses `udpin:HOST:PORT`, `udpout:HOST:PORT`, `tcpin:HOST:PORT` or `tcpout:HOST:PORT`
    /// (as in pymavlink, `udp:` is `udpin:` and `tcp:` is `tcpout:`).
    pub fn parse(s: &str) -> Result<Self, EndpointError> {
        let bad = || EndpointError(s.to_owned());
        let (kind, rest) = s.split_once(':').ok_or_else(bad)?;
        let addr = rest
            .to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(bad)?;
        match kind {
            "udpin" | "udp" => Ok(Self::UdpIn(addr)),
            "udpout" => Ok(Self::UdpOut(addr)),
            "tcpin" => Ok(Self::TcpIn(addr)),
            "tcpout" | "tcp" => Ok(Self::TcpOut(addr)),
            _ => Err(bad()),
        }
    }

    /// The address: where to bind or listen (`*in`), or where to send or connect (`*out`).
    pub fn addr(&self) -> SocketAddr {
        match *self {
            Self::UdpIn(a) | Self::UdpOut(a) | Self::TcpIn(a) | Self::TcpOut(a) => a,
        }
    }

    /// The same kind of endpoint at another address.
    pub fn with_addr(&self, addr: SocketAddr) -> Self {
        match self {
            Self::UdpIn(_) => Self::UdpIn(addr),
            Self::UdpOut(_) => Self::UdpOut(addr),
            Self::TcpIn(_) => Self::TcpIn(addr),
            Self::TcpOut(_) => Self::TcpOut(addr),
        }
    }
}

/// The canonical connection string, which [`Endpoint::parse`] reads back.
impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self {
            Self::UdpIn(_) => "udpin",
            Self::UdpOut(_) => "udpout",
            Self::TcpIn(_) => "tcpin",
            Self::TcpOut(_) => "tcpout",
        };
        write!(f, "{kind}:{}", self.addr())
    }
}

/// One valid MAVLink frame: its header, its decoded message and its bytes as received.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// MAVLink 1 or 2.
    pub version: MavlinkVersion,
    /// Sender's system id, component id and sequence number.
    pub header: MavHeader,
    /// The message.
    pub message: MavMessage,
    /// The frame as received (signature included), for forwarding unchanged.
    pub bytes: Vec<u8>,
}

impl Frame {
    /// The system the message is addressed to (its `target_system` field), `None` for a
    /// broadcast (no such field, or 0).
    pub fn target_system(&self) -> Option<u8> {
        target_system(&self.message)
    }
}

/// The `target_system` of a message, `None` when it has none or it is 0 (broadcast).
// Deprecated messages are still sent by clients (MAVProxy's SET_MODE, REQUEST_DATA_STREAM).
#[allow(deprecated)]
pub fn target_system(m: &MavMessage) -> Option<u8> {
    use MavMessage as M;
    let t = match m {
        M::COMMAND_LONG(c) => c.target_system,
        M::COMMAND_INT(c) => c.target_system,
        M::SET_POSITION_TARGET_LOCAL_NED(c) => c.target_system,
        M::SET_POSITION_TARGET_GLOBAL_INT(c) => c.target_system,
        M::SET_MODE(c) => c.target_system,
        M::PARAM_REQUEST_READ(c) => c.target_system,
        M::PARAM_REQUEST_LIST(c) => c.target_system,
        M::PARAM_SET(c) => c.target_system,
        M::MISSION_REQUEST_LIST(c) => c.target_system,
        M::MISSION_REQUEST_INT(c) => c.target_system,
        M::MISSION_REQUEST(c) => c.target_system,
        M::MISSION_COUNT(c) => c.target_system,
        M::MISSION_ITEM_INT(c) => c.target_system,
        M::MISSION_ACK(c) => c.target_system,
        M::MISSION_CLEAR_ALL(c) => c.target_system,
        M::MISSION_SET_CURRENT(c) => c.target_system,
        M::REQUEST_DATA_STREAM(c) => c.target_system,
        M::SET_ATTITUDE_TARGET(c) => c.target_system,
        M::MANUAL_CONTROL(c) => c.target,
        M::FILE_TRANSFER_PROTOCOL(c) => c.target_system,
        M::LOG_REQUEST_LIST(c) => c.target_system,
        M::PING(c) => c.target_system,
        _ => 0,
    };
    (t != 0).then_some(t)
}

/// `msg` as one MAVLink 2 frame from `header` (`None` if it cannot be serialised).
pub fn encode(header: MavHeader, msg: &MavMessage) -> Option<Vec<u8>> {
    let mut buf = Vec::with_capacity(MAX_FRAME_SIZE);
    mavlink::write_v2_msg(&mut buf, header, msg).ok()?;
    Some(buf)
}

/// What one [`StreamParser::push`] or [`parse_datagram`] produced.
#[derive(Debug, Default)]
pub struct Parsed {
    /// The complete frames, in stream order.
    pub frames: Vec<Frame>,
    /// Stretches of skipped bytes and undecodable frames.
    pub malformed: u64,
}

impl Parsed {
    /// The messages alone.
    pub fn into_messages(self) -> impl Iterator<Item = MavMessage> {
        self.frames.into_iter().map(|f| f.message)
    }
}

/// Reassembles MAVLink frames (1 or 2) from a byte stream delivered in arbitrary pieces.
///
/// Bytes that cannot start a frame are skipped; each stretch of skipped bytes between two valid
/// frames counts once as malformed (as a UDP datagram without a valid frame does), and so does a
/// frame with a valid checksum whose payload does not decode. A partial frame at the end of the
/// buffer waits for the next bytes. Frames of messages outside the common dialect fail their
/// checksum (their CRC_EXTRA is unknown) and are skipped like garbage.
#[derive(Debug, Default)]
pub struct StreamParser {
    buf: Vec<u8>,
    /// The bytes skipped since the last valid frame have already been counted.
    counted: bool,
}

impl StreamParser {
    /// Appends `bytes` and returns every frame completed by them.
    pub fn push(&mut self, bytes: &[u8]) -> Parsed {
        self.buf.extend_from_slice(bytes);
        let mut out = Parsed::default();
        // Everything before `pos` is consumed (frames and skipped bytes).
        let mut pos = 0;
        let mut reader = MavlinkReader::with_capacity(0, &self.buf[..]);
        // The reader skips to the next valid frame and fails at the end of the buffer (a partial
        // frame or nothing left); where the frame lies tells how many bytes were skipped.
        while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
            let (frame, header) = match &raw {
                MAVLinkMessageRaw::V1(m) => (
                    m.raw_bytes(),
                    MavHeader {
                        system_id: m.system_id().into(),
                        component_id: m.component_id(),
                        sequence: m.sequence(),
                    },
                ),
                MAVLinkMessageRaw::V2(m) => (
                    m.raw_bytes(),
                    MavHeader {
                        system_id: m.system_id(),
                        component_id: m.component_id(),
                        sequence: m.sequence(),
                    },
                ),
            };
            let Some(at) = self.buf[pos..]
                .windows(frame.len())
                .position(|w| w == frame)
            else {
                break; // the reader only returns frames it read from the buffer
            };
            if at > 0 && !self.counted {
                out.malformed += 1;
            }
            self.counted = false;
            pos += at + frame.len();
            match MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) {
                Ok(message) => out.frames.push(Frame {
                    version: raw.version(),
                    header,
                    message,
                    bytes: frame.to_vec(),
                }),
                Err(_) => out.malformed += 1,
            }
        }
        // A frame still to be completed starts within the last MAX_FRAME_SIZE bytes: anything
        // before is garbage.
        let keep_from = pos.max(self.buf.len().saturating_sub(MAX_FRAME_SIZE));
        if keep_from > pos && !self.counted {
            out.malformed += 1;
            self.counted = true;
        }
        self.buf.drain(..keep_from);
        out
    }

    /// Bytes waiting for the rest of a frame.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

/// The frames of one datagram (a datagram may carry several). Bytes that are not a frame, a
/// frame cut at the end, and a frame that does not decode each count as malformed.
pub fn parse_datagram(bytes: &[u8]) -> Parsed {
    let mut p = StreamParser::default();
    let mut out = p.push(bytes);
    if p.pending() > 0 && !p.counted {
        out.malformed += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd};

    fn frame(msg: &MavMessage, sequence: u8) -> Vec<u8> {
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence,
        };
        encode(header, msg).expect("serialise")
    }

    fn heartbeat() -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())
    }

    fn command(target_system: u8) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system,
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            param1: 148.0,
            ..COMMAND_LONG_DATA::default()
        })
    }

    #[test]
    fn connection_strings() {
        let local = |port| SocketAddr::from(([127, 0, 0, 1], port));
        for (s, e) in [
            ("udpin:127.0.0.1:14540", Endpoint::UdpIn(local(14540))),
            ("udp:127.0.0.1:14540", Endpoint::UdpIn(local(14540))),
            ("udpout:127.0.0.1:14550", Endpoint::UdpOut(local(14550))),
            ("tcpin:127.0.0.1:5760", Endpoint::TcpIn(local(5760))),
            ("tcpout:127.0.0.1:5760", Endpoint::TcpOut(local(5760))),
            ("tcp:127.0.0.1:5760", Endpoint::TcpOut(local(5760))),
        ] {
            assert_eq!(Endpoint::parse(s).ok(), Some(e), "{s}");
            // Display gives the canonical form, which parses back.
            assert_eq!(Endpoint::parse(&e.to_string()).ok(), Some(e));
        }
        assert_eq!(
            Endpoint::TcpIn(local(5760))
                .with_addr(local(5762))
                .to_string(),
            "tcpin:127.0.0.1:5762"
        );
        for bad in [
            "",
            "udpin",
            "tcpin",
            "serial:/dev/ttyUSB0",
            "udpin:nohost",
            "tcpout:nohost",
            "udpout:1.2.3.4:99999",
        ] {
            let e = Endpoint::parse(bad).expect_err(bad);
            assert!(e.to_string().contains("tcpout:HOST:PORT"), "{e}");
        }
    }

    #[test]
    fn stream_parser_reassembles_frames_and_counts_garbage_stretches() {
        let hb = frame(&heartbeat(), 0);
        let cmd = frame(&command(3), 1);
        let mut p = StreamParser::default();
        // One byte at a time: nothing until the last byte of the frame.
        for (i, b) in hb.iter().enumerate() {
            let r = p.push(&[*b]);
            assert_eq!(r.frames.len(), usize::from(i + 1 == hb.len()), "byte {i}");
            assert_eq!(r.malformed, 0);
        }
        assert_eq!(p.pending(), 0);
        // Garbage (with a false start marker), then two adjacent frames in one piece: the garbage
        // counts once; each frame keeps its header and its bytes.
        let mut bytes = vec![0xFD, 9, 0, 0, 1, 2, 3, b'x'];
        bytes.extend_from_slice(&cmd);
        bytes.extend_from_slice(&hb);
        let r = p.push(&bytes);
        assert_eq!(r.frames.len(), 2);
        assert!(matches!(r.frames[0].message, MavMessage::COMMAND_LONG(_)));
        assert_eq!(r.frames[0].bytes, cmd);
        assert_eq!(r.frames[0].target_system(), Some(3));
        assert_eq!(r.frames[1].target_system(), None);
        assert_eq!(
            (r.frames[0].header.system_id, r.frames[0].header.sequence),
            (255, 1)
        );
        assert_eq!(r.malformed, 1);
        // A corrupted frame is skipped and counted; the frame after it is read.
        let mut bad = cmd.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xFF;
        bad.extend_from_slice(&hb);
        let r = p.push(&bad);
        assert_eq!((r.frames.len(), r.malformed), (1, 1));
        // A long stretch of garbage is dropped as it comes (the buffer stays bounded) and counts
        // once, however many pieces it arrives in.
        let mut malformed = 0;
        for _ in 0..10 {
            let r = p.push(&[0x55; 200]);
            assert!(r.frames.is_empty());
            malformed += r.malformed;
            assert!(p.pending() <= MAX_FRAME_SIZE);
        }
        let r = p.push(&hb);
        assert_eq!(r.frames.len(), 1);
        assert_eq!(malformed + r.malformed, 1);
        // MAVLink 1 frames are read too.
        let mut v1 = Vec::new();
        mavlink::write_v1_msg(&mut v1, MavHeader::default(), &heartbeat()).expect("serialise");
        let r = p.push(&v1);
        assert_eq!(r.frames.len(), 1);
        assert_eq!(r.frames[0].version, MavlinkVersion::V1);
    }

    #[test]
    fn datagrams() {
        let hb = frame(&heartbeat(), 7);
        let mut two = hb.clone();
        two.extend_from_slice(&frame(&command(1), 8));
        let r = parse_datagram(&two);
        assert_eq!((r.frames.len(), r.malformed), (2, 0));
        // A cut frame, garbage, nothing: malformed, once each.
        for bad in [&hb[..hb.len() - 1], &[1u8, 2, 3][..], &[0xFD][..]] {
            let r = parse_datagram(bad);
            assert_eq!((r.frames.len(), r.malformed), (0, 1), "{bad:?}");
        }
        assert_eq!(parse_datagram(&[]).malformed, 0);
    }
}
