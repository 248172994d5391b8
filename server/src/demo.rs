//! `harrier demo`: the server, an in-process Zenoh peer and simulated vehicles in one process.
//! (Being built: issue 12.)

/// Arguments of `harrier demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {}

/// Runs the demo until interrupted.
pub fn run(_args: &DemoArgs) -> anyhow::Result<()> {
    anyhow::bail!("harrier demo is not built yet")
}
