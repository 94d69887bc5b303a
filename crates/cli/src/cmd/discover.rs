//! `vatcal discover` (being written).

/// Arguments of `vatcal discover`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal discover` is not implemented yet")
}
