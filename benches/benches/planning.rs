//! Planning benchmarks (issue 6 targets on this 2-core machine): the whole `vatcal plan` with
//! default options (4,500 TCP poses × 10 guide steps, Detmax 40 of N, tour, paths) ≤ 10 s, and
//! the closed-form IK of one tool pose (all 8 branches) ≤ 5 µs. Also the closed form + refinement
//! on the nominal model and on a calibrated model, one collision check, and the multi-start
//! numerical IK (issue 12; no target) of the same tool pose, and the closed form on the Meca500
//! alone on a table (`fixtures/meca500-table.toml`, issue 12: any 6R arm with a spherical wrist).
//!
//! Issue 31 item 5 (`vatcal plan --model fixtures/ur5e.toml` ≤ 2 s on 2 cores): the closed form
//! of the UR5e (three parallel middle axes, `ParallelArm`), the warm-started numerical IK of the
//! same pose, and the whole `plan_campaign` on the UR5e fixture with the defaults of
//! `vatcal plan` (seed 3) three ways — the closed form (the default), the warm-started
//! numerical IK, and the cold multi-start numerical IK the planner used before (group
//! `planning_ur5e`; ~5 s per run, filter it out with `planning/` or `planning_ur5e/plan_campaign/c`).
//! Under `cargo test --all-targets` (no `--bench` argument) each runs once with 12 orientations
//! instead of 500.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use vatcal_core::{CellFile, JointVector, ParamId};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::{CandidateOptions, IkChoice};
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::ik::{
    ArmAtGuide, ArmGeometry, ModelIk, ParallelArm, RefineOptions, ToolPoseIk, robot_base_frame,
};
use vatcal_planning::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk, solve_local};
use vatcal_planning::plan::{PlanOptions, plan_campaign};

/// Whether this is a measurement (`cargo bench` passes `--bench`) rather than `cargo test
/// --benches`, which runs every benchmark once to check that it runs.
fn measuring() -> bool {
    std::env::args().any(|a| a == "--bench")
}

