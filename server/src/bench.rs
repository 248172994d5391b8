//! `harrier bench`: the live service's load tool. (Being built: issue 12.)

/// Arguments of `harrier bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {}

/// Runs the load test and prints its figures.
pub fn run(_args: &BenchArgs) -> anyhow::Result<()> {
    anyhow::bail!("harrier bench is not built yet")
}
