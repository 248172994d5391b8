//! The Beast binary format that dump1090 and readsb serve on TCP port 30005 (and Mode-S Beast
//! receivers on their serial line): every message the receiver demodulated, raw, with its time
//! of arrival and signal level. [`BeastDecoder`] splits a byte stream into [`BeastFrame`]s
//! (pure, streaming: bytes in any pieces, no clock); [`crate::wire::mode_s`] decodes the Mode S
//! message a frame carries.
//!
//! | bytes | field |
//! |---|---|
//! | 1 | `0x1a`, the frame's start |
//! | 1 | type: `'1'` (0x31) Mode A/C reply, 2 bytes; `'2'` (0x32) Mode S short, 7 bytes; `'3'` (0x33) Mode S long, 14 bytes |
//! | 6 | time of arrival, a 12 MHz counter, big-endian ([`BeastFrame::timestamp`]) |
//! | 1 | signal level ([`BeastFrame::signal`]) |
//! | 2, 7 or 14 | the message ([`BeastFrame::message`]) |
//!
//! Every `0x1a` after the type byte is sent twice (`0x1a 0x1a`), so a lone `0x1a` can only start
//! a frame. Reference: Mode-S Beast documentation (modesbeast.com, "Binary format"), and
//! dump1090's `modesSendBeastOutput` / readsb's `decodeBinMessage`.
//!
//! What is refused ([`Refusal`]), each once, before the decoder looks for the next frame:
//! bytes outside a frame ([`Refusal::Garbage`]: a connection joined mid-frame, noise), a type
//! that is not one of the three ([`Refusal::Type`]: e.g. readsb's receiver-id `0xe3` or status
//! `'4'` frames; the bytes up to the next frame are part of that refusal), and a frame cut short
//! by a lone `0x1a` ([`Refusal::Truncated`]: that `0x1a` starts the next frame).

/// The escape byte: a frame's start, doubled inside a frame.
const ESC: u8 = 0x1a;
/// Time stamp and signal level, bytes.
const HEADER: usize = 7;
/// The longest message (Mode S long), bytes.
const MAX_MESSAGE: usize = 14;

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// `'1'`: a Mode A/C reply (2 bytes).
    ModeAc,
    /// `'2'`: a Mode S short message (56 bits).
    ModeSShort,
    /// `'3'`: a Mode S long message (112 bits).
    ModeSLong,
}

impl FrameKind {
    /// The kind of a type byte.
    fn from_type(byte: u8) -> Option<Self> {
        match byte {
            b'1' => Some(Self::ModeAc),
            b'2' => Some(Self::ModeSShort),
            b'3' => Some(Self::ModeSLong),
            _ => None,
        }
    }

    /// The message's length, bytes.
    pub fn message_len(self) -> usize {
        match self {
            Self::ModeAc => 2,
            Self::ModeSShort => 7,
            Self::ModeSLong => MAX_MESSAGE,
        }
    }
}

/// One frame, its escapes undone.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BeastFrame {
    /// What the message is.
    pub kind: FrameKind,
    /// The receiver's 48-bit time of arrival, 12 MHz ticks (free-running unless the receiver is
    /// GPS-disciplined; not used for tracking).
    pub timestamp: u64,
    /// The signal level (RSSI) byte.
    pub signal: u8,
    message: [u8; MAX_MESSAGE],
}

impl BeastFrame {
    /// The message: 2, 7 or 14 bytes.
    pub fn message(&self) -> &[u8] {
        &self.message[..self.kind.message_len()]
    }
}

/// Why bytes were refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// This many bytes outside any frame.
    #[error("{0} bytes outside a frame")]
    Garbage(usize),
    /// A frame of an unknown type (this byte), skipped to the next frame.
    #[error("frame type 0x{0:02x}")]
    Type(u8),
    /// A frame cut short by a lone `0x1a` after this many of its bytes.
    #[error("frame cut short after {0} of its bytes")]
    Truncated(usize),
}

/// Where the decoder is in the stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Looking for a `0x1a`; `quiet`: the bytes skipped belong to a refused frame.
    Outside { quiet: bool },
    /// After a `0x1a` outside a frame: the type byte next (or its double).
    Start { quiet: bool },
    /// Inside a frame: `got` bytes of its header and message so far; `escape`: the last was a
    /// `0x1a`, whose double is next.
    Body {
        kind: FrameKind,
        got: usize,
        escape: bool,
    },
}

