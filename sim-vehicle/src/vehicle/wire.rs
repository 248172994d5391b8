//! What a message carries on the wire beyond what the common-dialect crate decodes: its sender,
//! the component it is sent from, and MAVLink 2 extension fields.
//!
//! The `mavlink` crate is built without `mav2-message-extensions`, so its structs lack the
//! extension fields — among them `mission_type`, which tells a mission, geofence and rally-point
//! transfer apart, and GIMBAL_DEVICE_ATTITUDE_STATUS's `gimbal_device_id`. A received frame's
//! payload still holds them after the base fields; [`Incoming::of`] reads `mission_type` there,
//! and [`Outgoing`] appends extension bytes after a message's base fields when it is framed
//! ([`Outgoing::payload`]; MAVLink 2 trims trailing zero bytes either way).

use harrier_link::frame::Frame;
use harrier_link::px4::COMPONENT_ID;
#[allow(deprecated)]
use mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA,
    MISSION_REQUEST_LIST_DATA, MISSION_WRITE_PARTIAL_LIST_DATA, MavMessage,
};
use mavlink::{MavlinkVersion, Message, MessageData};

/// A received message with its sender and its `mission_type` extension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Incoming<'a> {
    /// The decoded message.
    pub message: &'a MavMessage,
    /// Sender's system and component id.
    pub sender: (u8, u8),
    /// `mission_type` (MAV_MISSION_TYPE) of a mission-protocol message: 0 (mission) when the
    /// message has no such field or the sender left it out.
    pub mission_type: u8,
}

/// Offset of a MAVLink 2 frame's payload (STX, length, flags ×2, sequence, system, component,
/// message id ×3).
const V2_PAYLOAD: usize = 10;

impl<'a> Incoming<'a> {
    /// A message from sender (system 255, component 190: a ground station) without extensions.
    pub fn from_gcs(message: &'a MavMessage) -> Self {
        Self {
            message,
            sender: (255, 190),
            mission_type: 0,
        }
    }

    /// The message of a received frame, its sender and `mission_type`.
    // MISSION_REQUEST is superseded by MISSION_REQUEST_INT; clients still send it.
    #[allow(deprecated)]
    pub fn of(frame: &'a Frame) -> Self {
        let base = match &frame.message {
            MavMessage::MISSION_COUNT(_) => Some(MISSION_COUNT_DATA::ENCODED_LEN),
            MavMessage::MISSION_REQUEST_LIST(_) => Some(MISSION_REQUEST_LIST_DATA::ENCODED_LEN),
            MavMessage::MISSION_REQUEST_INT(_) => Some(MISSION_REQUEST_INT_DATA::ENCODED_LEN),
            MavMessage::MISSION_REQUEST(_) => Some(MISSION_REQUEST_DATA::ENCODED_LEN),
            MavMessage::MISSION_ITEM_INT(_) => Some(MISSION_ITEM_INT_DATA::ENCODED_LEN),
            MavMessage::MISSION_ITEM(_) => Some(MISSION_ITEM_DATA::ENCODED_LEN),
            MavMessage::MISSION_ACK(_) => Some(MISSION_ACK_DATA::ENCODED_LEN),
            MavMessage::MISSION_CLEAR_ALL(_) => Some(MISSION_CLEAR_ALL_DATA::ENCODED_LEN),
            MavMessage::MISSION_WRITE_PARTIAL_LIST(_) => {
                Some(MISSION_WRITE_PARTIAL_LIST_DATA::ENCODED_LEN)
            }
            _ => None,
        };
        let mission_type = match (frame.version, base) {
            (MavlinkVersion::V2, Some(at)) => {
                let len = frame.bytes.get(1).map_or(0, |&l| usize::from(l));
                if at < len {
                    frame.bytes.get(V2_PAYLOAD + at).copied().unwrap_or(0)
                } else {
                    0
                }
            }
            _ => 0,
        };
        Self {
            message: &frame.message,
            sender: (
                u8::try_from(frame.header.system_id).unwrap_or(0),
                frame.header.component_id,
            ),
            mission_type,
        }
    }
}

/// A message the vehicle sends: from which of its components, with which extension bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Outgoing {
    /// The message (its base fields).
    pub message: MavMessage,
    /// The component it comes from: the autopilot (1) or the gimbal device (154).
    pub component: u8,
    /// Where the extension fields start in the payload (the base fields' length).
    extension_at: usize,
    /// The extension fields' bytes (little-endian, in the message definition's order).
    extension: Vec<u8>,
}

