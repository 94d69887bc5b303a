//! Detmax benchmarks (issue 3 targets on this 2-core machine: 40 of 3,300 candidates ≤ 20 ms,
//! 40 of 35,000 ≤ 150 ms, one restart, 34 parameters), plus the naive reference (an SVD per
//! trial design) on the small case for the speed-up ratio.
//!
//! Candidates are **model-based**: probe poses of the canonical cell
//! (`vatcal_sim::truth::probe_start_poses`: random joints inside the limits, then numerical
//! position IK that puts a random TCP exactly on one of the three calibration positions,
//! cycling over the positions), with the paper's 34-parameter Jacobian blocks in natural units.
//! They are generated once, seeded, outside the timed loop.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_core::{CellFile, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, naive_detmax};

fn canonical() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture");
    Model::from_cell(&cell).expect("model")
}

fn candidates(model: &Model, count: usize, seed: u64) -> Candidates {
    let poses = vatcal_sim::truth::probe_start_poses(model, count, seed);
    assert_eq!(poses.len(), count, "pose generation");
    Candidates::from_measurements(model, &poses, &ParamSet::paper34()).expect("candidate blocks")
}

/// One restart of the plain Wynn–Mitchell exchange (no excursions), O1.
fn one_restart(seed: u64) -> DetmaxOptions {
    DetmaxOptions { restarts: 1, seed, excursions: None, ..DetmaxOptions::new(40) }
}

/// Whether this is a measurement (`cargo bench` passes `--bench`) rather than `cargo test
/// --benches`, which runs every benchmark once to check that it runs.
fn measuring() -> bool {
    std::env::args().any(|a| a == "--bench")
}

fn bench_detmax(c: &mut Criterion) {
    let model = canonical();
    let small = candidates(&model, 3_300, 1);
    let large = candidates(&model, 35_000, 2);
    // the naive reference's single run under `cargo test` (dev profile) took 24 s on 3,300
    // candidates; the test run only checks that it runs, so there it gets the first 330 poses
    // of the same seed (the measurement keeps the 3,300 of the speed-up ratio)
    let naive_pool = if measuring() { None } else { Some(candidates(&model, 330, 1)) };
    let naive_pool = naive_pool.as_ref().unwrap_or(&small);

    let mut group = c.benchmark_group("detmax");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(10));
    group.bench_function("40_of_3300_one_restart", |b| {
        b.iter(|| detmax(black_box(&small), &one_restart(7)).expect("detmax"))
    });
    group.bench_function("40_of_35000_one_restart", |b| {
        b.iter(|| detmax(black_box(&large), &one_restart(7)).expect("detmax"))
    });
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(60));
    group.bench_function("naive_40_of_3300_one_restart", |b| {
        b.iter(|| naive_detmax(black_box(naive_pool), &one_restart(7)).expect("naive"))
    });
    group.finish();
}

criterion_group!(benches, bench_detmax);
criterion_main!(benches);