/// A streaming Beast decoder: [`BeastDecoder::push`] the bytes as they come, in any pieces.
#[derive(Debug, Clone)]
pub struct BeastDecoder {
    state: State,
    /// Bytes skipped outside a frame since the last one.
    garbage: usize,
    body: [u8; HEADER + MAX_MESSAGE],
}

impl Default for BeastDecoder {
    fn default() -> Self {
        Self {
            state: State::Outside { quiet: false },
            garbage: 0,
            body: [0; HEADER + MAX_MESSAGE],
        }
    }
}

impl BeastDecoder {
    /// Decodes `bytes`, handing each complete frame and each refusal to `out` in stream order. A
    /// frame split between two pushes is kept until its end comes; a run of garbage is reported
    /// when the next frame starts.
    pub fn push(&mut self, bytes: &[u8], mut out: impl FnMut(Result<BeastFrame, Refusal>)) {
        for &b in bytes {
            self.byte(b, &mut out);
        }
    }

    fn byte(&mut self, b: u8, out: &mut impl FnMut(Result<BeastFrame, Refusal>)) {
        match self.state {
            State::Outside { quiet } => {
                if b == ESC {
                    self.state = State::Start { quiet };
                } else {
                    self.garbage += 1;
                }
            }
            State::Start { quiet } => self.start(b, quiet, out),
            State::Body {
                kind,
                got,
                escape: true,
            } => {
                if b == ESC {
                    self.store(kind, got, ESC, out);
                } else {
                    // The lone 0x1a before this byte started the next frame.
                    out(Err(Refusal::Truncated(got)));
                    self.start(b, false, out);
                }
            }
            State::Body { kind, got, .. } => {
                if b == ESC {
                    self.state = State::Body {
                        kind,
                        got,
                        escape: true,
                    };
                } else {
                    self.store(kind, got, b, out);
                }
            }
        }
    }

    /// The byte after a `0x1a` outside a frame; `quiet`: the bytes skipped before belong to a
    /// refused frame. The skipped bytes are reported once a frame (or a refused one) starts.
    fn start(&mut self, b: u8, quiet: bool, out: &mut impl FnMut(Result<BeastFrame, Refusal>)) {
        if b == ESC {
            // A doubled 0x1a: the inside of a frame the decoder joined late, or a refused one.
            self.garbage += 2;
            self.state = State::Outside { quiet };
            return;
        }
        if self.garbage > 0 && !quiet {
            out(Err(Refusal::Garbage(self.garbage)));
        }
        self.garbage = 0;
        if let Some(kind) = FrameKind::from_type(b) {
            self.state = State::Body {
                kind,
                got: 0,
                escape: false,
            };
        } else {
            out(Err(Refusal::Type(b)));
            self.state = State::Outside { quiet: true };
        }
    }

    fn store(
        &mut self,
        kind: FrameKind,
        got: usize,
        b: u8,
        out: &mut impl FnMut(Result<BeastFrame, Refusal>),
    ) {
        self.body[got] = b;
        let got = got + 1;
        if got < HEADER + kind.message_len() {
            self.state = State::Body {
                kind,
                got,
                escape: false,
            };
            return;
        }
        let timestamp = self.body[..6]
            .iter()
            .fold(0_u64, |t, &b| (t << 8) | u64::from(b));
        let mut message = [0; MAX_MESSAGE];
        message[..kind.message_len()].copy_from_slice(&self.body[HEADER..got]);
        out(Ok(BeastFrame {
            kind,
            timestamp,
            signal: self.body[6],
            message,
        }));
        self.state = State::Outside { quiet: false };
    }
}

