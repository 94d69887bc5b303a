//! Identification benchmarks (issue 4 target on this 2-core machine: the paper's 34
//! parameters from 40 simulated probe measurements, to convergence, ≤ 2 ms).
//!
//! Data: the canonical cell as nominal model, a hidden "true" cell with the realistic error
//! budget (`vatcal_sim::truth`), 40 probe measurements with 3 µm noise. Generated once,
//! seeded, outside the timed loop. Benchmarks:
//!
//! * `identification/lm/paper34/40` — the full `identify` call with default options
//!   (identifiability check, Levenberg–Marquardt to convergence, statistics);
//! * `identification/lm-no-check/paper34/40` — the same without the identifiability check,
//!   to see its share;
//! * `identification/gn/paper34/40` — Gauss–Newton;
//! * `identification/jacobian/paper34/40` — one stacked Jacobian (40 × `jacobian_into`).

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_core::{CellFile, Measurement, ParamSet};
use vatcal_identification::{IdentifyOptions, Method, identify};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};

fn canonical() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture");
    Model::from_cell(&cell).expect("model")
}

fn campaign(nominal: &Model, count: usize) -> Vec<Measurement> {
    let truth = perturbed_truth(nominal, 2, &ErrorBudget::realistic());
    let starts = probe_start_poses(nominal, count + 4, 102);
    let mut m = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.003 }, 202);
    m.truncate(count);
    assert_eq!(m.len(), count, "measurement generation");
    m
}

fn bench_identification(c: &mut Criterion) {
    let nominal = canonical();
    let data = campaign(&nominal, 40);
    let params = ParamSet::paper34();
    let lm = IdentifyOptions::default();
    let fit = identify(&nominal, &data, &params, &lm).expect("fit");
    eprintln!(
        "identification bench data: {} LM iterations, {:?}, residual mean {:.4} mm",
        fit.iterations.len() - 1,
        fit.termination,
        fit.residual_stats.mean
    );

    let mut group = c.benchmark_group("identification");
    group.measurement_time(Duration::from_secs(5));
    group.bench_function("lm/paper34/40", |b| {
        b.iter(|| identify(black_box(&nominal), black_box(&data), &params, &lm).expect("fit"))
    });
    let no_check = IdentifyOptions { check_identifiability: false, ..IdentifyOptions::default() };
    group.bench_function("lm-no-check/paper34/40", |b| {
        b.iter(|| identify(black_box(&nominal), black_box(&data), &params, &no_check).expect("fit"))
    });
    let gn = IdentifyOptions::with_method(Method::GaussNewton);
    group.bench_function("gn/paper34/40", |b| {
        b.iter(|| identify(black_box(&nominal), black_box(&data), &params, &gn).expect("fit"))
    });
    let mut block = vec![0.0; 3 * params.len()];
    group.bench_function("jacobian/paper34/40", |b| {
        b.iter(|| {
            for m in &data {
                black_box(
                    nominal.measurement_jacobian_into(black_box(m), &params.0, &mut block).expect("block"),
                );
            }
        })
    });
    group.finish();
}

criterion_group!(benches, bench_identification);
criterion_main!(benches);
