//! Times the phases of `vatcal select` (same library calls as the CLI, O1, no ablation) on a
//! candidate file, to see where the whole-process time goes (`docs/performance.md`):
//!
//! ```text
//! cargo run --release -p vatcal-benches --example select_phases -- CELL.toml CANDIDATES.csv 40 1
//! ```

use std::process::ExitCode;
use std::time::Instant;

use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, selection_indices};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let [_, cell, candidates, count, restarts] = args.as_slice() else {
        eprintln!("usage: select_phases CELL.toml CANDIDATES.csv COUNT RESTARTS");
        return ExitCode::FAILURE;
    };
    match run(cell, candidates, count, restarts) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cell: &str, candidates: &str, count: &str, restarts: &str) -> Result<(), Box<dyn std::error::Error>> {
    let count: usize = count.parse()?;
    let restarts: usize = restarts.parse()?;
    let t0 = Instant::now();
    let mut last = (t0, vatcal_benches::cpu_ns());
    let mut lap = |what: &str| {
        let now = (Instant::now(), vatcal_benches::cpu_ns());
        println!(
            "{what:<28} {:8.2} ms wall {:8.2} ms CPU",
            (now.0 - last.0).as_secs_f64() * 1e3,
            now.1.saturating_sub(last.1) as f64 * 1e-6
        );
        last = now;
    };
    let model = Model::from_cell(&CellFile::load(cell)?)?;
    lap("load model");
    let table = vatcal_io::read_candidates(candidates, &model)?;
    lap("read candidates (CSV)");
    let params = ParamSet::paper34();
    let c = Candidates::from_measurements(&model, &table.measurements, &params)?;
    lap("candidate Jacobians");
    let opts = DetmaxOptions { restarts, seed: 7, excursions: None, ..DetmaxOptions::new(count) };
    let s = detmax(&c, &opts)?;
    lap("detmax");
    let i = selection_indices(&c, &s.selected)?;
    lap("selection indices");
    let out = std::env::temp_dir().join("select_phases_out.csv");
    table.write_subset(&out, &s.selected)?;
    lap("write selection");
    println!(
        "total {:8.2} ms wall {:8.2} ms CPU; O1 {:.4}, selected {:?}",
        t0.elapsed().as_secs_f64() * 1e3,
        vatcal_benches::cpu_ns() as f64 * 1e-6,
        i.raw.o1,
        s.selected
    );
    Ok(())
}
