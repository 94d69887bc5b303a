//! `vatcal select` (being written).

/// Arguments of `vatcal select`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal select` is not implemented yet")
}
