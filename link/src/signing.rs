//! MAVLink 2 message signing (<https://mavlink.io/en/guide/message_signing.html>) for both ends:
//! the ground station's GCS link and router, and harrier-sim's vehicles.
//!
//! A frame is signed by appending a 13-byte signature (incompat flag 0x01): link id, a 48-bit
//! timestamp in 10 µs units since 2015-01-01 00:00 UTC, and the first 6 bytes of
//! SHA-256(secret key ‖ header ‖ payload ‖ CRC ‖ link id ‖ timestamp). The hashing, the timestamps
//! and the replay state come from the mavlink crate ([`mavlink::SigningData`], feature
//! `mav2-message-signing`); harrier-link parses frames itself ([`crate::frame`]), so the check
//! runs on each frame's raw bytes, and the reason of a refusal (which the crate's
//! `verify_signature` folds into one `false`) is recovered by recomputing the signature.
//!
//! - [`SigningKey`]: the 32-byte secret, from 64 hex characters or a key file (64 hex characters,
//!   or exactly 32 raw bytes). pymavlink and MAVProxy (`signing setup PASSPHRASE`) use
//!   SHA-256(passphrase) as the key: `printf %s PASSPHRASE | sha256sum | cut -c1-64`.
//! - [`SigningMode`]: `off`; `sign` (sign what we send, accept unsigned frames, but refuse a
//!   *signed* frame whose signature is wrong or replayed); `signed_only` (refuse everything
//!   that is not correctly signed and fresh, MAVLink 1 included).
//! - [`Signer`]: signs outgoing frames ([`Signer::encode`]) and checks incoming ones
//!   ([`Signer::check`] → [`Rejection`]: `unsigned`, `bad_signature`, `replay`).
//!
//! A signed frame is a replay when its timestamp is not newer than the last one accepted from
//! the same (link id, system id, component id) stream, or when it opens a new stream more than
//! one minute older than the newest time this signer knows (its clock, or the newest timestamp
//! it accepted), the rule of the specification and of the mavlink crate.
//!
//! ```
//! use harrier_link::frame::{encode, parse_datagram};
//! use harrier_link::mavlink::MavHeader;
//! use harrier_link::mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};
//! use harrier_link::signing::{Rejection, Signer, Signing, SigningKey, SigningMode};
//!
//! let key = SigningKey::from_hex(&"2a".repeat(32))?;
//! let signing = Signing { key, mode: SigningMode::SignedOnly, link_id: 0 };
//! let (vehicle, gcs) = (signing.signer().unwrap(), signing.signer().unwrap());
//! let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
//! let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
//! let signed = vehicle.encode(header, &hb).unwrap();
//! let frame = &parse_datagram(&signed).frames[0];
//! assert_eq!(gcs.check(frame), Ok(()));
//! assert_eq!(gcs.check(frame), Err(Rejection::Replay)); // the same frame again
//! let unsigned = &parse_datagram(&encode(header, &hb).unwrap()).frames[0];
//! assert_eq!(gcs.check(unsigned), Err(Rejection::Unsigned));
//! # Ok::<(), harrier_link::signing::KeyError>(())
//! ```

use std::path::{Path, PathBuf};

use mavlink::consts::{MAX_FRAME_SIZE, v2};
use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MavlinkVersion, SigningConfig, SigningData};

use crate::frame::Frame;

/// Length of a signing key (bytes).
pub const KEY_LEN: usize = 32;

/// A key that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    /// Not 64 hex characters.
    #[error("a MAVLink signing key is 64 hex characters (32 bytes), got {0}")]
    Hex(String),
    /// The key file is neither 64 hex characters nor 32 raw bytes.
    #[error("signing key file {0}: expected 64 hex characters or exactly 32 raw bytes")]
    File(PathBuf),
    /// The key file cannot be read.
    #[error("signing key file {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The 32-byte secret shared by every party of a signed MAVLink network. Its `Debug` does not
/// show it.
#[derive(Clone, PartialEq, Eq)]
pub struct SigningKey([u8; KEY_LEN]);

impl std::fmt::Debug for SigningKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SigningKey(<secret>)")
    }
}

