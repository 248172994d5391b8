//! The server as a child process (`--server-process`): `harrier serve --config FILE` of this
//! binary (or `--server-bin`), started with the bench's configuration, its API address read from
//! its ready line, stopped with SIGINT. Its CPU and memory are then its own, apart from the
//! load's.

use std::io::{BufRead as _, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context as _;

/// Longest wait for the server's ready line.
const START_TIMEOUT: Duration = Duration::from_secs(60);
/// Longest wait for the server to stop after SIGINT, before SIGKILL.
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

/// A running `harrier serve`.
#[derive(Debug)]
pub(super) struct ServerProcess {
    child: Child,
    /// Its API.
    pub(super) addr: SocketAddr,
    config: PathBuf,
}

/// The API address of a `harrier serve: ready: http://ADDR/api/v1` line.
fn ready_addr(line: &str) -> Option<SocketAddr> {
    let rest = line.split("ready: http://").nth(1)?;
    rest.split('/').next()?.parse().ok()
}

impl ServerProcess {
    /// Writes `toml` to a temporary file and starts `bin serve --config FILE`; returns once it
    /// printed its ready line. Its later stderr lines are passed on to this process's.
    pub(super) fn start(bin: &Path, toml: &str) -> anyhow::Result<Self> {
        static RUN: AtomicU64 = AtomicU64::new(0);
        let config = std::env::temp_dir().join(format!(
            "harrier-bench-{}-{}.toml",
            std::process::id(),
            RUN.fetch_add(1, Relaxed)
        ));
        std::fs::write(&config, toml).with_context(|| format!("writing {}", config.display()))?;
        let mut child = Command::new(bin)
            .arg("serve")
            .arg("--config")
            .arg(&config)
            .env(
                "RUST_LOG",
                std::env::var("RUST_LOG").unwrap_or_else(|_| "warn".into()),
            )
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("starting {} serve", bin.display()))?;
        let stderr = child.stderr.take().context("the server's stderr")?;
        let (tx, rx) = mpsc::channel();
        std::thread::Builder::new()
            .name("bench-server-stderr".into())
            .spawn(move || {
                let mut ready = Some(tx);
                for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                    match ready_addr(&line) {
                        Some(addr) if ready.is_some() => {
                            if let Some(tx) = ready.take() {
                                let _ = tx.send(addr);
                            }
                        }
                        _ => eprintln!("[server] {line}"),
                    }
                }
            })?;
        let waited = Instant::now();
        let addr = loop {
            match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(addr) => break addr,
                Err(mpsc::RecvTimeoutError::Timeout) if waited.elapsed() < START_TIMEOUT => {
                    if let Some(status) = child.try_wait()? {
                        anyhow::bail!("the server exited before it was ready: {status}");
                    }
                }
                Err(_) => {
                    let _ = child.kill();
                    let _ = child.wait();
                    anyhow::bail!("the server printed no ready line within {START_TIMEOUT:?}");
                }
            }
        };
        Ok(Self {
            child,
            addr,
            config,
        })
    }

    /// Its process id.
    pub(super) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// SIGINT (the server shuts down in order), SIGKILL after [`STOP_TIMEOUT`].
    pub(super) fn stop(mut self) {
        use rustix::process::{Pid, Signal, kill_process};
        let _ = kill_process(Pid::from_child(&self.child), Signal::INT);
        let waited = Instant::now();
        while waited.elapsed() < STOP_TIMEOUT {
            if let Ok(Some(_)) = self.child.try_wait() {
                let _ = std::fs::remove_file(&self.config);
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        eprintln!("harrier bench: the server did not stop within {STOP_TIMEOUT:?}; killed");
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.config);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_ready_line_gives_the_api_address() {
        assert_eq!(
            super::ready_addr("harrier serve: ready: http://127.0.0.1:40123/api/v1"),
            Some("127.0.0.1:40123".parse().expect("address"))
        );
        assert_eq!(super::ready_addr("harrier serve: starting"), None);
    }
}