/// The cell file `fixtures/<name>`.
fn fixture(name: &str) -> CellFile {
    CellFile::load(format!("{}/../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect(name)
}

fn cell() -> CellFile {
    fixture("meca500-zaber.toml")
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
    let arm_at_guide = ArmAtGuide { model: &model, q1_mm: 120.0 };
    let joints: Vec<JointSpec> =
        model.joint_limits()[1..].iter().map(|(lo, hi)| JointSpec::revolute(*lo, *hi)).collect();
    let numeric = NumericIk::new(&arm_at_guide, &joints, MultiStartOptions::default()).expect("numeric ik");
    let refine = MultiStartOptions::default().refine;
    // the first start that converges (a converging local solve, not an abandoned one)
    let start = numeric
        .starts()
        .iter()
        .find(|s| solve_local(&arm_at_guide, &joints, s, &IkTarget::Pose(target), &refine).is_ok())
        .expect("a converging start")
        .clone();
    group.bench_function("numeric_multistart_all_branches", |b| {
        b.iter(|| black_box(numeric.solve(black_box(&IkTarget::Pose(target)))))
    });
    group.bench_function("numeric_one_converging_local_solve", |b| {
        b.iter(|| {
            black_box(solve_local(
                &arm_at_guide,
                &joints,
                black_box(&start),
                &IkTarget::Pose(target),
                &refine,
            ))
        })
    });
    let ur5e = Model::from_cell(&fixture("ur5e.toml")).expect("ur5e model");
    let ur5e_ik =
        ModelIk::new(&ur5e, RefineOptions::default(), MultiStartOptions::default()).expect("ur5e ik");
    let ur5e_q = JointVector::from_slice(&[0.3, -1.2, 1.1, -0.8, 1.4, 0.6]).expect("joints");
    let ur5e_target = ur5e.chain(&ur5e_q).tool;
    group.bench_function("numeric_multistart_ur5e_fixture", |b| {
        b.iter(|| black_box(ur5e_ik.solve(&[], black_box(&ur5e_target))))
    });
    // issue 31: the UR5e's closed form (bare, and as the planner's IK: 8 branches refined on the
    // model) and the numerical IK warm-started from the solutions of a pose 3 deg away on every
    // joint (stops once it has as many solutions as that neighbour)
    let ur5e_arm = ParallelArm::from_model(&ur5e).expect("ur5e parallel arm");
    let ur5e_local = robot_base_frame(&ur5e, 0.0).inverse().compose(&ur5e_target);
    group.bench_function("closed_form_8_branches_ur5e", |b| {
        b.iter(|| black_box(ur5e_arm.solve(black_box(&ur5e_local))))
    });
    let ur5e_closed =
        ModelIk::closed_form_first(&ur5e, RefineOptions::default(), MultiStartOptions::default())
            .expect("ur5e closed form");
    assert!(ur5e_closed.is_closed_form());
    group.bench_function("model_ik_closed_form_ur5e", |b| {
        b.iter(|| black_box(ur5e_closed.solve(&[], black_box(&ur5e_target))))
    });
    let ur5e_numeric = ModelIk::numerical(&ur5e, MultiStartOptions::default()).expect("numeric");
    let neighbour_q =
        JointVector::from_slice(&ur5e_q.as_slice().iter().map(|v| v + 0.05).collect::<Vec<_>>())
            .expect("joints");
    let neighbour = ur5e_numeric.solve(&[], &ur5e.chain(&neighbour_q).tool);
    group.bench_function("numeric_warm_ur5e_fixture", |b| {
        b.iter(|| {
            black_box(ur5e_numeric.solve_at_guide_warm(
                0.0,
                black_box(&ur5e_target),
                &neighbour,
                neighbour.len(),
            ))
        })
    });
    // issue 12: the closed form on a chain other than the canonical cell (the Meca500 alone on a
    // table), the planner's IK (`ModelIk`: 8 branches, refined on the model) and the bare closed form
    let table = Model::from_cell(&fixture("meca500-table.toml")).expect("meca500-table model");
    let table_ik =
        ModelIk::new(&table, RefineOptions::default(), MultiStartOptions::default()).expect("table ik");
    assert!(table_ik.is_closed_form());
    let table_q = JointVector::from_slice(&q.as_slice()[1..]).expect("joints");
    let table_target = table.chain(&table_q).tool;
    let table_arm = ArmGeometry::from_model(&table).expect("table arm");
    let table_local = robot_base_frame(&table, 0.0).inverse().compose(&table_target);
    group.bench_function("closed_form_8_branches_meca500_table", |b| {
        b.iter(|| black_box(table_arm.solve(black_box(&table_local))))
    });
    group.bench_function("model_ik_closed_form_meca500_table", |b| {
        b.iter(|| black_box(table_ik.solve(&[], black_box(&table_target))))
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

/// `plan_campaign` on the UR5e fixture as `vatcal plan --model fixtures/ur5e.toml --seed 3`
/// plans it, with the IK `ik` (12 orientations in test mode).
fn bench_plan_ur5e(c: &mut Criterion) {
    let cell = fixture("ur5e.toml");
    let model = Model::from_cell(&cell).expect("ur5e model");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let orientations = if measuring() { 500 } else { 12 };
    let opts = |ik: IkChoice, warm_start: bool| PlanOptions {
        candidates: CandidateOptions { orientations, ik, warm_start, ..CandidateOptions::default() },
        params: vatcal_core::ParamSet(Vec::new()),
        motion: cell.motion_limits(),
        seed: 3,
        ..PlanOptions::default()
    };
    let mut group = c.benchmark_group("planning_ur5e/plan_campaign");
    // flat sampling: ten samples of equal length (the linear default needs 55 runs)
    group.sample_size(10).sampling_mode(SamplingMode::Flat).measurement_time(Duration::from_secs(30));
    for (name, ik, warm) in [
        ("closed_form", IkChoice::ClosedFormFirst, true),
        ("numeric_warm", IkChoice::Numerical, true),
        ("numeric_cold_before", IkChoice::WithoutParallelClosedForm, false),
    ] {
        let o = opts(ik, warm);
        group.bench_function(name, |b| {
            b.iter(|| black_box(plan_campaign(&model, &geometry, &o).expect("plan")))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_ik, bench_plan, bench_plan_ur5e);
criterion_main!(benches);
