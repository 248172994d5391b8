//! One TCP connection of a link ([`TcpConn`]): the non-blocking stream, its receive parser and
//! its bounded send backlog.

use std::io::{self, Read, Write};
use std::net::TcpStream;

use harrier_link::frame::StreamParser;
use harrier_link::signing::Signer;

use super::received::{Peer, Received};

/// Most bytes queued for a slow TCP peer; further frames to it are dropped (telemetry is lossy,
/// and a frame is never cut).
const MAX_TX_BACKLOG: usize = 256 * 1024;

/// Most reads from one TCP connection per poll (the rest waits for the next tick).
const MAX_TCP_READS: usize = 16;

/// One TCP connection: non-blocking stream, receive parser and send backlog.
#[derive(Debug)]
pub(super) struct TcpConn {
    pub(super) id: u64,
    stream: TcpStream,
    parser: StreamParser,
    backlog: Vec<u8>,
}

impl TcpConn {
    pub(super) fn new(id: u64, stream: TcpStream) -> io::Result<Self> {
        stream.set_nonblocking(true)?;
        stream.set_nodelay(true)?;
        Ok(Self {
            id,
            stream,
            parser: StreamParser::default(),
            backlog: Vec::new(),
        })
    }

    /// Reads what is available (at most [`MAX_TCP_READS`] buffers, so that a flooding client
    /// cannot stall the loop); `None` when the connection is closed or broken.
    pub(super) fn receive(&mut self, buf: &mut [u8], signer: Option<&Signer>) -> Option<Received> {
        let mut got = Received::new(Peer::Tcp(self.id));
        for _ in 0..MAX_TCP_READS {
            match self.stream.read(buf) {
                Ok(0) => return None,
                Ok(n) => {
                    let p = self.parser.push(&buf[..n]);
                    got.malformed += p.malformed;
                    got.take(p.frames, signer);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(_) => return None,
            }
        }
        Some(got)
    }

    /// Queues a frame and writes as much of the backlog as the socket takes; `false` when the
    /// connection is broken.
    pub(super) fn send(&mut self, frame: &[u8]) -> bool {
        if self.backlog.len() + frame.len() <= MAX_TX_BACKLOG {
            self.backlog.extend_from_slice(frame);
        }
        self.flush()
    }

    pub(super) fn flush(&mut self) -> bool {
        while !self.backlog.is_empty() {
            match self.stream.write(&self.backlog) {
                Ok(0) => return false,
                Ok(n) => {
                    self.backlog.drain(..n);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return true,
                Err(_) => return false,
            }
        }
        true
    }
}
