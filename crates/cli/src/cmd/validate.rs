//! `vatcal validate` (being written).

/// Arguments of `vatcal validate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal validate` is not implemented yet")
}