/// One frame as a receiver sends it: `0x1a`, the type, then the time stamp, signal level and
/// message with every `0x1a` doubled (for the tests here and the feed's).
#[cfg(test)]
pub(crate) fn encode(timestamp: u64, signal: u8, message: &[u8]) -> Vec<u8> {
    let kind = match message.len() {
        2 => b'1',
        7 => b'2',
        _ => b'3',
    };
    let mut out = vec![ESC, kind];
    let body = timestamp.to_be_bytes()[2..]
        .iter()
        .chain([signal].iter())
        .chain(message.iter())
        .copied()
        .collect::<Vec<u8>>();
    for b in body {
        out.push(b);
        if b == ESC {
            out.push(ESC);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn decode_all(bytes: &[u8], piece: usize) -> Vec<Result<BeastFrame, Refusal>> {
        let mut d = BeastDecoder::default();
        let mut got = Vec::new();
        for p in bytes.chunks(piece.max(1)) {
            d.push(p, |r| got.push(r));
        }
        got
    }

    const LONG: [u8; 14] = [
        0x8d, 0x48, 0x40, 0xd6, 0x20, 0x2c, 0xc3, 0x71, 0xc3, 0x2c, 0xe0, 0x57, 0x60, 0x98,
    ];

    #[test]
    fn frames_of_the_three_kinds_with_escapes_in_any_pieces() {
        let mut stream = Vec::new();
        // 0x1a in the time stamp, the signal and the message.
        stream.extend(encode(0x1a_0000_001a, 0x1a, &LONG));
        stream.extend(encode(
            12_000_000,
            200,
            &[0x5d, 0x1a, 0x40, 0xd6, 0x12, 0x34, 0x56],
        ));
        stream.extend(encode(7, 1, &[0x1a, 0x1a]));
        assert_eq!(stream.iter().filter(|&&b| b == ESC).count(), 3 + 2 * 6);
        for piece in [1, 2, 3, 7, 64] {
            let got = decode_all(&stream, piece);
            assert_eq!(got.len(), 3, "piece {piece}");
            let f = got[0].as_ref().unwrap();
            assert_eq!(f.kind, FrameKind::ModeSLong);
            assert_eq!((f.timestamp, f.signal), (0x1a_0000_001a, 0x1a));
            assert_eq!(f.message(), &LONG);
            let f = got[1].as_ref().unwrap();
            assert_eq!(f.kind, FrameKind::ModeSShort);
            assert_eq!(f.message(), &[0x5d, 0x1a, 0x40, 0xd6, 0x12, 0x34, 0x56]);
            assert_eq!(f.timestamp, 12_000_000);
            let f = got[2].as_ref().unwrap();
            assert_eq!(
                (f.kind, f.message()),
                (FrameKind::ModeAc, &[0x1a, 0x1a][..])
            );
        }
    }

    #[test]
    fn garbage_unknown_types_and_cut_frames_are_refused_once_then_resynced() {
        let frame = encode(1, 2, &LONG);
        let mut stream = b"hello".to_vec();
        stream.extend(&frame);
        // A status frame of an unknown type, whose body is skipped with it.
        stream.extend([ESC, b'4', 1, 2, 3, ESC, ESC, 4]);
        stream.extend(&frame);
        // Cut short: the next frame's 0x1a comes after 5 bytes.
        stream.extend(&frame[..7]);
        stream.extend(&frame);
        // Joined inside a frame at an escaped 0x1a.
        stream.extend([ESC, ESC, 9, 9]);
        stream.extend(&frame);
        let got = decode_all(&stream, 5);
        let expected = [
            Err(Refusal::Garbage(5)),
            Ok(()),
            Err(Refusal::Type(b'4')),
            Ok(()),
            Err(Refusal::Truncated(5)),
            Ok(()),
            Err(Refusal::Garbage(4)),
            Ok(()),
        ];
        assert_eq!(got.len(), expected.len(), "{got:?}");
        for (g, e) in got.iter().zip(expected) {
            match (g, e) {
                (Ok(f), Ok(())) => assert_eq!(f.message(), &LONG),
                (Err(g), Err(e)) => assert_eq!(*g, e),
                _ => panic!("{g:?} where {e:?} was expected"),
            }
        }
    }

    #[test]
    fn random_bytes_never_panic_and_a_frame_after_them_is_found() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let frame = encode(99, 3, &LONG);
        for round in 0..2_000 {
            let n = rng.random_range(0..200);
            let mut stream: Vec<u8> = (0..n)
                .map(|_| {
                    if rng.random_bool(0.2) {
                        ESC
                    } else {
                        rng.random()
                    }
                })
                .collect();
            let mut d = BeastDecoder::default();
            let mut frames = 0;
            d.push(&stream, |r| frames += usize::from(r.is_ok()));
            // Whatever the noise left the decoder in, at most one frame is lost to it: the
            // second of two good frames always comes out whole.
            stream.clear();
            stream.extend(&frame);
            stream.extend(&frame);
            let mut last = None;
            d.push(&stream, |r| last = Some(r));
            assert_eq!(
                last.and_then(Result::ok).map(|f| f.message().to_vec()),
                Some(LONG.to_vec()),
                "round {round}"
            );
        }
    }
}
