//! `vatcal torque`: gravity torques of each row.

use std::io::Write;

/// Arguments of `vatcal torque` (the same as `vatcal fk`).
pub type Args = super::fk::Args;

/// Prints `tau2..tau7` [N·m] (moment of gravity about +z_i, on the model's own geometry with
/// zero compliance) per input row, in order.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(&args.model)?;
    let rows = vatcal_io::read_joint_rows(&args.input, &model)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "tau2,tau3,tau4,tau5,tau6,tau7")?;
    for row in rows {
        let t = model.gravity_torques(&row.q);
        writeln!(out, "{},{},{},{},{},{}", t[0], t[1], t[2], t[3], t[4], t[5])?;
    }
    Ok(())
}
