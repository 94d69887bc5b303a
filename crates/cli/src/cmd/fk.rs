//! `vatcal fk`: world position of each row's TCP.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;

/// Arguments of `vatcal fk` and `vatcal torque`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file (TOML, format meca500-zaber-cell v1 or serial-robot-cell v2).
    #[arg(long)]
    pub model: PathBuf,
    /// Joint rows: CSV with columns tcp,q1..qN for the model's N joints (mm for prismatic,
    /// degrees for revolute joints; canonical cell: q1 in mm, q2..q7 in degrees), and the
    /// optional context columns time_s, temperature_c, dir{i} of the revolute joints (required
    /// when the model has an effect that depends on them: backlash, thermal drift).
    #[arg(long)]
    pub input: PathBuf,
    /// Units, limit tolerance and directions of the input file.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// Prints `x,y,z` (world, mm) per input row, in order, with each row's context (approach
/// directions, time, temperature) applied to the model's effects.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(&args.model)?;
    let rows = args.read.joint_rows(&args.input, &model)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "x,y,z")?;
    for row in rows {
        let p = model
            .tcp_position_ctx(&row.q, &row.context, row.tcp)
            .with_context(|| format!("{}:{}", args.input.display(), row.line))?;
        writeln!(out, "{},{},{}", p.x, p.y, p.z)?;
    }
    Ok(())
}
