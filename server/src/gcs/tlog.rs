//! The raw MAVLink log (`.tlog`, as QGroundControl and MAVProxy write it): every frame after its
//! 8-byte big-endian UNIX time in µs, appended by a writer thread fed by `try_send`, so the link
//! actor never waits for the disk; a full queue drops the frame (the actor counts it).

use std::io::Write as _;
use std::path::Path;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::time::{Duration, Instant};

/// Frames waiting for the writer before new ones are dropped.
const QUEUE: usize = 16_384;
/// Longest time a written frame waits in the writer's buffer.
const FLUSH_EVERY: Duration = Duration::from_millis(200);

/// An open `.tlog` and its writer thread (which stops when this is dropped).
#[derive(Debug)]
pub(super) struct Tlog {
    tx: SyncSender<(u64, Vec<u8>)>,
}

impl Tlog {
    /// Opens `path` for appending (created if missing) and starts the writer thread.
    pub(super) fn create(path: &Path) -> std::io::Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)?;
        let (tx, rx) = std::sync::mpsc::sync_channel(QUEUE);
        std::thread::Builder::new()
            .name("harrier-tlog".into())
            .spawn(move || write(file, &rx))?;
        Ok(Self { tx })
    }

    /// Queues `frame`, stamped `unix_us`; `false` when it was dropped (the queue is full, or the
    /// writer stopped after a failed write).
    pub(super) fn append(&self, unix_us: u64, frame: &[u8]) -> bool {
        match self.tx.try_send((unix_us, frame.to_vec())) {
            Ok(()) => true,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => false,
        }
    }
}

/// The writer thread: appends what `rx` brings, flushes at least every [`FLUSH_EVERY`], and
/// stops at the first failed write or when the [`Tlog`] is gone.
fn write(file: std::fs::File, rx: &Receiver<(u64, Vec<u8>)>) {
    let mut w = std::io::BufWriter::new(file);
    let mut last_flush = Instant::now();
    loop {
        match rx.recv_timeout(FLUSH_EVERY) {
            Ok((us, frame)) => {
                if w.write_all(&us.to_be_bytes()).is_err() || w.write_all(&frame).is_err() {
                    tracing::warn!("tlog: write failed; raw logging stops");
                    return;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                let _ = w.flush();
                return;
            }
        }
        if last_flush.elapsed() >= FLUSH_EVERY {
            let _ = w.flush();
            last_flush = Instant::now();
        }
    }
}
