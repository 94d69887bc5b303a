//! TEMPORARY quality experiment (to be removed).
use std::time::Instant;
use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, greedy};

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(3300);
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml")).unwrap();
    let model = Model::from_cell(&cell).unwrap();
    for seed in [11u64, 12] {
        let poses = vatcal_sim::truth::probe_start_poses(&model, n, seed);
        let c = Candidates::from_measurements(&model, &poses, &ParamSet::paper34()).unwrap();
        let g = greedy(&c, &DetmaxOptions::new(40)).unwrap();
        println!("set {seed}: greedy O1 {:.4}", g.o1(34));
        for (restarts, exc) in [(1, None), (8, None), (8, Some(3)), (64, None), (64, Some(4))] {
            let t = Instant::now();
            let s = detmax(&c, &DetmaxOptions { restarts, seed: 5, excursions: exc, ..DetmaxOptions::new(40) }).unwrap();
            let per: Vec<String> = s.restarts.iter().take(8).map(|r| format!("{:.3}", r.objective_value)).collect();
            println!("  restarts {restarts} exc {exc:?}: O1 {:.4} ({:?}) first restarts {}", s.o1(34), t.elapsed(), per.join(" "));
        }
    }
}
