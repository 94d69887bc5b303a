//! The whole pipeline on a small candidate set, with the tour verified independently.

use crate::common;

use vatcal_core::JointVector;
use vatcal_kinematics::Model;
use vatcal_planning::candidates::{CandidateOptions, IkChoice, generate_candidates};
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::motion::{Resolution, interpolate};
use vatcal_planning::output::{PlanSummary, write_plan};
use vatcal_planning::plan::{Plan, PlanOptions, StepKind, plan_campaign};

fn small(seed: u64, start: Option<JointVector>) -> PlanOptions {
    PlanOptions {
        candidates: CandidateOptions { orientations: 40, guide_steps: 6, ..CandidateOptions::default() },
        detmax_restarts: 2,
        tour_restarts: 4,
        start,
        seed,
        ..PlanOptions::default()
    }
}

fn free_segment(checker: &CollisionChecker<'_>, a: &JointVector, b: &JointVector, probe: ProbeState) -> bool {
    let res = Resolution::default();
    let n = res.intervals_for(a, b, checker.model().joint_kinds());
    (0..=n).all(|i| checker.is_free(&interpolate(a, b, i as f64 / n as f64), probe))
}

/// Replays the tour: every move and measurement is collision-free with the probe where the
/// tour says it is, every measurement puts its TCP on its position.
fn replay(model: &Model, geometry: &CellGeometry, plan: &Plan, start: Option<JointVector>) {
    let checker = CollisionChecker::new(model, geometry, 2.0).expect("checker");
    let mut current: Option<JointVector> = start;
    let mut probe_at: Option<u32> = None;
    let mut previous_kind: Option<StepKind> = None;
    let mut measured = Vec::new();
    for (k, s) in plan.steps.iter().enumerate() {
        match s.kind {
            StepKind::ReplaceProbe => {
                assert!(probe_at != Some(s.position), "step {k}: re-placement to the same position");
                probe_at = Some(s.position);
            }
            StepKind::Move => {
                assert_eq!(probe_at, Some(s.position), "step {k}");
                // the move right after a measurement is the retreat: the ball leaves the probe
                let probe = if previous_kind == Some(StepKind::Measure) {
                    ProbeState::Measuring { position: s.position, tcp: s.tcp }
                } else {
                    ProbeState::At { position: s.position }
                };
                if let Some(c) = current {
                    assert!(free_segment(&checker, &c, &s.q, probe), "step {k}: move collides");
                } else {
                    assert!(checker.is_free(&s.q, probe));
                }
                current = Some(s.q);
            }
            StepKind::Measure => {
                let probe = ProbeState::Measuring { position: s.position, tcp: s.tcp };
                let from = current.expect("a move precedes every measurement");
                assert!(free_segment(&checker, &from, &s.q, probe), "step {k}: descent collides");
                let err = (model.tcp_position(&s.q, s.tcp).expect("fk")
                    - model.position(s.position).expect("p"))
                .norm();
                assert!(err < 1e-6, "step {k}: TCP {err} mm off");
                assert!(model.limit_violation(&s.q).is_none());
                measured.push(s.q);
                current = Some(s.q);
            }
        }
        previous_kind = Some(s.kind);
        if k > 0 {
            assert!(s.time_s >= plan.steps[k - 1].time_s, "time goes backwards at step {k}");
        }
    }
    let expected: Vec<JointVector> = plan.order.iter().map(|&i| plan.candidates.candidates[i].q).collect();
    assert_eq!(measured, expected);
}

#[test]
fn small_campaign_is_planned_and_every_step_verified() {
    let cell = common::cell();
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    // start from the retreat pose of some other measurement at position 3
    let other = CandidateOptions {
        orientations: 3,
        positions: Some(vec![3]),
        seed: 77,
        ..CandidateOptions::default()
    };
    let start = generate_candidates(&model, &checker, &other).expect("c").candidates[0].retreat;
    let opts = small(5, Some(start));
    let plan = plan_campaign(&model, &geometry, &opts).expect("plan");
    // selection
    assert_eq!(plan.selected.len(), 40);
    assert_eq!(plan.quality.raw.rank, opts.params.len());
    assert!(plan.quality.raw.o1 > plan.quality.candidates_o1, "Detmax should beat the whole set's O1");
    // the tour visits exactly the selection, each position in one block
    let mut order = plan.order.clone();
    order.sort_unstable();
    assert_eq!(order, plan.selected);
    let positions: Vec<u32> = plan.order.iter().map(|&i| plan.candidates.candidates[i].position).collect();
    let changes = positions.windows(2).filter(|w| w[0] != w[1]).count();
    let mut distinct = positions.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(changes, distinct.len() - 1);
    assert_eq!(plan.timing.replacements, changes);
    // time
    assert!(plan.timing.ordered_s <= plan.timing.selection_order_s + 1e-9);
    assert!(plan.timing.ordered_s < plan.timing.shuffled_order_s);
    assert!(plan.timing.planned_paths_s >= plan.timing.ordered_s - 1e-6);
    let last = plan.steps.last().expect("steps");
    assert!(
        (last.time_s - plan.timing.planned_paths_s).abs() < 0.01,
        "{} vs {}",
        last.time_s,
        plan.timing.planned_paths_s
    );
    replay(&model, &geometry, &plan, Some(start));
}

