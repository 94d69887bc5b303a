//! `vatcal identify` (being written).

/// Arguments of `vatcal identify`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal identify` is not implemented yet")
}
