//! Plans a calibration campaign with the library calls of `vatcal plan` (default options, the
//! chain's default parameter set) and a chosen inverse kinematics, and prints the phases'
//! times, the candidate stage counts and the O1 of the selection (`docs/performance.md`,
//! issue 31 item 5):
//!
//! ```text
//! cargo run --release -p vatcal-benches --example plan_ik -- CELL.toml SEED IK [ORIENTATIONS]
//! ```
//!
//! `IK` is `closed` (a closed form where the chain has one: the default of `vatcal plan`),
//! `before` (the spherical-wrist closed form or the numerical IK, cold: the planner before
//! issue 31), `numeric-cold` or `numeric-warm` (always the numerical IK, without / with warm
//! starts).

use std::process::ExitCode;
use std::time::Instant;

use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;
use vatcal_planning::candidates::{CandidateOptions, IkChoice};
use vatcal_planning::plan::{PlanOptions, campaign_candidates, plan_campaign};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (cell, seed, ik, orientations) = match args.as_slice() {
        [_, cell, seed, ik] => (cell, seed, ik, "500"),
        [_, cell, seed, ik, orientations] => (cell, seed, ik, orientations.as_str()),
        _ => {
            eprintln!("usage: plan_ik CELL.toml SEED closed|before|numeric-cold|numeric-warm [ORIENTATIONS]");
            return ExitCode::FAILURE;
        }
    };
    match run(cell, seed, ik, orientations) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cell_path: &str, seed: &str, ik: &str, orientations: &str) -> Result<(), Box<dyn std::error::Error>> {
    let (ik, warm_start) = match ik {
        "closed" => (IkChoice::ClosedFormFirst, true),
        "before" => (IkChoice::WithoutParallelClosedForm, false),
        "numeric-cold" => (IkChoice::Numerical, false),
        "numeric-warm" => (IkChoice::Numerical, true),
        other => return Err(format!("unknown IK `{other}`").into()),
    };
    let cell = CellFile::load(cell_path)?;
    let model = Model::from_cell(&cell)?;
    let geometry = CellGeometry::from_cell(&cell)?;
    let params = if model.is_meca500_on_guide() {
        vatcal_core::canonical::default_param_set()
    } else {
        ParamSet(Vec::new())
    };
    let opts = PlanOptions {
        candidates: CandidateOptions {
            orientations: orientations.parse()?,
            ik,
            warm_start,
            ..CandidateOptions::default()
        },
        params,
        motion: cell.motion_limits(),
        seed: seed.parse()?,
        ..PlanOptions::default()
    };
    let (t0, c0) = (Instant::now(), vatcal_benches::cpu_ns());
    let candidates = campaign_candidates(&model, &geometry, &opts)?;
    let (t1, c1) = (Instant::now(), vatcal_benches::cpu_ns());
    let plan = plan_campaign(&model, &geometry, &opts)?;
    let (t2, c2) = (Instant::now(), vatcal_benches::cpu_ns());
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    let cpu = |a: u64, b: u64| b.saturating_sub(a) as f64 * 1e-6;
    println!("IK: {}", candidates.ik);
    println!("counts: {:?}", candidates.counts);
    println!("candidates alone            {:8.1} ms wall {:8.1} ms CPU", ms(t0, t1), cpu(c0, c1));
    println!("whole plan_campaign         {:8.1} ms wall {:8.1} ms CPU", ms(t1, t2), cpu(c1, c2));
    println!(
        "O1 of the selection {:.6} ({} parameters), O1 of all {} candidates {:.4}",
        plan.quality.raw.o1,
        plan.params.len(),
        plan.candidates.candidates.len(),
        plan.quality.candidates_o1
    );
    Ok(())
}