impl SigningKey {
    /// The key as given.
    pub fn new(bytes: [u8; KEY_LEN]) -> Self {
        Self(bytes)
    }

    /// 64 hex characters (either case; surrounding whitespace ignored).
    pub fn from_hex(s: &str) -> Result<Self, KeyError> {
        let s = s.trim();
        let shown = || {
            // Never echo what may be most of a secret.
            if s.len() == 2 * KEY_LEN {
                "64 characters that are not all hex digits".to_owned()
            } else {
                format!("{} characters", s.len())
            }
        };
        if s.len() != 2 * KEY_LEN || !s.is_ascii() {
            return Err(KeyError::Hex(shown()));
        }
        let mut key = [0u8; KEY_LEN];
        for (k, pair) in key.iter_mut().zip(s.as_bytes().chunks_exact(2)) {
            let pair = std::str::from_utf8(pair).map_err(|_| KeyError::Hex(shown()))?;
            *k = u8::from_str_radix(pair, 16).map_err(|_| KeyError::Hex(shown()))?;
        }
        Ok(Self(key))
    }

    /// A key file: 64 hex characters (a trailing newline is fine) or exactly 32 raw bytes.
    pub fn from_file(path: &Path) -> Result<Self, KeyError> {
        let bytes = std::fs::read(path).map_err(|source| KeyError::Read {
            path: path.to_owned(),
            source,
        })?;
        if let Ok(raw) = <[u8; KEY_LEN]>::try_from(bytes.as_slice()) {
            return Ok(Self(raw));
        }
        std::str::from_utf8(&bytes)
            .ok()
            .and_then(|s| Self::from_hex(s).ok())
            .ok_or_else(|| KeyError::File(path.to_owned()))
    }

    /// The secret bytes.
    pub fn bytes(&self) -> &[u8; KEY_LEN] {
        &self.0
    }
}

/// What a link does about signatures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SigningMode {
    /// No signing: frames go out unsigned, and signatures of incoming frames are not checked.
    #[default]
    Off,
    /// Sign every outgoing frame; accept unsigned incoming frames, but refuse signed ones whose
    /// signature is wrong or replayed.
    Sign,
    /// Sign every outgoing frame; accept only correctly signed, fresh incoming frames.
    SignedOnly,
}

impl std::str::FromStr for SigningMode {
    type Err = String;

    /// `off`, `sign` or `signed_only`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "off" => Ok(Self::Off),
            "sign" => Ok(Self::Sign),
            "signed_only" => Ok(Self::SignedOnly),
            _ => Err(format!(
                "signing mode must be off, sign or signed_only, got {s:?}"
            )),
        }
    }
}

impl std::fmt::Display for SigningMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Off => "off",
            Self::Sign => "sign",
            Self::SignedOnly => "signed_only",
        })
    }
}

/// The signing settings of one party: key, mode and the link id it signs with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signing {
    /// The shared secret.
    pub key: SigningKey,
    /// What to sign and what to accept.
    pub mode: SigningMode,
    /// The link id in the signatures this party writes (0–255; distinct ids let several
    /// senders share one system and component id).
    pub link_id: u8,
}

impl Signing {
    /// A signer with its own timestamp and replay state, `None` when the mode is `off`.
    pub fn signer(&self) -> Option<Signer> {
        Signer::new(self)
    }
}

/// Why an incoming frame was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Rejection {
    /// Not signed (MAVLink 1, or MAVLink 2 without the signed flag) in `signed_only` mode.
    Unsigned,
    /// Signed, but not with our key (or altered on the way).
    BadSignature,
    /// Correctly signed, but its timestamp is not newer than the last one seen on its stream,
    /// or it opens a stream more than a minute in the past.
    Replay,
}

impl Rejection {
    /// Every reason, in the order of the counters.
    pub const ALL: [Self; 3] = [Self::Unsigned, Self::BadSignature, Self::Replay];

    /// `unsigned`, `bad_signature` or `replay` (metric label and log field).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Unsigned => "unsigned",
            Self::BadSignature => "bad_signature",
            Self::Replay => "replay",
        }
    }
}

