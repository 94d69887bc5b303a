//! `vatcal fk` (being written).

/// Arguments of `vatcal fk`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal fk` is not implemented yet")
}
