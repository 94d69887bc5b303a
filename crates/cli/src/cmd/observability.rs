//! `vatcal observability` (being written).

/// Arguments of `vatcal observability`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal observability` is not implemented yet")
}