impl From<MavMessage> for Outgoing {
    fn from(message: MavMessage) -> Self {
        Self {
            message,
            component: COMPONENT_ID,
            extension_at: 0,
            extension: Vec::new(),
        }
    }
}

impl Outgoing {
    /// `message` (a `D`) followed by the bytes of its extension fields.
    pub fn extended<D: MessageData>(message: MavMessage, extension: Vec<u8>) -> Self {
        Self {
            message,
            component: COMPONENT_ID,
            extension_at: D::ENCODED_LEN,
            extension,
        }
    }

    /// The same message from another component.
    pub fn from_component(self, component: u8) -> Self {
        Self { component, ..self }
    }

    /// The extension bytes (empty without).
    pub fn extension(&self) -> &[u8] {
        &self.extension
    }

    /// Writes the MAVLink 2 payload into `buf` (at least 255 bytes): the base fields, then the
    /// extension, trailing zeros trimmed; its length.
    fn payload(&self, buf: &mut [u8]) -> usize {
        let n = self.message.ser(MavlinkVersion::V2, buf);
        if self.extension.is_empty() {
            return n;
        }
        let end = (self.extension_at + self.extension.len()).min(buf.len());
        let at = self.extension_at.min(end);
        // `ser` wrote every base field (then trimmed the length): the bytes up to `at` are set.
        buf[at..end].copy_from_slice(&self.extension[..end - at]);
        let mut len = end;
        while len > 1 && buf[len - 1] == 0 {
            len -= 1;
        }
        len
    }
}

/// An [`Outgoing`] as the `mavlink` crate frames it.
#[derive(Debug)]
pub struct Framed<'a>(pub &'a Outgoing);

impl Message for Framed<'_> {
    fn message_id(&self) -> u32 {
        self.0.message.message_id()
    }
    fn message_name(&self) -> &'static str {
        self.0.message.message_name()
    }
    fn target_system_id(&self) -> Option<u8> {
        self.0.message.target_system_id()
    }
    fn target_component_id(&self) -> Option<u8> {
        self.0.message.target_component_id()
    }
    fn target_system_id_mut(&mut self) -> Option<&mut u8> {
        None
    }
    fn target_component_id_mut(&mut self) -> Option<&mut u8> {
        None
    }
    fn ser(&self, version: MavlinkVersion, bytes: &mut [u8]) -> usize {
        match version {
            MavlinkVersion::V2 => self.0.payload(bytes),
            MavlinkVersion::V1 => self.0.message.ser(version, bytes),
        }
    }
    fn parse(
        _version: MavlinkVersion,
        msgid: u32,
        _payload: &[u8],
    ) -> Result<Self, mavlink::error::ParserError> {
        // Only for sending.
        Err(mavlink::error::ParserError::UnknownMessage { id: msgid })
    }
    fn message_id_from_name(name: &str) -> Option<u32> {
        MavMessage::message_id_from_name(name)
    }
    fn default_message_from_id(_id: u32) -> Option<Self> {
        None
    }
    fn extra_crc(id: u32) -> u8 {
        MavMessage::extra_crc(id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::frame::parse_datagram;
    use mavlink::MavHeader;
    use mavlink::dialects::common::MISSION_COUNT_DATA;

    /// A fence MISSION_COUNT framed with its `mission_type` reads back as one; without the
    /// extension it reads as a mission (0); its CRC is the message's.
    #[test]
    fn mission_type_travels_in_the_extension_bytes() {
        let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 3,
            target_system: 255,
            target_component: 190,
        });
        let header = MavHeader {
            system_id: 7,
            component_id: 1,
            sequence: 0,
        };
        for (ext, expected) in [(vec![1u8], 1u8), (vec![], 0), (vec![2, 0, 0, 0, 0], 2)] {
            let out = Outgoing::extended::<MISSION_COUNT_DATA>(count.clone(), ext);
            let mut bytes = Vec::new();
            mavlink::write_v2_msg(&mut bytes, header, &Framed(&out)).expect("write");
            let parsed = parse_datagram(&bytes);
            assert_eq!(parsed.malformed, 0);
            let frame = &parsed.frames[0];
            assert_eq!(frame.message, count);
            let incoming = Incoming::of(frame);
            assert_eq!((incoming.mission_type, incoming.sender), (expected, (7, 1)));
        }
    }
}
