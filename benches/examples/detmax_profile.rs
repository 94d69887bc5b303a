//! TEMPORARY profiling helper (to be removed).
use std::time::Instant;
use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax};

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(35000);
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml")).unwrap();
    let model = Model::from_cell(&cell).unwrap();
    let t = Instant::now();
    let poses = vatcal_sim::truth::probe_start_poses(&model, n, 2);
    let c = Candidates::from_measurements(&model, &poses, &ParamSet::paper34()).unwrap();
    eprintln!("generation {:?}", t.elapsed());
    let iters: usize = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(12);
    for _ in 0..iters {
        let t = Instant::now();
        let s = detmax(&c, &DetmaxOptions { restarts: 1, seed: 7, ..DetmaxOptions::new(40) }).unwrap();
        eprintln!("detmax {:?} exchanges {} o1 {:.3}", t.elapsed(), s.restarts[0].exchanges, s.o1(34));
    }
}
