//! `vatcal plan` (being written).

/// Arguments of `vatcal plan`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal plan` is not implemented yet")
}
