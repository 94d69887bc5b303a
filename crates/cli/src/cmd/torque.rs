//! `vatcal torque`: gravity torques of each row.

use std::io::Write;

/// Arguments of `vatcal torque` (the same as `vatcal fk`).
pub type Args = super::fk::Args;

/// Prints `tau{i}` \[N·m\] of every revolute joint i (moment of gravity about +z_i, on the
/// model's own geometry with zero compliance; `tau2..tau7` on the canonical cell) per input
/// row, in order.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(&args.model)?;
    let rows = vatcal_io::read_joint_rows(&args.input, &model)?;
    let mut out = std::io::stdout().lock();
    let joints: Vec<usize> = (1..=model.joint_count()).filter(|i| model.is_revolute(*i)).collect();
    let header: Vec<String> = joints.iter().map(|i| format!("tau{i}")).collect();
    writeln!(out, "{}", header.join(","))?;
    for row in rows {
        let t = model.gravity_torques(&row.q);
        let values: Vec<String> = joints.iter().map(|i| t[i - 1].to_string()).collect();
        writeln!(out, "{}", values.join(","))?;
    }
    Ok(())
}
