//! `vatcal import-urdf`: a cell file (format `serial-robot-cell`, version 2) from the serial chain
//! between any two links of a URDF tree, up the tree where it must (see docs/urdf.md).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, bail};
use vatcal_core::{JointKind, JointVector};
use vatcal_kinematics::Model;
use vatcal_urdf::UrdfFk;

/// Arguments of `vatcal import-urdf`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// URDF file.
    pub urdf: PathBuf,
    /// Link the chain starts at; its frame becomes the cell's world frame (z up is assumed for
    /// gravity). Any link of the tree: the chain goes up from it to the lowest common ancestor
    /// of the two links (those joints reversed), then down to the tip link.
    #[arg(long)]
    pub base_link: String,
    /// Link the chain ends at; its origin becomes TCP 1.
    #[arg(long)]
    pub tip_link: String,
    /// Cell file to write (TOML).
    #[arg(long)]
    pub out: PathBuf,
}

/// Joint vectors used to check the written model against the URDF (deterministic, inside the
/// limits; +-180 deg for continuous joints).
fn check_vectors(chain: &vatcal_urdf::ImportedChain, count: usize) -> Vec<Vec<f64>> {
    (0..count)
        .map(|s| {
            chain
                .joints
                .iter()
                .enumerate()
                .map(|(k, j)| {
                    let u = 0.5 + 0.5 * ((s * 13 + k * 7) as f64 * 0.618).sin(); // 0..1
                    let (lo, hi) = match (j.q_min, j.q_max, j.kind) {
                        (Some(lo), Some(hi), _) => (lo, hi),
                        (_, _, JointKind::Revolute) => (-180.0, 180.0),
                        (_, _, JointKind::Prismatic) => (0.0, 0.0),
                    };
                    lo + (hi - lo) * u
                })
                .collect()
        })
        .collect()
}

/// Imports, checks the model vatcal builds from the cell against the URDF's own forward
/// kinematics, writes the cell and prints a summary.
pub fn run(args: Args) -> anyhow::Result<()> {
    let origin = args.urdf.display().to_string();
    let text =
        std::fs::read_to_string(&args.urdf).with_context(|| format!("cannot read URDF file {origin}"))?;
    let chain = vatcal_urdf::import_str(&text, &origin, &args.base_link, &args.tip_link)?;
    let cell = chain.to_cell(&origin);
    let model = Model::from_cell(&cell).context("the imported chain does not make a valid model")?;
    let fk = UrdfFk::new(&text, &origin, &args.base_link, &args.tip_link)?;
    let kinds: Vec<JointKind> = chain.joints.iter().map(|j| j.kind).collect();
    let vectors = check_vectors(&chain, 100);
    let mut worst: f64 = 0.0;
    for q in &vectors {
        let jv = JointVector::from_file_units(q, &kinds)?;
        let ours = model.tcp_position(&jv, 1)?;
        let theirs = fk.tip_position_mm(q).context("joint count")?;
        worst = worst.max((ours - nalgebra::Vector3::from(theirs)).norm());
    }
    if worst.is_nan() || worst > 1e-6 {
        bail!(
            "{origin}: the imported model misses the URDF's forward kinematics by {worst:e} mm (a bug; please report)"
        );
    }
    cell.save(&args.out)?;

    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{} ({} joints, {} -> {}) written to {}",
        chain.robot_name,
        chain.joints.len(),
        chain.base_link,
        chain.tip_link,
        args.out.display()
    )?;
    writeln!(
        out,
        "{:>3}  {:<24}  {:<9}  {:>10}  {:>10}  {:>9}  {:>10}  {:>10}  limits",
        "row", "joint", "kind", "alpha_deg", "a_mm", "beta_deg", "theta_deg", "d_mm"
    )?;
    for (k, j) in chain.joints.iter().enumerate() {
        let limits = match (j.q_min, j.q_max) {
            (Some(lo), Some(hi)) => format!("{lo} .. {hi}"),
            _ => "none (continuous)".into(),
        };
        writeln!(
            out,
            "{:>3}  {:<24}  {:<9}  {:>10}  {:>10}  {:>9}  {:>10}  {:>10}  {limits}",
            k + 1,
            j.name,
            j.kind.name(),
            j.alpha_deg,
            j.a_mm,
            j.beta_deg,
            j.theta_deg,
            j.d_mm
        )?;
    }
    let mass: f64 = chain.inertials.iter().map(|i| i.mass_kg).sum();
    writeln!(
        out,
        "TCP 1 (origin of {}) in frame {}: {:?} mm",
        chain.tip_link,
        chain.joints.len(),
        chain.tcp_mm
    )?;
    writeln!(
        out,
        "moving mass {mass:.3} kg in {} frames; tool 0 kg (add yours in [inertials.tool])",
        chain.inertials.len()
    )?;
    for n in &chain.notes {
        writeln!(out, "note: {n}")?;
    }
    writeln!(out, "check: FK of the model vs the URDF at {} joint vectors: max {worst:e} mm", vectors.len())?;
    writeln!(
        out,
        "edit before calibrating: [gravity] (base link z up assumed), [[calibration_positions]] (placeholder id 1 = TCP 1 at q = 0), [[tcps]], [inertials.tool]"
    )?;
    Ok(())
}