/// Refused frames by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Rejections {
    /// Unsigned frames refused (`signed_only`).
    pub unsigned: u64,
    /// Frames with a wrong signature.
    pub bad_signature: u64,
    /// Correctly signed frames refused as replays.
    pub replay: u64,
}

impl Rejections {
    /// Counts one refusal.
    pub fn count(&mut self, r: Rejection) {
        *self.get_mut(r) += 1;
    }

    /// The count of one reason.
    pub fn get(&self, r: Rejection) -> u64 {
        match r {
            Rejection::Unsigned => self.unsigned,
            Rejection::BadSignature => self.bad_signature,
            Rejection::Replay => self.replay,
        }
    }

    fn get_mut(&mut self, r: Rejection) -> &mut u64 {
        match r {
            Rejection::Unsigned => &mut self.unsigned,
            Rejection::BadSignature => &mut self.bad_signature,
            Rejection::Replay => &mut self.replay,
        }
    }

    /// Every refusal.
    pub fn total(&self) -> u64 {
        self.unsigned + self.bad_signature + self.replay
    }
}

/// Signs outgoing frames and checks incoming ones, for one party (all its links share it, so
/// that its timestamps only grow and a frame replayed onto another of its links is caught).
pub struct Signer {
    key: SigningKey,
    accept_unsigned: bool,
    /// The crate's signing state: the key, our link id, our last timestamp, and the last
    /// timestamp accepted per (link id, system id, component id).
    data: SigningData,
}

impl std::fmt::Debug for Signer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Signer")
            .field("accept_unsigned", &self.accept_unsigned)
            .finish_non_exhaustive()
    }
}

impl Signer {
    /// A signer for `signing`, `None` when its mode is `off`.
    pub fn new(signing: &Signing) -> Option<Self> {
        let accept_unsigned = match signing.mode {
            SigningMode::Off => return None,
            SigningMode::Sign => true,
            SigningMode::SignedOnly => false,
        };
        let config = SigningConfig::new(*signing.key.bytes(), signing.link_id, true, false);
        Some(Self {
            key: signing.key.clone(),
            accept_unsigned,
            data: SigningData::from_config(config),
        })
    }

    /// `msg` as one signed MAVLink 2 frame from `header` (`None` if it cannot be serialised).
    /// Each call takes a new timestamp: the current time, or one more than the last one.
    pub fn encode(&self, header: MavHeader, msg: &MavMessage) -> Option<Vec<u8>> {
        let mut buf = Vec::with_capacity(MAX_FRAME_SIZE);
        mavlink::write_v2_msg_signed(&mut buf, header, msg, Some(&self.data)).ok()?;
        Some(buf)
    }

