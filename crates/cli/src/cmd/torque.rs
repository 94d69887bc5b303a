//! `vatcal torque` (being written).

/// Arguments of `vatcal torque`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`vatcal torque` is not implemented yet")
}
