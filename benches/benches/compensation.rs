//! Compensation speed (issue 13 target: 10,000 poses compensated in ≤ 50 ms on one core).
//!
//! The calibrated model is a perturbed truth of the canonical cell (realistic geometric errors
//! and non-zero compliances, so the gravity-torque recursion runs in every FK call). The path
//! is 10,000 dense tool poses along a smooth joint-space curve (guide lifting 0.01 mm per pose,
//! like a printer's z axis), compensated as a path: the first pose from the closed-form
//! branches, every other pose by Newton warm-started from the previous one.
//!
//! `ur5e_path_1000_poses`: the same on the UR5e-class arm (`fixtures/ur5e.toml`, perturbed),
//! whose first pose is seeded by the multi-start numerical IK (the branch is the sign of det J).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_compensation::{Compensator, PathOptions, ToolTarget};
use vatcal_core::{CellFile, JointVector};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth};

const POSES: usize = 10_000;
/// Poses of the UR5e path (its first pose runs the multi-start numerical IK).
const UR_POSES: usize = 1_000;

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
    // any chain (issue 12): the UR5e-class arm, numerical-IK seeds on the first pose, then the
    // same warm-started Newton; 1,000 dense poses of a smooth path
    let ur_cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/ur5e.toml")).expect("UR5e fixture");
    let ur_nominal = Model::from_cell(&ur_cell).expect("model");
    let ur_calibrated = perturbed_truth(&ur_nominal, 1, &ErrorBudget::realistic());
    let ua = [0.3, -1.2, 1.1, -1.4, 1.2, 0.2];
    let ub = [0.9, -0.8, 1.4, -1.0, 1.6, 1.2];
    let ur_targets: Vec<ToolTarget> = (0..UR_POSES)
        .map(|k| {
            let t = k as f64 / (UR_POSES - 1) as f64;
            let s = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
            let q = JointVector::new::<6>(std::array::from_fn(|i| ua[i] + s * (ub[i] - ua[i])));
            ToolTarget::with_given(JointVector::zeros(6), ur_calibrated.chain(&q).tool)
        })
        .collect();
    let ur_comp = Compensator::new(&ur_calibrated, &ur_nominal).expect("compensator");
    let ur_opts = PathOptions::default();
    let result = ur_comp.compensate_path(&ur_targets, &ur_opts).expect("UR5e path");
    assert_eq!(result.solved().count(), UR_POSES);
    group.bench_function("ur5e_path_1000_poses", |bch| {
        bch.iter(|| ur_comp.compensate_path(black_box(&ur_targets), &ur_opts).expect("path"))
    });
    group.finish();
}

criterion_group!(benches, bench_compensation);
criterion_main!(benches);
