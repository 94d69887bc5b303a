//! D-optimal pose selection (Detmax) on a small candidate set, and what it can identify.
//!
//! 240 candidate probe poses of the canonical cell (random joints, then position IK onto one
//! of the three calibration positions: `vatcal_sim::truth::probe_start_poses`) are reduced to
//! the 40 that maximise `det(JᵀJ)` for the paper's 34 parameters. The selection's observability
//! indices are compared with 40 poses taken at random, then the identifiability analysis of a
//! larger parameter set names the parameters the data cannot separate.
//!
//! ```text
//! cargo run -p vatcal-observability --example detmax_select
//! ```

use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax};
use vatcal_observability::indices::indices_of;
use vatcal_observability::{ColumnScaling, analyze};
use vatcal_sim::truth::probe_start_poses;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let model = Model::from_cell(&cell)?;
    let poses = probe_start_poses(&model, 240, 1);
    let params = ParamSet::paper34();
    let candidates = Candidates::from_measurements(&model, &poses, &params)?;
    println!("{} candidates × {} parameters", candidates.len(), candidates.parameter_count());

    let options = DetmaxOptions { restarts: 4, seed: 7, ..DetmaxOptions::new(40) };
    let selection = detmax(&candidates, &options)?;
    println!(
        "Detmax: 40 poses, ln det = {:.3}, best of {} restarts (restart {})",
        selection.log_det,
        selection.restarts.len(),
        selection.best_restart
    );
    let chosen: Vec<Measurement> = selection.selected.iter().map(|&k| poses[k]).collect();
    let random: Vec<Measurement> = poses[..40].to_vec(); // the candidates are in random order
    let best = indices_of(&model, &chosen, &params, ColumnScaling::UnitNorm)?;
    let rand = indices_of(&model, &random, &params, ColumnScaling::UnitNorm)?;
    println!("              O1         condition   sigma_min  (unit-norm columns)");
    println!("Detmax  {:12.4e} {:12.1} {:11.4e}", best.o1, best.condition_number, best.sigma_min);
    println!("random  {:12.4e} {:12.1} {:11.4e}", rand.o1, rand.condition_number, rand.sigma_min);
    if best.o1 < rand.o1 {
        return Err("Detmax must beat a random design on its own criterion".into());
    }

    // which parameters could these 40 poses NOT separate, if we also asked for a_1, d_2 and
    // the TCP coordinates?
    let mut wider = params.clone();
    wider.0.extend([ParamId::A(2), ParamId::D(2)]);
    wider.0.extend(
        ParamSet::all_builtin(&model.tcp_ids(), &[]).iter().filter(|p| matches!(p, ParamId::Tcp { .. })),
    );
    let report = analyze(&model, &chosen, &wider)?;
    println!("{} parameters, rank {}; redundant:", report.parameter_count, report.rank);
    for r in report.redundant.iter().take(6) {
        println!("  {}", r.sentence());
    }
    Ok(())
}
