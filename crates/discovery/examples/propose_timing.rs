//! Times [`vatcal_discovery::propose::propose`] on a realistic case: a canonical-cell probe
//! case with a borderline gear error (as in `tests/discovery_tests/propose.rs`), discovery run
//! on it, then `COUNT` measurements proposed for its undecided effects from a pool of `POOL`
//! probe start poses (the demo's discovery proposal draws from ~9,000 planner candidates).
//!
//! ```text
//! cargo run --release -p vatcal-discovery --example propose_timing -- [POOL] [COUNT] [JSON_OUT]
//! ```
//! (defaults: 9000 poses, 24 measurements). Prints the time of `propose` (best of 3) and writes
//! the selection and its `ln Ds` to `JSON_OUT`, for comparing two versions of the code.

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "../tests/common/mod.rs"]
mod common;

use common::benchmark::{discover_probe_case, probe_case_with};
use vatcal_core::effects::EffectSpec;
use vatcal_discovery::propose::{focus_effects, propose};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let pool_size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(9000);
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(24);
    let seed = 1;
    let spec = EffectSpec::JointCyclic { joint: 5, harmonic: 1 };
    let data = probe_case_with(seed, spec, 0.8);
    let d = discover_probe_case(&data, &data.measurements, seed);
    let focus = focus_effects(&d, &data.measurements, 2);
    let pool = vatcal_sim::truth::probe_start_poses(&data.nominal, pool_size, seed + 1000);
    let weights = d.kind_sigmas.weights();
    let mut best = f64::INFINITY;
    let mut proposal = None;
    for _ in 0..3 {
        let t0 = std::time::Instant::now();
        let p = propose(&d.model, &d.params, &data.measurements, &focus, &pool, count, &weights)
            .expect("propose");
        best = best.min(t0.elapsed().as_secs_f64());
        proposal = Some(p);
    }
    let p = proposal.expect("ran");
    println!(
        "focus {:?} ({} params), pool {}, count {}: propose {:.3} s (best of 3, {} threads); ln Ds {:.6} -> {:.6}",
        p.focus,
        p.focus_params.len(),
        pool.len(),
        count,
        best,
        rayon::current_num_threads(),
        p.ln_ds_before,
        p.ln_ds_after
    );
    if let Some(path) = args.get(3) {
        std::fs::write(path, serde_json::to_string_pretty(&p).unwrap()).unwrap();
    }
}
