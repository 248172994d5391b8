//! Recorded sessions (the SQLite files of the live recorder): list and export as
//! `gcs-scenario/1`. (Being built: issue 12.)

/// Arguments of `harrier sessions`.
#[derive(Debug, clap::Args)]
pub struct SessionsArgs {}

/// Runs `harrier sessions`.
pub fn run(_args: &SessionsArgs) -> anyhow::Result<()> {
    anyhow::bail!("harrier sessions is not built yet")
}
