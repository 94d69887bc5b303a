//! `vatcal demo` (being written).

/// Arguments of `vatcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal demo` is not implemented yet")
}
