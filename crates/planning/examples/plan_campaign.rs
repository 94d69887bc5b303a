//! Plans a small calibration campaign for the Meca500 alone on a table
//! (`fixtures/meca500-table.toml`, a version-2 cell without a guide): candidate poses from the
//! multi-start numerical IK (screened for joint limits, singularities and collisions with the
//! cell's obstacles), a Detmax selection of 40 that identifies the chain's default parameter
//! set, the time-optimised visiting order and a collision-free path for every leg.
//!
//! ```text
//! cargo run -p vatcal-planning --example plan_campaign
//! ```
//!
//! For a real campaign raise `orientations` (the paper uses 500 per TCP and position) and the
//! restarts; `vatcal plan` does the same from the command line and writes the plan's files
//! (`vatcal_planning::output::write_plan`).

use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::plan::{PlanOptions, StepKind, plan_campaign};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?;
    let model = Model::from_cell(&cell)?;
    // the obstacles, probe and robot bodies the collision checks use
    let geometry = CellGeometry::from_cell(&cell)?;
    let opts = PlanOptions {
        candidates: CandidateOptions { orientations: 12, ..CandidateOptions::default() },
        count: 40,
        // empty: the chain's identifiable default set (the paper's 34 only on the canonical cell)
        params: ParamSet(Vec::new()),
        detmax_restarts: 1,
        tour_restarts: 2,
        motion: cell.motion_limits(),
        seed: 4,
        ..PlanOptions::default()
    };
    let plan = plan_campaign(&model, &geometry, &opts)?;

    let (counts, selected) = plan.counts();
    println!("candidates: {counts:?}");
    println!(
        "selected {selected} poses identifying {} parameters (rank {}), O1 = {:.3e} (all candidates: {:.3e})",
        plan.params.len(),
        plan.quality.raw.rank,
        plan.quality.raw.o1,
        plan.quality.candidates_o1
    );
    println!(
        "tour: {} steps, {} probe re-placements, about {:.0} s along the planned paths ({:.0} s in a shuffled order)",
        plan.steps.len(),
        plan.timing.replacements,
        plan.timing.planned_paths_s,
        plan.timing.shuffled_order_s
    );
    for step in plan.steps.iter().filter(|s| s.kind == StepKind::Measure).take(3) {
        println!(
            "  measure TCP {} on position {} at q = {:.2?} (file units), t = {:.0} s",
            step.tcp,
            step.position,
            step.q.to_file_units(model.joint_kinds()),
            step.time_s
        );
    }
    // every measurement puts its TCP on its calibration position (IK checked by FK)
    for &i in &plan.order {
        let c = &plan.candidates.candidates[i];
        let miss = (model.tcp_position(&c.q, c.tcp)? - model.position(c.position).ok_or("position")?).norm();
        if miss > 1e-6 {
            return Err(format!("candidate {i} misses its position by {miss} mm").into());
        }
    }
    Ok(())
}
