//! `harrier-sim`: simulated UAVs (skeleton).
//!
//! The vehicle simulator (MAVLink, targets, sensors, Zenoh detections) is not built yet; this
//! binary only reports that, so scripts that call it fail with a clear message.
//!
//! ```not_rust
//! cargo run -p harrier-sim -- --help
//! ```

use clap::Parser;

/// Simulated UAVs for Harrier (not implemented yet: see the project's issues).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {}

fn main() -> std::process::ExitCode {
    let _args = Args::parse();
    eprintln!("harrier-sim: the vehicle simulator is not implemented yet");
    std::process::ExitCode::from(2)
}
