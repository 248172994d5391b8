//! What a poll of a link's transports yields: the messages of one peer ([`Received`]) and where
//! they came from ([`Peer`]), so that replies go back there.

use std::net::SocketAddr;

use harrier_link::frame::Frame;
use harrier_link::signing::{Rejection, Signer};

/// Where a message came from, so that its replies go back there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Peer {
    /// A UDP sender.
    Udp(SocketAddr),
    /// A TCP connection of the link, by its number.
    Tcp(u64),
}

/// Messages received from one peer in one poll.
#[derive(Debug)]
pub(super) struct Received {
    pub(super) from: Peer,
    /// The frames accepted (message, sender, bytes).
    pub(super) frames: Vec<Frame>,
    /// Datagrams without a valid frame, skipped stretches of a stream, undecodable frames.
    pub(super) malformed: u64,
    /// Frames refused by the signature check.
    pub(super) rejected: Vec<Rejection>,
}

impl Received {
    pub(super) fn new(from: Peer) -> Self {
        Self {
            from,
            frames: Vec::new(),
            malformed: 0,
            rejected: Vec::new(),
        }
    }

    /// Keeps the frames `signer` accepts (all of them without signing) and counts the others.
    pub(super) fn take(&mut self, frames: Vec<Frame>, signer: Option<&Signer>) {
        for f in frames {
            match signer.map_or(Ok(()), |s| s.check(&f)) {
                Ok(()) => self.frames.push(f),
                Err(r) => self.rejected.push(r),
            }
        }
    }
}