    /// Whether `frame` may be used. An accepted signed frame advances its stream's timestamp,
    /// so the same frame is refused as a replay the next time.
    pub fn check(&self, frame: &Frame) -> Result<(), Rejection> {
        let signed = frame.version == MavlinkVersion::V2
            && frame
                .bytes
                .get(v2::INCOMPAT_FLAGS_OFFSET)
                .is_some_and(|f| f & v2::IFLAG_SIGNED != 0);
        if !signed {
            return if self.accept_unsigned {
                Ok(())
            } else {
                Err(Rejection::Unsigned)
            };
        }
        let mut buf = [0u8; MAX_FRAME_SIZE];
        let n = frame.bytes.len().min(MAX_FRAME_SIZE);
        buf[..n].copy_from_slice(&frame.bytes[..n]);
        let raw = MAVLinkV2MessageRaw::from_bytes_unparsed(buf);
        if self.data.verify_signature(&raw) {
            return Ok(());
        }
        // The crate says only "no": a signature that is right for our key means the timestamp
        // was refused.
        let mut expected = [0u8; v2::SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(self.key.bytes(), &mut expected);
        if expected == raw.signature_value() {
            Err(Rejection::Replay)
        } else {
            Err(Rejection::BadSignature)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{encode, parse_datagram};
    use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd};

    fn signing(key: u8, mode: SigningMode) -> Signing {
        Signing {
            key: SigningKey::new([key; KEY_LEN]),
            mode,
            link_id: 3,
        }
    }

    fn header(system_id: u8, sequence: u8) -> MavHeader {
        MavHeader {
            system_id: system_id.into(),
            component_id: 1,
            sequence,
        }
    }

    fn arm() -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            param1: 1.0,
            ..COMMAND_LONG_DATA::default()
        })
    }

    fn one(bytes: &[u8]) -> Frame {
        let p = parse_datagram(bytes);
        assert_eq!((p.frames.len(), p.malformed), (1, 0));
        p.frames.into_iter().next().expect("a frame")
    }

    #[test]
    fn keys_from_hex_and_files() {
        let hex = "00112233445566778899aabbccddeeffFFEEDDCCBBAA99887766554433221100";
        let k = SigningKey::from_hex(hex).expect("hex");
        assert_eq!(k.bytes()[..3], [0x00, 0x11, 0x22]);
        assert_eq!(k.bytes()[16], 0xFF);
        assert_eq!(format!("{k:?}"), "SigningKey(<secret>)");
        for bad in [
            "",
            "00",
            &hex[1..],
            &format!("{hex}0"),
            &hex.replace('a', "g"),
        ] {
            let e = SigningKey::from_hex(bad).expect_err(bad).to_string();
            assert!(e.contains("64 hex characters"), "{e}");
            assert!(!e.contains("0011"), "the error shows the key: {e}");
        }
        // Multi-byte characters of the right byte length are refused, not sliced.
        assert!(SigningKey::from_hex(&"é".repeat(32)).is_err());
        let dir = tempfile::tempdir().expect("temporary directory");
        let write = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).expect("write");
            p
        };
        let text = write("hex", format!("{hex}\n").as_bytes());
        assert_eq!(SigningKey::from_file(&text).expect("hex file"), k);
        let raw = write("raw", k.bytes());
        assert_eq!(SigningKey::from_file(&raw).expect("raw file"), k);
        let short = write("short", &[7; 31]);
        assert!(matches!(
            SigningKey::from_file(&short),
            Err(KeyError::File(_))
        ));
        assert!(matches!(
            SigningKey::from_file(&dir.path().join("absent")),
            Err(KeyError::Read { .. })
        ));
        assert_eq!("signed_only".parse(), Ok(SigningMode::SignedOnly));
        assert_eq!("sign".parse(), Ok(SigningMode::Sign));
        assert_eq!("off".parse(), Ok(SigningMode::Off));
        assert!("on".parse::<SigningMode>().is_err());
        assert_eq!(SigningMode::SignedOnly.to_string(), "signed_only");
        assert!(signing(1, SigningMode::Off).signer().is_none());
    }

    #[test]
    fn signed_frames_carry_link_id_and_growing_timestamps() {
        let s = signing(1, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let a = s.encode(header(1, 0), &arm()).expect("frame");
        let b = s.encode(header(1, 1), &arm()).expect("frame");
        let unsigned = encode(header(1, 0), &arm()).expect("frame");
        assert_eq!(a.len(), unsigned.len() + v2::SIGNATURE_SIZE);
        assert_eq!(
            a[v2::INCOMPAT_FLAGS_OFFSET] & v2::IFLAG_SIGNED,
            v2::IFLAG_SIGNED
        );
        let ts = |f: &[u8]| {
            let at = f.len() - v2::SIGNATURE_SIZE;
            assert_eq!(f[at], 3, "link id");
            let mut t = [0u8; 8];
            t[..6].copy_from_slice(&f[at + 1..at + 7]);
            u64::from_le_bytes(t)
        };
        assert!(ts(&b) > ts(&a));
        // 10 µs units since 2015-01-01: between 2020 and 2100.
        let years = ts(&a) as f64 / 1e5 / 86_400.0 / 365.25;
        assert!((5.0..85.0).contains(&years), "{years}");
        // The frame decodes as the message sent.
        assert_eq!(one(&a).message, arm());
    }

    #[test]
    fn signed_only_refuses_unsigned_wrong_key_and_replays() {
        let vehicle = signing(1, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let gcs = signing(1, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let intruder = signing(2, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let good = one(&gcs.encode(header(255, 0), &arm()).expect("frame"));
        assert_eq!(vehicle.check(&good), Ok(()));
        assert_eq!(vehicle.check(&good), Err(Rejection::Replay));
        // A later frame of the same stream is fine; the older one stays refused.
        let next = one(&gcs.encode(header(255, 1), &hb).expect("frame"));
        assert_eq!(vehicle.check(&next), Ok(()));
        assert_eq!(vehicle.check(&good), Err(Rejection::Replay));
        let forged = one(&intruder.encode(header(255, 2), &arm()).expect("frame"));
        assert_eq!(vehicle.check(&forged), Err(Rejection::BadSignature));
        // A tampered payload breaks the signature (the CRC is recomputed to pass the parser).
        let mut tampered = gcs.encode(header(255, 3), &arm()).expect("frame");
        let t = one(&tampered);
        let off = 10 + 4; // payload of COMMAND_LONG: param1 first
        tampered[off] ^= 0x01;
        let mut raw = [0u8; MAX_FRAME_SIZE];
        raw[..tampered.len()].copy_from_slice(&tampered);
        let mut m = MAVLinkV2MessageRaw::from_bytes_unparsed(raw);
        let crc = mavlink::calculate_crc(
            &m.as_slice()[1..10 + usize::from(m.payload_length())],
            <MavMessage as mavlink::Message>::extra_crc(m.message_id()),
        );
        let at = 10 + usize::from(m.payload_length());
        m.as_mut_slice()[at..at + 2].copy_from_slice(&crc.to_le_bytes());
        let tampered = one(&m.as_slice()[..tampered.len()]);
        assert_ne!(tampered.message, t.message);
        assert_eq!(vehicle.check(&tampered), Err(Rejection::BadSignature));
        // A stream that starts more than a minute in the past is a replay too.
        let mut old = gcs.encode(header(7, 0), &hb).expect("frame");
        let at = old.len() - v2::SIGNATURE_SIZE + 1;
        let mut ts = [0u8; 8];
        ts[..6].copy_from_slice(&old[at..at + 6]);
        let minute_ago = u64::from_le_bytes(ts) - 61 * 100_000;
        old[at..at + 6].copy_from_slice(&minute_ago.to_le_bytes()[..6]);
        let mut raw = [0u8; MAX_FRAME_SIZE];
        raw[..old.len()].copy_from_slice(&old);
        let mut m = MAVLinkV2MessageRaw::from_bytes_unparsed(raw);
        let mut sig = [0u8; v2::SIGNATURE_VALUE_SIZE];
        m.calculate_signature(&[1; KEY_LEN], &mut sig);
        m.signature_value_mut().copy_from_slice(&sig);
        let old = one(&m.as_slice()[..old.len()]);
        assert_eq!(vehicle.check(&old), Err(Rejection::Replay));
        for unsigned in [encode(header(255, 4), &arm()).expect("frame"), {
            let mut v1 = Vec::new();
            mavlink::write_v1_msg(&mut v1, header(255, 5), &hb).expect("frame");
            v1
        }] {
            assert_eq!(vehicle.check(&one(&unsigned)), Err(Rejection::Unsigned));
        }
        let mut counts = Rejections::default();
        for r in [Rejection::Replay, Rejection::Unsigned, Rejection::Replay] {
            counts.count(r);
        }
        assert_eq!((counts.get(Rejection::Replay), counts.total()), (2, 3));
    }

    #[test]
    fn sign_mode_accepts_unsigned_but_not_bad_signatures() {
        let vehicle = signing(1, SigningMode::Sign).signer().expect("signer");
        let intruder = signing(2, SigningMode::Sign).signer().expect("signer");
        let unsigned = one(&encode(header(255, 0), &arm()).expect("frame"));
        assert_eq!(vehicle.check(&unsigned), Ok(()));
        assert_eq!(vehicle.check(&unsigned), Ok(()));
        let forged = one(&intruder.encode(header(255, 1), &arm()).expect("frame"));
        assert_eq!(vehicle.check(&forged), Err(Rejection::BadSignature));
    }
}
