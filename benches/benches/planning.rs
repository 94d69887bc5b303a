//! Planning benchmarks (issue 6 targets on this 2-core machine): the whole `vatcal plan` with
//! default options (4,500 TCP poses × 10 guide steps, Detmax 40 of N, tour, paths) ≤ 10 s, and
//! the closed-form IK of one tool pose (all 8 branches) ≤ 5 µs. Also the closed form + refinement
//! on the nominal model and on a calibrated model, and one collision check.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_core::{CellFile, JointVector, ParamId};
use vatcal_kinematics::Model;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::ik::{ArmGeometry, RefineOptions, ToolPoseIk, robot_base_frame};
use vatcal_planning::plan::{PlanOptions, plan_campaign};

fn cell() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture")
}

fn bench_ik(c: &mut Criterion) {
    let model = Model::from_cell(&cell()).expect("model");
    let q = JointVector::from_mm_deg(120.0, [30.0, 20.0, -40.0, 50.0, 60.0, -70.0]);
    let target = model.chain(&q).tool;
    let base = robot_base_frame(&model, q[0]);
    let local = base.inverse().compose(&target);
    let arm = ArmGeometry::from_model(&model).expect("arm");
    let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
    let mut calibrated = model.clone();
    for i in 2..=7u8 {
        let a = calibrated.param(ParamId::Alpha(i)).expect("alpha");
        calibrated.set_param(ParamId::Alpha(i), a + 1e-3).expect("set");
        calibrated.set_param(ParamId::Compliance(i), 1e-3).expect("set");
    }
    let ik_calibrated = ToolPoseIk::new(&calibrated, RefineOptions::default()).expect("ik");
    let target_calibrated = calibrated.chain(&q).tool;
    let geometry = CellGeometry::from_cell(&cell()).expect("geometry");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");

    let mut group = c.benchmark_group("planning/ik");
    group.bench_function("closed_form_8_branches", |b| b.iter(|| black_box(arm.solve(black_box(&local)))));
    group.bench_function("closed_form_plus_refinement_nominal", |b| {
        b.iter(|| black_box(ik.solve_at_guide(black_box(120.0), black_box(&target))))
    });
    group.bench_function("closed_form_plus_refinement_calibrated", |b| {
        b.iter(|| black_box(ik_calibrated.solve_at_guide(black_box(120.0), black_box(&target_calibrated))))
    });
    group.bench_function("collision_check", |b| {
        b.iter(|| black_box(checker.check(black_box(&q), ProbeState::Everywhere)))
    });
    group.finish();
}

fn bench_plan(c: &mut Criterion) {
    let cell = cell();
    let model = Model::from_cell(&cell).expect("model");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let opts = PlanOptions { motion: cell.motion_limits(), ..PlanOptions::default() };
    let mut group = c.benchmark_group("planning");
    group.sample_size(10).measurement_time(Duration::from_secs(30));
    group.bench_function("plan_campaign_defaults", |b| {
        b.iter(|| black_box(plan_campaign(&model, &geometry, &opts).expect("plan")))
    });
    group.finish();
}

criterion_group!(benches, bench_ik, bench_plan);
criterion_main!(benches);
