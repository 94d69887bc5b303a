//! Oracle study of the discovery stage (issue 11): which hidden effects of the paper-like truth
//! carry the gap between the discovered model and the true-structure floor.
//!
//! Reads a finished `vatcal demo` run folder (`measurements.csv`, `discovery_measurements.csv`,
//! `validation_random.csv`, `calibrated.toml`), rebuilds the hidden truth of the seed and fits
//! the true structure with one group of effects left out, and only that group, reporting the
//! mean tracker-validation error on the random poses of each fit.
//!
//! `cargo run --release -p vatcal-demo --example discovery_oracle -- RUN_DIR SEED`

use std::path::PathBuf;

use vatcal_core::effects::EffectSpec;
use vatcal_core::{CellFile, Measurement};
use vatcal_kinematics::Model;
use vatcal_pipeline::discovery_stage::true_structure_fit;
use vatcal_sim::truth::TruthSpec;

fn group(spec: &EffectSpec) -> &'static str {
    match *spec {
        EffectSpec::JointCyclic { harmonic: 1, .. } => "cyclic h1",
        EffectSpec::JointCyclic { harmonic: 2, .. } => "cyclic h2",
        EffectSpec::JointCyclic { harmonic: 3 | 4, .. } => "cyclic h3-4",
        EffectSpec::JointCyclic { .. } => "cyclic h200",
        EffectSpec::JointBacklash { .. } => "backlash",
        EffectSpec::GuideAngular { .. } => "guide-angular",
        EffectSpec::GuideStraightness { .. } => "guide-straightness",
        EffectSpec::GuideCarriageTilt => "carriage-tilt",
        EffectSpec::ToolFrame => "tool-frame",
        EffectSpec::ThermalDrift { .. } => "thermal",
        _ => "other",
    }
}

fn mean_error(model: &Model, ms: &[Measurement]) -> f64 {
    let e: Vec<f64> = ms.iter().filter_map(|m| model.residual(m).ok()).map(|r| r.norm()).collect();
    e.iter().sum::<f64>() / e.len().max(1) as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().ok_or("usage: discovery_oracle RUN_DIR SEED")?);
    let seed: u64 = args.next().ok_or("usage: discovery_oracle RUN_DIR SEED")?.parse()?;
    let nominal = Model::from_cell(&CellFile::load(dir.join("nominal.toml"))?)?;
    let calibrated = Model::from_cell(&CellFile::load(dir.join("calibrated.toml"))?)?;
    let mut probe = vatcal_io::read_measurements(dir.join("measurements.csv"), &nominal)?;
    let calibration_count = probe.len();
    probe.extend(vatcal_io::read_measurements(dir.join("discovery_measurements.csv"), &nominal)?);
    let validation = vatcal_io::read_measurements(dir.join("validation_random.csv"), &nominal)?;
    let truth = TruthSpec::PaperLike.build(&nominal, seed)?.model;
    let effects = truth.effects().to_vec();
    println!(
        "seed {seed}: {} probe measurements ({calibration_count} calibration), {} validation poses",
        probe.len(),
        validation.len()
    );
    println!("truth itself (tracker/registration floor): {:.4} mm", mean_error(&truth, &validation));
    println!("calibrated (34): {:.4} mm", mean_error(&calibrated, &validation));
    // the calibration's parameter set: the paper's 34 on the canonical cell
    let base = vatcal_core::ParamSet::paper34();
    let fit = |specs: &[EffectSpec], ms: &[Measurement]| -> String {
        match true_structure_fit(&calibrated, ms, &base, specs) {
            Ok((m, _)) => format!("{:.4}", mean_error(&m, &validation)),
            Err(e) => format!("failed: {e}"),
        }
    };
    println!("true structure, all probe data: {} mm", fit(&effects, &probe));
    let half: Vec<Measurement> = probe.iter().step_by(2).copied().collect();
    println!("true structure, every 2nd probe measurement: {} mm", fit(&effects, &half));
    let mut groups: Vec<&str> = effects.iter().map(group).collect();
    groups.dedup();
    groups.sort_unstable();
    groups.dedup();
    println!("| group | true structure without it [mm] | paper34 + only it [mm] |");
    for g in groups {
        let without: Vec<EffectSpec> = effects.iter().copied().filter(|s| group(s) != g).collect();
        let only: Vec<EffectSpec> = effects.iter().copied().filter(|s| group(s) == g).collect();
        println!("| {g} | {} | {} |", fit(&without, &probe), fit(&only, &probe));
    }
    Ok(())
}
