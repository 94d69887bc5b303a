//! Compensation speed (issue 13 target: 10,000 poses compensated in ≤ 50 ms on one core).
//!
//! The calibrated model is a perturbed truth of the canonical cell (realistic geometric errors
//! and non-zero compliances, so the gravity-torque recursion runs in every FK call). The path
//! is 10,000 dense tool poses along a smooth joint-space curve (guide lifting 0.01 mm per pose,
//! like a printer's z axis), compensated as a path: the first pose from the closed-form
//! branches, every other pose by Newton warm-started from the previous one.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_compensation::{Compensator, PathOptions, ToolTarget};
use vatcal_core::{CellFile, JointVector};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth};

const POSES: usize = 10_000;

fn bench_compensation(c: &mut Criterion) {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture");
    let nominal = Model::from_cell(&cell).expect("model");
    let calibrated = perturbed_truth(&nominal, 1, &ErrorBudget::realistic());
    let a = JointVector::from_mm_deg(100.0, [-20.0, 10.0, -20.0, 30.0, 40.0, -50.0]);
    let b = JointVector::from_mm_deg(200.0, [35.0, 30.0, -5.0, -40.0, 70.0, 120.0]);
    let targets: Vec<ToolTarget> = (0..POSES)
        .map(|k| {
            let t = k as f64 / (POSES - 1) as f64;
            let s = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
            let q = JointVector::new::<7>(std::array::from_fn(|i| a[i] + s * (b[i] - a[i])));
            ToolTarget::new(q[0], calibrated.chain(&q).tool)
        })
        .collect();
    let comp = Compensator::new(&calibrated, &nominal).expect("compensator");
    let opts = PathOptions { start: Some(a), ..PathOptions::default() };
    // sanity: every pose solved
    let result = comp.compensate_path(&targets, &opts).expect("path");
    assert_eq!(result.solved().count(), POSES);
    let mut group = c.benchmark_group("compensation");
    group.sample_size(10);
    group.bench_function("path_10000_poses", |bch| {
        bch.iter(|| comp.compensate_path(black_box(&targets), &opts).expect("path"))
    });
    // the unit of work: one forward kinematics with compliance (gravity torques included)
    let q = a;
    let ctx = vatcal_core::MeasurementContext::default();
    group.bench_function("chain_full_with_compliance", |bch| {
        bch.iter(|| calibrated.chain_full(black_box(&q), &ctx, false, None))
    });
    group.finish();
}

criterion_group!(benches, bench_compensation);
criterion_main!(benches);