#[test]
fn files_round_trip_through_the_io_readers() {
    let cell = common::cell();
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let plan = plan_campaign(&model, &geometry, &small(9, None)).expect("plan");
    replay(&model, &geometry, &plan, None);
    let dir = std::env::temp_dir().join(format!("vatcal-plan-test-{}", std::process::id()));
    let summary = write_plan(&plan, &dir).expect("write");
    assert_eq!(summary, PlanSummary::of(&plan));
    let table = vatcal_io::read_candidates(dir.join("candidates.csv"), &model).expect("read back");
    assert_eq!(table.measurements.len(), plan.candidates.candidates.len());
    for (m, c) in table.measurements.iter().zip(&plan.candidates.candidates) {
        assert_eq!((m.tcp, m.position()), (c.tcp, Some(c.position)));
        let diff = m.q.as_slice().iter().zip(c.q.as_slice()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-12, "round trip changed the joints by {diff}");
    }
    let selected = vatcal_io::read_candidates(dir.join("selected.csv"), &model).expect("selected");
    assert_eq!(selected.measurements.len(), 40);
    let tour = std::fs::read_to_string(dir.join("tour.csv")).expect("tour");
    assert!(tour.starts_with("step,kind,position,tcp,q1,q2,q3,q4,q5,q6,q7,time_s\n"));
    assert_eq!(tour.lines().count(), plan.steps.len() + 1);
    assert_eq!(tour.matches(",measure,").count(), 40);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).expect("json"))
            .expect("valid json");
    assert_eq!(json["selected"], 40);
    assert!(json["counts"]["retreat_clear"].as_u64().expect("count") >= 40);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn too_few_candidates_is_a_clear_error() {
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&common::cell()).expect("geometry");
    let opts = PlanOptions {
        candidates: CandidateOptions { orientations: 1, guide_steps: 1, ..CandidateOptions::default() },
        ..PlanOptions::default()
    };
    let err = plan_campaign(&model, &geometry, &opts).expect_err("too few");
    assert!(err.to_string().contains("requested measurements"), "{err}");
}

/// A small plan on a version-2 fixture (any chain: the IK `ik` — a closed form where the chain
/// has one, or the warm-started numerical IK —, generic collision bodies, default parameter
/// set), every candidate checked by forward kinematics, the tour replayed and the files read
/// back with the fixture's `q1..qN` columns.
fn any_chain_plan(fixture: &str, seed: u64, ik: IkChoice) {
    let path = format!("{}/../../fixtures/{fixture}", env!("CARGO_MANIFEST_DIR"));
    let cell = vatcal_core::CellFile::load(&path).expect("fixture");
    let model = Model::from_cell(&cell).expect("model");
    assert!(!model.is_meca500_on_guide());
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let opts = PlanOptions {
        candidates: CandidateOptions { orientations: 12, guide_steps: 3, ik, ..CandidateOptions::default() },
        params: vatcal_core::ParamSet(Vec::new()),
        detmax_restarts: 1,
        tour_restarts: 2,
        motion: cell.motion_limits(),
        seed,
        ..PlanOptions::default()
    };
    let plan = plan_campaign(&model, &geometry, &opts).expect("plan");
    eprintln!(
        "{fixture} ({}): {:?}, {} parameters: {}",
        plan.candidates.ik,
        plan.candidates.counts,
        plan.params.len(),
        plan.params.names().join(",")
    );
    assert!(plan.candidates.guide_positions_mm.is_empty());
    assert!(plan.params.len() >= 20, "default set of {} parameters", plan.params.len());
    assert_eq!(plan.selected.len(), 40);
    assert_eq!(plan.quality.raw.rank, plan.params.len(), "the selection identifies the default set");
    let counts = plan.candidates.counts;
    assert!(counts.ik_solutions > counts.retreat_clear && counts.retreat_clear >= 40, "{counts:?}");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    for c in &plan.candidates.candidates {
        // IK vs FK: the TCP on its calibration position, joints inside the limits
        let err =
            (model.tcp_position(&c.q, c.tcp).expect("fk") - model.position(c.position).expect("p")).norm();
        assert!(err < 1e-6, "candidate TCP {err} mm off its position");
        assert!(model.limit_violation(&c.q).is_none() && model.limit_violation(&c.retreat).is_none());
        let up = model.tcp_position(&c.retreat, c.tcp).expect("fk") - model.position(c.position).expect("p");
        assert!((up - nalgebra::Vector3::new(0.0, 0.0, 30.0)).norm() < 1e-6, "retreat {up}");
        assert!(checker.is_free(&c.q, ProbeState::Measuring { position: c.position, tcp: c.tcp }));
    }
    replay(&model, &geometry, &plan, None);
    let dir = std::env::temp_dir().join(format!("vatcal-plan-{fixture}-{}", std::process::id()));
    write_plan(&plan, &dir).expect("write");
    let n = model.joint_count();
    let header: Vec<String> = (1..=n).map(|i| format!("q{i}")).collect();
    let tour = std::fs::read_to_string(dir.join("tour.csv")).expect("tour");
    assert!(tour.starts_with(&format!("step,kind,position,tcp,{},time_s\n", header.join(","))), "{tour:.80}");
    let table = vatcal_io::read_candidates(dir.join("selected.csv"), &model).expect("read back");
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(table.measurements.len(), 40);
    for (m, &i) in table.measurements.iter().zip(&plan.order) {
        let c = &plan.candidates.candidates[i];
        let diff = m.q.as_slice().iter().zip(c.q.as_slice()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-12, "round trip changed the joints by {diff}");
    }
}

#[test]
fn any_chain_plans_on_the_ur5e_fixture() {
    any_chain_plan("ur5e.toml", 3, IkChoice::ClosedFormFirst);
}

#[test]
fn any_chain_plans_on_the_ur5e_fixture_with_the_numerical_ik() {
    any_chain_plan("ur5e.toml", 3, IkChoice::Numerical);
}

#[test]
fn any_chain_plans_on_the_meca500_table_fixture() {
    any_chain_plan("meca500-table.toml", 4, IkChoice::ClosedFormFirst);
}
