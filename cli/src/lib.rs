//! # harrier-cli
//!
//! The `harrier` command (`src/main.rs`): one subcommand per program of the workspace, each a
//! library of its own. This crate's library holds only what joins them:
//!
//! * [`demo`] (`harrier demo`): the live service ([`harrier_server`]) with harrier-sim's world
//!   in-process; the one place outside the tests where the service and the simulator meet.
//! * [`tiles`] (`harrier tiles`): MBTiles files for the dashboard's map, rendered from a
//!   deployment's roads and obstacles.
//! * [`offline_map`]: a deployment's world for the tile renderer, and the demo's offline map
//!   (rendered once, cached), which both of the above use.
//! * [`init_logging`]: the structured logs every subcommand writes; [`error_message`]: an
//!   error as the commands print it.
//!
//! The others: `harrier serve` is [`harrier_server::start`], `harrier replay`, `guidance-sim`,
//! `gen-multi` and `sessions` are the offline tools of `harrier_tools`, `harrier bench` is
//! `harrier_bench`, and `harrier estimators` lists [`harrier_engine::registry`].

pub mod demo;
pub mod offline_map;
pub mod tiles;

/// Structured logs on stderr for the `harrier` commands: the `RUST_LOG` filter if set, else
/// `default`; colours only when stderr is a terminal (a redirected log gets no escape codes).
/// A second call keeps the first subscriber.
pub fn init_logging(default: &str) {
    use std::io::IsTerminal as _;
    use tracing_subscriber::EnvFilter;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default)),
        )
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}

/// `e` and its causes as one message, each text once (an error that quotes its cause, as
/// thiserror's `{source}` does, would otherwise print it twice), and when an address was taken
/// (`EADDRINUSE`) what to do: another `harrier demo` or `harrier serve` may hold the port.
pub fn error_message(e: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !message.contains(&text) {
            if !message.is_empty() {
                message.push_str(": ");
            }
            message.push_str(&text);
        }
    }
    let taken = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::AddrInUse)
    }) || message.contains("os error 98");
    if taken {
        message.push_str(
            "\n  the address is taken: another `harrier demo` or `harrier serve` may be running \
             (stop it), or choose free ones: `--listen 127.0.0.1:PORT` for the page and the API, \
             `--gcs udpin:127.0.0.1:PORT` for the GCS link, `--router none` (or other \
             endpoints) for the MAVLink router",
        );
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot listen on 127.0.0.1:8080: {source}")]
    struct Bind {
        source: std::io::Error,
    }

    #[test]
    fn a_taken_address_is_said_once_with_what_to_do() {
        let io = std::io::Error::from(std::io::ErrorKind::AddrInUse);
        let text = io.to_string();
        let e = anyhow::Error::new(Bind { source: io });
        let m = error_message(&e);
        assert_eq!(m.matches(&text).count(), 1, "{m}");
        assert!(m.starts_with("cannot listen on 127.0.0.1:8080: "), "{m}");
        assert!(
            m.contains("another `harrier demo`") && m.contains("--listen"),
            "{m}"
        );
        let plain = anyhow::anyhow!("no such file").context("sessions.sqlite");
        assert_eq!(error_message(&plain), "sessions.sqlite: no such file");
    }
}
