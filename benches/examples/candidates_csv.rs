//! Writes `COUNT` seeded model-based candidate poses of the canonical cell as a candidate-pose
//! CSV (`position,tcp,q1..q7`), the input of the `vatcal select` timing in
//! `docs/performance.md`:
//!
//! ```text
//! cargo run --release -p vatcal-benches --example candidates_csv -- 35000 2 /tmp/cand35k.csv
//! ```

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: candidates_csv COUNT SEED OUT.csv";
    let [_, count, seed, out] = args.as_slice() else {
        eprintln!("{usage}");
        return ExitCode::FAILURE;
    };
    let (Ok(count), Ok(seed)) = (count.parse::<usize>(), seed.parse::<u64>()) else {
        eprintln!("{usage} (COUNT and SEED are non-negative integers)");
        return ExitCode::FAILURE;
    };
    let model = vatcal_benches::canonical();
    let poses = vatcal_benches::candidate_poses(&model, count, seed);
    if let Err(e) = vatcal_io::write_measurements(out, &poses) {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    println!("wrote {} candidate poses to {out}", poses.len());
    ExitCode::SUCCESS
}
